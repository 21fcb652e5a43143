"""The smoothing law's check of a smoothed law against the limits (:mod:`.smoothing`, step 4).

A dense grid of times (uniform in t, the rests between pieces, about uniform in s), the law there
and the path's derivatives cubic Hermite from the samples: per sample the largest velocity (tool
speed rows included) and acceleration ratio to its limit, and around the highest peaks samples at
a quarter of the spacing. The samples nearest a limit are re-checked with the exact path
derivatives, and the breakpoints the law crosses with both one-sided values. Compiled when the
kernels are on (:func:`.kernels.piecewise_check`: the same grid), numpy otherwise.
Units: s, 1/s, 1/s^2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from . import kernels
from ._arrays import clip
from .checks import UNIFORM_S, UNIFORM_S_PINNED, distinct_times, peak_samples
from .sampling import PathSamples
from .tool import ToolRows
from .tuning import CHECK_MARGIN, CHECK_SAMPLES, EXACT_CHECKS
from .types import PathLike

__all__ = ['LimitCheck', 'SmoothedLaw', 'check_law']


class SmoothedLaw(Protocol):
    """What the check reads of a smoothed law (:class:`.smoothing.PiecewiseLaw`)."""

    @property
    def t_offsets(self) -> np.ndarray: ...       # (L + 1,) the rests' times, s

    @property
    def node_s(self) -> np.ndarray: ...          # nodes of s* (path parameter) ...

    @property
    def node_t(self) -> np.ndarray: ...          # ... and their times delayed by tau, s

    @property
    def duration(self) -> float: ...

    @property
    def n_pieces(self) -> int: ...

    @property
    def kernel_tables(self) -> kernels.LawTables: ...

    def times_at(self, s: np.ndarray) -> np.ndarray: ...

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]: ...


def _at_path_parameter(law: SmoothedLaw, t_grid: np.ndarray, s_grid: np.ndarray,
                       targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sdot and sddot when the (monotone) law passes the path parameters ``targets``."""
    j = clip(np.searchsorted(s_grid, targets), 1, s_grid.size - 1)
    s0, s1 = s_grid[j - 1], s_grid[j]
    w = np.where(s1 > s0, (targets - s0) / np.where(s1 > s0, s1 - s0, 1.0), 0.0)
    t = t_grid[j - 1] + w * (t_grid[j] - t_grid[j - 1])
    for _ in range(4):  # Newton on s(t) = target
        s, sd, _, _ = law.evaluate(t, jerk=False)
        step = np.where(sd > 0, (s - targets) / np.where(sd > 0, sd, 1.0), 0.0)
        t = clip(t - step, t_grid[j - 1], t_grid[j])
    _, sd, sdd, _ = law.evaluate(t, jerk=False)
    return sd, sdd


@dataclass(frozen=True, eq=False)
class LimitCheck:
    """Result of the dense check of a law: the uniform stretch it needs, and where.

    ``need`` is each sample's largest ratio to the limits, as a speed factor (velocity ratio, or
    the square root of the acceleration ratio), divided by ``1 - CHECK_MARGIN``.
    """

    factor: float          # uniform time stretch (>= 1) that keeps every sample within the limits
    t: np.ndarray          # (M,) check times of the law, s (not in order)
    need: np.ndarray       # (M,) speed factor over the limits at each (interpolated path derivatives)


def _ratios(ps: PathSamples, law: SmoothedLaw, t: np.ndarray, vmax: np.ndarray, amax: np.ndarray,
            tool: ToolRows | None, pinned: kernels.Pinned | None) -> tuple[np.ndarray, ...]:
    """At sorted times t (M,): s, sdot, sddot and the largest velocity and acceleration ratios
    to the limits over the joints (and the tool rows), q' and q'' interpolated from ``ps``;
    ``pinned``: the limits for the compiled kernel (:func:`.kernels.limit_tables`; None without it)."""
    if pinned is not None:
        s, sd, sdd, rv_t, ra_t = kernels.ratios(law.kernel_tables, ps.kernel_tables, pinned, t, jerk=False)
        if tool is not None:
            rv_t = np.maximum(rv_t, tool.ratios(s, sd))
        return s, sd, sdd, rv_t, ra_t
    s, sd, sdd, _ = law.evaluate(t, jerk=False)
    a, b = ps.interpolate_t(s)
    vel = a * sd
    np.abs(vel, out=vel)
    vel /= vmax[:, None]
    rv_t = vel.max(axis=0)
    a *= sdd
    b *= sd * sd
    a += b
    np.abs(a, out=a)
    a /= amax[:, None]
    ra_t = a.max(axis=0)
    if tool is not None:
        rv_t = np.maximum(rv_t, tool.ratios(s, sd))
    return s, sd, sdd, rv_t, ra_t


def check_law(path: PathLike, ps: PathSamples, law: SmoothedLaw, vmax: np.ndarray, amax: np.ndarray,
             check_samples: int | None, tool: ToolRows | None = None) -> LimitCheck:
    """Uniform time stretch (>= 1) that keeps ``law`` within ``1 - CHECK_MARGIN`` of the limits, and where.

    Dense check of the smoothed law against the full limits, with q', q'' interpolated from
    ``ps`` (and the tool rows' twist from ``tool.samples``); the samples nearest a limit and the
    breakpoints are re-checked with exact values.
    """
    m = int(check_samples) if check_samples is not None else max(CHECK_SAMPLES, 5 * ps.s.size)
    m = max(m, 10)
    pinned = kernels.limit_tables(vmax, amax) if kernels.active() else None     # for both calls
    if pinned is not None and math.isfinite(law.duration) and law.duration > 0.0:
        # the same grid, law and ratios in one compiled call
        t_chk, s, sd, sdd, rv_t, ra_t = kernels.piecewise_check(
            law.kernel_tables, kernels.Pinned(law.node_s, law.node_t), ps.kernel_tables, pinned, UNIFORM_S_PINNED, m)
        if tool is not None:
            rv_t = np.maximum(rv_t, tool.ratios(s, sd))
    else:
        t_chk = np.linspace(0.0, law.duration, m)
        if law.n_pieces > 1:
            t_chk = np.union1d(t_chk, law.t_offsets)
        # Also samples about uniform in s: a long law can cross a stretch of the path in a fraction
        # of its duration, where samples uniform in t are sparse.
        t_chk = distinct_times(np.concatenate([t_chk, law.times_at(UNIFORM_S)]))
        s, sd, sdd, rv_t, ra_t = _ratios(ps, law, t_chk, vmax, amax, tool, pinned)
    # Around the highest local peaks, samples at a quarter of the uniform spacing.
    need = np.maximum(rv_t, np.sqrt(ra_t))
    extra = peak_samples(t_chk, need, law.duration / (m - 1), law.duration)
    inner = ps.jumps
    if extra.size:       # appended: only the breakpoints' crossing times need the samples in order
        more = _ratios(ps, law, extra, vmax, amax, tool, pinned)
        t_chk, s, sd, sdd, rv_t, ra_t, need = (
            np.concatenate([u, v]) for u, v in zip((t_chk, s, sd, sdd, rv_t, ra_t, need),
                                                   (extra, *more, np.maximum(more[3], np.sqrt(more[4])))))
        if inner.size:
            order = np.argsort(t_chk, kind='stable')
            t_chk, s, sd, sdd, rv_t, ra_t, need = (u[order] for u in (t_chk, s, sd, sdd, rv_t, ra_t, need))
    rv, ra = float(rv_t.max()), float(ra_t.max())
    # The samples closest to a limit are verified with the exact path derivatives.
    k = max(1, min(EXACT_CHECKS, need.size))
    top = np.argpartition(need, -k)[-k:]
    q_x, a_x, b_x = (np.asarray(v, dtype=float) for v in path.evaluate(s[top], order=2))
    rv = max(rv, float(np.max(np.abs(a_x * sd[top, None]) / vmax)))
    if tool is not None:
        rv = max(rv, float(np.max(tool.exact_ratios(q_x, a_x, sd[top]))))
    ra = max(ra, float(np.max(np.abs(a_x * sdd[top, None] + b_x * (sd[top] ** 2)[:, None]) / amax)))
    # At breakpoints q'' (or q') may jump: check both one-sided values at the exact crossing time.
    # (Rests at corners need no check: sdot = sddot = 0 there.)
    if inner.size:
        sd_b, sdd_b = _at_path_parameter(law, t_chk, s, ps.s[inner])
        for aa, bb in ((ps.aL[inner], ps.bL[inner]), (ps.aR[inner], ps.bR[inner])):
            rv = max(rv, float(np.max(np.abs(aa * sd_b[:, None]) / vmax)))
            ra = max(ra, float(np.max(np.abs(aa * sdd_b[:, None] + bb * (sd_b**2)[:, None]) / amax)))
        if tool is not None:
            for V in (tool.samples.aL[inner], tool.samples.aR[inner]):
                rv = max(rv, float(np.max(tool.ratios_of(V.T, sd_b))))
    target = 1.0 - CHECK_MARGIN
    need /= target
    return LimitCheck(max(1.0, rv / target, math.sqrt(ra / target)), t_chk, need)
