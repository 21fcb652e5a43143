"""Point clouds into the planner node's collision scene (issue 41), through real nodes.

A ur5e planner with one sensor: clouds of a simulated depth camera (a table and a box ray cast,
with noise, NaNs and the arm's own image) published with rclpy. Oracles: the library called here
on the same float32 points (the node's verdicts and messages must be the same: code, pair, place),
the voxel count of that map (the node lists it), and the clouds the processor recorded in its bag,
replayed into the node.
"""
from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import MotionSequenceItem, PlanErrorCode
from geodesic_planner_interfaces.srv import ListCollisionObjects, PlanSequence
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosbags.highlevel import AnyReader
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import PointCloud2, PointField
from visualization_msgs.msg import Marker, MarkerArray

from cloud_util import capsule_points, depth_camera, look_at
from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.branches import check_trajectory
from geodesic_planner.core.collision import CollisionModel
from geodesic_planner.core.errors import CollisionError
from geodesic_planner.core.point_cloud import SelfFilter, cloud_map
from geodesic_planner.ros import conversions as cv

from .launch import (Collector, call_service, latched_qos, popen_node, wait_discovered, wait_for_subscribers,
                     wait_until)
from .test_plan_trajectory import DEADLINE, Planner, joints, plan_request

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

NS = '/t41'
TOPIC = '/t41/cam'
ROBOT = load_robot('ur5e')
MODEL = CollisionModel.for_robot(ROBOT)
Q0 = np.array([0.0, -1.9, 1.9, -1.57, -1.57, 0.0])
T0 = ROBOT.fk(Q0[None])[0]
TABLE = (np.array([-1.0, -0.8, -0.15]), np.array([0.3, 0.8, -0.10]))
BOX = (np.array([-0.42, 0.02, -0.10]), np.array([-0.28, 0.12, 0.43]))       # across the tool's line
CAMERA = look_at(np.array([-1.5, 0.1, 0.9]), np.array([-0.35, 0.07, 0.1]))
POSE7 = [*CAMERA[:3, 3], *Rotation.from_matrix(CAMERA[:3, :3]).as_quat()]
RES, PAD = 0.02, 0.03


def scene_cloud(boxes: list, seed: int) -> np.ndarray:
    """An organised float32 cloud (H, W, 3) in the camera frame: the boxes and the arm at Q0."""
    rng = np.random.default_rng(seed)
    image = depth_camera(boxes, CAMERA, width=200, height=150, rng=rng)
    S = ROBOT.segment_frames(Q0[None])[0]
    caps = [(S[b.segment] @ b.offset, b.geometry.halfLength) for b in MODEL.robot_bodies
            if type(b.geometry).__name__ == 'Capsule']
    arm = capsule_points(np.array([c[0] for c in caps]), np.array([c[1] for c in caps]), 0.05, 200, rng,
                         jitter=0.02)
    image[:1] = ((arm - CAMERA[:3, 3]) @ CAMERA[:3, :3]).astype(np.float32).reshape(1, 200, 3)
    return image


def message(points: np.ndarray, frame: str = 'cam', *, point_step: int = 16) -> PointCloud2:
    """PointCloud2 of (H, W, 3) float32 points, each padded to ``point_step`` bytes."""
    h, w, _ = points.shape
    raw = np.zeros((h, w, point_step), dtype=np.uint8)
    raw[:, :, :12] = np.ascontiguousarray(points, dtype='<f4').view(np.uint8).reshape(h, w, 12)
    msg = PointCloud2(height=h, width=w, point_step=point_step, row_step=w * point_step, is_dense=False,
                      fields=[PointField(name=c, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                              for i, c in enumerate('xyz')])
    msg.header.frame_id = frame
    msg.data = raw.tobytes()
    return msg


def library_map(points: np.ndarray) -> Any:
    return cloud_map(TOPIC, points.reshape(-1, 3), CAMERA, RES, self_filter=SelfFilter(MODEL, PAD), q=Q0)


def library_verdict(points: np.ndarray, goal: np.ndarray, start: np.ndarray = Q0) -> str:
    """The library's refusal message of the line start -> goal in the map of ``points`` ('' if clear)."""
    traj = GeodesicPlanner(ROBOT).plan(ROBOT.fk(start[None])[0], goal, start_joints=start).timed()
    try:
        check_trajectory(MODEL.with_objects([library_map(points).object]), traj)
    except CollisionError as err:
        return str(err)
    return ''


def shifted(dy: float) -> np.ndarray:
    T = T0.copy()
    T[1, 3] += dy
    return T


class Sensed(Planner):
    """A ur5e planner with the sensor, and the helper's publishers and clients."""

    def __init__(self, helper: Any, log_dir: FsPath) -> None:
        super().__init__(helper, log_dir, {
            'robot': 'ur5e', 'point_cloud_topics': [TOPIC], 'point_cloud_frames': ['cam'],
            'point_cloud_poses': [float(v) for v in POSE7], 'max_cloud_age': 60.0, 'max_cloud_rate': 100.0,
            'allowed_start_tolerance': 0.0, 'plan_timeout': 30.0, 'ptp_planning_timeout': 10.0}, NS)
        self.clouds = helper.create_publisher(PointCloud2, TOPIC,
                                              QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE))
        self.list = helper.create_client(ListCollisionObjects, f'{self.name}/list_collision_objects')
        self.sequence = helper.create_client(PlanSequence, f'{self.name}/plan_sequence')
        self.markers = Collector(helper, MarkerArray, f'{self.name}/octree_markers', latched_qos())
        wait_for_subscribers(self.clouds, 1, DEADLINE, watch=self.watch)

    def line(self) -> str:
        (found,) = [o for o in call_service(self.list, ListCollisionObjects.Request(), DEADLINE,
                                            watch=self.watch).objects if o.id == TOPIC]
        return found.mesh_resource

    def show(self, points: np.ndarray, voxels: int, **kw: Any) -> str:
        """Publish the cloud (and the joint state) until the node lists a map of ``voxels`` voxels."""
        def taken() -> str:
            self.states.publish(joints(ROBOT.joint_names, Q0))
            self.clouds.publish(message(points, **kw))
            line = self.line()
            return line if f' in {voxels} voxels ' in line else ''
        return wait_until(taken, DEADLINE, what=f'a map of {voxels} voxels', watch=self.watch)

    def refused(self) -> int:
        found = re.search(r'(\d+) refused', self.line())
        assert found is not None, self.line()
        return int(found.group(1))


@pytest.fixture(scope='module')
def sensed(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Sensed]:
    p = Sensed(helper, tmp_path_factory.mktemp('clouds'))
    try:
        yield p
    finally:
        p.stop()


CLOUD_A = scene_cloud([TABLE, BOX], 1)       # the box across the line
CLOUD_B = scene_cloud([TABLE], 2)            # the box taken away
LIVE: dict[str, str] = {}


def lin(goal: np.ndarray, start: np.ndarray = Q0) -> Any:
    return plan_request(goal=cv.matrix_to_pose_stamped(goal, ''), start_joints=start, names=ROBOT.joint_names)


def test_plans_refused_until_the_sensor_has_sent_a_cloud(sensed: Sensed) -> None:
    resp = sensed.plan(lin(shifted(0.4)))
    assert resp.error_code.val == PlanErrorCode.PLANNING_FAILED, resp.message
    assert f'no cloud from {TOPIC} yet' in resp.message and 'max_cloud_age' in resp.message
    assert sensed.line().startswith('octree: no cloud yet')


def test_a_box_seen_as_points_refuses_the_line_as_the_library_does(sensed: Sensed) -> None:
    expected = library_map(CLOUD_A)
    line = sensed.show(CLOUD_A, expected.voxels)
    assert f'octree: {expected.kept} points in {expected.voxels} voxels' in line, line
    assert f'{expected.robot} on the robot' in line and expected.robot >= 200
    resp = sensed.plan(lin(shifted(0.4)))
    assert resp.error_code.val == PlanErrorCode.INVALID_MOTION_PLAN, resp.message
    assert resp.message == library_verdict(CLOUD_A, shifted(0.4)), resp.message
    assert f"'{TOPIC}'" in resp.message and '% of the way' in resp.message
    LIVE['line'] = resp.message
    # the voxels as RViz markers: one cube list of the map's cells
    def cubes() -> Any:
        for arr in reversed(sensed.markers.messages):
            cube = [m for m in arr.markers if m.type == Marker.CUBE_LIST]
            if cube and len(cube[0].points) == expected.voxels:
                return cube[0]
        return None
    cube = wait_until(cubes, DEADLINE, what='octree markers of the map', watch=sensed.watch)
    assert cube.scale.x == RES and cube.header.frame_id == 'base_link'


def test_start_and_goal_inside_the_map_are_named(sensed: Sensed) -> None:
    inside = T0.copy()
    inside[:3, 3] = 0.5 * (BOX[0] + BOX[1])
    inside[2, 3] = BOX[1][2] - 0.05
    resp = sensed.plan(lin(inside))
    assert resp.error_code.val == PlanErrorCode.GOAL_IN_COLLISION, resp.message
    assert f"'{TOPIC}'" in resp.message
    q_in = GeodesicPlanner(ROBOT).plan(T0, inside, start_joints=Q0).q_goal
    resp = sensed.plan(lin(T0, start=q_in))
    assert resp.error_code.val == PlanErrorCode.START_STATE_IN_COLLISION, resp.message
    assert resp.message == library_verdict(CLOUD_A, T0, q_in)


def test_a_sequence_through_the_box_is_refused_naming_the_sensor(sensed: Sensed) -> None:
    goal = cv.matrix_to_pose_stamped(shifted(0.4), '')
    req = PlanSequence.Request(items=[MotionSequenceItem(motion='LIN', goal=goal)])
    req.start.pose.orientation.w = 0.0
    req.start_joints = joints(ROBOT.joint_names, Q0)
    resp = call_service(sensed.sequence, req, DEADLINE, watch=sensed.watch)
    assert resp.error_code.val == PlanErrorCode.INVALID_MOTION_PLAN, resp.message
    assert f"'{TOPIC}'" in resp.message and '% of the way' in resp.message


def test_a_ptp_goes_around_the_box_seen_as_points(sensed: Sensed) -> None:
    goal = cv.matrix_to_pose_stamped(shifted(0.4), '')
    req = PlanSequence.Request(items=[MotionSequenceItem(motion='PTP', goal=goal)])
    req.start.pose.orientation.w = 0.0
    req.start_joints = joints(ROBOT.joint_names, Q0)
    resp = call_service(sensed.sequence, req, DEADLINE, watch=sensed.watch)
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    assert 'went around obstacles (the direct path hits: ' + TOPIC in resp.message, resp.message
    q = np.array([p.positions for p in resp.trajectory.points])
    scene = MODEL.with_objects([library_map(CLOUD_A).object])
    d, _ = scene.distances(q)          # coal's distances at every published point, the map included
    assert d.min() > MODEL.padding


@pytest.mark.parametrize('seed', range(4))
def test_malformed_and_foreign_clouds_are_refused_the_map_kept(sensed: Sensed, seed: int) -> None:
    rng = np.random.default_rng(seed)
    bad = message(CLOUD_A[:4, :5])
    kind = seed % 4
    if kind == 0:
        bad.data = bytes(bad.data)[:-int(rng.integers(1, 16))]           # lengths that do not match
    elif kind == 1:
        bad.width = int(rng.integers(10**7, 10**9))                      # a huge width
    elif kind == 2:
        bad.fields[int(rng.integers(0, 3))].datatype = PointField.INT16  # wrong field size
    else:
        bad.header.frame_id = 'somewhere_else'                           # neither base nor sensor frame
    before = sensed.refused()

    def refused() -> bool:
        sensed.clouds.publish(bad)
        return sensed.refused() > before
    wait_until(refused, DEADLINE, what='the cloud refused', watch=sensed.watch)
    resp = sensed.plan(lin(shifted(0.4)))
    assert resp.message == LIVE['line']                                   # the map as it was


def test_the_box_taken_away_stops_blocking_with_the_next_cloud(sensed: Sensed) -> None:
    sensed.show(CLOUD_B, library_map(CLOUD_B).voxels)
    assert library_verdict(CLOUD_B, shifted(0.4)) == ''
    resp = sensed.plan(lin(shifted(0.4)))
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    assert resp.message.startswith('min_clearance') and resp.min_clearance > 0.01


def test_stale_maps_are_refused_or_planned_with_a_warning(sensed: Sensed) -> None:
    try:
        sensed.set_parameters(max_cloud_age=0.001)
        resp = sensed.plan(lin(shifted(0.4)))
        assert resp.error_code.val == PlanErrorCode.PLANNING_FAILED, resp.message
        assert re.search(rf'the map of {TOPIC} is [0-9.]+ s old', resp.message), resp.message
        sensed.set_parameters(stale_clouds='warn')
        resp = sensed.plan(lin(shifted(0.4)))
        assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
        assert resp.message.startswith('planned against stale maps (the map of'), resp.message
        assert 'min_clearance' in resp.message
    finally:
        sensed.set_parameters(max_cloud_age=60.0, stale_clouds='refuse')


def test_clouds_recorded_by_the_processor_replay_to_the_same_verdict(sensed: Sensed, helper: Any,
                                                                      tmp_path: FsPath) -> None:
    """The processor records the clouds (record_topics); the first one recorded, replayed into the
    node after another map, gives the verdict it gave live. A smaller image (100 x 75, 12-byte points:
    90 kB) than the others, so that best-effort delivery to the recorder does not lose it on a busy
    machine."""
    small = depth_camera([TABLE, BOX], CAMERA, width=100, height=75, rng=np.random.default_rng(3))
    bag = tmp_path / 'clouds'
    proc = popen_node('trajectory_processor_node', '-r', f'__ns:={NS}', name='t41_processor', log_dir=tmp_path,
                      params={'bag_path': str(bag), 'record_topics': [f'{TOPIC}=sensor_msgs/msg/PointCloud2']})
    try:
        wait_for_subscribers(sensed.clouds, 2, DEADLINE, watch=[proc])
        wait_discovered(helper, f'{NS}/trajectory_processor', DEADLINE, watch=[proc])
        sensed.show(small, library_map(small).voxels, point_step=12)
        live = sensed.plan(lin(shifted(0.4)))
        for _ in range(3):                   # more copies for the recorder, each after a round trip
            sensed.clouds.publish(message(small, point_step=12))
            sensed.line()
    finally:
        assert proc.stop() == 0, proc.log_text()
    assert live.error_code.val == PlanErrorCode.INVALID_MOTION_PLAN and f"'{TOPIC}'" in live.message, live.message
    with AnyReader([bag]) as reader:
        raw = [d for c, _, d in reader.messages() if c.topic == TOPIC]
    assert raw, proc.log_text()
    replayed = deserialize_message(raw[0], PointCloud2)
    sensed.show(CLOUD_B, library_map(CLOUD_B).voxels)        # another map meanwhile: the box gone
    assert sensed.plan(lin(shifted(0.4))).error_code.val == PlanErrorCode.SUCCESS
    voxels = library_map(small).voxels

    def taken() -> bool:
        sensed.states.publish(joints(ROBOT.joint_names, Q0))
        sensed.clouds.publish(replayed)
        return f' in {voxels} voxels ' in sensed.line()
    wait_until(taken, DEADLINE, what='the replayed map', watch=sensed.watch)
    resp = sensed.plan(lin(shifted(0.4)))
    assert (resp.error_code.val, resp.message) == (live.error_code.val, live.message)
