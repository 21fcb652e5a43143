"""Collisions through the real planner node: the scene parameter, the scene services and markers,
the collision error codes, min_clearance and the IK branch taken.

Oracles: closed-form IK of the planar 3R arm (unit links, both elbow branches), the capsules of
its links (radius link_radius) and exact geometry of spheres and boxes placed on them.
"""
from __future__ import annotations

import math
import re
from collections.abc import Iterator
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import CollisionObject, PlanErrorCode
from geodesic_planner_interfaces.srv import ListCollisionObjects, RemoveCollisionObject, SetCollisionObject
from numpy.testing import assert_allclose
from shape_msgs.msg import SolidPrimitive
from visualization_msgs.msg import Marker, MarkerArray

from .launch import Collector, call_service, latched_qos, wait_until
from .test_plan_trajectory import DEADLINE, Planner, goal_3r, ik_3r_down, plan_request
from .test_planner_node import GOAL_3R, ROBOT_3R, START_3R, ik_3r, pose_3r

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

SCENE = FsPath(__file__).resolve().parents[2] / 'msg_examples' / 'scene_box.yaml'
PADDING = 0.01
RADIUS = 0.05          # link_radius default: the 3R's links are capsules of this radius


def obj(name: str, kind: int, dims: list[float], x: float, y: float) -> CollisionObject:
    msg = CollisionObject(id=name)
    msg.primitive = SolidPrimitive(type=kind, dimensions=dims)
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.w = 1.0
    return msg


class ScenePlanner(Planner):
    """A planner node with the scene file, and clients of the scene services."""

    def __init__(self, helper: Any, log_dir: FsPath) -> None:
        super().__init__(helper, log_dir, {'robot': 'planar_3r', 'scene': str(SCENE)}, '/col')
        self.set_obj = helper.create_client(SetCollisionObject, f'{self.name}/set_collision_object')
        self.remove = helper.create_client(RemoveCollisionObject, f'{self.name}/remove_collision_object')
        self.list = helper.create_client(ListCollisionObjects, f'{self.name}/list_collision_objects')
        self.markers = Collector(helper, MarkerArray, f'{self.name}/scene_markers', latched_qos())

    def call(self, client: Any, req: Any) -> Any:
        return call_service(client, req, DEADLINE, watch=self.watch)

    def put(self, msg: CollisionObject) -> None:
        resp = self.call(self.set_obj, SetCollisionObject.Request(object=msg))
        assert resp.success, resp.message

    def ids(self) -> list[str]:
        return sorted(o.id for o in self.call(self.list, ListCollisionObjects.Request()).objects)


@pytest.fixture(scope='module')
def scene(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[ScenePlanner]:
    p = ScenePlanner(helper, tmp_path_factory.mktemp('collision'))
    try:
        p.set_state(ik_3r(*START_3R), ROBOT_3R.joint_names, _away)
        assert p.ids() == ['box']                # the scene parameter's file
        yield p
    finally:
        p.stop()


#: The success message: min_clearance, the closest pair, the place and their exact distance there.
CLOSEST = re.compile(r"min_clearance (?P<value>[0-9.]+) m \(the smallest distance over the path, at most 1 mm "
                     r"below it\): '(?P<a>[^']+)' and '(?P<b>[^']+)' come closest at (?P<percent>[0-9.]+) % of "
                     r"the way, (?P<closest>[0-9.]+) m apart there")


def least_distance(trajectory: Any, x: float, y: float, edge: float) -> float:
    """The smallest distance (m) at the trajectory's points between the planar 3R's link capsules
    (unit links from joint to joint, radius RADIUS) and a cube of ``edge`` m centred at (x, y, 0)."""
    coal = pytest.importorskip('coal')
    box, at = coal.Box(edge, edge, edge), coal.Transform3s(np.eye(3), np.array([x, y, 0.0]))
    least = math.inf
    for point in trajectory.points:
        angle, p = 0.0, np.zeros(3)
        for q in point.positions:
            angle += q
            u = np.array([math.cos(angle), math.sin(angle), 0.0])
            R = np.stack([np.cross([0.0, 0.0, 1.0], u), [0.0, 0.0, 1.0], u], axis=1)   # z along the link
            link = coal.Transform3s(R, p + 0.5 * u)
            least = min(least, coal.distance(coal.Capsule(RADIUS, 1.0), link, box, at,
                                             coal.DistanceRequest(), coal.DistanceResult()))
            p = p + u
    return least


def duration(reply: Any) -> float:
    """The duration (s) of a reply's trajectory."""
    end = reply.trajectory.points[-1].time_from_start
    return end.sec + 1e-9 * end.nanosec


def _away(req: Any) -> Any:
    """A from-state request that cannot collide with the scene file's box (a tiny move at A)."""
    req.goal = pose_3r(START_3R[0], START_3R[1] - 0.01, START_3R[2])
    return req


def test_box_across_the_line_is_refused_then_moved_aside(scene: ScenePlanner) -> None:
    scene.put(obj('box', SolidPrimitive.BOX, [0.3, 0.3, 0.3], 2.0, 2.0))     # the file's box
    resp = scene.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    assert resp.error_code.val == PlanErrorCode.INVALID_MOTION_PLAN, resp.message
    assert "'box'" in resp.message and "'link_3'" in resp.message, resp.message
    assert 'of the way' in resp.message and 'collision_padding' in resp.message
    assert len(resp.trajectory.points) == 0
    # the tool point (2.5 - s, 1.5 + s), the end of link_3's capsule, comes within radius + padding
    # of the box's corner (2.15, 1.85) at s = 0.35 - (r + pad) / sqrt(2): refused no later
    s_tip = 0.35 - (RADIUS + PADDING) / math.sqrt(2.0)
    assert 0.2 < resp.fraction <= s_tip + 1e-6
    scene.put(obj('box', SolidPrimitive.BOX, [0.3, 0.3, 0.3], 3.5, 3.5))
    resp = scene.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    assert resp.ik_branch == 'default'
    assert PADDING < resp.min_clearance < math.inf
    listed = scene.call(scene.list, ListCollisionObjects.Request()).objects
    assert [(o.id, o.pose.position.x, o.pose.position.y) for o in listed] == [('box', 3.5, 3.5)]
    # the success message names the closest pair and the place, and the clearance is never above
    # the distances at the published points (capsules and box placed here, coal's distances)
    said = CLOSEST.fullmatch(resp.message)
    assert said is not None, resp.message
    assert float(said['value']) == pytest.approx(resp.min_clearance, abs=5e-5)
    assert float(said['value']) <= float(said['closest']) <= float(said['value']) + 1e-3 + 1e-4
    assert 0.0 <= float(said['percent']) <= 100.0
    assert resp.min_clearance <= least_distance(resp.trajectory, 3.5, 3.5, 0.3) + 1e-9
    # the path's, not the time law's: a tool speed limit stretches the motion, nothing else changes
    scene.set_parameters(max_tool_speed=0.05)
    try:
        slow = scene.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    finally:
        scene.set_parameters(max_tool_speed=0.0)
    assert slow.error_code.val == PlanErrorCode.SUCCESS, slow.message
    assert duration(slow) > 1.5 * duration(resp)
    assert slow.min_clearance == resp.min_clearance and slow.message == resp.message


def test_scene_markers_follow_the_scene(scene: ScenePlanner) -> None:
    scene.put(obj('ball', SolidPrimitive.SPHERE, [0.07], 3.0, -1.0))

    def shows_ball() -> bool:
        if not len(scene.markers):
            return False
        last = scene.markers.messages[-1]
        return any(m.type == Marker.SPHERE and m.scale.x == pytest.approx(0.14) for m in last.markers)
    wait_until(shows_ball, DEADLINE, what='scene markers with the ball', watch=scene.watch)
    resp = scene.call(scene.remove, RemoveCollisionObject.Request(id='ball'))
    assert resp.success, resp.message
    assert 'ball' not in scene.ids()
    missing = scene.call(scene.remove, RemoveCollisionObject.Request(id='nothing'))
    assert not missing.success and "'nothing'" in missing.message


def test_start_and_goal_in_collision_have_their_codes(scene: ScenePlanner) -> None:
    qa = ik_3r(*START_3R)
    elbow = (math.cos(qa[0]), math.sin(qa[0]))
    scene.put(obj('post', SolidPrimitive.SPHERE, [0.1], *elbow))
    try:
        resp = scene.plan(plan_request(start_joints=qa, goal=pose_3r(*GOAL_3R)))
        assert resp.error_code.val == PlanErrorCode.START_STATE_IN_COLLISION, resp.message
        assert "'post'" in resp.message
        assert resp.ik_branch == ''
    finally:
        assert scene.call(scene.remove, RemoveCollisionObject.Request(id='post')).success
    scene.put(obj('at_goal', SolidPrimitive.SPHERE, [0.05], GOAL_3R[0], GOAL_3R[1]))
    try:
        resp = scene.plan(plan_request(start_joints=qa, goal=pose_3r(*GOAL_3R)))
        assert resp.error_code.val == PlanErrorCode.GOAL_IN_COLLISION, resp.message
        assert "'at_goal'" in resp.message and "'link_3'" in resp.message
    finally:
        assert scene.call(scene.remove, RemoveCollisionObject.Request(id='at_goal')).success


def test_the_other_elbow_branch_is_planned_where_the_default_collides(scene: ScenePlanner) -> None:
    qa = ik_3r(*START_3R)               # the default branch (seeded by the current state)
    elbow = (math.cos(qa[0]), math.sin(qa[0]))
    scene.put(obj('post', SolidPrimitive.SPHERE, [0.1], *elbow))
    try:
        # the node knows the robot's joint state: a plan must start there (start-state check)
        held = scene.plan(goal_3r(plan_request(pose_3r(*START_3R))))
        assert held.error_code.val == PlanErrorCode.START_STATE_IN_COLLISION, held.message
        assert 'no other IK branch' in held.message and 'current joint state' in held.message
        scene.set_parameters(allowed_start_tolerance=0.0)    # the start is free to choose
        try:
            resp = scene.plan(goal_3r(plan_request(pose_3r(*START_3R))))
        finally:
            scene.set_parameters(allowed_start_tolerance=0.01)
        assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
        assert resp.ik_branch.endswith(' of 2') and not resp.ik_branch.startswith('1 ')
        assert_allclose(resp.trajectory.points[0].positions, ik_3r_down(*START_3R), atol=1e-6)
        assert resp.min_clearance > PADDING
        # an explicit start state is kept: the same start as joints is refused
        fixed = scene.plan(plan_request(start_joints=qa, goal=pose_3r(*GOAL_3R)))
        assert fixed.error_code.val == PlanErrorCode.START_STATE_IN_COLLISION
    finally:
        assert scene.call(scene.remove, RemoveCollisionObject.Request(id='post')).success


def test_collision_check_off_ignores_the_scene(scene: ScenePlanner) -> None:
    scene.put(obj('box', SolidPrimitive.BOX, [0.3, 0.3, 0.3], 2.0, 2.0))
    assert scene.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R))).error_code.val == \
        PlanErrorCode.INVALID_MOTION_PLAN
    scene.set_parameters(collision_check=False)
    try:
        resp = scene.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
        assert resp.error_code.val == PlanErrorCode.SUCCESS and math.isnan(resp.min_clearance)
        refused = scene.call(scene.set_obj, SetCollisionObject.Request(
            object=obj('x', SolidPrimitive.SPHERE, [0.1], 5.0, 5.0)))
        assert not refused.success and 'collision_check' in refused.message
    finally:
        scene.set_parameters(collision_check=True)
    bad = obj('bad', SolidPrimitive.SPHERE, [-1.0], 0.0, 0.0)
    refused = scene.call(scene.set_obj, SetCollisionObject.Request(object=bad))
    assert not refused.success and 'radius' in refused.message, refused.message
    assert 'bad' not in scene.ids()
