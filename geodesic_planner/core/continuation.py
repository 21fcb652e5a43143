"""Following the tool's straight line + slerp by continuation: how far, and why not further.

The geodesic of the paper's metric between two poses is the line + slerp pulled back to joint
space whenever that pull-back is one smooth branch (docs/maths.md, section 3). The planner's fast
route finds that branch from a coarse mesh of IK seeds; where the seeds straddle a fold of the IK
map it misses the branch. :func:`follow_line` then walks the line from the start configuration in
small steps, each one Gauss-Newton IK seeded from the previous configuration (extrapolated with
the last joint velocity), halving the step where a step does not converge exactly or moves a
joint by more than :data:`MAX_JOINT_STEP` or faster than :data:`MAX_JOINT_RATE`. The result
either reaches the goal pose (its samples seed the fast route again: one branch, no joint jump)
or stops, and then says why and where:

* a singularity: the joints would have to flip (the step shrinks to :data:`MIN_STEP` with the
  Jacobian's smallest singular value below :data:`SINGULAR_RATIO` of its largest);
* a joint limit: the branch crosses a joint's position limit (found with unclamped IK);
* otherwise the next pose cannot be reached from the branch (outside the workspace).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .errors import LineUnreachableError, PathFollowError
from .ik import gauss_newton_batch
from .kinematics import Chain
from .limits import line_limit_error
from .pullback import EXACT_GUESS_RESIDUAL
from .transforms import line_slerp

#: First step, fraction of the line.
INITIAL_STEP = 1.0 / 32.0
#: Largest step, fraction of the line.
MAX_STEP = 1.0 / 16.0
#: Smallest step before the line is declared not followable, fraction of the line.
MIN_STEP = 1e-4
#: Largest joint change in one step, rad (or m): more means a jump to another branch.
MAX_JOINT_STEP = 0.1
#: Largest joint rate along the line, rad (or m) per whole line: near a singularity the rates
#: grow without bound (the joints flip); a line that a joint needs more than this for is not
#: followed. Ordinary moves need a few rad per line at most.
MAX_JOINT_RATE = 50.0
#: Points per step at which the joints are checked against their limits.
LIMIT_CHECKS = 8
#: Smallest singular value of the geometric Jacobian, relative to its largest, under which a
#: stop is reported as a singularity.
SINGULAR_RATIO = 1e-2

#: A tool path other than the line: s (m,) -> poses (m, 4, 4) and tool velocities dp/ds (m, 3),
#: base frame, m (its orientation the slerp from the start, e.g. CIRC's arc).
TaskPath = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class LineFollow:
    """How far the line + slerp can be followed from the start joints.

    Attributes:
        s: fractions of the line reached, increasing from 0, shape (k,).
        q: joints at those fractions, shape (k, dof), rad or m.
        fraction: the largest fraction followed (1.0: the whole line).
        error: why it stops (None when the whole line is followed): a
            :class:`~.errors.PathFollowError` (also a LimitError or IKError where that fits).
    """

    s: np.ndarray
    q: np.ndarray
    fraction: float
    error: PathFollowError | None

    def seeds(self, s: np.ndarray) -> np.ndarray:
        """Joints at fractions ``s`` (m,), piecewise linear between the samples: (m, dof)."""
        return np.stack([np.interp(s, self.s, self.q[:, j]) for j in range(self.q.shape[1])], axis=1)


def follow_line(robot: Chain, q_a: np.ndarray, T_a: np.ndarray, T_b: np.ndarray, w_body: np.ndarray,
                *, position_weight: float = 1.0, orientation_weight: float = 1.0,
                task: TaskPath | None = None, name: str = 'the straight line') -> LineFollow:
    """Follow the line + slerp from ``T_a`` (= FK of ``q_a``) to ``T_b`` by continuation.

    Args:
        robot: the arm.
        q_a: start joints (dof,), on the line's first pose.
        T_a, T_b: base->tool transforms of the two ends (m).
        w_body: ``so3_log(R_aᵀ R_b)`` (rad, start frame): the slerp's rotation vector.
        position_weight, orientation_weight: the metric's weights (as the IK of the planner).
        task: another tool path from ``T_a`` (its orientation the slerp of ``w_body``) instead of
            the line + slerp to ``T_b``; ``name``: the path in the messages.
    Returns:
        The samples reached and, where the line cannot be followed to its end, the reason.
    """
    s_done, q_done = [0.0], [np.array(q_a, dtype=float)]
    s, q = 0.0, q_done[0]
    v: np.ndarray | None = None
    task = task or _line(T_a, T_b, w_body)
    rate = _rate(robot, q, T_a[:3, :3], task(np.zeros(1))[1][0], w_body)
    ds = INITIAL_STEP
    while s < 1.0:
        checkpoint()
        ds = min(ds, 1.0 - s)
        target, dp = task(np.array([s + ds]))
        seed = q if v is None else q + v * ds
        q_new, res, _, _ = gauss_newton_batch(
            robot, target, seed[None], position_weight=position_weight,
            orientation_weight=orientation_weight, max_iterations=8,
            residual_tol=0.1 * EXACT_GUESS_RESIDUAL, within_limits=False)
        q_new = q_new[0]
        step = np.abs(q_new - q)
        if (np.isfinite(res[0]) and res[0] < EXACT_GUESS_RESIDUAL
                and step.max() <= min(MAX_JOINT_STEP, MAX_JOINT_RATE * ds)):
            rate_new = _rate(robot, q_new, target[0, :3, :3], dp[0], w_body)
            crossing = _limit_crossing(robot, q, q_new, rate, rate_new, s, ds)
            if crossing is not None:
                return LineFollow(np.array(s_done), np.array(q_done), crossing[0],
                                  _limit_error(robot, q, crossing, task, name))
            v = (q_new - q) / ds
            s, q, rate = s + ds, q_new, rate_new
            s_done.append(s)
            q_done.append(q)
            ds = min(2.0 * ds, MAX_STEP)
            continue
        ds *= 0.5
        if ds < MIN_STEP:
            return LineFollow(np.array(s_done), np.array(q_done), s, _stop_error(robot, q, s, name))
    s_done[-1] = 1.0
    return LineFollow(np.array(s_done), np.array(q_done), 1.0, None)


def _line(T_a: np.ndarray, T_b: np.ndarray, w_body: np.ndarray) -> TaskPath:
    """The line + slerp from T_a to T_b as a :data:`TaskPath`."""
    dp = T_b[:3, 3] - T_a[:3, 3]
    return lambda s: (line_slerp(T_a, T_b, s, w_body), np.broadcast_to(dp, (s.size, 3)))


def _rate(robot: Chain, q: np.ndarray, R: np.ndarray, dp: np.ndarray, w_body: np.ndarray) -> np.ndarray:
    """Joint velocity at q along the line, per unit of the line's parameter: least squares of the
    geometric Jacobian against the line's twist (tool velocity ``dp`` = p_b - p_a, angular
    velocity ``R w_body`` in the base frame, ``R`` the tool's rotation at q)."""
    return np.linalg.lstsq(robot.jacobian(q), np.concatenate([dp, R @ w_body]), rcond=None)[0]


def _limit_crossing(robot: Chain, q: np.ndarray, q_new: np.ndarray, rate: np.ndarray, rate_new: np.ndarray,
                    s: float, ds: float) -> tuple[float, int] | None:
    """(fraction, joint) where the step from q to q_new first leaves a position limit, or None.

    The joints between the two samples are the cubic Hermite interpolant of their positions and
    rates (error O(ds⁴)), checked at LIMIT_CHECKS points: an excursion past a limit and back
    within one step is found too.
    """
    u = np.linspace(0.0, 1.0, LIMIT_CHECKS + 1)[1:, None]
    h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
    path = h00 * q + h10 * ds * rate + h01 * q_new + h11 * ds * rate_new      # (checks, dof)
    path[-1] = q_new
    out = (path < robot.lower) | (path > robot.upper)
    if not np.any(out):
        return None
    k = int(np.argmax(np.any(out, axis=1)))
    j = int(np.argmax(out[k]))
    prev = q if k == 0 else path[k - 1]
    bound = robot.upper[j] if path[k, j] > robot.upper[j] else robot.lower[j]
    t = (bound - prev[j]) / (path[k, j] - prev[j]) if path[k, j] != prev[j] else 1.0
    u0 = 0.0 if k == 0 else float(u[k - 1, 0])
    return s + ds * (u0 + (float(u[k, 0]) - u0) * float(np.clip(t, 0.0, 1.0))), j


def _where(robot: Chain, q: np.ndarray) -> str:
    x, y, z = robot.fk(q)[:3, 3]
    return f'tool at {x:.4f}, {y:.4f}, {z:.4f} m'


def _percent(fraction: float) -> str:
    return f'{100.0 * fraction:.3g} %'


def _limit_error(robot: Chain, q: np.ndarray, crossing: tuple[float, int], task: TaskPath,
                 name: str) -> PathFollowError:
    fraction, j = crossing
    bound = robot.upper[j] if q[j] + 1e-12 >= 0.5 * (robot.lower[j] + robot.upper[j]) else robot.lower[j]
    return line_limit_error(robot, j, float(bound), fraction, task(np.array([fraction]))[0][0, :3, 3], name)


def _stop_error(robot: Chain, q: np.ndarray, fraction: float, name: str) -> PathFollowError:
    sv = np.linalg.svd(robot.jacobian(q), compute_uv=False)
    smallest, largest = float(sv[-1]), float(sv[0])
    if smallest < SINGULAR_RATIO * largest:
        return PathFollowError(
            f'{name} passes through a singularity of robot {robot.name!r} at '
            f'{_percent(fraction)} of the way ({_where(robot, q)}; smallest singular value '
            f'{smallest:.2g}): the joints would have to flip; followable fraction {fraction:.4f}',
            fraction=fraction)
    return LineUnreachableError(
        f'{name} cannot be followed by robot {robot.name!r} beyond {_percent(fraction)} '
        f'of the way ({_where(robot, q)}): no configuration near the start\'s branch reaches the '
        f'next pose; followable fraction {fraction:.4f}', fraction=fraction)
