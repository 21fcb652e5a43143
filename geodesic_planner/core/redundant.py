"""Arms with more than 6 joints: the tool exactly on line + slerp, the least joint motion.

docs/maths.md#redundant-arms. Among the joint paths whose tool follows the task geodesic exactly,
``fk(q(s)) = X(s)`` (straight line + slerp, linear in s), the planner returns the one of least
joint-space energy ``E = ∫₀¹ |q'(s)|² ds`` from the start joints: to the goal joints when they are
given, otherwise to the goal configuration (on the goal pose's self-motion manifold) that makes E
smallest. It is the ε → 0 limit of the geodesics of ``G + ε I``.

Euler-Lagrange: ``q'' = Jᵀ μ`` (no acceleration in the null space of the 6 x dof geometric
Jacobian J, base frame, rows [v; ω]); with the constraint twice differentiated, ``J q'' + J̇ q' = 0``
(the tool's twist ``V = J q'`` is constant along line + slerp), the path obeys

    q'' = a(q, q') = −J⁺ J̇ q',       J⁺ = Jᵀ (J Jᵀ)⁻¹,

and every solution keeps ``J q'`` constant. A free goal adds the transversality condition
``Nᵀ q'(1) = 0`` (N a basis of the null space of J there): no self-motion speed at the end.
:class:`RedundantEquations` evaluates a and its s-derivative analytically (generator products, as
in kinematics.py); redundant_solve.py solves for the path.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from . import compiled
from .kinematics import Chain, taylor3
from .metric import Metric
from .transforms import line_slerp, so3_log


def _vee(M: np.ndarray) -> np.ndarray:
    return np.stack([M[..., 2, 1], M[..., 0, 2], M[..., 1, 0]], axis=-1)


def skew_vee(M: np.ndarray) -> np.ndarray:
    """vee of the skew part of 3x3 matrices (..., 3, 3) -> (..., 3)."""
    return 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                           M[..., 1, 0] - M[..., 0, 1]], axis=-1)


def _point(S: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Translation part of S @ T for 4x4 batches (..., 4, 4) -> (..., 3)."""
    return (S[..., :3, :3] @ T[..., :3, 3:])[..., 0] + S[..., :3, 3]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross products of 3-vectors (..., 3) (np.cross without its overhead)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def solve6(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched solve of (N, 6, 6) systems with (N, 6) right-hand sides."""
    return np.linalg.solve(A, b[..., None])[..., 0]


class RedundantEquations:
    """The equation q'' = a(q, q') = −J⁺ J̇ q' of the least-motion path and its s-derivative.

    Args:
        robot: the chain (more than 6 joints; the formulas hold for 6 as well).
        metric: the paper's metric the path reports (``epsilon`` 0: its speed is constant).
    """

    def __init__(self, robot: Chain, metric: Metric) -> None:
        self.robot = robot
        self.metric = metric

    @staticmethod
    def jacobian(X: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Geometric Jacobian (N, 6, dof) from ``robot.generators`` (base frame, rows [v; ω])."""
        v = (X[..., :3, :3] @ T[:, None, :3, 3:])[..., 0] + X[..., :3, 3]
        return np.concatenate([v, _vee(X[..., :3, :3])], axis=-1).transpose(0, 2, 1)

    @staticmethod
    def rate(X: np.ndarray, T: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Directional derivative ``dJ[u] = Σ_j ∂J/∂q_j u_j`` of the geometric Jacobian.

        Joint k's spatial twist ξ_k = (ω_k, v_k) (``robot.generators``: ``X_k = [[ω_k^, v_k], [0, 0]]``)
        turns with the joints before it: ``dξ_k = [Σ_{j<k} ξ_j u_j, ξ_k]`` (Lie bracket
        ``[(a, b), (ω, v)] = (a × ω, a × v − ω × b)``), and J's velocity row is ``ω_k × p + v_k``
        with ``dp = J_v u``. X (..., dof, 4, 4) and T (..., 4, 4) broadcast with u (..., dof)
        -> (..., 6, dof). Compiled (:mod:`.compiled`) when the kernels are on.
        """
        if compiled.active():
            return compiled.jacobian_rate(X, T, u)
        Wm = X * u[..., None, None]
        C = np.cumsum(Wm, axis=-3)
        P = (C - Wm)[..., :3, :]                               # [hat(Σ_{j<k} ω_j u_j), Σ_{j<k} v_j u_j]
        total = C[..., -1:, :3, :]
        p = T[..., None, :3, 3:]
        dw = P[..., :3] @ _vee(X[..., :3, :3])[..., None]
        dp = total[..., :3] @ p + total[..., 3:]
        dv = (P[..., :3] @ X[..., :3, 3:] - X[..., :3, :3] @ P[..., 3:] + X[..., :3, :3] @ dp
              + cross(dw[..., 0], p[..., 0])[..., None])
        return np.swapaxes(np.concatenate([dv, dw], axis=-2)[..., 0], -1, -2)

    @staticmethod
    def velocity_term(X: np.ndarray, T: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``J̇ q' = dJ[v] v`` (N, 6): with ``S T = Σ_jk ∂²T/∂q_j∂q_k v_j v_k`` the velocity row is
        ``(S T)_p`` and the angular row ``vee(skew(S_R))``."""
        W = X * v[..., None, None]
        P = np.cumsum(W, axis=1) - W
        S = np.sum((W + 2.0 * P) @ W, axis=1)
        return np.concatenate([_point(S, T), skew_vee(S[:, :3, :3])], axis=-1)

    def terms(self, q: np.ndarray, v: np.ndarray, X: np.ndarray | None = None, T: np.ndarray | None = None
              ) -> tuple[np.ndarray, ...]:
        """X, T (``robot.generators``, computed unless given), J, J Jᵀ and μ = −(J Jᵀ)⁻¹ J̇ q'
        (q'' = Jᵀ μ) at q, v (N, dof)."""
        if X is None or T is None:
            X, T = self.robot.generators(np.ascontiguousarray(q, dtype=float))
        J = self.jacobian(X, T)
        A = J @ J.transpose(0, 2, 1)
        return X, T, J, A, -solve6(A, self.velocity_term(X, T, v))

    def acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """q'' = −J⁺ J̇ q' for q, v of shape (N, dof) -> (N, dof)."""
        _, _, J, _, mu = self.terms(q, np.asarray(v, dtype=float))
        return np.einsum('nki,nk->ni', J, mu)

    def jerk(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """q'' and q''' at (q, q'), each (N, dof).

        From ``d/ds (J q'' + J̇ q') = 0``: ``J q''' = r = −(2 J̇ q'' + dJ[q''] q' + d²J[q', q'] q')``,
        and from ``q'' = Jᵀ μ``: the null-space part of q''' is that of ``J̇ᵀ μ``. The third-order
        term comes from the Taylor coefficients c1, c2, c3 of the product of joint exponentials
        along q' (``p''' = (6 c3 T)_p``, ``(ω'')^ = skew(6 c3 − 2 c2 c1)`` for the rotation blocks).
        """
        v = np.asarray(v, dtype=float)
        X, T = self.robot.generators(np.ascontiguousarray(q, dtype=float))
        J = self.jacobian(X, T)
        A = J @ J.transpose(0, 2, 1)
        W = X * v[..., None, None]
        c1, c2, c3 = taylor3(W)
        # J̇ q' from c2 (the second-order term is 2 c2 T), then q'' = Jᵀ μ.
        mu = -solve6(A, np.concatenate([_point(2.0 * c2, T), skew_vee(2.0 * c2[:, :3, :3])], axis=-1))
        a = np.einsum('nki,nk->ni', J, mu)
        rot3 = 6.0 * c3[:, :3, :3] - 2.0 * c2[:, :3, :3] @ c1[:, :3, :3]
        third = np.concatenate([_point(6.0 * c3, T), skew_vee(rot3)], axis=-1)
        Jd = self.rate(X, T, v)
        w = _vee(X[..., :3, :3])
        aw = w * a[..., None]
        Pa = np.cumsum(aw, axis=1) - aw
        dJa_v = np.concatenate([np.einsum('nik,nk->ni', Jd[:, :3], a),      # the Hessian of p is symmetric
                                np.sum(cross(Pa, w * v[..., None]), axis=1)], axis=-1)
        r = -(2.0 * np.einsum('nik,nk->ni', Jd, a) + dJa_v + third)
        g = np.einsum('nki,nk->ni', Jd, mu)                                 # J̇ᵀ μ
        rhs = r - np.einsum('nik,nk->ni', J, g)
        return a, g + np.einsum('nki,nk->ni', J, solve6(A, rhs))


@dataclass(frozen=True)
class LineTask:
    """The task geodesic from T_a to T_b: poses ``line_slerp(T_a, T_b, s)`` and constant twist V.

    Attributes:
        T_a, T_b: 4x4 end poses (base frame, m); w_body: ``so3_log(R_aᵀ R_b)``, rad.
    """

    T_a: np.ndarray
    T_b: np.ndarray
    w_body: np.ndarray

    @functools.cached_property
    def twist(self) -> np.ndarray:
        """V = (p_b − p_a, R_a w_body) = J q' along the line (base frame, rows [v; ω]), (6,)."""
        return np.concatenate([self.T_b[:3, 3] - self.T_a[:3, 3], self.T_a[:3, :3] @ self.w_body])

    def poses(self, s: np.ndarray) -> np.ndarray:
        """Poses X(s) (N, 4, 4) at s (N,)."""
        return line_slerp(self.T_a, self.T_b, s, self.w_body)

    @classmethod
    def between(cls, T_a: np.ndarray, T_b: np.ndarray) -> LineTask:
        """The task geodesic between two 4x4 poses."""
        return cls(T_a, T_b, so3_log(T_a[:3, :3].T @ T_b[:3, :3]))


def pose_residual(T: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Task error (N, 6) of poses T against targets (N, 4, 4): position (m) and the rotation vector
    of ``R* Rᵀ`` to first order (rad), base frame."""
    M = targets[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
    return np.concatenate([targets[:, :3, 3] - T[:, :3, 3], skew_vee(M)], axis=-1)
