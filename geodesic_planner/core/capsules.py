"""Exact distances between spheres and capsules, batched: the bodies of the presets' collision models.

A capsule is the set of points within ``radius`` of a segment: its frame's z axis from
``-half_length`` to ``+half_length``; a sphere is a capsule of half length 0. The signed distance
of two of them is the distance of their segments less both radii (negative: the depth of their
overlap), as coal's capsule and sphere distances give it (to about 1e-16 m,
``test/core/test_capsules.py``). Batched, it replaces one coal call (and its Python around it) per
pair and configuration by one call for all of them; :mod:`.compiled` has the same loop in C
(``gp_capsule_distances``), this numpy code is the reference and the fallback.

The segments' closest points: C. Ericson, *Real-Time Collision Detection* (2005), section 5.1.9.
"""
from __future__ import annotations

import numpy as np

from . import compiled

__all__ = ['EPS', 'capsule_distances', 'segment_distances']

#: Squared segment length (m^2) under which a segment is a point; the same in the C kernel.
EPS = 1e-24


def segment_distances(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> np.ndarray:
    """Distances between the segments [a0, a1] and [b0, b1], arrays (K, 3) each -> (K,), m."""
    d1, d2, r = a1 - a0, b1 - b0, a0 - b0
    a = np.einsum('ki,ki->k', d1, d1)
    e = np.einsum('ki,ki->k', d2, d2)
    f = np.einsum('ki,ki->k', d2, r)
    c = np.einsum('ki,ki->k', d1, r)
    b = np.einsum('ki,ki->k', d1, d2)
    point_a, point_b = a <= EPS, e <= EPS
    safe_a, safe_e = np.where(point_a, 1.0, a), np.where(point_b, 1.0, e)
    denom = a * e - b * b
    s = np.where(denom > 0.0, np.clip((b * f - c * e) / np.where(denom > 0.0, denom, 1.0), 0.0, 1.0), 0.0)
    s = np.where(point_b, np.clip(-c / safe_a, 0.0, 1.0), s)
    s = np.where(point_a, 0.0, s)
    t = np.where(point_b, 0.0, (b * s + f) / safe_e)
    clamped = np.clip(t, 0.0, 1.0)
    s = np.where((clamped != t) & ~point_a, np.clip((b * clamped - c) / safe_a, 0.0, 1.0), s)
    diff = (a0 + s[:, None] * d1) - (b0 + clamped[:, None] * d2)
    return np.sqrt(np.einsum('ki,ki->k', diff, diff))


def capsule_distances(P: np.ndarray, half: np.ndarray, radius: np.ndarray, n: np.ndarray,
                      ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
    """Signed distances between bodies ``ia[k]`` and ``ib[k]`` at configuration ``n[k]``, (K,), m.

    Args:
        P: body frames, (N, bodies, 4, 4), base frame; a capsule's axis is its frame's z axis.
        half: each body's half length (0: a sphere), (bodies,), m.
        radius: each body's radius, (bodies,), m.
        n, ia, ib: (K,) integer indices.
    """
    n, ia, ib = (np.asarray(x, dtype=np.int64).reshape(-1) for x in (n, ia, ib))
    if compiled.active():
        return compiled.capsule_distances(P, half, radius, n, ia, ib)
    Fa, Fb = P[n, ia], P[n, ib]
    ua = half[ia, None] * Fa[:, :3, 2]
    ub = half[ib, None] * Fb[:, :3, 2]
    ca, cb = Fa[:, :3, 3], Fb[:, :3, 3]
    return segment_distances(ca - ua, ca + ua, cb - ub, cb + ub) - radius[ia] - radius[ib]
