"""One class, one code: every library error class's PlanErrorCode, resolved along its MRO.

The expected codes are written out here (MoveIt's values, ours below -100), one per class,
including the classes with two bases (a line past a joint limit, a line out of reach) and the
classes without a row of their own.
"""
from __future__ import annotations

import pytest

pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode as C

from geodesic_planner.core import errors as E
from geodesic_planner.ros.planning import error_code

EXPECTED = [
    (E.GeodesicPlannerError, C.PLANNING_FAILED), (E.RequestError, C.INVALID_REQUEST),
    (E.FrameError, C.FRAME_TRANSFORM_FAILURE), (E.StartStateError, C.START_STATE_MISMATCH),
    (E.JointStateError, C.INVALID_REQUEST),
    (E.TrajectoryError, C.PLANNING_FAILED), (E.KinematicsError, C.PLANNING_FAILED),
    (E.SingularMetricError, C.PLANNING_FAILED), (E.IKError, C.NO_IK_SOLUTION),
    (E.BVPError, C.PLANNING_FAILED), (E.LimitError, C.JOINT_LIMITS_VIOLATED),
    (E.BagError, C.PLANNING_FAILED), (E.CollisionError, C.PLANNING_FAILED),
    (E.StartInCollisionError, C.START_STATE_IN_COLLISION), (E.GoalInCollisionError, C.GOAL_IN_COLLISION),
    (E.PathInCollisionError, C.INVALID_MOTION_PLAN), (E.ConfigError, C.PLANNING_FAILED),
    (E.PlanningFailedError, C.PLANNING_FAILED), (E.PlanTimeoutError, C.TIMED_OUT),
]
FOLLOW = [(E.PathFollowError, C.PLANNING_FAILED), (E.LineLimitError, C.JOINT_LIMITS_VIOLATED),
          (E.LineUnreachableError, C.NO_IK_SOLUTION)]


def _make(cls: type) -> BaseException:
    if issubclass(cls, E.PathFollowError):
        return cls('x', fraction=0.5)
    if issubclass(cls, E.JointStateError):
        return cls('x', kind='missing')
    if issubclass(cls, E.CollisionError):
        return cls('x', pair=('a', 'b'), fraction=0.5, time=0.1, clearance=0.0)
    return cls('x')


@pytest.mark.parametrize('cls,code', EXPECTED + FOLLOW, ids=lambda v: getattr(v, '__name__', str(v)))
def test_each_error_class_has_its_code(cls: type, code: int) -> None:
    assert error_code(_make(cls)) == code


def test_every_library_error_class_is_covered() -> None:
    library = {c for c in vars(E).values() if isinstance(c, type) and issubclass(c, E.GeodesicPlannerError)}
    assert library <= {c for c, _ in EXPECTED + FOLLOW}


def test_anything_else_is_planning_failed() -> None:
    assert error_code(RuntimeError('x')) == C.PLANNING_FAILED
