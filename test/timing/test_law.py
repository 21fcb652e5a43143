"""The time-law seam (geodesic_planner.timing.law): a second law plugs in without touching the timing code."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from geodesic_planner.core.errors import LimitError, TrajectoryError
from geodesic_planner.timing import JointLimits, PathLike, Trajectory, check_trajectory, time_parameterize
from timing_paths import curved


@dataclass(frozen=True)
class _LinearScaling:
    """s(t) = t / T: constant path speed (moves at both ends, so not rest-to-rest)."""

    duration: float

    def evaluate(self, t, jerk=True):
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        z = np.zeros_like(t)
        return t / self.duration, np.full_like(t, 1.0 / self.duration), z, (z if jerk else None)


class ConstantPathSpeed:
    """A trivial second law: constant sdot, the slowest joint at its velocity limit on its worst sample."""

    def __call__(self, path: PathLike, limits: JointLimits, duration: float | None) -> Trajectory:
        s = np.linspace(0.0, 1.0, 201)
        _, q1 = path.evaluate(s, order=1)
        t_min = float(np.max(np.abs(q1) / limits.max_velocity))
        T = t_min if duration is None else duration
        if t_min > T:
            raise LimitError(f'duration {T} s is shorter than the minimum {t_min} s')
        return Trajectory(path=path, joint_names=limits.joint_names, duration=T,
                          max_velocity=limits.max_velocity, max_acceleration=limits.max_acceleration,
                          topp_duration=t_min, min_duration=t_min, scaling=_LinearScaling(T))


def test_a_second_law_plugs_in_through_the_protocol():
    path = curved()
    traj = time_parameterize(path, 2.0, 3.0, law=ConstantPathSpeed())
    assert traj.joint_names == ['j1', 'j2', 'j3']
    np.testing.assert_array_equal(traj.max_velocity, 2.0)  # the entry validated and broadcast it
    t, q, dq, ddq = traj.sample(0.01)
    s = t / traj.duration
    np.testing.assert_allclose(q, path.evaluate(s)[0], atol=1e-12)
    np.testing.assert_allclose(dq, path.evaluate(s)[1] / traj.duration, atol=1e-12)
    # Constant speed does not end at rest: the controller rules say so.
    with pytest.raises(TrajectoryError, match='final velocity'):
        check_trajectory(traj.joint_names, t, q, dq, ddq)
    check_trajectory(traj.joint_names, t, q, dq, ddq, require_rest_at_end=False)


def test_entry_validates_limits_and_duration_before_any_law_runs():
    calls = []

    def law(path, limits, duration):
        calls.append(duration)
        raise AssertionError('not reached')

    with pytest.raises(LimitError, match="joint 'j2'"):
        time_parameterize(curved(), [1.0, -1.0, 1.0], 1.0, law=law)
    with pytest.raises(LimitError, match='duration'):
        time_parameterize(curved(), 1.0, 1.0, duration=-1.0, law=law)
    assert calls == []


def test_scaled_limits_is_time_scaling_with_factors_one() -> None:
    """f = 0.5: velocities x 0.5, accelerations x 0.25, jerks x 0.125; the factors multiply
    velocities (tool speeds too) and accelerations only."""
    import numpy as np

    from geodesic_planner.timing.law import scaled_limits

    v, a, j = np.array([1.0, 2.0]), np.array([4.0, 8.0]), np.array([16.0, 32.0])
    out = scaled_limits(v, a, 0.5, max_jerk=j, max_tool_speed=1.0, max_tool_angular_speed=2.0)
    np.testing.assert_array_equal(out['max_velocity'], [0.5, 1.0])
    np.testing.assert_array_equal(out['max_acceleration'], [1.0, 2.0])
    np.testing.assert_array_equal(out['max_jerk'], [2.0, 4.0])
    assert out['max_tool_speed'] == 0.5 and out['max_tool_angular_speed'] == 1.0
    out = scaled_limits(v, a, 1.0, 0.5, 0.25)
    np.testing.assert_array_equal(out['max_velocity'], [0.5, 1.0])
    np.testing.assert_array_equal(out['max_acceleration'], [1.0, 2.0])
    assert set(out) == {'max_velocity', 'max_acceleration'}
