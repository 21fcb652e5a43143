"""The constant-speed law (geodesic_planner.timing.constant_speed, the paper's Lemma 2).

Checked independently of the law's own bookkeeping: the metric speed from the metric tensor of
``core/metric.py`` and the trajectory's joint velocities, the limits on a dense time grid of the
trajectory (joint velocity and acceleration; tool speeds from the geometric Jacobian), the
minimality of T by rescaling the samples in time.
"""
from __future__ import annotations

import numpy as np
import pytest
from timing_paths import check_limits, curved

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import LimitError, TrajectoryError
from geodesic_planner.timing import ConstantSpeed, SmoothRestToRest, check_trajectory, time_parameterize
from geodesic_planner.timing.constant_speed import DEFAULT_RAMP, inverse_shape, shape

ROBOTS = ('planar_3r', 'ur5e', 'panda', 'rrpp')
#: Relative slack on "never above the limit": floating-point round-off only (the law keeps its
#: samples 0.1 % below every limit and refines around the largest ones).
RTOL = 1e-9
#: The metric speed of a solved geodesic is constant in s to the solver's tolerance
#: (test/core/planning_checks.py: SPEED_TOL).
SPEED_TOL = 2e-3
SAMPLES = 20001

_CASES: dict[str, tuple[GeodesicPlanner, object]] = {}


def case(name: str):
    """(planner, path) of one move per preset (the paper's 3R and RRPP moves), planned once."""
    if name not in _CASES:
        robot = load_robot(name.split('.')[0])
        planner = GeodesicPlanner(robot, time_limit=20.0)
        if name == 'planar_3r':
            path = planner.plan_joints([0.258, 0.583, -0.317], [0.969, 0.380, -0.574])
        elif name == 'rrpp':
            path = planner.plan_joints([0.123, -1.539, 0.276, -0.640], [0.129, -1.629, 0.239, -0.643])
        elif name == 'ur5e':
            path = planner.plan_joints(robot.home, robot.home + [0.4, -0.3, 0.2, 0.5, -0.2, 1.0])
        elif name == 'panda':
            path = planner.plan_joints(robot.home, robot.home + [0.3, -0.2, 0.2, 0.3, -0.2, 0.3, 0.4])
        elif name == 'ur5e.via':
            qs = robot.home + np.array([[0, 0, 0, 0, 0, 0], [0.3, 0.1, 0, 0, 0, 0], [0.3, 0.1, 0.2, 0, 0.3, 0]])
            path = planner.plan_through(list(robot.fk(qs)), qs[0])
        else:
            raise KeyError(name)
        _CASES[name] = (planner, path)
    return _CASES[name]


def metric_speed(planner, traj, t):
    """|dq/dt|_G at times t, from the metric tensor and the trajectory's joint velocities."""
    q, dq, _ = traj.at_time(t)
    G = planner.metric.tensor(planner.robot, q)
    return np.sqrt(np.einsum('ni,nij,nj->n', dq, G, dq))


@pytest.mark.parametrize('ramp', [0.0, 0.1, DEFAULT_RAMP])
@pytest.mark.parametrize('name', ROBOTS)
def test_metric_speed_is_constant_between_the_ramps(name, ramp):
    planner, path = case(name)
    traj = time_parameterize(path, law=ConstantSpeed(ramp=ramp))
    T = traj.duration
    t = np.linspace(0.0, T, SAMPLES)
    inside = (t >= ramp * T) & (t <= (1.0 - ramp) * T)
    speed = metric_speed(planner, traj, t)
    # A geodesic of length L has |q'(s)|_G = L; the law moves s at 1 / ((1 - ramp) T) between its ramps.
    expected = path.length / ((1.0 - ramp) * T)
    var = float(np.max(np.abs(speed[inside] - expected)) / expected)
    assert var < SPEED_TOL, f'metric speed varies by {var:.3g} between the ramps'
    if ramp > 0.0:
        # Inside the ramps the speed rises from 0 and falls back to 0, never above the cruise speed.
        assert speed[0] == 0.0 and speed[-1] == 0.0
        assert float(speed.max()) <= expected * (1.0 + SPEED_TOL)
    # The default (smooth, near time-optimal) law does not keep the speed constant: the check can fail.
    smooth = time_parameterize(path)
    ts = np.linspace(0.2 * smooth.duration, 0.8 * smooth.duration, 2001)
    s_speed = metric_speed(planner, smooth, ts)
    assert float((s_speed.max() - s_speed.min()) / s_speed.max()) > 0.05


@pytest.mark.parametrize('ramp', [0.0, 0.1, DEFAULT_RAMP, 0.5])
@pytest.mark.parametrize('name', ROBOTS)
def test_limits_hold_and_a_tenth_less_time_breaks_one(name, ramp):
    _, path = case(name)
    traj = path.timed(law=ConstantSpeed(ramp=ramp))
    rv, ra = check_limits(traj, SAMPLES, RTOL)
    # Minimal: some row binds (within the law's 0.1 % margin and the grid) ...
    assert max(rv, np.sqrt(ra)) >= 0.995
    # ... so the same law 10 % faster (t -> 0.9 t: velocities / 0.9, accelerations / 0.81) breaks it.
    t = np.linspace(0.0, traj.duration, SAMPLES)
    _, dq, ddq = traj.at_time(t)
    fast_v = np.max(np.abs(dq / 0.9) / traj.max_velocity)
    fast_a = np.max(np.abs(ddq / 0.81) / traj.max_acceleration)
    assert max(fast_v, fast_a) > 1.0
    with pytest.raises(LimitError, match='shorter than the minimum'):
        path.timed(law=ConstantSpeed(ramp=ramp), duration=0.9 * traj.duration)


@pytest.mark.parametrize('ramp', [0.0, DEFAULT_RAMP])
@pytest.mark.parametrize('name', ['planar_3r', 'ur5e', 'panda'])
def test_tool_speed_rows_hold_and_bind(name, ramp):
    _, path = case(name)
    robot = path.robot
    free = path.timed(law=ConstantSpeed(ramp=ramp))
    t = np.linspace(0.0, free.duration, SAMPLES)
    q, dq, _ = free.at_time(t)
    twist = np.einsum('nij,nj->ni', robot.jacobian(q), dq)   # base frame, rows [v; ω]
    peak_v = float(np.linalg.norm(twist[:, :3], axis=1).max())
    limit = 0.4 * peak_v
    traj = path.timed(law=ConstantSpeed(ramp=ramp), max_tool_speed=limit)
    assert traj.duration > free.duration
    t = np.linspace(0.0, traj.duration, SAMPLES)
    q, dq, _ = traj.at_time(t)
    v = np.linalg.norm(np.einsum('nij,nj->ni', robot.jacobian(q), dq)[:, :3], axis=1)
    assert float(v.max()) <= limit * (1.0 + RTOL)
    check_limits(traj, SAMPLES, RTOL)
    # Minimal: the tool row binds (the joints' rows allowed 2.5x the speed), and 10 % less time breaks it.
    assert float(v.max()) >= 0.995 * limit
    assert float(v.max()) / 0.9 > limit


@pytest.mark.parametrize('name', ROBOTS)
def test_rest_at_both_ends_with_ramps(name):
    _, path = case(name)
    traj = path.timed(law=ConstantSpeed(ramp=0.1))
    _, dq, ddq = traj.at_time(np.array([0.0, traj.duration]))
    assert np.all(dq == 0.0) and np.all(ddq == 0.0)
    assert np.all(np.isfinite(traj.jerk_at_time(np.linspace(0.0, traj.duration, 1001))))
    # Acceleration continuous (the smoothstep ramps): no jump between neighbouring samples.
    t = np.linspace(0.0, traj.duration, 200001)
    _, _, ddq = traj.at_time(t)
    assert np.max(np.abs(np.diff(ddq, axis=0)) / traj.max_acceleration) < 0.01
    t_s, q_s, _, _ = traj.sample(0.004, check=True)   # JTC accepts it (zero final velocity)
    np.testing.assert_allclose(q_s[[0, -1]], [path.q_start, path.q_goal], atol=1e-12)
    assert traj.rests == (0.0, 1.0) and traj.rest_times == (0.0, traj.duration)


@pytest.mark.parametrize('name', ['planar_3r', 'rrpp'])
def test_pure_law_jumps_in_velocity_and_is_not_rest_to_rest(name):
    _, path = case(name)
    traj = path.timed(law=ConstantSpeed(ramp=0.0))
    s, sd, sdd = traj.s_of_t(np.linspace(0.0, traj.duration, 101))
    np.testing.assert_allclose(s, np.linspace(0.0, 1.0, 101), atol=1e-15)    # s = t / T exactly
    np.testing.assert_allclose(sd, 1.0 / traj.duration, rtol=1e-15)
    assert np.all(sdd == 0.0)
    _, dq, _ = traj.at_time(np.array([0.0, traj.duration]))
    q1 = path.evaluate(np.array([0.0, 1.0]), order=1)[1]
    np.testing.assert_allclose(dq, q1 / traj.duration, rtol=1e-12)
    assert traj.rests == ()
    t, q, dq, ddq = traj.sample(0.004)
    with pytest.raises(TrajectoryError, match='final velocity'):
        check_trajectory(traj.joint_names, t, q, dq, ddq)
    check_trajectory(traj.joint_names, t, q, dq, ddq, require_rest_at_end=False)


def test_via_points_rest_at_each_corner_with_ramps():
    planner, path = case('ur5e.via')
    corner = float(path.breakpoints[1])
    traj = path.timed(law=ConstantSpeed())
    assert traj.rests == pytest.approx((0.0, corner, 1.0), abs=1e-15)
    t_c = traj.rest_times[1]
    s, sd, _ = traj.s_of_t(np.array([t_c]))
    assert s[0] == pytest.approx(corner, abs=1e-15) and sd[0] == 0.0
    check_limits(traj, SAMPLES, RTOL)
    # Constant metric speed inside each piece, between its ramps.
    r = DEFAULT_RAMP
    for t0, t1 in ((0.0, t_c), (t_c, traj.duration)):
        d = t1 - t0
        t = np.linspace(t0 + r * d, t1 - r * d, 2001)
        speed = metric_speed(planner, traj, t)
        assert float(np.ptp(speed) / speed.mean()) < 2 * SPEED_TOL
    with pytest.raises(LimitError, match='corner'):
        path.timed(law=ConstantSpeed(ramp=0.0))


def test_duration_stretches_uniformly():
    planner, path = case('ur5e')
    fast = path.timed(law=ConstantSpeed())
    slow = path.timed(law=ConstantSpeed(), duration=2.0 * fast.duration)
    assert slow.duration == pytest.approx(2.0 * fast.duration, rel=1e-14)
    assert slow.min_duration == fast.min_duration
    t = np.linspace(0.0, fast.duration, 1001)
    np.testing.assert_allclose(metric_speed(planner, slow, 2.0 * t), 0.5 * metric_speed(planner, fast, t),
                               rtol=1e-9, atol=1e-12)


def test_duration_against_the_time_optimal_and_the_smooth_law():
    """The figures quoted with DEFAULT_RAMP: about 1.4-1.6x the time-optimal duration."""
    for name in ROBOTS:
        _, path = case(name)
        traj = path.timed(law=ConstantSpeed())
        smooth = path.timed()
        assert traj.topp_duration == pytest.approx(smooth.topp_duration, rel=1e-9)
        assert 1.3 < traj.optimality_ratio < 1.7, name
        assert traj.duration > smooth.duration


def test_synthetic_path_and_a_stationary_one():
    traj = time_parameterize(curved(), law=ConstantSpeed())
    check_limits(traj, SAMPLES, RTOL)
    planner = GeodesicPlanner(load_robot('planar_3r'))
    still = planner.plan_joints([0.3, 0.5, 0.1], [0.3, 0.5, 0.1]).timed(law=ConstantSpeed())
    assert still.duration == 0.0


def test_shape_derivatives_and_inverse():
    u = np.linspace(0.0, 1.0, 100001)
    h = u[1] - u[0]
    for ramp in (0.0, 0.1, 0.25, 0.5):
        s, d1, d2, d3 = shape(u, ramp)
        assert s[0] == 0.0 and s[-1] == 1.0 and np.all(np.diff(s) >= 0.0)
        # Finite differences of the law (tests only): each derivative integrates to the one below.
        np.testing.assert_allclose(np.diff(s) / h, 0.5 * (d1[1:] + d1[:-1]), atol=1e-6)
        np.testing.assert_allclose(np.diff(d1) / h, 0.5 * (d2[1:] + d2[:-1]), atol=1e-4 / max(ramp, 1.0))
        # The jerk jumps where a ramp meets the constant stretch (sddot is only continuous there).
        same = (np.sign(u[1:] - ramp) == np.sign(u[:-1] - ramp)) & \
            (np.sign(u[1:] - 1.0 + ramp) == np.sign(u[:-1] - 1.0 + ramp))
        np.testing.assert_allclose((np.diff(d2) / h)[same], (0.5 * (d3[1:] + d3[:-1]))[same],
                                   atol=1e-3 / max(ramp, 0.1) ** 2)
        if ramp > 0.0:
            assert d1[0] == d1[-1] == d2[0] == d2[-1] == 0.0
            np.testing.assert_allclose(d1[(u > ramp) & (u < 1.0 - ramp)], 1.0 / (1.0 - ramp), rtol=1e-15)
        np.testing.assert_allclose(shape(inverse_shape(s[::97], ramp), ramp)[0], s[::97], atol=1e-15)


@pytest.mark.parametrize('options, match', [(dict(ramp=-0.1), 'ramp'), (dict(ramp=0.6), 'ramp'),
                                            (dict(ramp='x'), 'ramp'), (dict(ramp=float('nan')), 'ramp'),
                                            (dict(grid_points=1), 'grid_points'),
                                            (dict(check_samples=5), 'check_samples')])
def test_options_out_of_range_are_refused(options, match):
    with pytest.raises(LimitError, match=match):
        ConstantSpeed(**options)


def test_the_law_is_a_time_law_like_the_default():
    _, path = case('planar_3r')
    a = path.timed(law=ConstantSpeed(ramp=0.2))
    b = time_parameterize(path, law=ConstantSpeed(ramp=0.2))
    assert a.duration == b.duration
    assert path.timed(law=SmoothRestToRest()).duration == path.timed().duration
    assert ConstantSpeed(ramp=0.1).rest_to_rest and not ConstantSpeed(ramp=0.0).rest_to_rest
