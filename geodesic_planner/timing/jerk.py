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
   accelerations allow gentler ramps: the 7-segment optimum peaks at sqrt(vmax jmax)). A path
   without rests inside also gets the 7-segment laws of s under constant bounds, stretched into
   the limits (:func:`_constant_bound`), first: the shortest of them bounds the search (scales,
   checks and local passes that cannot beat it are skipped or stopped); the shortest law is kept.
4. ``duration=`` stretches the law uniformly (never shorter than the minimum).

A path that declares itself a straight joint line (``joint_line``: a PTP's
:class:`~geodesic_planner.core.ptp.JointLinePath`) without tool limits skips all of this: its
time-optimal 7-segment law is in closed form (:mod:`.line_profile`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from . import kernels
from .law import final_duration
from .line_profile import line_bounds, seven_segment, time_joint_line
from .types import JointLimits, PathLike
from .sampling import PathSamples, refine_adaptively, sample_path
from .checks import local_cap
from .tuning import CHECK_MARGIN, LOCAL_PASSES, TOPP_MARGIN
from .tool import tool_rows
from .topp import topp
from .box_filter import BoxLaw, StarPiece, build_box_law, star_pieces, star_tables
from .box_check import BoxCheck
from .trajectory import Trajectory

#: Width factors of the coarse scan (times the reference width), then golden-section steps.
WIDTH_SCAN = (0.5, 0.71, 1.0, 1.41, 2.0, 2.83, 4.0)
GOLDEN_STEPS = 5
#: Acceleration scales of the optimal pass tried in order when the jerk binds (over LOOSE times
#: the v/a optimum), until one does not shorten the law.
ACCEL_SCALES = (0.7, 0.5, 0.35, 0.25)
LOOSE = 1.1
#: With a constant-bound law known first, a scale none of whose laws beat it leaves the gentler
#: scales unsearched unless its shortest (lower bound of a) law came within this fraction of it.
SCALE_NEAR = 0.005
#: Local slow-down passes (:func:`_local_passes`) run above this stretch (a dip the filter cannot follow).
LOCAL_TRIGGER = 1.1
#: The search under the cruise cap of the jerk rows runs when that cap is below this fraction of
#: the v/a-optimal x somewhere (0.03-0.07 at blends; 0.65 or more on the single moves measured).
CRUISE_TRIGGER = 0.5
#: Local passes stop after two in a row that shorten the law by less than this fraction.
LOCAL_GAIN = 0.002
#: Whether the constant-bound 7-segment laws (:func:`_constant_bound`) are tried. Off: on a ur5e LIN
#: found in a whole-suite run (test_jerk's random moves) such a law passed the exact check and yet
#: exceeded a joint's jerk limit by 9e-4 between the check's points; until that check covers this
#: law's shape, a law that may exceed a limit is not returned.
CONSTANT_BOUND_LAWS = False
#: (acceleration, jerk) factors on the constant bounds of :func:`_constant_bound`'s 7-segment laws.
CONSTANT_SHAPES = ((1.0, 1.0), (1.2, 0.6), (0.8, 0.8))


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
        line = getattr(path, 'joint_line', None)
        if line is not None and limits.max_tool_speed is None and limits.max_tool_angular_speed is None:
            return time_joint_line(path, line, limits, duration)     # closed form, time-optimal
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
        checker = BoxCheck(path, ps, limits, tool, self.check_samples)
        x0 = topp(fine, vmax * (1.0 - TOPP_MARGIN), amax * (1.0 - TOPP_MARGIN), x_max)
        pieces0 = star_pieces(fine.s, x0)
        t_star = sum(p.t_star for _, p in pieces0)     # the v/a optimum

        # A path without rests or breakpoints inside (not a blend) also gets the constant-bound
        # 7-segment laws, first: the shortest of them bounds the search (what cannot beat it is
        # not searched, and a check stops once certainly longer).
        bound: tuple[BoxLaw, float] | None = None
        if CONSTANT_BOUND_LAWS and len(pieces0) == 1 and not ps.jumps3.size:
            bound = _constant_bound(fine, limits, checker)

        def search(cap: np.ndarray | None) -> tuple[tuple[BoxLaw, float], np.ndarray, float] | None:
            """The shortest law over the acceleration scales, for the optimal pass under ``cap``,
            if one is shorter than ``bound``."""
            found: tuple[tuple[BoxLaw, float], np.ndarray, float] | None = None
            best_total = math.inf if bound is None else bound[1] * bound[0].duration
            start = WIDTH_SCAN.index(1.0)
            for beta in (1.0,) + ACCEL_SCALES:
                checkpoint()
                x = x0 if beta == 1.0 and cap is x_max else topp(
                    fine, vmax * (1.0 - TOPP_MARGIN), beta * amax * (1.0 - TOPP_MARGIN), cap)
                pieces = pieces0 if x is x0 else star_pieces(fine.s, x)
                w_ref = _reference_width(fine, x, pieces, jmax)
                if _floor(pieces, w_ref) >= best_total:
                    break       # this scale's laws are all longer than the one found: unsearched
                cand, shortest = _best_width(pieces, w_ref, checker, start, best_total)
                if cand is None:
                    # none shorter than the law found; beside the constant-bound law alone, a
                    # gentler scale is still tried when this one came close (``shortest``: its
                    # shortest lower bound)
                    if found is not None or shortest > (1.0 + SCALE_NEAR) * best_total:
                        break
                    continue
                # the next scale's scan starts from this one's width factor (nearest grid point)
                c = float(np.median(cand[0].width / w_ref))
                start = int(np.argmin([abs(math.log(c / g)) for g in WIDTH_SCAN]))
                total = cand[1] * cand[0].duration
                if total >= best_total:
                    break
                found, best_total = (cand, x, beta), total
                if beta == 1.0 and total <= LOOSE * t_star:
                    break
            return found

        # Where the optimal profile runs far above the cruise cap of the jerk rows (a sharp
        # feature such as a blend), the search runs under that cap; elsewhere under x_max.
        cruise = cruise_cap(ps, fine.s, jmax)
        cap = x_max
        if np.any(cruise < CRUISE_TRIGGER * x0):
            cap = cruise if x_max is None else np.minimum(x_max, cruise)
        found = search(cap)
        if found is None:           # the constant-bound law is the shortest
            assert bound is not None
            law, lam = bound
        else:
            best, best_x, best_beta = found
            law, lam = best
            if lam > LOCAL_TRIGGER:     # a local dip the filter cannot follow: slow down near it
                law, lam = _local_passes(fine, best_x, best_beta, best, checker, cap, jmax, bound)
            if bound is not None and len(law.width) == 1 and bound[1] * bound[0].duration < lam * law.duration:
                law, lam = bound
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
                  checker: BoxCheck, x_max: np.ndarray | None, jmax: np.ndarray,
                  bound: tuple[BoxLaw, float] | None = None) -> tuple[BoxLaw, float]:
    """Cap the optimal profile near the samples over a limit and filter again (as in
    :mod:`.smoothing`, step 3), keeping the shortest checked law; (law, its stretch).

    Each pass only lowers the cap, so its profile is slower and, with the window kept, its law
    no shorter before the stretch: once the law is as long as ``bound``'s stretched duration (a
    law known to be kept otherwise), no further pass can win and none is run."""
    lim = checker.limits
    law, lam = best
    cap = x_max
    stale = 0
    known = math.inf if bound is None else bound[1] * bound[0].duration
    for _ in range(LOCAL_PASSES):
        checkpoint()
        if law.duration * (1.0 - 1e-12) >= min(known, best[1] * best[0].duration):
            break
        t, need = checker.need(law)
        cap = local_cap(fine.s, x, law, t, need, float(law.width.max()), cap)
        x = topp(fine, lim.max_velocity * (1.0 - TOPP_MARGIN),
                 beta * lim.max_acceleration * (1.0 - TOPP_MARGIN), cap)
        pieces = star_pieces(fine.s, x)
        if len(pieces) != law.width.size:      # the rests moved: search the width again
            cand, _ = _best_width(pieces, _reference_width(fine, x, pieces, jmax), checker)
            assert cand is not None         # no bound: every check exact
            law, lam = cand
        else:                                  # keep the window: one check per pass
            tables = star_tables(pieces) if kernels.active() else None
            law = build_box_law(pieces, law.width, tables)
            lam = checker.search(pieces, tables, law.width, min(known, best[1] * best[0].duration))[0]
        gain = lam * law.duration < (1.0 - LOCAL_GAIN) * best[1] * best[0].duration
        if lam * law.duration < best[1] * best[0].duration:
            best = (law, lam)
        stale = 0 if gain else stale + 1
        if lam <= 1.0 + CHECK_MARGIN or stale >= 2:     # within the limits, or no longer paying
            break
    return best


def _constant_bound(fine: PathSamples, limits: JointLimits, checker: BoxCheck) -> tuple[BoxLaw, float] | None:
    """The shortest of the 7-segment laws of s under constant bounds (:mod:`.line_profile` with the
    path's largest |q'| per joint as the line's steps, the acceleration and jerk bounds times
    CONSTANT_SHAPES), each uniformly stretched into the limits: (law, its stretch); None if none.

    Such a law is the box filter of the trapezoid ``x = min(vp^2, 2 a s, 2 a (1 - s))`` with the
    window ``a / J`` (a its peak acceleration, :class:`.line_profile.SevenSegment`), built on the
    trapezoid's own four nodes, so exactly. Where the path is nearly straight in the joints and the
    jerk binds, it beats the filtered time-optimal profile (whose window is the same everywhere
    and whose acceleration peaks below the limit): ur5e LINs at 15 rad/s^3 up to 14 % shorter."""
    steps = np.maximum(np.abs(fine.aL), np.abs(fine.aR)).max(axis=0)
    if not np.any(steps):
        return None
    best: tuple[BoxLaw, float] | None = None
    known = math.inf
    V, A, J = line_bounds(steps, limits, TOPP_MARGIN)
    for fa, fj in CONSTANT_SHAPES:
        checkpoint()
        seven = seven_segment(V, fa * A, fj * J)
        a_peak, x_peak = seven.peak_acceleration, seven.peak_velocity ** 2
        corner = x_peak / (2.0 * a_peak)        # the trapezoid's own nodes: its s* is exact
        if not 0.0 < corner < 0.5:
            continue
        pieces = star_pieces(np.array([0.0, corner, 1.0 - corner, 1.0]), np.array([0.0, x_peak, x_peak, 0.0]))
        if len(pieces) != 1:
            continue
        tables = star_tables(pieces) if kernels.active() else None
        # a window a hair shorter than the star's cruise when the 7-segment law has none (two jerk
        # events would coincide there, and a check could read them as one jump of 2 J)
        width = np.array([a_peak / (fj * J) * (1.0 - 1e-6)])
        lam, duration, exact = checker.search(pieces, tables, width, known)
        if exact and lam * duration < known:
            best, known = (build_box_law(pieces, width, tables), lam), lam * duration
    return best


def _floor(pieces: list[tuple[float, StarPiece]], w_ref: np.ndarray) -> float:
    """A lower bound on the duration of every law :func:`_best_width` tries on ``pieces`` (s): each
    width is at least WIDTH_SCAN[0] w_ref and each stretch at least 1 (round-off aside)."""
    return (sum(p.t_star for _, p in pieces) + WIDTH_SCAN[0] * float(w_ref.sum())) * (1.0 - 1e-12)


def _best_width(pieces: list[tuple[float, StarPiece]], w_ref: np.ndarray, checker: BoxCheck,
                start: int = WIDTH_SCAN.index(1.0), bound: float = math.inf
                ) -> tuple[tuple[BoxLaw, float] | None, float]:
    """The width factor with the shortest checked duration, searched from ``WIDTH_SCAN[start]``:
    ((law, its stretch), stretched duration); (None, the shortest lower bound seen) when no width
    tried is shorter than ``bound`` (s: a law known already; each check stops once certainly
    longer than it)."""
    # log c -> (stretch x duration, width, stretch, exact); not exact: a lower bound, longer than
    # a duration known exactly (the check stopped there; see BoxCheck.search)
    cache: dict[float, tuple[float, np.ndarray, float, bool]] = {}
    tables = star_tables(pieces) if kernels.active() else None    # the same s* for every width

    def total(log_c: float, above: float = math.inf) -> float:
        """The duration of width factor exp(log_c), exact, or any value longer than ``above``."""
        hit = cache.get(log_c)
        above = min(above, bound)
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
            best = min(best, total(grid[k], above=best))
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
    shortest, width, lam, exact = min(cache.values(), key=lambda item: item[0])
    if not exact:       # a check stops early only past a shorter, exact duration, or ``bound``
        return None, shortest
    return (build_box_law(pieces, width, tables), lam), shortest


__all__ = ['JerkLimited', 'cruise_cap']
