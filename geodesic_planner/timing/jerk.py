"""The jerk-limited rest-to-rest law: time-optimal profile, box-filtered, checked against v, a, j.

The joint jerk along a path is ``d3q/dt3 = q' sdddot + 3 q'' sdot sddot + q''' sdot^3``; the path
q(s) never changes, only s(t).

1. The time-optimal v/a profile ``s*(t)`` is computed as for :mod:`.smoothing` (:mod:`.topp`,
   limits * (1 - TOPP_MARGIN), tool speed rows included); its duration is
   :attr:`Trajectory.topp_duration`. Its acceleration ``u*`` is piecewise constant (bang-bang).
2. **Box filter**: each rest-to-rest piece is replaced by its moving average over a window ``w``,
   ``s(t) = (1 / w) int_{t - w}^{t} s*(r) dr``, exactly (``s*`` is piecewise quadratic). Then
   ``sdot = (s*(t) - s*(t - w)) / w``, ``sddot = (sdot*(t) - sdot*(t - w)) / w`` is continuous
   and ``sdddot = (u*(t) - u*(t - w)) / w`` is bounded: the acceleration ramps linearly over
   ``w``, and every rest has zero velocity and acceleration. Each piece lasts ``T* + w``. On a
   straight joint line that cruises with a full acceleration phase, the box filter of the
   bang-bang profile with ``w = amax / jmax`` is exactly the time-optimal 7-segment profile.
3. **Width and stretch**: the reference width of a piece is ``max_j A_j / jmax_j`` (A_j the
   joint's peak acceleration in ``s*``). For a width factor ``c`` the law is checked on a dense
   grid (uniform in t, about uniform in s, and around every time where ``sdddot`` jumps); a
   uniform time stretch ``lambda`` divides velocities, accelerations and jerks by ``lambda``,
   ``lambda^2``, ``lambda^3`` exactly, so the smallest admissible ``lambda`` follows from the
   largest ratios. ``c`` is chosen by a coarse scan and golden-section search for the shortest
   duration ``lambda(c) * sum(T* + c w_ref)``. If the best law still needs a stretch above
   LOCAL_TRIGGER, the optimal profile is capped near the samples over a limit and filtered again
   with the same window (:func:`.checks.local_cap`), keeping the shortest law. Where the optimal
   profile runs far above the cruise cap of the jerk rows (:func:`cruise_cap`, ``x <=
   (jmax / |q'''|)^(2/3)``: what a blend's third derivative allows), the search runs under that
   cap. When the jerk binds (over LOOSE times the v/a optimum), the optimal pass is repeated with
   the acceleration limits scaled by ACCEL_SCALES, keeping the shortest law (gentler
   accelerations allow gentler ramps: the 7-segment optimum peaks at sqrt(vmax jmax)).
4. ``duration=`` stretches the law uniformly (never shorter than the minimum).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from . import kernels
from ._arrays import clip
from .law import final_duration
from .types import JointLimits, PathLike
from .sampling import PathSamples, refine_adaptively, sample_path
from .checks import UNIFORM_S, distinct_times, local_cap, peak_samples
from .tuning import CHECK_MARGIN, CHECK_SAMPLES, EXACT_CHECKS, LOCAL_PASSES, TOPP_MARGIN
from .tool import ToolRows, tool_rows
from .topp import topp
from .box_filter import BoxLaw, StarPiece, build_box_law, star_pieces, star_tables
from .trajectory import Trajectory

#: Uniform time samples of the check while the width is searched (plus those near the jerk
#: events and around the peaks); the law kept is checked again on CHECK_SAMPLES, exactly.
SEARCH_SAMPLES = 250
#: Width factors of the coarse scan (times the reference width), then golden-section steps.
WIDTH_SCAN = (0.5, 0.71, 1.0, 1.41, 2.0, 2.83, 4.0)
GOLDEN_STEPS = 5
_UNIFORM_S = kernels.Pinned(UNIFORM_S)      # its address, taken once
#: Acceleration scales of the optimal pass tried in order when the jerk binds (over LOOSE times
#: the v/a optimum), until one does not shorten the law.
ACCEL_SCALES = (0.7, 0.5, 0.35, 0.25)
LOOSE = 1.1
#: Local slow-down passes (:func:`_local_passes`) run above this stretch (a dip the filter cannot follow).
LOCAL_TRIGGER = 1.1
#: The search under the cruise cap of the jerk rows runs when that cap is below this fraction of
#: the v/a-optimal x somewhere (0.03-0.07 at blends; 0.65 or more on the single moves measured).
CRUISE_TRIGGER = 0.5
#: Local passes stop after two in a row that shorten the law by less than this fraction.
LOCAL_GAIN = 0.002


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
class _Checker:
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
        rv, ra, rj = self.ratios(law, exact)
        target = 1.0 - CHECK_MARGIN
        return max(1.0, rv / target, math.sqrt(ra / target), math.cbrt(rj / target))

    def search(self, pieces: list[tuple[float, StarPiece]], tables: kernels.Pinned | None, width: np.ndarray,
               above: float = math.inf) -> tuple[float, float, bool]:
        """:meth:`stretch` on the search grid of the box law of ``pieces`` with window ``width``
        (``tables``: their :func:`.box_filter.star_tables`): (stretch, duration, exact). Not exact:
        the check stopped once stretch x duration was certainly longer than ``above`` (s), and the
        stretch is a lower bound, with stretch x duration > ``above``."""
        if kernels.active() and tables is not None and self.tool is None and not self.ps.jumps3.size:
            target = 1.0 - CHECK_MARGIN
            t_star = sum(p.t_star for _, p in pieces)
            # on the stretch: over Lam, stretch x duration > above (duration within round-off of this sum)
            lam = above / (t_star + float(width.sum())) * (1.0 + 1e-9)
            rv, ra, rj, duration, peak, stopped = kernels.box_search_max(
                tables, width, self.ps.kernel_tables3, self._limits, _UNIFORM_S, self._samples(False),
                2 * SEARCH_SAMPLES, (lam * target, lam**2 * target, lam**3 * target), self._peak[0])
            if math.isfinite(duration) and duration > 0.0:
                if not stopped:
                    self._peak[0] = peak
                return max(1.0, rv / target, math.sqrt(ra / target), math.cbrt(rj / target)), duration, not stopped
        law = build_box_law(pieces, width, tables)
        return self.stretch(law), law.duration, True

    @functools.cached_property
    def _limits(self) -> kernels.Pinned:
        lim = self.limits
        jmax = lim.max_jerk if lim.max_jerk is not None else np.full(lim.max_velocity.size, np.inf)
        return kernels.limit_tables(lim.max_velocity, lim.max_acceleration, jmax)

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
        ps, lim = self.ps, self.limits
        vmax, amax = lim.max_velocity, lim.max_acceleration
        jmax = lim.max_jerk if lim.max_jerk is not None else np.full(vmax.size, np.inf)
        m = self._samples(full)
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
        out = (t, (s, sd, sdd, sddd), rv_t, ra_t, rj_t, need)
        self._last[:] = [law, full, out]
        return out

    def _samples(self, full: bool) -> int:
        """Uniform time samples of the dense grid (``full``) or of the search grid."""
        return max(10, int(self.check_samples) if self.check_samples is not None
                   else max(CHECK_SAMPLES, 5 * self.ps.s.size) if full else SEARCH_SAMPLES)

    def ratios(self, law: BoxLaw, exact: bool = True) -> tuple[float, float, float]:
        """Largest |v| / vmax, |a| / amax (tool speed included in v) and |j| / jmax of ``law``;
        ``exact``: see :meth:`stretch`."""
        ps = self.ps
        if not exact and kernels.active() and math.isfinite(law.duration) and law.duration > 0.0:
            # the search grid, the law there and its ratios in one compiled call (as _dense)
            t, s, sd, sdd, sddd, rv_t, ra_t, rj_t = kernels.box_search(
                law.tables, ps.kernel_tables3, self._limits, _UNIFORM_S, self._samples(False), 2 * SEARCH_SAMPLES)
            if self.tool is not None:
                rv_t = np.maximum(rv_t, self.tool.ratios(s, sd))
        else:
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
            for side in ((ps.aL, ps.bL, ps.cL), (ps.aR, ps.bR, ps.cR)):
                a_b, b_b, c_b = (arr[inner] for arr in side)
                rv, ra, rj = self._max_ratios((rv, ra, rj), a_b, b_b, c_b, sd_b, sdd_b, sddd_b)
            if self.tool is not None:
                for V in (self.tool.samples.aL[inner], self.tool.samples.aR[inner]):
                    rv = max(rv, float(np.max(self.tool.ratios_of(V.T, sd_b))))
        return rv, ra, rj

    def _max_ratios(self, prev: tuple[float, float, float], a: np.ndarray, b: np.ndarray,
                    c: np.ndarray, sd: np.ndarray, sdd: np.ndarray, sddd: np.ndarray
                    ) -> tuple[float, float, float]:
        """``prev`` raised by the ratios of exact derivatives a, b, c (K, dof) at sd, sdd, sddd (K,)."""
        lim = self.limits
        jmax = lim.max_jerk if lim.max_jerk is not None else np.full(a.shape[1], np.inf)
        sd, sdd, sddd = sd[:, None], sdd[:, None], sddd[:, None]
        return (max(prev[0], float(np.max(np.abs(a * sd) / lim.max_velocity))),
                max(prev[1], float(np.max(np.abs(a * sdd + b * sd**2) / lim.max_acceleration))),
                max(prev[2], float(np.max(np.abs(a * sddd + 3.0 * b * sd * sdd + c * sd**3) / jmax))))


def _reference_width(fine: PathSamples, x: np.ndarray, pieces: list[tuple[float, StarPiece]],
                     jmax: np.ndarray) -> np.ndarray:
    """Per piece, ``max_j A_j / jmax_j`` with A_j joint j's peak |acceleration| in s*, s."""
    u = np.diff(x) / (2.0 * np.diff(fine.s))
    acc = np.maximum(np.abs(fine.aR[:-1] * u[:, None] + fine.bR[:-1] * x[:-1, None]),
                     np.abs(fine.aL[1:] * u[:, None] + fine.bL[1:] * x[1:, None]))
    piece = np.cumsum(x[:-1] <= 0.0) - 1          # a new piece starts at every rest
    w = np.zeros(len(pieces))
    for i, (_, star) in enumerate(pieces):
        w[i] = max(float((acc[piece == i] / jmax).max()), 1e-6 * star.t_star)
    return w


@dataclass(frozen=True)
class JerkLimited:
    """Fastest jerk-limited rest-to-rest law this module builds (a :class:`~.law.TimeLaw`).

    Honours ``limits.max_jerk`` (required) besides the velocity, acceleration and tool limits.

    Attributes:
        grid_points: number of uniform s intervals at which the path is evaluated (>= 2).
        refine: the time-optimal pass runs on ``refine`` times finer steps (>= 1).
        check_samples: uniform time samples of the dense check (None: max(4000, 20 nodes)).
    Raises:
        LimitError: an option out of range (at construction).
    """

    grid_points: int = 100
    refine: int = 2
    check_samples: int | None = None
    honours_jerk = True

    def __post_init__(self) -> None:
        if int(self.grid_points) < 2:
            raise LimitError(f'grid_points must be >= 2, got {int(self.grid_points)}')
        if int(self.refine) < 1:
            raise LimitError(f'refine must be >= 1, got {self.refine}')

    def __call__(self, path: PathLike, limits: JointLimits, duration: float | None) -> Trajectory:
        """Time ``path`` within ``limits`` (jerk included); zero velocity and acceleration at every rest.

        Raises:
            LimitError: no ``limits.max_jerk``; ``duration`` shorter than the minimum (the
                message gives it); a path that cannot be traversed or returns bad derivatives.
        """
        if limits.max_jerk is None:
            raise LimitError('JerkLimited needs max_jerk')
        ps = refine_adaptively(path, sample_path(path, int(self.grid_points)))
        vmax, amax, jmax = limits.max_velocity, limits.max_acceleration, limits.max_jerk

        def trajectory(T: float, t_min: float, **kw: object) -> Trajectory:
            return Trajectory(path=path, joint_names=limits.joint_names, duration=float(T),
                              max_velocity=vmax, max_acceleration=amax, min_duration=float(t_min),
                              max_tool_speed=limits.max_tool_speed,
                              max_tool_angular_speed=limits.max_tool_angular_speed, max_jerk=jmax,
                              **kw)  # type: ignore[arg-type]

        if ps.aR.shape[1] != vmax.size:
            raise LimitError(f'path.evaluate returned {ps.aR.shape[1]} joints, expected {vmax.size}')
        if float(max(np.abs(ps.aR).max(), np.abs(ps.aL).max())) == 0.0:
            T = 0.0 if duration is None else duration
            return trajectory(T, 0.0, topp_duration=0.0, rest_times=(0.0, float(T)))
        tool = tool_rows(path, limits, ps)
        fine = ps.refined(int(self.refine))
        x_max = None if tool is None else tool.speed_cap(int(self.refine), TOPP_MARGIN)
        checker = _Checker(path, ps, limits, tool, self.check_samples)
        x0 = topp(fine, vmax * (1.0 - TOPP_MARGIN), amax * (1.0 - TOPP_MARGIN), x_max)
        t_star = sum(p.t_star for _, p in star_pieces(fine.s, x0))     # the v/a optimum

        def search(cap: np.ndarray | None) -> tuple[tuple[BoxLaw, float], np.ndarray, float]:
            """The shortest law over the acceleration scales, for the optimal pass under ``cap``."""
            found: tuple[tuple[BoxLaw, float], np.ndarray, float] | None = None
            start = WIDTH_SCAN.index(1.0)
            for beta in (1.0,) + ACCEL_SCALES:
                checkpoint()
                x = x0 if beta == 1.0 and cap is x_max else topp(
                    fine, vmax * (1.0 - TOPP_MARGIN), beta * amax * (1.0 - TOPP_MARGIN), cap)
                pieces = star_pieces(fine.s, x)
                w_ref = _reference_width(fine, x, pieces, jmax)
                if found is not None and _floor(pieces, w_ref) >= found[0][1] * found[0][0].duration:
                    break       # this scale's laws are all longer than the one found: unsearched
                cand = _best_width(pieces, w_ref, checker, start)
                # the next scale's scan starts from this one's width factor (nearest grid point)
                c = float(np.median(cand[0].width / w_ref))
                start = int(np.argmin([abs(math.log(c / g)) for g in WIDTH_SCAN]))
                total = cand[1] * cand[0].duration
                if found is not None and total >= found[0][1] * found[0][0].duration:
                    break
                found = (cand, x, beta)
                if beta == 1.0 and total <= LOOSE * t_star:
                    break
            assert found is not None
            return found

        # Where the optimal profile runs far above the cruise cap of the jerk rows (a sharp
        # feature such as a blend), the search runs under that cap; elsewhere under x_max.
        cruise = cruise_cap(ps, fine.s, jmax)
        cap = x_max
        if np.any(cruise < CRUISE_TRIGGER * x0):
            cap = cruise if x_max is None else np.minimum(x_max, cruise)
        best, best_x, best_beta = search(cap)
        law, lam = best
        if lam > LOCAL_TRIGGER:     # a local dip the filter cannot follow: slow down near it
            law, lam = _local_passes(fine, best_x, best_beta, best, checker, cap, jmax)
        # The search compared widths on interpolated derivatives; the law kept is checked exactly.
        lam = checker.stretch(law, exact=True)
        t_min = lam * law.duration
        T = final_duration(duration, t_min)
        scale = float(T / law.duration)
        rest_times = tuple(float(t) * scale for t in law.t_offsets[:-1]) + (float(T),)
        return trajectory(T, t_min, topp_duration=t_star, rests=law.rests, rest_times=rest_times,
                          scaling=law, time_scale=scale)


def cruise_cap(ps: PathSamples, s_fine: np.ndarray, jmax: np.ndarray) -> np.ndarray:
    """Cap on x = sdot^2 at ``s_fine`` from the jerk rows at cruise (sdot constant, the jerk is
    q''' sdot^3): x <= (jmax / |q'''|)^(2/3), the lower of each coarse step's two ends, 1/s^2."""
    c3 = (np.maximum(np.abs(ps.cL), np.abs(ps.cR)) / jmax).max(axis=1)
    with np.errstate(divide='ignore'):
        cruise = np.where(c3 > 0, c3, 0.0) ** (-2.0 / 3.0)
    step = np.minimum(cruise[:-1], cruise[1:])
    k = np.clip(np.searchsorted(ps.s, s_fine, side='right') - 1, 0, step.size - 1)
    return step[k]


def _local_passes(fine: PathSamples, x: np.ndarray, beta: float, best: tuple[BoxLaw, float],
                  checker: _Checker, x_max: np.ndarray | None, jmax: np.ndarray
                  ) -> tuple[BoxLaw, float]:
    """Cap the optimal profile near the samples over a limit and filter again (as in
    :mod:`.smoothing`, step 3), keeping the shortest checked law; (law, its stretch)."""
    lim = checker.limits
    law, lam = best
    cap = x_max
    stale = 0
    for _ in range(LOCAL_PASSES):
        checkpoint()
        t, need = checker.need(law)
        cap = local_cap(fine.s, x, law, t, need, float(law.width.max()), cap)
        x = topp(fine, lim.max_velocity * (1.0 - TOPP_MARGIN),
                 beta * lim.max_acceleration * (1.0 - TOPP_MARGIN), cap)
        pieces = star_pieces(fine.s, x)
        if len(pieces) != law.width.size:      # the rests moved: search the width again
            law, lam = _best_width(pieces, _reference_width(fine, x, pieces, jmax), checker)
        else:                                  # keep the window: one check per pass
            law = build_box_law(pieces, law.width)
            lam = checker.stretch(law)
        gain = lam * law.duration < (1.0 - LOCAL_GAIN) * best[1] * best[0].duration
        if lam * law.duration < best[1] * best[0].duration:
            best = (law, lam)
        stale = 0 if gain else stale + 1
        if lam <= 1.0 + CHECK_MARGIN or stale >= 2:     # within the limits, or no longer paying
            break
    return best


def _floor(pieces: list[tuple[float, StarPiece]], w_ref: np.ndarray) -> float:
    """A lower bound on the duration of every law :func:`_best_width` tries on ``pieces`` (s): each
    width is at least WIDTH_SCAN[0] w_ref and each stretch at least 1 (round-off aside)."""
    return (sum(p.t_star for _, p in pieces) + WIDTH_SCAN[0] * float(w_ref.sum())) * (1.0 - 1e-12)


def _best_width(pieces: list[tuple[float, StarPiece]], w_ref: np.ndarray, checker: _Checker,
                start: int = WIDTH_SCAN.index(1.0)) -> tuple[BoxLaw, float]:
    """The width factor with the shortest checked duration, searched from ``WIDTH_SCAN[start]``:
    (law, its stretch)."""
    # log c -> (stretch x duration, width, stretch, exact); not exact: a lower bound, longer than
    # a duration known exactly (the check stopped there; see _Checker.search)
    cache: dict[float, tuple[float, np.ndarray, float, bool]] = {}
    tables = star_tables(pieces) if kernels.active() else None    # the same s* for every width

    def total(log_c: float, above: float = math.inf) -> float:
        """The duration of width factor exp(log_c), exact, or any value longer than ``above``."""
        hit = cache.get(log_c)
        if hit is None or (not hit[3] and hit[0] <= above):
            width = math.exp(log_c) * w_ref
            lam, duration, exact = checker.search(pieces, tables, width, above)
            hit = cache[log_c] = (lam * duration, width, lam, exact)
        return hit[0]

    def known(log_c: float) -> float:
        """The exact duration of exp(log_c) when already checked, else infinity."""
        hit = cache.get(log_c)
        return hit[0] if hit is not None and hit[3] else math.inf

    def shorter_or_equal(x: float, y: float) -> bool:
        """total(x) <= total(y): the one known first, the other only as far as that decides."""
        if known(y) == math.inf:      # x first, as the comparison reads
            tx = total(x)
            return tx <= total(y, above=tx)
        ty = total(y)
        return total(x, above=ty) <= ty

    # The coarse scan walks from ``start`` towards the smaller durations and stops at the first
    # grid point whose neighbours are both longer (the full scan's choice whenever the durations
    # on the grid fall, then rise; 3-4 checks instead of 7).
    grid = [math.log(c) for c in WIDTH_SCAN]
    i = start
    while True:
        checkpoint()
        near = [j for j in (i - 1, i, i + 1) if 0 <= j < len(grid)]
        best = math.inf
        for k in near:      # in order; past the shortest so far, a check may stop early
            best = min(best, total(grid[k], above=best) if known(grid[k]) == math.inf else known(grid[k]))
        j = min(near, key=lambda k: cache[grid[k]][0])
        if j == i:
            break
        i = j
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    ratio = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    for _ in range(GOLDEN_STEPS):
        checkpoint()
        if shorter_or_equal(a, b):
            hi, b = b, a
            a = hi - ratio * (hi - lo)
        else:
            lo, a = a, b
            b = lo + ratio * (hi - lo)
    _, width, lam, exact = min(cache.values(), key=lambda item: item[0])
    assert exact        # a check stops early only past a shorter, exact duration
    return build_box_law(pieces, width, tables), lam


__all__ = ['JerkLimited', 'cruise_cap']
