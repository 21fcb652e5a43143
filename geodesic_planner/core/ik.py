"""Inverse kinematics at the path ends: damped least squares in the metric's pose embedding.

The error minimised is ``‖Ω^½ (f(q) − f*)‖`` with f = (p, n, o, a) ∈ R^12 and the metric's weights
Ω, so for arms that cannot reach every pose (fewer than 6 joints) the answer is the nearest
reachable pose in the least-squares sense of the metric, and its residual is reported. The planar
3R arm also has a closed form (elbow branch θ2 > 0 by default, paper Table 2).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .errors import IKError, RequestError
from .kinematics import Chain, embed12
from .transforms import check_transform, pose_error

#: Default allowed embedding distance between the requested pose and the nearest reachable one.
DEFAULT_IK_TOLERANCE = 1e-3
#: Residual below which a pose counts as reached exactly.
EXACT_RESIDUAL = 1e-9
#: Convergence threshold on the step size (rad or m).
STEP_TOL = 1e-13
#: A damped least-squares row stops when its cost fell by less than this fraction over the
#: last STAGNATION_WINDOW iterations (a local minimum, or the nearest reachable pose).
STAGNATION = 1e-2
STAGNATION_WINDOW = 10
#: Largest joint change of one damped least-squares step (rad or m): long steps are shortened.
DLS_MAX_STEP = 0.5
#: Newton iterations of :func:`polish`.
POLISH_ITERATIONS = 20
#: Candidates of the damped least squares that :func:`polish` tries, nearest the pose first.
POLISH_CANDIDATES = 3
#: Gauss-Newton attempt from a given seed before damped least squares: iterations, step bound (rad or m).
GN_ITERATIONS = 12
GN_MAX_STEP = 0.5


@dataclass(frozen=True)
class IKSolution:
    """Result of :func:`solve_ik`.

    Attributes:
        q: joint positions (dof,), rad or m.
        success: residual within tolerance and q within the joint limits.
        iterations: damped least-squares iterations used (all restarts); 0 when the closed form
            or Gauss-Newton from the seed reached the target exactly.
        residual: weighted embedding distance ‖Ω^½ (f(q) − f*)‖ (m-equivalent).
        position_error: distance of the reached tool position from the target, m.
        orientation_error: rotation angle between reached and target orientation, rad.
        reason: why it failed ('' on success).
    """

    q: np.ndarray
    success: bool
    iterations: int
    residual: float
    position_error: float
    orientation_error: float
    reason: str = ''


def _weights12(position_weight: float, orientation_weight: float) -> np.ndarray:
    return np.concatenate([np.full(3, position_weight), np.full(9, orientation_weight)])


def dls_batch(
    robot: Chain,
    targets: np.ndarray,
    seeds: np.ndarray,
    *,
    position_weight: float = 1.0,
    orientation_weight: float = 1.0,
    max_iterations: int = 50,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Batched Levenberg-Marquardt on the weighted embedding error.

    Each row stops on its own when it has converged or stagnates (a local minimum: less than
    STAGNATION relative decrease of its cost over STAGNATION_WINDOW iterations); only the rows
    still running are computed.

    Args:
        targets: target transforms (N, 4, 4).
        seeds: initial joints (N, dof).
    Returns:
        (q, residual, iterations): q (N, dof); residual (N,) weighted embedding distance.
    """
    w = _weights12(position_weight, orientation_weight)
    f_star = embed12(targets) * w
    q = np.array(seeds, dtype=float, copy=True)
    n = robot.dof
    lam = np.full(q.shape[0], 1e-3)
    X, T = robot.generators(q)
    e = embed12(T) * w - f_star
    cost = np.einsum('ni,ni->n', e, e)
    ref_cost = cost.copy()
    active = np.ones(q.shape[0], dtype=bool)
    eye = np.eye(n)
    it = 0
    for it in range(1, max_iterations + 1):
        checkpoint()
        i = np.flatnonzero(active)
        Xi, Ti, ei, ci, li = X[i], T[i], e[i], cost[i], lam[i]
        J = embed12(Xi @ Ti[:, None]).transpose(0, 2, 1) * w[:, None]   # (k, 12, dof)
        JtJ = J.transpose(0, 2, 1) @ J
        g = np.einsum('nki,nk->ni', J, ei)
        scale = np.einsum('nii->ni', JtJ).max(axis=1) + 1e-12
        A = JtJ + (li * scale)[:, None, None] * eye
        dq = -np.linalg.solve(A, g[..., None])[..., 0]
        dq *= np.minimum(1.0, DLS_MAX_STEP / np.maximum(np.abs(dq).max(axis=1, keepdims=True), 1e-300))
        q_new = np.minimum(np.maximum(q[i] + dq, robot.lower), robot.upper)  # stay within limits
        dq = q_new - q[i]
        X_new, T_new = robot.generators(q_new)
        e_new = embed12(T_new) * w - f_star[i]
        cost_new = np.einsum('ni,ni->n', e_new, e_new)
        better = cost_new <= ci
        q[i] = np.where(better[:, None], q_new, q[i])
        X[i] = np.where(better[:, None, None, None], X_new, Xi)
        T[i] = np.where(better[:, None, None], T_new, Ti)
        e[i] = np.where(better[:, None], e_new, ei)
        step = np.abs(dq).max(axis=1)
        cost[i] = np.where(better, cost_new, ci)
        lam[i] = np.where(better, np.maximum(li * 0.1, 1e-12), li * 10.0)
        done = (step < STEP_TOL) | (cost[i] < 1e-26) | (better & (step < 1e-10))
        if it % STAGNATION_WINDOW == 0:
            done |= cost[i] > (1.0 - STAGNATION) * ref_cost[i]
            ref_cost[i] = cost[i]
        active[i[done]] = False
        if not active.any():
            break
    return q, np.sqrt(cost), it


def gauss_newton_batch(
    robot: Chain,
    targets: np.ndarray,
    seeds: np.ndarray,
    *,
    position_weight: float = 1.0,
    orientation_weight: float = 1.0,
    max_iterations: int = 10,
    residual_tol: float = 1e-12,
    max_step: float | None = None,
    within_limits: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Batched undamped Gauss-Newton on the weighted embedding error, for seeds near a solution.

    Cheaper per iteration than :func:`dls_batch` (no trial step, no acceptance test) and
    quadratically convergent on reachable targets; meant for the mesh nodes of a path, whose
    seeds (joint interpolation, or a spline through nearby nodes) are close.

    Args:
        targets: target transforms (N, 4, 4).
        seeds: initial joints (N, dof).
        residual_tol: stop when every weighted embedding residual is below this (m).
        max_step: largest joint change per step (rad or m); longer steps are shortened (keeps a
            far seed on its own branch). None: full steps.
        within_limits: keep every iterate within the joint limits (False: let a solution beyond
            them be found, to tell where a path would cross them).
    Returns:
        (q, residual, X, T): q (N, dof); residual (N,) at q; ``robot.generators(q)`` at q.
    """
    w = np.empty((3, 4))
    w[:, :3] = orientation_weight
    w[:, 3] = position_weight
    target = targets[:, :3, :] * w
    q = np.array(seeds, dtype=float, copy=True)
    n = robot.dof
    eye = np.eye(n)
    for _ in range(max_iterations + 1):
        checkpoint()
        X, T = robot.generators(q)
        e = (T[:, :3, :] * w - target).reshape(-1, 12)
        cost = np.einsum('ni,ni->n', e, e)
        if cost.max() <= residual_tol * residual_tol or _ == max_iterations:
            break
        J = ((X @ T[:, None])[:, :, :3, :] * w).reshape(-1, n, 12)       # (N, dof, 12) = Jᵀ
        A = J @ J.transpose(0, 2, 1)
        # Regularisation relative to A's scale (the weights square into it): JJᵀ of a redundant
        # arm is singular, and a fixed 1e-14 vanishes against weights of 10 or more.
        A += (1e-12 * np.trace(A, axis1=1, axis2=2) / n + 1e-300)[:, None, None] * eye
        g = J @ e[..., None]
        dq = np.linalg.solve(A, g)[..., 0]
        if max_step is not None:
            dq *= np.minimum(1.0, max_step / np.maximum(np.abs(dq).max(axis=1, keepdims=True), 1e-300))
        q = q - dq
        if within_limits:
            q = np.minimum(np.maximum(q, robot.lower), robot.upper)
    return q, np.sqrt(cost), X, T


def _wrap_into_limits(robot: Chain, q: np.ndarray) -> np.ndarray:
    """Shift revolute joints by multiples of 2π towards their limits (the pose is unchanged)."""
    q = q.copy()
    for i, kind in enumerate(robot.joint_types):
        if kind != 'revolute':
            continue
        lo, hi = robot.lower[i], robot.upper[i]
        if np.isfinite(lo) and np.isfinite(hi) and hi - lo >= 2 * np.pi - 1e-12:
            mid = 0.5 * (lo + hi)
            q[i] = mid + (q[i] - mid + np.pi) % (2 * np.pi) - np.pi
            if q[i] > hi:
                q[i] -= 2 * np.pi
            if q[i] < lo:
                q[i] += 2 * np.pi
        elif np.isfinite(lo) and np.isfinite(hi):
            for k in (-1, 1):
                cand = q[i] + k * 2 * np.pi
                if not lo <= q[i] <= hi and lo <= cand <= hi:
                    q[i] = cand
    return q


def nearest_turn(robot: Chain, q: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Shift revolute joints of solutions ``q`` (dof,) or (N, dof), within the limits, by multiples
    of 2π (the pose is unchanged) to the value nearest ``reference`` (dof,) (the IK seed) within
    the limits.

    The short way from the seed is kept whenever the limits allow it: a wrist at 3.0 rad turned
    by +0.5 rad ends at 3.5, not at 3.5 − 2π. Joints with no such value are left as they are
    (with the reference within the limits, a turn farther than the two nearest lies outside them).
    """
    if np.abs(q - reference).max() <= np.pi:                             # already the nearest turn
        return q
    near = q + 2 * np.pi * np.round((reference - q) / (2 * np.pi))     # within π of the reference
    other = near - 2 * np.pi * np.sign(near - reference)                 # the next nearest turn
    lo, hi = robot.lower - 1e-9, robot.upper + 1e-9
    best = np.where((near >= lo) & (near <= hi), near, np.where((other >= lo) & (other <= hi), other, q))
    return np.where(robot.revolute, best, q)


def planar_3r_ik(T: np.ndarray, link_lengths: tuple[float, float, float] = (1.0, 1.0, 1.0),
                 elbow: int = 1) -> np.ndarray | None:
    """Closed-form IK of the planar 3R arm: pose in the xy plane -> (θ1, θ2, θ3), or None if unreachable.

    Args:
        T: 4x4 target; only x, y and the yaw φ = atan2(n_y, n_x) are used.
        elbow: +1 for θ2 >= 0 (paper Table 2), -1 for the other branch.
    """
    q = planar_3r_branches(np.asarray(T, dtype=float)[None], link_lengths)[0 if elbow >= 0 else 1, 0]
    return None if np.isnan(q[0]) else q


def planar_3r_branches(T: np.ndarray, link_lengths: tuple[float, float, float] = (1.0, 1.0, 1.0)
                       ) -> np.ndarray:
    """Both closed-form 3R solutions for targets (N, 4, 4) -> (2, N, 3): elbow θ2 >= 0, then θ2 <= 0.

    Only x, y and the yaw φ = atan2(n_y, n_x) are used; unreachable rows are NaN. Angles in (-π, π].
    """
    l1, l2, l3 = link_lengths
    phi = np.arctan2(T[:, 1, 0], T[:, 0, 0])
    wx = T[:, 0, 3] - l3 * np.cos(phi)
    wy = T[:, 1, 3] - l3 * np.sin(phi)
    c2 = (wx * wx + wy * wy - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    reach = np.abs(c2) <= 1.0 + 1e-12
    t2 = np.where(reach, np.arccos(np.clip(c2, -1.0, 1.0)), np.nan)
    out = np.empty((2, T.shape[0], 3))
    for b, t2b in enumerate((t2, -t2)):
        t1 = np.arctan2(wy, wx) - np.arctan2(l2 * np.sin(t2b), l1 + l2 * np.cos(t2b))
        out[b, :, 0], out[b, :, 1], out[b, :, 2] = t1, t2b, phi - t1 - t2b
    return (out + np.pi) % (2 * np.pi) - np.pi


def planar_3r_closed_form(T: np.ndarray) -> np.ndarray:
    """``Chain.closed_form_ik`` of the planar 3R preset: both branches (2, N, 3), NaN off the plane."""
    planar = (np.abs(T[:, 2, 3]) < 1e-9) & (np.abs(T[:, 2, 2] - 1.0) < 1e-9)
    out = planar_3r_branches(T)
    out[:, ~planar] = np.nan
    return out


def nearest_branch(candidates: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per row, the closed-form candidate nearest ``reference``.

    Args:
        candidates: (B, N, dof), NaN rows for no solution; reference: (N, dof).
    Returns:
        (N, dof); NaN rows where no branch exists.
    """
    d = np.abs(candidates - reference).max(axis=-1)
    d = np.where(np.isnan(d), np.inf, d)
    k = np.argmin(d, axis=0)
    return candidates[k, np.arange(candidates.shape[1])]


def _exact_solution(robot: Chain, T_target: np.ndarray, q: np.ndarray, position_weight: float,
                    orientation_weight: float, reference: np.ndarray | None = None) -> IKSolution | None:
    """``q`` as the IK solution if it reaches the target exactly within the joint limits, else None.

    With a ``reference`` (the seed), revolute joints take the turn nearest it (``nearest_turn``).
    """
    q = _wrap_into_limits(robot, q)
    if not robot.within_limits(q, 1e-9):
        return None
    if reference is not None:
        q = nearest_turn(robot, q, reference)
    T = robot.fk(q)
    w = _weights12(position_weight, orientation_weight)
    r = float(np.linalg.norm((embed12(T) - embed12(T_target)) * w))
    if r > EXACT_RESIDUAL:
        return None
    dp, dr = pose_error(T, T_target)
    return IKSolution(q, True, 0, r, float(dp), float(dr))


def polish(robot: Chain, T_target: np.ndarray, q: np.ndarray, position_weight: float = 1.0,
           orientation_weight: float = 1.0, iterations: int = POLISH_ITERATIONS) -> IKSolution | None:
    """``q`` (near a solution) moved onto ``T_target`` exactly within the joint limits, or None.

    Minimal-norm Newton steps of the geometric Jacobian on the joints that are free; a joint whose
    step would leave its limits is held at that limit (active set) and the others take up its
    part. Arms with 6 or more joints reach a pose that lies on a joint limit this way exactly,
    where damped least squares clamped at the limit stops short (within the IK tolerance).
    """
    lo, hi = robot.lower, robot.upper
    q = np.clip(np.asarray(q, dtype=float), lo, hi)
    R_t, p_t = T_target[:3, :3], T_target[:3, 3]
    for _ in range(iterations):
        T = robot.fk(q)
        M = R_t @ T[:3, :3].T
        e = np.concatenate([p_t - T[:3, 3], 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0],
                                                             M[1, 0] - M[0, 1]])])
        if np.abs(e).max() <= 1e-15:
            break
        J = robot.jacobian(q)
        free = np.ones(robot.dof, dtype=bool)
        step = np.zeros(robot.dof)
        for _ in range(robot.dof):
            step = np.zeros(robot.dof)
            step[free] = np.linalg.lstsq(J[:, free], e, rcond=None)[0]
            out = free & ((q + step < lo) | (q + step > hi))
            if not out.any():
                break
            q[out] = np.clip(q + step, lo, hi)[out]        # held at the limit it would pass
            free &= ~out
        q = np.clip(q + step, lo, hi)
    return _exact_solution(robot, T_target, q, position_weight, orientation_weight)


def solve_from_seed(robot: Chain, T_target: np.ndarray, seed: np.ndarray, position_weight: float = 1.0,
                    orientation_weight: float = 1.0) -> IKSolution | None:
    """The exact solution undamped Gauss-Newton reaches from ``seed`` (within the limits, polished
    onto a limit it passes by a hair), or None: the cheap first try of a goal on the seed's branch."""
    T_target = check_transform(T_target, 'IK target')
    seed = np.asarray(seed, dtype=float)
    q_gn, res_gn, _, _ = gauss_newton_batch(robot, T_target[None], seed[None], position_weight=position_weight,
                                            orientation_weight=orientation_weight, max_iterations=GN_ITERATIONS,
                                            residual_tol=0.1 * EXACT_RESIDUAL, max_step=GN_MAX_STEP)
    if not res_gn[0] <= EXACT_RESIDUAL:
        return None
    sol = _exact_solution(robot, T_target, q_gn[0], position_weight, orientation_weight, seed)
    if sol is None and robot.dof >= 6:
        sol = polish(robot, T_target, q_gn[0], position_weight, orientation_weight)
    return sol


def solve_ik(
    robot: Chain,
    T_target: np.ndarray,
    seed: np.ndarray | None = None,
    *,
    position_weight: float = 1.0,
    orientation_weight: float = 1.0,
    tolerance: float | None = None,
    restarts: int = 24,
    rng_seed: int = 0,
    raise_on_failure: bool = True,
) -> IKSolution:
    """Joint positions reaching ``T_target`` (or the nearest reachable pose), near ``seed``.

    Args:
        robot: the chain.
        T_target: 4x4 base->tool target.
        seed: initial joints (dof,); the robot's home when None. The branch found is the one the
            seed leads to (so seeding the goal with the start solution keeps the branch).
        tolerance: allowed weighted embedding distance between the target and the nearest
            reachable pose (default 1e-3); used for poses an arm cannot reach exactly. Arms with
            6 or more joints must reach a pose exactly (residual <= 1e-9) unless no seed does.
        restarts: extra random seeds (within limits) tried if the seed does not succeed; among
            exact solutions the one nearest to the seed is returned.
    Returns:
        IKSolution.
    Raises:
        IKError: unreachable beyond tolerance or outside joint limits (if raise_on_failure).
        RequestError: non-positive tolerance, bad seed.
    """
    if tolerance is None:
        tol = DEFAULT_IK_TOLERANCE
    elif not (np.isfinite(tolerance) and tolerance > 0):
        raise RequestError(f'IK tolerance must be a positive number, got {tolerance}')
    else:
        tol = float(tolerance)
    T_target = check_transform(T_target, 'IK target')
    q0 = np.asarray(robot.home if seed is None else robot.check_joints(seed, 'IK seed'), dtype=float)
    preferred = [q0]
    if robot.closed_form_ik is not None:
        closed = [c for c in robot.closed_form_ik(T_target[None])[:, 0] if not np.isnan(c[0])]
        if closed:
            # First branch by default (3R: θ2 > 0, paper Table 2); with a seed, the nearest to it.
            if seed is not None:
                closed.sort(key=lambda c: float(np.linalg.norm(c - q0)))
            preferred = [closed[0], q0, *closed[1:]]
            closed_sol = _exact_solution(robot, T_target, closed[0], position_weight, orientation_weight,
                                         None if seed is None else q0)
            if closed_sol is not None:
                return closed_sol
    if len(preferred) == 1:
        # Undamped Gauss-Newton with bounded steps from the seed (or home) first: cheaper than
        # damped least squares, and enough when the seed leads to an exact solution.
        q_gn, res_gn, _, _ = gauss_newton_batch(robot, T_target[None], q0[None], position_weight=position_weight,
                                                orientation_weight=orientation_weight, max_iterations=GN_ITERATIONS,
                                                residual_tol=0.1 * EXACT_RESIDUAL, max_step=GN_MAX_STEP)
        if res_gn[0] <= EXACT_RESIDUAL:
            gn_sol = _exact_solution(robot, T_target, q_gn[0], position_weight, orientation_weight, q0)
            if gn_sol is None and robot.dof >= 6:      # just outside a limit: the exact one on it
                gn_sol = polish(robot, T_target, q_gn[0], position_weight, orientation_weight)
            if gn_sol is not None:
                return gn_sol
    rng = np.random.default_rng(rng_seed)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    batches = [np.array(preferred[:1]), np.array(preferred[1:] + list(rng.uniform(lo, hi, (restarts, robot.dof))))]
    # Arms with 6 or more joints reach poses in their workspace exactly: do not stop at a local
    # minimum that merely lies within the tolerance (the tolerance is for unreachable poses).
    full_task = robot.dof >= 6
    qs: list[np.ndarray] = []
    res_l: list[float] = []
    total_it = 0
    for batch in batches:
        checkpoint()
        if batch.shape[0] == 0:
            continue
        q, res, it = dls_batch(robot, np.broadcast_to(T_target, (batch.shape[0], 4, 4)), batch,
                               position_weight=position_weight, orientation_weight=orientation_weight,
                               max_iterations=100)
        total_it += it
        qs += [_wrap_into_limits(robot, qk) for qk in q]
        res_l += [float(r) for r in res]
        ok = np.array([bool(robot.within_limits(qk, 1e-9)) for qk in qs])
        r = np.array(res_l)
        if np.any(ok & (r <= EXACT_RESIDUAL)) or (not full_task and np.any(ok & (r <= tol))):
            break
    ok = np.array([bool(robot.within_limits(qk, 1e-9)) for qk in qs])
    r = np.array(res_l)
    if full_task and not np.any(ok & (r <= EXACT_RESIDUAL)):
        # damped least squares held at a limit stops short of a pose that lies on it: polish the
        # nearest candidates onto it (active set), exactly or not at all
        for k in np.argsort(r)[:POLISH_CANDIDATES]:
            sol = polish(robot, T_target, qs[k], position_weight, orientation_weight)
            if sol is not None:
                qs[k], r[k], ok[k] = sol.q, sol.residual, True
                break
    # Solutions (within the limits and the tolerance) take the turn of each revolute joint nearest
    # the seed; failed ones keep their window, so that a joint stuck at a limit is freed when the
    # result seeds the next solve (the goal IK's continuation).
    solved = ok & (r <= tol)
    if solved.any():
        turned = nearest_turn(robot, np.array(qs), q0)
        qs = [turned[k] if solved[k] else qk for k, qk in enumerate(qs)]
    dist = np.array([float(np.linalg.norm(qk - q0)) for qk in qs])
    exact = ok & (r <= EXACT_RESIDUAL)
    within = ok & (r <= tol)
    if np.any(exact):
        k = int(np.argmin(np.where(exact, dist, np.inf)))       # the exact solution nearest the seed
    elif np.any(within):
        k = int(np.argmin(np.where(within, r, np.inf)))         # the nearest reachable pose
    elif np.any(ok):
        k = int(np.argmin(np.where(ok, r, np.inf)))
    else:
        k = int(np.argmin(r))
    success = bool(within[k])
    reason = ''
    if not ok[k]:
        reason = 'the only solutions found lie outside the joint limits'
    elif not success:
        reason = f'nearest reachable pose is {r[k]:.4g} away (tolerance {tol:.3g})'
    dp, dr = pose_error(robot.fk(qs[k]), T_target)
    best = IKSolution(qs[k], success, total_it, float(r[k]), float(dp), float(dr), reason)
    if not best.success and raise_on_failure:
        raise IKError(
            f'IK failed for robot {robot.name!r}: {best.reason}; target position '
            f'{np.round(T_target[:3, 3], 6).tolist()} m (position error {best.position_error:.4g} m, '
            f'orientation error {best.orientation_error:.4g} rad)',
            residual=best.residual, iterations=total_it)
    return best
