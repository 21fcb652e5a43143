"""Time-optimal path parameterization (TOPP-RA-like, Pham & Pham 2018) on sampled path derivatives.

The squared path speed ``x = sdot^2`` is computed by a backward pass (largest ``x`` from which the
end can still be reached at rest) and a greedy forward pass (largest admissible ``sddot``), subject
to ``|q'(s) sdot| <= vmax`` and ``|q'(s) sddot + q''(s) sdot^2| <= amax`` per joint, and to further
velocity rows given as a cap on ``x`` per node (the tool speed rows of :mod:`.tool`). ``sddot`` is
constant per step, so the optimal law ``s*(t)`` is piecewise quadratic in time. Where q' jumps (a
corner between the pieces of a piecewise geodesic) the profile is forced to rest.

Both passes are min-of-affine recursions. Each is solved first in closed form, with one
(iteratively chosen) constraint row per step, and accepted only when every step satisfies the
recursion over all rows to 1e-12; otherwise a plain loop over all rows gives the exact recursion.
On 200 random polynomial paths the closed form was refused in about 1 of 7 forward passes (and
on a few backward passes), so the loop is needed; guessing rows to shorten the loop would save
only about 4 % of those cases, so there is no third way. With the compiled kernels
(:mod:`.kernels`) the rows and both passes run in C, always by the exact recursion (microseconds);
this numpy code is their fallback and reference.
"""
from __future__ import annotations

import functools

import numpy as np

from ..core.cancel import checkpoint
from ..core.errors import LimitError
from . import kernels
from ._arrays import row_min
from .sampling import PathSamples

#: Cap on sdot^2 (1/s^2) where a path segment does not move any joint.
_X_CAP = 1e12


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


def _backward_closed(A: np.ndarray, B: np.ndarray, static: np.ndarray) -> np.ndarray | None:
    """The backward pass, vectorised: hi (n + 1,), or None when the closed form is not accepted.

    With one row per step, ``h_k = min(static_k, a_k h_{k+1} + b_k)`` (a_k > 0, h_n = 0) has a
    closed form: with ``L_k = sum_{i<k} log a_i`` and ``E_i = e^{L_i} b_i``,
    ``h_k = e^{-L_k} min_{m >= k} (e^{L_m} static_m + sum_{i=k}^{m-1} E_i)`` (static_n = 0); the
    partial sums are differences of prefix sums, or of suffix sums, whichever cancels less. Starting
    from the rows lowest at the solution for a = 1 (a cumulative minimum), it is solved again with
    the rows lowest at the previous solution. It is accepted when every step satisfies the recursion over all rows to
    ``_CLOSED_FORM_RTOL`` (exactly where it is zero: the rests); otherwise None.
    """
    n = static.size
    steps = np.arange(n)
    st = np.append(static, 0.0)
    with np.errstate(all='ignore'):
        # First guess: the rows lowest at the solution for a_k = 1 and the rows lowest at h = 0.
        C = np.zeros(n + 1)
        np.cumsum(row_min(B), out=C[1:])
        h0 = np.minimum.accumulate((st + C)[::-1])[::-1] - C
        g = np.argmin(A * h0[1:, None] + B, axis=1)
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
                return h
            if bool((act == g).all()):
                break
            g = act
    return None


def _forward_closed(alpha: np.ndarray, d: np.ndarray, two_h: np.ndarray, hi: np.ndarray
                    ) -> np.ndarray | None:
    """The forward pass, vectorised: x (n + 1,), or None, as :func:`_backward_closed`.

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
        np.cumsum(two_h * row_min(d), out=C[1:])
        x_1 = C + np.minimum.accumulate(top - C)
        g = np.argmin(alpha * x_1[:-1, None] + d, axis=1)
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
                return x
            if bool((act == g).all()):
                break
            g = act
    return None


def _backward_pass(A: np.ndarray, B: np.ndarray, static: np.ndarray) -> np.ndarray:
    """hi_k = min(static_k, min_j A_kj hi_{k+1} + B_kj) for k = n-1 .. 0, hi_n = 0; (n + 1,).

    In closed form (:func:`_backward_closed`) when it is accepted, else by a loop over all rows
    on plain floats (the exact recursion).
    """
    closed = _backward_closed(A, B, static)
    if closed is not None:
        return closed
    n = static.size
    st, A_l, B_l = static.tolist(), A.tolist(), B.tolist()
    hi = [0.0] * (n + 1)
    h = 0.0
    for k in range(n - 1, -1, -1):
        h = min([st[k]] + [ak * h + bk for ak, bk in zip(A_l[k], B_l[k])])
        hi[k] = h
    return np.array(hi)


def _forward_pass(alpha: np.ndarray, d: np.ndarray, two_h: np.ndarray, hi_np: np.ndarray) -> np.ndarray:
    """Greedy forward pass x_{k+1} = clip(x_k + 2 h_k u_k, 0, hi_{k+1}), x_0 = 0; (n + 1,).

    ``u_k = min((hi_{k+1} - x_k) / (2 h_k), min_j alpha_kj x_k + d_kj)``; in closed form
    (:func:`_forward_closed`) when it is accepted, else by a loop over all rows.
    """
    closed = _forward_closed(alpha, d, two_h, hi_np)
    if closed is not None:
        return closed
    n = two_h.size
    th, hi1_l = two_h.tolist(), hi_np[1:].tolist()
    al_l, d_l = alpha.tolist(), d.tolist()
    x = [0.0] * (n + 1)
    xk = 0.0
    for k in range(n):
        u = min([(hi1_l[k] - xk) / th[k]] + [ak * xk + dk for ak, dk in zip(al_l[k], d_l[k])])
        xk = min(max(xk + th[k] * u, 0.0), hi1_l[k])
        x[k + 1] = xk
    return np.array(x)


@functools.lru_cache(maxsize=16)
def _pairs(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j), i < j, of ``rows`` rows."""
    return np.triu_indices(rows, 1)


def topp(ps: PathSamples, vmax: np.ndarray, amax: np.ndarray, x_max: np.ndarray | None = None
         ) -> np.ndarray:
    """Time-optimal x = sdot^2 at the nodes (rest at both ends and at corners), TOPP-RA-like.

    Interpolation discretization: on step k, ``u_k`` (sddot) is constant and the acceleration
    constraints hold at both ends of the step, at s_k with x_k and at s_{k+1} with
    x_{k+1} = x_k + 2 h_k u_k; this keeps the profile honest near zero-inertia points (a joint
    turning round, q' = 0).

    Args:
        ps: path derivatives at the nodes.
        vmax, amax: limits, shape (dof,).
        x_max: further velocity rows as a cap on x = sdot^2 at each node, (n+1,), 1/s^2 (the
            tool speed rows, :meth:`~.tool.ToolRows.speed_cap`); None: joints only.
    Returns:
        x, shape (n+1,), zero at both ends and at corners.
    Raises:
        LimitError: the path cannot be traversed (zero speed forced over a whole step).
    """
    checkpoint()
    n = ps.s.size - 1
    # the same rows and passes compiled (kernels.topp), or in numpy
    out = kernels.topp(ps.kernel_rows, vmax, amax, x_max) if kernels.active() else _numpy_profile(
        ps, vmax, amax, x_max)
    out[n] = 0.0
    stuck = (out[:-1] <= 0.0) & (out[1:] <= 0.0)
    if np.any(stuck):
        k = int(np.argmax(stuck))
        raise LimitError(f'path cannot be traversed under the limits: speed forced to zero at s = {ps.s[k]:.6g}')
    return out


def _numpy_profile(ps: PathSamples, vmax: np.ndarray, amax: np.ndarray, x_max: np.ndarray | None) -> np.ndarray:
    """The rows and both passes of :func:`topp` in numpy: x (n + 1,) before its last node is zeroed."""
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
            xv = row_min((vmax / absa_n) ** 2)
            alpha = -rb / ra
            d = rl / absa
            c = -d
            xz = xv[:-1]  # no row with ra = 0: a neutral bound
        else:
            xv = row_min(np.where(mov_v, (vmax / np.where(mov_v, absa_n, 1.0)) ** 2, np.inf))
            absb = np.abs(rb)
            # Rows with ra = 0: |rb| x <= rl.
            xz = row_min(np.where(~moving & (absb > 0), rl / np.where(absb > 0, absb, 1.0), np.inf))
            # Bounds on u: alpha x + c <= u <= alpha x + d.
            alpha = np.where(moving, -rb / np.where(moving, ra, 1.0), 0.0)
            c = np.where(moving, -rl / np.where(moving, absa, 1.0), -np.inf)
            d = np.where(moving, rl / np.where(moving, absa, 1.0), np.inf)
        if x_max is not None:
            xv = np.minimum(xv, x_max)
        # Pairs (lower j, upper m): (alpha_j - alpha_m) x <= d_m - c_j = d_m + d_j (c = -d); each
        # unordered pair once, with |alpha_j - alpha_m| (a row that does not move has d = inf).
        iu, ju = _pairs(ra.shape[1])
        dT, alT = d.T.copy(), alpha.T.copy()
        xp = np.minimum.reduce((dT[iu] + dT[ju]) / np.abs(alT[iu] - alT[ju]), axis=0)
        # Lower bound u >= -x / (2 h) (x_{k+1} >= 0) against the upper bounds.
        coef = -1.0 / (2.0 * dl) - alpha
        lo_ok = moving & (coef > 0)
        xl = row_min(np.where(lo_ok, d / np.where(lo_ok, coef, 1.0), np.inf))
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
    return _forward_pass(alpha, d, 2.0 * dl[:, 0], hi)


__all__ = ['topp']
