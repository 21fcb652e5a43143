"""Time parameterization of a geometric path under joint velocity and acceleration limits.

The paper (Lemma 2) notes that a geodesic's speed is set by rescaling its parameter. This module
turns that into a practical time law ``s(t)`` for any path ``q(s)``, ``s`` in [0, 1]:

1. **Sampling**: the path is evaluated on a uniform grid of s plus its breakpoints
   (``path.breakpoints``, optional; one-sided derivatives are read there). Between the nodes, q'
   and q'' are cubic-Hermite interpolated from the exact q', q'', q''' at the nodes; steps where
   two independent interpolants disagree (a sharp feature of the path) are bisected with further
   exact evaluations until they agree.
2. **Time-optimal profile** (TOPP-RA-like, Pham & Pham 2018): the squared path speed
   ``x = sdot^2`` is computed by a backward pass (largest ``x`` from which the end can still be
   reached at rest) and a greedy forward pass (largest admissible ``sddot``), subject to
   ``|q'(s) sdot| <= vmax`` and ``|q'(s) sddot + q''(s) sdot^2| <= amax`` per joint. ``sddot`` is
   constant per step, so the optimal law ``s*(t)`` is piecewise quadratic in time; its duration
   is :attr:`Trajectory.topp_duration`. Where q' jumps (a corner between the pieces of a
   piecewise geodesic) the profile is forced to rest. Both passes are min-of-affine recursions;
   they are solved in closed form with one (iteratively chosen) constraint row per step and
   accepted only when every step satisfies the recursion over all rows to 1e-12, else by loops
   over guessed rows verified against all rows (the floats of a loop over all rows).
3. **Smoothing**: ``s*(t)`` has acceleration jumps (bang-bang), including at both ends. Each
   rest-to-rest piece is convolved with a triangular kernel of half-width
   ``tau = smoothing * T* / 2``, done exactly:
   ``s(t) = (S2(t + tau) - 2 S2(t) + S2(t - tau)) / tau^2`` with ``S2`` the second antiderivative
   of ``s*`` (constant before its start and after its end). Hence ``sddot`` is the second central
   difference of ``s*`` (continuous), the jerk is bounded, and every rest (both ends, corners)
   has zero velocity AND zero acceleration. Each piece lasts ``T* + 2 tau``.
4. **Guarantee**: the law is checked on a dense time grid against the full limits (plus
   samples about uniform in s, placed from the nodes of ``s*`` delayed by tau, where the law
   crosses the path fast); if smoothing
   pushed any joint over a limit, time is stretched uniformly (``t -> lambda t`` divides
   velocities by ``lambda`` and accelerations by ``lambda^2``) until every sample is within
   ``1 - CHECK_MARGIN`` of the limits; the samples nearest a limit are re-checked with the
   path's exact derivatives. :attr:`Trajectory.optimality_ratio` reports
   ``min_duration / topp_duration`` (about ``1 + smoothing``).
5. ``duration=`` stretches the law uniformly to exactly that duration (never shorter than the
   minimum, which the error names).

The path never changes: ``q(t) = path.q(s(t))``, ``dq/dt = q' sdot``,
``d2q/dt2 = q' sddot + q'' sdot^2``, evaluated exactly from the path.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from ..core.errors import LimitError
from ..core.path import JointPath

#: Relative margin kept below the limits (TOPP uses limits * (1 - TOPP_MARGIN)).
TOPP_MARGIN = 1e-3
#: After the dense check every sample satisfies |value| <= limit * (1 - CHECK_MARGIN).
CHECK_MARGIN = 1e-3
#: Cap on sdot^2 (1/s^2) where a path segment does not move any joint.
_X_CAP = 1e12


def _clip(x: Any, lo: Any, hi: Any) -> np.ndarray:
    """np.clip without its per-call overhead (it dominates on the small arrays used here)."""
    return np.minimum(np.maximum(x, lo), hi)


class PathLike(Protocol):
    """What :func:`time_parameterize` needs from a path."""

    joint_names: Any
    robot: Any

    def evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(q, q', q'', q''') at ``s`` (N,), each (N, dof); derivatives w.r.t. s."""


def _evaluate2(path: Any, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions and first two s-derivatives; our paths skip the third (evaluate(s, order=2))."""
    if isinstance(path, JointPath):
        q, q1, q2 = path.evaluate(s, order=2)
    else:
        q, q1, q2, _ = path.evaluate(s)
    return q, q1, q2


def _limits(value: Any, default: Any, dof: int, joint_names: list[str], what: str) -> np.ndarray:
    """Validate a per-joint limit (scalar broadcast); LimitError names the joint."""
    source = 'robot default' if value is None else 'requested'
    if value is None:
        value = default
    if value is None:
        raise LimitError(f'{what}: no limit given and the robot has no default')
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise LimitError(f'{what}: not a number or list of numbers ({err})') from err
    if arr.ndim == 0:
        arr = np.full(dof, float(arr))
    arr = arr.reshape(-1)
    if arr.shape != (dof,):
        raise LimitError(f'{what}: expected 1 or {dof} values (one per joint), got {arr.size}')
    for i, v in enumerate(arr):
        if not (math.isfinite(v) and v > 0.0):
            raise LimitError(
                f"{what} for joint '{joint_names[i]}' must be positive and finite, got {v!r} ({source})")
    return arr


@dataclass(frozen=True, eq=False)
class _PathSamples:
    """Exact path derivatives at the nodes; one-sided (left/right) values at breakpoints."""

    s: np.ndarray                 # (n+1,) nodes
    aL: np.ndarray                # first derivative arriving at a node (from the left), (n+1, dof)
    aR: np.ndarray                # first derivative leaving a node (to the right)
    bL: np.ndarray                # second derivative, left / right
    bR: np.ndarray
    cL: np.ndarray                # third derivative, left / right
    cR: np.ndarray
    stop: np.ndarray              # (n+1,) bool: the first derivative jumps here (a corner)

    def refined(self, factor: int) -> _PathSamples:
        """Samples on ``factor`` times finer steps (interpolated q', q''; q''' left at zero)."""
        if factor <= 1:
            return self
        n = self.s.size - 1
        dof = self.aR.shape[1]
        f = factor - 1
        extra = self.s[:-1, None] + np.diff(self.s)[:, None] * (np.arange(1, factor) / factor)
        k = np.repeat(np.arange(n), f)
        a, b = self._interpolate_steps(k, extra.reshape(-1) - self.s[k])
        m = n * factor + 1

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
        zeros = np.zeros((m, dof))
        stop = np.zeros(m, dtype=bool)
        stop[::factor] = self.stop
        return _PathSamples(merge(self.s, extra), merge(self.aL, a), merge(self.aR, a),
                            merge(self.bL, b), merge(self.bR, b), zeros, zeros, stop)

    @functools.cached_property
    def _coef(self) -> np.ndarray:
        """Per-step cubic coefficients of q' and q'' in ``r = s - s_k``: (8, dof, n).

        Rows 0..3: q' = p0 + r (p1 + r (p2 + r p3)); rows 4..7 the same for q''. The cubic
        Hermite interpolant of the values and slopes at both ends of each step.
        """
        h = np.diff(self.s)
        rows = []
        for v0, m0, v1, m1 in ((self.aR[:-1], self.bR[:-1], self.aL[1:], self.bL[1:]),
                               (self.bR[:-1], self.cR[:-1], self.bL[1:], self.cL[1:])):
            v0, m0, v1, m1 = v0.T, m0.T, v1.T, m1.T
            slope = (v1 - v0) / h
            rows += [v0, m0, (3.0 * slope - 2.0 * m0 - m1) / h, (m0 + m1 - 2.0 * slope) / (h * h)]
        return np.ascontiguousarray(np.stack(rows))

    def interpolate_t(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """First and second derivatives at ``s`` (M,), transposed: each (dof, M).

        Cubic Hermite interpolation on each step (the exact derivatives at the nodes as slopes).
        """
        n = self.s.size - 1
        k = _clip(np.searchsorted(self.s, s, side='right') - 1, 0, n - 1)
        return self._interpolate_steps(k, s - self.s[k])

    def _interpolate_steps(self, k: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q' and q'' at ``s_k + r`` on steps ``k`` (M,); each (dof, M)."""
        n = self.s.size - 1
        coef = self._coef
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


#: Offset (in s) used to read the left-hand derivatives at a breakpoint.
_LEFT_EPS = 1e-12
#: Relative jump of q' at a breakpoint above which the path has a corner (the law rests there).
CORNER_TOLERANCE = 1e-5
#: Fewest TOPP steps on a piece between two breakpoints.
MIN_PIECE_STEPS = 8
#: Samples of the dense check (those nearest a limit) re-verified with exact path derivatives.
EXACT_CHECKS = 32
#: Extra limit-check samples spread uniformly in s (mapped to t).
S_UNIFORM_CHECKS = 1000


def _sample_path(path: Any, grid_points: int) -> _PathSamples:
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
        parts = [np.linspace(a, b, max(MIN_PIECE_STEPS, int(math.ceil((b - a) * grid_points))) + 1)[:-1]
                 for a, b in zip(ends[:-1], ends[1:])]
        nodes = np.concatenate(parts + [np.ones(1)])
    else:
        nodes = np.linspace(0.0, 1.0, grid_points + 1)
    s_eval = np.concatenate([nodes, interior - _LEFT_EPS])
    _, a, b, c = (np.asarray(v, dtype=float) for v in path.evaluate(s_eval))
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
    return _PathSamples(nodes, aL, aR, bL, bR, cL, cR, stop)


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
    d2 = 2 * dof
    # (q', q'') and their slopes (q'', q''') at both ends of each step: the Hermite mid-points.
    mid_1 = 0.5 * (left[:, 3 * dof:3 * dof + d2] + right[:, :d2]) + h * (left[:, 4 * dof:] - right[:, dof:dof + d2]) / 8.0
    a0, b0, c0 = left[:, 3 * dof:4 * dof], left[:, 4 * dof:5 * dof], left[:, 5 * dof:]
    b1, c1 = right[:, dof:2 * dof], right[:, 2 * dof:3 * dof]
    a_mid_2 = a0 + h * (13.0 / 32.0 * b0 + 11.0 / 192.0 * h * c0 + 3.0 / 32.0 * b1 - 5.0 / 192.0 * h * c1)
    b_mid_2 = b0 + h * (3.0 * c0 + c1) / 8.0
    tiny = 1e-300
    limit = tol * (np.concatenate([scale[0], scale[1] + scale[0]]) + tiny)
    return (np.abs(mid_1 - np.concatenate([a_mid_2, b_mid_2], axis=1)) > limit).any(axis=1)


def _refine_adaptively(path: Any, ps: _PathSamples, tol: float = 1e-5, max_rounds: int = 12,
                       max_nodes: int = 2000) -> _PathSamples:
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
        h = s_r - s_l
        bad = _interpolation_suspects(h[:, None], d_l, d_r, scale, dof, tol)
        bad &= h > 1e-7
        if not np.any(bad) or count >= max_nodes:
            break
        idx = np.flatnonzero(bad)[: max_nodes - count]
        s_new = 0.5 * (s_l[idx] + s_r[idx])
        _, a, b, c = (np.asarray(v, dtype=float) for v in path.evaluate(s_new))
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
    return _PathSamples(s_all[order], aL, aR, bL, bR, cL, cR, stop)


def _row_min(values: np.ndarray) -> np.ndarray:
    """values.min(axis=1) for (n, m) arrays with few columns (numpy's argmin is much faster there)."""
    return values[np.arange(values.shape[0]), np.argmin(values, axis=1)]


#: Rounds of the row-guessing passes of _topp before the remaining steps use all rows.
_PASS_ROUNDS = 6


def _pick(values: np.ndarray, cols: np.ndarray) -> list[float]:
    """values[k, cols[k]] for each step k, as floats."""
    return values[np.arange(cols.size), cols].tolist()


#: Iterations of the vectorised (closed-form) TOPP passes.
_GUESS_ITERATIONS = 4
#: Relative per-step residual below which a closed-form TOPP pass is accepted.
_CLOSED_FORM_RTOL = 1e-12


def _sums(terms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Prefix and suffix sums of ``terms`` (n,): ``P_k = sum_{i<k}``, ``S_k = sum_{i>=k}``, each (n+1,)."""
    prefix = np.zeros(terms.size + 1)
    suffix = np.zeros(terms.size + 1)
    np.cumsum(terms, out=prefix[1:])
    np.cumsum(terms[::-1], out=suffix[-2::-1])
    return prefix, suffix


def _backward_closed(A: np.ndarray, B: np.ndarray, static: np.ndarray
                     ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """The backward pass, vectorised: (hi or None, guessed rows, first guess), rows (n,) ints.

    With one row per step, ``h_k = min(static_k, a_k h_{k+1} + b_k)`` (a_k > 0, h_n = 0) has a
    closed form: with ``L_k = sum_{i<k} log a_i`` and ``E_i = e^{L_i} b_i``,
    ``h_k = e^{-L_k} min_{m >= k} (e^{L_m} static_m + sum_{i=k}^{m-1} E_i)`` (static_n = 0); the
    partial sums are differences of prefix sums, or of suffix sums, whichever cancels less. Starting
    from the rows lowest at the solution for a = 1 (a cumulative minimum), it is solved again with
    the rows lowest at the previous solution. It is accepted when every step satisfies the recursion over all rows to
    ``_CLOSED_FORM_RTOL`` (exactly where it is zero: the rests); otherwise None, and the rows serve
    as guesses for the loop.
    """
    n = static.size
    steps = np.arange(n)
    st = np.append(static, 0.0)
    with np.errstate(all='ignore'):
        # First guess: the rows lowest at the solution for a_k = 1 and the rows lowest at h = 0.
        C = np.zeros(n + 1)
        np.cumsum(_row_min(B), out=C[1:])
        h0 = np.minimum.accumulate((st + C)[::-1])[::-1] - C
        g = first = np.argmin(A * h0[1:, None] + B, axis=1)
        for _ in range(_GUESS_ITERATIONS):
            L = np.zeros(n + 1)
            np.cumsum(np.log(A[steps, g]), out=L[1:])
            eL = np.exp(L)
            P, S = _sums(eL[:-1] * B[steps, g])
            est = eL * st
            m1 = np.minimum.accumulate((est + P)[::-1])[::-1]
            m2 = np.minimum.accumulate((est - S)[::-1])[::-1]
            # e^{L_k} h_k from the smaller of the prefix and suffix sums (less cancellation).
            h = np.where(P <= S, m1 - P, S + m2) / eL
            vals = A * h[1:, None] + B
            act = np.argmin(vals, axis=1)
            exact = np.minimum(static, vals[steps, act])
            if bool(np.all(np.abs(exact - h[:-1]) <= _CLOSED_FORM_RTOL * exact)):
                return h, act, first
            if bool((act == g).all()):
                break
            g = act
    return None, g, first


def _forward_closed(alpha: np.ndarray, d: np.ndarray, two_h: np.ndarray, hi: np.ndarray
                    ) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
    """The forward pass, vectorised: (x or None, guessed rows, first guess), as :func:`_backward_closed`.

    With one row per step, ``x_{k+1} = min(hi_{k+1}, p_k x_k + q_k)`` (p = 1 + 2 h alpha,
    q = 2 h d) has a closed form for p > 0: with ``L_j = sum_{i<j} log p_i`` and
    ``E_i = e^{-L_{i+1}} q_i``, ``x_j = e^{L_j} min_{m <= j} (e^{-L_m} hi_m + sum_{i=m}^{j-1} E_i)``
    (hi_0 = 0). Starting from the rows lowest at the solution for p = 1 and the rows lowest at
    x = 0; accepted when every step matches the exact update over all rows to
    ``_CLOSED_FORM_RTOL``.
    """
    n = two_h.size
    steps = np.arange(n)
    hi1 = hi[1:]
    top = hi.copy()
    top[0] = 0.0
    with np.errstate(all='ignore'):
        # First guess: the rows lowest at the solution for p_k = 1 and the rows lowest at x = 0.
        C = np.zeros(n + 1)
        np.cumsum(two_h * _row_min(d), out=C[1:])
        x_1 = C + np.minimum.accumulate(top - C)
        g = first = np.argmin(alpha * x_1[:-1, None] + d, axis=1)
        for _ in range(_GUESS_ITERATIONS):
            L = np.zeros(n + 1)
            np.cumsum(np.log(np.maximum(1.0 + two_h * alpha[steps, g], 1e-6)), out=L[1:])
            eL = np.exp(L)
            P, S = _sums(two_h * d[steps, g] / eL[1:])
            tl = top / eL
            m1 = np.minimum.accumulate(tl - P)
            m2 = np.minimum.accumulate(tl + S)
            x = np.where(P <= S, P + m1, m2 - S) * eL
            x0 = x[:-1]
            vals = alpha * x0[:, None] + d
            act = np.argmin(vals, axis=1)
            u = np.minimum((hi1 - x0) / two_h, vals[steps, act])
            exact = np.minimum(np.maximum(x0 + two_h * u, 0.0), hi1)
            if bool(np.all(np.abs(exact - x[1:]) <= _CLOSED_FORM_RTOL * exact)):
                return x, act, first
            if bool((act == g).all()):
                break
            g = act
    return None, g, first


def _backward_pass(A: np.ndarray, B: np.ndarray, static: np.ndarray) -> np.ndarray:
    """hi_k = min(static_k, min_j A_kj hi_{k+1} + B_kj) for k = n-1 .. 0, hi_n = 0; (n + 1,).

    First in closed form (:func:`_backward_closed`, accepted to a relative 1e-12 per step).
    Otherwise the recursion runs on plain floats over two guessed rows per step, and the result
    is checked against all rows at once: a step where the recursion holds with all rows, after
    steps that all hold, has exactly the value a loop over all rows gives (the same floating-point
    operations), so the loop resumes at the first step that fails, with the row lowest there (and
    the previous guess) as the guesses. After a few rounds the remaining steps use every row.
    """
    n = static.size
    st = static.tolist()
    hi = [0.0] * (n + 1)
    closed, g0, g1 = _backward_closed(A, B, static)
    if closed is not None:
        return closed
    start = n - 1
    for _ in range(_PASS_ROUNDS):
        a0, b0, a1, b1 = _pick(A, g0), _pick(B, g0), _pick(A, g1), _pick(B, g1)
        h = hi[start + 1]
        for k in range(start, -1, -1):
            h = min(st[k], a0[k] * h + b0[k], a1[k] * h + b1[k])
            hi[k] = h
        hv = np.array(hi)
        with np.errstate(invalid='ignore', over='ignore'):
            vals = A * hv[1:, None] + B
        act = np.argmin(vals, axis=1)
        bad = np.flatnonzero(np.minimum(static, vals[np.arange(n), act]) != hv[:-1])
        if bad.size == 0:
            return hv
        start = int(bad[-1])
        g0, g1 = act, g0
    A_l, B_l = A[:start + 1].tolist(), B[:start + 1].tolist()
    h = hi[start + 1]
    for k in range(start, -1, -1):
        h = min([st[k]] + [ak * h + bk for ak, bk in zip(A_l[k], B_l[k])])
        hi[k] = h
    return np.array(hi)


def _forward_pass(alpha: np.ndarray, d: np.ndarray, two_h: np.ndarray, hi_np: np.ndarray) -> np.ndarray:
    """Greedy forward pass x_{k+1} = clip(x_k + 2 h_k u_k, 0, hi_{k+1}), x_0 = 0; (n + 1,).

    ``u_k = min((hi_{k+1} - x_k) / (2 h_k), min_j alpha_kj x_k + d_kj)``; closed form first
    (:func:`_forward_closed`), else guessed rows checked against all rows, as in
    :func:`_backward_pass`.
    """
    n = two_h.size
    hi1 = hi_np[1:]
    th, hi1_l = two_h.tolist(), hi1.tolist()
    x = [0.0] * (n + 1)
    closed, g0, g1 = _forward_closed(alpha, d, two_h, hi_np)
    if closed is not None:
        return closed
    start = 0
    for _ in range(_PASS_ROUNDS):
        a0, d0, a1, d1 = _pick(alpha, g0), _pick(d, g0), _pick(alpha, g1), _pick(d, g1)
        xk = x[start]
        for k in range(start, n):
            u = min((hi1_l[k] - xk) / th[k], a0[k] * xk + d0[k], a1[k] * xk + d1[k])
            xk = min(max(xk + th[k] * u, 0.0), hi1_l[k])
            x[k + 1] = xk
        xv = np.array(x)
        x0 = xv[:-1]
        with np.errstate(invalid='ignore', over='ignore'):
            vals = alpha * x0[:, None] + d
        act = np.argmin(vals, axis=1)
        u = np.minimum((hi1 - x0) / two_h, vals[np.arange(n), act])
        bad = np.flatnonzero(np.minimum(np.maximum(x0 + two_h * u, 0.0), hi1) != xv[1:])
        if bad.size == 0:
            return xv
        start = int(bad[0])
        g0, g1 = act, g0
    al_l, d_l = alpha.tolist(), d.tolist()
    xk = x[start]
    for k in range(start, n):
        u = min([(hi1_l[k] - xk) / th[k]] + [ak * xk + dk for ak, dk in zip(al_l[k], d_l[k])])
        xk = min(max(xk + th[k] * u, 0.0), hi1_l[k])
        x[k + 1] = xk
    return np.array(x)


@functools.lru_cache(maxsize=16)
def _pairs(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j), i < j, of ``rows`` rows."""
    return np.triu_indices(rows, 1)


def _topp(ps: _PathSamples, vmax: np.ndarray, amax: np.ndarray) -> np.ndarray:
    """Time-optimal x = sdot^2 at the nodes (rest at both ends and at corners), TOPP-RA-like.

    Interpolation discretization: on step k, ``u_k`` (sddot) is constant and the acceleration
    constraints hold at both ends of the step, at s_k with x_k and at s_{k+1} with
    x_{k+1} = x_k + 2 h_k u_k; this keeps the profile honest near zero-inertia points (a joint
    turning round, q' = 0).

    Args:
        ps: path derivatives at the nodes.
        vmax, amax: limits, shape (dof,).
    Returns:
        x, shape (n+1,), zero at both ends and at corners.
    Raises:
        LimitError: the path cannot be traversed (zero speed forced over a whole step).
    """
    n = ps.s.size - 1
    dl = np.diff(ps.s)[:, None]                                   # (n, 1) step lengths
    with np.errstate(divide='ignore', invalid='ignore', over='ignore'):
        absa_n = np.maximum(np.abs(ps.aL), np.abs(ps.aR))
        mov_v = absa_n > 1e-12 * max(float(absa_n.max()), 1e-300)
        # Rows of step k: |ra u + rb x_k| <= rl.
        ra = np.concatenate([ps.aR[:-1], ps.aL[1:] + 2.0 * dl * ps.bL[1:]], axis=1)   # (n, 2 dof)
        rb = np.concatenate([ps.bR[:-1], ps.bL[1:]], axis=1)
        rl = np.concatenate([amax, amax])
        absa = np.abs(ra)
        moving = absa > 1e-12 * max(float(absa.max()), 1e-300)
        if mov_v.all() and moving.all():  # the usual case: no masking needed (same values)
            xv = _row_min((vmax / absa_n) ** 2)
            alpha = -rb / ra
            d = rl / absa
            c = -d
            xz = xv[:-1]  # no row with ra = 0: a neutral bound
        else:
            xv = _row_min(np.where(mov_v, (vmax / np.where(mov_v, absa_n, 1.0)) ** 2, np.inf))
            absb = np.abs(rb)
            # Rows with ra = 0: |rb| x <= rl.
            xz = _row_min(np.where(~moving & (absb > 0), rl / np.where(absb > 0, absb, 1.0), np.inf))
            # Bounds on u: alpha x + c <= u <= alpha x + d.
            alpha = np.where(moving, -rb / np.where(moving, ra, 1.0), 0.0)
            c = np.where(moving, -rl / np.where(moving, absa, 1.0), -np.inf)
            d = np.where(moving, rl / np.where(moving, absa, 1.0), np.inf)
        # Pairs (lower j, upper m): (alpha_j - alpha_m) x <= d_m - c_j = d_m + d_j (c = -d); each
        # unordered pair once, with |alpha_j - alpha_m| (a row that does not move has d = inf).
        iu, ju = _pairs(ra.shape[1])
        dT, alT = d.T.copy(), alpha.T.copy()
        xp = np.minimum.reduce((dT[iu] + dT[ju]) / np.abs(alT[iu] - alT[ju]), axis=0)
        # Lower bound u >= -x / (2 h) (x_{k+1} >= 0) against the upper bounds.
        coef = -1.0 / (2.0 * dl) - alpha
        lo_ok = moving & (coef > 0)
        xl = _row_min(np.where(lo_ok, d / np.where(lo_ok, coef, 1.0), np.inf))
        static = np.minimum(np.minimum(np.minimum(xv[:-1], xz), np.minimum(xp, xl)), _X_CAP)
        # Dynamic bound: alpha_j x + c_j <= (hi_{k+1} - x) / (2 h)
        #   <=> x (1 + 2 h alpha_j) <= hi_{k+1} - 2 h c_j.
        den = 1.0 + 2.0 * dl * alpha
        dyn_ok = moving & (den > 0)
        if dyn_ok.all():
            A = 1.0 / den
            B = -2.0 * dl * c / den
        else:
            A = np.where(dyn_ok, 1.0 / np.where(dyn_ok, den, 1.0), 0.0)
            B = np.where(dyn_ok, -2.0 * dl * c / np.where(dyn_ok, den, 1.0), np.inf)
    static = np.where(ps.stop[:-1], 0.0, np.maximum(static, 0.0))
    # Backward pass: largest x_k from which the end (and every corner) is reached at rest.
    hi = _backward_pass(A, B, static)
    # Forward pass: greedy largest sddot.
    x = _forward_pass(alpha, d, 2.0 * dl[:, 0], hi)
    out = x
    out[n] = 0.0
    stuck = (out[:-1] <= 0.0) & (out[1:] <= 0.0)
    if np.any(stuck):
        k = int(np.argmax(stuck))
        raise LimitError(f'path cannot be traversed under the limits: speed forced to zero at s = {ps.s[k]:.6g}')
    return out


@dataclass(frozen=True, eq=False)
class _PiecewiseLaw:
    """The smoothed law: rest-to-rest pieces one after the other (rests at corners of the path).

    Piece i runs from ``t_offsets[i]`` for ``T*_i + 2 tau_i``: its time-optimal law ``s*``
    (piecewise quadratic, relative to the piece's start ``s_start``: 0 before it starts, ``span``
    after it ends) smoothed by a triangular kernel of half-width ``tau_i``. All pieces are
    evaluated together: their ``s*`` segments sit in one table, searched by the key
    ``i * key_step + local time`` (``key_step`` exceeds four times every piece's duration, so the
    pieces' key ranges do not overlap); polynomials are evaluated in local time.
    """

    t_offsets: np.ndarray  # (L + 1,) start time of each piece; the last is the total duration
    pieces: np.ndarray     # (6, L): tau, duration, s_start, span, s_end, T* of each piece
    key_step: float
    seg_key: np.ndarray    # (S,) segment starts (keys)
    seg: np.ndarray        # (6, S): start (local time), s0, v0, u, S1, S2 of each s* segment
    node_s: np.ndarray     # (N + L,) path parameter at the nodes of s*, piece after piece
    node_t: np.ndarray     # (N + L,) their times in s* delayed by tau

    @property
    def n_pieces(self) -> int:
        return self.pieces.shape[1]

    @functools.cached_property
    def seg_3(self) -> np.ndarray:
        """The segment table three times side by side, (6, 3 S) (one copy per shift of the kernel)."""
        return np.tile(self.seg, 3)

    @property
    def duration(self) -> float:
        return float(self.t_offsets[-1])

    @property
    def t_star(self) -> float:
        return float(sum(self.pieces[5].tolist()))

    @property
    def rests(self) -> tuple[float, ...]:
        """Path parameters of the rests: each piece's start, then the last end."""
        return (float(self.pieces[2, 0]),) + tuple(self.pieces[4].tolist())

    def times_at(self, s: np.ndarray) -> np.ndarray:
        """Approximate times (M,) at which the smoothed law passes the path parameters ``s`` (M,).

        The time-optimal law's nodes delayed by tau (the smoothed law averages s* over
        [t - 2 tau, t]), linearly interpolated: cheap, and close enough to place check samples.
        """
        return np.interp(s, self.node_s, self.node_t)

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at times t (M,) in [0, duration] (clipped)."""
        t = np.asarray(t, dtype=float)
        offs = self.t_offsets
        nl = self.n_pieces
        if nl == 1:
            local = _clip(t, 0.0, self.duration)
            tau, dur, s_start, span, s_end = self.pieces[:5, 0].tolist()
            key_off = 0.0
        else:
            # Times within round-off of a rest snap onto it (exact rest there).
            j = _clip(np.searchsorted(offs, t), 1, offs.size - 1)
            near = np.where(np.abs(t - offs[j - 1]) <= np.abs(t - offs[j]), offs[j - 1], offs[j])
            t = np.where(np.abs(t - near) <= 1e-12 * max(1.0, self.duration), near, t)
            idx = _clip(np.searchsorted(offs, t, side='right') - 1, 0, nl - 1)
            tau, dur, s_start, span, s_end = self.pieces[:5].take(idx, axis=1)
            local = _clip(np.where(t >= offs.take(idx + 1), dur, t - offs.take(idx)), 0.0, dur)
            key_off = idx * self.key_step
        # s* and its integrals at local - j tau, j = 0, 1, 2 (the smoothed law is their second
        # central difference: a triangular kernel of half-width tau).
        c = local - tau
        q = np.concatenate([local, c, c - tau])
        m = local.size
        key = q + np.concatenate([key_off] * 3) if nl > 1 else q
        runs = key.reshape(3, m)
        ordered = m > 1 and bool(np.all(runs[:, 1:] >= runs[:, :-1]))
        if ordered:
            # Sorted times (the usual case): each run's samples per segment, by searching the
            # segment starts in the run, then repeats of the table rows (one array per row: large
            # 2-D temporaries cost more, in fresh memory, than the extra calls).
            counts = np.concatenate([np.diff(np.searchsorted(run, self.seg_key, side='left'), append=m)
                                     for run in runs])
            start, s0, v0, u, S1, S2 = (np.repeat(row, counts) for row in self.seg_3)
        else:
            k = np.searchsorted(self.seg_key, key, side='right') - 1
            start, s0, v0, u, S1, S2 = (row.take(k) for row in self.seg)
        # Horner, in place: S2 + r (S1 + r (s0 / 2 + r (v0 / 6 + r u / 24))), and likewise.
        r = q - start
        ru = r * u
        w2 = ru / 24.0
        w2 += v0 / 6.0
        w2 *= r
        w2 += 0.5 * s0
        w2 *= r
        w2 += S1
        w2 *= r
        w2 += S2
        w1 = ru / 6.0
        w1 += 0.5 * v0
        w1 *= r
        w1 += s0
        w1 *= r
        w1 += S1
        w0 = 0.5 * ru
        w0 += v0
        w0 *= r
        w0 += s0
        inv = 1.0 / (tau * tau)

        def second_difference(y: np.ndarray) -> np.ndarray:
            y = y.reshape(3, m)
            out = y[0] - 2.0 * y[1]
            out += y[2]
            out *= inv
            return out

        s = s_start + _clip(second_difference(w2), 0.0, span)
        sd = np.maximum(second_difference(w1), 0.0)
        sdd = second_difference(w0)
        if jerk:
            ru += v0
            sddd = second_difference(ru)
        else:
            sddd = None
        # Exact ends: at rest, at s_start and s_end.
        if ordered and nl == 1:  # the ends are a prefix and a suffix
            first = int(np.searchsorted(local, 0.0, side='right'))   # local <= 0
            last = int(np.searchsorted(local, dur, side='left'))     # local >= dur from here
            s[:first] = s_start
            s[last:] = s_end
            for arr in (sd, sdd) if sddd is None else (sd, sdd, sddd):
                arr[:first] = 0.0
                arr[last:] = 0.0
            return s, sd, sdd, sddd
        end = local >= dur
        start_ = local <= 0.0
        s = np.where(end, s_end, np.where(start_, s_start, s))
        zero = end | start_
        if np.any(zero):
            sd, sdd = np.where(zero, 0.0, sd), np.where(zero, 0.0, sdd)
            if sddd is not None:
                sddd = np.where(zero, 0.0, sddd)
        return s, sd, sdd, sddd


def _build_piecewise_law(s_nodes: np.ndarray, x: np.ndarray, smoothing: float) -> _PiecewiseLaw:
    """Split the optimal profile at its rests (x = 0) and smooth each rest-to-rest piece.

    On each step of a piece ``sddot*`` is constant, so ``s*(t)`` is exactly piecewise quadratic;
    its first and second integrals S1, S2 accumulate from the piece's start. All pieces at once:
    per-piece running sums are row-wise sums of a padded (pieces, steps) array.
    """
    rests = np.flatnonzero(x <= 0.0)
    n_steps = np.diff(rests)                       # (L,) steps per piece
    L = n_steps.size
    k = np.arange(rests[0], rests[-1])             # steps, piece after piece
    piece = np.repeat(np.arange(L), n_steps)
    first = rests[:-1]
    pos = k - first[piece]                         # index of the step in its piece
    start_s = s_nodes[first]
    rel0 = s_nodes[k] - start_s[piece]             # s at the step's ends, relative to the piece
    rel1 = s_nodes[k + 1] - start_s[piece]
    dl = rel1 - rel0
    v = np.sqrt(x)
    v0 = v[k]
    dt = 2.0 * dl / (v0 + v[k + 1])
    u = (x[k + 1] - x[k]) / (2.0 * dl)

    def running(vals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per piece, the running sum of ``vals`` (N,) at the end and at the start of each step."""
        if L == 1:
            end = np.cumsum(vals)
        else:
            pad = np.zeros((L, int(n_steps.max())))
            pad[piece, pos] = vals
            end = np.cumsum(pad, axis=1)[piece, pos]
        begin = np.concatenate([[0.0], end[:-1]])
        begin[pos == 0] = 0.0
        return end, begin

    t1, t0 = running(dt)
    S1e, S1s = running(rel0 * dt + v0 * dt**2 / 2.0 + u * dt**3 / 6.0)
    S2e, S2s = running(S1s * dt + rel0 * dt**2 / 2.0 + v0 * dt**3 / 6.0 + u * dt**4 / 24.0)
    last = np.cumsum(n_steps) - 1                  # last step of each piece
    t_star = t1[last]
    tau = 0.5 * smoothing * t_star
    dur = t_star + 2.0 * tau
    offsets = np.concatenate([[0.0], np.cumsum(dur)])
    span = rel1[last]
    pieces = np.stack([tau, dur, start_s, span, s_nodes[rests[1:]], t_star])
    # Segments: per piece, the rest before it, its steps, the rest after it.
    idx = np.arange(L)
    seg_steps = np.arange(k.size) + 2 * piece + 1
    seg_after = last + 2 * idx + 2
    seg_before = seg_after - n_steps - 1
    seg = np.zeros((6, k.size + 2 * L))
    seg[:, seg_steps] = (t0, rel0, v0, u, S1s, S2s)
    seg[:, seg_after] = (t_star, span, np.zeros(L), np.zeros(L), S1e[last], S2e[last])
    # A power of two: i * key_step is exact; local times lie in [-2 tau, duration] within +-key_step / 4.
    key_step = float(2.0 ** math.ceil(math.log2(4.0 * max(float(dur.max()), 1e-300))))
    seg_key = seg[0].copy()
    if L > 1:
        seg_key[seg_steps] += piece * key_step
        seg_key[seg_after] += idx * key_step
    seg_key[seg_before] = (idx - 0.5) * key_step
    seg_key[0] = -np.inf
    # Nodes of s* (both ends of every piece), delayed by tau, for placing check samples.
    node_s = np.empty(k.size + L)
    node_t = np.empty(k.size + L)
    node_steps = np.arange(k.size) + piece
    node_s[node_steps] = start_s[piece] + rel0
    node_t[node_steps] = (offsets[:-1] + tau)[piece] + t0
    node_s[last + idx + 1] = start_s + span
    node_t[last + idx + 1] = offsets[:-1] + tau + t_star
    return _PiecewiseLaw(offsets, pieces, key_step, seg_key, seg, node_s, node_t)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A path with a time law: ``q(t) = path.q(s(t))``, rest-to-rest.

    Attributes:
        path: the geometric path (unchanged).
        joint_names: joint names, length dof.
        duration: total time, s.
        max_velocity, max_acceleration: limits used, shape (dof,); rad/s (m/s), rad/s^2 (m/s^2).
        topp_duration: time-optimal (bang-bang, non-smooth) duration along the path, s.
        min_duration: fastest smooth rest-to-rest duration this module builds, s (>= topp_duration).
        rests: path parameters s where the motion comes to rest (0, corners of the path, 1).
        rest_times: the times of those rests, s (first 0, last ``duration``).
    """

    path: Any
    joint_names: list[str]
    duration: float
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    topp_duration: float
    min_duration: float
    rests: tuple[float, ...] = (0.0, 1.0)
    rest_times: tuple[float, ...] = ()
    _law: _PiecewiseLaw | None = field(repr=False, default=None)
    _law_scale: float = field(repr=False, default=1.0)

    @property
    def optimality_ratio(self) -> float:
        """``min_duration / topp_duration`` (1.0 is the non-smooth optimum; nan if stationary)."""
        if self.topp_duration <= 0.0:
            return float('nan')
        return self.min_duration / self.topp_duration

    def s_of_t(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path parameter and its time derivatives.

        Args:
            t: times, shape (M,) (or scalar), s; clipped to [0, duration].
        Returns:
            (s, sdot, sddot), each (M,); 1, 1/s, 1/s^2.
        """
        s, sd, sdd, _ = self._s_all(t)
        return s, sd, sdd

    def _s_all(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not np.all(np.isfinite(t)):
            raise LimitError('times must be finite')
        if self._law is None:  # stationary path
            one = (t >= self.duration).astype(float)
            z = np.zeros_like(t)
            return one, z, z, z
        lam = self._law_scale
        tl = np.where(t >= self.duration, self._law.duration, _clip(t, 0.0, self.duration) / lam)
        s, sd, sdd, sddd = self._law.evaluate(tl)
        return s, sd / lam, sdd / lam**2, sddd / lam**3

    def at_time(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint positions, velocities and accelerations at times ``t``.

        Args:
            t: times, shape (M,), s; clipped to [0, duration].
        Returns:
            (q, dq, ddq), each (M, dof); rad (m), rad/s (m/s), rad/s^2 (m/s^2).
        """
        s, sd, sdd = self.s_of_t(t)
        q, q1, q2 = _evaluate2(self.path, s)
        q1 = np.asarray(q1)
        return np.asarray(q), q1 * sd[:, None], q1 * sdd[:, None] + np.asarray(q2) * (sd**2)[:, None]

    def jerk_at_time(self, t: Any) -> np.ndarray:
        """Joint jerk d3q/dt3 at times ``t`` (M,) -> (M, dof); rad/s^3 (m/s^3)."""
        s, sd, sdd, sddd = self._s_all(t)
        _, q1, q2, q3 = self.path.evaluate(s)
        return (np.asarray(q1) * sddd[:, None] + 3.0 * np.asarray(q2) * (sd * sdd)[:, None]
                + np.asarray(q3) * (sd**3)[:, None])

    def times(self, dt: float) -> np.ndarray:
        """Sample times 0, dt, 2 dt, ..., duration (last exactly at duration), s."""
        try:
            dt = float(dt)
        except (TypeError, ValueError) as err:
            raise LimitError(f'dt must be a number, got {dt!r}') from err
        if not (math.isfinite(dt) and dt > 0.0):
            raise LimitError(f'dt must be positive and finite, got {dt!r}')
        T = self.duration
        if T <= 0.0:
            return np.zeros(1)
        n = int(math.floor(T / dt + 1e-9))
        t = np.arange(n + 1, dtype=float) * dt
        if T - t[-1] <= max(1e-9, 1e-6 * dt):
            t[-1] = T
            if t.size > 1 and t[-1] <= t[-2]:
                t = t[:-1]
                t[-1] = T
        else:
            t = np.append(t, T)
        return t

    def sample(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Uniform samples in time.

        Args:
            dt: time step, s (> 0).
        Returns:
            (t, q, dq, ddq): t (M,) from 0 to duration inclusive, the last sample exactly at
            ``duration`` (so the last step may be shorter than dt); the others (M, dof).
        Raises:
            LimitError: dt not positive and finite.
        """
        t = self.times(dt)
        q, dq, ddq = self.at_time(t)
        return t, q, dq, ddq

    def max_limit_ratios(self, samples: int = 4001) -> tuple[float, float]:
        """Largest |dq|/vmax and |ddq|/amax over ``samples`` uniform times (diagnostic)."""
        t = np.linspace(0.0, self.duration, max(int(samples), 2))
        _, dq, ddq = self.at_time(t)
        return (float(np.max(np.abs(dq) / self.max_velocity)),
                float(np.max(np.abs(ddq) / self.max_acceleration)))


def _at_path_parameter(law: _PiecewiseLaw, t_grid: np.ndarray, s_grid: np.ndarray,
                       targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sdot and sddot when the (monotone) law passes the path parameters ``targets``."""
    j = _clip(np.searchsorted(s_grid, targets), 1, s_grid.size - 1)
    s0, s1 = s_grid[j - 1], s_grid[j]
    w = np.where(s1 > s0, (targets - s0) / np.where(s1 > s0, s1 - s0, 1.0), 0.0)
    t = t_grid[j - 1] + w * (t_grid[j] - t_grid[j - 1])
    for _ in range(4):  # Newton on s(t) = target
        s, sd, _, _ = law.evaluate(t, jerk=False)
        step = np.where(sd > 0, (s - targets) / np.where(sd > 0, sd, 1.0), 0.0)
        t = _clip(t - step, t_grid[j - 1], t_grid[j])
    _, sd, sdd, _ = law.evaluate(t, jerk=False)
    return sd, sdd


def time_parameterize(path: PathLike, max_velocity: Any = None, max_acceleration: Any = None,
                      duration: float | None = None, *, grid_points: int = 100, refine: int = 2,
                      smoothing: float = 0.05, check_samples: int | None = None) -> Trajectory:
    """Fastest smooth rest-to-rest time law along ``path`` within joint limits.

    The path is evaluated once, at ``grid_points + 1`` uniform values of s plus its breakpoints
    (``path.breakpoints`` when present: both one-sided derivatives are read there; where q'
    jumps, i.e. at a corner, the motion comes to rest). Between the nodes, q' and q'' are
    interpolated (cubic Hermite with the exact q'' and q''' as slopes) for the time-optimal pass and
    the dense limit check; the returned trajectory itself evaluates the path exactly.

    Args:
        path: object with ``evaluate(s) -> (q, q', q'', q''')`` (each (len(s), dof), w.r.t. s in
            [0, 1]), ``joint_names`` and ``robot`` (``robot.max_velocity`` and
            ``robot.max_acceleration`` (dof,) are the default limits).
        max_velocity: per-joint limit (dof,) or scalar, rad/s (m/s for prismatic); None: robot's.
        max_acceleration: per-joint limit (dof,) or scalar, rad/s^2 (m/s^2); None: robot's.
        duration: if given, the law is stretched uniformly to exactly this duration, s.
        grid_points: number of uniform s intervals at which the path is evaluated.
        refine: the time-optimal (TOPP) pass runs on ``refine`` times finer steps, with q' and q''
            interpolated in between (no further path evaluations).
        smoothing: acceleration-ramp time of the smoothing as a fraction of the TOPP duration,
            in (0, 1]; the smooth law lasts about ``(1 + smoothing) * topp_duration``.
        check_samples: time samples of the dense limit check (default max(4000, 20 nodes)).
    Returns:
        A :class:`Trajectory`; zero velocity and acceleration at both ends, within the limits.
    Raises:
        LimitError: invalid limits (the message names the joint), duration shorter than the
            minimum (the message gives it), or a path that cannot be traversed.
    """
    grid_points = int(grid_points)
    if grid_points < 2:
        raise LimitError(f'grid_points must be >= 2, got {grid_points}')
    if int(refine) < 1:
        raise LimitError(f'refine must be >= 1, got {refine}')
    if not (0.0 < float(smoothing) <= 1.0):
        raise LimitError(f'smoothing must be in (0, 1], got {smoothing!r}')
    if duration is not None:
        try:
            duration = float(duration)
        except (TypeError, ValueError) as err:
            raise LimitError(f'duration must be a number, got {duration!r}') from err
        if not (math.isfinite(duration) and duration >= 0.0):
            raise LimitError(f'duration must be finite and >= 0, got {duration!r}')
    ps = _refine_adaptively(path, _sample_path(path, grid_points))
    dof = ps.aR.shape[1]
    joint_names = [str(n) for n in getattr(path, 'joint_names', [])]
    if len(joint_names) != dof:
        joint_names = joint_names or [f'joint{i + 1}' for i in range(dof)]
        if len(joint_names) != dof:
            raise LimitError(f'path has {len(joint_names)} joint names but {dof} joints')
    robot = getattr(path, 'robot', None)
    vmax = _limits(max_velocity, getattr(robot, 'max_velocity', None), dof, joint_names, 'max_velocity')
    amax = _limits(max_acceleration, getattr(robot, 'max_acceleration', None), dof, joint_names,
                   'max_acceleration')

    if float(max(np.abs(ps.aR).max(), np.abs(ps.aL).max())) == 0.0:
        # Stationary path: nothing moves; any duration (default 0) is feasible.
        T = 0.0 if duration is None else duration
        return Trajectory(path=path, joint_names=joint_names, duration=T, max_velocity=vmax,
                          max_acceleration=amax, topp_duration=0.0, min_duration=0.0,
                          rest_times=(0.0, float(T)))

    fine = ps.refined(int(refine))
    x = _topp(fine, vmax * (1.0 - TOPP_MARGIN), amax * (1.0 - TOPP_MARGIN))
    law = _build_piecewise_law(fine.s, x, float(smoothing))

    # Dense check of the smoothed law against the full limits; stretch time if needed.
    m = int(check_samples) if check_samples is not None else max(4000, 20 * ps.s.size)
    t_chk = np.linspace(0.0, law.duration, max(m, 10))
    if law.n_pieces > 1:
        t_chk = np.union1d(t_chk, law.t_offsets)
    # Also samples about uniform in s: a long law can cross a stretch of the path in a fraction
    # of its duration, where samples uniform in t are sparse. All in order of time (two sorted
    # runs: a cheap stable sort), hence of s, for the interpolation.
    t_chk = np.concatenate([t_chk, law.times_at(np.linspace(0.0, 1.0, S_UNIFORM_CHECKS))])
    t_chk = t_chk[np.argsort(t_chk, kind='stable')]
    t_chk = t_chk[np.concatenate([[True], t_chk[1:] > t_chk[:-1]])]  # distinct samples
    s, sd, sdd, _ = law.evaluate(t_chk, jerk=False)
    a, b = ps.interpolate_t(s)
    vel = a * sd
    np.abs(vel, out=vel)
    vel /= vmax[:, None]
    rv_t = vel.max(axis=0)
    a *= sdd
    b *= sd * sd
    a += b
    np.abs(a, out=a)
    a /= amax[:, None]
    ra_t = a.max(axis=0)
    rv, ra = float(rv_t.max()), float(ra_t.max())
    # The samples closest to a limit are verified with the exact path derivatives.
    need = np.maximum(rv_t, np.sqrt(ra_t))
    k = max(1, min(EXACT_CHECKS, need.size))
    top = np.argpartition(need, -k)[-k:]
    _, a_x, b_x = (np.asarray(v, dtype=float) for v in _evaluate2(path, s[top]))
    rv = max(rv, float(np.max(np.abs(a_x * sd[top, None]) / vmax)))
    ra = max(ra, float(np.max(np.abs(a_x * sdd[top, None] + b_x * (sd[top] ** 2)[:, None]) / amax)))
    # At breakpoints q'' (or q') may jump: check both one-sided values at the exact crossing time.
    # (Rests at corners need no check: sdot = sddot = 0 there.)
    inner = np.flatnonzero(((ps.aL != ps.aR).any(axis=1) | (ps.bL != ps.bR).any(axis=1)) & ~ps.stop)
    if inner.size:
        sd_b, sdd_b = _at_path_parameter(law, t_chk, s, ps.s[inner])
        for aa, bb in ((ps.aL[inner], ps.bL[inner]), (ps.aR[inner], ps.bR[inner])):
            rv = max(rv, float(np.max(np.abs(aa * sd_b[:, None]) / vmax)))
            ra = max(ra, float(np.max(np.abs(aa * sdd_b[:, None] + bb * (sd_b**2)[:, None]) / amax)))
    target = 1.0 - CHECK_MARGIN
    lam = max(1.0, rv / target, math.sqrt(ra / target))
    t_min = lam * law.duration
    if duration is None:
        T = t_min
    else:
        if duration < t_min * (1.0 - 1e-12):
            raise LimitError(
                f'duration {duration:.6g} s is shorter than the minimum {t_min:.6g} s for these limits')
        T = duration
    rests = law.rests
    scale = float(T / law.duration)
    rest_times = tuple(float(t) * scale for t in law.t_offsets[:-1]) + (float(T),)
    return Trajectory(path=path, joint_names=joint_names, duration=float(T), max_velocity=vmax,
                      max_acceleration=amax, topp_duration=law.t_star, min_duration=float(t_min),
                      rests=rests, rest_times=rest_times, _law=law, _law_scale=scale)


__all__ = ['CHECK_MARGIN', 'CORNER_TOLERANCE', 'TOPP_MARGIN', 'Trajectory', 'time_parameterize']
