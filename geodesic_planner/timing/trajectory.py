"""The timed trajectory: a path with a time law, ``q(t) = q(s(t))``, sampled exactly from the path."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from ._arrays import clip
from .sampling import path_derivatives
from .validate import check_trajectory

#: Samples evaluated at once by :meth:`Trajectory.sample` between two cancellation checkpoints
#: (tens of ms of work; the values do not depend on it).
SAMPLE_BLOCK = 4096

if TYPE_CHECKING:
    from .types import PathLike, TimeScaling


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A path with a time law: ``q(t) = path.q(s(t))``, rest-to-rest.

    Attributes:
        path: the geometric path (unchanged).
        joint_names: joint names, length dof.
        duration: total time, s.
        max_velocity, max_acceleration: limits used, shape (dof,); rad/s (m/s), rad/s^2 (m/s^2).
        topp_duration: time-optimal (bang-bang, non-smooth) duration along the path, s.
        min_duration: fastest smooth rest-to-rest duration this module builds, s (>= topp_duration).
        rests: path parameters s where the motion comes to rest (0, corners of the path, 1).
        rest_times: the times of those rests, s (first 0, last ``duration``).
        scaling: the law's ``s(t)`` (None for a stationary path: s jumps from 0 to 1 at the end).
        time_scale: trajectory time per time of ``scaling`` (>= 1: uniformly stretched).
        max_tool_speed: limit used on the linear speed of the tool frame origin (base frame), m/s;
            None: none.
        max_tool_angular_speed: limit used on the norm of the tool's angular velocity, rad/s;
            None: none.
        max_jerk: jerk limit used, shape (dof,), rad/s^3 (m/s^3); None: none (the law bounds
            the jerk but does not limit it).
    """

    path: PathLike
    joint_names: list[str]
    duration: float
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    topp_duration: float
    min_duration: float
    rests: tuple[float, ...] = (0.0, 1.0)
    rest_times: tuple[float, ...] = ()
    scaling: TimeScaling | None = field(repr=False, default=None)
    time_scale: float = field(repr=False, default=1.0)
    max_tool_speed: float | None = None
    max_tool_angular_speed: float | None = None
    max_jerk: np.ndarray | None = None

    @property
    def optimality_ratio(self) -> float:
        """``min_duration / topp_duration`` (1.0 is the non-smooth optimum; nan if stationary)."""
        if self.topp_duration <= 0.0:
            return float('nan')
        return self.min_duration / self.topp_duration

    def s_of_t(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path parameter and its time derivatives.

        Args:
            t: times, shape (M,) (or scalar), s; clipped to [0, duration].
        Returns:
            (s, sdot, sddot), each (M,); 1, 1/s, 1/s^2.
        """
        s, sd, sdd, _ = self._s_all(t)
        return s, sd, sdd

    def _s_all(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not np.all(np.isfinite(t)):
            raise LimitError('times must be finite')
        if self.scaling is None:  # stationary path
            one = (t >= self.duration).astype(float)
            z = np.zeros_like(t)
            return one, z, z, z
        lam = self.time_scale
        tl = np.where(t >= self.duration, self.scaling.duration, clip(t, 0.0, self.duration) / lam)
        s, sd, sdd, sddd = self.scaling.evaluate(tl)
        assert sddd is not None  # asked for (jerk=True)
        return s, sd / lam, sdd / lam**2, sddd / lam**3

    def at_time(self, t: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions, velocities and accelerations at times ``t``.

        Args:
            t: times, shape (M,), s; clipped to [0, duration].
        Returns:
            (q, dq, ddq), each (M, dof); rad (m), rad/s (m/s), rad/s^2 (m/s^2).
        """
        s, sd, sdd = self.s_of_t(t)
        q, q1, q2 = path_derivatives(self.path, s, 2)
        q1 = np.asarray(q1)
        return np.asarray(q), q1 * sd[:, None], q1 * sdd[:, None] + np.asarray(q2) * (sd**2)[:, None]

    def jerk_at_time(self, t: npt.ArrayLike) -> np.ndarray:
        """Joint jerk d3q/dt3 at times ``t`` (M,) -> (M, dof); rad/s^3 (m/s^3)."""
        s, sd, sdd, sddd = self._s_all(t)
        _, q1, q2, q3 = path_derivatives(self.path, s, 3)
        return (np.asarray(q1) * sddd[:, None] + 3.0 * np.asarray(q2) * (sd * sdd)[:, None]
                + np.asarray(q3) * (sd**3)[:, None])

    def times(self, dt: float) -> np.ndarray:
        """Sample times 0, dt, 2 dt, ..., duration (last exactly at duration), s."""
        try:
            dt = float(dt)
        except (TypeError, ValueError) as err:
            raise LimitError(f'dt must be a number, got {dt!r}') from err
        if not (math.isfinite(dt) and dt > 0.0):
            raise LimitError(f'dt must be positive and finite, got {dt!r}')
        T = self.duration
        if T <= 0.0:
            return np.zeros(1)
        n = math.floor(T / dt + 1e-9)
        t = np.arange(n + 1, dtype=float) * dt
        if T - t[-1] <= max(1e-9, 1e-6 * dt):
            t[-1] = T
            if t.size > 1 and t[-1] <= t[-2]:
                t = t[:-1]
                t[-1] = T
        else:
            t = np.append(t, T)
        return t

    def sample(self, dt: float, *, check: bool = False
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Uniform samples in time.

        Args:
            dt: time step, s (> 0).
            check: also validate the samples as joint_trajectory_controller would
                (:func:`~geodesic_planner.timing.validate.check_trajectory`, at rest at the end).
        Returns:
            (t, q, dq, ddq): t (M,) from 0 to duration inclusive, the last sample exactly at
            ``duration`` (so the last step may be shorter than dt); the others (M, dof).
        Raises:
            LimitError: dt not positive and finite.
            TrajectoryError: ``check`` and the samples would be rejected (e.g. dt below 1 ns).
        """
        t = self.times(dt)
        blocks = []
        for i in range(0, t.size, SAMPLE_BLOCK):
            checkpoint()
            blocks.append(self.at_time(t[i:i + SAMPLE_BLOCK]))
        q, dq, ddq = (np.concatenate(arrays) for arrays in zip(*blocks))
        if check:
            check_trajectory(self.joint_names, t, q, dq, ddq)
        return t, q, dq, ddq

    def max_limit_ratios(self, samples: int = 4001) -> tuple[float, float]:
        """Largest |dq|/vmax and |ddq|/amax over ``samples`` uniform times (diagnostic)."""
        t = np.linspace(0.0, self.duration, max(int(samples), 2))
        _, dq, ddq = self.at_time(t)
        return (float(np.max(np.abs(dq) / self.max_velocity)),
                float(np.max(np.abs(ddq) / self.max_acceleration)))


__all__ = ['Trajectory']
