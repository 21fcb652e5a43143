"""Lower bound on the duration of a jerk-limited motion: the per-joint 7-segment minimum time.

A rest-to-rest move of one joint over a distance ``d`` with limits ``|v| <= vmax``,
``|a| <= amax``, ``|j| <= jmax`` takes at least the time of the classic symmetric 7-segment
profile (jerk +-jmax, acceleration trapezoid or triangle, optional cruise), in closed form:

* accelerating from rest to a speed ``v`` takes ``Ta(v) = v / amax + amax / jmax`` if
  ``v >= amax^2 / jmax`` (amax is reached), else ``2 sqrt(v / jmax)``; it covers ``v Ta(v) / 2``.
* if ``d >= vmax Ta(vmax)`` the move cruises: ``T = Ta(vmax) + d / vmax``;
* otherwise the peak speed ``vp < vmax`` solves ``d = vp Ta(vp)`` and ``T = 2 Ta(vp)``:
  ``vp = amax (sqrt((amax / jmax)^2 + 4 d / amax) - amax / jmax) / 2`` if that is
  ``>= amax^2 / jmax``, else ``T = 4 (d / (2 jmax))^(1/3)``.

Any joint trajectory from rest to rest within the limits takes at least this time for each
joint's net displacement, so the largest over the joints bounds every synchronized jerk-limited
trajectory (a path that rests at corners: the sum over its rest-to-rest pieces). Independent of
the time laws: the benchmark and the tests compare the jerk-limited law against it.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt


def min_rest_to_rest_time(distance: npt.ArrayLike, max_velocity: npt.ArrayLike,
                          max_acceleration: npt.ArrayLike, max_jerk: npt.ArrayLike) -> np.ndarray:
    """Minimum time of a 1-D rest-to-rest move (7-segment profile), element-wise, s.

    Args:
        distance: |displacement|, any shape (broadcast with the limits); rad or m.
        max_velocity, max_acceleration, max_jerk: positive limits; rad/s, rad/s^2, rad/s^3 (or m).
    Returns:
        The minimum times, broadcast shape; 0 where the distance is 0.
    """
    d = np.abs(np.asarray(distance, dtype=float))
    v, a, j = (np.asarray(x, dtype=float) for x in (max_velocity, max_acceleration, max_jerk))
    d, v, a, j = np.broadcast_arrays(d, v, a, j)
    full = v >= a * a / j                               # amax reached on the way to vmax
    ta_v = np.where(full, v / a + a / j, 2.0 * np.sqrt(v / j))
    cruise = d >= v * ta_v
    t_cruise = ta_v + d / np.where(v > 0, v, 1.0)
    # No cruise: peak speed below vmax.
    vp_a = 0.5 * a * (np.sqrt((a / j) ** 2 + 4.0 * d / a) - a / j)
    t_a = 2.0 * (vp_a / a + a / j)
    t_j = 4.0 * np.cbrt(d / (2.0 * j))
    t_peak = np.where(vp_a >= a * a / j, t_a, t_j)
    return np.asarray(np.where(d > 0.0, np.where(cruise, t_cruise, t_peak), 0.0), dtype=float)


def rest_to_rest_lower_bound(q_rests: npt.ArrayLike, max_velocity: npt.ArrayLike,
                             max_acceleration: npt.ArrayLike, max_jerk: npt.ArrayLike) -> float:
    """Lower bound on the duration of a jerk-limited motion through the rests ``q_rests``, s.

    Args:
        q_rests: joint positions at the rests in order (both ends and any corners where the
            motion stops), shape (K, dof), K >= 1; rad or m.
        max_velocity, max_acceleration, max_jerk: per-joint limits, shape (dof,) or scalars.
    Returns:
        ``sum_k max_i T_i(|q_{k+1, i} - q_{k, i}|)`` with T the 7-segment minimum time.
    """
    q = np.atleast_2d(np.asarray(q_rests, dtype=float))
    if q.shape[0] < 2:
        return 0.0
    t = min_rest_to_rest_time(np.diff(q, axis=0), max_velocity, max_acceleration, max_jerk)
    return float(t.max(axis=1).sum())


__all__ = ['min_rest_to_rest_time', 'rest_to_rest_lower_bound']
