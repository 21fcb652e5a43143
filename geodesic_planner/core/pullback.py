"""The line + slerp pulled back to joint space at the mesh nodes: the planner's fast route.

At the nodes of a mesh in s, batched IK (closed form where the robot has one, Gauss-Newton from
seeds, damped least squares for what it leaves) puts the tool on the line + slerp; the joint
rates are the least-squares pull-back of the line's constant task velocity. When every node is
reached exactly, on one branch, and ε = 0, this is the geodesic itself (docs/maths.md, sections 3
and 4); the planner then verifies it against the geodesic equations.
"""
from __future__ import annotations

import numpy as np

from .ik import dls_batch, gauss_newton_batch, nearest_branch
from .kinematics import Chain, embed12
from .metric import Metric
from .transforms import hat, line_slerp

#: Task-space IK residual below which the line + slerp guess counts as exactly reachable.
EXACT_GUESS_RESIDUAL = 1e-10
#: Largest distance of a mesh node's IK solution from its seed on a followed branch, rad or m
#: (the continuation's samples are at most 0.1 apart: beyond this the node left the branch).
MAX_SEED_DRIFT = 0.2


def pulled_back_line(robot: Chain, metric: Metric, q_a: np.ndarray, q_b: np.ndarray, s: np.ndarray,
                     line: tuple[np.ndarray, np.ndarray, np.ndarray], seeds: np.ndarray | None = None, *,
                     on_branch: bool = False) -> tuple[np.ndarray, np.ndarray, bool]:
    """q, q' at the mesh s (m,): the line + slerp ``line`` = (T_a, T_b, w_body) pulled back.

    Returns (q, q', exact): ``exact`` is True when the line + slerp is reached at every node and
    ε = 0. Falls back to joint-space linear interpolation (exact = False) if the pull-back jumps
    branches: a node step far beyond the joint line's, or, with ``on_branch`` (``seeds`` sampled
    from one continuous branch, e.g. the line followed by continuation), a node that left its
    seed by more than MAX_SEED_DRIFT.
    """
    q_lin = q_a + s[:, None] * (q_b - q_a)
    v_lin = np.broadcast_to(q_b - q_a, q_lin.shape).copy()
    wp = metric.position_weight
    wo = metric.effective_orientation_weight
    T_a, T_b, w_body = line
    targets = line_slerp(T_a, T_b, s, w_body)
    seeds = q_lin.copy() if seeds is None else np.array(seeds, dtype=float)
    if robot.closed_form_ik is not None:
        closed = nearest_branch(robot.closed_form_ik(targets), seeds)
        seeds = np.where(np.isnan(closed[:, :1]), seeds, closed)
    seeds[0], seeds[-1] = q_a, q_b
    # Gauss-Newton first (cheap, converges in a few steps from close seeds); damped least
    # squares for whatever it leaves (far seeds, unreachable nodes).
    q_g, res, X, T = gauss_newton_batch(robot, targets, seeds, position_weight=wp,
                                        orientation_weight=wo or 1.0, max_iterations=6,
                                        residual_tol=0.1 * EXACT_GUESS_RESIDUAL)
    if not np.all(res < EXACT_GUESS_RESIDUAL):
        q_g, res, _ = dls_batch(robot, targets, seeds, position_weight=wp,
                                orientation_weight=wo or 1.0, max_iterations=15)
        X, T = robot.generators(q_g)
    q_g[0], q_g[-1] = q_a, q_b
    if on_branch:
        jump = np.abs(q_g - seeds).max() > MAX_SEED_DRIFT
    else:
        jump = np.abs(np.diff(q_g, axis=0)).max() > 3.0 * np.abs(np.diff(q_lin, axis=0)).max() + 0.05
    if not np.all(np.isfinite(q_g)) or jump:
        return q_lin, v_lin, False
    exact = bool(np.all(res < EXACT_GUESS_RESIDUAL)) and metric.epsilon == 0.0
    # q' = least-squares pull-back of the task velocity (exact on the task geodesic).
    fdot = np.zeros((s.size, 4, 4))
    fdot[:, :3, :3] = targets[:, :3, :3] @ hat(w_body)
    fdot[:, :3, 3] = T_b[:3, 3] - T_a[:3, 3]
    wts = np.concatenate([np.full(3, wp), np.full(9, wo)])
    J = embed12(X @ T[:, None]).transpose(0, 2, 1) * wts[:, None]
    rhs = np.einsum('nki,nk->ni', J, embed12(fdot) * wts)
    A = np.einsum('nki,nkj->nij', J, J) + (metric.epsilon + 1e-12) * np.eye(robot.dof)
    v_g = np.linalg.solve(A, rhs[..., None])[..., 0]
    return q_g, v_g, exact
