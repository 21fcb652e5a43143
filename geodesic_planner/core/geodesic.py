"""The geodesic equations of the metric and their analytic Jacobians (docs/maths.md#geodesic-equations).

For the pull-back metric ``G = Jᵀ Ω J (+ ε I)`` the geodesic equations (paper eq. 3-4) read

    G(q) q'' = − Jᵀ Ω H(q, q'),       H(q, v) = Σ_jk ∂²f/∂q_j∂q_k v_j v_k,

so no Christoffel symbols are formed. :class:`GeodesicEquations` evaluates ``q''`` and, for the
collocation solver, its exact derivatives ``∂q''/∂q`` and ``∂q''/∂q'`` (third derivatives of the
pose from products of spatial generators, see kinematics.py), batched over many configurations.
"""
from __future__ import annotations

import functools
import threading
import time
import warnings
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from . import compiled
from .cancel import checkpoint
from .chunks import in_chunks
from .errors import BVPError, SingularMetricError
from .kinematics import Chain, taylor3
from .metric import Metric
from .path import JointPath, check_order, check_s
from .polynomials import Interpolant, QuinticHermite


class PathEquations(Protocol):
    """What a :class:`GeodesicPath` needs of its equations: q'' = a(q, q') and q'''."""

    robot: Chain
    metric: Metric

    def acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray: ...
    def jerk(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...


#: Blocks of kinematics remembered (:meth:`GeodesicEquations._generators`): 8 blocks of CHUNK rows.
GENERATOR_CACHE = 8


class GeodesicEquations:
    """Right-hand side ``q'' = a(q, q')`` of the geodesic equations and its Jacobians.

    Args:
        robot: the chain.
        metric: the metric (weights, ε).
    """

    def __init__(self, robot: Chain, metric: Metric) -> None:
        self.robot = robot
        self.metric = metric
        self._mask = metric.mask
        self._eps_eye = metric.epsilon * np.eye(robot.dof)
        self._local = threading.local()  # per-thread caches: planners may be shared by threads

    @property
    def _cache(self) -> dict[bytes, tuple[np.ndarray, np.ndarray]]:
        return self._local.__dict__.setdefault('gen', {})

    @property
    def _acc_cache(self) -> dict[bytes, np.ndarray]:
        return self._local.__dict__.setdefault('acc', {})

    def _generators(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """robot.generators(q), remembering the last few blocks (solve_bvp evaluates the
        right-hand side and its Jacobian at the same points, both in blocks of CHUNK rows)."""
        key = q.tobytes()
        hit = self._cache.get(key)
        if hit is not None:
            return hit
        out = self.robot.generators(q)
        if len(self._cache) >= GENERATOR_CACHE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[key] = out
        return out

    def tensor(self, q: np.ndarray) -> np.ndarray:
        """Metric tensor G at q (N, dof) -> (N, dof, dof), sharing the kinematics cache."""
        return self.metric.tensor_from_generators(*self._generators(np.ascontiguousarray(q, dtype=float)))

    def _solve(self, G: np.ndarray, rhs: np.ndarray, q: np.ndarray) -> np.ndarray:
        try:
            return np.linalg.solve(G, rhs)
        except np.linalg.LinAlgError:
            self.metric.check_regular(self.robot, q, 'a point of the path')
            raise SingularMetricError(
                f'metric {self.metric.describe()} is numerically singular along the path '
                f'for robot {self.robot.name!r}') from None

    def acceleration(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Geodesic acceleration q'' for q, v of shape (N, dof) -> (N, dof); the last few results are
        remembered by value (solve_bvp evaluates the same points again after its line search)."""
        q = np.ascontiguousarray(q, dtype=float)
        v = np.ascontiguousarray(v, dtype=float)
        key = q.tobytes() + v.tobytes()
        hit = self._acc_cache.get(key)
        if hit is None:     # compiled, or numpy where G is not positive definite (it names a singular metric)
            hit = compiled.geodesic_acceleration(*self._generators(q), v, self._mask, self.metric.epsilon) \
                if compiled.active() else None
            hit = self.evaluate(q, v, jacobians=False)[0] if hit is None else hit
            if len(self._acc_cache) >= 8:
                self._acc_cache.pop(next(iter(self._acc_cache)))
            self._acc_cache[key] = hit
        return hit.copy()

    def _terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, ...]:
        """Shared terms of the equations at (q, v), each batched over N configurations.

        Returns:
            (q, X, T, Y, YΩ, G, W, C): q as a contiguous float array; the spatial generators X
            and tool pose T; ``Y_k = ∂T/∂q_k = X_k T`` and Y weighted by Ω; the metric G;
            ``W_k = X_k v_k`` and its running sum C over the joints.
        """
        q = np.ascontiguousarray(q, dtype=float)
        X, T = self._generators(q)
        Y = X @ T[:, None]
        YO = Y * self._mask
        G = np.einsum('nixy,njxy->nij', YO, Y) + self._eps_eye
        W = X * v[..., None, None]
        return q, X, T, Y, YO, G, W, np.cumsum(W, axis=1)

    @staticmethod
    def _velocity_columns(X: np.ndarray, T: np.ndarray, C: np.ndarray) -> np.ndarray:
        """Jdot columns ``D_k = Σ_j ∂²T/∂q_j∂q_k v_j = (C_k X_k + X_k (C_n − C_k)) T``, (N, dof, 4, 4)."""
        return (C @ X + X @ (C[:, -1:] - C)) @ T[:, None]

    def jerk(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Geodesic acceleration q'' and its s-derivative q''' at (q, q'), without full Jacobians.

        Differentiating ``G a + Jᵀ Ω H = 0`` along the path gives
        ``G q‴ = −(⟨D_k, f''⟩_Ω + ⟨Y_k, 3 Σ_j D_j a_j + T₃⟩_Ω)`` with ``Y_k = ∂T/∂q_k``,
        ``D_k = Σ_j ∂²T/∂q_j∂q_k v_j``, ``f'' = Σ_k Y_k a_k + H`` and ``T₃`` the third derivative
        of the pose along v (Taylor coefficients of the product of joint exponentials). The same
        value as ``∂a/∂q q' + ∂a/∂q' q''`` from :meth:`evaluate`, at a fraction of its cost.

        Takes q, v (N, dof), w.r.t. s; returns (a, dddq): q'' and q''' w.r.t. s, each (N, dof),
        compiled, or numpy where G is not positive definite (it raises SingularMetricError).
        """
        q, v = np.ascontiguousarray(q, dtype=float), np.asarray(v, dtype=float)
        hit = compiled.geodesic_jerk(*self._generators(q), v, self._mask, self.metric.epsilon) \
            if compiled.active() else None
        return in_chunks(self._jerk, q, v) if hit is None else hit

    def _jerk(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q, X, T, Y, YO, G, W, C = self._terms(q, v)
        # Taylor coefficients c1, c2, c3 of e^{W_1 t} ... e^{W_n t} (pose derivatives d! c_d T).
        _, c2, c3 = taylor3(W)
        H = 2.0 * c2 @ T
        T3 = 6.0 * c3 @ T
        a = self._solve(G, -np.einsum('nixy,nxy->ni', YO, H)[..., None], q)[..., 0]
        D = self._velocity_columns(X, T, C)
        Da = np.einsum('nkxy,nk->nxy', D, a)
        R4 = np.einsum('nkxy,nk->nxy', Y, a) + H
        rhs = (np.einsum('nkxy,nxy->nk', D, R4 * self._mask)
               + np.einsum('nkxy,nxy->nk', YO, 3.0 * Da + T3))
        return a, self._solve(G, -rhs[..., None], q)[..., 0]

    def evaluate(self, q: np.ndarray, v: np.ndarray, jacobians: bool = True
                 ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        """Acceleration and (optionally) its Jacobians.

        Args:
            q, v: joint positions and velocities w.r.t. s, shape (N, dof).
            jacobians: also return ∂a/∂q and ∂a/∂v.
        Returns:
            (a, da_dq, da_dv): a (N, dof); da_dq, da_dv (N, dof, dof) with [i, j] = ∂a_i/∂(q|v)_j.
        Raises:
            SingularMetricError: G is singular at one of the configurations.
        """
        return in_chunks(functools.partial(self._evaluate, jacobians=jacobians),
                         np.ascontiguousarray(q, dtype=float), np.asarray(v, dtype=float))

    def _evaluate(self, q: np.ndarray, v: np.ndarray, jacobians: bool
                  ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
        q, X, T, Y, YO, G, W, C = self._terms(q, v)
        Tn = T[:, None]
        P = C - W                                    # Σ_{j<k} W_j
        Wtot = C[:, -1:]
        terms = (W + 2.0 * P) @ W
        Scum = np.cumsum(terms, axis=1)
        S_all = Scum[:, -1]
        H = S_all @ T                                # Σ_jk ∂²T v_j v_k
        b = np.einsum('nixy,nxy->ni', YO, H)
        if not jacobians:
            a = self._solve(G, -b[..., None], q)[..., 0]
            return a, None, None
        D = self._velocity_columns(X, T, C)
        JtOD = np.einsum('nixy,nkxy->nik', YO, D)
        # One factorisation-free batched solve for a and ∂a/∂v.
        sol = self._solve(G, np.concatenate([-b[..., None], -2.0 * JtOD], axis=-1), q)
        a = sol[..., 0]
        da_dv = sol[..., 1:]
        # ∂a/∂q_m from ∂/∂q_m [G a + b] = 0.
        A = X * a[..., None, None]
        PA = np.cumsum(A, axis=1) - A
        Atot = PA[:, -1:] + A[:, -1:]
        dJa = (PA @ X + X @ (Atot - PA)) @ Tn        # (∂J/∂q_m) a
        S_lt = Scum - terms
        cross = 2.0 * P @ X @ (Wtot - P)
        S_ge = S_all[:, None] - S_lt - 2.0 * P @ (Wtot - P)
        dH = (S_lt @ X + X @ S_ge + cross) @ Tn      # ∂H/∂q_m
        R4 = np.einsum('nkxy,nk->nxy', Y, a) + H     # f'' = J a + H
        Q = np.swapaxes(X, -1, -2) @ (R4 * self._mask)[:, None]
        Nmat = np.einsum('nmxy,nkxy->nmk', Q, Y)     # <X_m X_k T, r>_Ω (valid for m <= k)
        U = np.triu(Nmat)
        M = U + np.swapaxes(U, -1, -2) - np.einsum('nii->ni', Nmat)[..., None] * np.eye(self.robot.dof)
        rhs = M + np.einsum('nkxy,nmxy->nkm', YO, dJa + dH)
        da_dq = -self._solve(G, rhs, q)
        return a, da_dq, da_dv


# ---------------------------------------------------------------------- boundary-value solver
@dataclass(frozen=True)
class SolverReport:
    """Diagnostics of a geodesic solve.

    Attributes:
        status: scipy ``solve_bvp`` status (0 = converged).
        message: what the solver said.
        iterations: Newton iterations of the collocation solver (0 when the pulled-back
            task-space geodesic was verified without one).
        max_residual: largest relative residual of the geodesic equations: solve_bvp's
            rms_residuals (method 'collocation') or the path's at its interval midpoints
            (method 'pullback').
        mesh_size: number of mesh nodes of the solution.
        time_ms: wall time of the whole plan (IK, initial guess, solve), ms.
        bc_residual: largest boundary-condition error, rad or m.
        method: 'pullback' (the task-space geodesic pulled back by IK at the mesh, verified) or
            'collocation' (solve_bvp).
        path_error: estimated largest distance in the metric (m) between the returned path and
            the exact geodesic between mesh nodes (method 'pullback'; NaN otherwise).
    """

    status: int
    message: str
    iterations: int
    max_residual: float
    mesh_size: int
    time_ms: float = 0.0
    bc_residual: float = 0.0
    method: str = 'collocation'
    path_error: float = float('nan')

    @property
    def success(self) -> bool:
        """True when the collocation converged."""
        return self.status == 0

    def as_dict(self) -> dict[str, object]:
        """JSON-friendly dict."""
        return {'status': self.status, 'message': self.message, 'iterations': self.iterations,
                'max_residual': self.max_residual, 'mesh_size': self.mesh_size,
                'time_ms': self.time_ms, 'bc_residual': self.bc_residual, 'method': self.method,
                'path_error': self.path_error}


def solve_geodesic_bvp(
    equations: GeodesicEquations,
    q_a: np.ndarray,
    q_b: np.ndarray,
    s_nodes: np.ndarray,
    q_guess: np.ndarray,
    v_guess: np.ndarray,
    *,
    tol: float = 1e-8,
    max_nodes: int = 2000,
    time_limit: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, SolverReport]:
    """Solve the geodesic two-point BVP q(0) = q_a, q(1) = q_b with scipy's solve_bvp.

    Args:
        q_a, q_b: boundary joint positions (dof,).
        s_nodes: initial mesh (m,) from 0 to 1.
        q_guess, v_guess: initial guess of q and q' at the nodes, (m, dof).
        tol: solve_bvp's relative collocation tolerance.
        max_nodes: mesh size limit.
        time_limit: wall-clock budget in s (None: unbounded); checked at every evaluation.
    Returns:
        (s, q, q', q'', report) at the solution's mesh (q'' = the equations' value at the nodes).
    Raises:
        BVPError: no convergence (status, message and residual in the error).
        SingularMetricError: the metric is singular along the way.
    """
    n = equations.robot.dof
    eye = np.eye(n)
    deadline = None if time_limit is None else time.perf_counter() + time_limit

    def check_time() -> None:
        checkpoint()
        if deadline is not None and time.perf_counter() > deadline:
            raise _TimeLimitError

    def fun(_s: np.ndarray, y: np.ndarray) -> np.ndarray:
        check_time()
        a = equations.acceleration(y[:n].T, y[n:].T)
        return np.vstack([y[n:], a.T])

    def fun_jac(_s: np.ndarray, y: np.ndarray) -> np.ndarray:
        check_time()
        _, da_dq, da_dv = equations.evaluate(y[:n].T, y[n:].T)
        assert da_dq is not None and da_dv is not None   # jacobians=True returns both
        m = y.shape[1]
        df = np.zeros((2 * n, 2 * n, m))
        df[:n, n:] = eye[..., None]
        df[n:, :n] = np.moveaxis(da_dq, 0, -1)
        df[n:, n:] = np.moveaxis(da_dv, 0, -1)
        return df

    def bc(ya: np.ndarray, yb: np.ndarray) -> np.ndarray:
        return np.concatenate([ya[:n] - q_a, yb[:n] - q_b])

    dbc_a = np.zeros((2 * n, 2 * n))
    dbc_a[:n, :n] = eye
    dbc_b = np.zeros((2 * n, 2 * n))
    dbc_b[n:, :n] = eye

    def bc_jac(_ya: np.ndarray, _yb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return dbc_a, dbc_b

    y0 = np.vstack([q_guess.T, v_guess.T])
    try:
        with warnings.catch_warnings(), np.errstate(all='ignore'):
            warnings.simplefilter('ignore')
            from scipy.integrate import solve_bvp   # on first use: 0.3 s less start-up where nothing is planned
            sol = solve_bvp(fun, bc, s_nodes, y0, fun_jac=fun_jac, bc_jac=bc_jac, tol=tol,
                            max_nodes=max_nodes, bc_tol=1e-10)
    except SingularMetricError as err:
        raise BVPError(f'geodesic solver diverged for robot {equations.robot.name!r} (its iterates '
                       f'reached a configuration where the metric is singular): {err}', status=-1) from err
    except _TimeLimitError:
        raise BVPError(f'geodesic solver exceeded its time limit of {time_limit:g} s for robot '
                       f'{equations.robot.name!r}', status=-2) from None
    except (ValueError, np.linalg.LinAlgError, FloatingPointError, ZeroDivisionError) as err:
        raise BVPError(f'geodesic solver failed for robot {equations.robot.name!r}: {err}',
                       status=-1) from err
    rms = sol.rms_residuals
    max_res = float(np.max(rms)) if rms is not None and rms.size else float('nan')
    if sol.status != 0 or not np.all(np.isfinite(sol.y)):
        cond = np.linalg.cond(equations.metric.tensor(equations.robot, np.stack([q_a, q_b]))).max()
        hint = f'; the metric is ill-conditioned at the ends (condition number {cond:.2g}): near a singularity' \
            if cond > 1e6 else ''
        raise BVPError(
            f'geodesic solver did not converge for robot {equations.robot.name!r} '
            f'(solve_bvp status {sol.status}: {sol.message}; max residual {max_res:.3g}, '
            f'{sol.x.size} nodes, {sol.niter} iterations){hint}', status=int(sol.status), max_residual=max_res)
    q = sol.y[:n].T
    bc_res = float(max(np.abs(q[0] - q_a).max(), np.abs(q[-1] - q_b).max()))
    report = SolverReport(int(sol.status), str(sol.message), int(sol.niter), max_res, int(sol.x.size),
                          bc_residual=bc_res)
    return sol.x, q, sol.y[n:].T, sol.yp[n:].T, report


class _TimeLimitError(Exception):
    """Internal: the solver's wall-clock budget ran out."""


class GeodesicPath(JointPath):
    """A solved geodesic: q(s) on s ∈ [0, 1] through the collocation mesh.

    Positions and first derivatives come from a C² quintic Hermite spline through the mesh
    (values, q' and the geodesic acceleration at the nodes); ``ddq`` and ``dddq`` are the geodesic
    equations' own: ``q'' = a(q, q')`` and ``q''' = ∂a/∂q q' + ∂a/∂q' q''``.

    Attributes:
        robot, metric: the model and metric the path is a geodesic of.
        s_nodes, q_nodes, v_nodes: the solution mesh (m,), (m, dof), (m, dof).
        solver: SolverReport.
        ik_start, ik_goal: IK solutions used for the ends (None if joints were given).
    """

    def __init__(self, equations: PathEquations, s_nodes: np.ndarray, q_nodes: np.ndarray,
                 v_nodes: np.ndarray, solver: SolverReport,
                 ik_start: object | None = None, ik_goal: object | None = None,
                 a_nodes: np.ndarray | None = None, spline: Interpolant | None = None) -> None:
        self.equations = equations
        self.robot = equations.robot
        self.metric = equations.metric
        self.s_nodes, self.q_nodes, self.v_nodes = s_nodes, q_nodes, v_nodes
        self.a_nodes = equations.acceleration(q_nodes, v_nodes) if a_nodes is None else a_nodes
        self._spline = QuinticHermite(s_nodes, q_nodes, v_nodes, self.a_nodes) if spline is None else spline
        self.solver = solver
        self.ik_start = ik_start
        self.ik_goal = ik_goal

    @functools.cached_property
    def length(self) -> float:
        """Metric length = the constant metric speed over s ∈ [0, 1] (mean over the mesh)."""
        return float(np.mean(self.metric.speed(self.robot, self.q_nodes, self.v_nodes)))

    @property
    def q_start(self) -> np.ndarray:
        """Joint positions at s = 0 (the start boundary condition)."""
        return self.q_nodes[0].copy()

    @property
    def q_goal(self) -> np.ndarray:
        """Joint positions at s = 1 (the goal boundary condition)."""
        return self.q_nodes[-1].copy()

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q and its first three s-derivatives at s (1-D in [0, 1]); each (len(s), dof).

        ``order`` < 3 returns only the first ``order + 1`` arrays.
        """
        s = check_s(s)
        order = check_order(order)
        q, dq = self._spline(s, order=1)
        if order <= 1:
            return (q, dq)[:order + 1]
        if order == 2:
            return q, dq, self.equations.acceleration(q, dq)
        a, dddq = self.equations.jerk(q, dq)
        return q, dq, a, dddq

    def interpolate(self, s: np.ndarray) -> tuple[np.ndarray, ...]:
        """q and its first three s-derivatives from the solution's spline (see
        :meth:`JointPath.interpolate`)."""
        return tuple(self._spline(check_s(s), order=3))

    def metric_speed(self, s: np.ndarray) -> np.ndarray:
        """sqrt(q'ᵀ G q') at s: constant (= length) along an exact geodesic."""
        q, dq = self.evaluate(s, order=1)
        return self.metric.speed(self.robot, q, dq)

    def residual(self, s: np.ndarray) -> np.ndarray:
        """Geodesic-equation residual ‖G q'' + Jᵀ Ω H(q, q')‖ with q'' from the spline, (len(s),).

        Uses the spline's own second derivative, so it measures how far the interpolated path is
        from satisfying the equations (not zero by construction).
        """
        s = check_s(s)
        q, dq, ddq = self._spline(s, order=2)
        a = self.equations.acceleration(q, dq)
        G = self.metric.tensor(self.robot, q)
        return np.linalg.norm(np.einsum('nij,nj->ni', G, ddq - a), axis=-1)


def collocation_rms(equations: GeodesicEquations, s: np.ndarray, q: np.ndarray, v: np.ndarray,
                    a: np.ndarray) -> np.ndarray:
    """RMS relative residual per mesh interval of the cubic collocation interpolant of (q, v).

    The same estimate scipy's solve_bvp uses to accept a mesh (5-point Lobatto quadrature of
    ``|S' − f(S)| / (1 + |f|)``, S the cubic Hermite interpolant of y = (q, q') with slopes
    f = (q', q'')), so a mesh that passes here on an exact geodesic passes in solve_bvp in one round.

    Args:
        s: mesh (m,); q, v, a: positions, q', q'' at the mesh, (m, dof).
    Returns:
        (m - 1,) rms residuals.
    """
    h = np.diff(s)[:, None]
    y = np.hstack([q, v])
    f = np.hstack([v, a])
    y0, y1, f0, f1 = y[:-1], y[1:], f[:-1], f[1:]
    offsets = (0.5, 0.5 + 0.5 * np.sqrt(3.0 / 7.0), 0.5 - 0.5 * np.sqrt(3.0 / 7.0))
    ys, dys = [], []
    for t in offsets:
        h00, h10, h01, h11 = 2 * t**3 - 3 * t**2 + 1, t**3 - 2 * t**2 + t, -2 * t**3 + 3 * t**2, t**3 - t**2
        d00, d10, d01, d11 = 6 * t**2 - 6 * t, 3 * t**2 - 4 * t + 1, -6 * t**2 + 6 * t, 3 * t**2 - 2 * t
        ys.append(h00 * y0 + h10 * h * f0 + h01 * y1 + h11 * h * f1)
        dys.append((d00 * y0 + d01 * y1) / h + d10 * f0 + d11 * f1)
    Y = np.vstack(ys)
    n = q.shape[1]
    F = np.hstack([Y[:, n:], equations.acceleration(Y[:, :n], Y[:, n:])])
    R = (np.vstack(dys) - F) / (1.0 + np.abs(F))
    r2 = np.sum(R * R, axis=1).reshape(3, -1)
    return np.sqrt(0.5 * (32.0 / 45.0 * r2[0] + 49.0 / 90.0 * (r2[1] + r2[2])))

def interpolation_error(equations: GeodesicEquations, s: np.ndarray, q: np.ndarray, v: np.ndarray,
                        a: np.ndarray, spline: QuinticHermite | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Error of the quintic Hermite path through exact geodesic nodes, per mesh interval.

    Between exact nodes (q, q', q'' = a) the spline's error is e(t) ≈ c (t (t − h))³ with its
    largest value at the midpoint, where ``e = h²/24 · (S''(mid) − a(S, S'))``: the spline's
    own second derivative against the geodesic equations there. The error is measured in the
    metric, ``sqrt(eᵀ G e)`` (m), i.e. as tool-pose distance for the paper's metric.

    Args:
        s: mesh (m,); q, v, a: exact positions, q', q'' at the mesh, (m, dof).
        spline: ``QuinticHermite(s, q, v, a)`` if already built.
    Returns:
        (path_error (m - 1,) in m, relative residual (m - 1,) ‖S'' − a‖∞ / (1 + ‖a‖∞) at the midpoints).
    """
    h = np.diff(s)
    mid = s[:-1] + 0.5 * h
    qm, vm, am_spline = (QuinticHermite(s, q, v, a) if spline is None else spline)(mid, order=2)
    am = equations.acceleration(qm, vm)
    diff = am_spline - am
    e = (h * h / 24.0)[:, None] * diff
    G = equations.tensor(qm)
    err = np.sqrt(np.maximum(np.einsum('ni,nij,nj->n', e, G, e), 0.0))
    res = np.abs(diff).max(axis=1) / (1.0 + np.abs(am).max(axis=1))
    return err, res
