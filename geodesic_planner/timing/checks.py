"""Helpers of the laws' dense limit checks, shared by the smoothing and the jerk-limited laws:
samples around the peaks of a check, distinct sorted times, and the local slow-down cap.
"""
from __future__ import annotations

import numpy as np

from .tuning import LOCAL_MARGIN, LOCAL_POWER, PEAK_CHECKS, PEAK_SAMPLES

__all__ = ['distinct_times', 'local_cap', 'peak_samples']


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
    factor = np.ones(s_nodes.size)
    for a, b, f in zip(lo.tolist(), hi.tolist(), need[bad].tolist()):
        np.maximum(factor[a:b], f, out=factor[a:b])
    return np.minimum(out, x / factor**LOCAL_POWER * (1.0 - LOCAL_MARGIN))


def peak_samples(t: np.ndarray, need: np.ndarray, spacing: float, duration: float) -> np.ndarray:
    """More check times (sorted) around the PEAK_CHECKS highest local peaks of ``need`` at sorted
    times ``t``: PEAK_SAMPLES within ``spacing`` on either side of each, in [0, duration]."""
    peak = np.flatnonzero((need[1:-1] >= need[:-2]) & (need[1:-1] >= need[2:])) + 1
    if not peak.size:
        return np.zeros(0)
    peak = peak[np.argsort(need[peak])[-PEAK_CHECKS:]]
    offsets = np.linspace(-spacing, spacing, PEAK_SAMPLES + 2)[1:-1]
    return np.sort(np.clip((t[peak][:, None] + offsets).reshape(-1), 0.0, duration))


def distinct_times(t: np.ndarray) -> np.ndarray:
    """Times sorted, each once (from sorted runs: a cheap stable sort)."""
    t = t[np.argsort(t, kind='stable')]
    return t[np.concatenate([[True], t[1:] > t[:-1]])]
