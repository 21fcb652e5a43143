"""Synthetic paths with exact derivatives, limit checks and time-optimal oracles for the timing tests.

Oracles: the analytic bang-bang time of a straight joint line, and a time-optimal profile solved
independently as a linear program (scipy HiGHS) on its own grid.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
from numpy.polynomial import polynomial as P

from geodesic_planner.timing import Trajectory

#: Our smooth law may be at most this much slower than the (non-smooth) time-optimal law.
OPTIMALITY_FACTOR = 1.10


class PolyPath:
    """q(s) = sum_k c_k s^k per joint; exact derivatives."""

    def __init__(self, coeffs, vmax=1.0, amax=2.0):
        self.c = np.asarray(coeffs, dtype=float)  # (degree + 1, dof)
        dof = self.c.shape[1]
        self.dof = dof
        self.joint_names = [f'j{i + 1}' for i in range(dof)]
        self.robot = SimpleNamespace(max_velocity=np.broadcast_to(vmax, (dof,)).astype(float),
                                     max_acceleration=np.broadcast_to(amax, (dof,)).astype(float))

    def evaluate(self, s, order=3):
        s = np.asarray(s, dtype=float)
        assert s.ndim == 1 and s.min() >= 0.0 and s.max() <= 1.0
        out, c = [], self.c
        for _ in range(order + 1):
            out.append(P.polyval(s, c).T.reshape(s.size, -1))
            c = P.polyder(c) if c.shape[0] > 1 else np.zeros_like(c[:1])
        return tuple(out)


def curved(vmax=(1.0, 1.5, 0.8), amax=3.0):
    return PolyPath([[0.1, 0.0, 0.0], [2.0, 1.0, -1.0], [-1.0, 3.0, 0.5], [0.5, -2.0, 1.0]], vmax, amax)


def check_limits(traj: Trajectory, n: int = 20001, rtol: float = 1e-9) -> tuple[float, float]:
    t = np.linspace(0.0, traj.duration, n)
    _, dq, ddq = traj.at_time(t)
    rv = np.max(np.abs(dq) / traj.max_velocity)
    ra = np.max(np.abs(ddq) / traj.max_acceleration)
    assert rv <= 1.0 + rtol, f'velocity limit exceeded by factor {rv}'
    assert ra <= 1.0 + rtol, f'acceleration limit exceeded by factor {ra}'
    return float(rv), float(ra)


def lp_topp_duration(path, vmax, amax, n=400) -> float:
    """Time-optimal duration by a linear program in (x = sdot^2, u = sddot) on an n-interval grid.

    Maximises sum(x) subject to x_{k+1} = x_k + 2 h u_k, |q' u + q'' x| <= amax and
    |q'|^2 x <= vmax^2 at the grid points, x_0 = x_n = 0; the maximal profile is the time-optimal one.
    """
    from scipy.optimize import linprog
    from scipy.sparse import lil_matrix

    h = 1.0 / n
    s = np.linspace(0.0, 1.0, n + 1)
    _, a, b, _ = path.evaluate(s)
    dof = a.shape[1]
    nx, nu = n + 1, n
    A_eq = lil_matrix((n + 2, nx + nu))
    b_eq = np.zeros(n + 2)
    for k in range(n):
        A_eq[k, k + 1] = 1.0
        A_eq[k, k] = -1.0
        A_eq[k, nx + k] = -2.0 * h
    A_eq[n, 0] = 1.0
    A_eq[n + 1, n] = 1.0
    A_ub = lil_matrix((2 * n * dof, nx + nu))
    b_ub = np.zeros(2 * n * dof)
    r = 0
    for k in range(n):
        for i in range(dof):
            for sign in (1.0, -1.0):
                A_ub[r, nx + k] = sign * a[k, i]
                A_ub[r, k] = sign * b[k, i]
                b_ub[r] = amax[i]
                r += 1
    with np.errstate(divide='ignore'):
        xv = np.min(np.where(np.abs(a) > 0, (vmax / np.abs(a)) ** 2, np.inf), axis=1)
    bounds = [(0.0, float(min(v, 1e9))) for v in xv] + [(None, None)] * nu
    c = np.concatenate([-np.ones(nx), np.zeros(nu)])
    res = linprog(c, A_ub=A_ub.tocsr(), b_ub=b_ub, A_eq=A_eq.tocsr(), b_eq=b_eq, bounds=bounds,
                  method='highs')
    assert res.status == 0, res.message
    x = np.maximum(res.x[:nx], 0.0)
    return float(np.sum(2.0 * h / (np.sqrt(x[:-1]) + np.sqrt(x[1:]))))


class CornerPath:
    """Two straight joint-space segments meeting at s = 0.5 with a corner (q' jumps)."""

    def __init__(self, d1, d2, vmax=1.0, amax=2.0):
        self.d1, self.d2 = np.asarray(d1, float), np.asarray(d2, float)
        dof = self.dof = self.d1.size
        self.joint_names = [f'j{i + 1}' for i in range(dof)]
        self.robot = SimpleNamespace(max_velocity=np.full(dof, vmax), max_acceleration=np.full(dof, amax))
        self.breakpoints = np.array([0.0, 0.5, 1.0])

    def evaluate(self, s, order=3):
        s = np.asarray(s, dtype=float)[:, None]
        first = s < 0.5
        q = np.where(first, 2 * s * self.d1, self.d1 + (2 * s - 1) * self.d2)
        dq = np.where(first, 2 * self.d1, 2 * self.d2) * np.ones_like(s)
        z = np.zeros_like(q)
        return (q, dq, z, z)[:order + 1]


def line_time(length, vmax, amax):
    return length / vmax + vmax / amax if length >= vmax**2 / amax else 2.0 * np.sqrt(length / amax)


class ZigZagPath:
    """Straight joint-space legs between given breakpoints, alternating direction (corners)."""

    def __init__(self, breaks):
        self.breakpoints = np.asarray(breaks, dtype=float)
        self.joint_names = ['j1', 'j2']
        self.dof = 2
        self.robot = SimpleNamespace(max_velocity=np.array([1.0, 1.0]), max_acceleration=np.array([2.0, 2.0]))
        legs = np.diff(self.breakpoints)
        dirs = np.array([[1.0, 0.5] if i % 2 == 0 else [0.5, -1.0] for i in range(legs.size)])
        self.slopes = dirs                       # dq/ds on each leg
        self.starts = np.concatenate([[[0.0, 0.0]], np.cumsum(dirs * legs[:, None], axis=0)])[:-1]

    def evaluate(self, s, order=3):
        s = np.asarray(s, dtype=float)
        i = np.clip(np.searchsorted(self.breakpoints, s, side='right') - 1, 0, self.slopes.shape[0] - 1)
        q = self.starts[i] + (s - self.breakpoints[i])[:, None] * self.slopes[i]
        z = np.zeros_like(q)
        return (q, self.slopes[i].copy(), z, z)[:order + 1]


def _ur5e_line_path():
    from geodesic_planner import GeodesicPlanner, load_robot
    from geodesic_planner.core.transforms import so3_exp
    robot = load_robot('ur5e')
    q_a = np.asarray(robot.home, dtype=float) + 0.1
    T_a = robot.fk(q_a)
    T_b = T_a.copy()
    T_b[:3, 3] += [0.1, -0.15, 0.05]
    T_b[:3, :3] = T_a[:3, :3] @ so3_exp(np.array([0.3, 0.2, -0.1]))
    return robot, GeodesicPlanner(robot), q_a, T_a, T_b
