"""The planner node as a user runs it: console script in a subprocess, real DDS, real services.

Every expectation comes from an exact oracle: closed-form IK of the planar 3R arm, the straight
line with linear phi (3R, metric dx^2 + dy^2 + 2 dphi^2) and line + slerp (6-joint arm) for the
tool path, forward kinematics for the ends, the robot's limits. No fixed sleeps: every wait has
an event and a deadline.
"""
from __future__ import annotations

import contextlib
import itertools
import math
import os
import signal
import subprocess
import threading
from collections.abc import Callable, Iterator
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped
from nav_msgs.srv import GetPlan
from numpy.testing import assert_allclose
from rcl_interfaces.msg import Log
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import (DescribeParameters, GetParameters, SetParameters,
                                 SetParametersAtomically)
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

import geodesic_planner
from geodesic_planner import load_robot
from geodesic_planner.ros import conversions as cv
from geodesic_planner.core.transforms import make_transform, pose_error, so3_exp, so3_log
from geodesic_planner.core.urdf import chain_from_urdf

from .launch import (Collector, call_service, latched_qos, popen_node, rosout_collector, wait_for_service,
                     wait_for_subscribers, wait_until, warm_up_client)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0      # s, generous: first plans include imports and caches on a loaded 2-core box
ERROR, WARN, INFO = 40, 30, 20


#: frame_id of the harmless GetPlan request that warms up a new client (its error line is ignored)
WARMUP_FRAME = '__warmup__'


def warmup_request(client: Any) -> Any:
    """A request with no effect for ``client``'s service type (a GetPlan one fails, logged)."""
    srv = client.srv_type
    if srv is GetPlan:
        return GetPlan.Request(goal=pose_3r(*GOAL_3R, frame=WARMUP_FRAME))
    if srv in (GetParameters, DescribeParameters):
        return srv.Request(names=[])
    return srv.Request(parameters=[])            # SetParameters(Atomically): empty, no change


def ready(client: Any, watch: list[Any]) -> None:
    """Wait for the service and one harmless round trip (see launch.warm_up_client)."""
    warm_up_client(client, warmup_request(client), DEADLINE, watch=watch)


def diagnose(proc: Any) -> str:
    """Thread stacks of a running node (SIGUSR1 -> faulthandler in its log) and of this process."""
    import faulthandler
    import tempfile

    text = ''
    if proc.alive():
        before = len(proc.log_text())
        os.kill(proc.pid, signal.SIGUSR1)
        with contextlib.suppress(AssertionError):
            wait_until(lambda: 'Thread 0x' in proc.log_text()[before:], 5.0, what='stack dump')
        text += f'--- {proc.describe()} stacks:\n{proc.log_text()[before:]}\n'
    with tempfile.TemporaryFile('w+') as f:
        faulthandler.dump_traceback(f, all_threads=True)
        f.seek(0)
        text += f'--- test process stacks:\n{f.read()}'
    return text


# =========================================================================== fixtures
# Nodes are started with test/ros/launch.py (console script, own process group, log file); the
# test process talks to them through a helper node on the session's spinning executor.

class PlannerUnderTest:
    """A running planner node and the helper-side entities talking to it."""

    def __init__(self, node: Any, log_dir: FsPath, robot: str, ns: str = '') -> None:
        ros_args = ['-r', f'__ns:={ns}'] if ns else []
        self.name = f'{ns}/geodesic_planner'
        self.logger = f'{ns.strip("/")}.geodesic_planner' if ns else 'geodesic_planner'
        self.process = popen_node('geodesic_planner_node', *ros_args, params={'robot': robot},
                                  name=f'planner_{robot}', log_dir=log_dir)
        self.watch = [self.process]
        self._barriers = itertools.count()
        # subscriptions before clients: the clients' warm-up round trips then prove that the
        # node has matched them (see launch.wait_discovered)
        self.traj = Collector(node, JointTrajectory, f'{self.name}/joint_trajectory',
                              QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.markers = Collector(node, MarkerArray, f'{self.name}/path_markers',
                                 latched_qos(10))
        self.plan_client = node.create_client(GetPlan, f'{self.name}/plan')
        self.set_client = node.create_client(SetParameters, f'{self.name}/set_parameters')
        self.get_client = node.create_client(GetParameters, f'{self.name}/get_parameters')
        wait_until(lambda: self.traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='trajectory publisher matched', watch=self.watch)
        for client in (self.plan_client, self.set_client, self.get_client):
            ready(client, self.watch)

    def call(self, client: Any, request: Any) -> Any:
        """call_service; on a timeout, both sides' thread stacks go into the failure message."""
        try:
            return call_service(client, request, DEADLINE, watch=self.watch)
        except AssertionError as err:
            raise AssertionError(f'{err}\n{diagnose(self.process)}') from None

    def plan(self, request: GetPlan.Request) -> GetPlan.Response:
        return self.call(self.plan_client, request)

    def wait_trajectories(self, n: int) -> list[JointTrajectory]:
        return self.traj.wait_for(n, DEADLINE, watch=self.watch)

    def log_mark(self, rosout: Collector) -> int:
        """Index into ``rosout.messages`` from which on only lines caused from now on arrive.

        A line logged by an earlier test may still be on its way (a reply does not mean that
        its log line has arrived). Barrier: a harmless request whose error line names a frame
        used once (warm-up lines are ignored by :func:`rosout_since`), waited for; the node's
        /rosout publisher is reliable and in order, so every earlier line has arrived with it.
        """
        frame = f'{WARMUP_FRAME}barrier{next(self._barriers)}'
        k = len(rosout)
        assert not self.plan(GetPlan.Request(goal=pose_3r(*GOAL_3R, frame=frame))).plan.poses
        return 1 + rosout.wait_for_message(
            lambda m: m.name == self.logger and f"'{frame}'" in m.msg, k, DEADLINE,
            what=f'the barrier line of {self.name}', watch=self.watch)

    def set_parameters(self, **values: Any) -> list[Any]:
        req = SetParameters.Request()
        req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        return list(self.call(self.set_client, req).results)

    def get_parameter(self, name: str) -> Any:
        req = GetParameters.Request(names=[name])
        value = self.call(self.get_client, req).values[0]
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=value)).value

    def stop(self) -> None:
        rc = self.process.stop(signal.SIGINT)
        assert rc == 0, self.process.log_text()


@pytest.fixture(scope='module')
def rosout(helper: Any) -> Collector:
    return rosout_collector(helper)


@pytest.fixture(scope='module')
def planar(helper: Any, rosout: Collector,
           tmp_path_factory: pytest.TempPathFactory) -> Iterator[PlannerUnderTest]:
    p = PlannerUnderTest(helper, tmp_path_factory.mktemp('planar'), 'planar_3r')
    yield p
    p.stop()


@pytest.fixture(scope='module')
def ur5e(helper: Any, rosout: Collector,
         tmp_path_factory: pytest.TempPathFactory) -> Iterator[PlannerUnderTest]:
    p = PlannerUnderTest(helper, tmp_path_factory.mktemp('ur5e'), 'ur5e', ns='/ur5e')
    yield p
    p.stop()


# =========================================================================== oracles

ROBOT_3R = load_robot('planar_3r')
START_3R = (2.5, 1.5, math.radians(30.0))                 # paper Table 1: p and yaw of n
GOAL_3R = (1.5, 2.5, math.atan2(0.7, 0.714))
#: goal of a good plan that must be told apart from the paper plan by its last point
OTHER_GOAL_3R = (GOAL_3R[0], GOAL_3R[1] - 0.01, GOAL_3R[2])


def pose_3r(x: float, y: float, psi: float, frame: str = '') -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(psi / 2), math.cos(psi / 2)
    return msg


def request(start: PoseStamped, goal: PoseStamped, tolerance: float = 0.0) -> GetPlan.Request:
    return GetPlan.Request(start=start, goal=goal, tolerance=tolerance)


def paper_request() -> GetPlan.Request:
    return request(pose_3r(*START_3R), pose_3r(*GOAL_3R))


def ik_3r(x: float, y: float, phi: float) -> np.ndarray:
    """Closed-form IK of the unit-link planar 3R arm, elbow branch theta2 > 0 (paper Table 2)."""
    wx, wy = x - math.cos(phi), y - math.sin(phi)
    q2 = math.acos((wx * wx + wy * wy - 2.0) / 2.0)
    q1 = math.atan2(wy, wx) - math.atan2(math.sin(q2), 1.0 + math.cos(q2))
    return np.array([q1, q2, phi - q1 - q2])


def fk_3r(q: np.ndarray) -> np.ndarray:
    """(N, 3) joint angles -> (N, 3) rows (x, y, phi)."""
    c = np.cumsum(q, axis=1)
    return np.stack([np.cos(c).sum(1), np.sin(c).sum(1), c[:, 2]], axis=1)


def check_controller_contract(msg: JointTrajectory, names: list[str]) -> cv.TrajectoryArrays:
    """What joint_trajectory_controller validates, plus a zero stamp, all fields per point and rest at both ends."""
    assert cv.validate_joint_trajectory(msg) == []
    assert list(msg.joint_names) == names
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)
    assert len(msg.points) >= 2
    for p in msg.points:
        assert len(p.positions) == len(p.velocities) == len(p.accelerations) == len(names)
    arr = cv.joint_trajectory_to_arrays(msg)
    assert arr.t[0] == 0.0
    assert np.all(np.diff(arr.t) > 0.0)
    assert np.all(np.isfinite(arr.positions))
    assert_allclose(arr.velocities[0], 0.0, atol=1e-12)
    assert_allclose(arr.velocities[-1], 0.0, atol=1e-12)
    return arr


def check_limits(arr: cv.TrajectoryArrays, vmax: np.ndarray, amax: np.ndarray) -> None:
    assert np.all(np.abs(arr.velocities) <= vmax * (1 + 1e-6) + 1e-12)
    assert np.all(np.abs(arr.accelerations) <= amax * (1 + 1e-6) + 1e-12)
    # positions, velocities and accelerations are one trajectory (central differences, O(dt^2))
    t, q, dq = arr.t, arr.positions, arr.velocities
    fd = (q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None]
    assert_allclose(fd, dq[1:-1], atol=5e-3 * float(np.max(vmax)))


def check_line_phi_3r(arr: cv.TrajectoryArrays, atol: float = 1e-6) -> None:
    """Tool on the straight line A->B with phi linear in the fraction along it (exact oracle)."""
    xyphi = fk_3r(arr.positions)
    a, b = np.array(START_3R), np.array(GOAL_3R)
    d = b[:2] - a[:2]
    lam = (xyphi[:, :2] - a[:2]) @ d / (d @ d)
    on_line = a[:2] + lam[:, None] * d
    assert np.max(np.linalg.norm(xyphi[:, :2] - on_line, axis=1)) < atol
    assert np.max(np.abs(xyphi[:, 2] - (a[2] + lam * (b[2] - a[2])))) < atol
    assert np.all(np.diff(lam) >= -1e-9)
    assert_allclose(lam[[0, -1]], [0.0, 1.0], atol=atol)


def rosout_since(rosout: Collector, k0: int, logger: str, level: int | None = None,
                 warmup: bool = False) -> list[Log]:
    """/rosout records of ``logger`` (at ``level``) received after the first ``k0``; only the
    client warm-up lines when ``warmup``, else all but those."""
    msgs = rosout.messages[k0:]
    return [m for m in msgs if m.name == logger and (level is None or m.level == level)
            and (WARMUP_FRAME in m.msg) == warmup]


def wait_log(rosout: Collector, k0: int, logger: str, level: int, text: str) -> Log:
    """Wait for a /rosout record after the first ``k0`` containing ``text``."""
    return wait_until(
        lambda: next((m for m in rosout_since(rosout, k0, logger, level) if text in m.msg), None),
        DEADLINE, what=f'log {level} from {logger} containing {text!r}')


# =========================================================================== tests: 3R

def test_paper_3r_plan_meets_controller_contract(planar: PlannerUnderTest, rosout: Collector) -> None:
    k0 = planar.log_mark(rosout)
    n0 = len(planar.traj)
    resp = planar.plan(paper_request())
    msgs = planar.wait_trajectories(n0 + 1)
    assert len(msgs) == n0 + 1
    arr = check_controller_contract(msgs[-1], ROBOT_3R.joint_names)
    # first point: the IK solution of the start (paper Table 2 branch); last reaches the goal
    assert_allclose(arr.positions[0], ik_3r(*START_3R), atol=1e-8)
    assert_allclose(arr.positions[0], [0.258, 0.583, -0.317], atol=1e-3)
    assert_allclose(fk_3r(arr.positions[-1:])[0], GOAL_3R, atol=1e-8)
    check_line_phi_3r(arr)
    check_limits(arr, ROBOT_3R.max_velocity, ROBOT_3R.max_acceleration)
    # response: tool poses at the trajectory points, base frame
    assert resp.plan.header.frame_id == 'base_link'
    assert len(resp.plan.poses) == len(arr.t)
    assert_allclose(cv.path_to_matrices(resp.plan), ROBOT_3R.fk(arr.positions), atol=1e-9)
    # markers: line strip through the same tool positions, axes at start and goal
    markers = wait_until(
        lambda: (m := planar.markers.messages) and len(m[-1].markers[1].points) == len(arr.t)
        and m[-1], DEADLINE, what='markers of the plan', watch=planar.watch)
    line = markers.markers[1]
    assert line.type == Marker.LINE_STRIP and line.header.frame_id == 'base_link'
    assert_allclose([[p.x, p.y, p.z] for p in line.points], ROBOT_3R.fk(arr.positions)[:, :3, 3],
                    atol=1e-9)
    # one info line with the figures
    log = wait_log(rosout, k0, planar.logger, INFO, 'plan: ')
    assert f'plan: {len(arr.t)} points' in log.msg


def test_fresh_subscriber_gets_the_trajectory(planar: PlannerUnderTest, helper: Any) -> None:
    # subscribe and call at once (no wait for matching), as a user script would; a subscriber
    # with incompatible QoS (transient_local vs our volatile writer) must not get in the way
    stale = Collector(helper, JointTrajectory, f'{planar.name}/joint_trajectory',
                      latched_qos())
    fresh = Collector(helper, JointTrajectory, f'{planar.name}/joint_trajectory',
                      QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    n0 = len(planar.traj)
    try:
        for n in (1, 2):
            assert len(planar.plan(paper_request()).plan.poses) > 0
            check_controller_contract(fresh.wait_for(n, DEADLINE, watch=planar.watch)[-1],
                                      ROBOT_3R.joint_names)
        # incompatible QoS: never matched, so it can never receive (nothing to wait for)
        assert stale.subscription.get_publisher_count() == 0
        assert len(stale) == 0
        # the fixture's subscription got both as well (before the next test counts from it)
        planar.wait_trajectories(n0 + 2)
    finally:
        helper.destroy_subscription(stale.subscription)
        helper.destroy_subscription(fresh.subscription)


def test_frame_id_base_link_accepted(planar: PlannerUnderTest) -> None:
    n0 = len(planar.traj)
    resp = planar.plan(request(pose_3r(*START_3R, frame='base_link'),
                               pose_3r(*GOAL_3R, frame='base_link')))
    assert len(resp.plan.poses) > 0
    arr = check_controller_contract(planar.wait_trajectories(n0 + 1)[-1], ROBOT_3R.joint_names)
    check_line_phi_3r(arr)


def _unnormalised(msg: PoseStamped, factor: float) -> PoseStamped:
    msg.pose.orientation.z *= factor
    msg.pose.orientation.w *= factor
    return msg


def _nan_goal() -> GetPlan.Request:
    req = paper_request()
    req.goal.pose.position.x = float('nan')
    return req


def _bad_requests() -> list[tuple[str, Callable[[], GetPlan.Request], str]]:
    return [
        ('nan_position', _nan_goal, 'NaN'),
        ('nan_quaternion', lambda: request(pose_3r(*START_3R),
                                           _unnormalised(pose_3r(*GOAL_3R), float('nan'))), 'NaN'),
        ('unnormalised', lambda: request(_unnormalised(pose_3r(*START_3R), 1.1), pose_3r(*GOAL_3R)),
         'not normalised'),
        ('zero_goal_quaternion', lambda: request(pose_3r(*START_3R),
                                                 _unnormalised(pose_3r(*GOAL_3R), 0.0)),
         'not normalised'),
        ('unreachable', lambda: request(pose_3r(*START_3R), pose_3r(3.5, 1.0, 0.0)), 'IK failed'),
        ('wrong_frame', lambda: request(pose_3r(*START_3R), pose_3r(*GOAL_3R, frame='world')),
         "frame_id 'world'"),
        ('wrong_start_frame', lambda: request(pose_3r(*START_3R, frame='map'), pose_3r(*GOAL_3R)),
         "frame_id 'map'"),
        ('negative_tolerance', lambda: request(pose_3r(*START_3R), pose_3r(*GOAL_3R), -1.0),
         'tolerance'),
    ]


@pytest.mark.parametrize(('case', 'make', 'cause'), _bad_requests(), ids=[c[0] for c in _bad_requests()])
def test_failure_then_good_request(planar: PlannerUnderTest, rosout: Collector, case: str,
                                   make: Callable[[], GetPlan.Request], cause: str) -> None:
    k0 = planar.log_mark(rosout)
    n0 = len(planar.traj)
    resp = planar.plan(make())
    assert len(resp.plan.poses) == 0
    assert resp.plan.header.frame_id == 'base_link'
    wait_log(rosout, k0, planar.logger, ERROR, cause)
    # the node keeps serving: the next good request succeeds, and its trajectory is the only
    # one published since (one publisher, reliable, in order: a failure's message would be
    # first, so the next message must be the good one; its goal differs from every bad one's)
    good = planar.plan(request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R)))
    assert len(good.plan.poses) > 0
    msgs = planar.wait_trajectories(n0 + 1)
    assert len(msgs) == n0 + 1
    arr = check_controller_contract(msgs[-1], ROBOT_3R.joint_names)
    assert_allclose(arr.positions[0], ik_3r(*START_3R), atol=1e-8)
    assert_allclose(fk_3r(arr.positions[-1:])[0], OTHER_GOAL_3R, atol=1e-8)
    wait_log(rosout, k0, planar.logger, INFO, 'plan: ')
    errors = rosout_since(rosout, k0, planar.logger, ERROR)
    assert len(errors) == 1, [e.msg for e in errors]        # one error line naming the cause
    assert cause in errors[0].msg


def test_quaternion_normalised_when_close(planar: PlannerUnderTest) -> None:
    n0 = len(planar.traj)
    req = request(_unnormalised(pose_3r(*START_3R), 1.0005), _unnormalised(pose_3r(*GOAL_3R), 0.9995))
    assert len(planar.plan(req).plan.poses) > 0
    arr = check_controller_contract(planar.wait_trajectories(n0 + 1)[-1], ROBOT_3R.joint_names)
    assert_allclose(arr.positions[0], ik_3r(*START_3R), atol=1e-8)
    check_line_phi_3r(arr)


def test_tolerance_for_unreachable_pose(planar: PlannerUnderTest, rosout: Collector) -> None:
    # 5 cm out of the arm's plane: only reachable within a tolerance (3 joints, 6-D pose)
    goal = pose_3r(*GOAL_3R)
    goal.pose.position.z = 0.05
    k0 = planar.log_mark(rosout)
    n0 = len(planar.traj)
    assert len(planar.plan(request(pose_3r(*START_3R), goal, tolerance=0.0)).plan.poses) == 0
    wait_log(rosout, k0, planar.logger, ERROR, 'IK failed')
    assert len(planar.plan(request(pose_3r(*START_3R), goal, tolerance=0.01)).plan.poses) == 0
    resp = planar.plan(request(pose_3r(*START_3R), goal, tolerance=0.1))
    assert len(resp.plan.poses) > 0
    # only the successful request published: a sentinel plan (its own goal) must come right
    # after it (one publisher, in order; a failed request's plan would look like this one)
    assert len(planar.plan(request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R))).plan.poses) > 0
    msgs = planar.wait_trajectories(n0 + 2)
    assert len(msgs) == n0 + 2
    assert_allclose(fk_3r(cv.joint_trajectory_to_arrays(msgs[-1]).positions[-1:])[0], OTHER_GOAL_3R, atol=1e-8)
    arr = check_controller_contract(msgs[-2], ROBOT_3R.joint_names)
    # the nearest reachable pose: same x, y, phi in the plane
    assert_allclose(fk_3r(arr.positions[-1:])[0], GOAL_3R, atol=1e-6)
    check_line_phi_3r(arr)


def test_plan_timeout_fails_request_and_publishes_nothing(planar: PlannerUnderTest,
                                                          rosout: Collector) -> None:
    # A plan whose trajectory is published before the timeout fires succeeds (by design: it is
    # out). So the plan must take long compared with a scheduling delay of the waiting thread on a
    # busy machine: ~60000 points take on the order of a second to build before any publish.
    n0 = len(planar.traj)
    assert len(planar.plan(paper_request()).plan.poses) > 0
    last = planar.wait_trajectories(n0 + 1)[-1].points[-1].time_from_start
    duration = last.sec + last.nanosec * 1e-9
    k0 = planar.log_mark(rosout)
    n0 = len(planar.traj)
    try:
        assert all(r.successful for r in planar.set_parameters(plan_timeout=1e-6,
                                                               sample_period=duration / 60000))
        assert len(planar.plan(paper_request()).plan.poses) == 0
        wait_log(rosout, k0, planar.logger, ERROR, 'timed out after 1e-06 s')
    finally:
        assert all(r.successful for r in planar.set_parameters(plan_timeout=5.0, sample_period=0.01))
    # the abandoned (paper) plan was never published: the next message is this one (own goal)
    assert len(planar.plan(request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R))).plan.poses) > 0
    msgs = planar.wait_trajectories(n0 + 1)
    assert len(msgs) == n0 + 1
    arr = check_controller_contract(msgs[-1], ROBOT_3R.joint_names)
    assert_allclose(fk_3r(arr.positions[-1:])[0], OTHER_GOAL_3R, atol=1e-8)


def test_state_and_parameters_served_during_a_long_plan(planar: PlannerUnderTest, helper: Any,
                                                        rosout: Collector) -> None:
    """A plan with ~60000 points takes on the order of a second; a parameter change and a
    /joint_states message sent after it are handled before its response (they never wait
    behind a plan), and the plan still succeeds and is published once."""
    n0 = len(planar.traj)
    assert len(planar.plan(paper_request()).plan.poses) > 0
    last = planar.wait_trajectories(n0 + 1)[-1].points[-1].time_from_start
    duration = last.sec + last.nanosec * 1e-9
    pub = helper.create_publisher(JointState, '/joint_states', 10)
    try:
        wait_for_subscribers(pub, 1, DEADLINE, watch=planar.watch)
        assert all(r.successful for r in planar.set_parameters(
            sample_period=duration / 60000, plan_timeout=DEADLINE))
        k0 = planar.log_mark(rosout)
        n1 = len(planar.traj)
        future = planar.plan_client.call_async(paper_request())
        results = planar.set_parameters(velocity_scaling=1.0)
        assert all(r.successful for r in results)
        assert not future.done(), 'the parameter change waited for the plan'

        def published_and_warned() -> Any:
            pub.publish(_joint_state(['joint1', 'joint2', 'bogus'], [1.0, 1.0, 1.0]))
            return next((m for m in rosout_since(rosout, k0, planar.logger, WARN)
                         if 'missing robot joints' in m.msg), None)
        wait_until(published_and_warned, DEADLINE, what='joint state warning', watch=planar.watch)
        assert not future.done(), 'the joint state waited for the plan'
        wait_until(future.done, DEADLINE, what='the long plan', watch=planar.watch)
        assert len(future.result().plan.poses) > 50000
        msgs = planar.wait_trajectories(n1 + 1)
        assert len(msgs) == n1 + 1 and len(msgs[-1].points) > 50000
    finally:
        helper.destroy_publisher(pub)
        assert all(r.successful for r in planar.set_parameters(sample_period=0.01,
                                                                plan_timeout=5.0))


def _rss_mb(pid: int) -> float:
    for line in FsPath(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024.0
    raise AssertionError(f'no VmRSS for pid {pid}')


def _hammer(planar: PlannerUnderTest, helper: Any, rosout: Collector, per_client: int,
            traj: Collector, on_progress: Callable[[int], None] | None = None) -> int:
    """4 clients x ``per_client`` requests, alternating good and bad (4 kinds of bad).

    Checks: every request answered; good ones planned, bad ones empty with one error line each;
    every success published exactly once (a sentinel plan closes the run). Returns the successes.
    """
    bad_kinds = [make for name, make, _ in _bad_requests()
                 if name in ('nan_position', 'unnormalised', 'unreachable', 'wrong_frame')]
    clients = [helper.create_client(GetPlan, f'{planar.name}/plan') for _ in range(4)]
    results: list[tuple[int, int, bool]] = []
    errors: list[BaseException] = []
    lock = threading.Lock()
    k_warm = len(rosout)
    for client in clients:
        ready(client, planar.watch)
    # the warm-up error lines are excluded from the counts below; wait until they are in
    wait_until(lambda: len(rosout_since(rosout, k_warm, planar.logger, ERROR, warmup=True)) >= 4,
               DEADLINE, what='warm-up error lines')
    n0, k0 = len(traj), len(rosout)

    def run(c: int) -> None:
        try:
            for i in range(per_client):
                good = (c + i) % 2 == 0
                req = paper_request() if good else bad_kinds[(c + i // 2) % len(bad_kinds)]()
                resp = call_service(clients[c], req, DEADLINE, watch=planar.watch)
                with lock:
                    results.append((c, len(resp.plan.poses), good))
                    done = len(results)
                if on_progress is not None and c == 0:
                    on_progress(done)
        except BaseException as err:  # noqa: BLE001 - reported by the main thread
            errors.append(err)

    try:
        threads = [threading.Thread(target=run, args=(c,)) for c in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(per_client * DEADLINE)
        assert not errors, errors
        assert len(results) == 4 * per_client             # every request answered
        assert all((n > 0) == good for _, n, good in results)
        successes = sum(good for _, _, good in results)
        # a sentinel plan after all the others: in-order delivery from the one publisher means
        # that any duplicate would arrive before the sentinel's message
        assert len(planar.plan(paper_request()).plan.poses) > 0
        msgs = traj.wait_for(n0 + successes + 1, DEADLINE, watch=planar.watch)
        assert len(msgs) == n0 + successes + 1
        for msg in msgs[n0:]:
            check_controller_contract(msg, ROBOT_3R.joint_names)
        # the sentinel's "plan: " line is the last one (one /rosout publisher, in order): with
        # it, every error line is in (other INFO lines, e.g. "waited ... ms", are not counted).
        # Every plan is in a line: its own "plan: ", or a "plans: N ..." summary of plans done
        # while others waited (written before the next "plan: " line, so before the sentinel's)
        def plans_logged() -> int:
            lines = [m.msg for m in rosout_since(rosout, k0, planar.logger, INFO)]
            return (sum(line.startswith('plan: ') for line in lines)
                    + sum(int(line.split()[1]) for line in lines if line.startswith('plans: ')))
        wait_until(lambda: plans_logged() >= successes + 1, DEADLINE, what='every plan in a log line')
        assert plans_logged() == successes + 1
        assert len(rosout_since(rosout, k0, planar.logger, ERROR)) == 4 * per_client - successes
        return successes
    finally:
        for client in clients:
            helper.destroy_client(client)


def test_concurrent_clients_each_success_published_once(planar: PlannerUnderTest, helper: Any,
                                                         rosout: Collector) -> None:
    assert _hammer(planar, helper, rosout, 6, planar.traj) == 12


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_load_4x200_memory_flat(planar: PlannerUnderTest, helper: Any, rosout: Collector) -> None:
    traj = Collector(helper, JointTrajectory, f'{planar.name}/joint_trajectory',
                     QoSProfile(depth=10, history=HistoryPolicy.KEEP_ALL,
                                reliability=ReliabilityPolicy.RELIABLE))
    rss: dict[str, float] = {}

    def progress(done: int) -> None:
        if done >= 100 and 'warm' not in rss:
            rss['warm'] = _rss_mb(planar.process.pid)

    try:
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='publisher matched')
        assert _hammer(planar, helper, rosout, 200, traj, progress) == 400
        rss['end'] = _rss_mb(planar.process.pid)
    finally:
        helper.destroy_subscription(traj.subscription)
    print(f'planner node RSS after 100 requests {rss["warm"]:.1f} MB, after 800 {rss["end"]:.1f} MB')
    assert rss['end'] - rss['warm'] < 15.0, rss          # MB: flat after warm-up


# --------------------------------------------------------------------------- parameters

def test_parameter_rejection_keeps_old_values(planar: PlannerUnderTest, rosout: Collector) -> None:
    cases = [
        ({'velocity_scaling': 0.0}, 'velocity_scaling'),
        ({'velocity_scaling': 1.5}, 'velocity_scaling'),
        ({'velocity_scaling': float('nan')}, 'velocity_scaling'),
        ({'max_velocity': [1.0, 2.0]}, 'max_velocity: 2 values for a robot with 3 joints'),
        ({'max_acceleration': [1.0, -2.0, 1.0]}, 'max_acceleration'),
        ({'sample_period': 0.0}, 'sample_period'),
        ({'plan_timeout': 1e300}, 'plan_timeout: must be in [1e-06, 3600]'),
        ({'orientation_weight': 1e300}, 'orientation_weight: must be in [0.001, 1000]'),
        ({'orientation_weight': 500.0}, 'orientation_weight / position_weight must be in'),
        ({'metric': 'euclid'}, 'metric'),
        ({'joint_names': ['a', 'b']}, 'joint_names'),
        ({'joint_names': ['a', 'a', 'b']}, 'joint_names'),
        ({'robot': 'no_such_robot'}, "cannot load robot 'no_such_robot'"),
        ({'velocity_scaling': 'fast'}, 'velocity_scaling'),
    ]
    for values, reason in cases:
        (result,) = planar.set_parameters(**values)
        assert not result.successful, values
        assert reason in result.reason, (values, result.reason)
    assert planar.get_parameter('velocity_scaling') == 1.0
    assert list(planar.get_parameter('max_velocity')) == []
    assert planar.get_parameter('robot') == 'planar_3r'
    # still planning with the old configuration
    n0 = len(planar.traj)
    assert len(planar.plan(paper_request()).plan.poses) > 0
    arr = check_controller_contract(planar.wait_trajectories(n0 + 1)[-1], ROBOT_3R.joint_names)
    check_limits(arr, ROBOT_3R.max_velocity, ROBOT_3R.max_acceleration)


def test_velocity_scaling_is_time_scaling_and_limits_apply(planar: PlannerUnderTest) -> None:
    n0 = len(planar.traj)
    planar.plan(paper_request())
    full = cv.joint_trajectory_to_arrays(planar.wait_trajectories(n0 + 1)[-1])
    try:
        assert all(r.successful for r in planar.set_parameters(velocity_scaling=0.5))
        planar.plan(paper_request())
        half = check_controller_contract(planar.wait_trajectories(n0 + 2)[-1], ROBOT_3R.joint_names)
        # time scaling: twice as long, same path, q_half(t) = q_full(t / 2)
        assert half.t[-1] == pytest.approx(2.0 * full.t[-1], rel=1e-6)
        check_line_phi_3r(half)
        check_limits(half, 0.5 * ROBOT_3R.max_velocity, 0.25 * ROBOT_3R.max_acceleration)
        assert np.max(np.abs(half.velocities)) == pytest.approx(
            0.5 * np.max(np.abs(full.velocities)), rel=1e-3)
        # per-joint limits from parameters: one value for all joints, then one per joint
        assert all(r.successful for r in planar.set_parameters(velocity_scaling=1.0,
                                                                max_velocity=[0.3]))
        planar.plan(paper_request())
        slow = check_controller_contract(planar.wait_trajectories(n0 + 3)[-1], ROBOT_3R.joint_names)
        check_limits(slow, np.full(3, 0.3), ROBOT_3R.max_acceleration)
        assert np.max(np.abs(slow.velocities)) > 0.29                # the limit is reached
        assert all(r.successful for r in planar.set_parameters(max_velocity=[0.2, 0.4, 0.6],
                                                                max_acceleration=[1, 1, 1]))
        planar.plan(paper_request())
        per = check_controller_contract(planar.wait_trajectories(n0 + 4)[-1], ROBOT_3R.joint_names)
        check_limits(per, np.array([0.2, 0.4, 0.6]), np.ones(3))
    finally:
        planar.set_parameters(velocity_scaling=1.0, max_velocity=[], max_acceleration=[])


def test_sample_period_parameter(planar: PlannerUnderTest, rosout: Collector) -> None:
    n0 = len(planar.traj)
    try:
        assert all(r.successful for r in planar.set_parameters(sample_period=0.05))
        planar.plan(paper_request())
        arr = check_controller_contract(planar.wait_trajectories(n0 + 1)[-1], ROBOT_3R.joint_names)
        steps = np.diff(arr.t)
        assert_allclose(steps[:-1], 0.05, atol=1e-9)
        assert 0.0 < steps[-1] <= 0.05 + 1e-9
        # a period below the accepted range is refused at set time, with the range
        (result,) = planar.set_parameters(sample_period=5e-324)
        assert not result.successful and 'sample_period: must be in [1e-05, 10]' in result.reason
        # the smallest accepted period with a plan so long that the message would be huge: the
        # request is refused with the cause, the message never built
        k0 = planar.log_mark(rosout)
        assert all(r.successful for r in planar.set_parameters(sample_period=1e-5))
        assert len(planar.plan(paper_request()).plan.poses) == 0
        wait_log(rosout, k0, planar.logger, ERROR, 'increase sample_period')
    finally:
        planar.set_parameters(sample_period=0.01)
    assert len(planar.plan(paper_request()).plan.poses) > 0
    msgs = planar.wait_trajectories(n0 + 2)
    assert len(msgs) == n0 + 2
    check_controller_contract(msgs[-1], ROBOT_3R.joint_names)


# --------------------------------------------------------------------------- joint states

def _joint_state(names: list[str], q: list[float]) -> JointState:
    return JointState(name=names, position=[float(v) for v in q])


def _from_state_request() -> GetPlan.Request:
    start = PoseStamped()
    start.pose.orientation.w = 0.0                  # all-zero quaternion, empty frame_id
    return request(start, pose_3r(*GOAL_3R))


def test_plan_from_joint_states(planar: PlannerUnderTest, helper: Any, rosout: Collector) -> None:
    pub = helper.create_publisher(JointState, '/joint_states', 10)
    try:
        wait_for_subscribers(pub, 1, DEADLINE, watch=planar.watch)
        q_s = np.array([0.4, 0.7, -0.5])
        # shuffled order plus a joint the robot does not have
        good = _joint_state(['joint3', 'gripper', 'joint1', 'joint2'], [q_s[2], 9.0, q_s[0], q_s[1]])
        n_before = len(planar.traj)

        def attempt() -> GetPlan.Response | None:
            pub.publish(good)
            resp = planar.plan(_from_state_request())
            return resp if resp.plan.poses else None

        wait_until(attempt, DEADLINE, what='a plan from the published joint state',
                   watch=planar.watch)
        arr = check_controller_contract(planar.wait_trajectories(n_before + 1)[-1],
                                        ROBOT_3R.joint_names)
        assert_allclose(arr.positions[0], q_s, atol=1e-12)
        assert_allclose(fk_3r(arr.positions[-1:])[0], GOAL_3R, atol=1e-8)

        # hostile messages, each with positions that would visibly change the start
        k0 = planar.log_mark(rosout)
        hostile = [
            (_joint_state(['joint1', 'joint2', 'joint3'], [1.0, 1.0]), 'names but 2 positions'),
            (_joint_state(['joint1', 'joint2', 'bogus'], [1.0, 1.0, 1.0]), "missing robot joints ['joint3']"),
            (_joint_state(['a', 'b', 'c'], [1.0, 1.0, 1.0]), 'none of the robot joints'),
            (_joint_state(['joint1', 'joint2', 'joint3'], [1.0, float('nan'), 1.0]), 'non-finite'),
            (_joint_state(['joint1', 'joint1', 'joint3'], [1.0, 1.0, 1.0]), 'duplicate'),
            (JointState(name=['joint1', 'joint2', 'joint3'], position=[1.0, 1.0, 1.0],
                        velocity=[0.0]), 'velocity values'),
        ]
        for msg, text in hostile:
            def published_and_warned(msg: JointState = msg, text: str = text) -> Any:
                pub.publish(msg)
                return next((m for m in rosout_since(rosout, k0, planar.logger, WARN)
                             if text in m.msg), None)
            wait_until(published_and_warned, DEADLINE, what=f'warning {text!r}',
                       watch=planar.watch)
        n1 = len(planar.traj)
        resp = planar.plan(_from_state_request())
        assert len(resp.plan.poses) > 0
        arr = check_controller_contract(planar.wait_trajectories(n1 + 1)[-1], ROBOT_3R.joint_names)
        assert_allclose(arr.positions[0], q_s, atol=1e-12)       # still the last valid state

        # a well-formed state outside the joint limits is the robot's state: plans from it fail
        k1, n2 = planar.log_mark(rosout), len(planar.traj)
        outside = _joint_state(['joint1', 'joint2', 'joint3'], [4.0, 0.1, 0.1])
        planned_meanwhile = [0]    # plans that still started from q_s (the new state not taken yet)

        def refused() -> bool:
            pub.publish(outside)
            if planar.plan(_from_state_request()).plan.poses:
                planned_meanwhile[0] += 1
                return False
            return True

        wait_until(refused, DEADLINE, what='a refused plan from an out-of-limits state',
                   watch=planar.watch)
        wait_log(rosout, k1, planar.logger, ERROR, 'joint1=4 not in [-3.14159, 3.14159]')
        wait_until(attempt, DEADLINE, what='a plan after the state is valid again',
                   watch=planar.watch)
        msgs = planar.wait_trajectories(n2 + planned_meanwhile[0] + 1)
        assert len(msgs) == n2 + planned_meanwhile[0] + 1
        for msg in msgs[n2:]:
            assert_allclose(cv.joint_trajectory_to_arrays(msg).positions[0], q_s, atol=1e-12)
    finally:
        helper.destroy_publisher(pub)


# --------------------------------------------------------------------------- 6-joint arm

def line_slerp_request(robot: Any, q0: np.ndarray, frame: str = '') -> tuple[GetPlan.Request, np.ndarray, np.ndarray]:
    """Start at fk(q0); goal 0.18 m away along a line and rotated by 30 deg about a fixed axis."""
    T_a = robot.fk(q0)
    axis = np.array([1.0, 2.0, -1.0]) / math.sqrt(6.0)
    T_b = make_transform(T_a[:3, 3] + [0.12, -0.08, 0.1],
                         so3_exp(math.radians(30.0) * axis) @ T_a[:3, :3])
    req = request(cv.matrix_to_pose_stamped(T_a, frame), cv.matrix_to_pose_stamped(T_b, frame))
    return req, T_a, T_b


def check_line_slerp(robot: Any, arr: cv.TrajectoryArrays, T_a: np.ndarray, T_b: np.ndarray,
                     atol: float = 1e-6) -> np.ndarray:
    """Tool path = straight line + slerp with one parameter (exact geodesic for 6 joints)."""
    tool = robot.fk(arr.positions)
    assert_allclose(tool[0], T_a, atol=1e-8)
    assert_allclose(tool[-1], T_b, atol=1e-8)
    d = T_b[:3, 3] - T_a[:3, 3]
    lam = (tool[:, :3, 3] - T_a[:3, 3]) @ d / (d @ d)
    assert np.max(np.linalg.norm(tool[:, :3, 3] - (T_a[:3, 3] + lam[:, None] * d), axis=1)) < atol
    w = so3_log(T_a[:3, :3].T @ T_b[:3, :3])
    R_line = T_a[:3, :3] @ so3_exp(lam[:, None] * w)
    assert np.max(np.linalg.norm(so3_log(np.swapaxes(R_line, 1, 2) @ tool[:, :3, :3]), axis=1)) < atol
    assert np.all(np.diff(lam) >= -1e-9)
    return tool


def test_ur5e_line_and_rotation(ur5e: PlannerUnderTest) -> None:
    robot = load_robot('ur5e')
    req, T_a, T_b = line_slerp_request(robot, np.array([0.3, -1.2, 1.4, -1.7, -1.5, 0.2]))
    n0 = len(ur5e.traj)
    resp = ur5e.plan(req)
    assert len(resp.plan.poses) > 0
    msgs = ur5e.wait_trajectories(n0 + 1)
    assert len(msgs) == n0 + 1
    arr = check_controller_contract(msgs[-1], robot.joint_names)
    check_limits(arr, robot.max_velocity, robot.max_acceleration)
    tool = check_line_slerp(robot, arr, T_a, T_b)
    assert_allclose(cv.path_to_matrices(resp.plan), tool, atol=1e-9)


def _pose_from_columns(p: tuple, n: tuple, o: tuple, a: tuple) -> PoseStamped:
    """Paper Table 5 pose (3 printed decimals): nearest rotation of (n o a), as a message."""
    U, _, Vt = np.linalg.svd(np.array([n, o, a]).T)
    return cv.matrix_to_pose_stamped(make_transform(p, U @ Vt), '')


def test_rrpp_paper_poses_and_tolerance(start_node: Any, helper: Any) -> None:
    # 4 joints, 6-D poses printed to 3 decimals: reachable only within a tolerance (docs/maths.md §3)
    robot = load_robot('rrpp')
    A = _pose_from_columns((-0.501, -0.901, -0.699), (0.100, -0.810, 0.577), (-0.102, 0.569, 0.816),
                           (-0.990, -0.141, -0.026))
    B = _pose_from_columns((-0.600, -0.800, -0.599), (0.105, -0.810, 0.577), (-0.016, 0.579, 0.815),
                           (-0.994, -0.095, 0.047))
    proc = start_node('geodesic_planner_node', '-r', '__ns:=/rrpp', params={'robot': 'rrpp'})
    traj = Collector(helper, JointTrajectory, '/rrpp/geodesic_planner/joint_trajectory',
                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    client = helper.create_client(GetPlan, '/rrpp/geodesic_planner/plan')  # its warm-up: traj matched
    try:
        ready(client, [proc])
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='publisher matched', watch=[proc])
        # "from the current joint state" before any joint state for this robot: a clear failure
        from_state = request(PoseStamped(), B)
        from_state.start.pose.orientation.w = 0.0
        assert len(call_service(client, from_state, DEADLINE, watch=[proc]).plan.poses) == 0
        wait_until(lambda: 'no valid /joint_states message with the joints' in proc.log_text(),
                   DEADLINE, what='no-joint-state error line')
        strict = call_service(client, request(A, B, tolerance=1e-4), DEADLINE, watch=[proc])
        assert len(strict.plan.poses) == 0
        wait_until(lambda: 'IK failed' in proc.log_text(), DEADLINE, what='IK error line')
        resp = call_service(client, request(A, B, tolerance=0.01), DEADLINE, watch=[proc])
        assert len(resp.plan.poses) > 0
        msgs = traj.wait_for(1, DEADLINE, watch=[proc])
        assert len(msgs) == 1                              # the strict request published nothing
        arr = check_controller_contract(msgs[0], robot.joint_names)
        check_limits(arr, robot.max_velocity, robot.max_acceleration)
        # paper Table 6 (signs restored in docs/maths.md §5), printed to 3 decimals
        assert_allclose(arr.positions[0], [0.123, -1.539, 0.276, -0.640], atol=2e-3)
        assert_allclose(arr.positions[-1], [0.129, -1.629, 0.239, -0.643], atol=2e-3)
        dp, dr = pose_error(robot.fk(arr.positions[-1]), cv.pose_to_matrix(B.pose))
        assert dp < 1e-3 and dr < 1e-3                      # the nearest reachable pose
    finally:
        helper.destroy_client(client)
        helper.destroy_subscription(traj.subscription)
    assert proc.stop() == 0


def test_robot_description_with_chain_ends_and_joint_names(start_node: Any, helper: Any,
                                                            tmp_path: FsPath) -> None:
    xml = (FsPath(geodesic_planner.__file__).parent / 'data' / 'kr6_like.urdf').read_text()
    names = [f'axis_{i}' for i in range(1, 7)]
    params = tmp_path / 'kr6.yaml'
    params.write_text(yaml.safe_dump({'/kr6/geodesic_planner': {'ros__parameters': {
        'robot_description': xml, 'base_link': 'kr6_base_link', 'tip_link': 'kr6_tool0',
        'joint_names': names, 'robot': 'no_such_robot'}}}))     # robot_description wins
    proc = start_node('geodesic_planner_node', '-r', '__ns:=/kr6', '--params-file', str(params))
    robot = chain_from_urdf(xml, 'kr6_base_link', 'kr6_tool0')
    traj = Collector(helper, JointTrajectory, '/kr6/geodesic_planner/joint_trajectory',
                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    client = helper.create_client(GetPlan, '/kr6/geodesic_planner/plan')  # its warm-up: traj matched
    try:
        ready(client, [proc])
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='kr6 trajectory publisher', watch=[proc])
        req, T_a, T_b = line_slerp_request(robot, np.array([0.2, -1.2, 1.0, 0.3, 0.8, 0.1]),
                                           frame='kr6_base_link')
        resp = call_service(client, req, DEADLINE, watch=[proc])
        assert len(resp.plan.poses) > 0, proc.log_text()
        assert resp.plan.header.frame_id == 'kr6_base_link'
        arr = check_controller_contract(traj.wait_for(1, DEADLINE, watch=[proc])[0], names)
        check_limits(arr, robot.max_velocity, robot.max_acceleration)
        check_line_slerp(robot, arr, T_a, T_b)
        req.goal.header.frame_id = 'world'                        # the URDF root is not the base
        assert len(call_service(client, req, DEADLINE, watch=[proc]).plan.poses) == 0
        wait_until(lambda: "frame_id 'world' is not the base frame 'kr6_base_link'"
                   in proc.log_text(), DEADLINE, what='the error line in the node log')
        # nothing published for it: a sentinel plan (another goal) must be the next message
        sentinel, _, T_s = line_slerp_request(robot, np.array([0.1, -1.0, 1.1, 0.2, 0.7, 0.0]),
                                              frame='kr6_base_link')
        assert len(call_service(client, sentinel, DEADLINE, watch=[proc]).plan.poses) > 0
        msgs = traj.wait_for(2, DEADLINE, watch=[proc])
        assert_allclose(robot.fk(cv.joint_trajectory_to_arrays(msgs[1]).positions[-1]), T_s, atol=1e-6)
    finally:
        helper.destroy_client(client)
        helper.destroy_subscription(traj.subscription)
    assert proc.stop() == 0


def test_robot_swap_at_runtime(start_node: Any, helper: Any) -> None:
    proc = start_node('geodesic_planner_node', '-r', '__ns:=/swap', params={'robot': 'planar_3r'})
    traj = Collector(helper, JointTrajectory, '/swap/geodesic_planner/joint_trajectory',
                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    plan = helper.create_client(GetPlan, '/swap/geodesic_planner/plan')   # warm-ups: traj matched
    atomic = helper.create_client(SetParametersAtomically,
                                  '/swap/geodesic_planner/set_parameters_atomically')
    robot = load_robot('ur5e')
    names = [f'ur_{n}' for n in robot.joint_names]
    try:
        for c in (plan, atomic):
            ready(c, [proc])
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='publisher matched', watch=[proc])

        def set_atomically(**values: Any) -> Any:
            req = SetParametersAtomically.Request(
                parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
            return call_service(atomic, req, DEADLINE, watch=[proc]).result

        bad = set_atomically(robot='ur5e', joint_names=['a', 'b', 'c'])
        assert not bad.successful and 'joint_names' in bad.reason
        assert set_atomically(robot='ur5e', joint_names=names).successful
        req, T_a, T_b = line_slerp_request(robot, np.array([0.3, -1.2, 1.4, -1.7, -1.5, 0.2]))
        assert len(call_service(plan, req, DEADLINE, watch=[proc]).plan.poses) > 0
        arr = check_controller_contract(traj.wait_for(1, DEADLINE, watch=[proc])[0], names)
        check_line_slerp(robot, arr, T_a, T_b)
        # the paper's 3R request is now for a 6-joint arm: unreachable, answered with a reason;
        # nothing published for it: a sentinel plan (another goal) must be the next message
        assert len(call_service(plan, paper_request(), DEADLINE, watch=[proc]).plan.poses) == 0
        sentinel, _, T_s = line_slerp_request(robot, np.array([0.1, -1.0, 1.1, -1.5, -1.4, 0.0]))
        assert len(call_service(plan, sentinel, DEADLINE, watch=[proc]).plan.poses) > 0
        msgs = traj.wait_for(2, DEADLINE, watch=[proc])
        assert_allclose(robot.fk(cv.joint_trajectory_to_arrays(msgs[1]).positions[-1]), T_s, atol=1e-6)
    finally:
        helper.destroy_client(plan)
        helper.destroy_client(atomic)
        helper.destroy_subscription(traj.subscription)
    assert proc.stop() == 0


def test_parameters_have_descriptions(planar: PlannerUnderTest, helper: Any) -> None:
    client = helper.create_client(DescribeParameters, f'{planar.name}/describe_parameters')
    names = ['robot', 'robot_description', 'base_link', 'tip_link', 'joint_names', 'metric',
             'position_weight', 'orientation_weight', 'max_velocity', 'max_acceleration',
             'velocity_scaling', 'sample_period', 'frame_id', 'plan_timeout']
    try:
        ready(client, planar.watch)
        resp = call_service(client, DescribeParameters.Request(names=names), DEADLINE)
    finally:
        helper.destroy_client(client)
    assert [d.name for d in resp.descriptors] == names
    assert all(d.description for d in resp.descriptors)


def test_joint_names_override_at_runtime(planar: PlannerUnderTest) -> None:
    n0 = len(planar.traj)
    try:
        assert all(r.successful for r in planar.set_parameters(joint_names=['a', 'b', 'c']))
        assert len(planar.plan(paper_request()).plan.poses) > 0
        arr = check_controller_contract(planar.wait_trajectories(n0 + 1)[-1], ['a', 'b', 'c'])
        check_line_phi_3r(arr)
    finally:
        assert all(r.successful for r in planar.set_parameters(joint_names=[]))
    assert len(planar.plan(paper_request()).plan.poses) > 0
    check_controller_contract(planar.wait_trajectories(n0 + 2)[-1], ROBOT_3R.joint_names)


# --------------------------------------------------------------------------- process

@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_signal_exits_zero(start_node: Any, helper: Any, sig: signal.Signals) -> None:
    proc = start_node('geodesic_planner_node', '-r', f'__ns:=/{sig.name.lower()}',
                      params={'robot': 'planar_3r'})
    client = helper.create_client(GetPlan, f'/{sig.name.lower()}/geodesic_planner/plan')
    try:
        wait_for_service(client, DEADLINE, watch=[proc])
    finally:
        helper.destroy_client(client)
    os.killpg(proc.pid, sig)
    try:
        rc = proc.popen.wait(15.0)
    except subprocess.TimeoutExpired:
        raise AssertionError(f'no exit 15 s after {sig.name}\n{diagnose(proc)}') from None
    out = proc.log_text()
    assert rc == 0, out
    assert 'Traceback' not in out


def test_sigint_while_planning_exits_zero(start_node: Any, helper: Any) -> None:
    proc = start_node('geodesic_planner_node', '-r', '__ns:=/busy', params={'robot': 'planar_3r'})
    traj = Collector(helper, JointTrajectory, '/busy/geodesic_planner/joint_trajectory',
                     QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    clients = [helper.create_client(GetPlan, '/busy/geodesic_planner/plan') for _ in range(2)]
    stop = threading.Event()

    def hammer(client: Any) -> None:
        while not stop.is_set():
            future = client.call_async(paper_request())
            while not future.done() and not stop.is_set():
                stop.wait(0.01)
            if not future.done():
                client.remove_pending_request(future)

    threads = [threading.Thread(target=hammer, args=(c,)) for c in clients]
    try:
        for c in clients:
            ready(c, [proc])
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='publisher matched', watch=[proc])
        for t in threads:
            t.start()
        traj.wait_for(5, DEADLINE, watch=[proc])     # requests keep coming while we signal
        os.killpg(proc.pid, signal.SIGINT)
        try:
            rc = proc.popen.wait(15.0)
        except subprocess.TimeoutExpired:
            raise AssertionError(f'no exit 15 s after SIGINT under load\n{diagnose(proc)}') from None
    finally:
        stop.set()
        for t in threads:
            t.join(10)
        for c in clients:
            helper.destroy_client(c)
        helper.destroy_subscription(traj.subscription)
    out = proc.log_text()
    assert rc == 0, out
    assert 'Traceback' not in out, out


@pytest.mark.parametrize(('params', 'text'), [
    ({'robot': 'no_such_robot'}, "cannot load robot 'no_such_robot'"),
    ({'velocity_scaling': 2.0}, 'velocity_scaling'),
    ({'max_velocity': [1.0, 2.0]}, 'max_velocity'),
    ({'robot': '/nonexistent/arm.urdf'}, 'cannot load'),
    ({'robot': 3}, 'robot'),
])
def test_bad_start_exits_nonzero_without_traceback(start_node: Any, params: dict[str, Any],
                                                    text: str) -> None:
    proc = start_node('geodesic_planner_node', params=params)
    rc = proc.wait(DEADLINE)
    out = proc.log_text()
    assert rc == 1, out
    assert 'cannot start' in out and text in out, out
    assert 'Traceback' not in out, out


BRANCHING_URDF = """<robot name="branchy">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="base"/><child link="b"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>
"""


FLOATING_URDF = """<robot name="floaty">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="floating"><parent link="base"/><child link="a"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
</robot>
"""


@pytest.mark.parametrize(('urdf', 'cause'), [
    (BRANCHING_URDF, 'cannot load robot_description'),
    (FLOATING_URDF, "joint 'j1' has unsupported type 'floating'"),
    ('<robot name="broken"><link', 'not valid XML'),
], ids=['branching', 'floating_joint', 'bad_xml'])
def test_unusable_urdf_exits_nonzero(start_node: Any, tmp_path: FsPath, urdf: str,
                                     cause: str) -> None:
    params = tmp_path / 'params.yaml'
    params.write_text(yaml.safe_dump(
        {'geodesic_planner': {'ros__parameters': {'robot_description': urdf}}}))
    proc = start_node('geodesic_planner_node', '--params-file', str(params))
    rc = proc.wait(DEADLINE)
    out = proc.log_text()
    assert rc == 1, out
    assert 'cannot start: cannot load robot_description' in out, out
    assert cause in out and 'Traceback' not in out, out
