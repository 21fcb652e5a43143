"""``min_clearance``: the smallest distance over a path that the collision check found clear.

:meth:`~.collision.CollisionModel.check_path` checks the geometric path q(s), s in [0, 1] (never
the samples of a time law: two time laws on one path get the same answer, bit for bit) and
leaves the distances at the s it checked: exact where they came near the padding, the bounding
spheres' lower bounds elsewhere. :func:`refine_min_clearance` turns them into the smallest
distance over the whole path, to within ``resolution`` (1 mm) below it and never above: between
two checked values a and b, pair p's distance is at least ``(d(a) + d(b) - R_p (b - a)) / 2``
(R_p: a bound on how fast the pair's distance changes with s, from :func:`path_speed`).
Intervals whose bound is more than ``resolution`` below the smallest exact distance found (U) are
bisected, their ends made exact for that pair, until none is; the result is the smallest bound
left, so the true minimum lies between it and U.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from .cancel import checkpoint

__all__ = ['PATH_SPEED_GRID', 'Refined', 'path_speed', 'refine_min_clearance', 'time_at']

#: (frames (N, bodies, 4, 4), configuration indices (K,), pair indices (K,)) -> exact distances (K,), m
Exact = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
#: Intervals of the grid of s on which :func:`path_speed` bounds |dq/ds|.
PATH_SPEED_GRID = 256
#: Brackets per step of :func:`time_at`, and its resolution relative to the duration (at least 1 s).
TIME_SPLIT = 64
TIME_RESOLUTION = 1e-12


class Refined(NamedTuple):
    """What :func:`refine_min_clearance` found."""

    #: a lower bound of the smallest distance over the motion, m
    lower: float
    #: the smallest exact distance found, m (>= the true minimum; ``closest - lower`` <= the
    #: resolution unless the budget of configurations ran out)
    closest: float
    #: the pair index, the time (s) and the path parameter where ``closest`` is reached
    pair: int
    time: float
    fraction: float
    #: configurations evaluated in all
    checks: int


def path_speed(path: Any, intervals: int = PATH_SPEED_GRID) -> np.ndarray:  # noqa: ANN401
    """A bound on |dq/ds| over s in [0, 1], per joint, (dof,): rad or m per unit of s.

    On a grid of ``intervals`` uniform intervals, with the path's own mesh nodes and the midpoints
    between them added (``path.s_nodes``, where it has them: a solver puts its nodes densely where
    the path changes fast, e.g. out of a singular start), the largest over the grid's intervals
    of the larger end's |dq/ds| plus the interval's length times the larger end's |d²q/ds²|:
    within an interval |dq/ds| exceeds its value at the nearer end by at most h / 2 times the
    largest |d²q/ds²| in it; twice that absorbs the change of d²q/ds² within the interval. (A
    single global h times the largest |d²q/ds²| would take a steep start's d²q/ds² over the
    whole path.)

    Args:
        path: has ``evaluate(s, order)`` -> (q, dq/ds, d²q/ds², ...), each (len(s), dof).
        intervals: intervals of the uniform grid.
    """
    s = np.linspace(0.0, 1.0, int(intervals) + 1)
    nodes = getattr(path, 's_nodes', None)
    if nodes is not None and len(nodes) > 1:
        nodes = np.asarray(nodes, dtype=float)
        s = np.unique(np.concatenate([s, nodes, 0.5 * (nodes[:-1] + nodes[1:])]).clip(0.0, 1.0))
    _, d1, d2 = path.evaluate(s, order=2)[:3]
    d1, d2 = np.abs(np.asarray(d1)), np.abs(np.asarray(d2))
    h = np.diff(s)[:, None]
    bound = np.maximum(d1[:-1], d1[1:]) + h * np.maximum(d2[:-1], d2[1:])
    return bound.max(axis=0) if bound.size else d1.max(axis=0)


def time_at(s_of_t: Callable[[np.ndarray], np.ndarray], duration: float, s: np.ndarray) -> np.ndarray:
    """Times (M,) s at which a time law's nondecreasing s(t) reaches the path parameters ``s``
    (M,): the first such time, within :data:`TIME_RESOLUTION` of the duration (0 for s <= s(0),
    ``duration`` past s(duration)). A search with :data:`TIME_SPLIT` times per bracket and step,
    all brackets in one call of ``s_of_t`` (7 calls)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    lo, hi = np.zeros_like(s), np.full_like(s, float(duration))
    u = np.linspace(0.0, 1.0, TIME_SPLIT + 1)[1:-1]
    for _ in range(16):
        grid = lo[:, None] + (hi - lo)[:, None] * u[None, :]                  # (M, TIME_SPLIT - 1)
        before = (np.asarray(s_of_t(grid.ravel())).reshape(grid.shape) < s[:, None])
        k = before.sum(axis=1)                                                # s(t) nondecreasing
        lo, hi = (np.where(k > 0, grid[np.arange(s.size), np.maximum(k - 1, 0)], lo),
                  np.where(k < u.size, grid[np.arange(s.size), np.minimum(k, u.size - 1)], hi))
        if np.all(hi - lo <= TIME_RESOLUTION * max(float(duration), 1.0)):
            break
    return np.where(np.asarray(s_of_t(lo)) >= s, lo, hi)


def refine_min_clearance(exact: Exact, frames: Callable[[np.ndarray], np.ndarray],
                         positions: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], R: np.ndarray,
                         t: np.ndarray, s: np.ndarray, D: np.ndarray, E: np.ndarray, P: np.ndarray, checks: int,
                         resolution: float, max_checks: int) -> Refined:
    """The smallest distance over the motion, to within ``resolution`` below it (never above),
    and where its closest exact distance is.

    Args:
        exact: exact distances of pairs at configurations of the given body frames.
        frames: joint positions (M, dof) -> body frames (M, bodies, 4, 4).
        positions: the motion's parameter (M,) -> (joint positions (M, dof), path parameter (M,)).
        R: a bound on how fast each pair's distance changes with the parameter, (pairs,), m per unit.
        t, s: the checked values of the parameter (sorted) and their path parameter, (N,).
        D, E: distances (N, pairs), m, and where they are exact (the rest: lower bounds); updated.
        P: the body frames at the checked values, (N, bodies, 4, 4).
        checks: configurations evaluated so far (at most ``max_checks`` in all; past it the
            smallest bound left is the answer, more than ``resolution`` below the closest
            distance found).
        resolution: m.
        max_checks: the budget of configurations.
    """
    def below(u: float) -> float:        # bounds under this are refined
        return u - resolution

    while True:                 # best first: the smallest distance at the checked values, exact
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
    todo = np.unique((ends * D.shape[1] + pe)[~E[ends, pe]])    # each (value, pair) once
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
        tm = 0.5 * (ta + tb)
        tu, at = np.unique(tm, return_inverse=True)    # one configuration per value
        if checks + tu.size > max_checks:
            lowest = min(lowest, float(bound.min()))
            break
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
    return Refined(min(U, lowest), U, p_min, t_min, s_min, checks)
