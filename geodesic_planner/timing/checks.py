"""Helpers of the laws' dense limit checks, shared by the smoothing and the jerk-limited laws:
samples around the peaks of a check, distinct sorted times, and the local slow-down cap.
"""
from __future__ import annotations

import numpy as np

from . import kernels
from .tuning import LOCAL_MARGIN, LOCAL_POWER, PEAK_CHECKS, PEAK_SAMPLES, S_UNIFORM_CHECKS

__all__ = ['UNIFORM_S', 'UNIFORM_S_PINNED', 'distinct_times', 'local_cap', 'peak_samples', 'range_max']

#: Path parameters of the check samples spread uniformly in s (each law maps them to times).
UNIFORM_S = np.linspace(0.0, 1.0, S_UNIFORM_CHECKS)
UNIFORM_S.flags.writeable = False
#: :data:`UNIFORM_S` for the compiled checks (its address taken once).
UNIFORM_S_PINNED = kernels.Pinned(UNIFORM_S)


def local_cap(s_nodes: np.ndarray, x: np.ndarray, law: object, t: np.ndarray, need: np.ndarray,
              window: float, cap: np.ndarray | None) -> np.ndarray:
    """A cap on x = sdot^2 (per node of ``s_nodes``) that slows the optimal profile ``x`` where
    a filtered law exceeded a limit: over the path the law crosses within ``window`` (s of time)
    of each sample with ``need`` > 1 + LOCAL_MARGIN (its speed factor over the limits), x is
    divided by that factor (``LOCAL_POWER``), LOCAL_MARGIN below; ``cap``: the previous cap.

    ``law.evaluate(t)`` must return s first (the smoothed and the box-filtered laws do).
    """
    out = np.full(s_nodes.size, np.inf) if cap is None else np.array(cap, dtype=float)
    bad = np.flatnonzero(need > 1.0 + LOCAL_MARGIN)
    if bad.size == 0:
        return out
    tb = t[bad]
    s_lo = law.evaluate(tb - window, jerk=False)[0]        # type: ignore[attr-defined]
    s_hi = law.evaluate(tb + window, jerk=False)[0]        # type: ignore[attr-defined]
    lo = np.searchsorted(s_nodes, s_lo, side='left')
    hi = np.searchsorted(s_nodes, s_hi, side='right')
    factor = np.maximum(range_max(s_nodes.size, lo, hi, need[bad]), 1.0)
    return np.minimum(out, x / factor**LOCAL_POWER * (1.0 - LOCAL_MARGIN))


def range_max(n: int, lo: np.ndarray, hi: np.ndarray, value: np.ndarray) -> np.ndarray:
    """Per index i < n, the largest ``value[k]`` with ``lo[k] <= i < hi[k]`` (-inf where none).

    Each interval is covered by two blocks of length 2^p (p = floor(log2(hi - lo))), one from
    each end (overlapping is harmless for a maximum); the blocks' maxima are pushed down one
    level at a time: O((n + K) log n) in numpy, no loop over the K intervals.
    """
    lo, hi, value = (np.asarray(v) for v in (lo, hi, value))
    keep = hi > lo
    lo, hi, value = lo[keep].astype(np.intp), hi[keep].astype(np.intp), value[keep].astype(float)
    out = np.full(n, -np.inf)
    if not lo.size:
        return out
    p = np.floor(np.log2(hi - lo)).astype(np.intp)
    levels = int(p.max()) + 1
    block = np.full((levels, n), -np.inf)      # block[j, i]: max over intervals covering [i, i + 2^j)
    np.maximum.at(block, (p, lo), value)
    np.maximum.at(block, (p, hi - (1 << p)), value)
    for j in range(levels - 1, 0, -1):
        half = 1 << (j - 1)
        np.maximum(block[j - 1], block[j], out=block[j - 1])
        np.maximum(block[j - 1, half:], block[j, :n - half], out=block[j - 1, half:])
    return block[0]


def peak_samples(t: np.ndarray, need: np.ndarray, spacing: float, duration: float) -> np.ndarray:
    """More check times (sorted) around the PEAK_CHECKS highest local peaks of ``need`` at sorted
    times ``t``: PEAK_SAMPLES within ``spacing`` on either side of each, in [0, duration]. Equal
    peaks at the cut: the later ones (a stable order, the same on every machine and compiled)."""
    if kernels.active():
        return kernels.peak_samples(t, need, spacing, duration, PEAK_CHECKS, PEAK_SAMPLES)
    peak = np.flatnonzero((need[1:-1] >= need[:-2]) & (need[1:-1] >= need[2:])) + 1
    if not peak.size:
        return np.zeros(0)
    peak = peak[np.argsort(need[peak], kind='stable')[-PEAK_CHECKS:]]
    offsets = np.linspace(-spacing, spacing, PEAK_SAMPLES + 2)[1:-1]
    return np.sort(np.clip((t[peak][:, None] + offsets).reshape(-1), 0.0, duration))


def distinct_times(t: np.ndarray) -> np.ndarray:
    """Times sorted, each once (from sorted runs: a cheap stable sort)."""
    t = t[np.argsort(t, kind='stable')]
    return t[np.concatenate([[True], t[1:] > t[:-1]])]
