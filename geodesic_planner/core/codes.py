"""The outcome code of a plan: each library error class -> one code of the planning service.

The numbers are those of the interface package's ``PlanErrorCode.msg`` (MoveIt's
``moveit_msgs/MoveItErrorCodes`` where MoveIt has a code of the same meaning, ours below -100);
``test/core/test_codes.py`` reads that file and checks every constant here against it. The ROS
bindings (``ros/planning.py``) reply with these numbers; the batch job (``geodesic-plan batch``)
writes them in its ``status`` column. No ROS import here.
"""
from __future__ import annotations

from enum import IntEnum

from .errors import (ConfigError, FrameError, GeodesicPlannerError, GoalInCollisionError, IKError, LimitError,
                     LineLimitError, LineUnreachableError, PathFollowError, PathInCollisionError, PlanTimeoutError,
                     RequestError, StartInCollisionError, StartStateError, TrajectoryError)

__all__ = ['ERROR_CODES', 'PlanCode', 'error_code']


class PlanCode(IntEnum):
    """The values of ``geodesic_planner_interfaces/msg/PlanErrorCode`` (see that file)."""

    SUCCESS = 1
    PLANNING_FAILED = -1
    INVALID_MOTION_PLAN = -2
    TIMED_OUT = -6
    START_STATE_IN_COLLISION = -10
    GOAL_IN_COLLISION = -12
    FRAME_TRANSFORM_FAILURE = -21
    NO_IK_SOLUTION = -31
    INVALID_REQUEST = -101
    START_STATE_MISMATCH = -102
    JOINT_LIMITS_VIOLATED = -103


#: Library error class -> PlanCode, one row per class; an error takes the code of the first class
#: along its method resolution order that has a row (classes without one, e.g. BVPError,
#: KinematicsError, CollisionError, take their base's).
ERROR_CODES: dict[type[BaseException], int] = {
    GeodesicPlannerError: PlanCode.PLANNING_FAILED,
    RequestError: PlanCode.INVALID_REQUEST,
    FrameError: PlanCode.FRAME_TRANSFORM_FAILURE,
    StartStateError: PlanCode.START_STATE_MISMATCH,
    TrajectoryError: PlanCode.PLANNING_FAILED,        # the generated trajectory, not the request
    ConfigError: PlanCode.PLANNING_FAILED,            # no usable model yet
    IKError: PlanCode.NO_IK_SOLUTION,
    LimitError: PlanCode.JOINT_LIMITS_VIOLATED,
    PathFollowError: PlanCode.PLANNING_FAILED,        # a line through a singularity
    LineLimitError: PlanCode.JOINT_LIMITS_VIOLATED,   # a line past a joint limit
    LineUnreachableError: PlanCode.NO_IK_SOLUTION,    # a line out of reach
    StartInCollisionError: PlanCode.START_STATE_IN_COLLISION,
    GoalInCollisionError: PlanCode.GOAL_IN_COLLISION,
    PathInCollisionError: PlanCode.INVALID_MOTION_PLAN,
    PlanTimeoutError: PlanCode.TIMED_OUT,
}


def error_code(err: BaseException) -> int:
    """The code of an error raised while planning (PLANNING_FAILED for anything else)."""
    for cls in type(err).__mro__:
        if cls in ERROR_CODES:
            return int(ERROR_CODES[cls])
    return int(PlanCode.PLANNING_FAILED)
