"""Piecewise geodesics through via points with the paper's trajectory scaling (eq. 10).

Each piece i is a geodesic on its own parameter u ∈ [0, 1] with constant metric speed L_i (its
length). Piece i gets the global interval of width Δs_i = L_i / Σ L, so that along the whole path
the metric speed is the same constant Σ L on both sides of every junction (the paper's velocity
continuity); ``q(s) = q_i((s − s_i)/Δs_i)`` and the k-th derivative divides by Δs_i^k.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from .geodesic import GeodesicPath, SolverReport
from .path import JointPath, by_segment, check_order, check_s


class PiecewiseGeodesicPath(JointPath):
    """Geodesic pieces joined at via points, scaled to equal metric speed.

    Attributes:
        pieces: the geodesic pieces, in order (pieces that do not move are dropped).
        kept: index of each kept piece among the pieces given (piece i runs from via point i).
        breakpoints: global s of the junctions, (len(pieces) + 1,), from 0 to 1.
        length: total metric length (= constant metric speed over s ∈ [0, 1]).
        solver: aggregate SolverReport (worst status/residual, summed iterations and time).
    """

    def __init__(self, pieces: Sequence[GeodesicPath], time_ms: float = 0.0) -> None:
        if not pieces:
            raise ValueError('a piecewise path needs at least one piece')
        lengths = np.array([p.length for p in pieces])
        keep = lengths > 1e-12 * max(lengths.max(), 1e-300)
        if not np.any(keep):
            keep[0] = True
        self.pieces = [p for p, k in zip(pieces, keep) if k]
        self.kept = np.flatnonzero(keep)   # indices of the kept pieces in the given sequence
        lengths = lengths[keep]
        self.robot = self.pieces[0].robot
        self.metric = self.pieces[0].metric
        total = float(lengths.sum())
        widths = lengths / total if total > 0 else np.full(len(self.pieces), 1.0 / len(self.pieces))
        self.breakpoints = np.concatenate([[0.0], np.cumsum(widths)])
        self.breakpoints[-1] = 1.0
        self.length = total
        reps = [p.solver for p in self.pieces]
        self.solver = SolverReport(
            max(r.status for r in reps), '; '.join(sorted({r.message for r in reps})),
            sum(r.iterations for r in reps), max(r.max_residual for r in reps),
            sum(r.mesh_size for r in reps), time_ms, max(r.bc_residual for r in reps),
            '+'.join(sorted({r.method for r in reps})), max(r.path_error for r in reps))

    @property
    def q_start(self) -> np.ndarray:
        """Joint positions at s = 0."""
        return self.pieces[0].q_start

    @property
    def q_goal(self) -> np.ndarray:
        """Joint positions at s = 1."""
        return self.pieces[-1].q_goal

    @property
    def via_joints(self) -> np.ndarray:
        """Joint positions at every junction (len(pieces) + 1, dof)."""
        return np.array([self.pieces[0].q_start] + [p.q_goal for p in self.pieces])

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q and its first three derivatives at global s (1-D in [0, 1]); each (len(s), dof).

        ``order`` < 3 returns only the first ``order + 1`` arrays.
        """
        order = check_order(order)
        return self._chain(check_s(s), order, lambda piece, u: piece.evaluate(u, order))

    def interpolate(self, s: np.ndarray) -> tuple[np.ndarray, ...]:
        """Each piece's :meth:`~.path.JointPath.interpolate`, at global s (the chain rule of
        :meth:`evaluate`)."""
        return self._chain(check_s(s), 3, lambda piece, u: piece.interpolate(u))

    def _chain(self, s: np.ndarray, order: int,
               values: Callable[[JointPath, np.ndarray], tuple[np.ndarray, ...]]) -> tuple[np.ndarray, ...]:
        """``values(piece, u)`` of the piece holding each global s, derivatives divided by the
        piece's width to the power of their order (the chain rule)."""
        out = [np.empty((s.size, self.dof)) for _ in range(order + 1)]
        for i, sel, u in by_segment(self.breakpoints, s):
            w = self.breakpoints[i + 1] - self.breakpoints[i]
            for k, arr in enumerate(values(self.pieces[i], u)):
                out[k][sel] = arr / w**k
        return tuple(out)

    def line_deviation(self, samples: int = 101) -> float:
        """Largest distance (m) of the tool position from each piece's straight segment."""
        return max(piece.line_deviation(samples) for piece in self.pieces)
