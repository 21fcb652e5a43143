"""The rest-to-rest smoothing law: time-optimal profile, smoothed, checked against the limits.

1. The path is sampled (:mod:`.sampling`) and its time-optimal profile computed (:mod:`.topp`)
   with limits * (1 - TOPP_MARGIN); its duration is :attr:`Trajectory.topp_duration`. Tool speed
   limits, when given, are velocity rows like the joints' (:mod:`.tool`): a cap on sdot^2.
2. **Smoothing**: ``s*(t)`` has acceleration jumps (bang-bang), including at both ends. Each
   rest-to-rest piece (the rests: both ends and the corners of the path) is convolved with a
   triangular kernel of half-width ``tau = smoothing * T* / 2``, done exactly:
   ``s(t) = (S2(t + tau) - 2 S2(t) + S2(t - tau)) / tau^2`` with ``S2`` the second antiderivative
   of ``s*`` (constant before its start and after its end). Hence ``sddot`` is the second central
   difference of ``s*`` (continuous), the jerk is bounded, and every rest has zero velocity AND
   zero acceleration. Each piece lasts ``T* + 2 tau``.
3. **Local slow-down**: where the smoothed law exceeds a limit by more than LOCAL_TRIGGER (a
   sharp dip of the optimal speed that the kernel cannot follow, e.g. a blend around a via
   point), the optimal profile is capped near the offending samples (x divided by their speed
   factor over the path crossed within ``LOCAL_WINDOW * tau`` of them) and smoothed again, up to
   LOCAL_PASSES times; the shortest law after step 4 is kept. Laws within LOCAL_TRIGGER skip it.
4. **Guarantee**: the law is checked on a dense time grid against the full limits (plus samples
   about uniform in s, placed from the nodes of ``s*`` delayed by tau, where the law crosses the
   path fast); if smoothing pushed any joint (or the tool) over a limit, time is stretched uniformly
   (``t -> lambda t`` divides velocities by ``lambda`` and accelerations by ``lambda^2``) until
   every sample is within ``1 - CHECK_MARGIN`` of the limits; the samples nearest a limit are
   re-checked with the exact path derivatives. ``min_duration / topp_duration`` is about
   ``1 + smoothing`` on paths without such dips.
5. ``duration=`` stretches the law uniformly to exactly that duration (never shorter than the
   minimum, which the error names).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from . import kernels
from ._arrays import clip
from .law import final_duration
from .types import JointLimits, PathLike
from .sampling import refine_adaptively, sample_path
from .tool import tool_rows
from .checks import local_cap
from .tuning import (LOCAL_PASSES, TOPP_MARGIN)
from .topp import topp
from .smooth_check import check_law
from .trajectory import Trajectory

#: The smoothed law needs a uniform stretch above this: local slow-down passes (LOCAL_PASSES
#: of them, see SmoothRestToRest), each capping the optimal profile near the samples over a limit.
LOCAL_TRIGGER = 1.01
#: A speed valley inside a rest-to-rest piece is deep when sdot drops below this fraction of the
#: peak speed on both sides; the kernel of a piece with k deep valleys is (1 + k) times narrower
#: (its ramps take ``smoothing`` of the time between valleys, as between rests).
VALLEY_DEPTH = 0.5
#: The cap of a local pass (:func:`.checks.local_cap`) covers the path the law crosses within
#: LOCAL_WINDOW * tau of each offending sample (narrow and gentle, repeated, slows the least: on
#: the blends of benchmarks/blends.py windows of 1, 0.5 and 0.25 tau gave 2.579, 2.503 and 2.478 s
#: on ur5e at r = 3 cm; 0.1 tau was erratic).
LOCAL_WINDOW = 0.25


@dataclass(frozen=True, eq=False)
class PiecewiseLaw:
    """The smoothed law: rest-to-rest pieces one after the other (rests at corners of the path).

    Piece i runs from ``t_offsets[i]`` for ``T*_i + 2 tau_i``: its time-optimal law ``s*``
    (piecewise quadratic, relative to the piece's start ``s_start``: 0 before it starts, ``span``
    after it ends) smoothed by a triangular kernel of half-width ``tau_i``. All pieces are
    evaluated together: their ``s*`` segments sit in one table, searched by the key
    ``i * key_step + local time`` (``key_step`` exceeds four times every piece's duration, so the
    pieces' key ranges do not overlap); polynomials are evaluated in local time.
    """

    t_offsets: np.ndarray  # (L + 1,) start time of each piece; the last is the total duration
    pieces: np.ndarray     # (6, L): tau, duration, s_start, span, s_end, T* of each piece
    key_step: float
    seg_key: np.ndarray    # (S,) segment starts (keys)
    seg: np.ndarray        # (6, S): start (local time), s0, v0, u, S1, S2 of each s* segment
    node_s: np.ndarray     # (N + L,) path parameter at the nodes of s*, piece after piece
    node_t: np.ndarray     # (N + L,) their times in s* delayed by tau

    @property
    def n_pieces(self) -> int:
        return self.pieces.shape[1]

    @functools.cached_property
    def seg_3(self) -> np.ndarray:
        """The segment table three times side by side, (6, 3 S) (one copy per shift of the kernel)."""
        return np.tile(self.seg, 3)

    @functools.cached_property
    def kernel_tables(self) -> kernels.LawTables:
        """The tables for the compiled :func:`.kernels.evaluate`."""
        return kernels.piecewise_tables(self.t_offsets, self.pieces, self.key_step, self.seg_key, self.seg)

    @property
    def duration(self) -> float:
        return float(self.t_offsets[-1])

    @property
    def t_star(self) -> float:
        return float(sum(self.pieces[5].tolist()))

    @property
    def rests(self) -> tuple[float, ...]:
        """Path parameters of the rests: each piece's start, then the last end."""
        return (float(self.pieces[2, 0]),) + tuple(self.pieces[4].tolist())

    def times_at(self, s: np.ndarray) -> np.ndarray:
        """Approximate times (M,) at which the smoothed law passes the path parameters ``s`` (M,).

        The time-optimal law's nodes delayed by tau (the smoothed law averages s* over
        [t - 2 tau, t]), linearly interpolated: cheap, and close enough to place check samples.
        """
        return np.interp(s, self.node_s, self.node_t)

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at times t (M,) in [0, duration] (clipped)."""
        t = np.asarray(t, dtype=float)
        if kernels.active() and t.ndim == 1:
            return kernels.evaluate(self.kernel_tables, t, jerk)
        offs = self.t_offsets
        nl = self.n_pieces
        if nl == 1:
            local = clip(t, 0.0, self.duration)
            tau, dur, s_start, span, s_end = self.pieces[:5, 0].tolist()
            key_off: float | np.ndarray = 0.0
        else:
            # Times within round-off of a rest snap onto it (exact rest there).
            j = clip(np.searchsorted(offs, t), 1, offs.size - 1)
            near = np.where(np.abs(t - offs[j - 1]) <= np.abs(t - offs[j]), offs[j - 1], offs[j])
            t = np.where(np.abs(t - near) <= 1e-12 * max(1.0, self.duration), near, t)
            idx = clip(np.searchsorted(offs, t, side='right') - 1, 0, nl - 1)
            tau, dur, s_start, span, s_end = self.pieces[:5].take(idx, axis=1)
            local = clip(np.where(t >= offs.take(idx + 1), dur, t - offs.take(idx)), 0.0, dur)
            key_off = idx * self.key_step
        # s* and its integrals at local - j tau, j = 0, 1, 2 (the smoothed law is their second
        # central difference: a triangular kernel of half-width tau).
        c = local - tau
        q = np.concatenate([local, c, c - tau])
        m = local.size
        key = q + np.concatenate([key_off] * 3) if nl > 1 else q
        runs = key.reshape(3, m)
        ordered = m > 1 and bool(np.all(runs[:, 1:] >= runs[:, :-1]))
        if ordered:
            # Sorted times (the usual case): each run's samples per segment, by searching the
            # segment starts in the run, then repeats of the table rows (one array per row: large
            # 2-D temporaries cost more, in fresh memory, than the extra calls).
            counts = np.concatenate([np.diff(np.searchsorted(run, self.seg_key, side='left'), append=m)
                                     for run in runs])
            start, s0, v0, u, S1, S2 = (np.repeat(row, counts) for row in self.seg_3)
        else:
            k = np.searchsorted(self.seg_key, key, side='right') - 1
            start, s0, v0, u, S1, S2 = (row.take(k) for row in self.seg)
        # Horner, in place: S2 + r (S1 + r (s0 / 2 + r (v0 / 6 + r u / 24))), and likewise.
        r = q - start
        ru = r * u
        w2 = ru / 24.0
        w2 += v0 / 6.0
        w2 *= r
        w2 += 0.5 * s0
        w2 *= r
        w2 += S1
        w2 *= r
        w2 += S2
        w1 = ru / 6.0
        w1 += 0.5 * v0
        w1 *= r
        w1 += s0
        w1 *= r
        w1 += S1
        w0 = 0.5 * ru
        w0 += v0
        w0 *= r
        w0 += s0
        inv = 1.0 / (tau * tau)

        def second_difference(y: np.ndarray) -> np.ndarray:
            y = y.reshape(3, m)
            out = y[0] - 2.0 * y[1]
            out += y[2]
            out *= inv
            return out

        s = s_start + clip(second_difference(w2), 0.0, span)
        sd = np.maximum(second_difference(w1), 0.0)
        sdd = second_difference(w0)
        if jerk:
            ru += v0
            sddd = second_difference(ru)
        else:
            sddd = None
        # Exact ends: at rest, at s_start and s_end.
        if ordered and nl == 1:  # the ends are a prefix and a suffix
            first = int(np.searchsorted(local, 0.0, side='right'))   # local <= 0
            last = int(np.searchsorted(local, dur, side='left'))     # local >= dur from here
            s[:first] = s_start
            s[last:] = s_end
            for arr in (sd, sdd) if sddd is None else (sd, sdd, sddd):
                arr[:first] = 0.0
                arr[last:] = 0.0
            return s, sd, sdd, sddd
        end = local >= dur
        start_ = local <= 0.0
        s = np.where(end, s_end, np.where(start_, s_start, s))
        zero = end | start_
        if np.any(zero):
            sd, sdd = np.where(zero, 0.0, sd), np.where(zero, 0.0, sdd)
            if sddd is not None:
                sddd = np.where(zero, 0.0, sddd)
        return s, sd, sdd, sddd


def _valleys(x: np.ndarray, rests: np.ndarray) -> np.ndarray:
    """Per rest-to-rest piece, the number of deep speed valleys inside it (sdot below
    VALLEY_DEPTH times the peak speed on both sides, e.g. a blend around a via point)."""
    v = np.sqrt(np.maximum(x, 0.0))
    out = np.zeros(rests.size - 1)
    for i, (a, b) in enumerate(zip(rests[:-1].tolist(), rests[1:].tolist())):
        w = v[a:b + 1]
        left = np.maximum.accumulate(w)
        right = np.maximum.accumulate(w[::-1])[::-1]
        deep = w < VALLEY_DEPTH * np.minimum(left, right)
        out[i] = np.count_nonzero(deep[1:] & ~deep[:-1])
    return out


def build_piecewise_law(s_nodes: np.ndarray, x: np.ndarray, smoothing: float) -> PiecewiseLaw:
    """Split the optimal profile at its rests (x = 0) and smooth each rest-to-rest piece.

    On each step of a piece ``sddot*`` is constant, so ``s*(t)`` is exactly piecewise quadratic;
    its first and second integrals S1, S2 accumulate from the piece's start. All pieces at once:
    per-piece running sums are row-wise sums of a padded (pieces, steps) array.
    """
    rests = np.flatnonzero(x <= 0.0)
    if kernels.active():        # the same tables, compiled
        return PiecewiseLaw(*kernels.build_piecewise(s_nodes, x, rests, smoothing, VALLEY_DEPTH))
    n_steps = np.diff(rests)                       # (L,) steps per piece
    L = n_steps.size
    k = np.arange(rests[0], rests[-1])             # steps, piece after piece
    piece = np.repeat(np.arange(L), n_steps)
    first = rests[:-1]
    pos = k - first[piece]                         # index of the step in its piece
    start_s = s_nodes[first]
    rel0 = s_nodes[k] - start_s[piece]             # s at the step's ends, relative to the piece
    rel1 = s_nodes[k + 1] - start_s[piece]
    dl = rel1 - rel0
    v = np.sqrt(x)
    v0 = v[k]
    dt = 2.0 * dl / (v0 + v[k + 1])
    u = (x[k + 1] - x[k]) / (2.0 * dl)

    def running(vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per piece, the running sum of ``vals`` (N,) at the end and at the start of each step."""
        if L == 1:
            end = np.cumsum(vals)
        else:
            pad = np.zeros((L, int(n_steps.max())))
            pad[piece, pos] = vals
            end = np.cumsum(pad, axis=1)[piece, pos]
        begin = np.concatenate([[0.0], end[:-1]])
        begin[pos == 0] = 0.0
        return end, begin

    t1, t0 = running(dt)
    S1e, S1s = running(rel0 * dt + v0 * dt**2 / 2.0 + u * dt**3 / 6.0)
    S2e, S2s = running(S1s * dt + rel0 * dt**2 / 2.0 + v0 * dt**3 / 6.0 + u * dt**4 / 24.0)
    last = np.cumsum(n_steps) - 1                  # last step of each piece
    t_star = t1[last]
    tau = 0.5 * smoothing * t_star / (1.0 + _valleys(x, rests))
    dur = t_star + 2.0 * tau
    offsets = np.concatenate([[0.0], np.cumsum(dur)])
    span = rel1[last]
    pieces = np.stack([tau, dur, start_s, span, s_nodes[rests[1:]], t_star])
    # Segments: per piece, the rest before it, its steps, the rest after it.
    idx = np.arange(L)
    seg_steps = np.arange(k.size) + 2 * piece + 1
    seg_after = last + 2 * idx + 2
    seg_before = seg_after - n_steps - 1
    seg = np.zeros((6, k.size + 2 * L))
    seg[:, seg_steps] = (t0, rel0, v0, u, S1s, S2s)
    seg[:, seg_after] = (t_star, span, np.zeros(L), np.zeros(L), S1e[last], S2e[last])
    # A power of two: i * key_step is exact; local times lie in [-2 tau, duration] within +-key_step / 4.
    key_step = float(2.0 ** math.ceil(math.log2(4.0 * max(float(dur.max()), 1e-300))))
    seg_key = seg[0].copy()
    if L > 1:
        seg_key[seg_steps] += piece * key_step
        seg_key[seg_after] += idx * key_step
    seg_key[seg_before] = (idx - 0.5) * key_step
    seg_key[0] = -np.inf
    # Nodes of s* (both ends of every piece), delayed by tau, for placing check samples.
    node_s = np.empty(k.size + L)
    node_t = np.empty(k.size + L)
    node_steps = np.arange(k.size) + piece
    node_s[node_steps] = start_s[piece] + rel0
    node_t[node_steps] = (offsets[:-1] + tau)[piece] + t0
    node_s[last + idx + 1] = start_s + span
    node_t[last + idx + 1] = offsets[:-1] + tau + t_star
    return PiecewiseLaw(offsets, pieces, key_step, seg_key, seg, node_s, node_t)


@dataclass(frozen=True)
class SmoothRestToRest:
    """Fastest smooth rest-to-rest law within the limits (a :class:`~.law.TimeLaw`).

    The path is evaluated once, at ``grid_points + 1`` uniform values of s plus its breakpoints;
    between the nodes, q' and q'' are interpolated (cubic Hermite with the exact q'' and q''' as
    slopes) for the time-optimal pass and the dense limit check; the returned trajectory itself
    evaluates the path exactly.

    Attributes:
        grid_points: number of uniform s intervals at which the path is evaluated (>= 2).
        refine: the time-optimal pass runs on ``refine`` times finer steps, with q' and q''
            interpolated in between (no further path evaluations); >= 1.
        smoothing: acceleration-ramp time as a fraction of the TOPP duration, in (0, 1]; the
            smooth law lasts about ``(1 + smoothing) * topp_duration``.
        check_samples: time samples of the dense limit check, uniform in t (None:
            max(CHECK_SAMPLES, 5 nodes)), before the samples around its peaks.
    Raises:
        LimitError: an option out of range (at construction).
    """

    grid_points: int = 100
    refine: int = 2
    smoothing: float = 0.05
    check_samples: int | None = None

    def __post_init__(self) -> None:
        if int(self.grid_points) < 2:
            raise LimitError(f'grid_points must be >= 2, got {int(self.grid_points)}')
        if int(self.refine) < 1:
            raise LimitError(f'refine must be >= 1, got {self.refine}')
        if not (0.0 < float(self.smoothing) <= 1.0):
            raise LimitError(f'smoothing must be in (0, 1], got {self.smoothing!r}')

    def __call__(self, path: PathLike, limits: JointLimits, duration: float | None) -> Trajectory:
        """Time ``path`` within ``limits``; zero velocity and acceleration at every rest.

        Raises:
            LimitError: ``duration`` shorter than the minimum (the message gives it), or a path
                that cannot be traversed or returns bad derivatives.
        """
        ps = refine_adaptively(path, sample_path(path, int(self.grid_points)))
        joint_names, vmax, amax = limits.joint_names, limits.max_velocity, limits.max_acceleration
        if ps.aR.shape[1] != vmax.size:
            raise LimitError(f'path.evaluate returned {ps.aR.shape[1]} joints, expected {vmax.size}')
        if float(max(np.abs(ps.aR).max(), np.abs(ps.aL).max())) == 0.0:
            # Stationary path: nothing moves; any duration (default 0) is feasible.
            T = 0.0 if duration is None else duration
            return Trajectory(path=path, joint_names=joint_names, duration=T, max_velocity=vmax,
                              max_acceleration=amax, topp_duration=0.0, min_duration=0.0,
                              rest_times=(0.0, float(T)), max_tool_speed=limits.max_tool_speed,
                              max_tool_angular_speed=limits.max_tool_angular_speed)
        tool = tool_rows(path, limits, ps)
        fine = ps.refined(int(self.refine))
        x_max = None if tool is None else tool.speed_cap(int(self.refine), TOPP_MARGIN)
        x = topp(fine, vmax * (1.0 - TOPP_MARGIN), amax * (1.0 - TOPP_MARGIN), x_max)
        law = build_piecewise_law(fine.s, x, float(self.smoothing))
        check = check_law(path, ps, law, vmax, amax, self.check_samples, tool)
        t_min = check.factor * law.duration
        topp_duration = law.t_star
        # Local slow-down: where smoothing pushed the law over a limit, cap the optimal profile
        # near there and smooth again, instead of stretching the whole motion.
        cap = x_max
        for _ in range(LOCAL_PASSES if check.factor > LOCAL_TRIGGER else 0):
            checkpoint()
            cap = local_cap(fine.s, x, law, check.t, check.need,
                            LOCAL_WINDOW * float(law.pieces[0].max()), cap)
            x = topp(fine, vmax * (1.0 - TOPP_MARGIN), amax * (1.0 - TOPP_MARGIN), cap)
            trial = build_piecewise_law(fine.s, x, float(self.smoothing))
            check = check_law(path, ps, trial, vmax, amax, self.check_samples, tool)
            if check.factor * trial.duration < t_min:
                law, t_min = trial, check.factor * trial.duration
            if check.factor <= LOCAL_TRIGGER:
                break
        T = final_duration(duration, t_min)
        scale = float(T / law.duration)
        rest_times = tuple(float(t) * scale for t in law.t_offsets[:-1]) + (float(T),)
        return Trajectory(path=path, joint_names=joint_names, duration=float(T), max_velocity=vmax,
                          max_acceleration=amax, topp_duration=topp_duration, min_duration=float(t_min),
                          rests=law.rests, rest_times=rest_times, scaling=law, time_scale=scale,
                          max_tool_speed=limits.max_tool_speed,
                          max_tool_angular_speed=limits.max_tool_angular_speed)


__all__ = ['LOCAL_TRIGGER', 'PiecewiseLaw',
           'SmoothRestToRest', 'build_piecewise_law']
