"""Timing planner paths (path.timed): limits respected between mesh nodes, no overshoot, bad limits named."""
from __future__ import annotations

import numpy as np
from planning_checks import Q3_A, Q3_B, expect_error, guarded, sample_path

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import LimitError


def test_regression_bad_time_limits(planar: GeodesicPlanner) -> None:
    path = planar.plan(None, None, Q3_A, Q3_B)
    expect_error('regression', lambda: path.timed(max_velocity=[1.0, 0.0, 1.0]), LimitError,
                 r"^max_velocity for joint 'joint2' must be positive and finite, "
                 r"got (np\.float64\()?0\.0\)? \(requested\)$")
    expect_error('regression', lambda: path.timed(max_acceleration=np.nan), LimitError,
                 r"^max_acceleration for joint 'joint1' must be positive and finite, got (np\.float64\()?nan")
    expect_error('regression', lambda: path.timed(max_velocity=[1.0, 1.0]), LimitError,
                 r'^max_velocity: expected 1 or 3 values \(one per joint\), got 2$')
    t_min = path.timed().duration
    expect_error('regression', lambda: path.timed(duration=0.5 * t_min), LimitError,
                 rf'^duration {0.5 * t_min:.6g} s is shorter than the minimum {t_min:.6g} s for these limits$')
    expect_error('regression', lambda: path.timed(duration=-1.0), LimitError, r'duration must be finite and >= 0')


# ---------------------------------------------------------------------------------------- known bugs
# Found by the fuzzer; strict xfail until the library is fixed (then they XPASS: drop the mark, and
# the matching 'known bugs' allowance in the fuzz checks above).
def test_regression_timing_overshoot() -> None:
    """Found by the fuzzer: timed() once exceeded the acceleration limit by 2.6 % on this panda
    geodesic (its limit check used interpolated path derivatives). Checked here on the exact path."""
    robot = load_robot('panda')
    q_a = [0.6647, -0.6792, 2.0275, -1.3748, 2.4197, 1.5174, 0.0113]
    q_b = [1.4129, 0.4855, 0.7249, -1.6125, 1.3656, 2.5324, 2.6255]
    path = GeodesicPlanner(robot).plan(None, None, q_a, q_b, method='collocation')   # the G + εI geodesic
    traj = path.timed()
    t = np.linspace(0.0, traj.duration, 20001)
    _, dq, ddq = traj.at_time(t)
    assert np.max(np.abs(dq) / robot.max_velocity) <= 1.0
    assert np.max(np.abs(ddq) / robot.max_acceleration) <= 1.0


def test_regression_timing_velocity_overshoot() -> None:
    """Found by the fuzzer: timed() exceeded small velocity limits by up to 1.3 % on this piecewise
    UR5e path (joint 4 near the end of a 327 s law: its check samples, uniform in t, were too
    sparse where the law crosses much of s in a second; now also sampled uniformly in s)."""
    path = sample_path('ur5e.piecewise')
    vmax = np.array([0.001, 1.0, 1.0, 0.00390625, 1.0, 1.0])
    traj = path.timed(vmax)
    t = np.linspace(0.0, traj.duration, 20001)
    dq = traj.at_time(t)[1]
    ratio = float(np.max(np.abs(dq) / vmax))
    assert ratio <= 1.0, f'max |dq| / vmax = {ratio:.7f}'


def test_regression_limits_between_mesh_nodes() -> None:
    """Found by the fuzzer: the limit check looked at the mesh nodes only, and the spline of this
    panda path went 1.03e-5 rad below joint 5's lower limit between them."""
    robot = load_robot('panda')
    q_a = [0.2298, -1.3294, -0.179, -2.3772, -2.8973, 3.6699, 1.2618]   # joint 5 on its lower limit
    q_b = [0.2133, -1.1278, -0.4356, -2.4423, -2.8973, 3.7525, 1.4748]
    out = guarded('regression', lambda: GeodesicPlanner(robot).plan(None, None, q_a, q_b))
    if out.value is not None:  # a LimitError naming joint 5 would be fine too
        q = out.value.evaluate(np.linspace(0.0, 1.0, 20001))[0]
        below = float(np.max(robot.lower - q))
        assert below <= 1e-9, f'{below:.3g} rad below a lower limit between mesh nodes'
