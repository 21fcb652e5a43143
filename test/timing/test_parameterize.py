"""The entry time_parameterize with the default (smooth rest-to-rest) law: oracles, limits, options."""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner.core.errors import GeodesicPlannerError, LimitError
from geodesic_planner.timing import time_parameterize
from timing_paths import (OPTIMALITY_FACTOR, CornerPath, PolyPath, ZigZagPath, _ur5e_line_path, check_limits,
                          curved, line_time, lp_topp_duration)


@pytest.mark.parametrize('length, vmax, amax', [(1.0, 1.0, 2.0), (0.2, 1.0, 2.0), (3.0, 0.5, 0.4)])
def test_straight_line_against_bang_bang_oracle(length, vmax, amax):
    # q(s) = q0 + s * length * dir; joint 2 moves half as far, so joint 1 limits.
    path = PolyPath([[0.3, -0.2], [length, -0.5 * length]], vmax, amax)
    traj = time_parameterize(path)
    # trapezoid, or triangle when the top speed is never reached
    t_opt = length / vmax + vmax / amax if length >= vmax**2 / amax else 2.0 * np.sqrt(length / amax)
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
    # the collocation geodesic the fuzzer found (a LIN between these joints is refused since issue 36)
    path = GeodesicPlanner(robot).plan(None, None, start_joints=q_a, goal_joints=q_b, method='collocation')
    traj = path.timed()
    rv, ra = check_limits(traj, n=40001)
    assert max(rv, ra) > 0.99
    assert traj.optimality_ratio <= OPTIMALITY_FACTOR
