"""URDF documents read as urdfdom reads them (robot_state_publisher, MoveIt and pinocchio use it).

urdfdom parses with tinyxml2, which does no namespace processing, so this reader takes every XML
name as written:

- an attribute in a namespace, declared or not (``<limit drake:acceleration="2.5" .../>``), is read
  and ignored; an element whose name has a prefix (``<xacro:property>``, ``<drake:joint>``) is not a
  URDF element and is ignored, as is every element other than ``link``, ``joint`` and ``material``
  directly under ``<robot>`` (``gazebo``, ``transmission``, ``ros2_control``, ...);
- numbers are read as urdfdom reads them: decimal, an optional sign and exponent, leading blanks
  only; ``nan``, ``inf``, ``0x1``, ``1_0`` and a trailing blank are refused; vectors are
  numbers separated by spaces;
- refused as urdfdom refuses them: a root element other than ``robot``, a robot without a name or
  with a version other than 1.0-1.2, two materials, links or joints of one name, a joint without
  a name or type, of an unknown type, whose parent or child link is missing or undeclared, a
  revolute or prismatic joint without ``<limit>``, a ``<limit>`` without effort or velocity, a
  ``<safety_controller>`` without k_velocity, a ``<mimic>`` without joint, a ``<dynamics>`` with
  neither damping nor friction, a bad number in any of them or in an origin or axis, two root links.
  A link's own content (visual, collision, inertial) never makes urdfdom refuse a document.

Stricter than urdfdom, so that reading is bounded for any input: at most :data:`MAX_URDF_BYTES`
characters, :data:`MAX_XML_ELEMENTS` XML elements and :data:`MAX_ELEMENTS` links and joints; no
DOCTYPE (so no entity expansion); well-formed XML only (tinyxml2 also takes, e.g., a second
top-level element); the link graph must be a tree (no link with two parents, no cycle, even in a
part that the root does not reach).
"""
from __future__ import annotations

import html
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from xml.parsers import expat

import numpy as np

from .errors import QUOTE_LIMIT, KinematicsError, quoted

#: Largest URDF accepted, characters (real robot descriptions are well under 1 MB).
MAX_URDF_BYTES = 10_000_000
#: Largest number of links plus joints accepted.
MAX_ELEMENTS = 20_000
#: Largest number of XML elements accepted (real URDFs have a few thousand).
MAX_XML_ELEMENTS = 500_000
#: Elements more levels below ``<robot>`` than this are counted but not kept (robot/joint/limit: 2).
KEEP_DEPTH = 2
#: Names listed in a message before the rest is only counted.
NAMES_SHOWN = 5
#: Joint types urdfdom knows.
JOINT_TYPES = ('revolute', 'continuous', 'prismatic', 'fixed', 'floating', 'planar')
#: URDF versions urdfdom 4-6 accept (``version="major.minor"``, default 1.0).
VERSIONS = ((1, 0), (1, 1), (1, 2))

# What C++ ``std::istream >> double`` reads to the end of the text (urdfdom's strToDouble).
_NUMBER = re.compile(r'[ \t\n\v\f\r]*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?')
# What C ``strtol`` reads to the end of the text (a version field).
_INTEGER = re.compile(r'[ \t\n\v\f\r]*[+-]?\d+')
# A start tag and its attributes, in the document's UTF-8 bytes.
_START_TAG = re.compile(rb'<[^\s/>]+((?:\s+[^\s=/>]+\s*=\s*(?:"[^"]*"|\'[^\']*\'))*)\s*/?>')
_ATTRIBUTE = re.compile(rb'([^\s=]+)\s*=\s*(?:"([^"]*)"|\'([^\']*)\')')
_BLANKS = (b'\t', b'\n', b'\r')


@dataclass(frozen=True)
class UrdfJoint:
    """One ``<joint>`` as urdfdom reads it.

    Attributes:
        name, type: joint name and type (one of :data:`JOINT_TYPES`).
        parent, child: link names.
        origin: parent link -> joint frame, 4x4 (m).
        axis: joint axis in the joint frame (3,), as written (not normalised); (1, 0, 0) by default.
        limit: (lower, upper, velocity) of ``<limit>`` (rad or m, rad/s or m/s), or None.
        soft: (soft_lower_limit, soft_upper_limit) of ``<safety_controller>`` (missing ones are 0,
            as urdfdom reads them), or None.
        mimic: (followed joint, multiplier, offset) of ``<mimic>``, or None.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    limit: tuple[float, float, float] | None
    soft: tuple[float, float] | None
    mimic: tuple[str, float, float] | None


@dataclass(frozen=True)
class UrdfModel:
    """A URDF document checked to be a tree (the links, their joints, the root link).

    Attributes:
        name: the robot element's name.
        links: link names in document order.
        joints: joints in document order.
        parent_joint: child link name -> the joint above it.
        children: link name -> child link names.
        root: the one link without a parent joint.
    """

    name: str
    links: tuple[str, ...]
    joints: tuple[UrdfJoint, ...]
    parent_joint: dict[str, UrdfJoint]
    children: dict[str, list[str]]
    root: str


def names_list(names: list[str]) -> str:
    """Up to NAMES_SHOWN names, each cut to the quote limit, then how many more (bounded messages)."""
    shown = ', '.join(quoted(n) for n in names[:NAMES_SHOWN])
    more = f', ... ({len(names) - NAMES_SHOWN} more)' if len(names) > NAMES_SHOWN else ''
    return f'[{shown}{more}]'


def origin_transform(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    """4x4 transform of a URDF <origin xyz rpy> (fixed-axis roll, pitch, yaw: R = Rz(y) Ry(p) Rx(r))."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    R = np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = xyz
    return T


def parse_number(text: str) -> float:
    """A number as urdfdom reads it (C++ ``istream >> double`` that must reach the end).

    Raises:
        ValueError: anything else, NaN, inf and overflow included.
    """
    if not _NUMBER.fullmatch(text):
        raise ValueError(text)
    value = float(text)
    if not np.isfinite(value):
        raise ValueError(text)
    return value


def _number(el: ET.Element, attr: str, default: float | None, where: str) -> float:
    """Attribute ``attr`` of ``el`` read as a number; ``default`` when it is missing (None: required)."""
    text = el.get(attr)
    if text is None:
        if default is None:
            raise KinematicsError(f'URDF: {where}: <{el.tag}> has no {attr} (urdfdom requires it)')
        return default
    try:
        return parse_number(text)
    except ValueError:
        raise KinematicsError(f'URDF: {where}: bad <{el.tag}>: {attr} = {quoted(text)} (values must be finite '
                              'decimal numbers, not NaN or inf)') from None


def _vector(text: str | None, default: tuple[float, float, float], what: str) -> np.ndarray:
    """Three numbers separated by spaces (urdfdom's Vector3), or ``default`` when ``text`` is None."""
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = [parse_number(piece) for piece in text.split(' ') if piece]
    except ValueError:
        raise KinematicsError(f'URDF: {what}: not numbers: {quoted(text)}') from None
    if len(values) != 3:
        raise KinematicsError(f'URDF: {what}: expected 3 finite numbers, got {quoted(text)}')
    return np.array(values)


def _read_xml(xml: str) -> ET.Element:
    """The document's root element, names as written (no namespace processing, like tinyxml2).

    Raises:
        KinematicsError: not text, too long, a DOCTYPE, too many elements, not well-formed XML.
    """
    if not isinstance(xml, str):
        raise KinematicsError(f'URDF: expected text, got {type(xml).__name__}')
    if len(xml) > MAX_URDF_BYTES:
        raise KinematicsError(f'URDF: {len(xml)} characters, more than the {MAX_URDF_BYTES} accepted')
    refusal = 'URDF: a DOCTYPE or entity declaration is not accepted'
    if '<!DOCTYPE' in xml or '<!ENTITY' in xml:
        raise KinematicsError(refusal)
    try:
        data = xml.encode('utf-8')
    except UnicodeEncodeError as err:
        raise KinematicsError(f'URDF: not valid XML ({err.reason} at character {err.start})') from err
    parser = expat.ParserCreate('utf-8')  # no namespace separator: names as written
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list[ET.Element | None] = []
    top: list[ET.Element] = []
    count = 0

    def start(name: str, attrs: dict[str, str]) -> None:
        nonlocal count
        count += 1
        if count > MAX_XML_ELEMENTS:
            raise KinematicsError(f'URDF: more than the {MAX_XML_ELEMENTS} XML elements accepted')
        if len(stack) > KEEP_DEPTH:
            stack.append(None)
            return
        if attrs:
            _restore_blanks(data, parser.CurrentByteIndex, attrs)
        el = ET.Element(name, attrs)
        parent = stack[-1] if stack else None
        if parent is None:
            top.append(el)
        else:
            parent.append(el)
        stack.append(el)

    def refuse(*_: object) -> None:
        raise KinematicsError(refusal)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda _name: stack.pop()
    parser.StartDoctypeDeclHandler = refuse
    parser.EntityDeclHandler = refuse
    try:
        parser.Parse(data, True)
    except expat.ExpatError as err:
        raise KinematicsError(f'URDF: not valid XML ({err})') from err
    return top[0]


def _restore_blanks(data: bytes, start: int, attrs: dict[str, str]) -> None:
    """Put back the tabs and line breaks that XML's attribute-value normalisation made spaces.

    expat turns them into spaces; tinyxml2, and so urdfdom, keeps them, and then ``xyz="0<tab>0 1"``
    or ``xyz="0 0 1<newline>"`` is no vector. ``start``: the byte index of the start tag in ``data``.
    """
    tag = _START_TAG.match(data, start)
    if tag is None or not any(c in tag.group(1) for c in _BLANKS):
        return
    for m in _ATTRIBUTE.finditer(tag.group(1)):
        raw = m.group(2) if m.group(2) is not None else m.group(3)
        if any(c in raw for c in _BLANKS):
            text = raw.decode('utf-8').replace('\r\n', '\n').replace('\r', '\n')
            attrs[m.group(1).decode('utf-8')] = html.unescape(text)


def _joint(j: ET.Element, links: set[str], model: str) -> UrdfJoint:
    """One ``<joint>`` read and checked as urdfdom's parseJoint and initTree do."""
    name = j.get('name')
    if name is None:
        raise KinematicsError('URDF: a <joint> has no name')
    where = f'joint {quoted(name)}'
    org = j.find('origin')
    origin = origin_transform(
        _vector(None if org is None else org.get('xyz'), (0.0, 0.0, 0.0), f'{where} origin xyz'),
        _vector(None if org is None else org.get('rpy'), (0.0, 0.0, 0.0), f'{where} origin rpy'))
    ends = []
    for role in ('parent', 'child'):
        el = j.find(role)
        ends.append('' if el is None else el.get('link', ''))
    jtype = j.get('type')
    if jtype is None:
        raise KinematicsError(f'URDF: {where} has no type')
    if jtype not in JOINT_TYPES:
        raise KinematicsError(f'URDF: {where} has unsupported type {quoted(jtype)} (urdfdom knows '
                              f'{", ".join(JOINT_TYPES)})')
    axis = np.array([1.0, 0.0, 0.0])
    ax = j.find('axis')
    if ax is not None and jtype not in ('fixed', 'floating'):
        axis = _vector(ax.get('xyz'), (0.0, 0.0, 0.0), f'{where} axis')
    lim, limit = j.find('limit'), None
    if lim is not None:
        limit = (_number(lim, 'lower', 0.0, where), _number(lim, 'upper', 0.0, where),
                 _number(lim, 'velocity', None, where))
        _number(lim, 'effort', None, where)
    elif jtype in ('revolute', 'prismatic'):
        raise KinematicsError(f'URDF: {where} ({jtype}) needs a <limit> element')
    safety, soft = j.find('safety_controller'), None
    if safety is not None:
        soft = (_number(safety, 'soft_lower_limit', 0.0, where), _number(safety, 'soft_upper_limit', 0.0, where))
        _number(safety, 'k_position', 0.0, where)
        _number(safety, 'k_velocity', None, where)
    calibration = j.find('calibration')
    if calibration is not None:
        _number(calibration, 'rising', 0.0, where)
        _number(calibration, 'falling', 0.0, where)
    mim, mimic = j.find('mimic'), None
    if mim is not None:
        if mim.get('joint') is None:
            raise KinematicsError(f'URDF: {where}: <mimic> names no joint (urdfdom requires it)')
        mimic = (mim.get('joint', ''), _number(mim, 'multiplier', 1.0, where), _number(mim, 'offset', 0.0, where))
    dyn = j.find('dynamics')
    if dyn is not None:
        if dyn.get('damping') is None and dyn.get('friction') is None:
            raise KinematicsError(f'URDF: {where}: <dynamics> has neither damping nor friction')
        _number(dyn, 'damping', 0.0, where)
        _number(dyn, 'friction', 0.0, where)
    if not ends[0] or not ends[1]:
        raise KinematicsError(f'URDF: {where} lacks a parent or child link')
    for role, link in zip(('parent', 'child'), ends):
        if link not in links:
            raise KinematicsError(f'URDF: {where}: {role} link {quoted(link)} is not a link of {quoted(model)}')
    return UrdfJoint(name, jtype, ends[0], ends[1], origin, axis, limit, soft, mimic)


def _check_acyclic(parent_of: dict[str, str]) -> None:
    """Every link reaches a root by walking up parent joints (each link has at most one parent).

    Raises:
        KinematicsError: naming a link on a cycle.
    """
    state: dict[str, int] = {}  # 1: on the current walk, 2: known to reach a root
    for start in parent_of:
        walk = []
        link: str | None = start
        while link is not None and state.get(link) != 2:
            if state.get(link) == 1:
                raise KinematicsError(f'URDF: the links form a cycle through {quoted(link)} (a URDF must be a tree)')
            state[link] = 1
            walk.append(link)
            link = parent_of.get(link)
        for visited in walk:
            state[visited] = 2


def _unique(names: list[str], what: str) -> None:
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise KinematicsError(f'URDF: two {what}s named {quoted(n)} (urdfdom requires unique names)')
        seen.add(n)


def read_urdf(xml: str) -> UrdfModel:
    """Read and check a URDF document as urdfdom does (see the module docstring), bounded.

    Args:
        xml: URDF text (e.g. the robot_description parameter).
    Raises:
        KinematicsError: naming the first cause of refusal.
    """
    root = _read_xml(xml)
    if root.tag != 'robot':
        raise KinematicsError(f'URDF: root element is <{root.tag[:QUOTE_LIMIT]}>, expected <robot>')
    name = root.get('name')
    if name is None:
        raise KinematicsError('URDF: the <robot> element has no name (urdfdom requires one)')
    _check_version(root.get('version'))
    _unique([m.get('name', '') for m in root.findall('material')], 'material')
    link_els, joint_els = root.findall('link'), root.findall('joint')
    n_elements = len(link_els) + len(joint_els)
    if n_elements > MAX_ELEMENTS:
        raise KinematicsError(f'URDF: {n_elements} links and joints, more than the {MAX_ELEMENTS} accepted')
    links = [lk.get('name') for lk in link_els]
    if any(lk is None for lk in links):
        raise KinematicsError('URDF: a <link> has no name')
    link_names = [str(lk) for lk in links]
    _unique(link_names, 'link')
    if not link_names:
        raise KinematicsError(f'URDF: {quoted(name)} has no <link>')
    link_set = set(link_names)
    joints = [_joint(j, link_set, name) for j in joint_els]
    _unique([j.name for j in joints], 'joint')
    parent_joint: dict[str, UrdfJoint] = {}
    children: dict[str, list[str]] = {lk: [] for lk in link_names}
    for j in joints:
        if j.child in parent_joint:
            raise KinematicsError(f'URDF: link {quoted(j.child)} has two parent joints (not a tree)')
        parent_joint[j.child] = j
        children[j.parent].append(j.child)
    _check_acyclic({c: j.parent for c, j in parent_joint.items()})
    roots = [lk for lk in link_names if lk not in parent_joint]
    if len(roots) != 1:
        raise KinematicsError(f'URDF: the links are not connected: expected one root link, found {len(roots)}: '
                              f'{names_list(roots)} (urdfdom refuses more than one root)')
    return UrdfModel(name, tuple(link_names), tuple(joints), parent_joint, children, roots[0])


def _check_version(version: str | None) -> None:
    """``version="major.minor"`` with a version urdfdom supports (none given: 1.0)."""
    if version is None:
        return
    fields = version.split('.')
    if len(fields) != 2 or not all(_INTEGER.fullmatch(f) for f in fields):
        raise KinematicsError(f"URDF: version {quoted(version)} is not of the form 'x.y'")
    if (int(fields[0]), int(fields[1])) not in VERSIONS:
        raise KinematicsError(f'URDF: version {quoted(version)}: urdfdom reads versions 1.0 to 1.2')
