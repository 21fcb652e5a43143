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
from .redundant import RedundantEquations, pose_residual, skew_vee

#: First step and largest step, fractions of the curve.
INITIAL_STEP = 1.0 / 32.0
MAX_STEP = 1.0 / 8.0
#: Smallest step before the curve is declared not followable (near a singular start the joints
#: move like the square root of s, and steps of 1e-8 of the way are needed there).
MIN_STEP = 1e-11
#: The most steps (accepted or not) of one trace: bounds its time on any input.
MAX_STEPS = 4000
#: Largest joint change in one step, rad or m (more: a jump to another branch).
MAX_JOINT_STEP = 0.1
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
#: A step whose midpoint's smallest singular value is below this fraction of both ends' (and
#: below SINGULAR_RATIO of the largest) stepped over a singular-value dip: it is shortened.
DIP_FRACTION = 0.5
#: Beyond 6 joints: the part of each joint's half-range, from its middle, beyond which the
#: self-motion pushes it back, and how fast at the limit (half-ranges per curve).
LIMIT_MARGIN = 0.8
LIMIT_PUSH = 4.0
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

    def jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        X, T = self.robot.generators(q[None])
        return X, T, RedundantEquations.jacobian(X, T)[0]

    def node(self, s: float, q: np.ndarray, X: np.ndarray, T: np.ndarray, J: np.ndarray) -> _Node:
        """q' = F(q, s) = J⁺ V + P g and q'' = dF[q'] + ∂F/∂s at q (module docstring)."""
        sv = np.linalg.svd(J, compute_uv=False)
        ss = np.array([s])
        V, dV = self.curve.twist(ss)[0], self.curve.twist_rate(ss)[0]
        if not self.redundant:
            # 6 joints: J square, q' = J⁻¹ V and J q'' = V' − J̇ q' (solved with J itself, whose
            # condition number is the square root of J Jᵀ's: near a singular start that matters)
            v = np.linalg.solve(J, V)
            a = np.linalg.solve(J, dV - RedundantEquations.velocity_term(X, T, v[None])[0])
        else:
            A = J @ J.T
            g, dgdq = self.push(q)
            y, z = np.linalg.solve(A, np.stack([V, J @ g], axis=1)).T
            v = J.T @ (y - z) + g
            dJ = RedundantEquations.rate(X, T, v[None])[0]          # dJ[v], (6, dof)
            dg = dgdq * v
            # d(J⁺ V) = dJᵀ y + Jᵀ dy, dy = A⁻¹ (V' − (dJ Jᵀ + J dJᵀ) y); d(P g) = dg − dJᵀ z − Jᵀ dz,
            # dz = A⁻¹ (dJ g + J dg − (dJ Jᵀ + J dJᵀ) z)
            dJJ = dJ @ J.T
            sym = dJJ + dJJ.T
            rhs = np.stack([dV - sym @ y, dJ @ g + J @ dg - sym @ z], axis=1)
            dy, dz = np.linalg.solve(A, rhs).T
            a = dJ.T @ (y - z) + J.T @ (dy - dz) + dg
        # J q' = V must hold: where V leaves J's range (a singular configuration) no finite q' does it
        if not np.linalg.norm(J @ v - V) <= VELOCITY_RESIDUAL * (np.linalg.norm(V) + 1e-300):
            raise np.linalg.LinAlgError('the tool velocity leaves the range of J')
        return _Node(s, q, v, a, float(sv[-1]), float(sv[0]))

    def project(self, q: np.ndarray, target: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """q moved onto the pose ``target`` (4, 4) by minimal-norm Newton steps, with X, T, J there;
        None when it does not converge."""
        q = q.copy()
        for _ in range(PROJECT_ITERATIONS):
            X, T, J = self.jacobian(q)
            e = pose_residual(T, target[None])[0]
            if not np.all(np.isfinite(e)):
                return None
            if float(np.abs(e).max()) <= PROJECT_TOL:
                return q, X, T, J
            try:
                q = q + J.T @ np.linalg.solve(J @ J.T, e)
            except np.linalg.LinAlgError:
                return None
        X, T, J = self.jacobian(q)
        e = pose_residual(T, target[None])[0]
        return (q, X, T, J) if float(np.abs(e).max()) <= 100.0 * PROJECT_TOL else None


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
          ik_goal: IKSolution | None = None, q_end: np.ndarray | None = None) -> TraceResult:
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
    Returns:
        TraceResult: the path, or the refusal with the followable fraction and the tool's place.
    Raises:
        BVPError: the deadline passed.
    """
    t0 = time.perf_counter() if t0 is None else t0
    twist = curve.twist(np.linspace(0.0, 1.0, 3))
    size = float(np.abs(twist).max())                  # m (and rad) per curve: the move's size
    flow = _Flow(robot, curve, max(min(tolerance, RELATIVE_TOLERANCE * size), FLOOR_TOLERANCE))
    q_a = np.asarray(q_a, dtype=float)
    try:
        node = flow.node(0.0, q_a, *flow.jacobian(q_a))
    except np.linalg.LinAlgError:
        sv = np.linalg.svd(flow.jacobian(q_a)[2], compute_uv=False)
        return TraceResult(None, _stop_error(robot, curve, _Node(0.0, q_a, q_a, q_a, float(sv[-1]), float(sv[0])),
                                             rate=True), 1)
    nodes = [node]
    h = INITIAL_STEP
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
        h = min(h, 1.0 - node.s)
        s1 = 1.0 if node.s + h >= 1.0 - 1e-12 else node.s + h
        h = s1 - node.s
        step = _step(flow, node, s1, q_end if s1 == 1.0 else None)
        if isinstance(step, tuple):
            new, err = step
            crossing = _limit_crossing(robot, node, new)
            if crossing is not None:
                fraction, j = crossing
                bound = float(robot.upper[j] if new.q[j] > flow.mid[j] else robot.lower[j])
                return TraceResult(None, line_limit_error(robot, j, bound, fraction,
                                                          curve.poses(np.array([fraction]))[0, :3, 3],
                                                          curve.name), len(nodes))
            worst = max(worst, err)
            nodes.append(new)
            node = new
            grow = 2.0 if err <= 0.0 else min(2.0, 0.9 * (tolerance / err) ** (1.0 / 6.0))
            h = min(MAX_STEP, h * max(grow, 0.5))
            continue
        # rejected: shorten (by the error's h⁶ law where one was measured)
        h *= 0.5 if step is None else max(0.1, min(0.5, 0.9 * (tolerance / step) ** (1.0 / 6.0)))
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


def _step(flow: _Flow, node: _Node, s1: float, q_end: np.ndarray | None = None
          ) -> tuple[_Node, float] | float | None:
    """The node at s1, with the tool's largest distance from the curve inside the step; or that
    distance (or None: no node, a jump, a singular-value dip) when the step must be shortened.
    ``q_end``: the goal joints, taken as the last node where the trace ends within SNAP_END of them."""
    h = s1 - node.s
    pred = node.q + h * node.v + 0.5 * h * h * node.a
    u = node.s + h * CHECK_POINTS
    poses = flow.curve.poses(np.concatenate([[s1], u]))
    found = flow.project(pred, poses[0])
    if found is None:
        return None
    q1, X, T, J = found
    if q_end is not None and np.abs(q1 - q_end).max() <= SNAP_END:
        q1 = np.array(q_end, dtype=float)
        X, T, J = flow.jacobian(q1)
    if not np.abs(q1 - node.q).max() <= MAX_JOINT_STEP:
        return None
    try:
        new = flow.node(s1, q1, X, T, J)
    except np.linalg.LinAlgError:
        return None
    if not (np.all(np.isfinite(new.v)) and np.all(np.isfinite(new.a))):
        return None
    qm = _between(_CHECK_WEIGHTS, node, new)
    Tm = flow.robot.fk(qm)
    want = poses[1:]
    dp = np.linalg.norm(Tm[:, :3, 3] - want[:, :3, 3], axis=1)
    dr = np.linalg.norm(skew_vee(Tm[:, :3, :3] @ np.swapaxes(want[:, :3, :3], 1, 2)), axis=1)
    err = float(np.maximum(dp, dr).max())
    if not np.isfinite(err):
        return None
    if err > flow.tolerance:
        return err
    near = SINGULAR_RATIO * max(node.sigma_max, new.sigma_max)
    if min(node.sigma, new.sigma) < near / DIP_FRACTION:        # near a singularity: look between
        sigma_mid = float(np.linalg.svd(flow.robot.jacobian(qm[1]), compute_uv=False)[-1])
        if sigma_mid < DIP_FRACTION * min(node.sigma, new.sigma) and sigma_mid < near:
            return None
    return new, err


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
            f'{curve.name} passes through a singularity of robot {robot.name!r} {where}; smallest singular '
            f'value {node.sigma:.2g}): no finite joint motion moves the tool along it there, the joints would '
            f'have to flip; followable fraction {fraction:.4f}', fraction=fraction)
    return LineUnreachableError(
        f'{curve.name} cannot be followed by robot {robot.name!r} beyond {_percent(fraction)} of the way '
        f'({_where(curve, fraction)}): no configuration near the start\'s branch reaches the next pose; '
        f'followable fraction {fraction:.4f}', fraction=fraction)
