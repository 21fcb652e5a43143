"""Around obstacles, made good (issue 39, section 2): from OMPL's way to the path of least
kinetic energy that keeps the clearance (docs/maths.md, section 11).

The path is :mod:`.least_energy`'s polynomial per joint (the joint line plus integrated-Legendre
modes: smooth to every order, ends exact), with :data:`MODES` modes. It starts as the least-squares
fit of the way (the polyline parameterised by its length in the mass metric at the line's middle)
and descends ``E + penalty`` by L-BFGS in the coefficients scaled by M's Cholesky factor (the
mass metric's covariant step, as in CHOMP): E the action, the penalty
:class:`~.obstacle_penalty.ObstaclePenalty` (every checked pair nearer than the padding plus
:data:`MARGIN` at :data:`PENALTY_POINTS` points of the path) with the joint limits' penalty.
Each result is kept only if it is inside the joint limits at the polynomial's exact extrema and
the continuous check (:meth:`~.collision.CollisionModel.check_path`) finds it clear of the
padding everywhere; else the descent continues with the obstacle weight 10x higher
(:data:`WEIGHTS`). When none passes (or the budget runs out first), the way itself is returned as
:class:`WayPath` (each straight segment with a septic smooth step, a rest at every corner:
smooth to the third derivative, collision-free as the search checked it).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from .blas import one_thread
from .collision import RESOLUTION, CollisionModel, MotionClearance
from .errors import CollisionError
from .kinematics import Chain
from .least_energy import ActionProblem, LeastEnergyPath, _basis, _inside, _path_coefficients
from .path import JointPath, by_segment, check_order, check_s

__all__ = ['MARGIN', 'MODES', 'Smoothed', 'WayPath', 'action_of', 'smooth_way', 'way_action']

#: Modes per joint of the path around obstacles, and the action's quadrature nodes.
MODES = 5
NODES = 20
#: Points of the path where the obstacle term is evaluated (the ends excluded: they are fixed).
PENALTY_POINTS = 24
#: The obstacle term acts on pairs nearer than the padding + the check's margin + this, m.
MARGIN = 0.03
#: Obstacle weights tried, each from the last result (a unit costs the line's action when every
#: point sits at the padding).
WEIGHTS = (10.0, 100.0, 1000.0)
#: Joint-limit penalty weight (per rad^2, times the line's action / grid points), and the
#: limits the penalty keeps (this far inside the real ones, rad or m).
LIMIT_WEIGHT = 1e4
LIMIT_INSET = 2e-3
#: L-BFGS's relative decrease to stop at (the action to about 1e-4), and its steps per descent.
FTOL = 1e-6
MAX_ITERATIONS = 30


class WayPath(JointPath):
    """The way's polyline, one septic smooth step ``35u^4 - 84u^5 + 70u^6 - 20u^7`` per segment:
    q'(s), q''(s), q'''(s) are zero at every corner (a rest), so the path is smooth to the third
    derivative and no time law leaves the checked segments. Segment k gets a share of s in
    proportion to its length in the mass metric at the line's middle."""

    def __init__(self, robot: Chain, waypoints: np.ndarray, metric: np.ndarray | None = None) -> None:
        self.robot = robot
        self.waypoints = np.asarray(waypoints, dtype=float)
        d = np.diff(self.waypoints, axis=0)
        M = np.eye(robot.dof) if metric is None else metric
        lengths = np.sqrt(np.maximum(np.einsum('ki,ij,kj->k', d, M, d), 0.0)) + 1e-12
        self.edges = np.concatenate([[0.0], np.cumsum(lengths) / lengths.sum()])
        self.edges[-1] = 1.0

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        s = check_s(s)
        order = check_order(order)
        out = [np.empty((s.size, self.robot.dof)) for _ in range(order + 1)]
        for k, sel, u in by_segment(self.edges, s):
            a, b = self.waypoints[k], self.waypoints[k + 1]
            w = self.edges[k + 1] - self.edges[k]
            steps = (u ** 4 * (35.0 + u * (-84.0 + u * (70.0 - 20.0 * u))),
                     u ** 3 * (140.0 + u * (-420.0 + u * (420.0 - 140.0 * u))) / w,
                     u ** 2 * (420.0 + u * (-1680.0 + u * (2100.0 - 840.0 * u))) / w ** 2,
                     u * (840.0 + u * (-5040.0 + u * (8400.0 - 4200.0 * u))) / w ** 3)
            out[0][sel] = a + steps[0][:, None] * (b - a)
            for k_ in range(1, order + 1):
                out[k_][sel] = steps[k_][:, None] * (b - a)
        return tuple(out)

    def deviation(self, s: np.ndarray) -> np.ndarray:
        """Zeros: a PTP has no tool geometry to keep."""
        return np.zeros(check_s(s).size)


@dataclass
class Smoothed:
    """What :func:`smooth_way` returned.

    Attributes:
        path: the path (a :class:`~.least_energy.LeastEnergyPath`, or the :class:`WayPath` fallback).
        clearance: the continuous check's answer on it (``refine=False``).
        action: ``int q'^T M q' ds`` of the path (the mass model's quadrature).
        way_action: the same of the way (its length squared in the mass metric at the line's
            middle, parameterised at constant speed).
        rounds: descents run; smooth_ms: their time; why: '' or why the fallback was taken.
    """

    path: JointPath
    clearance: MotionClearance
    action: float
    way_action: float
    rounds: int
    smooth_ms: float
    why: str = ''


class _OutOfTimeError(Exception):
    pass


def _way_samples(problem: ActionProblem, waypoints: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The polyline at s (constant speed in the metric at the line's middle)."""
    L = np.linalg.inv(problem.T.T)                      # M_mid = L L^T: |L^T d| is d's metric length
    d = np.diff(waypoints, axis=0)
    lengths = np.linalg.norm(d @ L, axis=1) + 1e-12
    edges = np.concatenate([[0.0], np.cumsum(lengths) / lengths.sum()])
    return np.stack([np.interp(s, edges, waypoints[:, j]) for j in range(waypoints.shape[1])], axis=1)


def _fit(problem: ActionProblem, waypoints: np.ndarray) -> np.ndarray:
    """Scaled coefficients z of the least-squares fit of the polyline."""
    s = np.linspace(0.0, 1.0, 201)[1:-1]
    B = _basis(2.0 * s - 1.0, problem.modes, 0)
    target = _way_samples(problem, waypoints, s) - (problem.q_a + s[:, None] * problem.dq)
    C = np.linalg.lstsq(B, target, rcond=None)[0]
    return np.linalg.solve(problem.T, C.T).T.ravel()


def _polyline_action(terms: Callable, waypoints: np.ndarray) -> float:
    """``int q'^T M q' ds`` of the polyline at constant speed in its own metric: (sum of segment
    lengths)^2, each length by Gauss-Legendre on M along the segment (the OMPL way's energy)."""
    x, w = np.polynomial.legendre.leggauss(8)
    u, w = 0.5 * (x + 1.0), 0.5 * w
    total = 0.0
    for a, b in pairwise(waypoints):
        d = b - a
        M = terms(a + u[:, None] * d, np.zeros((u.size, d.size)))[0]
        total += float(w @ np.sqrt(np.maximum(np.einsum('i,pij,j->p', d, M, d), 0.0)))
    return total * total


def way_action(terms: Callable, waypoints: np.ndarray) -> float:
    """The energy of a polyline at constant metric speed: its length in the mass metric, squared."""
    return _polyline_action(terms, np.asarray(waypoints, dtype=float))


def smooth_way(model: CollisionModel, terms: Callable, waypoints: np.ndarray, deadline: float) -> Smoothed:
    """The path of least action near the collision-free polyline ``waypoints`` (k, dof) that
    keeps the clearance, checked continuously; the polyline itself (:class:`WayPath`) when no
    descent passes the checks before ``deadline`` (time.monotonic()).

    Raises:
        Cancelled: the plan's token was cancelled.
    """
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    robot = model.robot
    q_a, q_b = waypoints[0], waypoints[-1]
    inset = np.minimum(LIMIT_INSET, 0.25 * (robot.upper - robot.lower))
    problem = ActionProblem(q_a, q_b, terms, robot.lower + inset, robot.upper - inset, modes=MODES, nodes=NODES,
                            limit_weight=LIMIT_WEIGHT)
    s = np.linspace(0.0, 1.0, PENALTY_POINTS + 2)[1:-1]
    from .obstacle_penalty import ObstaclePenalty
    active = model.padding + RESOLUTION + MARGIN
    penalty = ObstaclePenalty(model, q_a + s[:, None] * problem.dq, _basis(2.0 * s - 1.0, MODES, 0), active, 0.0)
    inner = penalty.__call__

    def extra(C: np.ndarray) -> tuple[float, np.ndarray]:
        if time.monotonic() > deadline:
            raise _OutOfTimeError
        return inner(C)

    problem.extra = extra
    way_e = _polyline_action(terms, waypoints)
    z = _fit(problem, waypoints)
    why, rounds = '', 0
    with one_thread():
        for weight in WEIGHTS:
            penalty.weight = weight * problem.scale / (MARGIN * MARGIN)
            rounds += 1
            try:
                r = minimize(problem.value_grad, z, jac=True, method='L-BFGS-B',
                             options={'maxiter': MAX_ITERATIONS, 'ftol': FTOL,
                                      'gtol': 1e-5 * np.sqrt(problem.scale)})
            except _OutOfTimeError:
                why = 'the budget ran out while smoothing'
                break
            if not np.all(np.isfinite(r.x)):
                why = 'the descent diverged'
                break
            z = r.x
            C = problem.coefficients(z)
            _, lam = _inside(problem_limits(problem, robot), C)
            if lam < 1.0:
                why = 'the smooth path left the joint limits'
                continue
            path = LeastEnergyPath(robot, _path_coefficients(problem, C))
            try:
                found = model.check_path(path, refine=False)
            except CollisionError as err:
                why = f'the smooth path was not clear ({err})'
                continue
            action = problem.action(z)
            if action >= way_e:
                why = 'the smooth path was not lower than the way'
                break
            path.action = action
            path.solve_ms = (time.perf_counter() - t0) * 1e3
            return Smoothed(path, found, action, way_e, rounds, path.solve_ms)
    metric = problem.terms((q_a + 0.5 * problem.dq)[None], np.zeros((1, robot.dof)))[0][0]
    way = WayPath(robot, waypoints, metric)
    found = model.check_path(way, refine=False)
    action = action_of(way, terms)
    return Smoothed(way, found, action, way_e, rounds, (time.perf_counter() - t0) * 1e3, why or 'no descent passed')


def problem_limits(problem: ActionProblem, robot: Chain) -> ActionProblem:
    """A view of ``problem`` with the robot's real joint limits (for the exact extrema check)."""
    view = object.__new__(ActionProblem)
    view.__dict__.update(problem.__dict__)
    view.lower, view.upper = robot.lower, robot.upper
    return view


def action_of(path: JointPath, terms: Callable, samples: int = 401) -> float:
    """``int q'^T M q' ds`` of a path by Simpson's rule (batched mass terms)."""
    k = int(samples) | 1
    s = np.linspace(0.0, 1.0, k)
    q, v = path.evaluate(s, 1)
    M = terms(q, v)[0]
    f = np.einsum('pi,pij,pj->p', v, M, v)
    h = 1.0 / (k - 1)
    return float(h / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum()))


def metric_length_ratio(a: float, b: float) -> float:
    """sqrt(a / b): how much longer a path of action a is than one of action b (constant speed)."""
    return math.sqrt(a / b) if b > 0.0 else math.inf
