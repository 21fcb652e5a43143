"""Joint position limits of a plan's ends and of its path, and the refusal that says where.

A path that is the line + slerp pulled back (methods 'pullback' and 'redundant') and leaves a
limit cannot follow the line: the refusal is a :class:`~.errors.LineLimitError` with the place
and the followable fraction, worded as the continuation words it (``core/continuation.py``).
Any other path (a collocation geodesic) leaving the limits is a plain LimitError.
"""
from __future__ import annotations

import numpy as np

from .errors import LimitError, LineLimitError
from .geodesic import GeodesicPath
from .kinematics import Chain

#: Joint positions may exceed their limits by this much (round-off), rad or m.
LIMIT_SLACK = 1e-9
#: Methods whose paths are the line + slerp itself.
LINE_METHODS = ('pullback', 'redundant')


def check_joint_limits(robot: Chain, q: np.ndarray, what: str) -> None:
    """Raise LimitError if joint positions q (dof,) lie outside the robot's limits."""
    bad = np.nonzero((q < robot.lower - LIMIT_SLACK) | (q > robot.upper + LIMIT_SLACK))[0]
    if bad.size:
        i = int(bad[0])
        raise LimitError(f'{what}: joint {robot.joint_names[i]!r} = {q[i]:.6g} is outside its limits '
                         f'[{robot.lower[i]:.6g}, {robot.upper[i]:.6g}]')


def check_path_limits(robot: Chain, path: GeodesicPath) -> None:
    """Raise LimitError (LineLimitError for a line path) if the path leaves the position limits:
    checked at the mesh nodes and 3 points between each pair of nodes."""
    nodes = path.s_nodes
    between = nodes[:-1, None] + np.diff(nodes)[:, None] * np.array([0.25, 0.5, 0.75])
    s = np.concatenate([nodes, between.ravel()])
    q = path.evaluate(s, order=0)[0]
    out = (q < robot.lower - LIMIT_SLACK) | (q > robot.upper + LIMIT_SLACK)
    if not np.any(out):
        return
    order = np.argsort(s)
    k = int(order[np.argmax(np.any(out[order], axis=1))])      # the first place out
    i = int(np.argmax(out[k]))
    bound = float(robot.upper[i] if q[k, i] > robot.upper[i] else robot.lower[i])
    if path.solver.method in LINE_METHODS:
        raise line_limit_error(robot, i, bound, float(s[k]), robot.fk(q[k])[:3, 3])
    raise LimitError(f'the geodesic leaves the joint limits: joint {robot.joint_names[i]!r} reaches '
                     f'{q[k, i]:.6g} at s = {s[k]:.3f} (limits [{robot.lower[i]:.6g}, {robot.upper[i]:.6g}])')


def line_limit_error(robot: Chain, joint: int, bound: float, fraction: float, point: np.ndarray) -> LineLimitError:
    """The refusal of a line whose branch passes joint ``joint``'s limit ``bound`` at ``fraction``
    of the way, with the tool at ``point`` (base frame, m)."""
    x, y, z = point
    return LineLimitError(
        f'the straight line cannot be followed by robot {robot.name!r}: joint '
        f'{robot.joint_names[joint]!r} would pass its limit {bound:.6g} at {100.0 * fraction:.3g} % of '
        f'the way (tool at {x:.4f}, {y:.4f}, {z:.4f} m); followable fraction {fraction:.4f}',
        fraction=fraction)
