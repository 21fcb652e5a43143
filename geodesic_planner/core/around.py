"""Around obstacles (issue 39, section 2): a way in joint space found by OMPL's RRTConnect.

The project's collision model is the state validity (every checked pair more than the padding
plus the continuous check's :data:`~.collision.RESOLUTION` apart) and the motion validity (each
straight joint segment checked continuously, :meth:`~.collision.CollisionModel.check_path`, as a
direct PTP is). The search runs until a way is found, the budget is spent, or the plan is
cancelled (:mod:`.cancel`: the termination condition looks at the token); OMPL's simplifier then
shortens the way (its shortcuts are motions checked the same way), and the result is checked
again, segment by segment, before it is returned.

:func:`plan_around` then makes the way good (:mod:`.smooth_around`): the path of least kinetic
energy near it that keeps the clearance, smooth to every order, checked continuously before it
is returned.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from collections.abc import Callable
from itertools import pairwise
from typing import Any

import numpy as np

from .cancel import Cancelled, checkpoint
from .collision import RESOLUTION, CollisionModel
from .errors import (CollisionError, GoalInCollisionError, PlanningFailedError, RequestError,
                     StartInCollisionError)
from .ptp import JointLinePath
from .smooth_around import Smoothed, smooth_way

__all__ = ['DEFAULT_TIMEOUT', 'AroundOptions', 'AroundPlan', 'Way', 'around_ptp', 'find_way', 'plan_around']

#: ``ptp_planning_timeout``'s default, s.
DEFAULT_TIMEOUT = 1.0
#: The simplifier's share of the budget (at most), s.
SIMPLIFY_TIME = 0.1
#: Joints without finite limits are searched within this of their start and goal, rad or m.
OPEN_RANGE = math.pi


@dataclass
class Way:
    """A collision-free polyline in joint space.

    Attributes:
        waypoints: (k, dof), from start to goal. search_ms, simplify_ms: the time of each step.
        states_checked, motions_checked: calls of the validity checks.
    """

    waypoints: np.ndarray
    search_ms: float
    simplify_ms: float
    states_checked: int
    motions_checked: int


def _ompl() -> tuple[Any, Any]:
    """ompl.base and ompl.geometric, OMPL's log at warnings and above."""
    from ompl import base as ob, geometric as og, util as ou

    ou.setLogLevel(ou.LogLevel.LOG_WARN)
    return ob, og


def find_way(model: CollisionModel, q_a: np.ndarray, q_b: np.ndarray, timeout: float = DEFAULT_TIMEOUT, *,
             seed: int | None = None, simplify: float = SIMPLIFY_TIME, verify: bool = True) -> Way:
    """A collision-free way from q_a to q_b (dof,) within ``timeout`` s.

    ``simplify``: the time given to OMPL's simplifier (shortcuts, B-spline smoothing, at most
    until the deadline), s; 0: one pass of its vertex reduction only (random shortcuts, as many
    tries as the path has states: the smoothing of :func:`plan_around` does the rest).

    ``verify``: check the way's segments continuously again before it is returned (each was
    checked when the search or the simplifier added it; :func:`plan_around` checks what it makes
    of the way instead).

    Raises:
        RequestError: a timeout that is not a positive finite number.
        StartInCollisionError, GoalInCollisionError: an end within the padding (their usual codes).
        PlanningFailedError: no way found in ``timeout`` s ("no collision-free path found in T s").
        Cancelled: the plan's token was cancelled (checked while the search runs).
    """
    if not (isinstance(timeout, (int, float)) and math.isfinite(timeout) and timeout > 0.0):
        raise RequestError(f'ptp_planning_timeout must be a finite number > 0 s, got {timeout!r}')
    robot = model.robot
    q_a = robot.check_joints(q_a, 'start joints')
    q_b = robot.check_joints(q_b, 'goal joints')
    model.check_state(q_a, 'start')
    model.check_state(q_b, 'goal')
    ob, og = _ompl()
    n = robot.dof
    lo = np.where(np.isfinite(robot.lower), robot.lower, np.minimum(q_a, q_b) - OPEN_RANGE)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.maximum(q_a, q_b) + OPEN_RANGE)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, float(lo[i]))
        bounds.setHigh(i, float(hi[i]))
    space.setBounds(bounds)
    if seed is not None:
        from ompl import util as ou
        ou.RNG.setSeed(int(seed))
    setup = og.SimpleSetup(space)
    info = setup.getSpaceInformation()
    counts = [0, 0]
    floor = model.padding + RESOLUTION

    def vector(state: object) -> np.ndarray:
        return np.array([state[i] for i in range(n)])  # type: ignore[index]

    def state_ok(state: object) -> bool:
        counts[0] += 1
        return bool(model.clear_above(vector(state)[None], floor)[0])

    def segment_ok(a: np.ndarray, b: np.ndarray) -> bool:
        counts[1] += 1
        try:
            model.check_path(JointLinePath(robot, a, b), refine=False)
        except CollisionError:
            return False
        return True

    validator: Any = ob.MotionValidator

    class Motions(validator):
        def checkMotion(self, a: object, b: object, *rest: object) -> bool:
            return segment_ok(vector(a), vector(b))

    setup.setStateValidityChecker(state_ok)
    motions = Motions(info)
    info.setMotionValidator(motions)
    start, goal = space.allocState(), space.allocState()
    for i in range(n):
        start[i], goal[i] = float(q_a[i]), float(q_b[i])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(info))
    deadline = time.monotonic() + float(timeout)
    cancelled = [False]

    def stop() -> bool:
        try:
            checkpoint()
        except Cancelled:
            cancelled[0] = True
            return True
        return time.monotonic() > deadline

    t0 = time.perf_counter()
    solved = setup.solve(ob.PlannerTerminationCondition(stop))
    search_ms = (time.perf_counter() - t0) * 1e3
    if cancelled[0]:
        checkpoint()                           # raises Cancelled with the token's reason
    if not (solved and setup.haveExactSolutionPath()):
        raise PlanningFailedError(f'no collision-free path found in {float(timeout):g} s')
    t1 = time.perf_counter()
    path = setup.getSolutionPath()
    if simplify > 0.0:
        setup.simplifySolution(min(simplify, max(deadline - time.monotonic(), 1e-3)))
        path = setup.getSolutionPath()
    else:
        og.PathSimplifier(info).reduceVertices(path)
    simplify_ms = (time.perf_counter() - t1) * 1e3
    points = np.array([vector(path.getState(k)) for k in range(path.getStateCount())])
    points[0], points[-1] = q_a, q_b
    for a, b in pairwise(points if verify else []):   # verified before it is returned
        if not segment_ok(a, b):
            raise PlanningFailedError(f'no collision-free path found in {float(timeout):g} s '
                                      '(a simplified segment failed the continuous check)')
    return Way(points, search_ms, simplify_ms, counts[0], counts[1])


@dataclass(frozen=True)
class AroundOptions:
    """How a blocked PTP plans around obstacles (a request's ``around``; None: it is refused).

    Attributes:
        model: the collision model (robot and scene) the way keeps clear of.
        timeout: ``ptp_planning_timeout``: the budget of the search and the smoothing per PTP item, s.
        seed: OMPL's random seed (None: not set; the same seed twice in a process warns).
    """

    model: CollisionModel
    timeout: float = DEFAULT_TIMEOUT
    seed: int | None = None


@dataclass
class AroundPlan:
    """A path around obstacles and how it was found."""

    way: Way
    smoothed: Smoothed
    total_ms: float

    @property
    def path(self) -> Any:  # noqa: ANN401
        return self.smoothed.path


def plan_around(model: CollisionModel, terms: Callable, q_a: np.ndarray, q_b: np.ndarray,
                timeout: float = DEFAULT_TIMEOUT, *, deadline: float | None = None,
                seed: int | None = None) -> AroundPlan:
    """A collision-free path from q_a to q_b of least action ``int q'^T M q' ds`` (``terms``: the
    mass model's M(q) and its derivative, :meth:`~.ptp.MassModel.terms`) near the way OMPL finds:
    :func:`find_way` (its vertex reduction only), then :func:`~.smooth_around.smooth_way`, checked
    continuously. Search and smoothing share one budget, ending at ``deadline`` (time.monotonic();
    default now + ``timeout``): the way found is smoothed until then, else returned as its polyline
    (smooth to the third derivative, checked continuously as a whole): the plan ends within the
    budget plus one descent step and that last check.

    Raises:
        as :func:`find_way` (PlanningFailedError "no collision-free path found in T s").
    """
    t0 = time.perf_counter()
    end = time.monotonic() + float(timeout) if deadline is None else float(deadline)
    failed = f'no collision-free path found in {float(timeout):g} s'
    left = end - time.monotonic()
    if left <= 0.0:
        raise PlanningFailedError(failed)
    try:
        way = find_way(model, q_a, q_b, left, seed=seed, simplify=0.0, verify=False)
    except PlanningFailedError:
        raise PlanningFailedError(failed) from None
    try:
        smoothed = smooth_way(model, terms, way.waypoints, end)
    except CollisionError:      # the polyline as one path, at places its segments' checks did not see
        raise PlanningFailedError(f'{failed} (the way failed the continuous check)') from None
    return AroundPlan(way, smoothed, (time.perf_counter() - t0) * 1e3)


def _blocked_at(err: CollisionError) -> str:
    """Where a collision error's pair meets, in a few words."""
    pair = getattr(err, 'pair', ('', ''))
    fraction = float(getattr(err, 'fraction', math.nan))
    return f'{pair[0]} and {pair[1]} at {100.0 * fraction:.0f} % of the way'


def around_ptp(options: AroundOptions, direct_to: Callable[[np.ndarray], Any], terms: Callable,
               q_start: np.ndarray, q_goal: np.ndarray, branches: Callable[[], list[np.ndarray]] | None = None,
               metric: str = 'mass') -> Any:  # noqa: ANN401
    """A PTP's path: the direct one (``direct_to(q_goal)``) when the continuous check finds it
    clear, else the least-energy path around the obstacles (:func:`plan_around`). With
    ``branches`` (a pose goal: its other IK solutions), the goals are taken in the order of their
    direct paths' action, and the collision-free path of least action is kept (a goal is
    skipped once the best path found is below its direct path's action, a lower bound of any way
    to it as long as the direct path is the least-energy one).

    The path returned has a ``note`` when it went around or changed branch (the reply's message).
    Raises:
        StartInCollisionError: the start within the padding.
        GoalInCollisionError: every goal within the padding (the first goal's error).
        PlanningFailedError: no way found within ``options.timeout`` s.
        Cancelled: the plan's token was cancelled.
    """
    from .smooth_around import action_of

    model = options.model
    t0 = time.perf_counter()
    end = time.monotonic() + float(options.timeout)
    direct = direct_to(q_goal)
    try:
        model.check_path(direct, refine=False)
        return direct
    except StartInCollisionError:
        raise
    except CollisionError as err:
        first = err
    goals = [(q_goal, direct)]
    if branches is not None:
        goals += [(q, direct_to(q)) for q in branches()]
    energies = [action_of(p, terms) for _, p in goals]
    order = np.argsort(energies, kind='stable')
    best: tuple[float, Any, str] | None = None
    goal_errors: list[CollisionError] = []
    searched = False
    for k in order.tolist():
        checkpoint()
        q_k, path_k = goals[k]
        if best is not None and best[0] <= energies[k]:
            break
        branch = f'; IK branch {k + 1} of {len(goals)} of the goal pose' if k else ''
        if k:
            try:
                model.check_path(path_k, refine=False)
                best = (energies[k], path_k, f'PTP goal: IK branch {k + 1} of {len(goals)} of the goal pose (the '
                                             f'direct path to the first collides: {_blocked_at(first)})')
                continue
            except StartInCollisionError:
                raise
            except GoalInCollisionError as err:
                goal_errors.append(err)
                continue
            except CollisionError:
                pass
        elif isinstance(first, GoalInCollisionError):
            goal_errors.append(first)
            continue
        if time.monotonic() >= end:
            break
        searched = True
        try:
            found = plan_around(model, terms, q_start, q_k, options.timeout, deadline=end, seed=options.seed)
        except PlanningFailedError:
            continue
        sm = found.smoothed
        if best is None or sm.action < best[0]:
            clearance = sm.clearance.refined()
            how = 'smooth, least energy' if not sm.why else f'the way as searched: {sm.why[:120]}'
            hit = _blocked_at(_collision(first, k, path_k, model))
            best = (sm.action, sm.path, (
                f'PTP went around obstacles (the direct path hits: {hit}): '
                f'min_clearance {clearance.min_clearance:.4f} m (collision_padding {model.padding:g} m), '
                f'{math.sqrt(sm.action / max(energies[k], 1e-300)):.2f}x the direct path\'s length in the {metric} '
                f'metric ({how}; search {found.way.search_ms:.0f} ms, smoothing {sm.smooth_ms:.0f} ms){branch}'))
    if best is None:
        if goal_errors and not searched and len(goal_errors) == len(goals):
            raise goal_errors[0]
        raise PlanningFailedError(f'no collision-free path found in {float(options.timeout):g} s '
                                  f'(the direct path hits {_blocked_at(first)})')
    path = best[1]
    path.note = best[2]
    path.around_ms = (time.perf_counter() - t0) * 1e3
    return path


def _collision(first: CollisionError, k: int, path: Any, model: CollisionModel) -> CollisionError:  # noqa: ANN401
    """The collision of goal k's direct path (the first's for k = 0)."""
    if k == 0:
        return first
    try:
        model.check_path(path, refine=False)
    except CollisionError as err:
        return err
    return first
