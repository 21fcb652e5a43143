"""The Trajectory type (geodesic_planner.timing.trajectory): chain rule, sampling grid."""
from __future__ import annotations

import numpy as np

from geodesic_planner.timing import time_parameterize
from timing_paths import curved


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


def test_checked_samples_pass_the_controller_rules():
    traj = time_parameterize(curved())
    t, q, dq, ddq = traj.sample(0.01, check=True)
    assert t[-1] == traj.duration and np.all(dq[-1] == 0.0)


def test_tiny_move_at_the_elbow_singularity_keeps_its_limits():
    # A 2-microradian ur5e move next to the elbow singularity (the slow fuzz case of
    # test_fuzz_singular_slow): the solver's spline, whose positions the trajectory gives, has a
    # q'' 2e-8 away from the geodesic equations' between its mesh nodes, and on so short a path
    # sdot^2 reaches 1e6. The trajectory's accelerations are the derivatives of its velocities
    # (the spline's), the ones the law was checked on: within the limits, and consistent.
    from geodesic_planner import GeodesicPlanner, load_robot
    robot = load_robot('ur5e')
    q_a = np.array([0.0, 0.0, 0.01, 0.0, 1.0, 0.0])
    q_b = q_a + np.array([0.0, 0.0, -2e-6, -1e-6, 0.0, 0.0])
    path = GeodesicPlanner(robot).plan(None, None, q_a, q_b)
    traj = path.timed()
    t = np.linspace(0.0, traj.duration, 4001)
    q, dq, ddq = traj.at_time(t)
    assert (np.abs(dq) / robot.max_velocity).max() <= 1.0
    assert (np.abs(ddq) / robot.max_acceleration).max() <= 1.0       # 1.00017 with the equations' q''
    # ddq is the time derivative of dq (central differences, interior samples)
    fd = (dq[2:] - dq[:-2]) / (t[2:] - t[:-2])[:, None]
    np.testing.assert_allclose(ddq[1:-1], fd, atol=1e-3 * robot.max_acceleration.max())
