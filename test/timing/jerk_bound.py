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


def greedy_speed(time: npt.ArrayLike, max_velocity: npt.ArrayLike, max_acceleration: npt.ArrayLike,
                 max_jerk: npt.ArrayLike) -> np.ndarray:
    """The largest speed a 1-D motion that started at rest can have ``time`` later, element-wise.

    Jerk +jmax until amax (or until the ramp down must begin), amax held, jerk -jmax so that the
    acceleration reaches 0 exactly at vmax, then vmax: the acceleration phase of the 7-segment
    profile. No admissible motion from rest is faster at any instant (nor, backwards in time, any
    motion ``time`` before it comes to rest).
    """
    t = np.asarray(time, dtype=float)
    v, a, j = (np.asarray(x, dtype=float) for x in (max_velocity, max_acceleration, max_jerk))
    full = v * j >= a * a
    t1 = np.where(full, a / j, np.sqrt(v / j))          # the jerk +J phase (and the -J phase)
    a1 = j * t1                                          # the peak acceleration
    t2 = np.where(full, v / a - a / j, 0.0)              # amax held
    v1 = j * t1**2 / 2.0
    v2 = v1 + a1 * t2
    h = t - t1 - t2
    return np.where(t <= t1, j * np.clip(t, 0.0, None) ** 2 / 2.0,
                    np.where(t <= t1 + t2, v1 + a1 * (t - t1), np.where(h <= t1, v2 + a1 * h - j * h**2 / 2.0, v)))


def _reach(T: np.ndarray, dq: np.ndarray, x_star: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray,
           steps: int) -> np.ndarray:
    """How far along s (uniform grid of dq's rows) the relaxed law of :func:`coupled_lower_bound`
    gets by time T, for each T (K,)."""
    n = dq.shape[0] - 1
    inv = 1.0 / np.maximum(np.abs(dq), 1e-300)
    inv_cell = np.maximum(inv[:-1], inv[1:])             # the largest 1/|q'_j| over each cell
    root_cell = np.sqrt(np.maximum(np.maximum(x_star[:-1], x_star[1:]), 0.0))
    sigma = np.zeros(T.size)
    dt = T / steps
    for k in range(steps):
        i = np.minimum((sigma * n).astype(int), n - 1)
        i2 = np.minimum(i + 1, n - 1)                    # the step may end in the next cell
        speed = np.minimum(greedy_speed(((k + 1) * dt)[:, None], v, a, j),          # since the start
                           greedy_speed((T - k * dt)[:, None], v, a, j))            # until the end
        cap = np.minimum(np.maximum(root_cell[i], root_cell[i2]),
                         (speed * np.maximum(inv_cell[i], inv_cell[i2])).min(axis=1))
        sigma = np.minimum(sigma + dt * cap, 1.0 + 1e-9)
    return sigma


def coupled_lower_bound(dq: npt.ArrayLike, x_star: npt.ArrayLike, max_velocity: npt.ArrayLike,
                        max_acceleration: npt.ArrayLike, max_jerk: npt.ArrayLike, lo: float, hi: float,
                        steps: int = 2000, candidates: int = 16, rounds: int = 3) -> float:
    """Lower bound on the duration of a jerk-limited rest-to-rest motion along a path, s (numerical).

    ``dq`` (N, dof): the path's q' at N uniform s in [0, 1]; ``x_star`` (N,): the v/a time-optimal
    sdot^2 there (every law within the v/a limits has sdot^2 <= x_star at every s). Joint j's
    speed ``|q'_j(s)| sdot`` is at most :func:`greedy_speed` of the time since the start, and of
    the time until the end T. So any law of duration T has ``sdot <= F_T(s, t) = min(sqrt(x_star),
    min_j greedy_j(t) / |q'_j|, min_j greedy_j(T - t) / |q'_j|)``, and by the comparison of 1-D
    ODEs its s(t) stays below the solution of ``sigma' = F_T(sigma, t)`` from 0, which therefore
    reaches 1 by T. F_T grows with T, so the smallest such T is found by bisection in [lo, hi]
    (``rounds`` of ``candidates`` durations, ``hi`` an admissible duration). The integration takes
    ``steps`` explicit steps, each with F's s-dependent caps at their largest over the sample cell
    and the next, and the speeds at the step's later start-side and earlier end-side times (the
    larger ones): first order, on the bound's side up to the cells' interpolation. It couples the
    joints through the path (unlike the per-joint bound) but keeps only their velocities' ramps:
    on a straight line it is the 7-segment optimum when that cruises, below it when not (the
    ramps from both ends meet in a kink).
    """
    dqa, xs = np.asarray(dq, dtype=float), np.asarray(x_star, dtype=float)
    v, a, j = (np.broadcast_to(np.asarray(x, dtype=float), dqa.shape[1:]) for x in (max_velocity, max_acceleration,
                                                                                      max_jerk))
    for _ in range(rounds):
        T = np.linspace(lo, hi, candidates)
        ok = _reach(T, dqa, xs, v, a, j, steps) >= 1.0
        k = int(np.argmax(ok)) if ok.any() else candidates - 1
        lo, hi = (float(T[k - 1]) if k > 0 else lo), float(T[k])
    return lo


__all__ = ['coupled_lower_bound', 'greedy_speed', 'min_rest_to_rest_time', 'rest_to_rest_lower_bound']
