"""PlanSequence through the real planner node: each motion type, one mixed sequence with blends,
the replies' fields and the error codes.

Oracles: the sequence's goals (FK of the trajectory's last point, the goals' positions), the
circle it was built on (computed here), Pilz's radius rule's arithmetic.
"""
from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import MotionSequenceItem, PlanErrorCode
from geodesic_planner_interfaces.srv import PlanSequence

from geodesic_planner import load_robot
from geodesic_planner.ros import conversions as cv

from .launch import call_service
from .test_plan_trajectory import DEADLINE, Planner, joints

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

ROBOT = load_robot('ur5e')
Q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
T0 = ROBOT.fk(Q0)


def moved(dp: list[float]) -> np.ndarray:
    T = T0.copy()
    T[:3, 3] = T0[:3, 3] + np.asarray(dp)
    return T


def item(motion: str, goal: np.ndarray | None = None, *, q: Any = None, circ: tuple[str, Any] | None = None,
         ptp: str = '', r: float = 0.0) -> MotionSequenceItem:
    msg = MotionSequenceItem(motion=motion, ptp=ptp, blend_radius=r)
    if goal is not None:
        msg.goal = cv.matrix_to_pose_stamped(goal, '')
    else:
        msg.goal.pose.orientation.w = 0.0          # an empty goal pose: use goal_joints
        msg.goal_joints = joints(ROBOT.joint_names, q)
    if circ is not None:
        msg.circ_constraint = circ[0]
        msg.circ_point.x, msg.circ_point.y, msg.circ_point.z = (float(v) for v in circ[1])
    return msg


def request(items: list[MotionSequenceItem]) -> PlanSequence.Request:
    req = PlanSequence.Request(items=items)
    req.start.pose.orientation.w = 0.0
    req.start_joints = joints(ROBOT.joint_names, Q0)
    return req


@pytest.fixture(scope='module')
def node(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Planner, Any]]:
    p = Planner(helper, tmp_path_factory.mktemp('sequence'), {'robot': 'ur5e'}, '/seq')
    client = helper.create_client(PlanSequence, f'{p.name}/plan_sequence')
    try:
        yield p, client
    finally:
        p.stop()


def ask(node: tuple[Planner, Any], items: list[MotionSequenceItem]) -> PlanSequence.Response:
    planner, client = node
    return call_service(client, request(items), DEADLINE, watch=planner.watch)


def last_tool(resp: PlanSequence.Response) -> np.ndarray:
    return ROBOT.fk(np.array(resp.trajectory.points[-1].positions))[:3, 3]


def test_each_motion_type_alone(node) -> None:
    T1 = moved([0.1, 0.0, 0.0])
    for it, goal in ((item('LIN', T1), T1[:3, 3]),
                     (item('CIRC', T1, circ=('center', T0[:3, 3] + [0.05, 0.05, 0.0])), T1[:3, 3]),
                     (item('PTP', q=Q0 + 0.2, ptp='joint_line'), ROBOT.fk(Q0 + 0.2)[:3, 3])):
        resp = ask(node, [it])
        assert resp.error_code.val == PlanErrorCode.SUCCESS, (it.motion, resp.message)
        assert resp.failed_item == -1
        np.testing.assert_allclose(last_tool(resp), goal, atol=1e-6)


def test_mixed_sequence_with_blends(node) -> None:
    T1, T2, T3 = moved([0.15, 0.0, 0.0]), moved([0.25, 0.1, 0.0]), moved([0.25, 0.25, -0.05])
    centre = T0[:3, 3] + [0.15, 0.1, 0.0]
    resp = ask(node, [item('LIN', T1, r=0.03), item('CIRC', T2, circ=('center', centre), r=0.03),
                      item('LIN', T3), item('PTP', q=Q0)])
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    assert 'joint line' in resp.message                 # the preset has no inertias: said so
    assert len(resp.blend_deviation) == 3
    assert 0.0 < resp.blend_deviation[0] <= 0.03 and 0.0 < resp.blend_deviation[1] <= 0.03
    assert resp.blend_deviation[2] == 0.0
    q = np.array([p.positions for p in resp.trajectory.points])
    np.testing.assert_allclose(q[-1], Q0, atol=1e-9)    # back at the start joints
    p = ROBOT.fk(q)[:, :3, 3]
    assert np.linalg.norm(p - T2[:3, 3], axis=1).min() <= 0.03 + 1e-6   # passed within the radius


def test_a_bad_item_names_its_index_and_code(node) -> None:
    T1 = moved([0.1, 0.0, 0.0])
    collinear = item('CIRC', moved([0.2, 0.0, 0.0]), circ=('interim', T0[:3, 3] + [0.15, 0.0, 0.0]))
    resp = ask(node, [item('LIN', T1), collinear])
    assert resp.error_code.val == PlanErrorCode.INVALID_REQUEST
    assert resp.failed_item == 1, resp.message
    assert 'sequence item 1 (CIRC)' in resp.message and 'collinear' in resp.message
    assert len(resp.trajectory.points) == 0
    resp = ask(node, [item('LIN', T1, r=0.01)])
    assert resp.error_code.val == PlanErrorCode.INVALID_REQUEST and 'last item' in resp.message
    resp = ask(node, [item('SPLINE', T1)])
    assert resp.error_code.val == PlanErrorCode.INVALID_REQUEST and 'items[0].motion' in resp.message
    assert ask(node, []).error_code.val == PlanErrorCode.INVALID_REQUEST
    # an unreachable goal: the IK's code, the item named
    resp = ask(node, [item('LIN', T1), item('PTP', moved([3.0, 0.0, 0.0]), ptp='joint_line')])
    assert resp.error_code.val == PlanErrorCode.NO_IK_SOLUTION and resp.failed_item == 1, resp.message


def test_ptp_of_least_kinetic_energy_on_a_urdf_with_inertias(helper: Any, tmp_path: Any) -> None:
    """The UR5 of example-robot-data: kinetic_energy plans the mass-matrix geodesic (off the joint
    line), without a note (its action against the joint line's: test/core/test_ptp.py)."""
    urdf = FsPath(__file__).resolve().parents[1] / 'data' / 'real_arms' / 'example-robot-data' / 'ur5_robot.urdf'
    ur5 = load_robot(str(urdf), tip_link='tool0')
    p = Planner(helper, tmp_path, {'robot': str(urdf), 'tip_link': 'tool0', 'collision_check': False}, '/seq_ke')
    try:
        client = helper.create_client(PlanSequence, f'{p.name}/plan_sequence')
        q_a = np.array([0.0, -1.0, 1.2, -1.5, -1.4, 0.2])
        q_b = q_a + np.array([1.5, 0.6, -0.9, 0.5, 1.0, -1.0])
        req = PlanSequence.Request(items=[MotionSequenceItem(motion='PTP', ptp='kinetic_energy')])
        req.items[0].goal.pose.orientation.w = 0.0
        req.items[0].goal_joints = joints(ur5.joint_names, q_b)
        req.start.pose.orientation.w = 0.0
        req.start_joints = joints(ur5.joint_names, q_a)
        resp = call_service(client, req, DEADLINE, watch=p.watch)
        assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
        assert resp.message == ''                                  # no fallback
        q = np.array([pt.positions for pt in resp.trajectory.points])
        np.testing.assert_allclose(q[[0, -1]], [q_a, q_b], atol=1e-9)
        u = (q - q_a) @ (q_b - q_a) / ((q_b - q_a) @ (q_b - q_a))
        off_line = np.linalg.norm(q - (q_a + u[:, None] * (q_b - q_a)), axis=1).max()
        assert off_line > 0.05                                      # not the joint line
    finally:
        p.stop()


def test_a_circ_goal_out_of_reach_is_no_ik_solution(node) -> None:
    """Issue 36 item 5b: was PLANNING_FAILED '(a joint limit, a singularity or out of reach)'. The
    goal is 1.49 m from the shoulder, beyond the UR5e's 1.15 m of links."""
    far = moved([-0.9, 0.0, 0.0])
    interim = 0.5 * (T0[:3, 3] + far[:3, 3]) + [0.0, 0.1, 0.1]
    resp = ask(node, [item('LIN', moved([0.0, 0.0, 0.05])), item('CIRC', far, circ=('interim', interim))])
    assert resp.error_code.val == PlanErrorCode.NO_IK_SOLUTION, resp.message
    assert resp.failed_item == 1, resp.message
    assert 'sequence item 1 (CIRC)' in resp.message and 'the nearest reachable pose is' in resp.message
    assert len(resp.trajectory.points) == 0
