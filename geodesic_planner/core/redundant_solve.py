"""The least-motion path of a redundant arm (redundant.py), solved and verified.

1. :func:`solve_nodes`: the path at Chebyshev-Lobatto nodes s_j = (1 − cos(πj/m))/2, where the
   derivatives of the polynomial through the nodes are exact matrix products (spectral accuracy).
   Newton iterations move every free node by a minimal-norm step ``J⁺ e`` onto its pose (no motion
   along its self-motion manifold) plus a null-space step ``N α`` that solves the linearised
   discrete Euler-Lagrange equations ``Nᵀ q''(s_j) = 0`` (and ``Nᵀ q'(1) = 0`` at a free goal),
   the turning of N with q included, so they converge quadratically. m grows until the last
   Chebyshev coefficients (the truncation error) are below the tolerance.
2. :func:`redundant_path`: at each node q' gets the exact task part (``J q' = V``) and q'' = a(q, q'),
   so the tool's pose, twist and its rate match line + slerp at every node. The quintic Hermite
   path through them is checked at every interval's midpoint (:func:`midpoint_error`: its
   distance from the solution, and the tool's pose error by forward kinematics);
   intervals above the tolerance are split, with the new nodes taken from the polynomial.
3. :func:`plan_redundant`: the planner's entry (free goal first, then the IK's goal).
"""
from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable

import numpy as np

from .cancel import checkpoint
from .errors import BVPError, LimitError
from .geodesic import GeodesicPath, SolverReport
from .ik import IKSolution
from .kinematics import Chain
from .polynomials import QuinticHermite, split_intervals
from .redundant import LineTask, RedundantEquations, pose_residual, skew_vee, solve6

#: Chebyshev intervals of the first solve, and the most a solve may use.
CHEBYSHEV_INTERVALS = 12
MAX_CHEBYSHEV_INTERVALS = 96
#: Newton iterations per solve, their convergence bound on the step (rad or m), and the largest
#: step of one iteration (longer ones are shortened).
NEWTON_ITERATIONS = 20
NEWTON_TOL = 1e-12
MAX_STEP = 0.3
#: Minimal-norm IK of inserted nodes: iterations, the pose error (m, rad) that ends them, and the
#: largest error a node may keep (beyond it the line cannot be followed this way).
PROJECT_ITERATIONS = 8
PROJECT_TOL = 1e-14
EXACT_NODE = 1e-12
#: Smallest singular value of J (m per rad, or per m) at the nodes; below it the solve gives up.
SINGULAR_SV = 1e-4
#: Mesh refinement rounds, and the fraction of the tolerance a refined interval aims at.
ROUNDS = 4
AIM = 0.1


class _NoPathError(Exception):
    """Internal: the line cannot be followed this way (the planner falls back)."""


class _TimeUpError(Exception):
    """Internal: the solve ran out of its time budget."""


@functools.lru_cache(maxsize=16)
def _coefficient_matrix(m: int) -> np.ndarray:
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
    dirs = np.concatenate([task_step[:, None], np.swapaxes(N, 1, 2)], axis=1).reshape(-1, robot.dof)
    rates = eq.rate(np.repeat(X, r + 1, axis=0), np.repeat(T, r + 1, axis=0), dirs)
    turn = np.einsum('fk,fakb->fab', mu, rates.reshape(-1, r + 1, 6, robot.dof) @ N[:, None])
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
                tail_tol: float, deadline: float | None = None) -> tuple[int, np.ndarray, int]:
    """The least-motion path at Chebyshev-Lobatto nodes, truncation error below ``tail_tol``.

    Newton iterations (:func:`_newton_step`) on chebyshev(m)'s nodes; once the last Chebyshev
    coefficients clearly exceed what the iterations still change, m grows to the value their
    geometric decay asks for, and the iterations go on from the polynomial on the new nodes.

    Args:
        q_a: start joints (dof,); q_b: goal joints (dof,), only the initial guess of the goal when
            ``free_end`` (the goal is then chosen by transversality).
        tail_tol: bound on the last two Chebyshev coefficients, rad or m.
    Returns:
        (m, Q, iterations): Q (m + 1, dof) at chebyshev(m)'s nodes; Newton iterations in all.
    Raises:
        _NoPathError, _TimeUpError.
    """
    m = CHEBYSHEV_INTERVALS
    Q = q_a + chebyshev(m)[0][:, None] * (q_b - q_a)
    Q[0], Q[-1] = q_a, q_b
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
        c = np.abs(chebyshev_coefficients(m, Q)).max(axis=1)
        tail = float(c[-2:].max())
        if ahead <= NEWTON_TOL and tail <= tail_tol:
            return m, Q, it
        if tail > tail_tol and tail > 100.0 * ahead:
            # |c_k| falls about geometrically: enough intervals for the tail to reach tail_tol.
            rate = max(np.log(max(float(c[m // 2 - 1:m // 2 + 1].max()), 1e-300) / tail) / (m - m // 2), 0.3)
            m_next = int(np.clip(m + np.ceil(np.log(tail / tail_tol) / rate) + 2, m + 4, 2 * m))
            if m_next > MAX_CHEBYSHEV_INTERVALS:
                raise _NoPathError(f'not resolved by {m} Chebyshev intervals')
            Q = interpolation_matrix(m, chebyshev(m_next)[0]) @ Q
            m, new_mesh = m_next, True
    raise _NoPathError(f'no convergence in {NEWTON_ITERATIONS} Newton iterations (last step {last:.3g})')


def _node_data(eq: RedundantEquations, task: LineTask, s: np.ndarray, q: np.ndarray, dq: np.ndarray,
               fixed_end: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nodes q (N, dof) at s exactly on their poses (the start, and a fixed end, kept as they
    are), q' with the exact task part (J q' = V, the null-space part of dq kept) and q'' = a(q, q')."""
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
    v = dq + np.einsum('nki,nk->ni', J, solve6(A, task.twist - np.einsum('nki,ni->nk', J, dq)))
    mu = -solve6(A, eq.velocity_term(X, T, v))
    return q, v, np.einsum('nki,nk->ni', J, mu)


def midpoint_error(eq: RedundantEquations, task: LineTask, s: np.ndarray, a: np.ndarray,
                   spline: QuinticHermite) -> tuple[np.ndarray, np.ndarray]:
    """Error of the quintic Hermite path through exact nodes, per mesh interval (s (m,), a (m, dof)).

    As in ``geodesic.interpolation_error``, the spline's deviation from the solution through the
    nodes is largest at the midpoint, ``e = h²/24 · (S''(mid) − a(S, S'))``. The error of an
    interval is the largest of: e's tool distance ``|J e|`` in the paper's metric (m), its joint
    distance ``|e|`` (rad or m), and the tool's actual pose error at the midpoint (forward
    kinematics against line + slerp: m, rad).

    Returns:
        (error (m − 1,), relative residual ‖S'' − a‖∞ / (1 + ‖a‖∞) at the midpoints (m − 1,)).
    """
    h = np.diff(s)
    mid = s[:-1] + 0.5 * h
    qm, vm, am_spline = spline(mid, order=2)
    _, T, J, _, mu = eq.terms(qm, vm)
    am = np.einsum('nki,nk->ni', J, mu)
    diff = am_spline - am
    e = (h * h / 24.0)[:, None] * diff
    Je = np.einsum('nki,ni->nk', J, e)
    wp, wo = eq.metric.position_weight, eq.metric.effective_orientation_weight
    tool = np.sqrt(wp**2 * np.sum(Je[:, :3] ** 2, axis=1) + 2.0 * wo**2 * np.sum(Je[:, 3:] ** 2, axis=1))
    target = task.poses(mid)
    dp = np.linalg.norm(T[:, :3, 3] - target[:, :3, 3], axis=1)
    dr = np.linalg.norm(skew_vee(T[:, :3, :3] @ np.swapaxes(target[:, :3, :3], 1, 2)), axis=1)
    err = np.max([tool, np.linalg.norm(e, axis=1), dp, dr], axis=0)
    return err, np.abs(diff).max(axis=1) / (1.0 + np.abs(am).max(axis=1))


def redundant_path(eq: RedundantEquations, task: LineTask, q_a: np.ndarray, q_b: np.ndarray, *, free_end: bool,
                   path_tolerance: float, max_nodes: int, t0: float, deadline: float | None = None,
                   ik_start: IKSolution | None = None, ik_goal: IKSolution | None = None) -> GeodesicPath:
    """The least-motion path with the tool on ``task`` (module docstring, steps 1-2).

    Args:
        q_a, q_b: start and goal joints (dof,), on task's end poses; with ``free_end`` q_b only
            seeds the goal.
        path_tolerance: m (and rad); max_nodes: mesh size limit; t0: perf_counter at the plan's
            start (for the report); deadline: perf_counter time limit, or None.
    Raises:
        _NoPathError, _TimeUpError.
    """
    if np.array_equal(q_a, q_b) and not task.twist.any():
        s = np.linspace(0.0, 1.0, 3)
        q = np.repeat(q_a[None], 3, axis=0)
        spline = QuinticHermite(s, q, 0.0 * q, 0.0 * q)
        rep = SolverReport(0, 'start and goal are the same configuration', 0, 0.0, 3,
                           (time.perf_counter() - t0) * 1e3, 0.0, 'redundant', 0.0)
        return GeodesicPath(eq, s, q, 0.0 * q, rep, ik_start, ik_goal, 0.0 * q, spline)
    m, Q, iterations = solve_nodes(eq, task, q_a, q_b, free_end, AIM * path_tolerance, deadline)
    s, D, _ = chebyshev(m)
    DQ = D @ Q
    q, v, a = _node_data(eq, task, s, Q, DQ, not free_end)
    for _ in range(ROUNDS):
        checkpoint()
        if deadline is not None and time.perf_counter() > deadline:
            raise _TimeUpError
        spline = QuinticHermite(s, q, v, a)
        err, res = midpoint_error(eq, task, s, a, spline)
        worst = float(err.max())
        if worst <= path_tolerance:
            rep = SolverReport(0, f'the least-motion path with the tool on line + slerp ({iterations} Newton '
                               f'iterations on {m + 1} Chebyshev nodes; verified between {s.size} nodes)',
                               iterations, float(res.max()), int(s.size), (time.perf_counter() - t0) * 1e3,
                               0.0, 'redundant', worst)
            return GeodesicPath(eq, s, q, v, rep, ik_start, ik_goal, a, spline)
        # The error scales like h^6: split each interval once into the parts it needs.
        parts = np.clip(np.ceil((err / (AIM * path_tolerance)) ** (1.0 / 6.0)), 1, 64).astype(int)
        if s.size + int(parts.sum()) - parts.size > max_nodes:
            break
        s = split_intervals(s, parts)
        B = interpolation_matrix(m, s)
        q, v, a = _node_data(eq, task, s, B @ np.vstack([q[:1], Q[1:-1], q[-1:]]), B @ DQ, True)
    raise _NoPathError(f'the path is not within {path_tolerance:g} of the solution after {ROUNDS} mesh rounds')


def plan_redundant(eq: RedundantEquations, task: LineTask, q_a: np.ndarray, q_b: np.ndarray,
                   ik_a: IKSolution | None, ik_b: IKSolution | None, *, t0: float, path_tolerance: float,
                   max_nodes: int, time_limit: float | None,
                   check_limits: Callable[[GeodesicPath], None] | None) -> GeodesicPath | None:
    """The planner's least-motion path (more than 6 joints), or None when it cannot be found.

    To a goal pose (``ik_b`` given) the goal configuration is free (transversality); if that path
    leaves the joint limits (``check_limits`` raises LimitError), the IK's goal q_b is kept instead,
    whose LimitError propagates.

    Raises:
        BVPError: the time limit ran out; LimitError: see above.
    """
    deadline = None if time_limit is None else time.perf_counter() + time_limit
    for free_end in (True, False) if ik_b is not None else (False,):
        try:
            path = redundant_path(eq, task, q_a, q_b, free_end=free_end, path_tolerance=path_tolerance,
                                  max_nodes=max_nodes, t0=t0, deadline=deadline, ik_start=ik_a, ik_goal=ik_b)
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
                continue
            raise
        return path
    return None
