"""URDF read as urdfdom reads it: the same documents accepted and refused as urdfdom (through
pinocchio, which wraps it), numbers read the same, namespace prefixes (declared or not) and
gazebo / transmission / ros2_control blocks ignored, and the few documents we refuse on purpose
where urdfdom would read them (bounded reading of hostile text)."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pin_oracle as P
import pytest
import urdf_util as U
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from geodesic_planner.core.errors import KinematicsError
from geodesic_planner.core.urdf import chain_from_urdf
from geodesic_planner.core.urdf_xml import parse_number, read_urdf

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
#: a revolute joint 1 m up, then a fixed tool 1 m along x
BASE = ('<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 1" rpy="0 0 0"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        '<joint name="t" type="fixed"><parent link="b"/><child link="c"/><origin xyz="1 0 0"/></joint></robot>')


def ours(xml: str) -> bool:
    try:
        read_urdf(xml)
    except KinematicsError:
        return False
    return True


def sub(old: str, new: str) -> str:
    assert old in BASE, old
    return BASE.replace(old, new, 1)


# (id, document, urdfdom accepts it)
SAME_AS_URDFDOM = [
    ('base', BASE, True),
    ('undeclared attribute prefix', sub('effort="1"', 'effort="1" drake:acceleration="2.5"'), True),
    ('undeclared element prefix', sub('</robot>', '<drake:joint name="j"/><x:link name="z"/></robot>'), True),
    ('default namespace', sub('<robot name="r">', '<robot name="r" xmlns="urn:x">'), True),
    ('prefixed root', sub('<robot name="r">', '<u:robot name="r">').replace('</robot>', '</u:robot>'), False),
    ('prefixed joint is no joint', sub('<joint name="t"', '<x:joint name="t"').replace('</joint></robot>',
                                                                                       '</x:joint></robot>'), False),
    ('gazebo transmission ros2_control', sub('</robot>', '<gazebo><joint name="j"/><link/></gazebo>'
                                         '<transmission name="x"><joint name="j"/></transmission>'
                                         '<ros2_control name="s" type="system"><joint name="j"/></ros2_control>'
                                         '</robot>'), True),
    ('robot without name', sub('<robot name="r">', '<robot>'), False),
    ('version 1.0', sub('name="r"', 'name="r" version="1.0"'), True),
    ('version 1.2', sub('name="r"', 'name="r" version="1.2"'), True),
    ('version 2.0', sub('name="r"', 'name="r" version="2.0"'), False),
    ('version 1', sub('name="r"', 'name="r" version="1"'), False),
    ('version 1.x', sub('name="r"', 'name="r" version="1.x"'), False),
    ('no link', '<robot name="r"/>', False),
    ('link without name', sub('<link name="c"/>', '<link name="c"/><link/>'), False),
    ('two links of one name', sub('<link name="c"/>', '<link name="c"/><link name="c"/>'), False),
    ('two joints of one name', sub('name="t"', 'name="j"'), False),
    ('two materials of one name', sub('</robot>', '<material name="m"/><material name="m"/></robot>'), False),
    ('bad material colour', sub('</robot>', '<material name="m"><color rgba="1 1"/></material></robot>'), True),
    ('bad link content', sub('<link name="b"/>', '<link name="b"><inertial><mass value="x"/></inertial>'
                                                 '<visual><geometry/></visual></link>'), True),
    ('joint without name', sub('<joint name="t"', '<joint'), False),
    ('joint without type', sub(' type="fixed"', ''), False),
    ('unknown joint type', sub('type="fixed"', 'type="spherical"'), False),
    ('planar joint', sub('type="fixed"', 'type="planar"'), True),
    ('undeclared parent link', sub('<link name="a"/>', ''), False),
    ('undeclared child link', sub('<link name="c"/>', ''), False),
    ('no parent element', sub('<parent link="b"/>', ''), False),
    ('empty parent link', sub('<parent link="b"/>', '<parent link=""/>'), False),
    ('two root links', sub('</robot>', '<link name="d"/></robot>'), False),
    ('revolute without limit', sub('<limit lower="-1" upper="1" effort="1" velocity="1"/>', ''), False),
    ('continuous without limit', sub('<limit lower="-1" upper="1" effort="1" velocity="1"/>', '').replace(
        'revolute', 'continuous'), True),
    ('limit without effort', sub('effort="1" ', ''), False),
    ('limit without velocity', sub(' velocity="1"', ''), False),
    ('limit without lower and upper', sub('lower="-1" upper="1" ', ''), True),
    ('fixed joint with a bad limit', sub('<origin xyz="1 0 0"/>', '<origin xyz="1 0 0"/><limit effort="1"/>'), False),
    ('fixed joint with a bad axis', sub('<origin xyz="1 0 0"/>', '<origin xyz="1 0 0"/><axis xyz="a"/>'), True),
    ('lower above upper', sub('upper="1"', 'upper="-2"'), True),
    ('axis without xyz', sub('<axis xyz="0 0 1"/>', '<axis/>'), True),
    ('mimic of an undeclared joint', sub('<origin xyz="1 0 0"/>', '<origin xyz="1 0 0"/><mimic joint="x"/>'), True),
    ('mimic without joint', sub('<origin xyz="1 0 0"/>', '<origin xyz="1 0 0"/><mimic multiplier="2"/>'), False),
    ('mimic with a bad multiplier', sub('<origin xyz="1 0 0"/>', '<origin xyz="1 0 0"/><mimic joint="j" '
                                                                 'multiplier="two"/>'), False),
    ('safety without k_velocity', sub('</joint>', '<safety_controller soft_lower_limit="0"/></joint>'), False),
    ('dynamics without damping and friction', sub('</joint>', '<dynamics/></joint>'), False),
    ('dynamics with a bad damping', sub('</joint>', '<dynamics damping="x"/></joint>'), False),
    ('calibration with a bad rising', sub('</joint>', '<calibration rising="x"/></joint>'), False),
    ('origin with two numbers', sub('xyz="0 0 1"', 'xyz="0 1"'), False),
    ('origin with extra spaces', sub('xyz="0 0 1"', 'xyz="  0   0 1 "'), True),
    ('origin with a bad rpy', sub('rpy="0 0 0"', 'rpy="a b c"'), False),
    ('second origin ignored', sub('rpy="0 0 0"/>', 'rpy="0 0 0"/><origin xyz="a"/>'), True),
    ('tab inside a vector', sub('xyz="0 0 1"', 'xyz="0\t0 1"'), False),
    ('newline ending a vector', sub('xyz="0 0 1"', 'xyz="0 0 1\n"'), False),
    ('char reference tab inside a vector', sub('xyz="0 0 1"', 'xyz="0&#9;0 1"'), False),
    ('newline between attributes', sub('xyz="0 0 1" rpy', 'xyz="0 0 1"\n  rpy'), True),
    ('newline before a number', sub('lower="-1"', 'lower="\n-1"'), True),
]


@pytest.mark.parametrize('doc, accepted', [c[1:] for c in SAME_AS_URDFDOM], ids=[c[0] for c in SAME_AS_URDFDOM])
def test_accepts_and_refuses_what_urdfdom_does(doc, accepted):
    assert P.accepts(doc) == accepted       # the oracle says so (a changed urdfdom shows up here)
    assert ours(doc) == accepted


# (id, document, our reason): urdfdom reads these; we refuse them to keep reading bounded and tree-shaped.
# pinocchio loads all but the link with two parents (urdfdom accepts that one; pinocchio then fails).
STRICTER = [
    ('doctype', '<!DOCTYPE robot>' + BASE, 'DOCTYPE'),
    ('second top-level element', '<other/>' + BASE, 'not valid XML'),
    ('undefined entity', sub('name="r"', 'name="r&x;"'), 'not valid XML'),
    ('link with two parents', sub('</robot>', '<link name="d"/><joint name="k" type="fixed"><parent link="d"/>'
                                              '<child link="b"/></joint><joint name="k2" type="fixed">'
                                              '<parent link="a"/><child link="d"/></joint></robot>'),
     "link 'b' has two parent joints"),
    ('a cycle apart from the tree', sub('</robot>', '<link name="d"/><link name="e"/><joint name="k" type="fixed">'
                                                    '<parent link="d"/><child link="e"/></joint><joint name="k2" '
                                                    'type="fixed"><parent link="e"/><child link="d"/></joint>'
                                                    '</robot>'), 'cycle'),
]


@pytest.mark.parametrize('doc, reason', [c[1:] for c in STRICTER], ids=[c[0] for c in STRICTER])
def test_refused_on_purpose_although_urdfdom_reads_it(doc, reason):
    assert P.accepts(doc) == ('two parent' not in reason)
    with pytest.raises(KinematicsError, match=reason):
        read_urdf(doc)


NUMBER_TEXT = st.text(alphabet='0123456789+-.eE naix_', max_size=8)


@settings(max_examples=300, deadline=None)
@given(text=NUMBER_TEXT)
def test_numbers_are_read_as_urdfdom_reads_them(text):
    """Any short text as a joint limit: accepted exactly when urdfdom accepts it, with the same value."""
    doc = sub('upper="1"', f'upper="{text}"')
    assert ours(doc) == P.accepts(doc), text
    if ours(doc):
        joint = P.model(doc).joints[1]
        assert read_urdf(doc).joints[0].limit[1] == P.model(doc).upperPositionLimit[joint.idx_q] == parse_number(text)


@settings(max_examples=200, deadline=None)
@given(text=st.text(alphabet='01.-e ', max_size=12))
def test_vectors_are_read_as_urdfdom_reads_them(text):
    """Any short text as an origin's xyz: accepted exactly when urdfdom accepts it, with the same offset."""
    doc = sub('xyz="0 0 1"', f'xyz="{text}"')
    assert ours(doc) == P.accepts(doc), text
    if ours(doc):
        m = P.model(doc)
        assert_allclose(read_urdf(doc).joints[0].origin[:3, 3], m.jointPlacements[1].translation, atol=0, rtol=0)


def test_undeclared_prefixes_on_a_real_arm_give_the_same_fk():
    """UR5 with attributes and elements in undeclared namespaces everywhere, among them prefixed
    twins of URDF elements (a <drake:origin> before the joint's origin, a <drake:link> that would be
    a second root): the chain and its FK are those of the plain file, and pinocchio agrees."""
    plain = (DATA / 'example-robot-data' / 'ur5_robot.urdf').read_text()
    text = plain.replace('<limit ', '<limit drake:acceleration="2.5" ')
    text = re.sub(r'<(joint|link) name=', r'<\1 gp:note="x" name=', text)
    text = text.replace('<origin ', '<drake:origin xyz="9 9 9" rpy="1 1 1"/><origin ', 1)
    text = text.replace('<robot name="ur5" ', '<robot name="ur5" xmlns="urn:gp" ', 1)
    text = text.replace('</robot>', '<drake:link name="ghost"/><xacro:property name="pi" value="3"/>'
                                    '<drake:joint name="elbow_joint" type="fixed"><parent link="ghost"/>'
                                    '<child link="forearm_link"/></drake:joint></robot>')
    assert text.count('drake:') >= 8 and 'xmlns:drake' not in text and 'xmlns:gp' not in text
    with pytest.raises(ET.ParseError, match='unbound prefix'):
        ET.fromstring(text)
    robot = chain_from_urdf(text, 'base_link', 'tool0')
    reference = chain_from_urdf(plain, 'base_link', 'tool0')
    assert robot.joint_names == reference.joint_names
    qs = np.random.default_rng(5).uniform(reference.lower, reference.upper, size=(30, 6))
    assert_allclose(robot.fk(qs), reference.fk(qs), atol=0, rtol=0)
    assert np.array_equal(robot.lower, reference.lower) and np.array_equal(robot.max_velocity, reference.max_velocity)
    assert max(P.errors(robot, P.model(text), qs)) <= 1e-12


def test_gazebo_transmission_and_ros2_control_blocks_are_ignored():
    """Blocks whose children share names with the chain's joints and links change nothing."""
    blocks = ('<gazebo reference="b"><material>Gazebo/Grey</material><joint name="j" type="fixed"/></gazebo>'
              '<gazebo><plugin name="p" filename="libp.so"><link name="c"/></plugin></gazebo>'
              '<transmission name="tr"><type>transmission_interface/SimpleTransmission</type>'
              '<joint name="j"><hardwareInterface>PositionJointInterface</hardwareInterface></joint>'
              '<actuator name="m"><mechanicalReduction>100</mechanicalReduction></actuator></transmission>'
              '<ros2_control name="sys" type="system"><hardware><plugin>mock/GenericSystem</plugin></hardware>'
              '<joint name="j"><command_interface name="position"><param name="min">-9</param>'
              '</command_interface><state_interface name="position"/></joint></ros2_control>')
    robot = chain_from_urdf(sub('</robot>', blocks + '</robot>'))
    assert robot.joint_names == ['j'] and (robot.lower[0], robot.upper[0]) == (-1.0, 1.0)
    for q in (-0.7, 0.2, 1.0):   # by hand: up 1 m, turn q about z, 1 m along x
        assert_allclose(robot.fk(np.array([q])), U.xyz_rpy((0, 0, 1), (0, 0, q)) @ U.xyz_rpy((1, 0, 0), (0, 0, 0)),
                        atol=1e-15)
