"""URDF chains: a DH chain written as URDF (fixed joints folded in, rpy origins, re-oriented joint
axes, prismatic and continuous joints, base offset, tool) has the DH chain's FK; limits are read;
the example URDFs under geodesic_planner/data match their DH tables; continuous and fixed joints
inside a chain and mimic joints match hand-computed transforms and pinocchio; errors name their cause."""
from __future__ import annotations

import os
import re

import numpy as np
import pin_oracle
import pytest
import urdf_util as U
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from geodesic_planner import load_robot
from geodesic_planner.core.errors import KinematicsError, RequestError
from geodesic_planner.core.urdf import chain_from_urdf

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # test/
DATA = os.path.join(os.path.dirname(HERE), 'geodesic_planner', 'data')
BRANCHING = os.path.join(HERE, 'data', 'branching.urdf')
PI = np.pi

UR5E_DH = [(0.0, 0.1625, 0.0, PI / 2), (0.0, 0.0, -0.425, 0.0), (0.0, 0.0, -0.3922, 0.0),
           (0.0, 0.1333, 0.0, PI / 2), (0.0, 0.0997, 0.0, -PI / 2), (0.0, 0.0996, 0.0, 0.0)]
STANFORD_DH = [(0.0, 0.412, 0.0, -PI / 2), (0.0, 0.154, 0.0, PI / 2), (-PI / 2, 0.1, 0.0, 0.0),
               (0.0, 0.0, 0.0, -PI / 2), (0.0, 0.0, 0.0, PI / 2), (0.0, 0.263, 0.0, 0.0)]
STANFORD_KINDS = ['revolute', 'revolute', 'prismatic', 'revolute', 'revolute', 'revolute']
# modified DH with two prismatic joints and angle offsets (RRPP-like, plus a wrist)
MDH = [(0.0, 0.0, 0.3, 0.2), (0.9553, 1.0, 0.0, -0.4), (0.0, 0.0, 0.1, 0.0), (-PI / 2, 1.0, 0.2, PI),
       (PI / 2, 0.05, 0.1, 0.3)]
MDH_KINDS = ['revolute', 'revolute', 'prismatic', 'prismatic', 'revolute']


def read(path: str) -> str:
    with open(path, encoding='utf-8') as fh:
        return fh.read()


def check_fk(robot, rows, kinds, rng, *, modified=False, base=None, tool=None, n=12):
    for q in rng.uniform(-1.5, 1.5, size=(n, len(rows))):
        assert_allclose(robot.fk(q), U.dh_product(rows, kinds, q, modified=modified, base=base, tool=tool),
                        atol=1e-13)


# ---------------------------------------------------------------------- DH chains written as URDF
def test_ur5e_as_urdf_with_base_offset_and_tool_matches_dh():
    base = U.xyz_rpy((0.5, -0.25, 0.75), (0.2, -0.1, 2.0))
    tool = U.xyz_rpy((0.0, 0.0, 0.15), (0.0, PI / 2, 0.0))
    xml = U.dh_to_urdf('ur5e_urdf', UR5E_DH, ['revolute'] * 6, base=base, tool=tool, split=(0, 2, 4))
    robot = chain_from_urdf(xml)
    assert robot.dof == 6  # the fixed joints (base, DH splits, tool) are folded in
    assert robot.joint_names == [f'joint{i}' for i in range(1, 7)]
    assert (robot.base_link, robot.tip_link) == ('world', 'tool0')
    check_fk(robot, UR5E_DH, ['revolute'] * 6, np.random.default_rng(1), base=base, tool=tool)


@pytest.mark.parametrize('twist_seed', [3, 4, 5])
def test_standard_dh_with_prismatic_and_continuous_and_reoriented_axes(twist_seed):
    """Joint frames re-oriented by random rotations: general rpy origins and non-z axes."""
    base = U.xyz_rpy((0.1, 0.2, 0.3), (0.3, -0.2, 1.0))
    tool = U.xyz_rpy((0.01, 0.0, 0.1), (0.0, 0.5, 0.0))
    xml = U.dh_to_urdf('mixed', STANFORD_DH, STANFORD_KINDS, continuous=(0, 5), split=(1, 3),
                       twist_seed=twist_seed, base=base, tool=tool,
                       lower=[-2.0, -1.5, -0.2, -3.0, -2.5, -9.0], upper=[2.0, 1.5, 0.7, 3.0, 2.5, 9.0],
                       velocity=[1.0, 2.0, 0.3, 4.0, 5.0, 6.0])
    assert 'type="continuous"' in xml and 'type="prismatic"' in xml
    robot = chain_from_urdf(xml)
    assert robot.joint_types == tuple(STANFORD_KINDS)
    check_fk(robot, STANFORD_DH, STANFORD_KINDS, np.random.default_rng(twist_seed), base=base, tool=tool)
    # limits: continuous joints are unlimited in position; the others are read from <limit>
    assert_allclose(robot.lower, [-np.inf, -1.5, -0.2, -3.0, -2.5, -np.inf])
    assert_allclose(robot.upper, [np.inf, 1.5, 0.7, 3.0, 2.5, np.inf])
    assert_allclose(robot.max_velocity, [1.0, 2.0, 0.3, 4.0, 5.0, 6.0])
    assert np.all(robot.max_acceleration > 0)


def test_modified_dh_with_two_prismatic_joints_as_urdf():
    base = U.xyz_rpy((-0.2, 0.0, 0.4), (PI, 0.0, 0.3))
    tool = U.xyz_rpy((0.0, 0.0, 1.0), (PI, 0.0, -PI / 2))
    xml = U.dh_to_urdf('mdh', MDH, MDH_KINDS, modified=True, base=base, tool=tool, split=(0, 3),
                       twist_seed=11)
    robot = chain_from_urdf(xml)
    check_fk(robot, MDH, MDH_KINDS, np.random.default_rng(2), modified=True, base=base, tool=tool)


def test_axis_is_normalised_and_sign_matters():
    xml = U.dh_to_urdf('one', [(0.0, 0.1, 0.5, 0.0)], ['revolute'])
    r1 = chain_from_urdf(xml)
    r2 = chain_from_urdf(xml.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 2.5"/>'))
    r3 = chain_from_urdf(xml.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 -1"/>'))
    q = np.array([0.7])
    assert_allclose(r2.fk(q), r1.fk(q), atol=1e-15)
    assert_allclose(r3.fk(q), r1.fk(-q), atol=1e-15)


def test_continuous_joint_without_limit_element():
    xml = ('<robot name="r"><link name="a"/><link name="b"/>'
           '<joint name="j" type="continuous"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/></joint></robot>')
    robot = chain_from_urdf(xml)
    assert robot.lower[0] == -np.inf and robot.upper[0] == np.inf
    assert robot.max_velocity[0] > 0 and robot.max_acceleration[0] > 0
    assert_allclose(robot.fk(np.array([0.3])), U.rz(0.3), atol=1e-15)


def test_default_axis_is_x():
    """URDF spec: a joint without <axis> rotates about x of its frame."""
    xml = ('<robot name="r"><link name="a"/><link name="b"/><link name="c"/>'
           '<joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
           '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
           '<joint name="t" type="fixed"><parent link="b"/><child link="c"/><origin xyz="0 1 0"/></joint></robot>')
    T = chain_from_urdf(xml).fk(np.array([0.5]))
    assert_allclose(T[:3, 3], [0.0, np.cos(0.5), np.sin(0.5)], atol=1e-15)
    assert_allclose(T[:3, :3], U.rx(0.5)[:3, :3], atol=1e-15)


def test_sub_chain_between_named_links_composes():
    """fk(world -> tool) = fk(world -> link3) · fk(link3 -> tool) with the joints split accordingly."""
    xml = read(os.path.join(DATA, 'kr6_like.urdf'))
    full = chain_from_urdf(xml)
    upper = chain_from_urdf(xml, tip_link='link3')
    lower = chain_from_urdf(xml, base_link='link3')
    assert upper.joint_names == full.joint_names[:3] and lower.joint_names == full.joint_names[3:]
    for q in np.random.default_rng(3).uniform(-1, 1, size=(5, 6)):
        assert_allclose(full.fk(q), upper.fk(q[:3]) @ lower.fk(q[3:]), atol=1e-14)


# ---------------------------------------------------------------------- example URDF files
@pytest.mark.parametrize('key', list(U.EXAMPLE_ARMS))
def test_example_urdf_files_match_their_dh_tables(key):
    spec = U.EXAMPLE_ARMS[key]
    path = os.path.join(DATA, f'{key}.urdf')
    robot = load_robot(path)
    assert robot.name == key
    assert robot.joint_names == spec['joint_names']
    assert (robot.base_link, robot.tip_link) == (spec['root_link'], spec['tip_link'])
    assert_allclose(robot.lower, spec['lower'], rtol=1e-14)
    assert_allclose(robot.upper, spec['upper'], rtol=1e-14)
    assert_allclose(robot.max_velocity, spec['velocity'], rtol=1e-14)
    assert robot.within_limits(robot.home)
    xml = read(path)
    assert xml.count('type="fixed"') >= 3 and 'rpy="0 0 0"' in xml
    rng = np.random.default_rng(4)
    for q in rng.uniform(robot.lower, robot.upper, size=(10, robot.dof)):
        assert_allclose(robot.fk(q), U.arm_fk(spec, q), atol=1e-14)
    # the base offset is really there: at q = 0 the first joint axis passes through the base origin
    assert_allclose(robot.fk(np.zeros(robot.dof)), U.arm_fk(spec, np.zeros(robot.dof)), atol=1e-14)
    assert not np.allclose(spec['base'], np.eye(4))
    # the string API (robot_description) gives the same chain
    assert_allclose(chain_from_urdf(xml).fk(q), robot.fk(q), atol=0)


# ---------------------------------------------------------------------- trees, tip links, errors
def test_branching_tree_needs_tip_link():
    with pytest.raises(KinematicsError, match=r"not a serial chain: link 'base' has 2 children"):
        load_robot(BRANCHING)
    with pytest.raises(KinematicsError, match='set tip_link'):
        chain_from_urdf(read(BRANCHING), base_link='link1')


def test_branching_tree_left_branch_by_hand():
    robot = load_robot(BRANCHING, tip_link='left_tool')
    assert robot.joint_names == ['j1', 'j_left']
    assert_allclose(robot.max_velocity, [2.0, 1.5])
    for q1, q2 in np.random.default_rng(5).uniform(-2, 2, size=(8, 2)):
        T = robot.fk(np.array([q1, q2]))
        assert_allclose(T[:3, 3], [0.5 * np.cos(q1) + 0.3 * np.cos(q1 + q2),
                                   0.5 * np.sin(q1) + 0.3 * np.sin(q1 + q2), 1.0], atol=1e-15)
        assert_allclose(T[:3, :3], U.rz(q1 + q2)[:3, :3], atol=1e-15)


def test_branching_tree_right_branch_prismatic_by_hand():
    robot = load_robot(BRANCHING, tip_link='right_link')
    assert robot.joint_types == ('revolute', 'prismatic')
    assert_allclose([robot.lower[1], robot.upper[1], robot.max_velocity[1]], [-0.1, 0.4, 0.25])
    for q1, d in [(0.3, 0.1), (-1.2, 0.35), (2.0, -0.05)]:
        T = robot.fk(np.array([q1, d]))
        assert_allclose(T[:3, 3], [-(0.2 + d) * np.sin(q1), (0.2 + d) * np.cos(q1), 1.0], atol=1e-15)


def test_mimic_joint_on_the_chain_is_rejected():
    with pytest.raises(KinematicsError, match=r"joint 'right_finger_joint' is a mimic joint on the chain from 'base' "
                                              r"to 'right_finger': it moves with joint 'j_right' \(on the chain\) as "
                                              r"2 \* q \+ 0, which a chain of independent joints cannot represent"):
        load_robot(BRANCHING, tip_link='right_finger')


# ------------------------------------------------------------- mimic, continuous and fixed joints (pinocchio)
#: base -(j1 revolute z, 0.4 up)- l1 -(fix1: 0.3 along x, rpy)- l2 -(j2 continuous y)- l3 -(fix2)- l4
#: -(j3 prismatic x)- l5 -(tool fixed)- tool; a two-finger gripper hangs from l5, finger_b mimics finger_a.
ARM = """<robot name="mixed">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/><link name="l5"/>
  <link name="tool"/><link name="finger_a"/><link name="finger_b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="1.5"/></joint>
  <joint name="fix1" type="fixed"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="0.3 -0.2 0.5"/></joint>
  <joint name="j2" type="continuous"><parent link="l2"/><child link="l3"/><axis xyz="0 1 0"/></joint>
  <joint name="fix2" type="fixed"><parent link="l3"/><child link="l4"/><origin xyz="0 0 0.25" rpy="0 1.2 0"/></joint>
  <joint name="j3" type="prismatic"><parent link="l4"/><child link="l5"/><origin xyz="0.1 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.3" effort="1" velocity="0.2"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l5"/><child link="tool"/><origin xyz="0 0 0.05"/></joint>
  <joint name="finger_a_joint" type="prismatic"><parent link="l5"/><child link="finger_a"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="0.1"/></joint>
  <joint name="finger_b_joint" type="prismatic"><parent link="l5"/><child link="finger_b"/>
    <axis xyz="0 -1 0"/><limit lower="0" upper="0.04" effort="1" velocity="0.1"/>
    <mimic joint="finger_a_joint" multiplier="1" offset="0"/></joint>
</robot>"""


def hand_fk(q):
    """ARM's base -> tool, multiplied out by hand."""
    return (U.tr(0, 0, 0.4) @ U.rz(q[0]) @ U.xyz_rpy((0.3, 0, 0), (0.3, -0.2, 0.5)) @ U.ry(q[1])
            @ U.xyz_rpy((0, 0, 0.25), (0, 1.2, 0)) @ U.tr(0.1, 0, 0) @ U.tr(q[2], 0, 0) @ U.tr(0, 0, 0.05))


def test_continuous_and_fixed_joints_inside_the_chain_and_a_mimic_finger_off_it():
    robot = chain_from_urdf(ARM, tip_link='tool')
    assert robot.joint_names == ['j1', 'j2', 'j3'] and robot.joint_types == ('revolute', 'revolute', 'prismatic')
    assert_allclose(robot.lower, [-2, -np.inf, 0]) and assert_allclose(robot.upper, [2, np.inf, 0.3])
    qs = np.random.default_rng(8).uniform([-2, -7, 0], [2, 7, 0.3], size=(25, 3))
    for q in qs:
        assert_allclose(robot.fk(q), hand_fk(q), atol=1e-15)
    assert max(pin_oracle.errors(robot, pin_oracle.model(ARM), qs)) <= 1e-12
    # the mimic finger may even follow a joint that does not exist (urdfdom does not check): still off the chain
    assert chain_from_urdf(ARM.replace('joint="finger_a_joint"', 'joint="nope"'), tip_link='tool').dof == 3
    finger = chain_from_urdf(ARM, tip_link='finger_a')
    assert finger.joint_names == ['j1', 'j2', 'j3', 'finger_a_joint']


@pytest.mark.parametrize('followed, where', [('finger_a_joint', 'not on the chain'), ('j3', 'on the chain')])
def test_mimic_joint_that_moves_is_refused_on_the_chain(followed, where):
    xml = ARM.replace('joint="finger_a_joint"', f'joint="{followed}"').replace('multiplier="1" offset="0"',
                                                                                'multiplier="-0.5" offset="0.01"')
    with pytest.raises(KinematicsError, match=rf"joint 'finger_b_joint' is a mimic joint on the chain from 'base' to "
                                              rf"'finger_b': it moves with joint '{followed}' \({where}\) as "
                                              r"-0.5 \* q \+ 0.01, .*choose a tip_link before it"):
        chain_from_urdf(xml, tip_link='finger_b')


@pytest.mark.parametrize('kind, axis', [('prismatic', '0 -1 0'), ('revolute', '0.6 0 0.8')])
def test_mimic_joint_with_multiplier_zero_stays_at_its_offset(kind, axis):
    """q_mimic = 0 * q + offset: a fixed joint at the offset, folded in (checked against pinocchio
    with that joint set to the offset)."""
    xml = ARM.replace('multiplier="1" offset="0"', 'multiplier="0" offset="0.03"').replace(
        '<joint name="finger_b_joint" type="prismatic">', f'<joint name="finger_b_joint" type="{kind}">').replace(
        '<axis xyz="0 -1 0"/>', f'<axis xyz="{axis}"/>')
    robot = chain_from_urdf(xml, tip_link='finger_b')
    assert robot.joint_names == ['j1', 'j2', 'j3']
    m = pin_oracle.model(xml)
    for q in np.random.default_rng(9).uniform([-2, -7, 0], [2, 7, 0.3], size=(10, 3)):
        ref = pin_oracle.fk(m, robot.joint_names, q, 'base', 'finger_b', rest={'finger_b_joint': 0.03})
        assert_allclose(robot.fk(q), ref, atol=1e-12)


def test_floating_joint_on_the_chain_is_rejected_but_fine_elsewhere():
    with pytest.raises(KinematicsError, match=r"joint 'camera_mount' has unsupported type 'floating'"):
        load_robot(BRANCHING, tip_link='camera')
    # the floating joint is on another branch: irrelevant to base -> left_tool
    assert load_robot(BRANCHING, tip_link='left_tool').dof == 2


def test_planar_joint_is_rejected():
    xml = read(BRANCHING).replace('type="floating"', 'type="planar"')
    with pytest.raises(KinematicsError, match="unsupported type 'planar'"):
        chain_from_urdf(xml, tip_link='camera')


@pytest.mark.parametrize('kwargs, match', [
    ({'base_link': 'nope', 'tip_link': 'left_tool'}, "base_link 'nope' is not a link of 'two_branch'"),
    ({'tip_link': 'nope'}, "tip_link 'nope' is not a link of 'two_branch'"),
    ({'base_link': 'left_tool', 'tip_link': 'link1'}, "tip_link 'link1' is not below base_link 'left_tool'"),
    ({'base_link': 'left_tip', 'tip_link': 'left_tool'}, "no actuated joint between 'left_tip' and 'left_tool'"),
])
def test_missing_or_misplaced_base_and_tip(kwargs, match):
    with pytest.raises(KinematicsError, match=match):
        chain_from_urdf(read(BRANCHING), **kwargs)


GOOD = ('<robot name="r"><link name="a"/><link name="b"/>'
        '<joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 1" rpy="0 0 0"/>'
        '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')


_MALFORMED = [
    (GOOD.replace('</robot>', ''), 'not valid XML'),
    ('<robot name="r"><link name="a"></robot>', 'not valid XML'),
    (GOOD.replace('<robot name="r">', '<model name="r">').replace('</robot>', '</model>'),
     r'root element is <model>, expected <robot>'),
    (GOOD.replace('<limit lower="-1" upper="1" effort="1" velocity="1"/>', ''),
     r"joint 'j' \(revolute\) needs a <limit>"),
    (GOOD.replace('xyz="0 0 1" rpy', 'xyz="0 1" rpy'), "joint 'j' origin xyz: expected 3 finite numbers"),
    (GOOD.replace('rpy="0 0 0"', 'rpy="a b c"'), "joint 'j' origin rpy: not numbers"),
    (GOOD.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 nan"/>'), "joint 'j' axis: not numbers"),
    (GOOD.replace('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), 'invalid axis'),
    (GOOD.replace('<parent link="a"/>', ''), "joint 'j' lacks a parent or child link"),
    (GOOD.replace('upper="1"', 'upper="x"'), r"joint 'j': bad <limit>"),
    (GOOD.replace('upper="1"', 'upper="-2"'), 'lower limit > upper limit'),
    (GOOD.replace('</robot>', '<link name="c"/></robot>'),
     r"not connected: expected one root link, found 2: \['a', 'c'\]"),
    (GOOD.replace('</robot>', '<link name="c"/><joint name="k" type="fixed"><parent link="c"/>'
                  '<child link="b"/></joint></robot>'), "link 'b' has two parent joints"),
    (GOOD.replace('type="revolute"', 'type="floating"'), "unsupported type 'floating'"),
    (GOOD.replace('type="revolute"', 'type="fixed"'), "no actuated joint between 'a' and 'b'"),
]


@pytest.mark.parametrize('xml, match', _MALFORMED, ids=[f'{i}-{m[:30]}' for i, (_, m) in enumerate(_MALFORMED)])
def test_malformed_urdf_errors(xml, match):
    chain_from_urdf(GOOD)  # the unmodified document is fine
    with pytest.raises(KinematicsError, match=match):
        chain_from_urdf(xml)


def test_load_robot_urdf_file_errors(tmp_path):
    bad = tmp_path / 'bad.urdf'
    bad.write_text('<robot name="x"><link name="a"></robot>')
    with pytest.raises(KinematicsError, match='not valid XML'):
        load_robot(str(bad))
    with pytest.raises(RequestError, match=r"cannot read URDF .*missing\.urdf"):
        load_robot(str(tmp_path / 'missing.urdf'))


@pytest.mark.parametrize('safety, expected', [
    ('<safety_controller soft_lower_limit="-0.5" soft_upper_limit="0.75" k_position="10" k_velocity="1"/>',
     (-0.5, 0.75)),
    ('<safety_controller soft_lower_limit="-2" soft_upper_limit="0.5" k_velocity="1"/>', (-1.0, 0.5)),
    # a soft limit not given is 0, as urdfdom reads it (and MoveIt and ros2_control use it)
    ('<safety_controller soft_lower_limit="-0.25" k_velocity="1"/>', (-0.25, 0.0)),
    ('<safety_controller soft_upper_limit="0.5" k_velocity="1"/>', (0.0, 0.5)),
    ('', (-1.0, 1.0)),
])
def test_safety_controller_soft_limits_narrow_the_position_limits(safety, expected):
    robot = chain_from_urdf(GOOD.replace('</joint>', safety + '</joint>'))
    assert (robot.lower[0], robot.upper[0]) == expected


def test_safety_controller_does_not_bound_a_continuous_joint():
    """MoveIt and ros2_control keep a continuous joint unbounded whatever its safety controller says."""
    xml = GOOD.replace('type="revolute"', 'type="continuous"').replace(
        '</joint>', '<safety_controller soft_lower_limit="-0.5" soft_upper_limit="0.5" k_velocity="1"/></joint>')
    robot = chain_from_urdf(xml)
    assert (robot.lower[0], robot.upper[0]) == (-np.inf, np.inf)


@pytest.mark.parametrize('safety, match', [
    ('<safety_controller soft_lower_limit="0.9" soft_upper_limit="-0.9" k_velocity="1"/>', 'leave no room'),
    ('<safety_controller k_velocity="1"/>', r'soft limits \[0, 0\] leave no room .*a soft limit not given is 0'),
    ('<safety_controller soft_lower_limit="-1" soft_upper_limit="1"/>', 'has no k_velocity'),
    ('<safety_controller soft_lower_limit="abc" k_velocity="1"/>', 'bad <safety_controller>'),
    ('<safety_controller soft_upper_limit="nan" k_velocity="1"/>', 'NaN'),
])
def test_bad_soft_limits_are_refused(safety, match):
    with pytest.raises(KinematicsError, match=match):
        chain_from_urdf(GOOD.replace('</joint>', safety + '</joint>'))


# ---------------------------------------------------------------------------------- hostile sources

def _graph_urdf(edges, extra_links=()):
    """A URDF whose revolute joints connect (parent, child) link pairs."""
    links = sorted({x for e in edges for x in e} | set(extra_links))
    body = ''.join(f'<link name="{lk}"/>' for lk in links)
    body += ''.join(f'<joint name="j{i}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
                    f'<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
                    for i, (p, c) in enumerate(edges))
    return f'<robot name="g">{body}</robot>'


@pytest.mark.timeout(20)
@pytest.mark.parametrize('edges, kwargs', [
    ([('a', 'b'), ('b', 'a')], {}),
    ([('a', 'b'), ('b', 'a')], {'base_link': 'a'}),
    ([('r', 's'), ('a', 'b'), ('b', 'c'), ('c', 'a')], {'base_link': 'r', 'tip_link': 'b'}),
    ([('r', 's'), ('a', 'b'), ('b', 'c'), ('c', 'a')], {'base_link': 'a'}),
    ([('a', 'a')], {}),
])
def test_cycles_are_refused_at_once(edges, kwargs):
    with pytest.raises(KinematicsError, match='cycle'):
        chain_from_urdf(_graph_urdf(edges), **kwargs)


def test_disconnected_tip_is_refused():
    with pytest.raises(KinematicsError, match='not below base_link'):
        chain_from_urdf(_graph_urdf([('a', 'b'), ('a', 'x'), ('x', 'y')]), base_link='b', tip_link='y')
    # two separate trees: urdfdom refuses the document ("Two root links found"), whatever the chain ends
    for kwargs in ({}, {'base_link': 'a', 'tip_link': 'b'}, {'base_link': 'a', 'tip_link': 'y'}):
        with pytest.raises(KinematicsError, match=r"one root link, found 2: \['a', 'x'\]"):
            chain_from_urdf(_graph_urdf([('a', 'b'), ('x', 'y')]), **kwargs)


@settings(max_examples=150, deadline=2000)
@given(parents=st.lists(st.integers(min_value=-1, max_value=11), min_size=1, max_size=12),
       base=st.integers(min_value=0, max_value=11), tip=st.integers(min_value=0, max_value=11))
def test_any_link_graph_gives_a_chain_or_one_clear_error(parents, base, tip):
    """Link i hangs below link parents[i] (-1: none): trees, forests, cycles, self-loops."""
    edges = [(f'l{p}', f'l{i}') for i, p in enumerate(parents) if p >= 0]
    xml = _graph_urdf(edges, extra_links=[f'l{i}' for i in range(len(parents))])
    try:
        chain = chain_from_urdf(xml, base_link=f'l{base}', tip_link=f'l{tip}')
    except KinematicsError as err:
        assert str(err).startswith('URDF: ')
    else:
        assert 1 <= chain.dof <= len(parents)


@pytest.mark.parametrize('xml, match', [
    ('<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">]><robot name="r">&a;</robot>', 'DOCTYPE'),
    ('<robot name="r">' + '<link name="x"/>' * 20_001 + '</robot>', 'more than the 20000'),
    (GOOD.replace('velocity="1"', 'velocity="inf"'), 'must be finite'),
    (GOOD.replace('lower="-1"', 'lower="nan"'), 'must be finite'),
    # half a million elements inside an ignored block: counted and refused, never all kept
    (GOOD.replace('</robot>', '<gazebo>' + '<a/>' * 500_001 + '</gazebo></robot>'),
     'more than the 500000 XML elements'),
], ids=['doctype', 'too-many-elements', 'inf-velocity', 'nan-limit', 'too-many-xml-elements'])
@pytest.mark.timeout(20)
def test_hostile_documents_are_refused(xml, match):
    with pytest.raises(KinematicsError, match=match):
        chain_from_urdf(xml)


def test_deep_nesting_in_an_ignored_block_is_read_without_keeping_it():
    """200 000 nested elements (deeper than any recursion limit): read, not kept, the chain is GOOD's."""
    xml = GOOD.replace('</robot>', '<gazebo>' + '<a>' * 200_000 + '</a>' * 200_000 + '</gazebo></robot>')
    assert_allclose(chain_from_urdf(xml).fk(np.array([0.4])), chain_from_urdf(GOOD).fk(np.array([0.4])), atol=0)


def test_oversized_text_is_refused_before_parsing(monkeypatch):
    import geodesic_planner.core.urdf_xml as urdf_module
    monkeypatch.setattr(urdf_module, 'MAX_URDF_BYTES', 1000)
    with pytest.raises(KinematicsError, match='more than the 1000'):
        chain_from_urdf(GOOD + ' ' * 1000)


@pytest.mark.timeout(20)
def test_model_files_must_be_regular_bounded_utf8(tmp_path):
    fifo = tmp_path / 'arm.urdf'
    os.mkfifo(fifo)                                   # opening it for reading would block
    with pytest.raises(RequestError, match='not a regular file'):
        load_robot(str(fifo))
    with pytest.raises(RequestError, match='not a regular file'):
        load_robot('/dev/zero')                       # endless: never read
    with pytest.raises(RequestError, match='not a regular file'):
        load_robot(str(tmp_path) + os.sep)
    latin = tmp_path / 'latin.urdf'
    latin.write_bytes(GOOD.replace('name="r"', 'name="r\xe9"').encode('latin-1'))
    with pytest.raises(RequestError, match='not UTF-8'):
        load_robot(str(latin))
    good = tmp_path / 'good.urdf'
    good.write_text(GOOD)
    assert load_robot(str(good)).dof == 1


@pytest.mark.parametrize(('xml', 'match'), [
    # 5000 separate links (not connected): the message counts them, it does not list them all
    ('<robot name="r">' + ''.join(f'<link name="l{i}"/>' for i in range(5000)) + '</robot>',
     r"not connected: expected one root link, found 5000: \['l0', 'l1', 'l2', 'l3', 'l4', \.\.\. \(4995 more\)\]"),
    # a cycle through a link with a 100 000-character name
    (_graph_urdf([('x' * 100_000, 'y' * 100_000), ('y' * 100_000, 'x' * 100_000)]),
     r"cycle through '([xy])\1{79}'\.\.\. \(100000 characters\)"),
    # a link with 3000 children
    (_graph_urdf([('a', f'c{i}') for i in range(3000)]), r'has 3000 children \[.*\(2995 more\)\]; set tip_link'),
    # a 100 000-character root tag
    ('<' + 'r' * 100_000 + '/>', r'root element is <r{80}>, expected <robot>'),
], ids=['disconnected', 'long_name_cycle', 'many_children', 'long_root_tag'])
def test_regression_model_errors_are_bounded(xml: str, match: str) -> None:
    """Issue 13 #1/#9: an error about a hostile model names its cause in a bounded message
    (before, the root list, the children list and the names were echoed in full)."""
    with pytest.raises(KinematicsError, match=match) as info:
        chain_from_urdf(xml)
    assert len(str(info.value)) < 1000


# test/data/branching.urdf by hand: the links below 'link1', and every link with the root first
BELOW_LINK1 = {'left_link', 'left_tip', 'left_tool', 'right_link', 'right_finger'}


def _listed(message: str) -> list[str]:
    """The quoted names of a message's last [...] list."""
    return re.findall(r"'([^']*)'", message[message.rindex('['):])


def test_wrong_tip_link_lists_the_candidates_below_base_link():
    with pytest.raises(KinematicsError, match="tip_link 'nope' is not a link of 'two_branch'; candidate tip "
                                              "links below base_link 'link1': ") as err:
        chain_from_urdf(read(BRANCHING), base_link='link1', tip_link='nope')
    listed = _listed(str(err.value))
    assert set(listed) == BELOW_LINK1 and len(listed) == len(BELOW_LINK1)
    assert set(listed[:2]) == {'left_tool', 'right_finger'}          # the leaves (tips) first


def test_misspelt_links_list_the_closest_name_first():
    with pytest.raises(KinematicsError, match="tip_link 'left_tol' is not a link") as err:
        load_robot(BRANCHING, tip_link='left_tol')
    assert _listed(str(err.value))[0] == 'left_tool'
    assert str(err.value).endswith('(2 more)]')                     # 7 links below 'base', 5 shown
    with pytest.raises(KinematicsError, match="base_link 'bse' is not a link of 'two_branch'; candidate base "
                                              "links: ") as err:
        load_robot(BRANCHING, base_link='bse', tip_link='left_tool')
    assert _listed(str(err.value))[0] == 'base'


def test_tip_link_above_base_link_lists_what_is_below():
    with pytest.raises(KinematicsError, match="tip_link 'left_link' is not below base_link 'left_tip'; candidate "
                                              r"tip links below base_link 'left_tip': \['left_tool'\]"):
        chain_from_urdf(read(BRANCHING), base_link='left_tip', tip_link='left_link')
    with pytest.raises(KinematicsError, match="base_link 'left_tool' has no link below it"):
        chain_from_urdf(read(BRANCHING), base_link='left_tool', tip_link='link1')
