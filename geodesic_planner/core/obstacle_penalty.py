"""The obstacle term of the path of least energy around obstacles (issue 39, section 2).

CHOMP's idea on the project's own collision model: at points ``s_g`` of the path, every checked
pair whose distance d is below ``active`` (the padding plus a margin) costs ``(active - d)^2``;
the sum over pairs and points, times a weight, is added to the action. Its gradient is analytic:
coal's witness points ``p1`` (on body 1) and ``p2`` (on body 2) and its normal ``n`` (from 1 to
2) give ``dd/dq = n . (dp2/dq - dp1/dq)``, where a point fixed on the segment moved by joints
``1 .. k`` moves with ``dp/dq_j = u_j x (p - o_j)`` (revolute joint j: axis u_j through o_j) or
``u_j`` (prismatic). Only pairs whose bounding spheres come within ``active`` are handed to coal
(the model's own bound), so a far obstacle costs nothing.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np

from .collision import CollisionModel, PairTable

__all__ = ['Contacts', 'ObstaclePenalty', 'contacts']


@dataclass
class Contacts:
    """Pairs nearer than a threshold at a batch of configurations.

    Attributes:
        n: configuration index (K,). pair: pair index (K,). d: coal's distance, m (K,).
        grad: dd/dq (K, dof).
    """

    n: np.ndarray
    pair: np.ndarray
    d: np.ndarray
    grad: np.ndarray


def contacts(model: CollisionModel, qs: np.ndarray, below: float, candidates: np.ndarray | None = None,
             seen: np.ndarray | None = None, fns: dict[int, Any] | None = None) -> Contacts:
    """Every checked pair whose distance is below ``below`` (m) at the configurations qs (N, dof),
    with the distance's gradient in q.

    ``candidates`` (N, pairs), bool: only these may be below (the others are known not to be);
    ``seen`` (N, pairs): set to a lower bound of every pair's distance (coal's distance where it
    was computed, the bounding spheres' elsewhere, or a box's); ``fns``: coal's distance functor per pair,
    kept between calls.
    """
    robot = model.robot
    qs = np.asarray(qs, dtype=float)
    table = model.pair_table
    ia, ib = table.first, table.second
    empty = Contacts(np.zeros(0, int), np.zeros(0, int), np.zeros(0), np.zeros((0, robot.dof)))
    if ia.size == 0 or not len(qs):
        return empty
    P, centers = model.body_frames(qs)
    bound = (np.linalg.norm(centers[:, ia] - centers[:, ib], axis=-1)
             - table.radius[ia] - table.radius[ib])
    _box_bounds(table, P, centers, bound)
    if seen is not None:
        seen[:] = bound
    near = bound < below
    if candidates is not None:
        near &= candidates
    ns, ps = np.nonzero(near)
    if ns.size == 0:
        return empty
    geometry, seg = table.geometry, table.segment
    request, result = coal.DistanceRequest(), coal.DistanceResult()
    fns = {} if fns is None else fns
    cache: dict[tuple[int, int], Any] = {}

    def tf(n: int, b: int) -> Any:  # noqa: ANN401
        T = cache.get((n, b))
        if T is None:
            T = cache[n, b] = coal.Transform3s(P[n, b, :3, :3], P[n, b, :3, 3])
        return T

    d = np.empty(ns.size)
    w1, w2, nv = np.empty((ns.size, 3)), np.empty((ns.size, 3)), np.empty((ns.size, 3))
    for k, (n, p) in enumerate(zip(ns.tolist(), ps.tolist())):
        i, j = int(ia[p]), int(ib[p])
        fn = fns.get(p)
        if fn is None:
            fn = fns[p] = coal.ComputeDistance(geometry[i], geometry[j])
        result.clear()
        d[k] = fn(tf(n, i), tf(n, j), request, result)
        w1[k], w2[k], nv[k] = result.getNearestPoint1(), result.getNearestPoint2(), result.normal
    if seen is not None:
        seen[ns, ps] = d
    keep = d < below
    ns, ps, d, w1, w2, nv = ns[keep], ps[keep], d[keep], w1[keep], w2[keep], nv[keep]
    Tj = robot.frames(qs)[0][ns]                       # (K, dof, 4, 4): joint frames before motion
    u, o = Tj[..., :3, 2], Tj[..., :3, 3]
    revolute = np.asarray(robot.revolute, dtype=bool)
    joints = np.arange(robot.dof)

    def moved(points: np.ndarray, segment: np.ndarray) -> np.ndarray:
        """n . dp/dq_j of points on their segments, (K, dof)."""
        rot = np.einsum('ki,kji->kj', nv, np.cross(u, points[:, None] - o))
        lin = np.einsum('ki,kji->kj', nv, u)
        g = np.where(revolute[None], rot, lin)
        return g * (joints[None] < segment[:, None])

    grad = moved(w2, seg[ib[ps]]) - moved(w1, seg[ia[ps]])
    return Contacts(ns, ps, d, grad)


def _box_bounds(table: PairTable, P: np.ndarray, centers: np.ndarray, bound: np.ndarray) -> None:
    """Raise ``bound`` (N, pairs) where one body of a pair is a box (a scene object, e.g. a table or
    a wall, whose bounding sphere is far larger than the box): the other body's bounding sphere
    against the box itself, ``|max(|R^T (c - t)| - h, 0)| - r``, is also a lower bound."""
    half = [np.asarray(g.halfSide, dtype=float) if isinstance(g, coal.Box) else None for g in table.geometry]
    is_box = np.array([h is not None for h in half])
    if not is_box.any():
        return
    sides = np.stack([np.zeros(3) if h is None else h for h in half])
    for box, other in ((table.first, table.second), (table.second, table.first)):
        sel = np.flatnonzero(is_box[box])
        if not sel.size:
            continue
        k, o = box[sel], other[sel]
        Pk = P[:, k]                                                          # (N, S, 4, 4)
        rel = centers[:, o] - Pk[..., :3, 3]                                  # base frame
        local = np.einsum('nsji,nsj->nsi', Pk[..., :3, :3], rel)              # in the box's frame
        out = np.linalg.norm(np.maximum(np.abs(local) - sides[k], 0.0), axis=-1) - table.radius[o]
        bound[:, sel] = np.maximum(bound[:, sel], out)


@dataclass
class ObstaclePenalty:
    """``weight * sum_g sum_pairs max(active - d, 0)^2 / G`` at the points ``line + basis @ C`` of a
    path (G points), as a function of the coefficients C (K, dof): the ``extra`` cost of
    :class:`~.least_energy.ActionProblem`.

    Between evaluations it remembers coal's distances and the points: a pair whose distance
    there was d cannot come nearer than ``d - R . |q_new - q_old|`` (R: the model's bound on how
    fast the pair's distance changes per unit of each joint), so it is skipped while that stays
    above ``active``.

    Attributes:
        worst: the smallest distance seen at the last evaluation (inf when no pair was active).
    """

    model: CollisionModel
    line: np.ndarray          # (G, dof)
    basis: np.ndarray         # (G, K)
    active: float
    weight: float
    worst: float = field(default=np.inf)
    _q: np.ndarray | None = field(default=None, repr=False)
    _d: np.ndarray | None = field(default=None, repr=False)
    _fns: dict[int, Any] = field(default_factory=dict, repr=False)

    def __call__(self, C: np.ndarray) -> tuple[float, np.ndarray]:
        q = self.line + self.basis @ C
        reach = self.model.pair_table.reach                      # (pairs, dof), m per rad (or m)
        if self._q is None or self._d is None:
            lower = np.full((len(q), reach.shape[0]), -np.inf)
        else:
            lower = self._d - np.abs(q - self._q) @ reach.T      # still a lower bound at q
        seen = np.empty_like(lower)
        found = contacts(self.model, q, self.active, lower <= self.active, seen, self._fns)
        self._q, self._d = q, np.maximum(seen, lower)
        self.worst = float(found.d.min()) if found.d.size else np.inf
        if not found.d.size:
            return 0.0, np.zeros_like(C)
        gap = self.active - found.d
        k = self.weight / len(q)
        dq = np.zeros_like(q)
        np.add.at(dq, found.n, (-2.0 * k * gap)[:, None] * found.grad)
        return float(k * np.sum(gap * gap)), self.basis.T @ dq
