"""Uniform resampling and velocity scaling of joint trajectories (pure numpy, no ROS).

The interpolation between the incoming waypoints follows ros2_controllers'
joint_trajectory_controller (``doc/trajectory.rst``), so a resampled trajectory is the one the
controller would have executed from the original waypoints:

* positions, velocities and accelerations all given: **quintic Hermite** polynomial per segment,
  matching position, velocity and acceleration at both ends (C2 across waypoints);
* positions and velocities given: **cubic Hermite** per segment (C1; the acceleration of each
  output point is the cubic's second derivative);
* positions only: the controller would interpolate linearly, which has velocity jumps at every
  waypoint and never ends at rest. We use instead a **C2 cubic spline clamped to zero velocity at
  both ends** (through every waypoint, at rest at start and end). Accelerations given without
  velocities are ignored (same case).

Velocity scaling is time scaling (``doc/speed_scaling.rst``): with factor f in (0, 1], times are
divided by f (the trajectory lasts 1/f as long), velocities multiplied by f and accelerations by
f**2; positions, and hence the path, are unchanged. Quintic and cubic Hermite interpolation
commute with this scaling, so ``resample(*scale_velocity(...))`` is exactly the slowed-down
interpolant of the original waypoints.

Everything is vectorised: segment lookup by ``np.searchsorted``, no per-sample Python loop.
"""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import RequestError
from ..core.polynomials import evaluate_polynomials, quintic_coefficients

#: Default upper bound on the number of output samples (protects nodes from absurd requests).
MAX_SAMPLES = 1_000_000
#: The nodes' cap on the points of one trajectory they publish (the planner's; the processor's
#: ``max_output_points`` default).
MAX_POINTS = 100_000

__all__ = [
    'MAX_POINTS',
    'MAX_SAMPLES',
    'process_trajectory',
    'resample',
    'sample_count',
    'sample_times',
    'scale_velocity',
]


def _check_times(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0:
        msg = f'times must be a non-empty 1-D array, got shape {t.shape}'
        raise RequestError(msg)
    if not np.all(np.isfinite(t)):
        msg = f'times contain non-finite values at indices {np.flatnonzero(~np.isfinite(t)).tolist()}'
        raise RequestError(msg)
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        msg = f'times must be strictly increasing: t[{i}] = {t[i]!r} s after t[{i - 1}] = {t[i - 1]!r} s'
        raise RequestError(msg)
    return t


def _check_values(name: str, x: np.ndarray | None, n: int, dof: int | None) -> np.ndarray | None:
    if x is None:
        return None
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[0] != n or (dof is not None and x.shape[1] != dof):
        want = f'({n}, {dof if dof is not None else "dof"})'
        msg = f'{name} must have shape {want}, got {x.shape}'
        raise RequestError(msg)
    if not np.all(np.isfinite(x)):
        row = int(np.flatnonzero(~np.all(np.isfinite(x), axis=1))[0])
        msg = f'{name} contain non-finite values (first at point {row})'
        raise RequestError(msg)
    return x


def _check_period(sample_period: float) -> float:
    try:
        dt = float(sample_period)
    except (TypeError, ValueError):
        msg = f'sample_period must be a number, got {sample_period!r}'
        raise RequestError(msg) from None
    if not math.isfinite(dt) or dt <= 0.0:
        msg = f'sample_period must be finite and > 0 s, got {sample_period!r}'
        raise RequestError(msg)
    return dt


def sample_count(span: float, sample_period: float) -> float:
    """The most samples :func:`sample_times` gives for ``span`` s at ``sample_period`` s:
    ``floor(span / dt) + 2`` (a float: inf for an infinite span or a vanishing period); computed
    before anything is allocated."""
    with np.errstate(over='ignore', divide='ignore', invalid='ignore'):
        ratio = float(np.float64(span) / np.float64(sample_period))
    return math.floor(ratio * (1.0 + 1e-12)) + 2.0 if math.isfinite(ratio) else math.inf


def sample_times(t_start: float, t_end: float, sample_period: float, *, max_samples: int = MAX_SAMPLES) -> np.ndarray:
    """Uniform sample times ``t_start + k * sample_period`` up to and including ``t_end``.

    The last sample is exactly ``t_end``. When the end lies less than 1e-6 * sample_period after
    a grid point, that grid point is dropped and the last interval is that much longer than the
    period (no sliver segment that would collapse when rounded to nanoseconds); otherwise the
    final interval is shorter than the period.

    Args:
        t_start: first time, s.
        t_end: last time (>= t_start), s.
        sample_period: spacing, s (> 0).
        max_samples: refuse to produce more samples than this.

    Returns:
        Times, shape (M,), s; M >= 1, strictly increasing.

    Raises:
        RequestError: non-finite or non-positive period, t_end < t_start, too many samples.
    """
    dt = _check_period(sample_period)
    t0, t1 = float(t_start), float(t_end)
    if not (math.isfinite(t0) and math.isfinite(t1)) or t1 < t0:
        msg = f'need finite t_start <= t_end, got {t_start!r}, {t_end!r}'
        raise RequestError(msg)
    span = t1 - t0
    n_inner = int(sample_count(span, dt)) - 2     # grid points after t_start, before or at t_end
    if n_inner + 2 > max_samples:
        msg = (f'{span:.6g} s at a sample period of {dt:.6g} s would need {n_inner + 1} points '
               f'(limit {max_samples})')
        raise RequestError(msg)
    times = t0 + dt * np.arange(n_inner + 1, dtype=float)
    if n_inner > 0 and span - dt * n_inner <= 1e-6 * dt:
        times[-1] = t1  # grid (nearly) hits the end: the end replaces that grid point
    elif span > 0.0:
        times = np.append(times, t1)
    return times


def _cubic_coefficients(t: np.ndarray, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Cubic Hermite coefficients, shape (N - 1, 6, dof) (powers 4 and 5 zero)."""
    h = np.diff(t)[:, None]
    p0, p1 = q[:-1], q[1:]
    v0, v1 = dq[:-1], dq[1:]
    c = np.zeros((len(h), 6, q.shape[1]))
    c[:, 0] = p0
    c[:, 1] = v0
    c[:, 2] = (3.0 * (p1 - p0) - (2.0 * v0 + v1) * h) / (h * h)
    c[:, 3] = (2.0 * (p0 - p1) + (v0 + v1) * h) / (h * h * h)
    return c


def resample(
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    ddq: np.ndarray | None,
    sample_period: float,
    *,
    max_samples: int = MAX_SAMPLES,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Resample a joint trajectory every ``sample_period`` seconds, last point exactly at the end.

    Output times are ``t[0] + k * sample_period`` and ``t[-1]`` (see :func:`sample_times`).
    Between waypoints the trajectory is the controller's interpolant (module docstring): quintic
    Hermite with positions+velocities+accelerations, cubic Hermite with positions+velocities,
    clamped C2 cubic spline (at rest at both ends) with positions only. Output samples that fall
    on a waypoint time reproduce that waypoint exactly (in particular the first and last point).

    Args:
        t: waypoint times (time_from_start), shape (N,), s, strictly increasing.
        q: positions, shape (N, dof); rad or m.
        dq: velocities, shape (N, dof), rad/s or m/s; or None.
        ddq: accelerations, shape (N, dof), rad/s**2 or m/s**2; or None (ignored without dq).
        sample_period: output spacing, s (> 0).
        max_samples: refuse to produce more output points than this.

    Returns:
        (t_new (M,), q_new (M, dof), dq_new (M, dof), ddq_new (M, dof)).

    Raises:
        RequestError: wrong shapes, non-finite values, non-increasing times, bad period, too many samples.
    """
    t = _check_times(t)
    n = t.size
    q_arr = _check_values('positions', q, n, None)
    assert q_arr is not None
    dof = q_arr.shape[1]
    dq_arr = _check_values('velocities', dq, n, dof)
    ddq_arr = _check_values('accelerations', ddq, n, dof)
    times = sample_times(t[0], t[-1], sample_period, max_samples=max_samples)

    if n == 1:
        vel = dq_arr if dq_arr is not None else np.zeros_like(q_arr)
        acc = ddq_arr if (ddq_arr is not None and dq_arr is not None) else np.zeros_like(q_arr)
        return times, q_arr.copy(), vel.copy(), acc.copy()

    if dq_arr is not None and ddq_arr is not None:
        pos, vel, acc = evaluate_polynomials(quintic_coefficients(t, q_arr, dq_arr, ddq_arr), t, times)
        knot_acc = ddq_arr
    elif dq_arr is not None:
        pos, vel, acc = evaluate_polynomials(_cubic_coefficients(t, q_arr, dq_arr), t, times)
        knot_acc = None  # cubic Hermite acceleration is discontinuous at waypoints: keep evaluated one
    else:
        from scipy.interpolate import CubicSpline   # on first use: 0.3 s of start-up (scipy.special)
        spline = CubicSpline(t, q_arr, axis=0, bc_type='clamped')
        pos, vel, acc = spline(times), spline(times, 1), spline(times, 2)
        dq_arr = spline(t, 1)
        dq_arr[[0, -1]] = 0.0  # clamped ends: exactly at rest
        knot_acc = spline(t, 2)

    # Samples that land exactly on a waypoint take the waypoint's values (no rounding drift).
    idx = np.searchsorted(t, times)
    hit = (idx < n) & (t[np.minimum(idx, n - 1)] == times)
    k = idx[hit]
    pos[hit] = q_arr[k]
    vel[hit] = dq_arr[k]
    if knot_acc is not None:
        acc[hit] = knot_acc[k]
    return times, pos, vel, acc


def _check_factor(f: float) -> float:
    try:
        factor = float(f)
    except (TypeError, ValueError):
        msg = f'velocity scaling must be a number in (0, 1], got {f!r}'
        raise RequestError(msg) from None
    if not (math.isfinite(factor) and 0.0 < factor <= 1.0):
        msg = f'velocity scaling must be in (0, 1], got {f!r}'
        raise RequestError(msg)
    return factor


def scale_velocity(
    t: np.ndarray, dq: np.ndarray | None, ddq: np.ndarray | None, f: float,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Slow a trajectory down by the factor f (time scaling; positions unchanged).

    Args:
        t: times, shape (N,), s.
        dq: velocities, shape (N, dof), or None.
        ddq: accelerations, shape (N, dof), or None.
        f: velocity scaling factor in (0, 1].

    Returns:
        (t / f, dq * f, ddq * f**2); None stays None.

    Raises:
        RequestError: f outside (0, 1] or not finite.
    """
    factor = _check_factor(f)
    t_new = np.asarray(t, dtype=float) / factor
    dq_new = None if dq is None else np.asarray(dq, dtype=float) * factor
    ddq_new = None if ddq is None else np.asarray(ddq, dtype=float) * (factor * factor)
    return t_new, dq_new, ddq_new


def process_trajectory(
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    ddq: np.ndarray | None,
    *,
    sample_period: float,
    velocity_scaling: float = 1.0,
    max_samples: int = MAX_SAMPLES,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scale then resample: the trajectory processor's whole computation.

    Equivalent to ``resample(t / f, q, dq * f, ddq * f**2, sample_period)``: points every
    ``sample_period`` seconds of the slowed-down trajectory, lasting 1/f times as long.

    Args:
        t: waypoint times, shape (N,), s.
        q, dq, ddq: shape (N, dof) (dq/ddq may be None, see :func:`resample`).
        sample_period: output spacing, s.
        velocity_scaling: f in (0, 1].
        max_samples: limit on output points.

    Returns:
        (t_new (M,), q_new, dq_new, ddq_new (M, dof)).

    Raises:
        RequestError: invalid input, factor or period.
    """
    factor = _check_factor(velocity_scaling)
    _check_period(sample_period)
    t_checked = _check_times(t)
    t_s, dq_s, ddq_s = scale_velocity(t_checked, dq, ddq, factor)
    return resample(t_s, q, dq_s, ddq_s, sample_period, max_samples=max_samples)
