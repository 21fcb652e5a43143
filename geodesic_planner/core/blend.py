"""Via points without stopping: blend zones around the corners of a piecewise geodesic.

A piecewise geodesic (:mod:`.piecewise`) has a corner at each via point: q′ changes direction
there, so a timed motion must rest. A blend replaces the corner by a smooth passage:

* The zone of via point k is the last metric length ℓ_k of the incoming geodesic and the first
  ℓ_k of the outgoing one. ℓ_k is the largest length for which both cut points are within the
  blend radius r of the via point's tool position (bracketed on the exact line), at most
  half of either neighbouring piece (zones never overlap).
* Inside the zone both motions run at their natural rates over the same interval,
  τ = (σ − σ_a)/ℓ_k ∈ [0, 1] of metric arc length σ, and are mixed in joint space:
  ``q = q_in(τ) + w(τ) (q_out(τ) − q_in(τ))`` with the septic smoothstep ``w`` (w′, w″, w‴ vanish
  at both ends). So q, q′, q″ and q‴ are continuous at the zone's ends; the zone is ℓ_k shorter
  than the corner it replaces (the motion cuts the corner rather than slowing into it).
* Away from the zones the path is the pieces themselves: the exact geodesic (tool on the line,
  orientation by slerp).

To first order in the zone's size the tool position is the same convex mix of two points on the
two segments, each within r of the via point, so inside the ball of radius r around it; the
orientation is the same mix of two rotations towards the via orientation. The size is then
checked exactly on a dense grid (forward kinematics), and the zone shrunk until every sample is
within r. :class:`BlendZone` reports, per via point, what the blend did to the tool.
s is the path parameter in [0, 1]; lengths are metric lengths (the paper's metric).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .errors import RequestError
from .geodesic import GeodesicPath
from .path import JointPath, by_segment, check_order, check_s
from .piecewise import PiecewiseGeodesicPath
from .transforms import pose_error, segment_distance

#: Samples of a zone checked against the blend radius (forward kinematics).
CHECK_SAMPLES = 201
#: Factor a zone's length shrinks by when a sample leaves the ball of radius r.
SHRINK = 0.7
#: Most shrink steps before a via point is passed without a blend (a stop).
MAX_SHRINKS = 40
#: Sub-intervals of each zone given to the time laws as breakpoints (sampling resolution).
ZONE_NODES = 4
#: The cut point at distance r on the exact line: CUT_ROUNDS brackets of CUT_POINTS values of u
#: (resolution (CUT_POINTS - 1) ** -CUT_ROUNDS of the piece, about 1e-9).
CUT_POINTS = 33
CUT_ROUNDS = 6


@dataclass(frozen=True)
class BlendZone:
    """What the blend around one via point did to the tool (base frame).

    Attributes:
        via: index of the via point in the poses given to ``plan_through`` (1 .. N-1).
        s_start, s_end: the zone on the blended path's parameter s.
        radius: the requested blend radius, m.
        entry_distance: tool distance from the via point at the zone's ends (the larger), m.
        max_distance: largest tool distance from the via point inside the zone, m (≤ radius).
        deviation: largest distance of the tool from the stopping path (the two segments that
            meet at the via point) inside the zone, m: how much of the corner is cut.
        max_angle: largest rotation of the tool from the via orientation inside the zone, rad.
        entry_angle: rotation from the via orientation at the zone's ends (the larger), rad.
    """

    via: int
    s_start: float
    s_end: float
    radius: float
    entry_distance: float
    max_distance: float
    deviation: float
    max_angle: float
    entry_angle: float


def smoothstep(tau: np.ndarray) -> tuple[np.ndarray, ...]:
    """Septic smoothstep w(τ) = 35τ⁴ − 84τ⁵ + 70τ⁶ − 20τ⁷ and its first three derivatives.

    w(0) = 0, w(1) = 1, and w′, w″, w‴ vanish at both ends.
    """
    t = np.asarray(tau, dtype=float)
    t2, t3 = t * t, t * t * t
    w = t2 * t2 * (35.0 - 84.0 * t + 70.0 * t2 - 20.0 * t3)
    w1 = 140.0 * t3 * (1.0 - t) ** 3
    w2 = 420.0 * t2 * (1.0 - t) ** 2 * (1.0 - 2.0 * t)
    w3 = 840.0 * t * (1.0 - t) * (1.0 - 5.0 * t + 5.0 * t2)
    return w, w1, w2, w3


def check_radii(blend_radius: float | Sequence[float] | np.ndarray, vias: int) -> np.ndarray:
    """Per-via-point blend radii (m) from a scalar or one value per via point.

    Raises:
        RequestError: wrong count, negative, NaN or infinite.
    """
    try:
        r = np.asarray(blend_radius, dtype=float)
    except (TypeError, ValueError) as err:
        raise RequestError(f'blend_radius: expected metres, got {blend_radius!r}') from err
    if r.ndim == 0:
        r = np.full(vias, float(r))
    if r.shape != (vias,):
        raise RequestError(f'blend_radius: expected one value or one per via point ({vias}), '
                           f'got shape {r.shape}')
    if not np.all(np.isfinite(r)) or np.any(r < 0):
        raise RequestError(f'blend_radius: must be finite and >= 0 m, got {r.tolist()}')
    return r


class _Piece:
    """One exact portion: piece ``i`` on u ∈ [u0, u1], or a blend (incoming, outgoing, ℓ)."""

    def __init__(self, kind: str, i: int, u0: float, u1: float, length: float) -> None:
        self.kind, self.i, self.u0, self.u1, self.length = kind, i, u0, u1, length


class BlendedPath(JointPath):
    """A piecewise geodesic whose corners are replaced by blend zones (see module docstring).

    Attributes:
        stopping_path: the piecewise geodesic the blends were cut from (rests at via points).
        zones: BlendZone per blended via point, in order.
        breakpoints: s of every zone's ends (and ZONE_NODES - 1 points inside each), with 0 and 1.
        length: metric length of the blended path (shorter than the stopping path's).
        solver: the stopping path's aggregate SolverReport.
    """

    def __init__(self, path: PiecewiseGeodesicPath, blend_radius: float | Sequence[float] | np.ndarray,
                 via_index: Sequence[int] | None = None) -> None:
        self.stopping_path = path
        self.robot = path.robot
        self.metric = path.metric
        self.solver = path.solver
        pieces: list[GeodesicPath] = path.pieces
        n = len(pieces)
        radii = check_radii(blend_radius, n - 1)
        self._via_index = list(range(1, n)) if via_index is None else list(via_index)
        lengths = np.array([p.length for p in pieces])
        self._lengths = lengths
        ends = self.robot.fk(path.via_joints)          # tool at every junction, (n + 1, 4, 4)
        self._ends = ends
        half = np.zeros(n - 1)
        for k in range(1, n):
            checkpoint()
            if radii[k - 1] > 0.0:
                half[k - 1] = self._zone_length(k, radii[k - 1])
        self._build(half)
        for k in range(1, n):
            if half[k - 1] <= 0.0:      # no blend asked: a stop at this via point
                continue
            for _ in range(MAX_SHRINKS):
                if self._report(k, radii[k - 1]).max_distance <= radii[k - 1] * (1.0 + 1e-9):
                    break
                half[k - 1] *= SHRINK
                self._build(half)
            else:       # never within r: stop at this via point
                half[k - 1] = 0.0
                self._build(half)
        zones = [self._report(k, radii[k - 1]) for k in range(1, n) if half[k - 1] > 0.0]
        self.zones: list[BlendZone] = zones

    # ------------------------------------------------------------------ construction
    def _tool_distance(self, i: int, u: np.ndarray, target: np.ndarray) -> np.ndarray:
        """Tool distance (m) from ``target`` at u on piece i."""
        q = self.stopping_path.pieces[i].evaluate(np.clip(u, 0.0, 1.0), 0)[0]
        return np.linalg.norm(self.robot.fk(q)[:, :3, 3] - target, axis=1)

    def _cut(self, i: int, radius: float, at_end: bool) -> float:
        """Metric length from the via point to the point of piece i at tool distance ``radius``.

        ``at_end``: the via point is piece i's end (u = 1), else its start (u = 0). The tool moves
        monotonically along the exact segment, so the crossing is bracketed on CUT_POINTS values
        of u, CUT_ROUNDS times; the result is on the inner side (distance <= radius).
        """
        via_u = 1.0 if at_end else 0.0
        target = self._ends[i + 1 if at_end else i][:3, 3]
        outside, inside = 1.0 - via_u, via_u
        if self._tool_distance(i, np.array([outside]), target)[0] <= radius:
            return float(self._lengths[i])
        for _ in range(CUT_ROUNDS):
            checkpoint()
            u = np.linspace(outside, inside, CUT_POINTS)
            within = self._tool_distance(i, u, target) <= radius
            k = int(np.argmax(within))         # first value of u (from outside) within r
            if k == 0:                         # round-off: the bracket's outer end is within r
                break
            outside, inside = float(u[k - 1]), float(u[k])
        return float(abs(via_u - inside) * self._lengths[i])

    def _zone_length(self, k: int, radius: float) -> float:
        """ℓ_k for via point k (between pieces k-1 and k) and radius r, before the exact check."""
        ell_in = self._cut(k - 1, radius, at_end=True)
        ell_out = self._cut(k, radius, at_end=False)
        return float(min(ell_in, ell_out, 0.5 * self._lengths[k - 1], 0.5 * self._lengths[k]))

    def _build(self, half: np.ndarray) -> None:
        """Lay out exact portions and blends for zone lengths ``half`` (0: no blend, a corner)."""
        n = len(self._lengths)
        segs: list[_Piece] = []
        for i in range(n):
            u0 = half[i - 1] / self._lengths[i] if i > 0 else 0.0
            u1 = 1.0 - (half[i] / self._lengths[i] if i < n - 1 else 0.0)
            if u1 > u0:
                segs.append(_Piece('piece', i, u0, u1, (u1 - u0) * self._lengths[i]))
            if i < n - 1 and half[i] > 0.0:
                segs.append(_Piece('blend', i + 1, 0.0, 1.0, half[i]))
        self._segs = segs
        total = sum(g.length for g in segs)
        self.length = float(total)
        edges = np.concatenate([[0.0], np.cumsum([g.length for g in segs])]) / total
        edges[-1] = 1.0
        self._edges = edges
        # Breakpoints: every zone's ends, and ZONE_NODES - 1 points inside each zone, so that
        # the time laws sample a short zone as finely as a whole piece (timing.sampling).
        inner = [edges[j] + (edges[j + 1] - edges[j]) * np.arange(1, ZONE_NODES) / ZONE_NODES
                 for j, g in enumerate(segs) if g.kind == 'blend']
        self.breakpoints = np.union1d(edges, np.concatenate(inner)) if inner else edges.copy()

    def _report(self, k: int, radius: float) -> BlendZone:
        """Measure the tool inside the zone of via point k on a dense grid."""
        j = next(m for m, g in enumerate(self._segs) if g.kind == 'blend' and g.i == k)
        s = np.linspace(self._edges[j], self._edges[j + 1], CHECK_SAMPLES)
        T = self.robot.fk(self.evaluate(s, 0)[0])
        via = self._ends[k]
        dist, ang = pose_error(T, via[None])
        p = T[:, :3, 3]
        dev = np.minimum(segment_distance(p, self._ends[k - 1][:3, 3], via[:3, 3]),
                         segment_distance(p, via[:3, 3], self._ends[k + 1][:3, 3]))
        return BlendZone(self._via_index[k - 1], float(s[0]), float(s[-1]), float(radius),
                         float(max(dist[0], dist[-1])), float(dist.max()), float(dev.max()),
                         float(ang.max()), float(max(ang[0], ang[-1])))

    # ------------------------------------------------------------------ JointPath
    @property
    def q_start(self) -> np.ndarray:
        """Joint positions at s = 0."""
        return self.stopping_path.q_start

    @property
    def q_goal(self) -> np.ndarray:
        """Joint positions at s = 1."""
        return self.stopping_path.q_goal

    def _natural(self, i: int, u: np.ndarray, order: int, interpolated: bool = False) -> list[np.ndarray]:
        """Piece i at u with derivatives w.r.t. the blended path's s (natural rate); from the
        piece's interpolant (order 3) when ``interpolated``."""
        scale = self.length / self._lengths[i]
        piece = self.stopping_path.pieces[i]
        u = np.clip(u, 0.0, 1.0)
        values = piece.interpolate(u) if interpolated else piece.evaluate(u, order)
        return [arr * scale**m for m, arr in enumerate(values)]

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q and its first three derivatives w.r.t. s at s (1-D in [0, 1]); each (len(s), dof).

        ``order`` < 3 returns only the first ``order + 1`` arrays.
        """
        return self._blend(check_s(s), check_order(order), interpolated=False)

    def interpolate(self, s: np.ndarray) -> tuple[np.ndarray, ...]:
        """:meth:`evaluate` through the pieces' interpolants (see :meth:`JointPath.interpolate`)."""
        return self._blend(check_s(s), 3, interpolated=True)

    def _blend(self, s: np.ndarray, order: int, interpolated: bool) -> tuple[np.ndarray, ...]:
        out = [np.empty((s.size, self.dof)) for _ in range(order + 1)]
        for j, sel, x in by_segment(self._edges, s):
            g = self._segs[j]
            if g.kind == 'piece':
                vals = self._natural(g.i, g.u0 + x * (g.u1 - g.u0), order, interpolated)
            else:
                k, ell = g.i, g.length
                q_in = self._natural(k - 1, 1.0 - (1.0 - x) * ell / self._lengths[k - 1], order, interpolated)
                q_out = self._natural(k, x * ell / self._lengths[k], order, interpolated)
                rate = self.length / ell                      # dτ/ds
                w = [d * rate**m for m, d in enumerate(smoothstep(x))]
                diff = [b - a for a, b in zip(q_in, q_out)]
                binom = ((1,), (1, 1), (1, 2, 1), (1, 3, 3, 1))
                vals = [q_in[m] + sum(c * w[jj][:, None] * diff[m - jj]
                                      for jj, c in enumerate(binom[m])) for m in range(order + 1)]
            for m in range(order + 1):
                out[m][sel] = vals[m]
        return tuple(out)

    def line_deviation(self, samples: int = 101) -> float:
        """Largest distance (m) of the tool from its piece's straight segment, outside the blend
        zones (inside them see ``zones``), on ``samples`` values of u per exact portion."""
        worst = 0.0
        for g in self._segs:
            if g.kind != 'piece':
                continue
            u = np.linspace(g.u0, g.u1, int(samples))
            worst = max(worst, float(self.stopping_path.pieces[g.i].deviation(u).max()))
        return worst

    def exact_intervals(self) -> list[tuple[float, float]]:
        """The intervals of s outside every blend zone, where the path is the exact geodesic."""
        return [(float(self._edges[j]), float(self._edges[j + 1]))
                for j, g in enumerate(self._segs) if g.kind == 'piece']
