"""Time parameterization (geodesic_planner.timing.parameterize) on synthetic polynomial paths.

Oracles: the analytic bang-bang time of a straight joint line, and a time-optimal profile solved
independently as a linear program (scipy HiGHS) on its own grid.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from numpy.polynomial import polynomial as P

from geodesic_planner.core.errors import GeodesicPlannerError, LimitError
from geodesic_planner.timing.parameterize import Trajectory, time_parameterize

#: Our smooth law may be at most this much slower than the (non-smooth) time-optimal law.
OPTIMALITY_FACTOR = 1.10


class PolyPath:
    """q(s) = sum_k c_k s^k per joint; exact derivatives."""

    def __init__(self, coeffs, vmax=1.0, amax=2.0):
        self.c = np.asarray(coeffs, dtype=float)  # (degree + 1, dof)
        dof = self.c.shape[1]
        self.joint_names = [f'j{i + 1}' for i in range(dof)]
        self.robot = SimpleNamespace(max_velocity=np.broadcast_to(vmax, (dof,)).astype(float),
                                     max_acceleration=np.broadcast_to(amax, (dof,)).astype(float))

    def evaluate(self, s):
        s = np.asarray(s, dtype=float)
        assert s.ndim == 1 and s.min() >= 0.0 and s.max() <= 1.0
        out, c = [], self.c
        for _ in range(4):
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


@pytest.mark.parametrize('length, vmax, amax', [(1.0, 1.0, 2.0), (0.2, 1.0, 2.0), (3.0, 0.5, 0.4)])
def test_straight_line_against_bang_bang_oracle(length, vmax, amax):
    # q(s) = q0 + s * length * dir; joint 2 moves half as far, so joint 1 limits.
    path = PolyPath([[0.3, -0.2], [length, -0.5 * length]], vmax, amax)
    traj = time_parameterize(path)
    if length >= vmax**2 / amax:
        t_opt = length / vmax + vmax / amax          # trapezoid
    else:
        t_opt = 2.0 * np.sqrt(length / amax)         # triangle
    assert traj.topp_duration == pytest.approx(t_opt, rel=3e-3)
    assert t_opt * (1 - 1e-6) <= traj.duration <= OPTIMALITY_FACTOR * t_opt
    rv, ra = check_limits(traj)
    assert max(rv, ra) > 0.97  # a limit is actually reached: not wastefully slow


def test_curved_path_limits_hold_on_dense_grid_and_ends_at_rest():
    path = curved()
    traj = time_parameterize(path)
    check_limits(traj)
    q_end, dq_end, ddq_end = traj.at_time(np.array([0.0, traj.duration]))
    q_ref = path.evaluate(np.array([0.0, 1.0]))[0]
    np.testing.assert_allclose(q_end, q_ref, atol=1e-12)
    np.testing.assert_array_equal(dq_end, 0.0)
    np.testing.assert_array_equal(ddq_end, 0.0)
    # Rest is approached smoothly: acceleration tends to zero near the ends (not a jump).
    eps = 1e-4 * traj.duration
    _, dq_near, ddq_near = traj.at_time(np.array([eps, traj.duration - eps]))
    assert np.max(np.abs(ddq_near) / traj.max_acceleration) < 0.05
    assert np.max(np.abs(dq_near) / traj.max_velocity) < 1e-3


def test_acceleration_is_continuous():
    traj = time_parameterize(curved())
    t = np.linspace(0.0, traj.duration, 200001)
    _, _, ddq = traj.at_time(t)
    jumps = np.max(np.abs(np.diff(ddq, axis=0)) / traj.max_acceleration)
    assert jumps < 0.01  # a bang-bang (TOPP) law would jump by about 2 amax here
    jerk = traj.jerk_at_time(t)
    assert np.all(np.isfinite(jerk))


@pytest.mark.parametrize('vmax, amax', [((1.0, 1.5, 0.8), 3.0), (5.0, 0.7), ((0.3, 2.0, 2.0), (4.0, 1.0, 9.0))])
def test_duration_close_to_independent_time_optimum(vmax, amax):
    path = curved(vmax, amax)
    traj = time_parameterize(path)
    t_lp = lp_topp_duration(path, traj.max_velocity, traj.max_acceleration)
    ratio = traj.duration / t_lp
    assert 0.99 <= ratio <= OPTIMALITY_FACTOR, ratio
    assert traj.topp_duration == pytest.approx(t_lp, rel=0.01)
    assert traj.optimality_ratio == pytest.approx(traj.min_duration / traj.topp_duration)
    check_limits(traj)


def test_chain_rule_and_path_unchanged():
    path = curved()
    traj = time_parameterize(path)
    t = np.linspace(0.0, traj.duration, 4001)
    s, sd, sdd = traj.s_of_t(t)
    q, dq, ddq = traj.at_time(t)
    np.testing.assert_allclose(q, path.evaluate(s)[0], atol=1e-14)
    assert np.all(np.diff(s) >= 0.0) and s[0] == 0.0 and s[-1] == 1.0
    dt = t[1] - t[0]
    # Finite differences of the sampled law and of q(t) (test-only check of the analytic values).
    np.testing.assert_allclose((s[2:] - s[:-2]) / (2 * dt), sd[1:-1], atol=1e-5 * sd.max())
    np.testing.assert_allclose((sd[2:] - sd[:-2]) / (2 * dt), sdd[1:-1], atol=2e-3 * np.abs(sdd).max())
    np.testing.assert_allclose((q[2:] - q[:-2]) / (2 * dt), dq[1:-1], atol=1e-5 * np.abs(dq).max())
    np.testing.assert_allclose((dq[2:] - dq[:-2]) / (2 * dt), ddq[1:-1], atol=2e-3 * np.abs(ddq).max())


def test_duration_stretch_is_exact_and_uniform():
    path = curved()
    fast = time_parameterize(path)
    lam = 1.7
    slow = time_parameterize(path, duration=lam * fast.duration)
    assert slow.duration == lam * fast.duration
    t = np.linspace(0.0, fast.duration, 501)
    q0, dq0, ddq0 = fast.at_time(t)
    q1, dq1, ddq1 = slow.at_time(lam * t)
    np.testing.assert_allclose(q1, q0, atol=1e-12)
    np.testing.assert_allclose(dq1, dq0 / lam, atol=1e-12)
    np.testing.assert_allclose(ddq1, ddq0 / lam**2, atol=1e-10)
    ts, qs, _, _ = slow.sample(0.01)
    assert ts[-1] == slow.duration
    np.testing.assert_allclose(qs[-1], path.evaluate(np.array([1.0]))[0][0], atol=1e-12)
    check_limits(slow)
    # Exactly the minimum is accepted.
    assert time_parameterize(path, duration=fast.duration).duration == fast.duration


def test_duration_shorter_than_feasible_names_the_minimum():
    path = curved()
    t_min = time_parameterize(path).duration
    with pytest.raises(LimitError, match=r'shorter than the minimum') as err:
        time_parameterize(path, duration=0.5 * t_min)
    assert f'{t_min:.6g}' in str(err.value)


def test_scalar_limits_broadcast():
    path = curved()
    a = time_parameterize(path, 2.0, 3.0)
    b = time_parameterize(path, [2.0, 2.0, 2.0], np.array([3.0, 3.0, 3.0]))
    np.testing.assert_array_equal(a.max_velocity, [2.0, 2.0, 2.0])
    np.testing.assert_array_equal(a.max_acceleration, [3.0, 3.0, 3.0])
    assert a.duration == b.duration


def test_robot_limits_are_the_default():
    path = curved(vmax=(0.4, 0.5, 0.6), amax=(1.0, 2.0, 3.0))
    traj = time_parameterize(path)
    np.testing.assert_array_equal(traj.max_velocity, [0.4, 0.5, 0.6])
    np.testing.assert_array_equal(traj.max_acceleration, [1.0, 2.0, 3.0])
    # Halving all velocity and acceleration limits at least slows the motion down.
    assert time_parameterize(path, [0.2, 0.25, 0.3], [0.5, 1.0, 1.5]).duration > traj.duration


@pytest.mark.parametrize('vmax, amax, joint', [
    ([1.0, 0.0, 1.0], 1.0, 'j2'),
    ([1.0, 1.0, -2.0], 1.0, 'j3'),
    (1.0, [np.nan, 1.0, 1.0], 'j1'),
    (1.0, [1.0, np.inf, 1.0], 'j2'),
    (-1.0, 1.0, 'j1'),
])
def test_invalid_limits_name_the_joint(vmax, amax, joint):
    with pytest.raises(LimitError, match=f"joint '{joint}'"):
        time_parameterize(curved(), vmax, amax)


def test_wrong_number_of_limits_and_bad_arguments():
    with pytest.raises(LimitError, match='one per joint'):
        time_parameterize(curved(), [1.0, 1.0], 1.0)
    with pytest.raises(LimitError, match='duration'):
        time_parameterize(curved(), 1.0, 1.0, duration=float('nan'))
    traj = time_parameterize(curved())
    for bad in (0.0, -0.1, float('inf'), float('nan')):
        with pytest.raises(LimitError, match='dt'):
            traj.sample(bad)
    assert issubclass(LimitError, GeodesicPlannerError)


def test_sample_grid_uniform_with_last_sample_at_duration():
    traj = time_parameterize(curved())
    dt = 0.013
    t, q, dq, ddq = traj.sample(dt)
    assert t[0] == 0.0 and t[-1] == traj.duration
    steps = np.diff(t)
    np.testing.assert_allclose(steps[:-1], dt, rtol=1e-12)
    assert 0.0 < steps[-1] <= dt + 1e-12
    assert q.shape == dq.shape == ddq.shape == (t.size, 3)
    # A dt that divides the duration gives no tiny extra step.
    d2 = time_parameterize(curved(), duration=2.6)
    t2 = d2.sample(0.1)[0]
    assert t2.size == 27 and t2[-1] == 2.6 and np.all(np.diff(t2) > 0.099)


def test_stationary_path():
    path = PolyPath([[0.5, -1.0]], 1.0, 1.0)
    traj = time_parameterize(path)
    assert traj.duration == 0.0
    t, q, dq, ddq = traj.sample(0.01)
    assert t.tolist() == [0.0]
    np.testing.assert_allclose(q, [[0.5, -1.0]])
    held = time_parameterize(path, duration=2.0)
    t, q, dq, _ = held.sample(0.5)
    np.testing.assert_allclose(q, np.tile([0.5, -1.0], (t.size, 1)))
    np.testing.assert_array_equal(dq, 0.0)


def test_path_with_a_joint_that_does_not_move_and_a_turning_point():
    # Joint 1 goes out and back (q' = 0 at s = 0.5), joint 2 never moves.
    path = PolyPath([[0.0, 0.2], [2.0, 0.0], [-2.0, 0.0]], 1.0, 2.0)
    traj = time_parameterize(path)
    check_limits(traj)
    q = traj.sample(0.001)[1]
    np.testing.assert_allclose(q[:, 1], 0.2)
    assert q[:, 0].max() == pytest.approx(0.5, abs=1e-6)
    # Independent optimum: out 0.5 rad and back, each a triangle/trapezoid at vmax 1, amax 2.
    t_half = 0.5 / 1.0 + 1.0 / 2.0
    assert 2 * t_half * (1 - 1e-6) <= traj.duration <= OPTIMALITY_FACTOR * 2 * t_half


# ------------------------------------------------------------------ corners and breakpoints
class CornerPath:
    """Two straight joint-space segments meeting at s = 0.5 with a corner (q' jumps)."""

    def __init__(self, d1, d2, vmax=1.0, amax=2.0):
        self.d1, self.d2 = np.asarray(d1, float), np.asarray(d2, float)
        dof = self.d1.size
        self.joint_names = [f'j{i + 1}' for i in range(dof)]
        self.robot = SimpleNamespace(max_velocity=np.full(dof, vmax), max_acceleration=np.full(dof, amax))
        self.breakpoints = np.array([0.0, 0.5, 1.0])

    def evaluate(self, s):
        s = np.asarray(s, dtype=float)[:, None]
        first = s < 0.5
        q = np.where(first, 2 * s * self.d1, self.d1 + (2 * s - 1) * self.d2)
        dq = np.where(first, 2 * self.d1, 2 * self.d2) * np.ones_like(s)
        z = np.zeros_like(q)
        return q, dq, z, z


def line_time(length, vmax, amax):
    return length / vmax + vmax / amax if length >= vmax**2 / amax else 2.0 * np.sqrt(length / amax)


def test_corner_of_a_piecewise_path_is_a_rest():
    path = CornerPath([0.8, 0.0], [0.0, 0.6])
    traj = time_parameterize(path)
    assert traj.rests == pytest.approx((0.0, 0.5, 1.0))
    check_limits(traj)
    assert len(traj.rest_times) == 3 and traj.rest_times[0] == 0.0 and traj.rest_times[2] == traj.duration
    s, sd, sdd = traj.s_of_t(np.array([traj.rest_times[1]]))
    assert s[0] == pytest.approx(0.5, abs=1e-12) and sd[0] == 0.0 and sdd[0] == 0.0
    t = np.linspace(0.0, traj.duration, 100001)
    _, dq, ddq = traj.at_time(t)
    # Velocities are continuous through the corner (no jump at the change of direction).
    assert np.max(np.abs(np.diff(dq, axis=0))) < 1e-3
    # Each leg is a rest-to-rest straight move: oracle = two bang-bang times.
    t_opt = line_time(0.8, 1.0, 2.0) + line_time(0.6, 1.0, 2.0)
    assert traj.topp_duration == pytest.approx(t_opt, rel=0.01)
    assert t_opt <= traj.duration <= OPTIMALITY_FACTOR * t_opt


def test_smooth_breakpoint_is_not_a_rest():
    # Same direction on both sides: a breakpoint without a corner.
    path = CornerPath([0.4, 0.2], [0.4, 0.2])
    traj = time_parameterize(path)
    assert traj.rests == (0.0, 1.0)
    t_opt = line_time(0.8, 1.0, 2.0)  # joint 1 moves 0.8 in one straight line
    assert t_opt <= traj.duration <= OPTIMALITY_FACTOR * t_opt


# ------------------------------------------------------------------ real arms (core planner)
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


@pytest.mark.parametrize('name', ['planar_3r', 'rrpp', 'ur5e', 'panda'])
def test_geodesic_paths_of_the_presets_respect_limits_and_rest(name):
    from geodesic_planner import GeodesicPlanner, load_robot
    robot = load_robot(name)
    q_a = np.asarray(robot.home, dtype=float)
    if name == 'planar_3r':
        q_a, q_b = np.array([0.258, 0.583, -0.317]), np.array([0.969, 0.380, -0.574])
    else:
        q_b = q_a + np.linspace(0.15, -0.1, robot.dof)
    path = GeodesicPlanner(robot).plan(None, None, start_joints=q_a, goal_joints=q_b)
    traj = path.timed()
    assert traj.joint_names == robot.joint_names
    np.testing.assert_array_equal(traj.max_velocity, robot.max_velocity)
    rv, ra = check_limits(traj)
    assert max(rv, ra) > 0.97
    t, q, dq, ddq = traj.sample(0.002)
    np.testing.assert_allclose(q[[0, -1]], [q_a, q_b], atol=1e-9)
    np.testing.assert_array_equal(dq[[0, -1]], 0.0)
    np.testing.assert_array_equal(ddq[[0, -1]], 0.0)
    assert 1.0 <= traj.optimality_ratio <= OPTIMALITY_FACTOR
    half = path.timed(np.asarray(robot.max_velocity) / 2, np.asarray(robot.max_acceleration) / 4)
    assert half.duration == pytest.approx(2.0 * traj.duration, rel=0.02)  # time scaling by 2


def test_geodesic_duration_close_to_independent_optimum_on_ur5e():
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    path = planner.plan(T_a, T_b, start_joints=q_a)
    traj = path.timed()
    t_lp = lp_topp_duration(path, traj.max_velocity, traj.max_acceleration, n=300)
    assert 0.99 <= traj.duration / t_lp <= OPTIMALITY_FACTOR
    check_limits(traj)


def test_piecewise_geodesic_with_a_corner_rests_there():
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    T_mid = T_a.copy()
    T_mid[:3, 3] += [0.1, 0.0, 0.0]  # A -> M -> B is a polyline with a corner at M
    path = planner.plan_through([T_a, T_mid, T_b], start_joints=q_a)
    traj = path.timed()
    check_limits(traj)
    assert len(traj.rests) == 3 and traj.rests[1] == pytest.approx(path.breakpoints[1])
    t = np.linspace(0.0, traj.duration, 20001)
    _, dq, _ = traj.at_time(t)
    assert np.max(np.abs(np.diff(dq, axis=0))) < 0.01 * robot.max_velocity.max()


def test_polynomial_baseline_knots_one_sided_accelerations():
    """The paper's cubic polynomial is only C1: q'' jumps at its knots; limits hold on both sides."""
    from geodesic_planner import load_robot
    from geodesic_planner.core.baselines import polynomial_path
    robot = load_robot('planar_3r')
    q_a = np.array([0.2578, 0.5828, -0.3170])
    T_a, T_b = robot.fk(q_a), robot.fk(np.array([0.9692, 0.3799, -0.5735]))
    path = polynomial_path(robot, T_a, T_b, q_a)
    traj = path.timed()
    check_limits(traj, n=50001)


class ZigZagPath:
    """Straight joint-space legs between given breakpoints, alternating direction (corners)."""

    def __init__(self, breaks):
        self.breakpoints = np.asarray(breaks, dtype=float)
        self.joint_names = ['j1', 'j2']
        self.robot = SimpleNamespace(max_velocity=np.array([1.0, 1.0]), max_acceleration=np.array([2.0, 2.0]))
        legs = np.diff(self.breakpoints)
        dirs = np.array([[1.0, 0.5] if i % 2 == 0 else [0.5, -1.0] for i in range(legs.size)])
        self.slopes = dirs                       # dq/ds on each leg
        self.starts = np.concatenate([[[0.0, 0.0]], np.cumsum(dirs * legs[:, None], axis=0)])[:-1]

    def evaluate(self, s):
        s = np.asarray(s, dtype=float)
        i = np.clip(np.searchsorted(self.breakpoints, s, side='right') - 1, 0, self.slopes.shape[0] - 1)
        q = self.starts[i] + (s - self.breakpoints[i])[:, None] * self.slopes[i]
        z = np.zeros_like(q)
        return q, self.slopes[i].copy(), z, z


def test_many_short_pieces_rest_at_every_corner():
    breaks = np.concatenate([[0.0, 0.003, 0.0045], np.linspace(0.01, 1.0, 25)])  # pieces far below 1/100
    path = ZigZagPath(breaks)
    traj = time_parameterize(path)
    assert len(traj.rests) == breaks.size
    np.testing.assert_allclose(traj.rests, breaks, atol=1e-12)
    check_limits(traj, n=100001)
    for t_rest, s_rest in zip(traj.rest_times, traj.rests):
        s, sd, sdd = traj.s_of_t(np.array([t_rest]))
        assert s[0] == pytest.approx(s_rest, abs=1e-12) and sd[0] == 0.0 and sdd[0] == 0.0
    # Oracle: every leg is a rest-to-rest straight move of its own.
    legs = np.diff(breaks) * np.abs(path.slopes).max(axis=1)
    t_opt = sum(line_time(length, 1.0, 2.0) for length in legs)
    assert t_opt <= traj.duration <= OPTIMALITY_FACTOR * t_opt


def test_regression_sharp_geodesic_from_fuzzing():
    """A random 7-joint chain whose geodesic has a sharp feature near s = 0.005 (q'' ~ 1e3,
    q''' ~ 1e5). 101 uniform samples cannot resolve it: interpolating between them overshot the
    acceleration limit by 0.3 % (4 % before rounding these numbers). The adaptive refinement and
    the exact re-check of the samples nearest a limit keep it within the limits."""
    from geodesic_planner import GeodesicPlanner, chain_from_dh
    rows = [(-0.67284, 0.215194, 0.251336, -1.570796), (-1.024715, 0.114486, 0.166167, 0.0),
            (0.775601, 0.481395, 0.570078, 1.570796), (2.445888, 0.06948, 0.456711, 0.0),
            (-2.14178, 0.219622, 0.410436, -1.570796), (-2.401776, 0.396356, 0.27061, 0.0),
            (0.505209, 0.380409, 0.593735, -1.570796)]
    kinds = ['prismatic', 'revolute', 'revolute', 'revolute', 'prismatic', 'revolute', 'revolute']
    robot = chain_from_dh('fuzz', rows, kinds, max_velocity=[0.6897, 0.4881, 2.1364, 0.9143, 0.9773, 1.4414, 1.6773],
                          max_acceleration=[4.4534, 9.5792, 3.3319, 6.2192, 0.6543, 1.1058, 2.39])
    q_a = np.array([-0.437314, -0.067353, 0.148415, -0.668158, 0.1573, -0.836354, -0.215451])
    q_b = np.array([0.039641, -0.107366, 0.414124, -1.110444, 0.489339, -0.061467, 0.026068])
    path = GeodesicPlanner(robot).plan(None, None, start_joints=q_a, goal_joints=q_b)
    traj = path.timed()
    rv, ra = check_limits(traj, n=40001)
    assert max(rv, ra) > 0.99
    assert traj.optimality_ratio <= OPTIMALITY_FACTOR


# ------------------------------------------------------------------ internals against plain references
def reference_topp(ps, vmax, amax):
    """The time-optimal profile of ``timing._topp`` written as plain loops over steps and rows.

    Step k, rows j (joints at the step start, then at its end): |ra_j u + rb_j x_k| <= amax_j, with
    x_{k+1} = x_k + 2 h u; static bound = min(velocity, rows that do not move, row pairs,
    x_{k+1} >= 0, cap); backward pass over all rows, then the greedy forward pass.
    """
    from geodesic_planner.timing import parameterize as timing
    s, aL, aR, bL, bR = (np.asarray(v, dtype=float) for v in (ps.s, ps.aL, ps.aR, ps.bL, ps.bR))
    n, dof = s.size - 1, aR.shape[1]
    absa_n = np.maximum(np.abs(aL), np.abs(aR))
    tiny_n = 1e-12 * max(float(absa_n.max()), 1e-300)
    rows = []
    for k in range(n):
        h = float(s[k + 1] - s[k])
        ra = [float(aR[k, i]) for i in range(dof)] + [float(aL[k + 1, i] + 2.0 * h * bL[k + 1, i]) for i in range(dof)]
        rb = [float(bR[k, i]) for i in range(dof)] + [float(bL[k + 1, i]) for i in range(dof)]
        rows.append((h, ra, rb))
    tiny = 1e-12 * max(max(abs(v) for _, ra, _ in rows for v in ra), 1e-300)
    rl = [float(v) for v in amax] * 2
    static, lines, upper = [], [], []
    for k, (h, ra, rb) in enumerate(rows):
        xv = min([(vmax[i] / absa_n[k, i]) * (vmax[i] / absa_n[k, i]) for i in range(dof) if absa_n[k, i] > tiny_n]
                 or [np.inf])
        mov = [abs(v) > tiny for v in ra]
        xz = min([rl[j] / abs(rb[j]) for j in range(2 * dof) if not mov[j] and rb[j] != 0.0] or [np.inf])
        al = [-rb[j] / ra[j] if mov[j] else 0.0 for j in range(2 * dof)]
        c = [-rl[j] / abs(ra[j]) if mov[j] else -np.inf for j in range(2 * dof)]
        d = [rl[j] / abs(ra[j]) if mov[j] else np.inf for j in range(2 * dof)]
        xp = min([(d[m] - c[j]) / (al[j] - al[m]) for j in range(2 * dof) for m in range(2 * dof)
                  if mov[j] and mov[m] and al[j] - al[m] > 0] or [np.inf])
        coef = [-1.0 / (2.0 * h) - al[j] for j in range(2 * dof)]
        xl = min([d[j] / coef[j] for j in range(2 * dof) if mov[j] and coef[j] > 0] or [np.inf])
        st = 0.0 if ps.stop[k] else max(min(xv, xz, xp, xl, timing._X_CAP), 0.0)
        static.append(st)
        den = [1.0 + 2.0 * h * al[j] for j in range(2 * dof)]
        lines.append([(1.0 / den[j], -2.0 * h * c[j] / den[j]) for j in range(2 * dof) if mov[j] and den[j] > 0])
        upper.append(list(zip(al, d)))
    hi = [0.0] * (n + 1)
    for k in range(n - 1, -1, -1):
        hi[k] = min([static[k]] + [a * hi[k + 1] + b for a, b in lines[k]])
    x = [0.0] * (n + 1)
    for k in range(n):
        two_h = 2.0 * rows[k][0]
        u = min([(hi[k + 1] - x[k]) / two_h] + [a * x[k] + d for a, d in upper[k]])
        x[k + 1] = min(max(x[k] + two_h * u, 0.0), hi[k + 1])
    x[n] = 0.0
    return np.array(x)


def _fine_samples(path):
    from geodesic_planner.timing import parameterize as timing
    return timing._refine_adaptively(path, timing._sample_path(path, 100)).refined(2)


def _topp_cases():
    rng = np.random.default_rng(7)
    cases = [('curved', curved(), 1.0), ('curved slow', curved(), 0.2),
             ('turning point, still joint', PolyPath([[0.0, 0.2], [2.0, 0.0], [-2.0, 0.0]], 1.0, 2.0), 1.0),
             ('corner', CornerPath([0.8, 0.0], [0.0, 0.6]), 1.0),
             ('zigzag', ZigZagPath(np.linspace(0.0, 1.0, 6)), 1.0)]
    for i in range(4):
        cases.append((f'random {i}', PolyPath(rng.standard_normal((5, 4)), rng.uniform(0.3, 2.0, 4),
                                              rng.uniform(0.5, 4.0, 4)), float(rng.choice([0.3, 1.0, 3.0]))))
    return cases


@pytest.mark.parametrize('name, path, scale', _topp_cases(), ids=[c[0] for c in _topp_cases()])
def test_topp_passes_equal_plain_all_rows_loops(name, path, scale, monkeypatch):
    from geodesic_planner.timing import parameterize as timing
    ps = _fine_samples(path)
    vmax = path.robot.max_velocity * scale
    amax = path.robot.max_acceleration
    ref = reference_topp(ps, vmax, amax)
    assert ref.max() > 0.0
    # Default: the closed-form passes, accepted to 1e-12 per step; exact zeros at the rests.
    x = timing._topp(ps, vmax, amax)
    np.testing.assert_allclose(x, ref, rtol=1e-10, atol=0.0)
    np.testing.assert_array_equal(x[ref == 0.0], 0.0)
    # Closed form refused: the guessed-row loops, checked against all rows, give the same floats.
    monkeypatch.setattr(timing, '_CLOSED_FORM_RTOL', -1.0)
    np.testing.assert_array_equal(timing._topp(ps, vmax, amax), ref)
    # No guessing rounds either: every row on every step.
    monkeypatch.setattr(timing, '_PASS_ROUNDS', 0)
    np.testing.assert_array_equal(timing._topp(ps, vmax, amax), ref)


def test_path_interpolation_is_the_cubic_hermite_of_the_samples():
    """q', q'' between the nodes: the cubic Hermite basis (oracle) in any order of s."""
    from geodesic_planner.timing import parameterize as timing
    base = timing._refine_adaptively(curved(), timing._sample_path(curved(), 20))
    rng = np.random.default_rng(3)
    s = rng.uniform(0.0, 1.0, 3000)
    a, b = base.interpolate(s)
    k = np.clip(np.searchsorted(base.s, s, side='right') - 1, 0, base.s.size - 2)
    h = (base.s[k + 1] - base.s[k])[:, None]
    x = ((s - base.s[k])[:, None]) / h
    h00, h10, h01, h11 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x, -2 * x**3 + 3 * x**2, x**3 - x**2
    a_ref = h00 * base.aR[k] + h10 * h * base.bR[k] + h01 * base.aL[k + 1] + h11 * h * base.bL[k + 1]
    b_ref = h00 * base.bR[k] + h10 * h * base.cR[k] + h01 * base.bL[k + 1] + h11 * h * base.cL[k + 1]
    np.testing.assert_allclose(a, a_ref, rtol=0.0, atol=1e-12 * np.abs(a_ref).max())
    np.testing.assert_allclose(b, b_ref, rtol=0.0, atol=1e-12 * np.abs(b_ref).max())
    order = np.argsort(s)
    a_sorted, b_sorted = base.interpolate(s[order])  # sorted s takes another code path
    np.testing.assert_array_equal(a_sorted, a[order])
    np.testing.assert_array_equal(b_sorted, b[order])


@pytest.mark.parametrize('path', [curved(), ZigZagPath(np.linspace(0.0, 1.0, 6))], ids=['one piece', 'five pieces'])
def test_time_law_does_not_depend_on_the_order_of_the_times(path):
    traj = time_parameterize(path)
    t = np.concatenate([np.linspace(0.0, traj.duration, 2001), np.array(traj.rest_times)])
    t = np.concatenate([t, t + 1e-13])  # also just past each rest
    order = np.random.default_rng(5).permutation(t.size)
    sorted_t = np.sort(t)
    ref = traj._s_all(sorted_t)  # sorted times take another code path
    got = traj._s_all(t[order])
    rank = np.argsort(np.argsort(t[order], kind='stable'), kind='stable')
    for r, g in zip(ref, got):
        np.testing.assert_array_equal(g, r[rank])
