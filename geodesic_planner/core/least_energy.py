"""PTP of least kinetic energy: direct minimisation of the discretised action (docs/maths.md, section 10).

The path is a polynomial in s for each joint,

    q(s) = q_a + s (q_b - q_a) + sum_k phi_k(2 s - 1) c_k,   k = 1 .. K,

with ``phi_k = (P_{k+1} - P_{k-1}) / sqrt(2 (2k + 1))`` (integrated Legendre polynomials: zero at
both ends, their derivatives orthonormal), so the ends are exact and the path is smooth to every
order (each time law can differentiate it). The action ``E = int_0^1 q'^T M(q) q' ds`` is
integrated by Gauss-Legendre quadrature; its gradient is analytic: at each node the derivative of
``v^T M(q) v`` in q is ``2 C(q, v)^T v`` (C the Coriolis matrix, ``dM/ds = C + C^T``) and in v is
``2 M v``. With a constant M, ``E = dq^T M dq + 2 sum_k c_k^T M c_k``: the coefficients are scaled by
the Cholesky factor of M at the line's middle (``c_k = L^-T z_k``), which makes the Hessian nearly
the identity and L-BFGS converge in a few dozen steps.

The energy has several local minima on whole-range moves (an elbow folds one way or the other; the
geodesic equation's two-point problem also has saddles between them, where a collocation solver
can stop). Each descent starts from the joint line or from a perturbation of it
(:func:`start_directions`) on a coarse problem (:data:`COARSE_MODES` modes); the lowest is
refined on :data:`MODES` modes. A descent method ends at a local minimum unless it starts on a
saddle's stable set, which the perturbed starts leave.

Joint limits: where a descent's path nears them, SLSQP continues with the limits as linear
constraints on a grid; then the path is pulled towards the joint line (inside the limits, the box
being convex) by the least factor that keeps it inside at the polynomial's exact extrema.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import legendre as leg

from .blas import one_thread
from .cancel import checkpoint
from .errors import BVPError
from .kinematics import Chain
from .path import JointPath, check_order, check_s

__all__ = ['MODES', 'ActionProblem', 'LeastEnergyPath', 'least_energy_path', 'start_directions']

#: Modes per joint (polynomial degree K + 1), Gauss-Legendre nodes of the action's quadrature.
MODES = 10
QUADRATURE = 24
#: The same for the coarse problem every start is descended on.
COARSE_MODES = 3
COARSE_NODES = 12
#: Points of the joint-limit penalty's grid.
LIMIT_GRID = 65
#: Perturbed starts besides the joint line, and their size (times the line's metric length,
#: in the scaled coordinates of the first mode).
PERTURBED_STARTS = 4
START_SCALE = 0.35
#: Coarse results (the lowest, of different actions) refined on the full problem.
REFINED = 1
#: L-BFGS stopping rule: relative decrease of E, and projected gradient (scaled units).
FTOL = 1e-9
GTOL = 1e-4
MAX_ITERATIONS = 200
#: A joint whose path comes this close to a limit (rad or m, times 1 + its move) is kept inside
#: it on the grid by the constrained step.
LIMIT_MARGIN = 1e-3
#: A joint within this of a limit between the ends (rad or m) is reported as held by it.
TOUCH = 1e-4
#: Rounds of the constrained step (each adds the joints the last result nears).
LIMIT_ROUNDS = 3


def _legendre_basis(K: int) -> np.ndarray:
    """Legendre coefficients of phi_1 .. phi_K: (K, K + 2)."""
    out = np.zeros((K, K + 2))
    for k in range(1, K + 1):
        out[k - 1, k + 1] = 1.0
        out[k - 1, k - 1] -= 1.0
        out[k - 1] /= np.sqrt(2.0 * (2 * k + 1))
    return out


def _basis(x: np.ndarray, K: int, der: int) -> np.ndarray:
    """phi_k^(der)(x) for k = 1 .. K, d/dx: (len(x), K)."""
    coef = _legendre_basis(K).T                   # (K + 2, K): columns are the polynomials
    if der:
        coef = leg.legder(coef, der, axis=0)
    return np.asarray(leg.legval(x, coef)).T


@dataclass
class ActionProblem:
    """The discretised action of paths from q_a to q_b in the scaled coefficients z (K * dof,).

    ``terms(q, v) -> (M (m, dof, dof), dE/dq (m, dof))`` gives M(q) and the derivative of
    ``v^T M(q) v`` in q at m points. ``extra``: added costs of the coefficients C (K, dof) and of
    the quadrature and grid points (for the obstacle term of the planner around obstacles): a
    function ``C -> (value, gradient in C)``.
    """

    q_a: np.ndarray
    q_b: np.ndarray
    terms: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    lower: np.ndarray
    upper: np.ndarray
    modes: int = MODES
    nodes: int = QUADRATURE
    extra: Callable[[np.ndarray], tuple[float, np.ndarray]] | None = None
    evaluations: int = 0
    limit_weight: float = 0.0
    _cache: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        K, n = self.modes, self.q_a.size
        self.dq = self.q_b - self.q_a
        x, w = leg.leggauss(self.nodes)
        self.s, self.w = 0.5 * (x + 1.0), 0.5 * w
        self.B0, self.B1 = _basis(x, K, 0), 2.0 * _basis(x, K, 1)
        sg = np.linspace(0.0, 1.0, LIMIT_GRID)
        self.s_grid, self.G0 = sg, _basis(2.0 * sg - 1.0, K, 0)
        M_mid = self.terms((self.q_a + 0.5 * self.dq)[None], np.zeros((1, n)))[0][0]
        try:
            Lc = np.linalg.cholesky(0.5 * (M_mid + M_mid.T))
        except np.linalg.LinAlgError:
            Lc = np.diag(np.sqrt(np.maximum(np.diag(M_mid), 1e-12)))
        self.T = np.linalg.inv(Lc).T              # c_k = T z_k
        self.line_action = float(self.dq @ M_mid @ self.dq)
        self.scale = max(self.line_action, 1e-12)

    def coefficients(self, z: np.ndarray) -> np.ndarray:
        """C (K, dof) of the scaled coefficients z."""
        return z.reshape(self.modes, -1) @ self.T.T

    def value_grad(self, z: np.ndarray) -> tuple[float, np.ndarray]:
        """The action (plus penalties) and its gradient in z."""
        checkpoint()
        self.evaluations += 1
        C = self.coefficients(z)
        q = self.q_a + self.s[:, None] * self.dq + self.B0 @ C
        v = self.dq + self.B1 @ C
        M, dq_term = self.terms(q, v)
        Mv = np.einsum('pij,pj->pi', M, v)
        E = float(self.w @ np.einsum('pi,pi->p', v, Mv))
        gC = self.B0.T @ (self.w[:, None] * dq_term) + self.B1.T @ (2.0 * self.w[:, None] * Mv)
        if self.limit_weight > 0.0:
            qg = self.q_a + self.s_grid[:, None] * self.dq + self.G0 @ C
            over = np.maximum(qg - self.upper, 0.0) - np.maximum(self.lower - qg, 0.0)
            k = self.limit_weight * self.scale / LIMIT_GRID
            E += k * float(np.sum(over * over))
            gC += self.G0.T @ (2.0 * k * over)
        if self.extra is not None:
            e, g = self.extra(C)
            E += e
            gC += g
        return E, (gC @ self.T).ravel()

    def action(self, z: np.ndarray) -> float:
        """The action alone (no penalty, no extra cost)."""
        weight, extra = self.limit_weight, self.extra
        self.limit_weight, self.extra = 0.0, None
        try:
            return self.value_grad(z)[0]
        finally:
            self.limit_weight, self.extra = weight, extra

    def descend(self, z0: np.ndarray) -> tuple[np.ndarray, float, int]:
        """L-BFGS from z0: (z, value, iterations)."""
        from scipy.optimize import minimize  # on first use (start-up time)

        r = minimize(self.value_grad, z0, jac=True, method='L-BFGS-B',
                     options={'maxiter': MAX_ITERATIONS, 'ftol': FTOL, 'gtol': GTOL * np.sqrt(self.scale)})
        if not np.all(np.isfinite(r.x)) or not np.isfinite(r.fun):
            raise BVPError('kinetic_energy: the descent of the action diverged (NaN)')
        return r.x, float(r.fun), int(r.nit)


def start_directions(problem: ActionProblem, count: int = PERTURBED_STARTS) -> list[np.ndarray]:
    """Perturbed starts (scaled coordinates z): the first mode pushed along the action's gradient
    at the joint line, then against it, ... (``count`` of them), each of size ``START_SCALE`` times
    the line's metric length. The gradient direction breaks the symmetry of a move through a
    stretched arm (the two ways of folding it are then started on both sides)."""
    K, n = problem.modes, problem.q_a.size
    g = problem.value_grad(np.zeros(K * n))[1].reshape(K, n)[0]
    if not np.any(g):
        g = np.ones(n)
    d = g / np.linalg.norm(g)
    size = START_SCALE * np.sqrt(problem.scale)
    out = []
    for i in range(count):
        z = np.zeros((K, n))
        z[0] = (-1.0 if i % 2 == 0 else 1.0) * size * d * (1.0 + i // 2)
        out.append(z.ravel())
    return out


_GRID = 257


def _max_bump(coef: np.ndarray, line: tuple[float, float], lo: float, hi: float) -> float:
    """The largest lambda in [0, 1] with line + lambda * bump inside [lo, hi] on x in [-1, 1]
    (Legendre coefficients ``coef`` of the bump in x; line: its values at x = -1 and 1): from a
    dense grid, then checked (a bound on the curvature between grid points, else the exact
    extrema) and shrunk where that is not yet enough."""
    a, b = line
    lin = np.array([(a + b) / 2.0, (b - a) / 2.0])

    def ok(lam: float) -> bool:
        c = lam * coef
        c[:2] += lin
        x = leg.legroots(leg.legder(c)) if c.size > 2 else np.array([])
        x = np.concatenate([np.real(x[np.abs(np.imag(x)) < 1e-9]) if x.size else x, [-1.0, 1.0]])
        x = x[(x >= -1.0) & (x <= 1.0)]
        val = leg.legval(x, c)
        return bool(np.all(val <= hi + 1e-9) and np.all(val >= lo - 1e-9))

    x = np.linspace(-1.0, 1.0, _GRID)
    bump, base = leg.legval(x, coef), lin[0] + lin[1] * x
    with np.errstate(divide='ignore', invalid='ignore'):
        room = np.where(bump > 0.0, (hi - base) / bump, np.where(bump < 0.0, (lo - base) / bump, np.inf))
    lam = float(np.clip(np.min(room), 0.0, 1.0))
    # between grid points a polynomial exceeds its chord by at most h^2/8 max|p''|, and
    # max|P_k''| = (k - 1) k (k + 1) (k + 2) / 8 on [-1, 1]
    k = np.arange(coef.size)
    curve = (2.0 / (_GRID - 1)) ** 2 / 8.0 * float(np.sum(np.abs(coef) * (k - 1) * k * (k + 1) * (k + 2) / 8.0))
    step = 1e-9
    while lam > 1e-12:
        value = base + lam * bump
        if (np.min(hi - value) > lam * curve and np.min(value - lo) > lam * curve) or ok(lam):
            return lam
        lam *= 1.0 - step
        step = min(2.0 * step, 0.5)
    return 0.0


class LeastEnergyPath(JointPath):
    """A polynomial joint path (Legendre series in x = 2 s - 1, one per joint).

    Attributes:
        coef: Legendre coefficients (K + 2, dof). action: ``int q'^T M q' ds`` by the planner's
        quadrature. start_actions: the action each start's descent reached (the joint line first).
        iterations: L-BFGS steps of all descents. solve_ms: the solver's time. limited: joints
        whose limit binds (the path touches it).
    """

    def __init__(self, robot: Chain, coef: np.ndarray, *, action: float = float('nan'),
                 start_actions: tuple[float, ...] = (), iterations: int = 0, solve_ms: float = 0.0,
                 limited: tuple[str, ...] = ()) -> None:
        self.robot = robot
        self.coef = coef
        self._ders = [coef]
        for _ in range(3):
            self._ders.append(leg.legder(self._ders[-1]) if self._ders[-1].shape[0] > 1
                              else np.zeros_like(coef[:1]))
        self.action = action
        self.start_actions = start_actions
        self.iterations = iterations
        self.solve_ms = solve_ms
        self.limited = limited

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        s = check_s(s)
        x = 2.0 * s - 1.0
        return tuple(np.asarray(leg.legval(x, self._ders[k])).T.reshape(s.size, -1) * 2.0 ** k
                     for k in range(check_order(order) + 1))

    def deviation(self, s: np.ndarray) -> np.ndarray:
        """Zeros: a PTP has no tool geometry to keep."""
        return np.zeros(check_s(s).size)


def _path_coefficients(problem: ActionProblem, C: np.ndarray) -> np.ndarray:
    """Legendre coefficients in x (K + 2, dof) of the line plus the bumps C (K, dof)."""
    coef = _legendre_basis(problem.modes).T @ C
    coef[0] += problem.q_a + 0.5 * problem.dq
    coef[1] += 0.5 * problem.dq
    return coef


def _inside(problem: ActionProblem, C: np.ndarray) -> tuple[np.ndarray, float]:
    """C shrunk towards the joint line (the least) until the path is inside the limits: (C, lambda)."""
    basis = _legendre_basis(problem.modes).T
    lam = 1.0
    for j in range(C.shape[1]):
        if np.isfinite(problem.lower[j]) or np.isfinite(problem.upper[j]):
            lam = min(lam, _max_bump(basis @ C[:, j], (problem.q_a[j], problem.q_b[j]),
                                     problem.lower[j], problem.upper[j]))
    return lam * C, lam


@dataclass
class Descent:
    """One descent's result."""

    z: np.ndarray
    action: float
    iterations: int


def _near_limits(problem: ActionProblem, paths: list[np.ndarray]) -> set[tuple[int, float]]:
    """(joint, side) of the limits a joint comes within :data:`LIMIT_MARGIN` of on one of ``paths``."""
    line = problem.q_a + problem.s_grid[:, None] * problem.dq
    qs = [line + problem.G0 @ problem.coefficients(z) for z in paths]
    margin = LIMIT_MARGIN * (1.0 + np.abs(problem.dq))
    return {(j, sign) for j in range(problem.q_a.size)
            for sign, bound in ((1.0, problem.upper[j]), (-1.0, problem.lower[j]))
            if np.isfinite(bound) and any(np.any(sign * (q[:, j] - bound) > -margin[j]) for q in qs)}


def _limit_rows(problem: ActionProblem, near: set[tuple[int, float]]) -> tuple[np.ndarray, np.ndarray]:
    """Linear constraints A z <= b that keep the grid points inside the limits ``near``."""
    line = problem.q_a + problem.s_grid[:, None] * problem.dq
    rows, rhs = [], []
    for j, sign in sorted(near):
        bound = problem.upper[j] if sign > 0 else problem.lower[j]
        # q_gj = line_gj + sum_ki G0[g, k] T[j, i] z[k, i]
        rows.append(sign * np.einsum('gk,i->gki', problem.G0, problem.T[j]).reshape(LIMIT_GRID, -1))
        rhs.append(sign * (bound - line[:, j]))
    return np.concatenate(rows), np.concatenate(rhs)


def _feasible(problem: ActionProblem, z: np.ndarray) -> np.ndarray:
    """z pulled towards the joint line until its path is inside the limits."""
    C, _ = _inside(problem, problem.coefficients(z))
    return np.linalg.solve(problem.T, C.T).T.ravel()


def _descend_within_limits(problem: ActionProblem, z0: np.ndarray) -> tuple[np.ndarray, int]:
    """The descent from z0; where it leaves or nears the limits, SLSQP with the limits on the grid
    (of the joints that near them; again with more joints while the result nears others), from the
    lower of z0 and the descent's end, each pulled inside."""
    from scipy.optimize import minimize

    z, _, it = problem.descend(z0)
    near = _near_limits(problem, [z])
    if not near:
        return z, it
    zi = min((_feasible(problem, z), _feasible(problem, z0)), key=problem.action)
    for _ in range(LIMIT_ROUNDS):
        A, b = _limit_rows(problem, near)
        r = minimize(problem.value_grad, zi, jac=True, method='SLSQP',
                     constraints=[{'type': 'ineq', 'fun': lambda x, A=A, b=b: b - A @ x, 'jac': lambda x, A=A: -A}],
                     options={'maxiter': MAX_ITERATIONS, 'ftol': FTOL * problem.scale})
        it += int(r.nit)
        if not np.all(np.isfinite(r.x)):
            break
        inside = _feasible(problem, r.x)
        if problem.action(inside) < problem.action(zi):
            zi = inside
        more = _near_limits(problem, [r.x]) - near
        if not more:
            break
        near |= more
    return zi, it


def minimise(problem: ActionProblem, starts: list[np.ndarray]) -> tuple[Descent, list[Descent]]:
    """Descend from each start (within the limits); the lowest and all."""
    results = []
    for z0 in starts:
        z, total = _descend_within_limits(problem, z0)
        z = _feasible(problem, z)
        results.append(Descent(z, problem.action(z), total))
    return min(results, key=lambda d: d.action), results


def _distinct(runs: list[Descent], count: int) -> list[Descent]:
    """The ``count`` lowest descents of different actions (relative gap above 1e-4)."""
    out: list[Descent] = []
    for d in sorted(runs, key=lambda d: d.action):
        if all(abs(d.action - o.action) > 1e-4 * max(o.action, 1e-12) for o in out):
            out.append(d)
    return out[:count]


def _embed(coarse: ActionProblem, fine: ActionProblem, z: np.ndarray) -> np.ndarray:
    """The scaled coefficients of ``fine`` for the path ``z`` of ``coarse`` (its modes, zeros above)."""
    C = np.zeros((fine.modes, fine.q_a.size))
    C[:coarse.modes] = coarse.coefficients(z)
    return np.linalg.solve(fine.T, C.T).T.ravel()


def least_energy_path(robot: Chain, terms: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
                      q_a: np.ndarray, q_b: np.ndarray, *, modes: int = MODES,
                      perturbed: int = PERTURBED_STARTS) -> LeastEnergyPath:
    """The path of least action from q_a to q_b (dof,) inside the joint limits: every start descended
    on the coarse problem (:data:`COARSE_MODES` modes), the lowest refined on ``modes`` modes.

    Raises:
        BVPError: a descent diverged (NaN in the mass model).
    """
    t0 = time.perf_counter()
    n = robot.dof
    fine = ActionProblem(q_a, q_b, terms, robot.lower, robot.upper, modes=modes)
    if np.allclose(q_a, q_b, rtol=0.0, atol=1e-12):
        coef = _path_coefficients(fine, np.zeros((modes, n)))
        return LeastEnergyPath(robot, coef, action=0.0, start_actions=(0.0,), solve_ms=0.0)
    coarse = ActionProblem(q_a, q_b, terms, robot.lower, robot.upper, modes=COARSE_MODES, nodes=COARSE_NODES)
    with one_thread():
        starts = [np.zeros(COARSE_MODES * n)] + start_directions(coarse, perturbed)
        _, runs = minimise(coarse, starts)
        top, refined = minimise(fine, [_embed(coarse, fine, d.z) for d in _distinct(runs, REFINED)])
    C = fine.coefficients(top.z)
    coef = _path_coefficients(fine, C)
    path = LeastEnergyPath(robot, coef, action=top.action, start_actions=tuple(r.action for r in runs),
                           iterations=sum(r.iterations for r in runs + refined),
                           solve_ms=(time.perf_counter() - t0) * 1e3)
    q = path.evaluate(np.linspace(0.0, 1.0, 1025)[1:-1], 0)[0]
    touch = np.any((q >= robot.upper - TOUCH) | (q <= robot.lower + TOUCH), axis=0)
    path.limited = tuple(name for name, t in zip(robot.joint_names, touch) if t)
    return path
