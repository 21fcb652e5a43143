"""Around obstacles, first step (issue 39, section 2): a way in joint space found by OMPL's RRTConnect.

The project's collision model is the state validity (every checked pair more than the padding
plus the continuous check's :data:`~.collision.RESOLUTION` apart) and the motion validity (each
straight joint segment checked continuously, :meth:`~.collision.CollisionModel.check_path`, as a
direct PTP is). The search runs until a way is found, the budget is spent, or the plan is
cancelled (:mod:`.cancel`: the termination condition looks at the token); OMPL's simplifier then
shortens the way (its shortcuts are motions checked the same way), and the result is checked
again, segment by segment, before it is returned.

Not done yet (the issue's next steps): turning the way into a smooth path of least kinetic
energy that keeps the clearance, and planning PTP items around obstacles by default.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from itertools import pairwise
from typing import Any

import numpy as np

from .cancel import Cancelled, checkpoint
from .collision import RESOLUTION, CollisionModel
from .errors import CollisionError, PlanningFailedError, RequestError
from .ptp import JointLinePath

__all__ = ['DEFAULT_TIMEOUT', 'Way', 'find_way']

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
             seed: int | None = None) -> Way:
    """A collision-free way from q_a to q_b (dof,) within ``timeout`` s.

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
        return bool(model.distances(vector(state)[None])[0][0] > floor)

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
    setup.simplifySolution(min(SIMPLIFY_TIME, max(deadline - time.monotonic(), 1e-3)))
    simplify_ms = (time.perf_counter() - t1) * 1e3
    path = setup.getSolutionPath()
    points = np.array([vector(path.getState(k)) for k in range(path.getStateCount())])
    points[0], points[-1] = q_a, q_b
    for a, b in pairwise(points):   # verified before it is returned
        if not segment_ok(a, b):
            raise PlanningFailedError(f'no collision-free path found in {float(timeout):g} s '
                                      '(a simplified segment failed the continuous check)')
    return Way(points, search_ms, simplify_ms, counts[0], counts[1])
