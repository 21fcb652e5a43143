"""Joint position limits of a plan's ends and of its path, and the refusal that says where.

A path that is the line + slerp pulled back (methods 'pullback', 'redundant' and 'trace') and leaves a
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
#: Points checked between two mesh nodes, besides the turning points (check_path_limits).
BETWEEN = 7
#: Bisections of a turning point's bracket (its place to 2**-TURN_BISECTIONS of the bracket).
TURN_BISECTIONS = 30
#: Methods whose paths are the line + slerp itself.
LINE_METHODS = ('pullback', 'redundant', 'trace')


def check_joint_limits(robot: Chain, q: np.ndarray, what: str) -> None:
    """Raise LimitError if joint positions q (dof,) lie outside the robot's limits."""
    bad = np.nonzero((q < robot.lower - LIMIT_SLACK) | (q > robot.upper + LIMIT_SLACK))[0]
    if bad.size:
        i = int(bad[0])
        raise LimitError(f'{what}: joint {robot.joint_names[i]!r} = {q[i]:.6g} is outside its limits '
                         f'[{robot.lower[i]:.6g}, {robot.upper[i]:.6g}]')


def check_path_limits(robot: Chain, path: GeodesicPath) -> None:
    """Raise LimitError (LineLimitError for a line path) if the path leaves the position limits.

    Checked at the mesh nodes, at :data:`BETWEEN` points between each pair of nodes, and at each
    joint's turning points near a limit: where its velocity changes sign between two samples and
    the joint could reach a limit in between (``h |q'|`` from the nearer sample), the turning point
    is found by bisection on the sign of q' and checked too. A geodesic that ends on a limit may
    overshoot it between the last two nodes by micro-radians before turning back (found by the fuzz
    tests); a sampled check alone misses that.
    """
    nodes = path.s_nodes
    between = nodes[:-1, None] + np.diff(nodes)[:, None] * (np.arange(1, BETWEEN + 1) / (BETWEEN + 1))
    s = np.sort(np.concatenate([nodes, between.ravel()]))
    q, dq = path.evaluate(s, order=1)
    lo, hi = robot.lower - LIMIT_SLACK, robot.upper + LIMIT_SLACK
    turns = _turning_points(path, s, q, dq, lo, hi)
    if turns is not None:
        s, q = np.concatenate([s, turns[0]]), np.concatenate([q, turns[1]])
    out = (q < lo) | (q > hi)
    if not np.any(out):
        return
    order = np.argsort(s, kind='stable')
    k = int(order[np.argmax(np.any(out[order], axis=1))])      # the first place out
    i = int(np.argmax(out[k]))
    bound = float(robot.upper[i] if q[k, i] > robot.upper[i] else robot.lower[i])
    if path.solver.method in LINE_METHODS:
        raise line_limit_error(robot, i, bound, float(s[k]), robot.fk(q[k])[:3, 3])
    raise LimitError(f'the geodesic leaves the joint limits: joint {robot.joint_names[i]!r} reaches '
                     f'{q[k, i]:.6g} at s = {s[k]:.3f} (limits [{robot.lower[i]:.6g}, {robot.upper[i]:.6g}])')


def _turning_points(path: GeodesicPath, s: np.ndarray, q: np.ndarray, dq: np.ndarray, lo: np.ndarray,
                    hi: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The places (M,) and positions (M, dof) of the joints' turning points between samples ``s``
    that may lie beyond a limit (a minimum near ``lo`` or a maximum near ``hi``), or None."""
    h = np.diff(s)[:, None]
    reach = h * np.maximum(np.abs(dq[:-1]), np.abs(dq[1:]))       # how far q may go in between
    minimum = (dq[:-1] < 0.0) & (dq[1:] > 0.0) & (np.minimum(q[:-1], q[1:]) - reach < lo)
    maximum = (dq[:-1] > 0.0) & (dq[1:] < 0.0) & (np.maximum(q[:-1], q[1:]) + reach > hi)
    k, j = np.nonzero(minimum | maximum)
    if not k.size:
        return None
    a, b = s[k], s[k + 1]
    rising = dq[k, j] < 0.0           # a minimum: q' goes from - to +
    for _ in range(TURN_BISECTIONS):
        m = 0.5 * (a + b)
        d = path.evaluate(m, order=1)[1][np.arange(k.size), j]
        left = (d < 0.0) == rising    # the turning point lies right of m
        a, b = np.where(left, m, a), np.where(left, b, m)
    m = 0.5 * (a + b)
    return m, path.evaluate(m, order=0)[0]


def line_limit_error(robot: Chain, joint: int, bound: float, fraction: float, point: np.ndarray,
                     name: str = 'the straight line') -> LineLimitError:
    """The refusal of a line (or of the path ``name``) whose branch passes joint ``joint``'s limit
    ``bound`` at ``fraction`` of the way, with the tool at ``point`` (base frame, m)."""
    x, y, z = point
    return LineLimitError(
        f'{name} cannot be followed by robot {robot.name!r}: joint '
        f'{robot.joint_names[joint]!r} would pass its limit {bound:.6g} at {100.0 * fraction:.3g} % of '
        f'the way (tool at {x:.4f}, {y:.4f}, {z:.4f} m); followable fraction {fraction:.4f}',
        fraction=fraction)
