"""The smallest distance over a motion that the collision check found clear (``min_clearance``).

:meth:`~.collision.CollisionModel.check_motion` leaves the distances at the times it checked:
exact where they came near the padding, the bounding spheres' lower bounds elsewhere.
:func:`refine_min_clearance` turns them into the smallest distance over the whole motion, to
within a tolerance below it and never above: between two checked times a and b, pair p's distance
is at least ``(d(a) + d(b) - R_p (b - a)) / 2`` (R_p: the pair's largest relative speed).
Intervals whose bound is below the smallest exact distance found (U) less the tolerance are
bisected, their ends made exact for that pair, until none is; the result is the smallest bound
left.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .cancel import checkpoint

__all__ = ['refine_min_clearance']

#: (frames (N, bodies, 4, 4), configuration indices (K,), pair indices (K,)) -> exact distances (K,), m
Exact = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def refine_min_clearance(exact: Exact, frames: Callable[[np.ndarray], np.ndarray],
                         positions: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], R: np.ndarray,
                         t: np.ndarray, s: np.ndarray, D: np.ndarray, E: np.ndarray, P: np.ndarray, checks: int,
                         resolution: float, tolerance: float, max_checks: int
                         ) -> tuple[float, int, float, float, int]:
    """The smallest distance over the motion, to within max(``resolution``, ``tolerance`` of it)
    below, and where: (distance m, pair index, time s, path parameter s, configurations checked).

    Args:
        exact: exact distances of pairs at configurations of the given body frames.
        frames: joint positions (M, dof) -> body frames (M, bodies, 4, 4).
        positions: times (M,) s -> (joint positions (M, dof), path parameter (M,)).
        R: each pair's largest relative speed, (pairs,), m/s.
        t, s: the checked times (sorted) and their path parameter, (N,).
        D, E: distances (N, pairs), m, and where they are exact (the rest: lower bounds); updated.
        P: the body frames at the checked times, (N, bodies, 4, 4).
        checks: configurations evaluated so far (at most ``max_checks`` in all; past it the
            smallest bound left is the answer).
    """
    def below(u: float) -> float:        # bounds under this are refined
        return u - max(resolution, tolerance * u)

    while True:                 # best first: the smallest distance at the checked times, exact
        n, p = (int(i) for i in np.unravel_index(int(np.argmin(D)), D.shape))
        if E[n, p]:
            break
        D[n, p] = exact(P, np.array([n]), np.array([p]))[0]
        E[n, p] = True
    U, where = float(D[n, p]), (p, float(t[n]), float(s[n]))
    dt = np.diff(t)
    lb = 0.5 * (D[:-1] + D[1:] - R[None, :] * dt[:, None])       # (intervals, pairs)
    ia, pa = np.nonzero(lb < below(U))
    # the smallest bound set aside (a lower bound of the distance there)
    lowest = float(np.where(lb < below(U), np.inf, lb).min()) if lb.size else math.inf
    ends, pe = np.concatenate([ia, ia + 1]), np.concatenate([pa, pa])
    todo = np.unique((ends * D.shape[1] + pe)[~E[ends, pe]])    # each (time, pair) once
    tn, tp = np.divmod(todo, D.shape[1])
    D[tn, tp] = exact(P, tn, tp)
    E[ends, pe] = True
    if ends.size and D[ends, pe].min() < U:
        k = int(np.argmin(D[ends, pe]))
        U, where = float(D[ends[k], pe[k]]), (int(pe[k]), float(t[ends[k]]), float(s[ends[k]]))
    ta, tb, Da, Db = t[ia], t[ia + 1], D[ia, pa], D[ia + 1, pa]
    while pa.size:
        checkpoint()
        bound = 0.5 * (Da + Db - R[pa] * (tb - ta))
        keep = bound < below(U)
        if (~keep).any():
            lowest = min(lowest, float(bound[~keep].min()))
        ta, tb, Da, Db, pa, bound = ta[keep], tb[keep], Da[keep], Db[keep], pa[keep], bound[keep]
        if not pa.size:
            break
        if checks + pa.size > max_checks:
            lowest = min(lowest, float(bound.min()))
            break
        tm = 0.5 * (ta + tb)
        tu, at = np.unique(tm, return_inverse=True)    # one configuration per time
        qm, sm = positions(tu)
        dm = exact(frames(qm), at, pa)
        sm = np.asarray(sm)[at]
        checks += tu.size
        k = int(np.argmin(dm))
        if dm[k] < U:
            U, where = float(dm[k]), (int(pa[k]), float(tm[k]), float(sm[k]))
        ta, tb = np.concatenate([ta, tm]), np.concatenate([tm, tb])
        Da, Db = np.concatenate([Da, dm]), np.concatenate([dm, Db])
        pa = np.concatenate([pa, pa])
    p_min, t_min, s_min = where
    return min(U, lowest), p_min, t_min, s_min, checks
