"""Compiled kernels of the time laws' hot loops (in ``core/_kernels_timing.c``, loaded by
:mod:`geodesic_planner.core.compiled`), with the numpy code as the fallback.

They do sample by sample what the numpy code of :mod:`.smoothing`, :mod:`.box_filter`,
:mod:`.sampling` and :mod:`.topp` does on whole arrays: evaluating a law, interpolating the path's
derivatives and taking the ratios to the limits, the TOPP rows and passes. The callers ask
:func:`active` and otherwise run their numpy code, which stays the reference
(``test/timing/test_kernels.py`` compares the two, and runs the laws with each). Off without the
extension, with ``GP_KERNELS=numpy`` or inside :func:`numpy_only` (:data:`REASON` says why).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.compiled import LIB as _LIB
from ..core.compiled import REASON, Pinned, active, numpy_only, scratch
from ..core.compiled import f64 as _f64

__all__ = ['REASON', 'LawTables', 'Pinned', 'active', 'backward_pass', 'box_search', 'box_search_max', 'box_tables',
           'build_piecewise', 'evaluate', 'forward_pass', 'hermite_coef', 'hermite_ratios', 'limit_tables',
           'merge_columns', 'numpy_only', 'path_tables', 'peak_samples', 'piecewise_check', 'piecewise_tables',
           'point_ratios', 'ratios', 'refine', 'suspects']


@dataclass(frozen=True, eq=False)
class LawTables:
    """A law's tables for its kernel: the C function and its arguments after (m, t)."""

    fn: Any
    const: tuple[Any, ...]
    keep: Pinned | tuple[Pinned, ...]


def build_piecewise(s: np.ndarray, x: np.ndarray, rests: np.ndarray, smoothing: float, valley_depth: float
                    ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`.smoothing.build_piecewise_law` compiled, on nodes s (n + 1,) with the optimal profile x
    (n + 1,) and its rests (L + 1,): t_offsets (L + 1,), pieces (6, L), key_step, seg_key (S,),
    seg (6, S), node_s and node_t (K + L,), with K steps and S = K + 2 L segments."""
    assert _LIB is not None
    s, x = _f64(s), _f64(x)
    rests = np.ascontiguousarray(rests, dtype=np.int64)
    L = rests.size - 1
    K = int(rests[-1] - rests[0])
    S, M = K + 2 * L, K + L
    sizes = (6 * L, L + 1, 6 * S, S, M, M, 1)
    block = np.empty(sum(sizes))
    base = block.ctypes.data
    ptrs, parts, at = [], [], 0
    for size in sizes:
        ptrs.append(base + 8 * at)
        parts.append(block[at:at + size])
        at += size
    _LIB.gp_build_piecewise(s.ctypes.data, x.ctypes.data, L, rests.ctypes.data, float(smoothing), float(valley_depth),
                            *ptrs)
    pieces, offs, seg, seg_key, node_s, node_t, key_step = parts
    return offs, pieces.reshape(6, L), float(key_step[0]), seg_key, seg.reshape(6, S), node_s, node_t


def refine(rows: Pinned, coef: Pinned, factor: int) -> tuple[np.ndarray, ...]:
    """:meth:`.sampling.PathSamples.refined` compiled: ``rows`` its ``kernel_rows`` (s, aL, aR,
    bL, bR, stop), ``coef`` its ``kernel_tables`` (s, coef); s, aL, aR, bL, bR on the finer nodes."""
    assert _LIB is not None
    s, aL = rows.arrays[0], rows.arrays[1]
    assert s is not None and aL is not None
    n, dof = s.size - 1, aL.shape[1]
    m = n * factor + 1
    block = np.empty(m + 4 * m * dof)
    base = block.ctypes.data
    outs = (base + 8 * (m + i * m * dof) for i in range(4))
    _LIB.gp_refine(n, dof, factor, *rows.ptrs[:5], coef.ptrs[1], base, *outs)
    return (block[:m], *(block[m + i * m * dof:m + (i + 1) * m * dof].reshape(m, dof) for i in range(4)))


def suspects(h: np.ndarray, left: np.ndarray, right: np.ndarray, scale: np.ndarray, dof: int, tol: float
             ) -> np.ndarray:
    """:func:`.sampling._interpolation_suspects` compiled (same arguments, h (n,) or (n, 1)): (n,) bool."""
    assert _LIB is not None
    h, left, right, scale = (_f64(a) for a in (h, left, right, scale))
    n = h.size
    bad = np.empty(n, dtype=np.uint8)
    _LIB.gp_suspects(n, dof, h.ctypes.data, left.ctypes.data, right.ctypes.data, scale.ctypes.data, float(tol),
                     bad.ctypes.data)
    return bad.view(bool)


def hermite_coef(s: np.ndarray, aL: np.ndarray, aR: np.ndarray, bL: np.ndarray, bR: np.ndarray, cL: np.ndarray,
                 cR: np.ndarray) -> np.ndarray:
    """:attr:`.sampling.PathSamples.coef` compiled, from the samples' arrays: (8, dof, n)."""
    assert _LIB is not None
    arrays = [_f64(a) for a in (s, aL, aR, bL, bR, cL, cR)]
    n, dof = arrays[0].size - 1, arrays[1].shape[1]
    out = np.empty((8, dof, n))
    _LIB.gp_hermite_coef(n, dof, *(a.ctypes.data for a in arrays), out.ctypes.data)
    return out


def piecewise_tables(t_offsets: np.ndarray, pieces: np.ndarray, key_step: float, seg_key: np.ndarray,
                     seg: np.ndarray) -> LawTables:
    """Tables of :class:`.smoothing.PiecewiseLaw` (its attributes of the same names)."""
    assert _LIB is not None
    p = Pinned(t_offsets, pieces, seg_key, seg)
    o, pc, k, sg = p.ptrs
    return LawTables(_LIB.gp_piecewise_evaluate, (pieces.shape[1], o, pc, float(key_step), seg_key.size, k, sg), p)


def piecewise_check(law: LawTables, nodes: Pinned, path: Pinned, limits: Pinned, us: Pinned, m: int
                    ) -> np.ndarray:
    """The dense check of a smoothed law (``law``: its :func:`piecewise_tables`; ``nodes``: its
    node_s and node_t) in one call: its grid (m uniform times, the rests between pieces, the times
    at which it passes ``us`` (one array); sorted, each once), the law there and the ratios of
    :func:`ratios` without the jerk: rows t, s, sd, sdd, rv, ra, (6, M) (a view)."""
    assert _LIB is not None
    L = law.const[0]
    u, c, node_s = us.arrays[0], path.arrays[1], nodes.arrays[0]
    assert u is not None and c is not None and node_s is not None
    cap = m + u.size + L + 1
    out = np.empty((6, cap))
    work = scratch('grid', cap)
    M = _LIB.gp_piecewise_check(m, u.size, us.ptrs[0], node_s.size, *nodes.ptrs, *law.const, c.shape[2], path.ptrs[0],
                                c.shape[1], path.ptrs[1], limits.ptrs[0], limits.ptrs[1], work.ctypes.data,
                                out.ctypes.data)
    return out[:, :M]


def box_tables(t_offsets: np.ndarray, width: np.ndarray, stars: Pinned) -> LawTables:
    """Tables of :class:`.box_filter.BoxLaw`: its offsets and windows, and its pieces' s*
    (``stars``: :func:`.box_filter.star_tables`, shared by the laws of every window tried)."""
    assert _LIB is not None
    p = Pinned(t_offsets, width)
    return LawTables(_LIB.gp_box_evaluate, (width.size, *p.ptrs, *stars.ptrs), (p, stars))


def box_search(law: LawTables, path: Pinned, limits: Pinned, us: Pinned, m: int, max_inside: int,
               full: bool = False, reuse: bool = False) -> np.ndarray:
    """The dense check of a box-filtered law (``law``: its :func:`box_tables`) in one call: its grid
    (m uniform times, the times at which it passes ``us`` (one array), inside its jerk events' gaps
    three samples each (``full``) or the middles, at most ``max_inside``; sorted, each once), the
    law there and the ratios of :func:`ratios` with the jerk: rows t, s, sd, sdd, sddd, rv, ra, rj
    and a spare row, (9, M) (a view; with ``reuse`` of this thread's scratch buffer, valid until
    the next such call)."""
    assert _LIB is not None
    L, stars = law.const[0], law.keep[1]      # type: ignore[index]
    first, u = stars.arrays[1], us.arrays[0]
    c = path.arrays[1]
    assert first is not None and u is not None and c is not None
    K = int(first[-1])
    cap = m + u.size + (3 * (2 * K + 3 * L) if full else max_inside)
    work = scratch('grid', 6 * K + 5 * L + 3 + 2 * cap)
    out = scratch('grid out', 9 * cap).reshape(9, cap) if reuse else np.empty((9, cap))
    nodes, coef, coef3 = path.ptrs
    M = _LIB.gp_box_search_grid(m, u.size, us.ptrs[0], max_inside, int(full), *law.const, c.shape[2], nodes,
                                c.shape[1], coef, coef3, *limits.ptrs, work.ctypes.data, out.ctypes.data)
    return out[:, :M]


def point_ratios(a: np.ndarray, b: np.ndarray, c: np.ndarray, sd: np.ndarray, sdd: np.ndarray, sddd: np.ndarray,
                 limits: Pinned) -> tuple[float, float, float]:
    """The largest v, a, j ratios of exact derivatives a, b, c (K, dof) at sd, sdd, sddd (K,), as
    ``box_check.BoxCheck._max_ratios`` computes them (``limits``: the limits themselves, not reciprocals)."""
    assert _LIB is not None
    arrays = [_f64(v) for v in (a, b, c, sd, sdd, sddd)]
    out = np.empty(3)
    _LIB.gp_point_ratios(arrays[0].shape[0], arrays[0].shape[1], *(v.ctypes.data for v in arrays), *limits.ptrs,
                         out.ctypes.data)
    return float(out[0]), float(out[1]), float(out[2])


def peak_samples(t: np.ndarray, need: np.ndarray, spacing: float, duration: float, peaks: int, per: int
                 ) -> np.ndarray:
    """:func:`.checks.peak_samples` compiled (``peaks`` highest local peaks, ``per`` samples each)."""
    assert _LIB is not None
    t, need = _f64(t), _f64(need)
    out = np.empty(peaks * per)
    work = np.empty(2 * peaks)
    m = _LIB.gp_peak_samples(t.size, t.ctypes.data, need.ctypes.data, float(spacing), float(duration), peaks, per,
                             work.ctypes.data, out.ctypes.data)
    return out[:m]


def merge_columns(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The columns of a (R, na) and b (R, nb) (rows of contiguous doubles) merged by their first
    row, sorted in each: as ``np.argsort(np.concatenate([a[0], b[0]]), kind='stable')`` orders
    them; (R, na + nb)."""
    assert _LIB is not None and a.shape[0] == b.shape[0] and a.strides[1] == b.strides[1] == 8
    out = np.empty((a.shape[0], a.shape[1] + b.shape[1]))
    before = np.empty(b.shape[1] + 1, dtype=np.int64)
    _LIB.gp_merge_columns(a.shape[0], a.shape[1], a.strides[0] // 8, a.ctypes.data, b.shape[1], b.strides[0] // 8,
                          b.ctypes.data, out.ctypes.data, before.ctypes.data)
    return out


def box_search_max(stars: Pinned, width: np.ndarray, path: Pinned, limits: Pinned, us: Pinned, m: int,
                   max_inside: int, bound: tuple[float, float, float], origin: float = 0.0,
                   crossings: Pinned | None = None) -> tuple[float, float, float, float, float, bool]:
    """The largest ratios of :func:`box_search` for the box-filtered law of window ``width`` (L,) on
    the pieces ``stars`` (:func:`.box_filter.star_tables`), without building the law: rv, ra, rj,
    the law's duration, the fraction of it where the speed factor peaked, and whether the check
    stopped early, after a block of samples where one ratio exceeded its ``bound`` (the maxima then
    cover only the samples seen; the blocks are taken from the fraction ``origin`` of the duration on).
    ``crossings``: breakpoints the law crosses, checked when it did not stop: their s (K,), the
    one-sided q', q'', q''' there (2 K, dof each: left, then right) and vmax, amax, jmax."""
    assert _LIB is not None
    first, u = stars.arrays[1], us.arrays[0]
    c = path.arrays[1]
    assert first is not None and u is not None and c is not None
    L, cap = width.size, m + u.size + max_inside
    width = _f64(width)
    cross = crossings.arrays[0] if crossings is not None else None
    nc = 0 if cross is None else cross.size
    work = scratch('grid', L + 1 + 6 * int(first[-1]) + 5 * L + 3 + 4 * cap + 5 * nc)
    out = np.array(bound + (0.0, 0.0), dtype=float)      # the bounds in, the maxima and more out
    nodes, coef, coef3 = path.ptrs
    stopped = _LIB.gp_box_search_max(m, u.size, us.ptrs[0], max_inside, L, width.ctypes.data, *stars.ptrs,
                                     c.shape[2], nodes, c.shape[1], coef, coef3, *limits.ptrs, out.ctypes.data,
                                     float(origin), nc, *(crossings.ptrs if crossings is not None else (None,) * 7),
                                     work.ctypes.data, out.ctypes.data)
    return float(out[0]), float(out[1]), float(out[2]), float(out[3]), float(out[4]), bool(stopped)


def path_tables(nodes: np.ndarray, coef: np.ndarray, coef3: np.ndarray | None = None) -> Pinned:
    """Cubic-Hermite tables of :class:`.sampling.PathSamples`: its ``s``, ``coef`` and ``coef3``
    (for the jerk ratios only)."""
    return Pinned(nodes, coef, coef3)


def limit_tables(vmax: np.ndarray, amax: np.ndarray, jmax: np.ndarray | None = None) -> Pinned:
    """Per-joint limits (dof,) for :func:`ratios` and :func:`hermite_ratios`, as reciprocals
    (the kernels multiply; an infinite limit gives 0)."""
    with np.errstate(divide='ignore'):
        return Pinned(*(None if v is None else 1.0 / np.asarray(v, dtype=float) for v in (vmax, amax, jmax)))


def evaluate(law: LawTables, t: np.ndarray, jerk: bool
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The law at times t (M,): s, sdot, sddot and (if ``jerk``) sdddot, as its numpy ``evaluate``."""
    t = _f64(t)
    m = t.size
    out = np.empty((4 if jerk else 3, m))
    base, row = out.ctypes.data, 8 * m
    law.fn(m, t.ctypes.data, *law.const, base, base + row, base + 2 * row, base + 3 * row if jerk else None)
    return out[0], out[1], out[2], (out[3] if jerk else None)


def _hermite(path: Pinned, limits: Pinned, m: int, rows: list[int | None], jerk: bool) -> None:
    """gp_hermite_ratios on m samples: rows = addresses of s, sd, sdd, sddd (in), rv, ra, rj (out)."""
    assert _LIB is not None
    nodes, coef, coef3 = path.ptrs
    c = path.arrays[1]
    assert c is not None and (coef3 is not None or not jerk)
    vmax, amax, jmax = limits.ptrs
    assert jmax is not None or not jerk
    _LIB.gp_hermite_ratios(m, rows[0], rows[1], rows[2], rows[3] if jerk else None, c.shape[2], nodes,
                           c.shape[1], coef, coef3 if jerk else None, vmax, amax, jmax if jerk else None,
                           rows[4], rows[5], rows[6] if jerk else None)


def ratios(law: LawTables, path: Pinned, limits: Pinned, t: np.ndarray, jerk: bool) -> tuple[np.ndarray, ...]:
    """The law at times t (M,) and its ratios to the limits there, the path's derivatives cubic
    Hermite from ``path``: s, sd, sdd, rv, ra, or with ``jerk`` s, sd, sdd, sddd, rv, ra, rj, each
    (M,); rv, ra, rj: the largest |velocity|, |acceleration|, |jerk| over its limit of the joints."""
    t = _f64(t)
    m = t.size
    out = np.empty((7, m))
    base, row = out.ctypes.data, 8 * m
    p: list[int | None] = [base + i * row for i in range(7)]
    law.fn(m, t.ctypes.data, *law.const, p[0], p[1], p[2], p[3] if jerk else None)
    _hermite(path, limits, m, p, jerk)
    return tuple(out) if jerk else (out[0], out[1], out[2], out[4], out[5])


def hermite_ratios(path: Pinned, limits: Pinned, s: np.ndarray, sd: np.ndarray, sdd: np.ndarray,
                   sddd: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Per sample (s, sd, sdd[, sddd]) (M,), the ratios of :func:`ratios` (rj with ``sddd``)."""
    jerk = sddd is not None
    ins = [_f64(v) for v in ((s, sd, sdd, sddd) if sddd is not None else (s, sd, sdd))]
    m = ins[0].size
    out = np.empty((3, m))
    base, row = out.ctypes.data, 8 * m
    rows: list[int | None] = [v.ctypes.data for v in ins] + [None] * (4 - len(ins))
    _hermite(path, limits, m, rows + [base, base + row, base + 2 * row], jerk)
    return out[0], out[1], (out[2] if jerk else None)


def topp(rows: Pinned, vmax: np.ndarray, amax: np.ndarray, x_max: np.ndarray | None) -> np.ndarray:
    """The time-optimal x = sdot^2 (n + 1,) of :func:`.topp.topp` before its last node is zeroed:
    the constraint rows, then the backward and forward passes, all compiled. ``rows``: the
    samples' ``kernel_rows`` (nodes, aL, aR, bL, bR, stop)."""
    assert _LIB is not None
    s, aL = rows.arrays[0], rows.arrays[1]
    assert s is not None and aL is not None
    n, dof = s.size - 1, aL.shape[1]
    R = 2 * dof
    lim = Pinned(vmax, amax, x_max)
    block = scratch('topp', 4 * n * R + 2 * n + 2 * (n + 1))       # rows, passes: consumed here
    base = block.ctypes.data
    alpha, d, A, B = (base + 8 * i * n * R for i in range(4))
    static = base + 8 * 4 * n * R
    two_h = static + 8 * n
    hi = two_h + 8 * n
    x = hi + 8 * (n + 1)
    _LIB.gp_topp_rows(n, dof, *rows.ptrs[:5], *lim.ptrs, rows.ptrs[5], alpha, d, A, B, static, two_h)
    _LIB.gp_backward_pass(n, R, A, B, static, hi)
    _LIB.gp_forward_pass(n, R, alpha, d, two_h, hi, x)
    return block[4 * n * R + 2 * n + n + 1:].copy()


def backward_pass(A: np.ndarray, B: np.ndarray, static: np.ndarray) -> np.ndarray:
    """The backward pass of :func:`topp` alone (the exact recursion of :func:`.topp._backward_pass`),
    for checking it against a plain loop: hi (n + 1,)."""
    assert _LIB is not None
    A, B, static = _f64(A), _f64(B), _f64(static)
    n, R = A.shape
    hi = np.empty(n + 1)
    _LIB.gp_backward_pass(n, R, A.ctypes.data, B.ctypes.data, static.ctypes.data, hi.ctypes.data)
    return hi


def forward_pass(alpha: np.ndarray, d: np.ndarray, two_h: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The forward pass of :func:`topp` alone (the exact recursion of :func:`.topp._forward_pass`),
    for checking it against a plain loop: x (n + 1,)."""
    assert _LIB is not None
    alpha, d, two_h, hi = _f64(alpha), _f64(d), _f64(two_h), _f64(hi)
    n, R = alpha.shape
    x = np.empty(n + 1)
    _LIB.gp_forward_pass(n, R, alpha.ctypes.data, d.ctypes.data, two_h.ctypes.data, hi.ctypes.data,
                         x.ctypes.data)
    return x
