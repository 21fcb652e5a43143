"""Path sampling for time laws: derivatives at nodes, cubic-Hermite in between.

The path is evaluated (``path.interpolate``, its solver's spline, where it has one; else
``path.evaluate``) on a uniform grid of s plus its breakpoints (``path.breakpoints``, optional;
one-sided derivatives are read there, and where q' jumps, a corner, the motion must rest). Between
the nodes, q' and q'' are cubic-Hermite interpolated from the exact q', q'', q''' at the nodes;
steps where two independent interpolants disagree (a sharp feature of the path) are bisected with
further exact evaluations until they agree. Derivatives are w.r.t. s in [0, 1].
"""
from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from ..core.path import JointPath
from . import kernels
from ._arrays import clip

if TYPE_CHECKING:
    from .types import PathLike

#: Offset (in s) used to read the left-hand derivatives at a breakpoint.
_LEFT_EPS = 1e-12
#: Relative jump of q' at a breakpoint above which the path has a corner (the law rests there).
CORNER_TOLERANCE = 1e-5
#: Fewest TOPP steps on a piece between two breakpoints.
MIN_PIECE_STEPS = 8


@dataclass(frozen=True, eq=False)
class PathSamples:
    """Exact path derivatives at the nodes; one-sided (left/right) values at breakpoints."""

    s: np.ndarray                 # (n+1,) nodes
    aL: np.ndarray                # first derivative arriving at a node (from the left), (n+1, dof)
    aR: np.ndarray                # first derivative leaving a node (to the right)
    bL: np.ndarray                # second derivative, left / right
    bR: np.ndarray
    cL: np.ndarray                # third derivative, left / right
    cR: np.ndarray
    stop: np.ndarray              # (n+1,) bool: the first derivative jumps here (a corner)

    def refined(self, factor: int) -> PathSamples:
        """Samples on ``factor`` times finer steps (interpolated q', q''; q''' left at zero)."""
        if factor <= 1:
            return self
        n = self.s.size - 1
        dof = self.aR.shape[1]
        m = n * factor + 1
        zeros = np.zeros((m, dof))
        stop = np.zeros(m, dtype=bool)
        stop[::factor] = self.stop
        if kernels.active():      # the same values, compiled
            s, aL, aR, bL, bR = kernels.refine(self.kernel_rows, self.kernel_tables, factor)
            return PathSamples(s, aL, aR, bL, bR, zeros, zeros, stop)
        f = factor - 1
        extra = self.s[:-1, None] + np.diff(self.s)[:, None] * (np.arange(1, factor) / factor)
        k = np.repeat(np.arange(n), f)
        a, b = self._interpolate_steps(k, extra.reshape(-1) - self.s[k])

        def merge(node_vals: np.ndarray, extra_vals: np.ndarray) -> np.ndarray:
            """Node values (n+1, ...) and each step's extra values (n, factor - 1, ...) interleaved."""
            out = np.empty((m,) + node_vals.shape[1:])
            body = out[:-1].reshape((n, factor) + node_vals.shape[1:])
            body[:, 0] = node_vals[:-1]
            body[:, 1:] = extra_vals
            out[-1] = node_vals[-1]
            return out

        a = a.T.reshape(n, f, dof)
        b = b.T.reshape(n, f, dof)
        return PathSamples(merge(self.s, extra), merge(self.aL, a), merge(self.aR, a),
                            merge(self.bL, b), merge(self.bR, b), zeros, zeros, stop)

    @functools.cached_property
    def coef(self) -> np.ndarray:
        """Per-step cubic coefficients of q' and q'' in ``r = s - s_k``: (8, dof, n).

        Rows 0..3: q' = p0 + r (p1 + r (p2 + r p3)); rows 4..7 the same for q''. The cubic
        Hermite interpolant of the values and slopes at both ends of each step.
        """
        if kernels.active():
            return kernels.hermite_coef(self.s, self.aL, self.aR, self.bL, self.bR, self.cL, self.cR)
        h = np.diff(self.s)
        rows = []
        for v0, m0, v1, m1 in ((self.aR[:-1], self.bR[:-1], self.aL[1:], self.bL[1:]),
                               (self.bR[:-1], self.cR[:-1], self.bL[1:], self.cL[1:])):
            v0, m0, v1, m1 = v0.T, m0.T, v1.T, m1.T
            slope = (v1 - v0) / h
            rows += [v0, m0, (3.0 * slope - 2.0 * m0 - m1) / h, (m0 + m1 - 2.0 * slope) / (h * h)]
        return np.ascontiguousarray(np.stack(rows))

    @functools.cached_property
    def coef3(self) -> np.ndarray:
        """Per step, ``q''' = d0 + r (d1 + r d2)`` in ``r = s - s_k``: (3, dof, n), the derivative
        of the cubic Hermite of q'' (values q'', slopes q''' at both ends of a step)."""
        h = np.diff(self.s)
        v0, m0, v1, m1 = self.bR[:-1].T, self.cR[:-1].T, self.bL[1:].T, self.cL[1:].T
        slope = (v1 - v0) / h
        return np.stack([m0, 2.0 * (3.0 * slope - 2.0 * m0 - m1) / h, 3.0 * (m0 + m1 - 2.0 * slope) / (h * h)])

    @functools.cached_property
    def kernel_tables(self) -> kernels.Pinned:
        """The cubic-Hermite tables of q' and q'' for the compiled :func:`.kernels.ratios`."""
        return kernels.path_tables(self.s, self.coef)

    @functools.cached_property
    def _jumps_mask(self) -> np.ndarray:
        """(n + 1,) bool: q' or q'' jumps at the node (a breakpoint) and the motion does not rest."""
        return ((self.aL != self.aR).any(axis=1) | (self.bL != self.bR).any(axis=1)) & ~self.stop

    @functools.cached_property
    def jumps(self) -> np.ndarray:
        """Indices of the nodes where q' or q'' jumps (a breakpoint) but the motion does not rest."""
        return np.flatnonzero(self._jumps_mask)

    @functools.cached_property
    def jumps3(self) -> np.ndarray:
        """:attr:`jumps`, and the nodes where only q''' jumps (for the jerk checks)."""
        return np.flatnonzero(self._jumps_mask | ((self.cL != self.cR).any(axis=1) & ~self.stop))

    @functools.cached_property
    def kernel_rows(self) -> kernels.Pinned:
        """The nodes, one-sided q' and q'' and corners for the compiled :func:`.kernels.topp`."""
        return kernels.Pinned(self.s, self.aL, self.aR, self.bL, self.bR, self.stop)

    @functools.cached_property
    def kernel_tables3(self) -> kernels.Pinned:
        """:attr:`kernel_tables` with the third derivative (for the jerk ratios)."""
        return kernels.path_tables(self.s, self.coef, self.coef3)

    def third_derivative_t(self, s: np.ndarray) -> np.ndarray:
        """q''' at sorted ``s`` (M,), consistent with :meth:`interpolate_t`'s q''; (dof, M)."""
        coef = self.coef3
        n = self.s.size - 1
        k = clip(np.searchsorted(self.s, s, side='right') - 1, 0, n - 1)
        counts = np.bincount(k, minlength=n)
        r = s - self.s[k]
        out = np.repeat(coef[2], counts, axis=1)
        out *= r
        out += np.repeat(coef[1], counts, axis=1)
        out *= r
        out += np.repeat(coef[0], counts, axis=1)
        return out

    def interpolate_t(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and second derivatives at ``s`` (M,), transposed: each (dof, M).

        Cubic Hermite interpolation on each step (the exact derivatives at the nodes as slopes).
        """
        n = self.s.size - 1
        k = clip(np.searchsorted(self.s, s, side='right') - 1, 0, n - 1)
        return self._interpolate_steps(k, s - self.s[k])

    def _interpolate_steps(self, k: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q' and q'' at ``s_k + r`` on steps ``k`` (M,); each (dof, M)."""
        n = self.s.size - 1
        coef = self.coef
        if k.size > 1 and bool(np.all(k[1:] >= k[:-1])):  # sorted: repeating is cheaper
            counts = np.bincount(k, minlength=n)

            def at(i: int) -> np.ndarray:
                return np.repeat(coef[i], counts, axis=1)
        else:
            def at(i: int) -> np.ndarray:
                return coef[i].take(k, axis=1)
        # Horner, one coefficient block at a time (no large gathered table).
        a = at(3)
        a *= r
        b = at(7)
        b *= r
        for i in (2, 1):
            a += at(i)
            a *= r
            b += at(4 + i)
            b *= r
        a += at(0)
        b += at(4)
        return a, b

    def interpolate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and second derivatives at ``s`` (M,) by cubic Hermite interpolation; each (M, dof)."""
        a, b = self.interpolate_t(s)
        return a.T, b.T



def path_derivatives(path: PathLike, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
    """q and its first ``order`` s-derivatives at s, float arrays (len(s), dof): from the path's
    own interpolant where it has one (a solver's spline, :meth:`.JointPath.interpolate`: the
    positions a trajectory gives and their derivatives, the ones the laws are checked on), else
    ``path.evaluate``."""
    own = getattr(type(path), 'interpolate', None)
    if own is not None and own is not JointPath.interpolate:
        out = tuple(path.interpolate(s))[:order + 1]      # type: ignore[attr-defined]
    else:
        out = tuple(path.evaluate(s, order=order))
    return tuple(np.asarray(v, dtype=float) for v in out)


def sample_path(path: PathLike, grid_points: int) -> PathSamples:
    """Evaluate the path once: a uniform grid plus its breakpoints (``path.breakpoints``, optional)."""
    raw = getattr(path, 'breakpoints', None)
    interior = np.zeros(0)
    if raw is not None:
        arr = np.asarray(raw, dtype=float).reshape(-1)
        arr = arr[np.isfinite(arr)]
        interior = np.unique(arr[(arr > 1e-9) & (arr < 1.0 - 1e-9)])
        if interior.size > 1:  # merge breakpoints closer than 1e-9
            interior = interior[np.concatenate([[True], np.diff(interior) > 1e-9])]
    if interior.size:
        # Each piece between breakpoints: uniform steps of about 1 / grid_points, at least
        # MIN_PIECE_STEPS of them (a piece may start and end at rest).
        ends = np.concatenate([[0.0], interior, [1.0]])
        parts = [np.linspace(a, b, max(MIN_PIECE_STEPS, math.ceil((b - a) * grid_points)) + 1)[:-1]
                 for a, b in itertools.pairwise(ends)]
        nodes = np.concatenate(parts + [np.ones(1)])
    else:
        nodes = np.linspace(0.0, 1.0, grid_points + 1)
    s_eval = np.concatenate([nodes, interior - _LEFT_EPS])
    _, a, b, c = path_derivatives(path, s_eval)
    if a.ndim != 2 or a.shape[0] != s_eval.size:
        raise LimitError(f'path.evaluate returned shape {a.shape}, expected ({s_eval.size}, dof)')
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(c))):
        raise LimitError('path derivatives contain NaN or inf')
    m = nodes.size
    aR, bR, cR = a[:m], b[:m], c[:m]
    aL, bL, cL = aR.copy(), bR.copy(), cR.copy()
    stop = np.zeros(m, dtype=bool)
    if interior.size:
        idx = np.searchsorted(nodes, interior)
        aL[idx], bL[idx], cL[idx] = a[m:], b[m:], c[m:]
        scale = np.maximum(np.abs(aL[idx]).max(axis=1), np.abs(aR[idx]).max(axis=1))
        jump = np.abs(aL[idx] - aR[idx]).max(axis=1)
        stop[idx] = jump > CORNER_TOLERANCE * np.maximum(scale, 1e-300)
    return PathSamples(nodes, aL, aR, bL, bR, cL, cR, stop)


def _interpolation_suspects(h: np.ndarray, left: np.ndarray, right: np.ndarray, scale: np.ndarray,
                            dof: int, tol: float) -> np.ndarray:
    """Steps whose cubic-Hermite interpolation of q' or q'' is not trustworthy, (n,) bool.

    Steps of lengths ``h`` (n, 1) between nodes with data ``left`` and ``right`` (n, 6 dof): q',
    q'', q''' from the left, then from the right, side by side; ``scale`` (3, dof): the largest
    |q'|, |q''|, |q'''| over all nodes. On each step two independent mid-point estimates are
    compared: q'(mid) from the Hermite of q' (slopes q'') and from integrating the Hermite of q''
    (slopes q'''); q''(mid) from the Hermite of q'' and from integrating q''' interpolated linearly.
    For a smooth path they agree to O(h^4 q^(5)) and O(h^3 q^(5)); a disagreement above ``tol``
    times the joint's scale flags the step. Nothing is divided by h, so slightly inconsistent
    derivative data (a collocation solution) does not make the indicator grow under refinement.
    """
    if kernels.active():
        return kernels.suspects(h, left, right, scale, dof, tol)
    d2 = 2 * dof
    # (q', q'') and their slopes (q'', q''') at both ends of each step: the Hermite mid-points.
    mid_1 = (0.5 * (left[:, 3 * dof:3 * dof + d2] + right[:, :d2])
             + h * (left[:, 4 * dof:] - right[:, dof:dof + d2]) / 8.0)
    a0, b0, c0 = left[:, 3 * dof:4 * dof], left[:, 4 * dof:5 * dof], left[:, 5 * dof:]
    b1, c1 = right[:, dof:2 * dof], right[:, 2 * dof:3 * dof]
    a_mid_2 = a0 + h * (13.0 / 32.0 * b0 + 11.0 / 192.0 * h * c0 + 3.0 / 32.0 * b1 - 5.0 / 192.0 * h * c1)
    b_mid_2 = b0 + h * (3.0 * c0 + c1) / 8.0
    tiny = 1e-300
    limit = tol * (np.concatenate([scale[0], scale[1] + scale[0]]) + tiny)
    return (np.abs(mid_1 - np.concatenate([a_mid_2, b_mid_2], axis=1)) > limit).any(axis=1)


def refine_adaptively(path: PathLike, ps: PathSamples, tol: float = 1e-5, max_rounds: int = 12,
                      max_nodes: int = 2000) -> PathSamples:
    """Bisect the steps where interpolation is not trustworthy, with exact path evaluations.

    Each round checks only the steps made by the previous round's bisections: the scale of the
    test only grows as nodes are added, so a step that passed once passes again.
    """
    dof = ps.aR.shape[1]
    D = np.hstack([ps.aL, ps.bL, ps.cL, ps.aR, ps.bR, ps.cR])
    scale = np.abs(D).max(axis=0).reshape(2, 3, dof).max(axis=0)
    # The steps to check: their ends (s and node data).
    s_l, s_r, d_l, d_r = ps.s[:-1], ps.s[1:], D[:-1], D[1:]
    count = ps.s.size
    new_s, new_d = [], []
    for _ in range(max_rounds):
        checkpoint()
        h = s_r - s_l
        bad = _interpolation_suspects(h[:, None], d_l, d_r, scale, dof, tol)
        bad &= h > 1e-7
        if not np.any(bad) or count >= max_nodes:
            break
        idx = np.flatnonzero(bad)[: max_nodes - count]
        s_new = 0.5 * (s_l[idx] + s_r[idx])
        _, a, b, c = path_derivatives(path, s_new)
        new = np.hstack([a, b, c, a, b, c])
        if not np.all(np.isfinite(new)):
            raise LimitError('path derivatives contain NaN or inf')
        new_s.append(s_new)
        new_d.append(new)
        count += s_new.size
        scale = np.maximum(scale, np.abs(new).max(axis=0).reshape(2, 3, dof).max(axis=0))
        # The halves of each bisected step, in order of s.
        s_l = np.stack([s_l[idx], s_new], axis=1).reshape(-1)
        s_r = np.stack([s_new, s_r[idx]], axis=1).reshape(-1)
        d_l, d_r = (np.stack([d_l[idx], new], axis=1).reshape(-1, D.shape[1]),
                    np.stack([new, d_r[idx]], axis=1).reshape(-1, D.shape[1]))
    if not new_s:
        return ps
    # Insert the new (non-breakpoint) nodes in order of s.
    s_all = np.concatenate([ps.s] + new_s)
    order = np.argsort(s_all, kind='stable')
    D = np.concatenate([D] + new_d)[order]
    stop = np.concatenate([ps.stop, np.zeros(count - ps.s.size, dtype=bool)])[order]
    aL, bL, cL, aR, bR, cR = (np.ascontiguousarray(D[:, i * dof:(i + 1) * dof]) for i in range(6))
    return PathSamples(s_all[order], aL, aR, bL, bR, cL, cR, stop)


__all__ = ['CORNER_TOLERANCE', 'MIN_PIECE_STEPS', 'PathSamples', 'refine_adaptively', 'sample_path']
