"""The tool's curve followed exactly, step by step: the line route's last resort, and its refusals.

The planner's fast routes (the pull-back at a mesh, the least-motion solve of a redundant arm)
need a regular metric at the ends, one smooth branch their seeds find, and (beyond 6 joints) a
boundary-value solve that converges. Where they do not apply, :func:`trace` follows the task
curve (the line + slerp of a LIN) from the start joints with adaptive steps, and either returns
a path whose tool stays on the curve (checked by forward kinematics inside every step) or says
why and where it stops. It never returns a path off the curve.

The path is the integral curve of the resolved-rate flow, with the tool's twist ``V(s)``
prescribed by the curve (constant on a line + slerp), ``J⁺ = Jᵀ (J Jᵀ)⁻¹`` and ``P = I − J⁺ J`` the
null-space projector (zero on 6 joints):

    q' = F(q, s) = J⁺ V(s) + P g(q),       q'' = dF[q'] + ∂F/∂s   (analytic, from dJ[q']),

so ``J q' = V`` holds along it. On 6 joints this is the pulled-back line itself (the geodesic of
the paper's metric, docs/maths.md section 3), valid from a singular start where the metric cannot
be inverted. Beyond 6 joints it is the least-norm path, with ``g`` a velocity that pushes joints
away from their limits in the outer part of their range (:data:`LIMIT_MARGIN`): the line kept
inside the limits (not the least-motion path, which core/redundant_solve.py returns where its
solve converges).

Each step predicts the next node from (q, q', q''), moves it onto its pose by minimal-norm Newton
steps, projects q' onto ``J q' = V`` and evaluates q''. The step is accepted when the quintic
Hermite between the two nodes keeps the tool within ``tolerance`` of the curve (forward kinematics
at three interior points), no joint moves by more than :data:`MAX_JOINT_STEP`, the Jacobian's
smallest singular value shows no dip between the nodes (a singularity stepped over), and no joint
leaves its limits; otherwise the step is shortened. A step shorter than :data:`MIN_STEP`, a joint
rate beyond :data:`MAX_RATE`, or a limit crossed is a refusal naming the place
(:class:`~.errors.PathFollowError` and subclasses: singularity, joint limit, out of reach).
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .errors import BVPError, LineUnreachableError, PathFollowError
from .geodesic import GeodesicPath, SolverReport
from .ik import IKSolution
from .kinematics import Chain
from .limits import LIMIT_SLACK, line_limit_error
from .metric import Metric
from .polynomials import QuinticHermite
from .redundant import RedundantEquations

#: First step and largest step, fractions of the curve.
INITIAL_STEP = 1.0 / 32.0
MAX_STEP = 1.0 / 8.0
#: Smallest step before the curve is declared not followable (near a singular start the joints
#: move like the square root of s, and steps of 1e-8 of the way are needed there).
MIN_STEP = 1e-11
#: The most steps (accepted or not) of one trace: bounds its time on any input.
MAX_STEPS = 4000
#: Largest joint change in one step, rad or m, and largest Newton correction of a predicted node
#: (more: a jump to another branch; the prediction's own error is third order in the step).
MAX_JOINT_STEP = 0.5
MAX_CORRECTION = 0.05
#: Largest joint rate, rad (or m) per whole curve: beyond it the joints would have to flip (a
#: singularity on the way). A singular start reaches about 1e3.
MAX_RATE = 1e5
#: Largest relative residual of ``J q' = V`` at a node (beyond it the configuration is singular for
#: this motion: no finite joint velocity moves the tool along the curve).
VELOCITY_RESIDUAL = 1e-6
#: The tolerance is at most this fraction of the move's size (a micrometre move is followed to a
#: picometre: its shape, not only its place), and never below FLOOR_TOLERANCE (m, rad).
RELATIVE_TOLERANCE = 1e-8
FLOOR_TOLERANCE = 1e-13
#: A stop this close to either end (fraction of the curve) is named as at its start or end.
END_FRACTION = 5e-5
#: Goal joints within this distance (rad or m) of where the trace ends are taken as its end.
SNAP_END = 1e-3
#: Newton iterations putting a node on its pose, and the pose error (m, rad) that ends them.
PROJECT_ITERATIONS = 12
PROJECT_TOL = 1e-13
#: Smallest singular value of J, relative to its largest, under which a stop is a singularity.
SINGULAR_RATIO = 1e-2
#: The trace stops at a node whose smallest singular value is below this fraction of the largest
#: and falling: the curve runs into a singularity there (a start near one that it moves away from
#: is followed).
SINGULAR_STOP = 1e-5
#: A step whose midpoint's smallest singular value is below this fraction of both ends' (and
#: below SINGULAR_RATIO of the largest) stepped over a singular-value dip: it is shortened.
DIP_FRACTION = 0.5
#: Beyond 6 joints: the part of each joint's half-range, from its middle, beyond which the
#: self-motion pushes it back, and how fast at the limit (half-ranges per curve).
LIMIT_MARGIN = 0.8
LIMIT_PUSH = 4.0
#: Beyond 6 joints: corrections of a node's self-motion per step (see _advance).
CORRECTIONS = 2
#: Steps computed together (batched): accepted in order while they pass.
BATCH = 6
#: Interior points of a step where the tool is checked against the curve.
CHECK_POINTS = np.array([0.25, 0.5, 0.75])
#: Points of a step where the joints are checked against their limits.
LIMIT_POINTS = np.linspace(0.0, 1.0, 9)[1:]


@dataclass(frozen=True)
class TaskCurve:
    """A tool curve over s ∈ [0, 1]: poses, twist ``V = (p', ω)`` (base frame) and its s-derivative.

    Attributes:
        poses: s (N,) -> (N, 4, 4). twist: s (N,) -> (N, 6). twist_rate: s (N,) -> (N, 6).
        name: how a refusal names it ('the straight line', 'the arc').
    """

    poses: Callable[[np.ndarray], np.ndarray]
    twist: Callable[[np.ndarray], np.ndarray]
    twist_rate: Callable[[np.ndarray], np.ndarray]
    name: str = 'the straight line'


def line_curve(poses: Callable[[np.ndarray], np.ndarray], twist: np.ndarray) -> TaskCurve:
    """The line + slerp as a TaskCurve: ``poses`` (e.g. ``LineTask.poses``) and its constant twist (6,)."""
    V = np.asarray(twist, dtype=float)
    return TaskCurve(poses, lambda s: np.broadcast_to(V, (np.size(s), 6)),
                     lambda s: np.zeros((np.size(s), 6)))


@dataclass(frozen=True)
class _Node:
    s: float
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    sigma: float           # smallest singular value of J
    sigma_max: float


def _hermite_weights(u: np.ndarray) -> np.ndarray:
    """Quintic Hermite basis at u (k,) in [0, 1]: rows of weights of (q0, h q0', h² q0'', q1, h q1', h² q1'')."""
    u = np.asarray(u, dtype=float)[:, None]
    u2, u3, u4, u5 = u**2, u**3, u**4, u**5
    return np.hstack([1 - 10 * u3 + 15 * u4 - 6 * u5, u - 6 * u3 + 8 * u4 - 3 * u5,
                      0.5 * u2 - 1.5 * u3 + 1.5 * u4 - 0.5 * u5, 10 * u3 - 15 * u4 + 6 * u5,
                      -4 * u3 + 7 * u4 - 3 * u5, 0.5 * u3 - u4 + 0.5 * u5])


_CHECK_WEIGHTS = _hermite_weights(CHECK_POINTS)
_LIMIT_WEIGHTS = _hermite_weights(LIMIT_POINTS)


def _between(weights: np.ndarray, a: _Node, b: _Node) -> np.ndarray:
    """The quintic Hermite between nodes a and b at the points of ``weights``: (k, dof)."""
    h = b.s - a.s
    return weights @ np.stack([a.q, h * a.v, h * h * a.a, b.q, h * b.v, h * h * b.a])


class _Flow:
    """The path's equation on one robot and curve (module docstring): q' = F(q, s), q'' = dF/ds."""

    def __init__(self, robot: Chain, curve: TaskCurve, tolerance: float) -> None:
        self.robot, self.curve, self.tolerance = robot, curve, tolerance
        self.redundant = robot.dof > 6
        lo, hi = robot.lower, robot.upper
        finite = np.isfinite(lo) & np.isfinite(hi)
        self.finite = finite
        self.mid = 0.5 * (np.where(finite, lo, 0.0) + np.where(finite, hi, 0.0))
        self.half = np.where(finite, 0.5 * (np.where(finite, hi, 1.0) - np.where(finite, lo, -1.0)), 1.0)

    def push(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g(q) (rad or m per curve, away from the limits in the outer part of each range) and
        its derivative (diagonal: dg_j/dq_j)."""
        u = (q - self.mid) / self.half
        over = np.clip((np.abs(u) - LIMIT_MARGIN) / (1.0 - LIMIT_MARGIN), 0.0, None)
        g = np.where(self.finite, -np.sign(u) * LIMIT_PUSH * over**3 * self.half, 0.0)
        dg = np.where(self.finite, -3.0 * LIMIT_PUSH * over**2 / (1.0 - LIMIT_MARGIN), 0.0)
        return g, dg

    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X, T (``robot.generators``) and the geometric Jacobians at q (k, dof)."""
        X, T = self.robot.generators(q)
        return X, T, RedundantEquations.jacobian(X, T)

    def nodes(self, s: np.ndarray, q: np.ndarray, X: np.ndarray, T: np.ndarray, J: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """q' = F(q, s) = J⁺ V + P g and q'' = dF[q'] + ∂F/∂s at the rows of q (k, dof) (module
        docstring), the Jacobian's smallest and largest singular values, and whether ``J q' = V``
        holds (where V leaves J's range, at a singular configuration, no finite q' does it)."""
        sv = np.linalg.svd(J, compute_uv=False)
        V, dV = self.curve.twist(s), self.curve.twist_rate(s)
        if not self.redundant:
            # 6 joints: J square, q' = J⁻¹ V and J q'' = V' − J̇ q' (solved with J itself, whose
            # condition number is the square root of J Jᵀ's: near a singular start that matters)
            v = np.linalg.solve(J, V[..., None])[..., 0]
            a = np.linalg.solve(J, (dV - RedundantEquations.velocity_term(X, T, v))[..., None])[..., 0]
        else:
            Jt = np.swapaxes(J, 1, 2)
            A = J @ Jt
            g, dgdq = self.push(q)
            yz = np.linalg.solve(A, np.stack([V, np.einsum('kij,kj->ki', J, g)], axis=2))
            y, z = yz[..., 0], yz[..., 1]
            v = np.einsum('kji,kj->ki', J, y - z) + g
            dJ = RedundantEquations.rate(X, T, v)                  # dJ[v], (k, 6, dof)
            dg = dgdq * v
            # d(J⁺ V) = dJᵀ y + Jᵀ dy, dy = A⁻¹ (V' − (dJ Jᵀ + J dJᵀ) y); d(P g) = dg − dJᵀ z − Jᵀ dz,
            # dz = A⁻¹ (dJ g + J dg − (dJ Jᵀ + J dJᵀ) z)
            dJJ = dJ @ Jt
            sym = dJJ + np.swapaxes(dJJ, 1, 2)
            rhs = np.stack([dV - np.einsum('kij,kj->ki', sym, y),
                            np.einsum('kij,kj->ki', dJ, g) + np.einsum('kij,kj->ki', J, dg)
                            - np.einsum('kij,kj->ki', sym, z)], axis=2)
            d = np.linalg.solve(A, rhs)
            a = (np.einsum('kji,kj->ki', dJ, y - z) + np.einsum('kji,kj->ki', J, d[..., 0] - d[..., 1]) + dg)
        r = np.einsum('kij,kj->ki', J, v) - V
        ok = np.sqrt(np.sum(r * r, axis=1)) <= VELOCITY_RESIDUAL * (np.sqrt(np.sum(V * V, axis=1)) + 1e-300)
        return v, a, sv[:, -1], sv[:, 0], ok & np.all(np.isfinite(v), axis=1) & np.all(np.isfinite(a), axis=1)

    def project(self, q: np.ndarray, targets: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The rows of q (k, dof) moved onto their poses ``targets`` (k, 4, 4) by minimal-norm Newton
        steps: (q, X, T, J there, converged (k,))."""
        q = q.copy()
        live = np.ones(q.shape[0], dtype=bool)
        for _ in range(PROJECT_ITERATIONS):
            X, T, J = self.frames(q)
            e = _residual(T, targets)
            err = np.abs(e).max(axis=1)
            live &= np.isfinite(err)
            todo = live & (err > PROJECT_TOL)
            if not todo.any():
                break
            Jt = np.swapaxes(J[todo], 1, 2)
            try:
                q[todo] += np.einsum('kij,kj->ki', Jt, np.linalg.solve(J[todo] @ Jt, e[todo][..., None])[..., 0])
            except np.linalg.LinAlgError:
                live &= ~todo
        else:
            X, T, J = self.frames(q)
            err = np.abs(_residual(T, targets)).max(axis=1)
        return q, X, T, J, live & (err <= 100.0 * PROJECT_TOL)


def _residual(T: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Pose errors (k, 6) of T against targets (k, 4, 4): position, and the rotation vector of
    ``R* Rᵀ`` to first order (base frame)."""
    M = targets[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2)
    out = np.empty((T.shape[0], 6))
    out[:, :3] = targets[:, :3, 3] - T[:, :3, 3]
    out[:, 3] = 0.5 * (M[:, 2, 1] - M[:, 1, 2])
    out[:, 4] = 0.5 * (M[:, 0, 2] - M[:, 2, 0])
    out[:, 5] = 0.5 * (M[:, 1, 0] - M[:, 0, 1])
    return out


class TracedPath(GeodesicPath):
    """A path found by :func:`trace`: q and its s-derivatives from the quintic Hermite spline through
    the nodes (exact q, q', q'' there), which keeps the tool within the trace's tolerance of the
    curve. On 6 joints it is the pulled-back line (the paper's geodesic), verified by FK."""

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q and its first ``order`` s-derivatives (the spline's) at s; each (len(s), dof)."""
        return self.interpolate(s)[:order + 1]


@dataclass(frozen=True)
class TraceResult:
    """What :func:`trace` found: the path, or the reason and place it stops.

    Attributes:
        path: the traced path (None when the curve cannot be followed to its end).
        error: why not (a :class:`~.errors.PathFollowError`), or None.
        nodes: accepted steps + 1.
    """

    path: TracedPath | None
    error: PathFollowError | None
    nodes: int


def trace(robot: Chain, curve: TaskCurve, q_a: np.ndarray, *, metric: Metric, tolerance: float = 1e-9,
          t0: float | None = None, deadline: float | None = None, ik_start: IKSolution | None = None,
          ik_goal: IKSolution | None = None, q_end: np.ndarray | None = None, seeds_only: bool = False
          ) -> TraceResult:
    """Follow ``curve`` from the start joints ``q_a`` (on its first pose) to its end (module docstring).

    Args:
        robot: the arm (6 joints or more).
        curve: the tool's curve; metric: what the returned path reports its length in.
        tolerance: largest distance of the tool from the curve, m (and rad for the orientation);
            at most RELATIVE_TOLERANCE of the move's size.
        t0: perf_counter at the plan's start (the report's time); deadline: perf_counter limit.
        ik_start, ik_goal: the ends' IK solutions, kept on the path (the goal's q is the trace's end).
        q_end: goal joints (dof,) the path must end at: where the trace ends within
            :data:`SNAP_END` of them (a goal near a singularity is ill-conditioned in the joints), its
            last node is moved onto them and the last step checked again; otherwise the path ends where
            the curve leads (the caller compares).
        seeds_only: the path will only seed another solve (beyond 6 joints: no self-motion
            corrections, steps computed six at a time); with a coarse tolerance.
    Returns:
        TraceResult: the path, or the refusal with the followable fraction and the tool's place.
    Raises:
        BVPError: the deadline passed.
    """
    t0 = time.perf_counter() if t0 is None else t0
    twist = curve.twist(np.linspace(0.0, 1.0, 3))
    size = float(np.abs(twist).max())                  # m (and rad) per curve: the move's size
    tol = tolerance if seeds_only else max(min(tolerance, RELATIVE_TOLERANCE * size), FLOOR_TOLERANCE)
    flow = _Flow(robot, curve, tol)
    q_a = np.asarray(q_a, dtype=float)
    X, T, J = flow.frames(q_a[None])
    v, a, lo, hi, ok = _nodes(flow, np.zeros(1), q_a[None], X, T, J)     # J may be singular at the start
    node = _Node(0.0, q_a, v[0], a[0], float(lo[0]), float(hi[0]))
    if not ok[0]:
        return TraceResult(None, _stop_error(robot, curve, node, rate=True), 1)
    nodes = [node]
    # beyond 6 joints each node seeds the next (its self-motion is corrected), unless only seeds are asked
    batch = 1 if flow.redundant and not seeds_only else BATCH
    h, k = INITIAL_STEP, batch
    worst = 0.0
    for _ in range(MAX_STEPS):
        if node.s >= 1.0:
            break
        checkpoint()
        if deadline is not None and time.perf_counter() > deadline:
            raise BVPError(f'following {curve.name} exceeded the time limit for robot {robot.name!r} '
                           f'at {_percent(node.s)} of the way', status=-2)
        if not np.abs(node.v).max() <= MAX_RATE:
            return TraceResult(None, _stop_error(robot, curve, node, rate=True), len(nodes))
        h = min(h, 1.0 - node.s, 0.8 * MAX_JOINT_STEP / max(float(np.abs(node.v).max()), 1e-300))
        s_new = node.s + h * np.arange(1, k + 1)
        s_new = s_new[s_new < 1.0 - 1e-12]
        if s_new.size < k:
            s_new = np.append(s_new, 1.0)
        accepted, failure = _advance(flow, node, s_new, q_end, correct=not seeds_only)
        for new, err in accepted:
            crossing = _limit_crossing(robot, node, new)
            if crossing is not None:
                fraction, j = crossing
                bound = float(robot.upper[j] if new.q[j] > flow.mid[j] else robot.lower[j])
                return TraceResult(None, line_limit_error(robot, j, bound, fraction,
                                                          curve.poses(np.array([fraction]))[0, :3, 3],
                                                          curve.name), len(nodes))
            worst = max(worst, err)
            nodes.append(new)
            if new.sigma < SINGULAR_STOP * new.sigma_max and new.sigma < node.sigma:
                # heading into a singularity (a fold of the branch): the joint rates grow without bound
                return TraceResult(None, _stop_error(robot, curve, new), len(nodes))
            node = new
        if failure is False:                        # the whole batch: longer steps, as the error allows
            err = max((e for _, e in accepted), default=0.0)
            h *= 2.0 if err <= 0.0 else min(2.0, max(0.5, 0.9 * (tol / err) ** (1.0 / 6.0)))
            h = min(h, MAX_STEP)
            k = batch
            continue
        # a step failed: shorten (by the error's h⁶ law where one was measured)
        h *= 0.5 if failure is None else max(0.1, min(0.5, 0.9 * (tol / failure) ** (1.0 / 6.0)))
        k = max(min(2, batch), min(batch, len(accepted) + 1))
        if h < MIN_STEP:
            return TraceResult(None, _stop_error(robot, curve, node), len(nodes))
    else:
        return TraceResult(None, _stop_error(robot, curve, node), len(nodes))
    s = np.array([n.s for n in nodes])
    q = np.array([n.q for n in nodes])
    v = np.array([n.v for n in nodes])
    a = np.array([n.a for n in nodes])
    spline = QuinticHermite(s, q, v, a)
    rep = SolverReport(0, f'{curve.name} + slerp followed step by step ({s.size} nodes, the tool within '
                       f'{max(worst, 0.0):.2g} of it between them)', 0, 0.0, int(s.size),
                       (time.perf_counter() - t0) * 1e3, 0.0, 'trace', worst)
    eq = RedundantEquations(robot, metric)
    return TraceResult(TracedPath(eq, s, q, v, rep, ik_start, ik_goal, a, spline), None, len(nodes))


def _advance(flow: _Flow, node: _Node, s_new: np.ndarray, q_end: np.ndarray | None, correct: bool = True
             ) -> tuple[list[tuple[_Node, float]], float | bool | None]:
    """The next nodes at s_new (k,), computed together and accepted in order while each step keeps
    the tool within the tolerance of the curve (FK at CHECK_POINTS), moves no joint by more than
    MAX_JOINT_STEP and shows no singular-value dip. Returns the accepted (node, tool error) and
    why the first other one failed: False (none failed), its tool error, or None (no node there,
    a jump, a dip). ``q_end``: the goal joints, taken as the last node where the trace ends within
    SNAP_END of them. ``correct``: beyond 6 joints, move a single node's self-motion onto the flow."""
    d = (s_new - node.s)[:, None]
    pred = node.q + d * node.v + 0.5 * d * d * node.a
    m = s_new.size
    u = np.concatenate([[node.s], s_new])
    checks = (u[:-1, None] + np.diff(u)[:, None] * CHECK_POINTS).ravel()
    poses = flow.curve.poses(np.concatenate([s_new, checks]))
    q, X, T, J, converged = flow.project(pred, poses[:m])
    if q_end is not None and s_new[-1] == 1.0 and converged[-1] and np.abs(q[-1] - q_end).max() <= SNAP_END:
        q[-1] = q_end
        X, T, J = flow.frames(q)
    v, a, lo, hi, ok = _nodes(flow, s_new, q, X, T, J)
    with np.errstate(all='ignore'):
        if correct and flow.redundant and m == 1 and ok[0] and converged[0] and q_end is None:
            # the self-motion of the predicted node is only second order: move it (in J's null
            # space) onto the flow's two-point Hermite-Obreschkoff step, q1 = q0 + h/2 (v0 + v1)
            # + h^2/12 (a0 - a1) + O(h^5), so that the nodes' q, q', q'' agree and q''' is smooth
            for _ in range(CORRECTIONS):
                h1 = s_new[0] - node.s
                d = node.q + 0.5 * h1 * (node.v + v[0]) + h1 * h1 / 12.0 * (node.a - a[0]) - q[0]
                Jr = J[0]
                d -= Jr.T @ np.linalg.solve(Jr @ Jr.T, Jr @ d)
                q, X, T, J, converged = flow.project(q + d, poses[:1])
                v, a, lo, hi, ok = flow.nodes(s_new, q, X, T, J)
                if not (ok[0] and converged[0]):
                    break
    ok &= converged
    prev_q = np.vstack([node.q[None], q[:-1]])
    ok &= np.abs(q - prev_q).max(axis=1) <= MAX_JOINT_STEP
    ok &= np.abs(q - pred).max(axis=1) <= MAX_CORRECTION
    # the quintic Hermite of every step at its check points, by forward kinematics
    h = np.diff(u)[:, None, None]
    P = np.stack([np.vstack([node.q[None], q[:-1]]), h[:, :, 0] * np.vstack([node.v[None], v[:-1]]),
                  (h * h)[:, :, 0] * np.vstack([node.a[None], a[:-1]]), q, h[:, :, 0] * v,
                  (h * h)[:, :, 0] * a], axis=1)                     # (m, 6, dof)
    qm = np.einsum('cj,mjd->mcd', _CHECK_WEIGHTS, P).reshape(-1, q.shape[1])
    with np.errstate(all='ignore'):
        Tm = flow.robot.fk(np.where(np.isfinite(qm), qm, 0.0))
        want = poses[m:]
        e = _residual(Tm, want)
        err = np.maximum(np.sqrt(np.sum(e[:, :3] ** 2, axis=1)), np.sqrt(np.sum(e[:, 3:] ** 2, axis=1)))
    err = np.where(np.isfinite(err), err, np.inf).reshape(m, -1).max(axis=1)
    sigma = np.concatenate([[node.sigma], lo])
    sigma_max = np.concatenate([[node.sigma_max], hi])
    near = np.minimum(sigma[:-1], sigma[1:]) < SINGULAR_RATIO * np.maximum(sigma_max[:-1], sigma_max[1:]) / DIP_FRACTION
    dip = np.zeros(m, dtype=bool)
    if near.any():                                      # near a singularity: look between the nodes
        mids = qm.reshape(m, -1, q.shape[1])[:, CHECK_POINTS.size // 2]
        with np.errstate(all='ignore'):
            sm = np.linalg.svd(flow.frames(np.where(np.isfinite(mids), mids, 0.0))[2], compute_uv=False)[:, -1]
        dip = near & (sm < DIP_FRACTION * np.minimum(sigma[:-1], sigma[1:])) & (
            sm < SINGULAR_RATIO * np.maximum(sigma_max[:-1], sigma_max[1:]))
    accepted: list[tuple[_Node, float]] = []
    for j in range(m):
        if not ok[j] or dip[j]:
            return accepted, None
        if err[j] > flow.tolerance:
            return accepted, float(err[j])
        accepted.append((_Node(float(s_new[j]), q[j], v[j], a[j], float(lo[j]), float(hi[j])), float(err[j])))
    return accepted, False


def _nodes(flow: _Flow, s: np.ndarray, q: np.ndarray, X: np.ndarray, T: np.ndarray, J: np.ndarray
           ) -> tuple[np.ndarray, ...]:
    """:meth:`_Flow.nodes` on all rows at once, else (a Jacobian exactly singular) row by row: such
    a row is marked not ok, with its singular values (for the refusal's message)."""
    with np.errstate(all='ignore'):
        try:
            return flow.nodes(s, q, X, T, J)
        except np.linalg.LinAlgError:
            pass
        n = q.shape[1]
        v, a = np.full((s.size, n), np.nan), np.full((s.size, n), np.nan)
        lo, hi, ok = np.zeros(s.size), np.ones(s.size), np.zeros(s.size, dtype=bool)
        for j in range(s.size):
            try:
                out = flow.nodes(s[j:j + 1], q[j:j + 1], X[j:j + 1], T[j:j + 1], J[j:j + 1])
            except np.linalg.LinAlgError:
                sv = np.linalg.svd(J[j], compute_uv=False)
                lo[j], hi[j] = float(sv[-1]), float(sv[0])
                continue
            v[j], a[j], lo[j], hi[j], ok[j] = out[0][0], out[1][0], out[2][0], out[3][0], out[4][0]
    return v, a, lo, hi, ok


def _limit_crossing(robot: Chain, node: _Node, new: _Node) -> tuple[float, int] | None:
    """(fraction, joint) where the step's spline first leaves a position limit (to 1e-9 of the
    step, by bisection between the checked points), or None."""
    q = _between(_LIMIT_WEIGHTS, node, new)
    lo, hi = robot.lower - LIMIT_SLACK, robot.upper + LIMIT_SLACK
    out = (q < lo) | (q > hi)
    if not np.any(out):
        return None
    k = int(np.argmax(np.any(out, axis=1)))
    j = int(np.argmax(out[k]))
    a, b = (float(LIMIT_POINTS[k - 1]) if k else 0.0), float(LIMIT_POINTS[k])
    for _ in range(30):
        m = 0.5 * (a + b)
        qm = _between(_hermite_weights(np.array([m])), node, new)[0, j]
        a, b = (m, b) if lo[j] <= qm <= hi[j] else (a, m)
    return node.s + (new.s - node.s) * a, j


def _percent(fraction: float) -> str:
    return f'{100.0 * fraction:.3g} %'


def _where(curve: TaskCurve, s: float) -> str:
    x, y, z = curve.poses(np.array([s]))[0, :3, 3]
    return f'tool at {x:.4f}, {y:.4f}, {z:.4f} m'


def _stop_error(robot: Chain, curve: TaskCurve, node: _Node, rate: bool = False) -> PathFollowError:
    """Why the trace stops at ``node``: a singularity (J nearly rank-deficient, or joint rates beyond
    MAX_RATE), else the next poses out of the branch's reach."""
    fraction = node.s
    if rate or node.sigma < SINGULAR_RATIO * node.sigma_max:
        if fraction < END_FRACTION or fraction > 1.0 - END_FRACTION:
            end = 'start' if fraction < END_FRACTION else 'end'
            where = f'at its {end} ({_percent(round(fraction))} of the way, {_where(curve, fraction)}'
        else:
            where = f'at {_percent(fraction)} of the way ({_where(curve, fraction)}'
        return PathFollowError(
            f'{curve.name} passes through a singularity of robot {robot.name!r} {where}; the Jacobian\'s '
            f'smallest singular value {node.sigma:.2g}, {node.sigma / node.sigma_max:.2g} of its largest): the '
            f'joints would have to flip; followable fraction {fraction:.4f}', fraction=fraction)
    return LineUnreachableError(
        f'{curve.name} cannot be followed by robot {robot.name!r} beyond {_percent(fraction)} of the way '
        f'({_where(curve, fraction)}): no configuration near the start\'s branch reaches the next pose; '
        f'followable fraction {fraction:.4f}', fraction=fraction)
