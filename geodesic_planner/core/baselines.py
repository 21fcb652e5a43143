"""Baseline planners the geodesic is compared with (paper Table 3, benchmarks).

* :func:`polynomial_path` — the paper's cubic-polynomial method (section "The improved geodesic
  algorithm for a planar 3R robot"): ``n_via`` via points spread uniformly on the straight line
  (position linear, orientation slerp), inverse kinematics at each via point (seeded from the
  previous one), the end-effector velocity held constant and mapped to joint velocities with the
  inverse Jacobian, one cubic Hermite polynomial per joint per segment.
* :func:`cartesian_ik_path` — "Cartesian line + IK at every sample" (what MoveIt's Pilz LIN
  planner does): IK at ``samples`` poses of the line + slerp, joined by a cubic spline.

Both return paths with the same contract as a geodesic path: ``evaluate(s) -> (q, q', q'', q''')``
over s in [0, 1] (derivatives w.r.t. s), ``joint_names``, ``robot``, ``ee_poses(s)`` and
``timed(...)``, plus ``breakpoints`` (the knots, where higher derivatives jump; the time
parameterization reads one-sided derivatives there).
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from .errors import IKError, RequestError
from .kinematics import Chain
from .path import JointPath, check_order, check_s
from .transforms import check_transform, line_slerp, so3_log

#: ``ik(robot, T_target (4, 4), seed (dof,)) -> q (dof,)``.
IKFunction = Callable[[Chain, np.ndarray, np.ndarray], np.ndarray]

#: Default largest accepted IK residual at a via point / sample (weighted embedding distance,
#: m-equivalent). Arms with fewer than 6 joints follow the nearest reachable pose of the line.
DEFAULT_VIA_TOLERANCE = 1e-2


def _default_ik(tolerance: float) -> IKFunction:
    """IK through :func:`geodesic_planner.core.ik.solve_ik`, seeded, no random restarts.

    Restarts are disabled so the branch stays the one the seed leads to; the nearest reachable
    pose is accepted up to ``tolerance`` (arms with fewer than 6 joints).
    """
    def ik(robot: Chain, T: np.ndarray, seed: np.ndarray) -> np.ndarray:
        from .ik import solve_ik
        try:
            sol = solve_ik(robot, T, seed, tolerance=tolerance, restarts=0, raise_on_failure=False)
        except TypeError:  # an older solve_ik without these keywords
            sol = solve_ik(robot, T, seed, tolerance=tolerance)
        if not sol.success:
            raise IKError(f'IK failed at a via point (target position {np.round(T[:3, 3], 6).tolist()} m): '
                          f'{sol.reason}', residual=sol.residual, iterations=sol.iterations)
        return np.asarray(sol.q, dtype=float)
    return ik


def _unwrap(robot: Chain, q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Shift revolute joints of ``q`` by multiples of 2 pi towards ``ref`` when within limits."""
    types = getattr(robot, 'joint_types', None)
    if types is None:
        return q
    out = q.copy()
    lower = np.asarray(getattr(robot, 'lower', np.full(q.size, -np.inf)), dtype=float)
    upper = np.asarray(getattr(robot, 'upper', np.full(q.size, np.inf)), dtype=float)
    for i, kind in enumerate(types):
        if kind != 'revolute':
            continue
        cand = q[i] + 2.0 * np.pi * np.round((ref[i] - q[i]) / (2.0 * np.pi))
        if lower[i] - 1e-9 <= cand <= upper[i] + 1e-9:
            out[i] = cand
    return out


def line_twist(T_start: np.ndarray, T_goal: np.ndarray) -> np.ndarray:
    """Constant end-effector twist of the line + slerp path per unit s, base frame, rows [v; w].

    ``v = p_B - p_A`` (m per unit s); ``w = R_A log(R_A^T R_B)`` (rad per unit s): the slerp
    ``R(s) = R_A exp(s [log(R_A^T R_B)])`` has this constant angular velocity in the base frame.

    Returns:
        (6,) twist.
    """
    v = T_goal[:3, 3] - T_start[:3, 3]
    w = T_start[:3, :3] @ so3_log(T_start[:3, :3].T @ T_goal[:3, :3])
    return np.concatenate([v, w])


class _SplinePath(JointPath):
    """Shared behaviour of the baseline paths: a scipy piecewise polynomial q(s) per joint."""

    _spline: Any

    def evaluate(self, s: npt.ArrayLike, order: int = 3) -> tuple[np.ndarray, ...]:
        """q, dq/ds, d2q/ds2, d3q/ds3 at ``s`` (1-D in [0, 1]); each (len(s), dof); rad or m.

        At a knot the one-sided derivatives of the segment to its right are returned (of the
        last segment at s = 1); the jerk is piecewise constant and jumps at knots. ``order`` < 3
        returns only the first ``order + 1`` arrays.
        """
        s = check_s(s)
        sp = self._spline
        return tuple(sp(s, k) for k in range(check_order(order) + 1))


class PolynomialPath(_SplinePath):
    """The paper's cubic-polynomial baseline: cubic Hermite per joint between via points.

    Attributes:
        robot: the chain.
        s_via: via-point parameters, shape (n_via,), uniform in [0, 1].
        q_via: joint positions at the via points, shape (n_via, dof).
        dq_via: joint velocities w.r.t. s at the via points, shape (n_via, dof).
        twist: the constant end-effector twist per unit s, (6,), base frame [v; w].
        end_velocity: 'constant' (paper) or 'zero'.
    """

    def __init__(self, robot: Chain, s_via: np.ndarray, q_via: np.ndarray, dq_via: np.ndarray,
                 twist: np.ndarray, end_velocity: str) -> None:
        self.robot = robot
        self.s_via = np.asarray(s_via, dtype=float)
        self.q_via = np.asarray(q_via, dtype=float)
        self.dq_via = np.asarray(dq_via, dtype=float)
        self.twist = np.asarray(twist, dtype=float)
        self.end_velocity = end_velocity
        self._spline = CubicHermiteSpline(self.s_via, self.q_via, self.dq_via, axis=0)

    @property
    def breakpoints(self) -> np.ndarray:
        """Knots in s (the via points): q'' and q''' jump there (the path is C1)."""
        return self.s_via

    def coefficients(self) -> np.ndarray:
        """Cubic coefficients per segment and joint, local variable ``u = s - s_k``.

        Returns:
            (n_via - 1, 4, dof): ``q = c0 + c1 u + c2 u^2 + c3 u^3`` on segment k.
        """
        c = self._spline.c  # (4, n_seg, dof), highest power first
        return np.transpose(c[::-1], (1, 0, 2)).copy()


class CartesianIKPath(_SplinePath):
    """Cartesian line + IK at every sample, joined by a not-a-knot cubic spline per joint.

    Attributes:
        robot: the chain.
        s_samples: sample parameters, shape (samples,), uniform in [0, 1].
        q_samples: IK solutions at the samples, shape (samples, dof).
    """

    def __init__(self, robot: Chain, s_samples: np.ndarray, q_samples: np.ndarray) -> None:
        self.robot = robot
        self.s_samples = np.asarray(s_samples, dtype=float)
        self.q_samples = np.asarray(q_samples, dtype=float)
        bc = 'not-a-knot' if self.s_samples.size >= 4 else 'natural'
        self._spline = CubicSpline(self.s_samples, self.q_samples, axis=0, bc_type=bc)

    @property
    def breakpoints(self) -> np.ndarray:
        """Knots in s (the samples): q''' jumps there (the spline is C2)."""
        return self.s_samples


def _ik_along_line(robot: Chain, T_start: np.ndarray, T_goal: np.ndarray, s: np.ndarray,
                   q_start: npt.ArrayLike | None, q_goal: npt.ArrayLike | None, ik: IKFunction) -> np.ndarray:
    """IK at line + slerp poses ``s``, each seeded with the previous solution."""
    dof = int(getattr(robot, 'dof', len(robot.joint_names)))
    poses = line_slerp(T_start, T_goal, s)
    qs = np.empty((s.size, dof))
    if q_start is None:
        qs[0] = ik(robot, poses[0], np.asarray(robot.home, dtype=float))
    else:
        qs[0] = _check_q(q_start, dof, 'q_start')
    for k in range(1, s.size):
        if k == s.size - 1 and q_goal is not None:
            qs[k] = _check_q(q_goal, dof, 'q_goal')
        else:
            qs[k] = _unwrap(robot, np.asarray(ik(robot, poses[k], qs[k - 1]), dtype=float), qs[k - 1])
    return qs


def _check_q(q: npt.ArrayLike | None, dof: int, what: str) -> np.ndarray:
    arr = np.asarray(q, dtype=float).reshape(-1)
    if arr.shape != (dof,) or not np.all(np.isfinite(arr)):
        raise RequestError(f'{what}: expected {dof} finite joint values, got {arr.tolist()}')
    return arr


def polynomial_path(robot: Chain, T_start: npt.ArrayLike, T_goal: npt.ArrayLike,
                    q_start: npt.ArrayLike | None = None, n_via: int = 11, *,
                    q_goal: npt.ArrayLike | None = None, end_velocity: str = 'constant', ik: IKFunction | None = None,
                    ik_tolerance: float = DEFAULT_VIA_TOLERANCE) -> PolynomialPath:
    """The paper's cubic-polynomial path along the straight line from ``T_start`` to ``T_goal``.

    Via points ``s_k = k / (n_via - 1)`` on the line + slerp; joints at each by IK seeded with the
    previous via point (``q_start`` at s = 0, ``q_goal`` at s = 1 when given). The end-effector
    twist is constant, ``[p_B - p_A; R_A log(R_A^T R_B)]`` per unit s (base frame), and is mapped to
    joint velocities with the pseudo-inverse of the geometric Jacobian (rows [v; w]) at each via
    point; for arms with fewer than 6 joints that is the least-squares joint rate. One cubic
    Hermite polynomial per joint and segment matches positions and velocities at both ends.

    End velocities: ``end_velocity='constant'`` (default) uses the same mapped twist at s = 0 and
    s = 1, as the paper did — its Fig. 5(b) shows the end-effector speed at about |AB| = 1.414 over
    the whole of [0, 1], including the ends, and Fig. 6 non-zero joint velocities at both ends.
    ``'zero'`` makes the path start and end at rest instead.

    Args:
        robot: chain with ``fk``, ``jacobian``, ``joint_names``, ``home``.
        T_start, T_goal: 4x4 base->tool transforms (line end points).
        q_start: joints at s = 0 (dof,); by IK from ``robot.home`` when None.
        n_via: number of via points including both ends (paper: 11), >= 2.
        q_goal: joints at s = 1; by IK seeded from the previous via point when None.
        end_velocity: 'constant' or 'zero'.
        ik: ``ik(robot, T, seed) -> q``; default :func:`geodesic_planner.core.ik.solve_ik`, seeded, no
            restarts, nearest reachable pose accepted within ``ik_tolerance``.
        ik_tolerance: largest accepted IK residual (weighted embedding distance).
    Returns:
        :class:`PolynomialPath`.
    Raises:
        RequestError: bad arguments. IKError: a via point is not reachable.
    """
    T_start = check_transform(T_start, 'T_start')
    T_goal = check_transform(T_goal, 'T_goal')
    if isinstance(n_via, bool) or int(n_via) != n_via or int(n_via) < 2:
        raise RequestError(f'n_via must be an integer >= 2, got {n_via!r}')
    if end_velocity not in ('constant', 'zero'):
        raise RequestError(f"end_velocity must be 'constant' or 'zero', got {end_velocity!r}")
    n_via = int(n_via)
    ik_fn = ik if ik is not None else _default_ik(ik_tolerance)
    s_via = np.linspace(0.0, 1.0, n_via)
    q_via = _ik_along_line(robot, T_start, T_goal, s_via, q_start, q_goal, ik_fn)
    twist = line_twist(T_start, T_goal)
    J = np.asarray(robot.jacobian(q_via), dtype=float)      # (n_via, 6, dof)
    dq_via = np.linalg.pinv(J) @ twist                       # (n_via, dof)
    if end_velocity == 'zero':
        dq_via[0] = 0.0
        dq_via[-1] = 0.0
    return PolynomialPath(robot, s_via, q_via, dq_via, twist, end_velocity)


def cartesian_ik_path(robot: Chain, T_start: npt.ArrayLike, T_goal: npt.ArrayLike,
                      q_start: npt.ArrayLike | None = None, samples: int = 100, *,
                      q_goal: npt.ArrayLike | None = None, ik: IKFunction | None = None,
                      ik_tolerance: float = DEFAULT_VIA_TOLERANCE) -> CartesianIKPath:
    """Cartesian straight line + slerp with IK at every sample (MoveIt Pilz LIN style).

    Args:
        robot: chain with ``fk``, ``jacobian``, ``joint_names``, ``home``.
        T_start, T_goal: 4x4 base->tool transforms.
        q_start: joints at s = 0; by IK from ``robot.home`` when None.
        samples: number of poses including both ends, >= 2 (uniform in s).
        q_goal: joints at s = 1 (optional).
        ik: ``ik(robot, T, seed) -> q``; see :func:`polynomial_path`.
        ik_tolerance: largest accepted IK residual.
    Returns:
        :class:`CartesianIKPath` (its ``q_samples`` are the IK solutions).
    Raises:
        RequestError: bad arguments. IKError: a sample is not reachable.
    """
    T_start = check_transform(T_start, 'T_start')
    T_goal = check_transform(T_goal, 'T_goal')
    if isinstance(samples, bool) or int(samples) != samples or int(samples) < 2:
        raise RequestError(f'samples must be an integer >= 2, got {samples!r}')
    ik_fn = ik if ik is not None else _default_ik(ik_tolerance)
    s = np.linspace(0.0, 1.0, int(samples))
    qs = _ik_along_line(robot, T_start, T_goal, s, q_start, q_goal, ik_fn)
    return CartesianIKPath(robot, s, qs)


__all__ = ['CartesianIKPath', 'PolynomialPath', 'cartesian_ik_path', 'line_twist', 'polynomial_path']
