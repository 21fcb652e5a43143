"""Serial chains from URDF (root link to tip link, fixed joints folded in, limits read).

Supported joint types: revolute, continuous (revolute without position limits), prismatic, fixed.
Anything else on the chain (floating, planar, mimic joints) is rejected with a clear error.

Reading is bounded for any input: at most :data:`MAX_URDF_BYTES` of text and :data:`MAX_ELEMENTS`
links and joints, no DOCTYPE (so no entity expansion), and the link graph is checked to be a tree
(no link with two parents, no cycle) before it is walked.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from .errors import QUOTE_LIMIT, KinematicsError, quoted
from .kinematics import DEFAULT_MAX_ACCELERATION, DEFAULT_MAX_VELOCITY, PRISMATIC, REVOLUTE, Chain, Joint

#: Largest URDF accepted, bytes of text (real robot descriptions are well under 1 MB).
MAX_URDF_BYTES = 10_000_000
#: Largest number of links plus joints accepted.
MAX_ELEMENTS = 20_000


#: Names listed in a message before the rest is only counted.
NAMES_SHOWN = 5


def _names(names: list[str]) -> str:
    """Up to NAMES_SHOWN names, each cut to the quote limit, then how many more (bounded messages)."""
    shown = ', '.join(quoted(n) for n in names[:NAMES_SHOWN])
    more = f', ... ({len(names) - NAMES_SHOWN} more)' if len(names) > NAMES_SHOWN else ''
    return f'[{shown}{more}]'


def _floats(text: str | None, n: int, default: list[float], what: str) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        vals = [float(x) for x in text.split()]
    except ValueError as err:
        raise KinematicsError(f'URDF: {what}: not numbers: {quoted(text)}') from err
    if len(vals) != n or not np.all(np.isfinite(vals)):
        raise KinematicsError(f'URDF: {what}: expected {n} finite numbers, got {quoted(text)}')
    return np.array(vals)


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


def _check_acyclic(joints_by_child: dict[str, ET.Element]) -> None:
    """Every link reaches a root by walking up parent joints (each link has at most one parent).

    Raises:
        KinematicsError: naming a link on a cycle.
    """
    state: dict[str, int] = {}  # 1: on the current walk, 2: known to reach a root
    for start in joints_by_child:
        walk = []
        link: str | None = start
        while link is not None and state.get(link) != 2:
            if state.get(link) == 1:
                raise KinematicsError(f'URDF: the links form a cycle through {quoted(link)} (a URDF must be a tree)')
            state[link] = 1
            walk.append(link)
            joint = joints_by_child.get(link)
            link = joint.find('parent').get('link') if joint is not None else None  # type: ignore[union-attr]
        for visited in walk:
            state[visited] = 2


def chain_from_urdf(xml: str, base_link: str | None = None, tip_link: str | None = None,
                    name: str | None = None) -> Chain:
    """Chain from URDF text (e.g. the robot_description parameter).

    Args:
        xml: URDF document.
        base_link: chain root (default: the tree's root link).
        tip_link: chain tip (default: the single leaf link; required if the tree branches).
        name: model name (default: the robot element's name).
    Raises:
        KinematicsError: malformed XML, no path base->tip, a branching tree without tip_link,
            unsupported joint types on the chain, missing limits on a revolute/prismatic joint.
    """
    if not isinstance(xml, str):
        raise KinematicsError(f'URDF: expected text, got {type(xml).__name__}')
    if len(xml) > MAX_URDF_BYTES:
        raise KinematicsError(f'URDF: {len(xml)} characters, more than the {MAX_URDF_BYTES} accepted')
    if '<!DOCTYPE' in xml or '<!ENTITY' in xml:
        raise KinematicsError('URDF: a DOCTYPE or entity declaration is not accepted')
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as err:
        raise KinematicsError(f'URDF: not valid XML ({err})') from err
    if root.tag != 'robot':
        raise KinematicsError(f'URDF: root element is <{root.tag[:QUOTE_LIMIT]}>, expected <robot>')
    model = name or root.get('name') or 'urdf_robot'
    n_elements = len(root.findall('link')) + len(root.findall('joint'))
    if n_elements > MAX_ELEMENTS:
        raise KinematicsError(f'URDF: {n_elements} links and joints, more than the {MAX_ELEMENTS} accepted')
    links = [lk.get('name') for lk in root.findall('link')]
    joints_by_child: dict[str, ET.Element] = {}
    parents: dict[str, str] = {}
    children: dict[str, list[str]] = {lk: [] for lk in links if lk}
    for j in root.findall('joint'):
        parent = j.find('parent')
        child = j.find('child')
        p = None if parent is None else parent.get('link')
        c = None if child is None else child.get('link')
        if not p or not c:
            raise KinematicsError(f'URDF: joint {j.get("name")!r} lacks a parent or child link')
        if c in joints_by_child:
            raise KinematicsError(f'URDF: link {quoted(c)} has two parent joints (not a tree)')
        joints_by_child[c] = j
        parents[c] = p
        children.setdefault(p, []).append(c)
        children.setdefault(c, [])
    _check_acyclic(joints_by_child)
    roots = [lk for lk in children if lk not in joints_by_child]
    if base_link is None:
        if len(roots) != 1:
            raise KinematicsError(f'URDF: the links are not connected: expected one root link, found '
                                  f'{len(roots)}: {_names(roots)}; set base_link')
        base_link = roots[0]
    if base_link not in children:
        raise KinematicsError(f'URDF: base_link {quoted(base_link)} is not a link of {quoted(model)}')
    if tip_link is None:
        # Follow the tree down from base_link; it must not branch.
        link = base_link
        while children[link]:
            if len(children[link]) > 1:
                raise KinematicsError(
                    f'URDF: not a serial chain: link {quoted(link)} has {len(children[link])} children '
                    f'{_names(children[link])}; set tip_link')
            link = children[link][0]
        tip_link = link
    if tip_link not in children:
        raise KinematicsError(f'URDF: tip_link {quoted(tip_link)} is not a link of {quoted(model)}')
    # Walk up from tip to base.
    path = []
    link = tip_link
    while link != base_link:
        found = joints_by_child.get(link)
        if found is None:
            raise KinematicsError(f'URDF: tip_link {quoted(tip_link)} is not below base_link {quoted(base_link)}')
        path.append(found)
        link = parents[link]
    path.reverse()
    fixed = [np.eye(4)]
    joints: list[Joint] = []
    for j in path:
        jname = j.get('name', '?')
        jtype = j.get('type', '')
        org = j.find('origin')
        T = origin_transform(
            _floats(org.get('xyz') if org is not None else None, 3, [0, 0, 0], f'joint {quoted(jname)} origin xyz'),
            _floats(org.get('rpy') if org is not None else None, 3, [0, 0, 0], f'joint {quoted(jname)} origin rpy'))
        fixed[-1] = fixed[-1] @ T
        if jtype == 'fixed':
            continue
        if jtype not in ('revolute', 'continuous', 'prismatic'):
            raise KinematicsError(f'URDF: joint {quoted(jname)} has unsupported type {quoted(jtype)} '
                                  '(supported: revolute, continuous, prismatic, fixed)')
        if j.find('mimic') is not None:
            raise KinematicsError(f'URDF: joint {quoted(jname)} is a mimic joint (unsupported)')
        ax = j.find('axis')
        axis = _floats(ax.get('xyz') if ax is not None else None, 3, [1, 0, 0], f'joint {quoted(jname)} axis')
        lim = j.find('limit')
        lower, upper, vel = -np.inf, np.inf, DEFAULT_MAX_VELOCITY
        if lim is not None:
            try:
                if jtype != 'continuous':
                    lower = float(lim.get('lower', 0.0))
                    upper = float(lim.get('upper', 0.0))
                v = float(lim.get('velocity', DEFAULT_MAX_VELOCITY))
            except ValueError as err:
                raise KinematicsError(f'URDF: joint {quoted(jname)}: bad <limit> ({quoted(err)})') from err
            if not (np.isfinite(v) and (jtype == 'continuous' or (np.isfinite(lower) and np.isfinite(upper)))):
                raise KinematicsError(f'URDF: joint {quoted(jname)}: <limit> values must be finite '
                                      f'(lower {lower:g}, upper {upper:g}, velocity {v:g})')
            vel = v if v > 0 else DEFAULT_MAX_VELOCITY
        elif jtype != 'continuous':
            raise KinematicsError(f'URDF: joint {quoted(jname)} ({jtype}) needs a <limit> element')
        lower, upper = _soft_limits(j.find('safety_controller'), jname, lower, upper)
        kind = PRISMATIC if jtype == 'prismatic' else REVOLUTE
        joints.append(Joint(jname, kind, axis, lower, upper, vel, DEFAULT_MAX_ACCELERATION))
        fixed.append(np.eye(4))
    if not joints:
        raise KinematicsError(f'URDF: no actuated joint between {quoted(base_link)} and {quoted(tip_link)}')
    chain = Chain(model, joints, fixed, base_link=base_link, tip_link=tip_link)
    return Chain(model, joints, fixed, base_link=base_link, tip_link=tip_link, home=regular_home(chain))


def _soft_limits(safety: ET.Element | None, jname: str, lower: float, upper: float) -> tuple[float, float]:
    """Position limits narrowed to a ``<safety_controller>``'s soft limits, as ros2_control does.

    The soft limits are where the controller starts pushing back, so a plan must stay inside them.
    """
    if safety is None:
        return lower, upper
    try:
        soft_lower = float(safety.get('soft_lower_limit', '-inf'))
        soft_upper = float(safety.get('soft_upper_limit', 'inf'))
    except ValueError as err:
        raise KinematicsError(f'URDF: joint {quoted(jname)}: bad <safety_controller> ({quoted(err)})') from err
    if np.isnan(soft_lower) or np.isnan(soft_upper):
        raise KinematicsError(f'URDF: joint {quoted(jname)}: <safety_controller> soft limits must not be NaN')
    lo, hi = max(lower, soft_lower), min(upper, soft_upper)
    if not lo < hi:
        raise KinematicsError(f'URDF: joint {quoted(jname)}: soft limits [{soft_lower:g}, {soft_upper:g}] leave no '
                              f'room inside the limits [{lower:g}, {upper:g}]')
    return lo, hi


def regular_home(chain: Chain) -> np.ndarray:
    """A default IK seed away from singularities: the zero pose (clipped into the limits) if the
    tool Jacobian is well conditioned there, else the best of a few fixed bent poses.

    URDF zero poses are often singular (arm stretched straight up), and an IK seeded there picks
    a near-singular branch.
    """
    lo, hi = chain.lower, chain.upper
    finite = np.isfinite(lo) & np.isfinite(hi)
    mid = np.where(finite, 0.5 * (np.where(finite, lo, 0.0) + np.where(finite, hi, 0.0)), 0.0)
    bend = np.where(np.arange(chain.dof) % 2 == 0, 0.4, -0.6)
    candidates = [np.zeros(chain.dof), bend, -bend, mid, mid + bend, mid - bend]
    margin = np.where(finite, 1e-3 * (np.where(finite, hi, 0.0) - np.where(finite, lo, 0.0)), 0.0)
    candidates = [np.clip(c, lo + margin, hi - margin) for c in candidates]
    k = min(chain.dof, 6)
    sv = np.linalg.svd(chain.jacobian12(np.array(candidates)), compute_uv=False)[:, :k]
    quality = sv[:, -1] / sv[:, 0]
    if quality[0] > 0.05:
        return candidates[0]
    return candidates[int(np.argmax(quality))]
