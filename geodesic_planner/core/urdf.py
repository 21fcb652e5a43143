"""Serial chains from URDF (base link to tip link, fixed joints folded in, limits read).

The document is read as urdfdom reads it, by :mod:`.urdf_xml` (namespaces, ``gazebo``,
``transmission`` and ``ros2_control`` blocks, mimic fingers, bounded reading of hostile text: see
there). On the chain from base to tip:

- revolute, continuous (revolute without position limits) and prismatic joints become the chain's
  joints; fixed joints, anywhere, are folded into the fixed transforms between them;
- a mimic joint (q = multiplier * q_followed + offset) moves with another joint, which a chain of
  independent joints cannot represent: it is refused with the reason, unless its multiplier is 0
  (it then stays at its offset and is folded in like a fixed joint). Mimic joints off the chain
  (gripper fingers) are ignored;
- floating and planar joints are refused;
- position limits are narrowed to a ``<safety_controller>``'s soft limits, as MoveIt and
  ros2_control read them (a missing soft limit is 0, as urdfdom reads it).
"""
from __future__ import annotations

import difflib

import numpy as np

from .errors import KinematicsError, quoted
from .kinematics import DEFAULT_MAX_ACCELERATION, DEFAULT_MAX_VELOCITY, PRISMATIC, REVOLUTE, Chain, Joint
from .urdf_xml import (
    MAX_ELEMENTS,
    MAX_URDF_BYTES,
    MAX_XML_ELEMENTS,
    UrdfJoint,
    UrdfModel,
    names_list,
    origin_transform,
    read_urdf,
)

__all__ = ['MAX_ELEMENTS', 'MAX_URDF_BYTES', 'MAX_XML_ELEMENTS', 'chain_from_urdf', 'origin_transform', 'read_urdf',
           'regular_home']


def chain_from_urdf(xml: str, base_link: str | None = None, tip_link: str | None = None,
                    name: str | None = None) -> Chain:
    """Chain from URDF text (e.g. the robot_description parameter).

    Args:
        xml: URDF document.
        base_link: chain root (default: the tree's root link).
        tip_link: chain tip (default: the single leaf link; required if the tree branches).
        name: model name (default: the robot element's name).
    Raises:
        KinematicsError: a document urdfdom refuses (or one too large or not a tree), no path
            base->tip, a branching tree without tip_link, a joint on the chain that a chain of
            independent revolute and prismatic joints cannot represent.
    """
    urdf = read_urdf(xml)
    model = name or urdf.name
    base_link = urdf.root if base_link is None else base_link
    if base_link not in urdf.children:
        bases = candidate_links(urdf, urdf.root, base_link, tips=False)
        raise KinematicsError(f'URDF: base_link {quoted(base_link)} is not a link of {quoted(model)}; '
                              f'candidate base links: {names_list(bases)}')
    if tip_link is None:
        tip_link = _single_leaf(urdf, base_link)
    if tip_link not in urdf.children:
        raise KinematicsError(f'URDF: tip_link {quoted(tip_link)} is not a link of {quoted(model)}; '
                              f'{_tips_below(urdf, base_link, tip_link)}')
    path = _path(urdf, base_link, tip_link)
    on_chain = {j.name for j in path}
    fixed = [np.eye(4)]
    joints: list[Joint] = []
    for j in path:
        fixed[-1] = fixed[-1] @ j.origin
        if j.type == 'fixed':
            continue
        if j.type not in ('revolute', 'continuous', 'prismatic'):
            raise KinematicsError(f'URDF: joint {quoted(j.name)} has unsupported type {quoted(j.type)} '
                                  '(supported: revolute, continuous, prismatic, fixed)')
        if j.mimic is not None:
            fixed[-1] = fixed[-1] @ _mimic_at_rest(j, on_chain, base_link, tip_link)
            continue
        joints.append(_joint(j))
        fixed.append(np.eye(4))
    if not joints:
        raise KinematicsError(f'URDF: no actuated joint between {quoted(base_link)} and {quoted(tip_link)}')
    chain = Chain(model, joints, fixed, base_link=base_link, tip_link=tip_link)
    return Chain(model, joints, fixed, base_link=base_link, tip_link=tip_link, home=regular_home(chain))


def _single_leaf(urdf: UrdfModel, base_link: str) -> str:
    """The leaf below ``base_link`` when the tree does not branch there."""
    link = base_link
    while urdf.children[link]:
        below = urdf.children[link]
        if len(below) > 1:
            raise KinematicsError(f'URDF: not a serial chain: link {quoted(link)} has {len(below)} children '
                                  f'{names_list(below)}; set tip_link')
        link = below[0]
    return link


def candidate_links(urdf: UrdfModel, top: str, wanted: str, *, tips: bool = True) -> list[str]:
    """The links at and below ``top`` that a wrong link name ``wanted`` may have meant: the closest
    names first (:func:`difflib.get_close_matches`), then (``tips``) the leaf links, the usual
    tips, then the rest in tree order (breadth first, ``top`` first)."""
    below = [top]
    for link in below:                  # grows while it is read: breadth first
        below.extend(urdf.children[link])
    close = difflib.get_close_matches(wanted, below, n=len(below), cutoff=0.6)
    taken = set(close)
    leaves = [link for link in below if tips and not urdf.children[link] and link not in taken]
    taken.update(leaves)
    return close + leaves + [link for link in below if link not in taken]


def _tips_below(urdf: UrdfModel, base_link: str, tip_link: str) -> str:
    """The candidate tip links below ``base_link``, for a message."""
    found = [link for link in candidate_links(urdf, base_link, tip_link) if link != base_link]
    if not found:
        return f'base_link {quoted(base_link)} has no link below it'
    return f'candidate tip links below base_link {quoted(base_link)}: {names_list(found)}'


def _path(urdf: UrdfModel, base_link: str, tip_link: str) -> list[UrdfJoint]:
    """The joints from ``base_link`` down to ``tip_link``."""
    path = []
    link = tip_link
    while link != base_link:
        found = urdf.parent_joint.get(link)
        if found is None:
            raise KinematicsError(f'URDF: tip_link {quoted(tip_link)} is not below base_link {quoted(base_link)}; '
                                  f'{_tips_below(urdf, base_link, tip_link)}')
        path.append(found)
        link = found.parent
    path.reverse()
    return path


def _mimic_at_rest(j: UrdfJoint, on_chain: set[str], base_link: str, tip_link: str) -> np.ndarray:
    """The motion of a mimic joint with multiplier 0 (it stays at its offset), else a refusal."""
    followed, multiplier, offset = j.mimic or ('', 1.0, 0.0)
    if multiplier != 0.0:
        where = 'on the chain' if followed in on_chain else 'not on the chain'
        raise KinematicsError(
            f'URDF: joint {quoted(j.name)} is a mimic joint on the chain from {quoted(base_link)} to '
            f'{quoted(tip_link)}: it moves with joint {quoted(followed)} ({where}) as '
            f'{multiplier:g} * q + {offset:g}, which a chain of independent joints cannot represent; '
            'choose a tip_link before it')
    axis = j.axis / np.linalg.norm(j.axis) if np.linalg.norm(j.axis) > 1e-9 else j.axis
    M = np.eye(4)
    if j.type == 'prismatic':
        M[:3, 3] = offset * axis
    else:
        K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        M[:3, :3] += np.sin(offset) * K + (1.0 - np.cos(offset)) * (K @ K)
    return M


def _joint(j: UrdfJoint) -> Joint:
    """The chain joint of a revolute, continuous or prismatic URDF joint, with its limits."""
    lower, upper, vel = -np.inf, np.inf, DEFAULT_MAX_VELOCITY
    if j.limit is not None:
        if j.type != 'continuous':
            lower, upper = j.limit[0], j.limit[1]
        vel = j.limit[2] if j.limit[2] > 0 else DEFAULT_MAX_VELOCITY
    if j.soft is not None and j.type != 'continuous':
        lower, upper = _soft_limits(j.soft, j.name, lower, upper)
    kind = PRISMATIC if j.type == 'prismatic' else REVOLUTE
    return Joint(j.name, kind, j.axis, lower, upper, vel, DEFAULT_MAX_ACCELERATION)


def _soft_limits(soft: tuple[float, float], jname: str, lower: float, upper: float) -> tuple[float, float]:
    """Position limits narrowed to a ``<safety_controller>``'s soft limits, as MoveIt and ros2_control do.

    The soft limits are where the controller starts pushing back, so a plan must stay inside them.
    """
    lo, hi = max(lower, soft[0]), min(upper, soft[1])
    if not lo < hi:
        raise KinematicsError(f'URDF: joint {quoted(jname)}: soft limits [{soft[0]:g}, {soft[1]:g}] leave no '
                              f'room inside the limits [{lower:g}, {upper:g}] (a soft limit not given is 0, '
                              'as urdfdom, MoveIt and ros2_control read it)')
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
