"""The closed-form jerk-limited law of a straight joint line (geodesic_planner.timing.line_profile).

Every figure is checked independently of the law: the limits by exact derivatives
(``Trajectory.at_time``, ``jerk_at_time``) on a dense grid and by finite differences of the
positions sampled at 1 kHz; the duration against the 7-segment minimum time of
test/timing/jerk_bound.py (itself checked against a linear program in test_jerk.py), which is the
optimum along the line when one joint's limits bind.
"""
from __future__ import annotations

import numpy as np
import pytest
from test_jerk import check_jerk_law

from geodesic_planner import load_robot
from geodesic_planner.core.errors import LimitError
from geodesic_planner.core.ptp import JointLinePath
from geodesic_planner.timing import JerkLimited, time_parameterize
from geodesic_planner.timing.line_profile import LINE_MARGIN, SevenSegment, seven_segment
from jerk_bound import min_rest_to_rest_time

#: 1 kHz, the controllers' rate.
DT = 1e-3


def line(robot_name: str = 'ur5e', step: float | np.ndarray = 0.5, seed: int = 0) -> JointLinePath:
    robot = load_robot(robot_name)
    q_a = robot.home + np.random.default_rng(seed).uniform(-0.3, 0.3, robot.dof)
    return JointLinePath(robot, q_a, q_a + step)


def check_finite_differences(traj, vmax: np.ndarray, amax: np.ndarray, jmax: np.ndarray) -> None:
    """Positions sampled at 1 kHz: their differences agree with the exact derivatives and stay
    within the limits (a difference quotient is a mean of the derivative it approximates)."""
    t, q, dq, ddq = traj.sample(DT)
    h = np.diff(t)[:, None]
    v_fd = np.diff(q, axis=0) / h
    assert np.all(np.abs(v_fd) <= vmax * (1.0 + 1e-9))
    # the trapezoid rule of the exact velocities, to its error bound jmax dt^2 / 12
    np.testing.assert_allclose(v_fd, 0.5 * (dq[1:] + dq[:-1]), atol=jmax.max() * DT ** 2 / 12.0 * (1.0 + 1e-6))
    a_fd = np.diff(dq, axis=0) / h
    assert np.all(np.abs(a_fd) <= amax * (1.0 + 1e-9))
    j_fd = np.diff(ddq, axis=0) / h
    assert np.all(np.abs(j_fd) <= jmax * (1.0 + 1e-9))
    np.testing.assert_array_equal(dq[-1], 0.0)


@pytest.mark.parametrize('robot_name', ['ur5e', 'panda', 'planar_3r'])
@pytest.mark.parametrize('step', [0.01, 0.2, 1.5])
@pytest.mark.parametrize('jerk', [10.0, 50.0, 1000.0])
def test_line_is_the_per_joint_optimum(robot_name: str, step: float, jerk: float) -> None:
    """Equal steps and limits of one joint binding: the law's duration is the slowest joint's own
    7-segment minimum time (to LINE_MARGIN), and every limit holds."""
    path = line(robot_name, step)
    robot = path.robot
    traj = path.timed(max_jerk=jerk)
    jmax = np.full(robot.dof, jerk)
    check_jerk_law(traj, jmax)
    check_finite_differences(traj, robot.max_velocity, robot.max_acceleration, jmax)
    q_a, dq = path.joint_line
    best = float(min_rest_to_rest_time(np.abs(dq), robot.max_velocity, robot.max_acceleration, jmax).max())
    assert best <= traj.duration <= best * (1.0 + 2.0 * LINE_MARGIN)
    np.testing.assert_array_equal(traj.at_time(np.array([traj.duration]))[0][0], q_a + dq)


def test_mixed_limits_time_the_line_under_the_tightest_bounds() -> None:
    """Joint 1's velocity and joint 2's acceleration bind: along the line the optimum is the
    1-D minimum time under both bounds on s, longer than each joint's own optimum."""
    robot = load_robot('ur5e')
    dq = np.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0])
    path = JointLinePath(robot, robot.home, robot.home + dq)
    vmax = np.array([0.5, 10.0, 1.0, 1.0, 1.0, 1.0])
    amax = np.array([10.0, 0.5, 1.0, 1.0, 1.0, 1.0])
    jmax = np.full(6, 100.0)
    traj = path.timed(max_velocity=vmax, max_acceleration=amax, max_jerk=jmax)
    check_jerk_law(traj, jmax)
    check_finite_differences(traj, vmax, amax, jmax)
    own = min_rest_to_rest_time(1.0, vmax[:2], amax[:2], jmax[:2])
    on_line = float(min_rest_to_rest_time(1.0, 0.5, 0.5, 100.0))
    assert own.max() < 0.95 * on_line
    assert on_line <= traj.duration <= on_line * (1.0 + 2.0 * LINE_MARGIN)
    # the line is kept: both joints at the same fraction of their step at every time
    q = traj.at_time(np.linspace(0.0, traj.duration, 501))[0] - robot.home
    np.testing.assert_allclose(q[:, 0], q[:, 1], atol=1e-15)


@pytest.mark.parametrize(('V', 'A', 'J'), [
    (1.0, 2.0, 20.0),    # cruise, A reached
    (1.0, 2.0, 1.0),     # cruise, A not reached
    (5.0, 2.0, 20.0),    # no cruise, A reached
    (5.0, 2.0, 5.0),     # no cruise, A not reached
])
def test_seven_segment_profile(V: float, A: float, J: float) -> None:
    """Ends at rest at exactly 1; within V, A, J; continuous; the minimum time."""
    law = seven_segment(V, A, J)
    assert isinstance(law, SevenSegment)
    assert law.duration == pytest.approx(float(min_rest_to_rest_time(1.0, V, A, J)), rel=1e-12)
    t = np.linspace(0.0, law.duration, 200001)
    s, v, a, j = law.evaluate(t)
    assert s[0] == 0.0 and s[-1] == 1.0 and v[0] == 0.0 and v[-1] == 0.0
    assert np.all(np.diff(s) >= 0.0)
    assert v.max() <= V * (1.0 + 1e-12) and np.abs(a).max() <= A * (1.0 + 1e-12)
    assert np.abs(j).max() <= J
    dt = t[1] - t[0]
    np.testing.assert_allclose(np.diff(s) / dt, 0.5 * (v[1:] + v[:-1]), atol=J * dt ** 2)
    np.testing.assert_allclose(np.diff(v) / dt, 0.5 * (a[1:] + a[:-1]), atol=J * dt)
    assert np.abs(np.diff(a)).max() <= J * dt * (1.0 + 1e-9)


def test_duration_stationary_and_tool_limits() -> None:
    path = line()
    fast = path.timed(max_jerk=20.0)
    slow = path.timed(max_jerk=20.0, duration=1.7 * fast.duration)
    assert slow.duration == 1.7 * fast.duration
    check_jerk_law(slow, np.full(6, 20.0))
    with pytest.raises(LimitError, match='shorter than the minimum'):
        path.timed(max_jerk=20.0, duration=0.99 * fast.duration)
    still = line(step=0.0).timed(max_jerk=20.0)
    assert still.duration == 0.0 and still.scaling is None
    # explicit JerkLimited: the same closed form; a tool limit: the general law (its own checks)
    assert time_parameterize(path, max_jerk=20.0, law=JerkLimited()).duration == fast.duration
    tool = path.timed(max_jerk=20.0, max_tool_speed=0.2)
    assert not isinstance(tool.scaling, SevenSegment) and tool.duration > fast.duration
