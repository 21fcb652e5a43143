"""One class, one code: every library error class's PlanErrorCode, resolved along its MRO.

The expected codes are written out here (MoveIt's values, ours below -100), one per class,
including the classes with two bases (a line past a joint limit, a line out of reach) and the
classes without a row of their own. Then the code and the reason of a pose whose orientation was
left unset (an all-zero quaternion), through the real planner node.
"""
from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import MotionSequenceItem
from geodesic_planner_interfaces.msg import PlanErrorCode as C
from geodesic_planner_interfaces.srv import PlanSequence

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


# ------------------------------------------------------- an unset orientation, through the real node
@pytest.fixture(scope='module')
def planar(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    from .test_plan_trajectory import Planner
    p = Planner(helper, tmp_path_factory.mktemp('codes_planar'), {'robot': 'planar_3r'}, '/codes')
    try:
        yield p
    finally:
        p.stop()


def _unset(x: float, y: float, frame: str = '') -> Any:
    """A pose at (x, y, 0) whose quaternion is all zero (a default Quaternion has w = 1)."""
    from geometry_msgs.msg import PoseStamped
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 0.0
    return msg


@pytest.mark.ros
@pytest.mark.timeout(300)
def test_an_all_zero_quaternion_is_an_unset_orientation_not_a_missing_pose(planar: Any) -> None:
    """Goal and start poses with a position and an all-zero quaternion: INVALID_REQUEST naming the
    end and the unset orientation, never "give a goal pose" nor a start from the current state."""
    from .test_plan_trajectory import DEADLINE, call_service, plan_request, pose_3r
    from .test_planner_node import GOAL_3R, START_3R
    cases = {
        'goal': (plan_request(pose_3r(*START_3R), _unset(1.5, 2.5)),
                 'goal: the orientation is unset (an all-zero quaternion) at position [1.5, 2.5, 0]'),
        'start': (plan_request(_unset(2.5, 1.5), pose_3r(*GOAL_3R)),
                  'start: the orientation is unset (an all-zero quaternion) at position [2.5, 1.5, 0]'),
        'goal in the base frame': (plan_request(pose_3r(*START_3R), _unset(1.5, 2.5, 'base_link')),
                                   'goal.orientation: quaternion is not normalised (norm 0, expected 1 within '
                                   '0.001): all zero, the orientation is unset'),
    }
    for name, (req, reason) in cases.items():
        resp = planar.plan(req)
        assert resp.error_code.val == C.INVALID_REQUEST, (name, resp.message)
        assert resp.message.startswith(reason), (name, resp.message)
        assert 'give a goal pose' not in resp.message
    client = planar.helper.create_client(PlanSequence, f'{planar.name}/plan_sequence')
    try:
        req = PlanSequence.Request(items=[MotionSequenceItem(motion='LIN', goal=_unset(1.5, 2.5))])
        req.start = pose_3r(*START_3R)
        resp = call_service(client, req, DEADLINE, watch=planar.watch)
        assert resp.error_code.val == C.INVALID_REQUEST, resp.message
        assert resp.message.startswith('items[0].goal: the orientation is unset (an all-zero quaternion)'), \
            resp.message
    finally:
        planar.helper.destroy_client(client)
