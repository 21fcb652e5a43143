"""PlanSequence through the real planner node with a scene: a PTP item whose path a box blocks
goes around it (issue 39, section 2), blends with the LIN after it, and is refused with
ptp_around_obstacles false.

Oracles: coal's distances (the UR5's collision meshes, built here from the files) at every
published point of the trajectory and between them (dense joint interpolation), each above the
padding; the direct joint line's collision by the same model; the goals by FK.
"""
from __future__ import annotations

from collections.abc import Iterator
from itertools import pairwise
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import MotionSequenceItem, PlanErrorCode
from geodesic_planner_interfaces.srv import PlanSequence

from geodesic_planner import load_robot
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import PathInCollisionError
from geodesic_planner.core.kinematics import trans
from geodesic_planner.core.ptp import JointLinePath
from geodesic_planner.ros import conversions as cv

from .launch import call_service
from .test_plan_trajectory import DEADLINE, Planner, joints

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DATA = FsPath(__file__).resolve().parents[1] / 'data' / 'real_arms'
MESHES = DATA / 'meshes'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
UR5_SRDF = MESHES / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
Q_A = np.array([0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
Q_B = np.array([-0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
ROBOT = load_robot(str(UR5_URDF), tip_link='tool0')
MID = [float(x) for x in ROBOT.fk(0.5 * (Q_A + Q_B))[:3, 3]]
EDGE = 0.12


@pytest.fixture(scope='module')
def model() -> CollisionModel:
    m = CollisionModel.for_robot(ROBOT, UR5_URDF.read_text(), package_dirs=[str(MESHES)], srdf=UR5_SRDF.read_text())
    return m.with_objects([SceneObject('box', Shape('box', (EDGE,) * 3), trans(*MID))])


@pytest.fixture(scope='module')
def node(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Planner, Any]]:
    tmp = tmp_path_factory.mktemp('around')
    scene = tmp / 'scene.yaml'
    scene.write_text('objects:\n  - id: box\n    type: box\n'
                     f'    dimensions: [{EDGE}, {EDGE}, {EDGE}]\n'
                     f'    pose: {{position: [{MID[0]!r}, {MID[1]!r}, {MID[2]!r}], orientation: [0, 0, 0, 1]}}\n')
    p = Planner(helper, tmp, {'robot': str(UR5_URDF), 'tip_link': 'tool0', 'srdf': str(UR5_SRDF),
                              'package_dirs': [str(MESHES)], 'scene': str(scene)}, '/around')
    client = helper.create_client(PlanSequence, f'{p.name}/plan_sequence')
    try:
        yield p, client
    finally:
        p.stop()


def ptp_then_lin(r: float) -> PlanSequence.Request:
    ptp = MotionSequenceItem(motion='PTP', ptp='kinetic_energy', blend_radius=r)
    ptp.goal.pose.orientation.w = 0.0
    ptp.goal_joints = joints(ROBOT.joint_names, Q_B)
    T = ROBOT.fk(Q_B)
    T[:3, 3] += [0.0, 0.0, 0.1]
    lin = MotionSequenceItem(motion='LIN', goal=cv.matrix_to_pose_stamped(T, ''))
    req = PlanSequence.Request(items=[ptp, lin])
    req.start.pose.orientation.w = 0.0
    req.start_joints = joints(ROBOT.joint_names, Q_A)
    return req


def test_a_blocked_ptp_goes_around_and_blends_with_the_next_lin(node, model) -> None:
    planner, client = node
    with pytest.raises(PathInCollisionError):            # the premise: the box blocks the joint line
        model.check_path(JointLinePath(ROBOT, Q_A, Q_B))
    resp = call_service(client, ptp_then_lin(0.03), DEADLINE, watch=planner.watch)
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    assert 'sequence item 0: PTP went around obstacles' in resp.message, resp.message
    assert 'min_clearance' in resp.message and "x the direct path's length" in resp.message
    q = np.array([pt.positions for pt in resp.trajectory.points])
    np.testing.assert_allclose(q[0], Q_A, atol=1e-9)
    # blended: the PTP's goal is passed within the radius, not stopped at
    assert resp.blend_deviation[0] > 0.0
    t = np.array([pt.time_from_start.sec + 1e-9 * pt.time_from_start.nanosec for pt in resp.trajectory.points])
    v = np.array([pt.velocities for pt in resp.trajectory.points])
    near_goal = np.argmin(np.linalg.norm(q - Q_B, axis=1))
    assert np.abs(v[near_goal]).max() > 1e-3 and 0.0 < t[near_goal] < t[-1]
    # every point and the joint segments between them (0.5 mrad steps) clear by coal's distances
    dense = np.concatenate([a + np.linspace(0.0, 1.0, max(int(np.abs(b - a).max() / 5e-4), 2))[:-1, None] * (b - a)
                            for a, b in pairwise(q)] + [q[-1:]])
    d, _ = model.distances(dense)
    assert d.min() >= model.padding, d.min()
    assert abs(resp.min_clearance - d.min()) < 0.01


def test_off_a_blocked_ptp_is_refused(node) -> None:
    planner, client = node
    planner.set_parameters(ptp_around_obstacles=False)
    try:
        resp = call_service(client, ptp_then_lin(0.0), DEADLINE, watch=planner.watch)
        assert resp.error_code.val == PlanErrorCode.INVALID_MOTION_PLAN, resp.message
        assert 'collision on the way' in resp.message
    finally:
        planner.set_parameters(ptp_around_obstacles=True)
