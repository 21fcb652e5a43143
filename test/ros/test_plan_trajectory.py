"""The PlanTrajectory service through the real planner node: error codes, execute, start state.

Oracles: closed-form IK and FK of the planar 3R arm (both elbow branches), the straight line
with linear phi, the polyline through the via poses (blends: the balls of blend_radius around
them), the robot's and a joint_limits.yaml's limits, forward kinematics of the URDF model.
Waits are on replies and messages, with deadlines; "nothing was published" is proven by a later
message that must arrive first (one publisher, reliable, in order).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path as FsPath
from typing import Any

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory
from numpy.testing import assert_allclose
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from geometry_msgs.msg import PoseStamped
from trajectory_msgs.msg import JointTrajectory

import geodesic_planner
import urdf_util as U
from line_cases import MISSED, THROUGH_ELBOW
from geodesic_planner.core.urdf import chain_from_urdf
from geodesic_planner.ros import conversions as cv

from tools.graph import StatusWatch

from .launch import Collector, call_service, latched_qos, popen_node, rosout_collector, wait_until, warm_up_client
from .test_planner_node import (GOAL_3R, OTHER_GOAL_3R, ROBOT_3R, START_3R,
                                check_controller_contract, check_limits, check_line_phi_3r,
                                fk_3r, ik_3r, pose_3r)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0
OK = PlanErrorCode.SUCCESS
KR6_URDF = FsPath(geodesic_planner.__file__).parent / 'data' / 'kr6_like.urdf'
#: three via poses (x, y, phi) between START_3R and GOAL_3R, wrist points within 1.8 m of the base
VIAS_3R = ((2.0, 1.9, math.radians(40.0)), (1.7, 1.5, math.radians(30.0)),
           (1.6, 2.2, math.radians(50.0)))
#: blend radius, m: under half the shortest segment (0.32 m), so the balls around the vias are apart
BLEND_R = 0.09


def ik_3r_down(x: float, y: float, phi: float) -> np.ndarray:
    """Closed-form IK of the planar 3R arm, the other elbow branch (theta2 < 0)."""
    q1, q2, _ = ik_3r(x, y, phi)
    wx, wy = x - math.cos(phi), y - math.sin(phi)
    q1 = math.atan2(wy, wx) + math.atan2(math.sin(q2), 1.0 + math.cos(q2))
    return np.array([q1, -q2, phi - q1 + q2])


def joints(names: list[str], q: Any) -> JointState:
    return JointState(name=list(names), position=[float(v) for v in q])


def plan_request(start: Any = None, goal: Any = None, *, start_joints: Any = None,
                 goal_joints: Any = None, execute: bool = False, names: list[str] | None = None,
                 **fields: Any) -> PlanTrajectory.Request:
    """A PlanTrajectory request; start None = from the current state (default-constructed)."""
    names = names or ROBOT_3R.joint_names
    req = PlanTrajectory.Request(execute=execute, **fields)
    if start is not None:
        req.start = start
    if goal is not None:
        req.goal = goal
    if start_joints is not None:
        req.start_joints = joints(names, start_joints)
    if goal_joints is not None:
        req.goal_joints = joints(names, goal_joints)
    return req


class Planner:
    """A planner node, a PlanTrajectory client, a /joint_states publisher and collectors."""

    def __init__(self, helper: Any, log_dir: FsPath, params: dict[str, Any], ns: str) -> None:
        self.helper = helper
        self.name = f'{ns}/geodesic_planner'
        self.process = popen_node('geodesic_planner_node', '-r', f'__ns:={ns}', params=params,
                                  name=ns.strip('/'), log_dir=log_dir)
        self.watch = [self.process]
        self.traj = Collector(helper, JointTrajectory, f'{self.name}/joint_trajectory',
                              QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.states = helper.create_publisher(JointState, '/joint_states', 10)   # absolute in the node
        self.client = helper.create_client(PlanTrajectory, f'{self.name}/plan_trajectory')
        self.set_client = helper.create_client(SetParameters, f'{self.name}/set_parameters')
        try:
            wait_until(lambda: self.traj.subscription.get_publisher_count() > 0, DEADLINE,
                       what='trajectory publisher matched', watch=self.watch)
            # harmless round trips: a request with an unknown frame (FRAME_TRANSFORM_FAILURE)
            warm_up_client(self.client, plan_request(goal=pose_3r(*GOAL_3R, frame='__warmup__')),
                           DEADLINE, watch=self.watch)
            warm_up_client(self.set_client, SetParameters.Request(parameters=[]), DEADLINE,
                           watch=self.watch)
        except BaseException:
            self.process.stop()          # never leave a node running behind a failed start
            raise

    def plan(self, req: PlanTrajectory.Request) -> PlanTrajectory.Response:
        return call_service(self.client, req, DEADLINE, watch=self.watch)

    def set_parameters(self, **values: Any) -> None:
        req = SetParameters.Request(
            parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
        results = call_service(self.set_client, req, DEADLINE, watch=self.watch).results
        assert all(r.successful for r in results), [r.reason for r in results]

    def set_state(self, q: np.ndarray, names: list[str], goal: Any) -> None:
        """Publish ``q`` on /joint_states until a from-state plan to ``goal`` starts exactly at it.

        The node's subscription is best effort, so one message may be lost; the reply (the
        plan's first point) proves which state the node holds.
        """
        def holds() -> bool:
            self.states.publish(joints(names, q))
            resp = self.plan(goal(PlanTrajectory.Request()))
            return (resp.error_code.val == OK
                    and np.allclose(resp.trajectory.points[0].positions, q, atol=1e-12, rtol=0))
        wait_until(holds, DEADLINE, what=f'joint state {list(q)} taken by the node', watch=self.watch)

    def stop(self) -> None:
        assert self.process.stop() == 0, self.process.log_text()


def goal_3r(req: PlanTrajectory.Request) -> PlanTrajectory.Request:
    req.goal = pose_3r(*GOAL_3R)
    return req


@pytest.fixture(scope='module')
def planar(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Planner]:
    p = Planner(helper, tmp_path_factory.mktemp('pt_planar'), {'robot': 'planar_3r'}, '/pt')
    try:
        p.set_state(ik_3r(*START_3R), ROBOT_3R.joint_names, goal_3r)
        yield p
    finally:
        p.stop()


# =========================================================================== success

def test_success_reply_carries_the_plan(planar: Planner) -> None:
    resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    assert resp.error_code.val == OK and resp.message.startswith('min_clearance '), resp.message
    arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
    assert_allclose(arr.positions[0], ik_3r(*START_3R), atol=1e-8)
    assert_allclose(fk_3r(arr.positions[-1:])[0], GOAL_3R, atol=1e-8)
    check_line_phi_3r(arr)
    check_limits(arr, ROBOT_3R.max_velocity, ROBOT_3R.max_acceleration)
    # tool path: the tool poses at the trajectory's points (base frame)
    assert resp.tool_path.header.frame_id == 'base_link'
    assert_allclose(cv.path_to_matrices(resp.tool_path), ROBOT_3R.fk(arr.positions), atol=1e-9)
    assert resp.solver_method in ('pullback', 'collocation')
    assert 0.0 <= resp.path_error < 1e-6          # the tool on the line (the oracle above agrees)
    assert 0.0 < resp.planning_time < DEADLINE


def test_unset_start_means_current_state(planar: Planner) -> None:
    q = ik_3r(*START_3R)
    zero = PlanTrajectory.Request()
    zero.start.pose.orientation.w = 0.0              # the GetPlan marker works too
    for req in (PlanTrajectory.Request(), zero):
        resp = planar.plan(goal_3r(req))
        assert resp.error_code.val == OK, resp.message
        assert_allclose(resp.trajectory.points[0].positions, q, atol=1e-12, rtol=0)


def test_scaling_factors_slow_the_plan(planar: Planner) -> None:
    full = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    half = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                    velocity_scaling_factor=0.5, acceleration_scaling_factor=0.25))
    assert full.error_code.val == half.error_code.val == OK
    a_full = cv.joint_trajectory_to_arrays(full.trajectory)
    a_half = cv.joint_trajectory_to_arrays(half.trajectory)
    check_limits(a_half, 0.5 * ROBOT_3R.max_velocity, 0.25 * ROBOT_3R.max_acceleration)
    # velocity x 0.5 and acceleration x 0.25 is exact time scaling by 2 (same path)
    assert a_half.t[-1] == pytest.approx(2.0 * a_full.t[-1], rel=1e-6)


# =========================================================================== execute

def test_execute_false_publishes_nothing_and_true_publishes_the_reply(planar: Planner) -> None:
    n0 = len(planar.traj)
    quiet = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    loud = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R), execute=True))
    assert quiet.error_code.val == loud.error_code.val == OK
    msgs = planar.traj.wait_for(n0 + 1, DEADLINE, watch=planar.watch)
    # one publisher, reliable, in order: had the first plan been published, it would come first
    assert msgs[n0] == loud.trajectory
    assert msgs[n0] != quiet.trajectory
    assert_allclose(fk_3r(np.array([msgs[n0].points[-1].positions]))[0], OTHER_GOAL_3R, atol=1e-8)
    # and exactly once: a sentinel plan is the next message
    sentinel = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), execute=True))
    msgs = planar.traj.wait_for(n0 + 2, DEADLINE, watch=planar.watch)
    assert len(msgs) == n0 + 2 and msgs[n0 + 1] == sentinel.trajectory


# =========================================================================== error codes

def _nan_goal() -> PlanTrajectory.Request:
    req = plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R))
    req.goal.pose.position.x = float('nan')
    return req


def _other_branch_start() -> PlanTrajectory.Request:
    # joints 0.1 rad from the state on joint1: beyond the default allowed_start_tolerance 0.01
    return plan_request(start_joints=ik_3r(*START_3R) + [0.1, 0.0, 0.0], goal=pose_3r(*GOAL_3R))


def _far_start_pose() -> PlanTrajectory.Request:
    # a reachable start pose whose IK (seeded with the state) is far from the state
    return plan_request(pose_3r(*GOAL_3R), pose_3r(*START_3R))


CASES: list[tuple[str, Callable[[], PlanTrajectory.Request], int, str]] = [
    ('nan', _nan_goal, PlanErrorCode.INVALID_REQUEST, 'NaN'),
    ('unnormalised', lambda: plan_request(pose_3r(*START_3R), _scaled(pose_3r(*GOAL_3R), 1.1)),
     PlanErrorCode.INVALID_REQUEST, 'not normalised'),
    ('no goal', lambda: plan_request(pose_3r(*START_3R)), PlanErrorCode.INVALID_REQUEST, 'goal'),
    ('pose and joints', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                             goal_joints=ik_3r(*GOAL_3R)),
     PlanErrorCode.INVALID_REQUEST, 'not both'),
    ('wrong joint names', lambda: plan_request(goal_joints=[0.1, 0.2, 0.3], names=['a', 'b', 'c']),
     PlanErrorCode.INVALID_REQUEST, 'goal_joints'),
    ('factor', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                    velocity_scaling_factor=1.5),
     PlanErrorCode.INVALID_REQUEST, 'velocity_scaling_factor'),
    ('frame', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R, frame='world')),
     PlanErrorCode.FRAME_TRANSFORM_FAILURE, "frame_id 'world'"),
    ('via frame', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                       via_poses=[pose_3r(2.0, 2.0, 0.8, frame='map')]),
     PlanErrorCode.FRAME_TRANSFORM_FAILURE, "via_poses[0]: frame_id 'map'"),
    ('unreachable', lambda: plan_request(pose_3r(*START_3R), pose_3r(3.5, 1.0, 0.0)),
     PlanErrorCode.NO_IK_SOLUTION, 'IK'),
    ('start joints', _other_branch_start, PlanErrorCode.START_STATE_MISMATCH, 'allowed_start_tolerance'),
    ('start pose', _far_start_pose, PlanErrorCode.START_STATE_MISMATCH, 'allowed_start_tolerance'),
    ('joint limits', lambda: plan_request(goal_joints=[4.0, 0.0, 0.0]),
     PlanErrorCode.JOINT_LIMITS_VIOLATED, 'outside its limits'),
    ('blend negative', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                            via_poses=[pose_3r(*VIAS_3R[0])], blend_radius=-0.01),
     PlanErrorCode.INVALID_REQUEST, 'blend_radius'),
    ('blend nan', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                       via_poses=[pose_3r(*VIAS_3R[0])], blend_radius=math.nan),
     PlanErrorCode.INVALID_REQUEST, 'blend_radius'),
    ('blend inf', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), blend_radius=math.inf),
     PlanErrorCode.INVALID_REQUEST, 'blend_radius'),
    ('too long', lambda: plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                      velocity_scaling_factor=1e-4, acceleration_scaling_factor=1e-8),
     PlanErrorCode.PLANNING_FAILED, 'more than 100000'),
]


def _scaled(msg: Any, factor: float) -> Any:
    msg.pose.orientation.z *= factor
    msg.pose.orientation.w *= factor
    return msg


def _good_after(planar: Planner, n0: int) -> None:
    """The node keeps serving: a good executed plan is the only message published since ``n0``."""
    good = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R), execute=True))
    assert good.error_code.val == OK, good.message
    msgs = planar.traj.wait_for(n0 + 1, DEADLINE, watch=planar.watch)
    assert len(msgs) == n0 + 1 and msgs[n0] == good.trajectory


@pytest.mark.parametrize(('case', 'make', 'code', 'reason'), CASES, ids=[c[0] for c in CASES])
def test_error_code_and_reason_in_the_reply(planar: Planner, case: str,
                                            make: Callable[[], PlanTrajectory.Request], code: int,
                                            reason: str) -> None:
    n0 = len(planar.traj)
    req = make()
    req.execute = True                   # a refused plan is never published, even when asked
    resp = planar.plan(req)
    assert resp.error_code.val == code, (resp.error_code.val, resp.message)
    assert reason in resp.message
    assert len(resp.trajectory.points) == 0 and len(resp.tool_path.poses) == 0
    _good_after(planar, n0)


def test_timed_out(planar: Planner) -> None:
    # ~60000 points take about a second to build before any publish, so the 1 us timeout fires
    # first even on a busy machine (a trajectory already published would make the plan succeed)
    first = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    duration = cv.joint_trajectory_to_arrays(first.trajectory).t[-1]
    n0 = len(planar.traj)
    planar.set_parameters(plan_timeout=1e-6, sample_period=duration / 60000)
    try:
        resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), execute=True))
    finally:
        planar.set_parameters(plan_timeout=5.0, sample_period=0.01)
    assert resp.error_code.val == PlanErrorCode.TIMED_OUT, resp.message
    assert 'plan_timeout' in resp.message
    _good_after(planar, n0)


def test_abandoned_plan_is_cancelled_and_the_next_one_plans(planar: Planner) -> None:
    """Issue 26: a plan of ~99 000 points (seconds of work) abandoned at a 0.5 s plan_timeout is
    cancelled. The good request sent right after the refusal waits only for it to stop (tens of
    ms), then plans within its own 0.5 s; before, it waited for the abandoned computation to end
    and timed out too. The abandoned plan is never published."""
    n0 = len(planar.traj)
    f = 0.0017                                   # ~990 s at the 3R's limits: ~99 000 points
    long_one = plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), execute=True,
                            velocity_scaling_factor=f, acceleration_scaling_factor=f * f)
    good_one = plan_request(pose_3r(*START_3R), pose_3r(*OTHER_GOAL_3R), execute=True)
    planar.set_parameters(plan_timeout=0.5)
    try:
        refused = planar.plan(long_one)
        good = planar.plan(good_one)
    finally:
        planar.set_parameters(plan_timeout=5.0)
    assert refused.error_code.val == PlanErrorCode.TIMED_OUT, refused.message
    assert 'plan_timeout' in refused.message and 'cancelled' in refused.message
    assert good.error_code.val == OK, good.message
    assert good.planning_time < 0.5
    msgs = planar.traj.wait_for(n0 + 1, DEADLINE, watch=planar.watch)
    assert len(msgs) == n0 + 1 and msgs[n0] == good.trajectory       # the abandoned one: never
    stopped = StatusWatch(planar.helper)
    try:      # the node measured the abandoned plan's stop: well under CANCEL_WAIT
        stopped.wait(planar.name, 'abandoned plan stop ms max', lambda v: 0.0 <= float(v) < 2000.0,
                     DEADLINE, watch=planar.watch)
        print(f"abandoned plan stopped {stopped.values(planar.name)['abandoned plan stop ms last']} ms "
              f'after its cancellation; the next request took {good.planning_time * 1e3:.1f} ms')
    finally:
        planar.helper.destroy_subscription(stopped.subscription)


def test_a_line_through_a_singularity_is_refused_with_the_place_and_the_fraction(
        helper: Any, tmp_path_factory: pytest.TempPathFactory) -> None:
    """Issue 21 #5 through the node: the ur5e line through its folded elbow is refused with
    PLANNING_FAILED, the reason and place in the message and the followable fraction in the reply
    (as GetCartesianPath); a followable line gives fraction 1; another failure -1."""
    names = geodesic_planner.load_robot('ur5e').joint_names
    ur = Planner(helper, tmp_path_factory.mktemp('pt_ur5e'), {'robot': 'ur5e'}, '/pt_ur5e')
    try:
        q_a, q_b = THROUGH_ELBOW
        goal = cv.matrix_to_pose(U.ur5e_fk_batch(np.array([q_b]))[0])
        req = plan_request(start_joints=q_a, goal=PoseStamped(pose=goal), names=names)
        refused = ur.plan(req)
        assert refused.error_code.val == PlanErrorCode.PLANNING_FAILED, refused.message
        assert 'passes through a singularity' in refused.message and '% of the way' in refused.message
        assert 0.5 < refused.fraction < 1.0
        assert f'followable fraction {refused.fraction:.4f}' in refused.message
        q_a, q_b = MISSED['elbow_nearly_stretched']
        goal = cv.matrix_to_pose(U.ur5e_fk_batch(np.array([q_b]))[0])
        ok = ur.plan(plan_request(start_joints=q_a, goal=PoseStamped(pose=goal), names=names))
        assert ok.error_code.val == OK and ok.fraction == 1.0 and ok.solver_method == 'trace', ok.message  # traced
        other = ur.plan(plan_request(start_joints=q_a, goal=pose_3r(*GOAL_3R, frame='elsewhere'),
                                     names=names))
        assert other.error_code.val == PlanErrorCode.FRAME_TRANSFORM_FAILURE and other.fraction == -1.0
    finally:
        ur.stop()


# =========================================================================== start state

def test_start_pose_solved_from_the_current_state(planar: Planner) -> None:
    """The start pose's IK is seeded with /joint_states: the robot's own elbow branch."""
    down = ik_3r_down(*START_3R)
    assert_allclose(fk_3r(down[None])[0], START_3R, atol=1e-12)          # the oracle itself
    try:
        planar.set_state(down, ROBOT_3R.joint_names, goal_3r)
        resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
        assert resp.error_code.val == OK, resp.message
        assert_allclose(resp.trajectory.points[0].positions, down, atol=1e-8)
    finally:
        planar.set_state(ik_3r(*START_3R), ROBOT_3R.joint_names, goal_3r)
    resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    assert_allclose(resp.trajectory.points[0].positions, ik_3r(*START_3R), atol=1e-8)


def test_start_tolerance_parameter(planar: Planner) -> None:
    q = ik_3r(*START_3R)
    within = plan_request(start_joints=q + [0.009, -0.009, 0.0], goal=pose_3r(*GOAL_3R))
    assert planar.plan(within).error_code.val == OK
    planar.set_parameters(allowed_start_tolerance=0.0)            # 0 disables the check
    try:
        resp = planar.plan(_other_branch_start())
        assert resp.error_code.val == OK, resp.message
        assert_allclose(resp.trajectory.points[0].positions, q + [0.1, 0.0, 0.0], atol=1e-12)
    finally:
        planar.set_parameters(allowed_start_tolerance=0.01)
    assert planar.plan(_other_branch_start()).error_code.val == PlanErrorCode.START_STATE_MISMATCH


def test_via_poses(planar: Planner) -> None:
    via = (2.0, 2.0, 0.8)      # wrist point 1.83 m from the base: reachable (3R, unit links)
    resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                                    via_poses=[pose_3r(*via)]))
    assert resp.error_code.val == OK, resp.message
    arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
    xyphi = fk_3r(arr.positions)
    # passes the via point (it rests there) and is straight on both pieces
    k = int(np.argmin(np.linalg.norm(xyphi[:, :2] - via[:2], axis=1)))
    assert_allclose(xyphi[k], via, atol=1e-8)
    for a, b, part in ((START_3R, via, xyphi[:k + 1]), (via, GOAL_3R, xyphi[k:])):
        d = np.subtract(b[:2], a[:2])
        rel = part[:, :2] - a[:2]
        assert np.max(np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])) / np.linalg.norm(d) < 1e-6
    assert resp.path_error < 1e-6


def _via_request(blend_radius: float) -> PlanTrajectory.Request:
    return plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R),
                        via_poses=[pose_3r(*v) for v in VIAS_3R], blend_radius=blend_radius)


def _polyline_distance(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(N, len(corners) - 1) distances of 2-D points to each segment of the polyline ``corners``."""
    a, b = corners[:-1], corners[1:]
    ab = b - a
    u = np.clip(np.einsum('nkd,kd->nk', points[:, None] - a, ab) / np.einsum('kd,kd->k', ab, ab), 0, 1)
    return np.linalg.norm(points[:, None] - (a + u[..., None] * ab), axis=2)


def _speeds_at_vias(arr: cv.TrajectoryArrays) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Joint speed norm at every point, tool (x, y, phi) by the closed-form FK, and the index of
    the point nearest to each via pose."""
    xyphi = fk_3r(arr.positions)
    near = [int(np.argmin(np.linalg.norm(xyphi[:, :2] - v[:2], axis=1))) for v in VIAS_3R]
    return np.linalg.norm(arr.velocities, axis=1), xyphi, near


def test_blend_radius_passes_via_poses_without_stopping(planar: Planner) -> None:
    resp = planar.plan(_via_request(BLEND_R))
    assert resp.error_code.val == OK, resp.message
    arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
    check_limits(arr, ROBOT_3R.max_velocity, ROBOT_3R.max_acceleration)
    speed, xyphi, near = _speeds_at_vias(arr)
    # no stop: moving at every interior point, and between the first and the last via pose never
    # slower than a few percent of the peak (the stopping plan below comes to rest there)
    assert np.all(speed[1:-1] > 0.0), np.flatnonzero(speed[1:-1] == 0.0)
    assert near[0] < near[1] < near[2]
    assert speed[near[0]:near[2] + 1].min() > 0.02 * speed.max()
    # the tool: within BLEND_R of each via pose, and of the polyline start-vias-goal everywhere
    corners = np.array([START_3R[:2], *[v[:2] for v in VIAS_3R], GOAL_3R[:2]])
    xy = xyphi[:, :2]
    to_via = np.linalg.norm(xy[:, None] - corners[None, 1:-1], axis=2)      # (N, 3)
    assert np.all(to_via.min(axis=0) <= BLEND_R), to_via.min(axis=0)
    to_line = _polyline_distance(xy, corners)
    assert to_line.min(axis=1).max() <= BLEND_R
    # outside the balls of radius BLEND_R around the vias the path is the exact line (the
    # tool on its segment); the reply's path_error says the same
    outside = to_via.min(axis=1) > BLEND_R
    assert outside.sum() > len(xy) // 2
    assert to_line[outside].min(axis=1).max() < 1e-6
    assert resp.path_error < 1e-6
    # blend_deviation: one value per via pose, within the radius, and what the samples inside
    # each ball show (distance from the two segments that meet at the via pose; sampled, so a
    # little below the zone's dense maximum)
    dev = np.array(resp.blend_deviation)
    assert dev.shape == (3,)
    assert np.all((dev > 0.0) & (dev <= BLEND_R)), dev
    for k in range(3):
        ball = to_via[:, k] <= BLEND_R
        seen = to_line[ball][:, k:k + 2].min(axis=1).max()
        assert 0.8 * dev[k] <= seen <= dev[k] + 1e-9, (k, seen, dev[k])


def test_blend_radius_zero_rests_at_every_via_pose(planar: Planner) -> None:
    resp = planar.plan(_via_request(0.0))
    assert resp.error_code.val == OK, resp.message
    arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
    speed, xyphi, near = _speeds_at_vias(arr)
    assert len(resp.blend_deviation) == 0
    # the samples are 10 ms apart, so none falls exactly on the stop: the nearest one passes the
    # via pose within 1 um at a speed of at most 0.1 % of the peak
    for k, v in zip(near, VIAS_3R):
        assert_allclose(xyphi[k], v, atol=1e-6)
        assert speed[k] < 1e-3 * speed.max(), (k, speed[k], speed.max())


def test_blend_radius_without_via_poses_is_ignored(planar: Planner) -> None:
    plain = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    blended = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), blend_radius=0.05))
    assert plain.error_code.val == blended.error_code.val == OK, blended.message
    assert blended.trajectory == plain.trajectory
    assert len(blended.blend_deviation) == 0


# =========================================================================== model and limits

KR6 = chain_from_urdf(KR6_URDF.read_text())
KR6_Q0 = KR6.home
KR6_Q1 = KR6.home + np.array([0.3, -0.2, 0.25, 0.4, -0.3, 0.5])
#: joint_limits.yaml: kr6_a2 much tighter than the others; kr6_a6 has no acceleration limit
KR6_VEL = {'kr6_a1': 1.0, 'kr6_a2': 0.1, 'kr6_a3': 1.0, 'kr6_a4': 1.2, 'kr6_a5': 1.2, 'kr6_a6': 1.5}
KR6_ACC = {'kr6_a1': 2.0, 'kr6_a2': 0.5, 'kr6_a3': 2.0, 'kr6_a4': 3.0, 'kr6_a5': 3.0}


@pytest.fixture(scope='module')
def described(helper: Any, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Planner, Collector]]:
    """A planner with robot:='' that takes its model from /robot_description and a limits file."""
    tmp = tmp_path_factory.mktemp('pt_described')
    limits = {'joint_limits': {
        name: {'has_velocity_limits': True, 'max_velocity': KR6_VEL[name],
               'has_acceleration_limits': name in KR6_ACC, 'max_acceleration': KR6_ACC.get(name, 0.0),
               'has_jerk_limits': False}
        for name in KR6.joint_names}}
    (tmp / 'joint_limits.yaml').write_text(yaml.safe_dump(limits))
    latched = latched_qos()
    rosout = rosout_collector(helper)
    description = helper.create_publisher(String, '/robot_description', latched)
    description.publish(String(data=KR6_URDF.read_text()))      # before the node starts: latched
    try:
        p = Planner(helper, tmp, {'robot': '', 'joint_limits': str(tmp / 'joint_limits.yaml')},
                    '/described')
        try:
            yield p, rosout
        finally:
            p.stop()
    finally:
        helper.destroy_publisher(description)
        helper.destroy_subscription(rosout.subscription)


def _kr6_plan(p: Planner) -> PlanTrajectory.Response:
    return p.plan(plan_request(start_joints=KR6_Q0, goal_joints=KR6_Q1, names=KR6.joint_names))


def test_model_from_robot_description(described: tuple[Planner, Collector]) -> None:
    p, _ = described
    # the URDF may arrive after the node is up: until then it says so, with PLANNING_FAILED
    resp = wait_until(lambda: (r := _kr6_plan(p)).error_code.val != PlanErrorCode.PLANNING_FAILED and r,
                      DEADLINE, what='a plan with the model from /robot_description', watch=p.watch)
    assert resp.error_code.val == OK, resp.message
    arr = check_controller_contract(resp.trajectory, KR6.joint_names)
    assert_allclose(arr.positions[0], KR6_Q0, atol=1e-12)
    assert_allclose(arr.positions[-1], KR6_Q1, atol=1e-9)
    assert_allclose(cv.path_to_matrices(resp.tool_path), KR6.fk(arr.positions), atol=1e-9)


def test_limits_from_joint_limits_yaml(described: tuple[Planner, Collector]) -> None:
    p, rosout = described
    resp = wait_until(lambda: (r := _kr6_plan(p)).error_code.val == OK and r, DEADLINE,
                      what='a kr6 plan', watch=p.watch)
    arr = cv.joint_trajectory_to_arrays(resp.trajectory)
    vmax = np.array([KR6_VEL[n] for n in KR6.joint_names])
    amax = np.array([KR6_ACC.get(n, KR6.max_acceleration[i]) for i, n in enumerate(KR6.joint_names)])
    check_limits(arr, vmax, amax)
    # the tight joint binds: its peak speed reaches its own limit, far below the others'
    peak = np.abs(arr.velocities).max(axis=0)
    assert peak[1] == pytest.approx(KR6_VEL['kr6_a2'], rel=0.05)
    # the joint without an acceleration limit from any source is named at start, with the default
    log = wait_until(lambda: next((m for m in rosout.messages if m.name == 'described.geodesic_planner'
                                   and 'no acceleration limit' in m.msg), None),
                     DEADLINE, what='the missing acceleration limit warning', watch=p.watch)
    assert "['kr6_a6']" in log.msg and '5 rad/s^2' in log.msg


def _tool_speeds(arr: cv.TrajectoryArrays, h: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Linear (m/s) and angular (rad/s) tool speed at every point, by central differences of the
    closed-form 3R forward kinematics along each point's joint velocity (independent of the
    planner's Jacobian)."""
    d = (fk_3r(arr.positions + h * arr.velocities) - fk_3r(arr.positions - h * arr.velocities)) / (2 * h)
    return np.linalg.norm(d[:, :2], axis=1), np.abs(d[:, 2])


def test_tool_speed_limits_honoured(planar: Planner) -> None:
    free = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    v_free, w_free = _tool_speeds(cv.joint_trajectory_to_arrays(free.trajectory))
    v_lim, w_lim = 0.3 * v_free.max(), 0.5 * w_free.max()
    for params, index, limit in (({'max_tool_speed': v_lim}, 0, v_lim),
                                 ({'max_tool_angular_speed': w_lim}, 1, w_lim)):
        planar.set_parameters(sample_period=0.002, **params)       # a dense sample: 2 ms
        try:
            resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
        finally:
            planar.set_parameters(sample_period=0.01, **{k: 0.0 for k in params})
        assert resp.error_code.val == OK, resp.message
        arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
        check_line_phi_3r(arr)                                   # the same path, slower
        speed = _tool_speeds(arr)[index]
        assert speed.max() <= limit * (1 + 1e-6), (params, speed.max())
        assert speed.max() >= 0.95 * limit, (params, speed.max())       # and it binds
        assert arr.t[-1] > cv.joint_trajectory_to_arrays(free.trajectory).t[-1]


def test_huge_user_strings_are_cut_short(planar: Planner) -> None:
    """A 1 MB frame_id or joint name is refused with a one-line reason that quotes 80 characters."""
    huge = 'w' * 1_000_000
    resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R, frame=huge)))
    assert resp.error_code.val == PlanErrorCode.FRAME_TRANSFORM_FAILURE
    assert '(1000000 characters)' in resp.message and len(resp.message) < 400, len(resp.message)
    resp = planar.plan(plan_request(goal_joints=[0.1, 0.2, 0.3], names=['joint1', 'joint2', huge]))
    assert resp.error_code.val == PlanErrorCode.INVALID_REQUEST
    assert '(1000000 characters)' in resp.message and len(resp.message) < 400, len(resp.message)


def test_jerk_limit_honoured(planar: Planner) -> None:
    """max_jerk: the jerk between the published accelerations (2 ms apart) never exceeds it, and
    the plan is slower than without it."""
    free = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    a_free = cv.joint_trajectory_to_arrays(free.trajectory)
    jerk_limit = 2.0                                          # rad/s^3, binding for this move
    planar.set_parameters(max_jerk=[jerk_limit], sample_period=0.002)
    try:
        resp = planar.plan(plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)))
    finally:
        planar.set_parameters(max_jerk=[], sample_period=0.01)
    assert resp.error_code.val == OK, resp.message
    arr = check_controller_contract(resp.trajectory, ROBOT_3R.joint_names)
    check_line_phi_3r(arr)                                     # the same path
    check_limits(arr, ROBOT_3R.max_velocity, ROBOT_3R.max_acceleration)
    # mean jerk over each 2 ms step, from the published accelerations (independent of the law)
    jerk = np.diff(arr.accelerations, axis=0) / np.diff(arr.t)[:, None]
    assert np.abs(jerk).max() <= jerk_limit * (1 + 1e-6), np.abs(jerk).max()
    assert np.abs(jerk).max() >= 0.9 * jerk_limit              # it binds
    assert arr.t[-1] > a_free.t[-1]
