"""Piecewise quintic (and cubic) Hermite polynomials: coefficients and vectorised evaluation.

Shared by the paths (:class:`QuinticHermite`) and the trajectory resampler
(:mod:`geodesic_planner.timing.resample`), so a path and a resampled trajectory interpolate alike.
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from . import compiled

__all__ = ['Interpolant', 'QuinticHermite', 'evaluate_polynomials', 'quintic_coefficients', 'split_intervals']


def quintic_coefficients(
    t: np.ndarray, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray,
) -> np.ndarray:
    """Per-segment polynomial coefficients of the quintic Hermite interpolant.

    Segment i covers [t[i], t[i+1]] with local time tau = t - t[i] and
    q(tau) = sum_k c[i, k] tau**k, matching positions, velocities and accelerations at both ends
    (the formulas of joint_trajectory_controller's ``Trajectory::interpolate_between_points``).

    Args:
        t: waypoint times, shape (N,), s, strictly increasing, N >= 2.
        q, dq, ddq: positions, velocities, accelerations, shape (N, dof).

    Returns:
        Coefficients, shape (N - 1, 6, dof), ascending powers of tau (units rad/s**k or m/s**k).
    """
    h = np.diff(t)[:, None]
    p0, p1 = q[:-1], q[1:]
    v0, v1 = dq[:-1], dq[1:]
    a0, a1 = ddq[:-1], ddq[1:]
    h2 = h * h
    c = np.empty((len(h), 6, q.shape[1]))
    c[:, 0] = p0
    c[:, 1] = v0
    c[:, 2] = 0.5 * a0
    c[:, 3] = (-20.0 * p0 + 20.0 * p1 - 3.0 * a0 * h2 + a1 * h2 - 12.0 * v0 * h - 8.0 * v1 * h) / (2.0 * h2 * h)
    c[:, 4] = (30.0 * p0 - 30.0 * p1 + 3.0 * a0 * h2 - 2.0 * a1 * h2 + 16.0 * v0 * h + 14.0 * v1 * h) / (2.0 * h2 * h2)
    c[:, 5] = (-12.0 * p0 + 12.0 * p1 - a0 * h2 + a1 * h2 - 6.0 * v0 * h - 6.0 * v1 * h) / (2.0 * h2 * h2 * h)
    return c


def evaluate_polynomials(c: np.ndarray, t: np.ndarray, times: np.ndarray, order: int = 2) -> tuple[np.ndarray, ...]:
    """Evaluate piecewise polynomials (N-1, 6, dof) at times (M,): position, velocity, acceleration
    and (``order`` 3) jerk.

    ``order`` < 3 returns only the first ``order + 1`` of them. Compiled (:mod:`.compiled`) when
    the kernels are on, with the same Horner steps.
    """
    if compiled.active():
        return compiled.polynomials(compiled.Pinned(t, c), times, min(order, 3))
    seg = np.minimum(np.maximum(np.searchsorted(t, times, side='right') - 1, 0), len(t) - 2)
    tau = (times - t[seg])[:, None]
    cs = c[seg]  # (M, 6, dof)
    pos = cs[:, 5]
    vel = 5.0 * cs[:, 5]
    acc = 20.0 * cs[:, 5]
    jerk = 60.0 * cs[:, 5]
    for k in (4, 3, 2, 1, 0):  # Horner over the 6 coefficients (fixed, not per sample)
        pos = pos * tau + cs[:, k]
        if k >= 1 and order >= 1:
            vel = vel * tau + k * cs[:, k]
        if k >= 2 and order >= 2:
            acc = acc * tau + k * (k - 1) * cs[:, k]
        if k >= 3 and order >= 3:
            jerk = jerk * tau + k * (k - 1) * (k - 2) * cs[:, k]
    return (pos, vel, acc, jerk)[:order + 1]



class Interpolant(Protocol):
    """What a path needs of its interpolant: values and derivatives up to ``order`` (<= 3) at xs."""

    def __call__(self, xs: np.ndarray, order: int = 2) -> list[np.ndarray]: ...


class QuinticHermite:
    """C² piecewise-quintic interpolation of values, first and second derivatives at knots.

    The same interpolant the trajectory processor uses (:func:`quintic_coefficients`):
    coefficients are computed once, evaluation is one vectorised Horner pass.

    Args:
        x: knots (m,), strictly increasing.
        y, dy, ddy: values and derivatives at the knots, (m, d).
    """

    def __init__(self, x: np.ndarray, y: np.ndarray, dy: np.ndarray, ddy: np.ndarray) -> None:
        self.x = np.asarray(x, dtype=float)
        self._coefficients = quintic_coefficients(self.x, *(np.asarray(a, dtype=float) for a in (y, dy, ddy)))
        self._pinned: compiled.Pinned | None = None     # knots and coefficients for the kernel

    def __call__(self, xs: np.ndarray, order: int = 2) -> list[np.ndarray]:
        """Values and derivatives up to ``order`` (<= 3) at xs (k,): list of (k, d) arrays."""
        if compiled.active():
            if self._pinned is None:
                self._pinned = compiled.Pinned(self.x, self._coefficients)
            return list(compiled.polynomials(self._pinned, xs, min(order, 3)))
        return list(evaluate_polynomials(self._coefficients, self.x, xs, order=min(order, 3)))


def split_intervals(s: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """Mesh s (m,) with interval i split into ``parts[i]`` (>= 1) equal parts."""
    starts = np.cumsum(parts) - parts
    k = np.arange(int(parts.sum())) - np.repeat(starts, parts)        # index within the interval
    frac = k / np.repeat(parts, parts)
    return np.concatenate([np.repeat(s[:-1], parts) + np.repeat(np.diff(s), parts) * frac, s[-1:]])
