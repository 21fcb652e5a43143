"""The jerk-limited law's check of a box-filtered law against the limits (:mod:`.jerk`, step 3).

A dense grid of times (uniform in t, about uniform in s, and between the law's jerk events), the
law there and the path's derivatives cubic Hermite from the samples (:class:`.PathSamples`): per
sample the largest ratio of |velocity|, |acceleration| and |jerk| to its limit (tool speed rows
included). The breakpoints the law crosses are checked with their exact one-sided derivatives;
the law kept is also checked with the exact derivatives of the path at the samples nearest a
limit. The width search compares laws on a coarser grid, with the interpolated derivatives alone,
and compiled (:func:`.kernels.box_search_max`): without building each law, and stopping once a
law is certainly longer than one already known. Units: s, 1/s, 1/s^2, 1/s^3.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.cancel import checkpoint
from . import kernels
from ._arrays import clip
from .box_filter import BoxLaw, StarPiece, build_box_law
from .checks import UNIFORM_S, UNIFORM_S_PINNED, distinct_times, peak_samples
from .sampling import PathSamples
from .tool import ToolRows
from .tuning import CHECK_MARGIN, CHECK_SAMPLES, EXACT_CHECKS
from .types import JointLimits, PathLike

__all__ = ['SEARCH_SAMPLES', 'BoxCheck']

#: Uniform time samples of the check while the width is searched (plus those near the jerk
#: events and around the peaks); the law kept is checked again on CHECK_SAMPLES, exactly.
SEARCH_SAMPLES = 250


def _stretch_of(rv: float, ra: float, rj: float) -> float:
    """The uniform time stretch (>= 1) that brings the largest v, a, j ratios within 1 - CHECK_MARGIN."""
    target = 1.0 - CHECK_MARGIN
    return max(1.0, rv / target, math.sqrt(ra / target), math.cbrt(rj / target))


def _crossing_times(law: BoxLaw, t: np.ndarray, s: np.ndarray, targets: np.ndarray,
                    newton: int = 6) -> np.ndarray:
    """Times at which the (monotone) law passes ``targets``: bracketed on samples, interpolated
    linearly there, then ``newton`` Newton steps."""
    j = clip(np.searchsorted(s, targets), 1, s.size - 1)
    lo, hi = t[j - 1], t[j]
    ds = s[j] - s[j - 1]
    tc = lo + (hi - lo) * np.where(ds > 0, clip((targets - s[j - 1]) / np.where(ds > 0, ds, 1.0), 0.0, 1.0), 0.5)
    for _ in range(newton):
        checkpoint()
        sc, sdc, _, _ = law.evaluate(tc, jerk=False)
        step = np.where(sdc > 0, (sc - targets) / np.where(sdc > 0, sdc, 1.0), 0.0)
        tc = clip(tc - step, lo, hi)
    return tc


@dataclass(frozen=True, eq=False)
class BoxCheck:
    """The dense check of a box law against the limits (ratios at time scale 1)."""

    path: PathLike
    ps: PathSamples
    limits: JointLimits
    tool: ToolRows | None
    check_samples: int | None
    # The last law's dense grid (the local passes check a law, then ask where it is over).
    _last: list[object] = field(default_factory=list, repr=False)
    # Where the last full search check peaked (fraction of its duration): the next check starts there.
    _peak: list[float] = field(default_factory=lambda: [0.0], repr=False)

    def stretch(self, law: BoxLaw, exact: bool = False) -> float:
        """Smallest uniform time stretch (>= 1) keeping ``law`` within 1 - CHECK_MARGIN of every
        limit; ``exact``: on the full grid, the samples nearest a limit re-checked with
        ``path.evaluate`` (else on the search grid with the interpolated derivatives alone)."""
        return _stretch_of(*self.ratios(law, exact))

    def search(self, pieces: list[tuple[float, StarPiece]], tables: kernels.Pinned | None, width: np.ndarray,
               above: float = math.inf) -> tuple[float, float, bool]:
        """:meth:`stretch` on the search grid of the box law of ``pieces`` with window ``width``
        (``tables``: their :func:`.box_filter.star_tables`): (stretch, duration, exact). Not exact:
        the check stopped once stretch x duration was certainly longer than ``above`` (s), and the
        stretch is a lower bound, with stretch x duration > ``above``."""
        if kernels.active() and tables is not None and self.tool is None:
            target = 1.0 - CHECK_MARGIN
            t_star = sum(p.t_star for _, p in pieces)
            # a stretch over lam makes stretch x duration > above for sure (the law's duration is
            # this sum up to round-off; 1e-9 of margin), so the ratios' bounds are lam's powers
            lam = above / (t_star + float(width.sum())) * (1.0 + 1e-9)
            rv, ra, rj, duration, peak, stopped = kernels.box_search_max(
                tables, width, self.ps.kernel_tables3, self._limits, UNIFORM_S_PINNED, self._samples(False),
                2 * SEARCH_SAMPLES, (lam * target, lam**2 * target, lam**3 * target), self._peak[0],
                self._crossings)
            if math.isfinite(duration) and duration > 0.0:
                if not stopped:
                    self._peak[0] = peak
                return _stretch_of(rv, ra, rj), duration, not stopped
        law = build_box_law(pieces, width, tables)
        return self.stretch(law), law.duration, True

    @functools.cached_property
    def _sides(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q', q'', q''' at the breakpoints crossed (:attr:`.PathSamples.jumps3`): the left-hand
        values, then the right-hand ones, each (2 K, dof)."""
        ps, inner = self.ps, self.ps.jumps3
        return tuple(np.concatenate([left[inner], right[inner]])
                     for left, right in ((ps.aL, ps.aR), (ps.bL, ps.bR), (ps.cL, ps.cR)))

    @functools.cached_property
    def _crossings(self) -> kernels.Pinned | None:
        """The breakpoints for :func:`.kernels.box_search_max`: their s, the one-sided q', q'', q'''
        (:attr:`_sides`) and vmax, amax, jmax; None without breakpoints."""
        if not self.ps.jumps3.size:
            return None
        return kernels.Pinned(self.ps.s[self.ps.jumps3], *self._sides, *self._plain_limits.arrays)

    @functools.cached_property
    def _jmax(self) -> np.ndarray:
        """The jerk limits (dof,), infinite without them."""
        lim = self.limits
        return lim.max_jerk if lim.max_jerk is not None else np.full(lim.max_velocity.size, np.inf)

    @functools.cached_property
    def _plain_limits(self) -> kernels.Pinned:
        """vmax, amax, jmax for :func:`.kernels.point_ratios`."""
        return kernels.Pinned(self.limits.max_velocity, self.limits.max_acceleration, self._jmax)

    @functools.cached_property
    def _limits(self) -> kernels.Pinned:
        """vmax, amax, jmax as the kernels' reciprocals (:func:`.kernels.limit_tables`)."""
        return kernels.limit_tables(self.limits.max_velocity, self.limits.max_acceleration, self._jmax)

    def need(self, law: BoxLaw) -> tuple[np.ndarray, np.ndarray]:
        """Check times (M,) and each one's speed factor over the limits (interpolated path
        derivatives): max(v ratio, sqrt(a ratio), cbrt(j ratio)) / (1 - CHECK_MARGIN)."""
        dense = self._dense(law)
        t, need = dense[0], dense[5]
        return t, need / (1.0 - CHECK_MARGIN)

    def _dense(self, law: BoxLaw, full: bool = True) -> tuple[np.ndarray, tuple[np.ndarray, ...], np.ndarray,
                                                              np.ndarray, np.ndarray, np.ndarray]:
        """The dense grid: times, (s, sd, sdd, sddd) there, per-sample v, a, j ratios, and each
        sample's speed factor max(v, sqrt(a), cbrt(j)); the last law's is kept (read only).
        ``full``: CHECK_SAMPLES uniform samples (else SEARCH_SAMPLES, for comparing widths)."""
        if self._last and self._last[0] is law and self._last[1] == full:
            return self._last[2]  # type: ignore[return-value]
        m = self._samples(full)
        if kernels.active() and math.isfinite(law.duration) and law.duration > 0.0:
            out = self._dense_compiled(law, m, full)
        else:
            out = self._dense_numpy(law, m, full)
        self._last[:] = [law, full, out]
        return out

    def _dense_compiled(self, law: BoxLaw, m: int, full: bool) -> tuple[np.ndarray, tuple[np.ndarray, ...],
                                                                        np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_dense_numpy`'s grid and columns, compiled (the same times, bit for bit)."""
        ps = self.ps

        def finish(block: np.ndarray) -> np.ndarray:
            """Rows t, s, sd, sdd, sddd, rv, ra, rj: the tool rows into rv, the speed factor into row 8."""
            if self.tool is not None:
                np.maximum(block[5], self.tool.ratios(block[1], block[2]), out=block[5])
            np.maximum(np.maximum(block[5], np.sqrt(block[6])), np.cbrt(block[7]), out=block[8])
            return block

        # in this thread's scratch buffer, merged or copied into the block kept before it returns
        block = finish(kernels.box_search(law.tables, ps.kernel_tables3, self._limits, UNIFORM_S_PINNED, m,
                                          2 * SEARCH_SAMPLES, full, reuse=True))
        extra = peak_samples(block[0], block[8], law.duration / (m - 1), law.duration) if full else np.zeros(0)
        if extra.size:
            more = np.empty((9, extra.size))
            more[0] = extra
            more[1:8] = kernels.ratios(law.tables, ps.kernel_tables3, self._limits, extra, jerk=True)
            block = kernels.merge_columns(block, finish(more))
        else:
            block = np.array(block)
        t, s, sd, sdd, sddd, rv_t, ra_t, rj_t, need = block
        return t, (s, sd, sdd, sddd), rv_t, ra_t, rj_t, need

    def _dense_numpy(self, law: BoxLaw, m: int, full: bool) -> tuple[np.ndarray, tuple[np.ndarray, ...], np.ndarray,
                                                                      np.ndarray, np.ndarray, np.ndarray]:
        """The dense grid of :meth:`_dense` in numpy (the reference of the compiled one)."""
        ps, lim = self.ps, self.limits
        vmax, amax, jmax = lim.max_velocity, lim.max_acceleration, self._jmax
        ev = law.jerk_events()
        gap = np.diff(ev)
        keep = gap > 0
        e0, g = ev[:-1][keep], gap[keep]
        # Between two jerk events everything is smooth: the full check samples both ends (the
        # one-sided values of a jump) and the middle; the search, which only compares widths,
        # the middle alone (fine grids, as at blends, have thousands of events).
        if full:
            inside: tuple[np.ndarray, ...] = (e0 + 0.01 * g, e0 + 0.5 * g, e0 + 0.99 * g)
        else:     # at most 2 SEARCH_SAMPLES of them, evenly strided
            stride = max(1, -(-e0.size // (2 * SEARCH_SAMPLES)))
            inside = ((e0 + 0.5 * g)[::stride],)
        t = np.concatenate([np.linspace(0.0, law.duration, m),
                            law.times_at(UNIFORM_S), *inside])
        t = distinct_times(t)

        def ratios(t: np.ndarray) -> tuple[np.ndarray, ...]:
            if kernels.active():
                s, sd, sdd, sddd, rv_t, ra_t, rj_t = kernels.ratios(law.tables, ps.kernel_tables3, self._limits,
                                                                    t, jerk=True)
            else:
                s, sd, sdd, jerk = law.evaluate(t)
                assert jerk is not None
                sddd = jerk
                a, b = ps.interpolate_t(s)
                c = ps.third_derivative_t(s)
                rv_t = (np.abs(a * sd) / vmax[:, None]).max(axis=0)
                ra_t = (np.abs(a * sdd + b * sd**2) / amax[:, None]).max(axis=0)
                rj_t = (np.abs(a * sddd + 3.0 * b * (sd * sdd) + c * sd**3) / jmax[:, None]).max(axis=0)
            if self.tool is not None:
                rv_t = np.maximum(rv_t, self.tool.ratios(s, sd))
            need = np.maximum(np.maximum(rv_t, np.sqrt(ra_t)), np.cbrt(rj_t))
            return s, sd, sdd, sddd, rv_t, ra_t, rj_t, need

        cols = ratios(t)
        # Around the highest peaks, samples at a quarter of the uniform spacing (full grid only).
        extra = peak_samples(t, cols[-1], law.duration / (m - 1), law.duration) if full else np.zeros(0)
        if extra.size:
            order = np.argsort(np.concatenate([t, extra]), kind='stable')
            t = np.concatenate([t, extra])[order]
            cols = tuple(np.concatenate([u, v])[order] for u, v in zip(cols, ratios(extra)))
        s, sd, sdd, sddd, rv_t, ra_t, rj_t, need = cols
        return t, (s, sd, sdd, sddd), rv_t, ra_t, rj_t, need

    def _samples(self, full: bool) -> int:
        """Uniform time samples of the dense grid (``full``) or of the search grid."""
        return max(10, int(self.check_samples) if self.check_samples is not None
                   else max(CHECK_SAMPLES, 5 * self.ps.s.size) if full else SEARCH_SAMPLES)

    def ratios(self, law: BoxLaw, exact: bool = True) -> tuple[float, float, float]:
        """Largest |v| / vmax, |a| / amax (tool speed included in v) and |j| / jmax of ``law``;
        ``exact``: see :meth:`stretch`."""
        ps = self.ps
        t, (s, sd, sdd, sddd), rv_t, ra_t, rj_t, need = self._dense(law, full=exact)
        rv, ra, rj = float(rv_t.max()), float(ra_t.max()), float(rj_t.max())
        # The samples closest to a limit, with the exact path derivatives (the law kept; the
        # search compares widths on the interpolated derivatives alone).
        if exact:
            k = max(1, min(EXACT_CHECKS, need.size))
            top = np.argpartition(need, -k)[-k:]
            q_x, a_x, b_x, c_x = (np.asarray(v, dtype=float) for v in self.path.evaluate(s[top]))
            rv, ra, rj = self._max_ratios((rv, ra, rj), a_x, b_x, c_x, sd[top], sdd[top], sddd[top])
            if self.tool is not None:
                rv = max(rv, float(np.max(self.tool.exact_ratios(q_x, a_x, sd[top]))))
        # Breakpoints where q'' or q''' jumps (not a rest): both one-sided values where crossed.
        inner = ps.jumps3
        if inner.size:
            # the search compares widths: the crossing interpolated between its samples suffices
            crossing = _crossing_times(law, t, s, ps.s[inner], newton=6 if exact else 0)
            _, sd_b, sdd_b, sddd_b = law.evaluate(crossing)
            assert sddd_b is not None
            a_b, b_b, c_b = self._sides       # both sides at once: the left values, then the right
            rv, ra, rj = self._max_ratios((rv, ra, rj), a_b, b_b, c_b, *(np.concatenate([v, v]) for v in
                                                                           (sd_b, sdd_b, sddd_b)))
            if self.tool is not None:
                for V in (self.tool.samples.aL[inner], self.tool.samples.aR[inner]):
                    rv = max(rv, float(np.max(self.tool.ratios_of(V.T, sd_b))))
        return rv, ra, rj

    def _max_ratios(self, prev: tuple[float, float, float], a: np.ndarray, b: np.ndarray,
                    c: np.ndarray, sd: np.ndarray, sdd: np.ndarray, sddd: np.ndarray
                    ) -> tuple[float, float, float]:
        """``prev`` raised by the ratios of exact derivatives a, b, c (K, dof) at sd, sdd, sddd (K,)."""
        if kernels.active():
            rv, ra, rj = kernels.point_ratios(a, b, c, sd, sdd, sddd, self._plain_limits)
            return max(prev[0], rv), max(prev[1], ra), max(prev[2], rj)
        lim, jmax = self.limits, self._jmax
        sd, sdd, sddd = sd[:, None], sdd[:, None], sddd[:, None]
        return (max(prev[0], float(np.max(np.abs(a * sd) / lim.max_velocity))),
                max(prev[1], float(np.max(np.abs(a * sdd + b * sd**2) / lim.max_acceleration))),
                max(prev[2], float(np.max(np.abs(a * sddd + 3.0 * b * sd * sdd + c * sd**3) / jmax))))
