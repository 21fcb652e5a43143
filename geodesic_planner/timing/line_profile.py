"""The time-optimal jerk-limited rest-to-rest law of a straight joint line, in closed form.

On the line ``q(s) = q_a + s dq`` (a PTP's ``joint_line``) every joint moves in proportion:
``q' = dq``, ``q'' = q''' = 0``, so joint j's velocity, acceleration and jerk are ``dq_j sdot``,
``dq_j sddot`` and ``dq_j sdddot``. Its limits are limits on s:

    |sdot| <= V = min_j vmax_j / |dq_j|,  |sddot| <= A = min_j amax_j / |dq_j|,
    |sdddot| <= J = min_j jmax_j / |dq_j|.

The fastest motion of s from rest at 0 to rest at 1 under three such bounds is the symmetric
7-segment profile (jerk +J, 0, -J, cruise, -J, 0, +J; :func:`seven_segment`): accelerating to a
peak speed ``vp`` takes ``Ta = vp / A + A / J`` when A is reached (``vp >= A^2 / J``), else
``2 sqrt(vp / J)``, and covers ``vp Ta / 2``; ``vp = V`` when ``V Ta(V) <= 1`` (then it cruises),
else ``vp`` solves ``vp Ta(vp) = 1``. It is the time-optimal motion *along the line*: ruckig's
answer with ``Synchronization.Phase`` whenever ruckig keeps to the line (when one joint's velocity
bound and another's acceleration bound bind together, ruckig falls back to timing each joint on its
own, off the line; benchmarks/peers.py says which). The law needs no dense check: every joint's
velocity, acceleration and jerk are ``|dq_j|`` times those of s, at most ``(1 - LINE_MARGIN)``
times the joint's limit by construction.
"""
from __future__ import annotations

import math
import numpy as np

from ..core.errors import LimitError
from .law import final_duration
from .trajectory import Trajectory
from .types import JointLimits, PathLike

__all__ = ['LINE_MARGIN', 'SevenSegment', 'line_bounds', 'seven_segment', 'time_joint_line',
           'trapezoid_duration']

#: Relative margin below every limit (round-off only: the profile is exact). Costs at most this
#: fraction of the duration.
LINE_MARGIN = 1e-6


class SevenSegment:
    """The symmetric 7-segment profile of s from rest at 0 to rest at 1 (a ``TimeScaling``).

    Attributes:
        duration: total time, s.
        knots: start times of the first half's segments (jerk +J, 0, -J, cruise), (4,), s.
        states: s, sdot, sddot at those starts, (4, 3); 1, 1/s, 1/s^2.
        jerks: sdddot on each, (4,), 1/s^3.
        peak_velocity: the largest sdot, 1/s.
        peak_acceleration: the largest sddot, 1/s^2 (A, or below it when A is not reached).

    It is the box filter, over a window ``peak_acceleration / J``, of the bang-bang profile that
    accelerates at ``peak_acceleration`` to ``peak_velocity`` and cruises (:mod:`.jerk` builds it so).
    """

    __slots__ = ('_knots', '_states', 'duration', 'jerks', 'peak_velocity')

    @property
    def peak_acceleration(self) -> float:
        return float(self._states[1][2])

    def __init__(self, duration: float, knots: tuple[float, ...], states: tuple[tuple[float, float, float], ...],
                 jerks: tuple[float, ...], peak_velocity: float) -> None:
        self.duration, self.jerks, self.peak_velocity = duration, np.array(jerks), peak_velocity
        self._knots, self._states = knots, states     # arrays on first use (a law is built per plan)

    @property
    def knots(self) -> np.ndarray:
        return np.array(self._knots)

    @property
    def states(self) -> np.ndarray:
        return np.array(self._states)

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at times ``t`` (M,), s; clipped to [0, duration].

        The second half mirrors the first: ``s(T - tau) = 1 - s(tau)``, so s(T) is exactly 1.
        """
        T = self.duration
        knots, states = self.knots, self.states
        t = np.clip(np.asarray(t, dtype=float), 0.0, T)
        back = t > 0.5 * T
        tau = np.where(back, T - t, t)
        k = np.clip(np.searchsorted(knots, tau, side='right') - 1, 0, 3)
        h = tau - knots[k]
        s0, v0, a0 = states[k, 0], states[k, 1], states[k, 2]
        j = self.jerks[k]
        s = s0 + h * (v0 + h * (0.5 * a0 + h * j / 6.0))
        v = v0 + h * (a0 + 0.5 * h * j)
        a = a0 + h * j
        s = np.where(back, 1.0 - s, s)
        a = np.where(back, -a, a)
        return s, v, a, (j if jerk else None)


def _accel_time(vp: float, A: float, J: float) -> float:
    """Time to accelerate from rest to ``vp`` under A and J, s."""
    return vp / A + A / J if vp * J >= A * A else 2.0 * math.sqrt(vp / J)


def seven_segment(V: float, A: float, J: float) -> SevenSegment:
    """The time-optimal rest-to-rest profile of s over [0, 1] under |sdot| <= V, |sddot| <= A,
    |sdddot| <= J (positive and finite; 1/s, 1/s^2, 1/s^3)."""
    if V * _accel_time(V, A, J) <= 1.0:            # cruises at V
        vp = V
        cruise = (1.0 - V * _accel_time(V, A, J)) / V
    else:
        vp = 0.5 * A * (math.sqrt((A / J) ** 2 + 4.0 / A) - A / J)    # A reached, no cruise
        if vp * J < A * A:                          # A not reached either
            vp = (0.5 * math.sqrt(J)) ** (2.0 / 3.0)
        vp = min(vp, V)
        cruise = 0.0
    if vp * J >= A * A:
        tj, ta = A / J, vp / A - A / J
    else:
        tj, ta = math.sqrt(vp / J), 0.0
    jerks = (J, 0.0, -J, 0.0)
    durations = (tj, ta, tj)
    knots: list[float] = [0.0]
    states: list[tuple[float, float, float]] = [(0.0, 0.0, 0.0)]
    s, v, a, t = 0.0, 0.0, 0.0, 0.0
    for j, h in zip(jerks, durations):
        s, v, a = s + h * (v + h * (0.5 * a + h * j / 6.0)), v + h * (a + 0.5 * h * j), a + h * j
        t += h
        knots.append(t)
        states.append((s, v, 0.0 if j < 0.0 else a))   # the acceleration ramp ends at exactly 0
    # The first half ends half-way through the cruise (at s = 1/2 by the symmetry).
    T = 2.0 * t + cruise
    return SevenSegment(float(T), tuple(knots), tuple(states), jerks, float(vp))


def trapezoid_duration(V: float, A: float) -> float:
    """The v/a time-optimal (bang-bang) rest-to-rest duration of s over [0, 1], s."""
    return 1.0 / V + V / A if V * V <= A else 2.0 / math.sqrt(A)


def line_bounds(dq: np.ndarray, limits: JointLimits, margin: float = LINE_MARGIN
                ) -> tuple[float, float, float]:
    """(V, A, J): the bounds on s's velocity, acceleration and jerk of the line with direction
    ``dq`` (dof,), not all zero, under ``limits`` (``max_jerk`` required), each ``(1 - margin)``
    below the tightest joint's; 1/s, 1/s^2, 1/s^3."""
    assert limits.max_jerk is not None
    d = np.abs(dq)
    k = 1.0 - margin        # max() of a short list: a few µs less than numpy's reductions
    return (k / max((d / limits.max_velocity).tolist()), k / max((d / limits.max_acceleration).tolist()),
            k / max((d / limits.max_jerk).tolist()))


def time_joint_line(path: PathLike, line: tuple[np.ndarray, np.ndarray], limits: JointLimits,
                    duration: float | None) -> Trajectory:
    """The jerk-limited trajectory of the joint line ``line = (q_a, dq)`` (each (dof,)) along
    ``path``: the 7-segment profile, stretched uniformly to ``duration`` when given.

    Raises:
        LimitError: no ``limits.max_jerk``; ``line`` not of the path's size or not finite;
            ``duration`` shorter than the minimum (the message gives it).
    """
    if limits.max_jerk is None:
        raise LimitError('the joint line law needs max_jerk')
    dq = np.asarray(line[1], dtype=float)
    vmax, amax, jmax = limits.max_velocity, limits.max_acceleration, limits.max_jerk
    steps = dq.tolist() if dq.ndim == 1 else []
    if dq.shape != vmax.shape or not math.isfinite(math.fsum(steps)):
        raise LimitError(f'joint_line: expected {vmax.size} finite joint steps, got {dq!r}')
    if not any(steps):
        T = 0.0 if duration is None else duration
        return Trajectory(path=path, joint_names=limits.joint_names, duration=float(T), max_velocity=vmax,
                          max_acceleration=amax, topp_duration=0.0, min_duration=0.0,
                          rest_times=(0.0, float(T)), max_jerk=jmax)
    V, A, J = line_bounds(dq, limits)
    law = seven_segment(V, A, J)
    t_min = law.duration
    T = t_min if duration is None else final_duration(duration, t_min)
    return Trajectory(path=path, joint_names=limits.joint_names, duration=T, max_velocity=vmax,
                      max_acceleration=amax, topp_duration=trapezoid_duration(V, A), min_duration=t_min,
                      rest_times=(0.0, T), scaling=law, time_scale=T / t_min, max_jerk=jmax)
