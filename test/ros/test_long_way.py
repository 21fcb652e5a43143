"""The long way round through the real planner node (issue 13 #10).

A UR5e wrist (limits ±2π) at 2π − 1e-3 asked to turn the tool by +0.5 rad: the short way is
beyond the joint's limit, the only goal within the limits is a −5.78 rad wrist move. The node
must refuse it with JOINT_LIMITS_VIOLATED and the library's reason, and keep planning ordinary
requests (the same start, the tool turned by −0.5 rad: a −0.5 rad wrist move, checked on the
trajectory's ends).
"""
from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory
from numpy.testing import assert_allclose
from sensor_msgs.msg import JointState

from geodesic_planner import load_robot
from geodesic_planner.core.kinematics import rot_z
from geodesic_planner.ros import conversions as cv

from .launch import RclpyRuntime, call_service, popen_node, warm_up_client

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0
UR5E = load_robot('ur5e')
Q0 = np.array([0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 2 * math.pi - 1e-3])


def request(turn: float) -> PlanTrajectory.Request:
    """From joints Q0 to the tool pose of Q0 turned by ``turn`` rad about the tool's z axis."""
    req = PlanTrajectory.Request()
    req.start_joints = JointState(name=list(UR5E.joint_names), position=[float(v) for v in Q0])
    req.goal = cv.matrix_to_pose_stamped(UR5E.fk(Q0) @ rot_z(turn), 'base_link')
    return req


@pytest.fixture(scope='module')
def node(rclpy_runtime: RclpyRuntime, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Any, Any]]:
    helper = rclpy_runtime.create_node('long_way_test')
    proc = popen_node('geodesic_planner_node', '-r', '__ns:=/lw', params={'robot': 'ur5e'}, name='lw',
                      log_dir=tmp_path_factory.mktemp('long_way'))
    client = helper.create_client(PlanTrajectory, '/lw/geodesic_planner/plan_trajectory')
    warm_up_client(client, PlanTrajectory.Request(), DEADLINE, watch=[proc])
    yield client, proc
    assert proc.stop() == 0, proc.log_text()
    rclpy_runtime.destroy_node(helper)


def test_long_way_refused_then_a_normal_plan(node: tuple[Any, Any]) -> None:
    client, proc = node
    resp = call_service(client, request(+0.5), DEADLINE, watch=[proc])
    assert resp.error_code.val == PlanErrorCode.JOINT_LIMITS_VIOLATED == -103
    assert "long way round: joint 'wrist_3_joint' would travel -5.783 rad" in resp.message, resp.message
    assert 'the tool needs a rotation of only 0.5 rad' in resp.message
    assert "blocked by the joint's limit 6.28319" in resp.message
    assert not resp.trajectory.points

    resp = call_service(client, request(-0.5), DEADLINE, watch=[proc])
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    arr = cv.joint_trajectory_to_arrays(resp.trajectory)
    expected = Q0.copy()
    expected[5] -= 0.5
    assert_allclose(arr.positions[0], Q0, atol=1e-9)
    assert_allclose(arr.positions[-1], expected, atol=1e-8)
    assert proc.alive()
