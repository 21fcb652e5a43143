"""The box filter of the jerk-limited law (:mod:`.jerk`, steps 1-2): the time-optimal profile's
rest-to-rest pieces ``s*`` (:class:`StarPiece`) and their moving average over a window ``w``
(:class:`BoxLaw`), evaluated exactly (``s*`` is piecewise quadratic in time).

``s(t) = (1 / w) int_{t - w}^{t} s*(r) dr``, so ``sdot = (s*(t) - s*(t - w)) / w``,
``sddot = (sdot*(t) - sdot*(t - w)) / w`` and ``sdddot = (u*(t) - u*(t - w)) / w``; each piece
lasts ``T* + w`` and starts and ends at rest. Units: s, path parameter s, 1/s, 1/s^2, 1/s^3.
"""
from __future__ import annotations

import functools
import itertools
from dataclasses import dataclass, field

import numpy as np

from . import kernels
from ._arrays import clip
from .checks import distinct_times


@dataclass(frozen=True, eq=False)
class StarPiece:
    """The time-optimal law of one rest-to-rest piece, ``s*(r) - s_start`` in local time r, s.

    Per step k (starting at ``t0[k]``): ``s* = s0 + v0 d + u d^2 / 2`` with ``d = r - t0[k]``;
    ``S1`` is the integral of ``s* - s_start`` from 0 to ``t0[k]``. Before 0: 0; after
    ``t_star``: ``span``, at rest.
    """

    t0: np.ndarray
    s0: np.ndarray
    v0: np.ndarray
    u: np.ndarray
    S1: np.ndarray
    t_star: float
    span: float
    S1_end: float

    def at(self, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Integral S1, s* - s_start, sdot*, sddot* at local times ``r`` (M,) (any real)."""
        k = clip(np.searchsorted(self.t0, r, side='right') - 1, 0, self.t0.size - 1)
        d = r - self.t0[k]
        s0, v0, u = self.s0[k], self.v0[k], self.u[k]
        S1 = self.S1[k] + d * (s0 + d * (0.5 * v0 + d * u / 6.0))
        s = s0 + d * (v0 + 0.5 * u * d)
        v = v0 + u * d
        before, after = r <= 0.0, r >= self.t_star
        zero = before | after
        S1 = np.where(before, 0.0, np.where(after, self.S1_end + self.span * (r - self.t_star), S1))
        s = np.where(before, 0.0, np.where(after, self.span, s))
        return S1, s, np.where(zero, 0.0, v), np.where(zero, 0.0, u)


def star_pieces(s_nodes: np.ndarray, x: np.ndarray) -> list[tuple[float, StarPiece]]:
    """Split the optimal profile x = sdot*^2 (n+1,) at its rests: (s_start, piece) per piece."""
    rests = np.flatnonzero(x <= 0.0)
    out = []
    for a, b in itertools.pairwise(rests):
        rel = s_nodes[a:b + 1] - s_nodes[a]
        dl = np.diff(rel)
        v = np.sqrt(x[a:b + 1])
        dt = 2.0 * dl / (v[:-1] + v[1:])
        u = (x[a + 1:b + 1] - x[a:b]) / (2.0 * dl)
        t0 = np.concatenate([[0.0], np.cumsum(dt)])
        s0, v0 = rel[:-1], v[:-1]
        S1 = np.concatenate([[0.0], np.cumsum(s0 * dt + v0 * dt**2 / 2.0 + u * dt**3 / 6.0)])
        out.append((float(s_nodes[a]), StarPiece(t0[:-1], s0, v0, u, S1[:-1], float(t0[-1]),
                                                  float(rel[-1]), float(S1[-1]))))
    return out


@dataclass(frozen=True, eq=False)
class BoxLaw:
    """The box-filtered law (a :class:`~.law.TimeScaling`): pieces one after the other.

    Piece i starts at ``t_offsets[i]`` at rest at ``s_start[i]`` and lasts
    ``stars[i].t_star + width[i]``.
    """

    stars: tuple[StarPiece, ...]
    s_start: np.ndarray
    width: np.ndarray
    t_offsets: np.ndarray
    star_tables: kernels.Pinned | None = field(default=None, repr=False)   # of ``stars`` (star_tables)

    @property
    def n_pieces(self) -> int:
        return len(self.stars)

    @property
    def duration(self) -> float:
        return float(self.t_offsets[-1])

    @property
    def t_star(self) -> float:
        return float(sum(p.t_star for p in self.stars))

    @property
    def rests(self) -> tuple[float, ...]:
        return (float(self.s_start[0]),) + tuple(float(s0 + p.span) for s0, p in zip(
            self.s_start, self.stars, strict=True))

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at times ``t`` (M,), clipped to [0, duration]."""
        if kernels.active() and np.ndim(t) == 1:
            return kernels.evaluate(self.tables, np.asarray(t, dtype=float), jerk)
        t = clip(np.asarray(t, dtype=float), 0.0, self.duration)
        offs = self.t_offsets
        out = np.zeros((4, t.size))
        idx = clip(np.searchsorted(offs, t, side='right') - 1, 0, self.n_pieces - 1)
        for i, star in enumerate(self.stars):
            m = idx == i
            w = float(self.width[i])
            dur = star.t_star + w
            r = clip(t[m] - offs[i], 0.0, dur)
            r = np.where(np.abs(r - dur) <= 1e-12 * max(1.0, self.duration), dur, r)
            both = star.at(np.concatenate([r, r - w]))     # s* now and w earlier, in one pass
            n = r.size
            A, B = [v[:n] for v in both], [v[n:] for v in both]
            s = clip((A[0] - B[0]) / w, 0.0, star.span)
            rows = (s, np.maximum((A[1] - B[1]) / w, 0.0), (A[2] - B[2]) / w, (A[3] - B[3]) / w)
            rest = (r <= 0.0) | (r >= dur)
            for j, row in enumerate(rows):
                out[j, m] = np.where(rest, 0.0, row)
            out[0, m] = self.s_start[i] + np.where(r >= dur, star.span, out[0, m])
        return out[0], out[1], out[2], (out[3] if jerk else None)

    @functools.cached_property
    def tables(self) -> kernels.LawTables:
        """The law's tables for the compiled :func:`.kernels.evaluate` (its pieces' s* from
        ``star_tables`` when given)."""
        stars = self.star_tables or star_tables(list(zip(self.s_start.tolist(), self.stars)))
        return kernels.box_tables(self.t_offsets, self.width, stars)

    def times_at(self, s: np.ndarray) -> np.ndarray:
        """Approximate times (M,) at which the law passes ``s`` (M,): s*'s nodes delayed by w / 2."""
        ts, ss = [], []
        for i, star in enumerate(self.stars):
            ts.append(self.t_offsets[i] + 0.5 * self.width[i] + np.append(star.t0, star.t_star))
            ss.append(self.s_start[i] + np.append(star.s0, star.span))
        return np.interp(s, np.concatenate(ss), np.concatenate(ts))

    def jerk_events(self) -> np.ndarray:
        """Sorted times where sdddot may jump: s*'s step starts, and the same delayed by w."""
        ev = [self.t_offsets[i] + np.append(star.t0, star.t_star) + shift
              for i, star in enumerate(self.stars) for shift in (0.0, float(self.width[i]))]
        return distinct_times(np.concatenate(ev + [self.t_offsets]))


def star_tables(pieces: list[tuple[float, StarPiece]]) -> kernels.Pinned:
    """The pieces' s* in flat tables for :func:`.kernels.box_tables`, the same for every window:
    ends (4, L) (T*, span, S1 at the end, s_start), each piece's first step (L + 1,), and the
    steps' t0, s0, v0, u, S1 (all pieces, in order)."""
    stars = [p for _, p in pieces]
    ends = np.array([[p.t_star for p in stars], [p.span for p in stars], [p.S1_end for p in stars],
                     [s for s, _ in pieces]], dtype=float)
    first = np.concatenate([[0], np.cumsum([p.t0.size for p in stars])]).astype(np.int64)
    steps = (np.concatenate([getattr(p, name) for p in stars]).astype(float) for name in ('t0', 's0', 'v0', 'u', 'S1'))
    return kernels.Pinned(ends, first, *steps)


def build_box_law(pieces: list[tuple[float, StarPiece]], width: np.ndarray,
                  tables: kernels.Pinned | None = None) -> BoxLaw:
    """The box-filtered law of ``pieces`` with window ``width`` (L,) per piece, s; ``tables``:
    their :func:`star_tables`, when several windows are tried on the same pieces."""
    durations = np.array([p.t_star for _, p in pieces]) + width
    return BoxLaw(tuple(p for _, p in pieces), np.array([s for s, _ in pieces]), width,
                  np.concatenate([[0.0], np.cumsum(durations)]), tables)


__all__ = ['BoxLaw', 'StarPiece', 'build_box_law', 'star_pieces', 'star_tables']
