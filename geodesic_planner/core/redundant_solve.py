"""The least-motion path of a redundant arm (redundant.py), solved and verified.

1. :func:`solve_nodes`: the path at Chebyshev-Lobatto nodes s_j = (1 − cos(πj/m))/2, where the
   derivatives of the polynomial through the nodes are exact matrix products (spectral accuracy).
   Newton iterations move every free node by a minimal-norm step ``J⁺ e`` onto its pose (no motion
   along its self-motion manifold) plus a null-space step ``N α`` that solves the linearised
   discrete Euler-Lagrange equations ``Nᵀ q''(s_j) = 0`` (and ``Nᵀ q'(1) = 0`` at a free goal),
   the turning of N with q included, so they converge quadratically. m grows until the last
   Chebyshev coefficients (the truncation error) are below a tenth of the tolerance.
2. :func:`redundant_path`: the nodes are put exactly on their poses, and the path is the
   polynomial through them (:class:`ChebyshevPolynomial`: q and q' anywhere, exact at the nodes;
   q'' and q''' from the equation, as for every GeodesicPath). It is checked at every interval's
   midpoint, where the interpolation error peaks (:func:`midpoint_error`: the tool's pose by
   forward kinematics against line + slerp, and the residual of the equation).
3. :func:`plan_redundant`: the planner's entry (free goal first, then the IK's goal).
"""
from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable

import numpy as np

from .cancel import checkpoint
from .continuation import LineFollow
from .errors import BVPError, LimitError
from .geodesic import GeodesicPath, SolverReport
from .ik import IKSolution
from .kinematics import Chain
from .redundant import LineTask, RedundantEquations, pose_residual, skew_vee, solve6

#: Chebyshev intervals of the first solve, and the most a solve may use.
CHEBYSHEV_INTERVALS = 12
MAX_CHEBYSHEV_INTERVALS = 256
#: Newton iterations per solve, their convergence bound on the step (rad or m), and the largest
#: step of one iteration (longer ones are shortened).
NEWTON_ITERATIONS = 24
NEWTON_TOL = 1e-12
MAX_STEP = 0.3
#: Minimal-norm IK that puts the solved nodes on their poses: iterations, the pose error (m, rad)
#: that ends them, and the largest error a node may keep (beyond it the line is not followed).
PROJECT_ITERATIONS = 8
PROJECT_TOL = 1e-14
EXACT_NODE = 1e-12
#: Smallest singular value of J (m per rad, or per m) at the nodes; below it the solve gives up.
SINGULAR_SV = 1e-4
#: The truncation error of the Chebyshev solution is held below this fraction of the tolerance.
TAIL_FRACTION = 0.1


class _NoPathError(Exception):
    """Internal: the line cannot be followed this way (the planner falls back)."""


class _TimeUpError(Exception):
    """Internal: the solve ran out of its time budget."""


@functools.lru_cache(maxsize=16)
def _coefficient_matrix(m: int) -> np.ndarray:
    """Matrix (m + 1, m + 1): values at chebyshev(m)'s nodes -> Chebyshev coefficients."""
    j = np.arange(m + 1)
    half = np.where((j == 0) | (j == m), 0.5, 1.0)
    out = np.cos(np.pi * np.outer(j, j) / m) * half[None, :] * half[:, None] * (2.0 / m)
    out.setflags(write=False)
    return out


@functools.lru_cache(maxsize=16)
def chebyshev(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Chebyshev-Lobatto nodes s_j = (1 − cos(πj/m))/2 (m + 1,) on [0, 1], d/ds and d²/ds² matrices."""
    j = np.arange(m + 1)
    x = np.cos(np.pi * j / m)
    c = np.where((j == 0) | (j == m), 2.0, 1.0) * (-1.0) ** j
    D = np.outer(c, 1.0 / c) / (x[:, None] - x[None, :] + np.eye(m + 1))
    D -= np.diag(D.sum(axis=1))
    D *= -2.0                                              # s = (1 − x)/2
    out = ((1.0 - x) / 2.0, D, D @ D)
    for arr in out:
        arr.setflags(write=False)
    return out


def interpolation_matrix(m: int, s: np.ndarray) -> np.ndarray:
    """Matrix (len(s), m + 1): values at chebyshev(m)'s nodes -> the polynomial's values at s."""
    nodes = chebyshev(m)[0]
    w = (-1.0) ** np.arange(m + 1)
    w[[0, -1]] *= 0.5
    d = s[:, None] - nodes[None, :]
    hit = d == 0.0
    B = w / np.where(hit, 1.0, d)
    on = hit.any(axis=1)
    B[on] = hit[on]
    return B / B.sum(axis=1, keepdims=True)


def chebyshev_coefficients(m: int, Q: np.ndarray) -> np.ndarray:
    """Chebyshev coefficients (m + 1, dof) of the polynomial through Q at chebyshev(m)'s nodes."""
    return _coefficient_matrix(m) @ Q


def project(robot: Chain, q: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes q (N, dof) moved onto their poses (N, 4, 4) by minimal-norm Newton steps ``J⁺ e``.

    Returns:
        (q, X, T): the nodes and ``robot.generators`` there.
    Raises:
        _NoPathError: a node still misses its pose by more than EXACT_NODE.
    """
    q = q.copy()
    for _ in range(PROJECT_ITERATIONS + 1):
        X, T = robot.generators(q)
        e = pose_residual(T, targets)
        err = float(np.abs(e).max())
        if err <= PROJECT_TOL:
            break
        J = RedundantEquations.jacobian(X, T)
        q += np.einsum('nki,nk->ni', J, solve6(J @ J.transpose(0, 2, 1), e))
    else:
        if not err <= EXACT_NODE:
            raise _NoPathError(f'a node misses the line by {err:.3g}')
        X, T = robot.generators(q)
    return q, X, T


def null_basis(J: np.ndarray, AJ: np.ndarray) -> np.ndarray:
    """Orthonormal bases (N, dof, dof − 6) of the null spaces of J (N, 6, dof), with AJ = (J Jᵀ)⁻¹ J.

    7 joints: the largest column of the projector ``I − Jᵀ (J Jᵀ)⁻¹ J = n nᵀ``, normalised (cheaper
    than a factorisation); more joints: the last columns of a complete QR of Jᵀ.
    """
    n = J.shape[-1]
    if n == 7:
        P = np.eye(n) - np.swapaxes(J, 1, 2) @ AJ
        k = np.argmax(np.einsum('nii->ni', P), axis=1)
        col = np.take_along_axis(P, k[:, None, None], axis=2)
        return col / np.linalg.norm(col, axis=1, keepdims=True)
    return np.linalg.qr(np.swapaxes(J, 1, 2), mode='complete')[0][..., 6:]


def _newton_step(eq: RedundantEquations, Q: np.ndarray, free: np.ndarray, targets: np.ndarray, L: np.ndarray,
                 Lf: np.ndarray) -> float:
    """One Newton iteration on the free nodes of Q (in place, module docstring step 1): a minimal-norm
    step ``J⁺ e`` onto the poses plus the null-space step of the linearised rows ``Nᵀ (L Q) = 0``.
    Returns the step's size (rad or m)."""
    robot = eq.robot
    r = robot.dof - 6
    X, T = robot.generators(Q[free])
    J = eq.jacobian(X, T)
    A6 = J @ J.transpose(0, 2, 1)
    sol = np.linalg.solve(A6, np.concatenate([J, pose_residual(T, targets)[..., None]], axis=-1))
    N = null_basis(J, sol[..., :-1])
    task_step = np.einsum('fki,fk->fi', J, sol[..., -1])
    g = L @ Q + Lf @ task_step                     # q'' (q' at a free end) after the task step
    mu = np.einsum('fkn,fn->fk', sol[..., :-1], g)  # g = Jᵀ μ + N ν
    # N turns with q, by −Nᵀ dJ[δ]ᵀ μ along a step δ (up to O(ν) terms): δ = the task step t
    # (a constant term) and the null-space steps n_a (diagonal blocks of the Newton matrix).
    dirs = np.concatenate([task_step[:, None], np.swapaxes(N, 1, 2)], axis=1)       # (F, 1 + r, dof)
    turn = np.einsum('fk,fakb->fab', mu, eq.rate(X[:, None], T[:, None], dirs) @ N[:, None])
    nu = np.einsum('fnr,fn->fr', N, g) - turn[:, 0]
    A = np.einsum('fnr,gns->frgs', N, N) * Lf[:, None, :, None]
    diag = np.arange(free.size)
    A[diag, :, diag, :] -= np.swapaxes(turn[:, 1:], 1, 2)
    k = free.size * r                                 # k = 0 on 6 joints: the task step alone
    alpha = np.linalg.solve(A.reshape(k, k), -nu.reshape(k)).reshape(-1, r) if k else np.zeros((free.size, 0))
    step = max(float(np.abs(alpha).max(initial=0.0)), float(np.abs(task_step).max()))
    if not np.isfinite(step):
        raise _NoPathError('the Newton step is not finite')
    Q[free] += (task_step + np.einsum('fnr,fr->fn', N, alpha)) * min(1.0, MAX_STEP / step)
    return step


def solve_nodes(eq: RedundantEquations, task: LineTask, q_a: np.ndarray, q_b: np.ndarray, free_end: bool,
                tail_tol: float, deadline: float | None = None, max_intervals: int = MAX_CHEBYSHEV_INTERVALS,
                follow: LineFollow | None = None) -> tuple[int, np.ndarray, int, float]:
    """The least-motion path at Chebyshev-Lobatto nodes, truncation error below ``tail_tol``.

    Newton iterations (:func:`_newton_step`) on chebyshev(m)'s nodes; once the last Chebyshev
    coefficients clearly exceed what the iterations still change, m grows to the value their
    geometric decay asks for, and the iterations go on from the polynomial on the new nodes.

    Args:
        q_a: start joints (dof,); q_b: goal joints (dof,), only the initial guess of the goal when
            ``free_end`` (the goal is then chosen by transversality).
        tail_tol: bound on the last two Chebyshev coefficients, rad or m.
        max_intervals: the most Chebyshev intervals allowed (at most MAX_CHEBYSHEV_INTERVALS).
        follow: the line followed by continuation from q_a, whose samples start the iterations
            (with a fixed goal, shifted linearly in s onto it); None: the straight joint line.
    Returns:
        (m, Q, iterations, tail): Q (m + 1, dof) at chebyshev(m)'s nodes, the Newton iterations in
        all, and the last two Chebyshev coefficients' size (rad or m).
    Raises:
        _NoPathError, _TimeUpError.
    """
    max_intervals = min(max_intervals, MAX_CHEBYSHEV_INTERVALS)
    m = min(CHEBYSHEV_INTERVALS, max_intervals)
    s = chebyshev(m)[0]
    if follow is None:
        Q = q_a + s[:, None] * (q_b - q_a)
    else:
        Q = follow.seeds(s)
        if not free_end:
            Q += s[:, None] * (q_b - follow.q[-1])
    Q[0] = q_a
    if not (free_end and follow is not None):
        Q[-1] = q_b
    last = gain = np.inf
    new_mesh = True
    for it in range(1, NEWTON_ITERATIONS + 1):
        checkpoint()
        if deadline is not None and time.perf_counter() > deadline:
            raise _TimeUpError
        if new_mesh:
            s, D, D2 = chebyshev(m)
            free = np.arange(1, m + 1) if free_end else np.arange(1, m)
            targets = task.poses(s[free])
            # Rows: Euler-Lagrange Nᵀ q'' = 0 at the inner nodes, transversality Nᵀ q' = 0 at a free end.
            L = np.vstack([D2[1:m], D[m:]]) if free_end else D2[1:m]
        step = _newton_step(eq, Q, free, targets, L, L[:, free])
        # Quadratic convergence: the next step would be about gain · step², gain = step / last²
        # (kept from the previous mesh on a new one).
        if step < last < np.inf and not new_mesh:
            gain = step / last**2
        ahead = min(step, gain * step**2)
        last, new_mesh = step, False
        if ahead > 1e-4:                               # the tail means nothing yet
            continue
        c = np.abs(chebyshev_coefficients(m, Q)).max(axis=1)
        tail = float(c[-2:].max())
        if ahead <= NEWTON_TOL and tail <= tail_tol:
            return m, Q, it, tail
        if tail > tail_tol and tail > 100.0 * ahead:
            # |c_k| falls about geometrically: enough intervals for the tail to reach tail_tol.
            rate = max(np.log(max(float(c[m // 2 - 1:m // 2 + 1].max()), 1e-300) / tail) / (m - m // 2), 1e-3)
            m_next = min(int(np.clip(m + np.ceil(np.log(tail / tail_tol) / rate) + 2, m + 4, 2 * m)),
                         max(max_intervals, m + 1))
            if m_next > max_intervals:
                raise _NoPathError(f'not resolved by {m} Chebyshev intervals')
            Q = interpolation_matrix(m, chebyshev(m_next)[0]) @ Q
            m, new_mesh = m_next, True
    raise _NoPathError(f'no convergence in {NEWTON_ITERATIONS} Newton iterations (last step {last:.3g})')


def _node_data(eq: RedundantEquations, task: LineTask, m: int, q: np.ndarray, fixed_end: bool
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nodes q (m + 1, dof) of chebyshev(m) moved exactly onto their poses (the start, and a
    fixed end, kept as they are), the polynomial's q' there and q'' = a(q, q').

    Raises:
        _NoPathError: a node is (nearly) singular.
    """
    s, D, _ = chebyshev(m)
    q_in = q
    q, X, T = project(eq.robot, q, task.poses(s))
    q[0] = q_in[0]
    if fixed_end:
        q[-1] = q_in[-1]
    J = eq.jacobian(X, T)
    A = J @ J.transpose(0, 2, 1)
    low = float(np.sqrt(max(np.linalg.eigvalsh(A)[:, 0].min(), 0.0)))
    if low < SINGULAR_SV:
        raise _NoPathError(f'the path passes near a singularity (smallest singular value of J {low:.3g})')
    v = D @ q
    return q, v, -np.einsum('nki,nk->ni', J, solve6(A, eq.velocity_term(X, T, v)))


class ChebyshevPolynomial:
    """The polynomial through values at chebyshev(m)'s nodes: values and s-derivatives anywhere.

    Args:
        m: intervals; Q: values at the nodes, (m + 1, dof).
    """

    def __init__(self, m: int, Q: np.ndarray) -> None:
        self.m = m
        self._nodes, D, D2 = chebyshev(m)
        self._Q = Q
        rel = Q - Q[0]                     # relative to the start: a still path stays exactly still
        self._values = (rel, D @ rel, D2 @ rel, D @ (D2 @ rel))

    def __call__(self, xs: np.ndarray, order: int = 2) -> list[np.ndarray]:
        """Values and derivatives up to ``order`` (<= 3) at xs (k,): list of (k, dof) arrays; at a
        node, exactly its value."""
        xs = np.asarray(xs, dtype=float)
        B = interpolation_matrix(self.m, xs)
        out = [B @ values for values in self._values[:min(order, 3) + 1]]
        out[0] += self._Q[0]
        k = np.searchsorted(self._nodes, xs).clip(0, self.m)
        on = self._nodes[k] == xs
        out[0][on] = self._Q[k[on]]
        return out


def midpoint_error(eq: RedundantEquations, task: LineTask, s: np.ndarray, path: ChebyshevPolynomial
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The tool's pose error (m and rad: the larger) and the relative residual of the equation,
    ``‖P'' − a(P, P')‖∞ / (1 + ‖a‖∞)``, at the midpoints of the mesh s (m,), each (m − 1,).

    Between Chebyshev nodes the interpolation error is largest about half-way (it follows the next
    Chebyshev polynomial, whose extrema interlace the nodes).
    """
    mid = s[:-1] + 0.5 * np.diff(s)
    qm, vm, am_poly = path(mid, order=2)
    _, T, J, _, mu = eq.terms(qm, vm)
    am = np.einsum('nki,nk->ni', J, mu)
    target = task.poses(mid)
    dp = np.linalg.norm(T[:, :3, 3] - target[:, :3, 3], axis=1)
    dr = np.linalg.norm(skew_vee(T[:, :3, :3] @ np.swapaxes(target[:, :3, :3], 1, 2)), axis=1)
    return np.maximum(dp, dr), np.abs(am_poly - am).max(axis=1) / (1.0 + np.abs(am).max(axis=1))


def redundant_path(eq: RedundantEquations, task: LineTask, q_a: np.ndarray, q_b: np.ndarray, *, free_end: bool,
                   path_tolerance: float, t0: float, deadline: float | None = None, max_nodes: int = 2000,
                   ik_start: IKSolution | None = None, ik_goal: IKSolution | None = None,
                   follow: LineFollow | None = None) -> GeodesicPath:
    """The least-motion path with the tool on ``task`` (module docstring, steps 1-2).

    Args:
        q_a, q_b: start and goal joints (dof,), on task's end poses; with ``free_end`` q_b only
            seeds the goal.
        path_tolerance: m (and rad); t0: perf_counter at the plan's start (for the report);
            deadline: perf_counter time limit, or None; max_nodes: the most nodes (>= 3);
            follow: the line followed by continuation, to start the iterations from (solve_nodes).
    Raises:
        _NoPathError, _TimeUpError.
    """
    if np.array_equal(q_a, q_b) and not task.twist.any():
        m, q, iterations, tail = 2, np.repeat(q_a[None], 3, axis=0), 0, 0.0
        v = a = 0.0 * q
    else:
        m, Q, iterations, tail = solve_nodes(eq, task, q_a, q_b, free_end, TAIL_FRACTION * path_tolerance,
                                             deadline, max_nodes - 1, follow)
        q, v, a = _node_data(eq, task, m, Q, not free_end)
    s = chebyshev(m)[0]
    path = ChebyshevPolynomial(m, q)
    err, res = midpoint_error(eq, task, s, path)
    worst = max(float(err.max()), tail)
    if not worst <= path_tolerance:
        raise _NoPathError(f'the path is {worst:.3g} from the solution (tolerance {path_tolerance:g})')
    rep = SolverReport(0, f'the least-motion path with the tool on line + slerp ({iterations} Newton iterations '
                       f'on {m + 1} Chebyshev nodes)', iterations, float(res.max()), m + 1,
                       (time.perf_counter() - t0) * 1e3, 0.0, 'redundant', worst)
    # q' at the nodes: the polynomial's (its task part J q' = V to the tolerance), q'' the equation's.
    return GeodesicPath(eq, s, q, v, rep, ik_start, ik_goal, a, path)


def plan_redundant(eq: RedundantEquations, task: LineTask, q_a: np.ndarray, q_b: np.ndarray,
                   ik_a: IKSolution | None, ik_b: IKSolution | None, *, t0: float, path_tolerance: float,
                   max_nodes: int, time_limit: float | None,
                   check_limits: Callable[[GeodesicPath], None] | None,
                   seeds: LineFollow | None = None) -> GeodesicPath | None:
    """The planner's least-motion path (more than 6 joints), or None when it cannot be found.

    To a goal pose (``ik_b`` given) the goal configuration is free (transversality); if that path
    leaves the joint limits (``check_limits`` raises LimitError), the IK's goal q_b is kept instead,
    whose LimitError propagates. Each is solved from the straight joint line, or, with ``seeds``
    (the line already followed, e.g. traced by core/trace.py, where the iterations from the joint
    line wandered off near a singularity), from those.

    Raises:
        BVPError: the time limit ran out; LimitError: see above.
    """
    deadline = None if time_limit is None else time.perf_counter() + time_limit
    for free_end in (True, False) if ik_b is not None else (False,):
        try:
            path = redundant_path(eq, task, q_a, q_b, free_end=free_end, path_tolerance=path_tolerance, t0=t0,
                                  deadline=deadline, max_nodes=max_nodes, ik_start=ik_a, ik_goal=ik_b,
                                  follow=seeds)
        except (_NoPathError, np.linalg.LinAlgError):   # LinAlgError: J singular at a node
            continue
        except _TimeUpError:
            raise BVPError(f'geodesic solver exceeded its time limit of {time_limit:g} s for robot '
                           f'{eq.robot.name!r}', status=-2) from None
        if free_end and ik_b is not None:
            path.ik_goal = dataclasses.replace(ik_b, q=path.q_goal)
        try:
            if check_limits is not None:
                check_limits(path)
        except LimitError:
            if free_end:
                continue        # the IK's goal next
            raise
        return path
    return None
