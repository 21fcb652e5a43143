"""The trajectory processor node as a user runs it: console script, real DDS, real bags.

Oracles: the input is a minimum-jerk quintic q(t) = q0 + (q1 - q0) b(t / T), which quintic
Hermite interpolation reproduces exactly, so the output must be q(f t), f q'(f t), f**2 q''(f t)
at t = k * sample_period; bags are read back with rosbags and compared decoded (never bytes).
No fixed sleeps: every wait has an event and a deadline.
"""
from __future__ import annotations

import re
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')

from numpy.testing import assert_allclose, assert_array_equal
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from geodesic_planner.io.bags import JOINT_TRAJECTORY, bag_info, read_trajectories, to_cdr
from geodesic_planner.ros import conversions as cv

from .launch import (Collector, call_service, deliver, wait_discovered, wait_for_service,
                     wait_for_subscribers, wait_until)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0
#: s to wait for one plan to go through both nodes before asking again (see plan_through_both)
PROBE_TIMEOUT = 5.0
PROCESSOR = '/trajectory_processor'
PLANNER = '/geodesic_planner'
INPUT = '/geodesic_planner/joint_trajectory'
OUTPUT = '/trajectory_processor/joint_trajectory'
NAMES = ['joint1', 'joint2', 'joint3']
FIXTURE_BAG = Path(__file__).resolve().parents[2] / 'msg_examples' / 'bags' / 'paper_3r_scaling_0.5'
QOS = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.VOLATILE)


# =========================================================================== oracle
def min_jerk(t: np.ndarray, T: float, q0: np.ndarray, q1: np.ndarray) -> tuple[np.ndarray, ...]:
    """q0 + (q1 - q0) (10 s^3 - 15 s^4 + 6 s^5), s = t / T, and its first two derivatives."""
    s = (np.asarray(t, dtype=float) / T)[:, None]
    b = 10 * s**3 - 15 * s**4 + 6 * s**5
    db = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddb = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    d = (np.asarray(q1) - np.asarray(q0))[None, :]
    return np.asarray(q0)[None, :] + d * b, d * db, d * ddb


T_END = 2.0
KNOTS = np.array([0.0, 0.3, 0.7, 1.2, 1.6, 2.0])
Q0, Q1 = np.array([0.2, -0.5, 1.0]), np.array([1.0, 0.4, -0.3])


def known_trajectory(q0: np.ndarray = Q0, q1: np.ndarray = Q1) -> JointTrajectory:
    q, dq, ddq = min_jerk(KNOTS, T_END, q0, q1)
    return cv.arrays_to_joint_trajectory(NAMES, KNOTS, q, dq, ddq)


def check_output(msg: JointTrajectory, f: float, dt: float, q0: np.ndarray = Q0,
                 q1: np.ndarray = Q1) -> cv.TrajectoryArrays:
    """Points every dt (ns-exact), lasting T / f, on q(f t) with scaled derivatives, at rest at the end."""
    assert cv.validate_joint_trajectory(msg) == []
    assert list(msg.joint_names) == NAMES
    ns = np.array([p.time_from_start.sec * 10**9 + p.time_from_start.nanosec for p in msg.points])
    end_ns = round(T_END / f * 1e9)
    dt_ns = round(dt * 1e9)
    n_expected = int(np.ceil(end_ns / dt_ns - 1e-6)) + 1
    assert len(ns) == n_expected
    assert_array_equal(ns[:-1], np.arange(len(ns) - 1) * dt_ns)
    assert ns[-1] == end_ns
    arr = cv.joint_trajectory_to_arrays(msg)
    q, dq, ddq = min_jerk(f * arr.t, T_END, q0, q1)
    assert_allclose(arr.positions, q, atol=1e-9)
    assert_allclose(arr.velocities, f * dq, atol=1e-8)
    assert_allclose(arr.accelerations, f * f * ddq, atol=1e-7)
    assert_array_equal(arr.velocities[[0, -1]], 0.0)
    assert_array_equal(arr.accelerations[[0, -1]], 0.0)
    assert_array_equal(arr.positions[-1], min_jerk(np.array([T_END]), T_END, q0, q1)[0][0])  # the last knot
    return arr


# =========================================================================== harness
class Processor:
    """A running trajectory_processor_node and the helper-side entities talking to it."""

    def __init__(self, start_node: Any, node: Any, params: dict[str, Any], name: str = 'processor') -> None:
        self.process = start_node('trajectory_processor_node', params=params, name=name)
        self.node = node
        self.watch = [self.process]
        self.pub = node.create_publisher(JointTrajectory, INPUT, QOS)
        self.out = Collector(node, JointTrajectory, OUTPUT, QOS)
        self.set_client = node.create_client(SetParameters, '/trajectory_processor/set_parameters')
        self.get_client = node.create_client(GetParameters, '/trajectory_processor/get_parameters')
        wait_for_subscribers(self.pub, 1, DEADLINE, watch=self.watch)
        wait_until(lambda: self.out.subscription.get_publisher_count() > 0, DEADLINE,
                   what='processor output publisher matched', watch=self.watch)
        self.sync()

    def sync(self) -> None:
        """Wait until the node knows every publisher and subscription the test created so far.

        Our publisher seeing the node's subscription is not enough: a volatile reader drops what
        was sent before it had matched the writer itself (Fast DDS); and the node's publisher
        must have matched our subscription. See :func:`launch.wait_discovered`.
        """
        wait_discovered(self.node, PROCESSOR, DEADLINE, watch=self.watch)

    def wait_outputs(self, n: int) -> list[JointTrajectory]:
        return self.out.wait_for(n, DEADLINE, watch=self.watch)

    def wait_log(self, text: str) -> str:
        return wait_until(lambda: text in self.process.log_text() and self.process.log_text(), DEADLINE,
                          what=f'log line containing {text!r}', watch=self.watch)

    def set_parameters(self, **values: Any) -> list[Any]:
        wait_for_service(self.set_client, DEADLINE, watch=self.watch)
        req = SetParameters.Request()
        req.parameters = [Parameter(k, value=v).to_parameter_msg() for k, v in values.items()]
        return list(call_service(self.set_client, req, DEADLINE, watch=self.watch).results)

    def get_parameter(self, name: str) -> Any:
        wait_for_service(self.get_client, DEADLINE, watch=self.watch)
        value = call_service(self.get_client, GetParameters.Request(names=[name]), DEADLINE,
                             watch=self.watch).values[0]
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=value)).value

    def stop(self, sig: signal.Signals = signal.SIGINT) -> str:
        rc = self.process.stop(sig)
        log = self.process.log_text()
        assert rc == 0, log
        assert 'bag closed' in log or 'bag_path' not in ' '.join(self.process.argv), log
        return log


def decoded(path: Path, topic: str) -> list[Any]:
    with AnyReader([path]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(d, c.msgtype) for c, _, d in reader.messages(connections=conns)] if conns else []


def bag_dir(log: str) -> Path:
    match = re.search(r'bag closed: (\S+) \(', log)
    assert match, log
    return Path(match.group(1))


# =========================================================================== tests
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_known_trajectory_resampled_scaled_and_recorded(start_node: Any, ros_node: Any, tmp_path: Path,
                                                        storage: str) -> None:
    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'velocity_scaling': 0.5, 'sample_period': 0.01,
                                         'bag_path': str(bag), 'storage': storage})
    sent = known_trajectory()
    p.pub.publish(sent)
    (out,) = p.wait_outputs(1)
    arr = check_output(out, 0.5, 0.01)
    assert len(arr.t) == 401
    log = p.stop(signal.SIGINT)
    assert 'received trajectory: 6 points, 2 s -> published 401 points, 4 s' in log
    assert bag_dir(log) == bag

    info = bag_info(bag)
    assert info.storage == storage
    counts = {t.name: t.count for t in info.topics}
    assert counts == {INPUT: 1, OUTPUT: 1, '/joint_states': 0}
    (rin,) = read_trajectories(bag, INPUT)
    (rout,) = read_trajectories(bag, OUTPUT)
    sent_arr = cv.joint_trajectory_to_arrays(sent)
    assert_array_equal(rin.positions, sent_arr.positions)
    assert_array_equal(rin.velocities, sent_arr.velocities)
    assert_array_equal(rout.t, arr.t)
    assert_array_equal(rout.positions, arr.positions)
    assert_array_equal(rout.velocities, arr.velocities)
    assert_array_equal(rout.accelerations, arr.accelerations)
    assert rout.stamp_ns >= rin.stamp_ns


def test_invalid_trajectories_rejected_recorded_and_node_keeps_going(start_node: Any, ros_node: Any,
                                                                    tmp_path: Path) -> None:
    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag')})
    good = known_trajectory()

    def mutated(fn: Any) -> JointTrajectory:
        msg = known_trajectory()
        fn(msg)
        return msg

    cases = [
        ('point 2: 2 positions, expected 3', lambda m: setattr(m.points[2], 'positions', [0.0, 1.0])),
        ('point 1: velocities contain NaN or inf', lambda m: m.points[1].velocities.__setitem__(0, float('nan'))),
        ('point 3: positions contain NaN or inf', lambda m: m.points[3].positions.__setitem__(2, float('inf'))),
        ('not after', lambda m: setattr(m.points[4], 'time_from_start', m.points[3].time_from_start)),
        ('no points', lambda m: setattr(m, 'points', [])),
        ('duplicate joint names', lambda m: setattr(m, 'joint_names', ['a', 'a', 'b'])),
    ]
    for _, fn in cases:
        p.pub.publish(mutated(fn))
    p.pub.publish(good)
    outs = p.wait_outputs(1)  # processed in order: when the good one is out, the bad ones were handled
    for cause, _ in cases:
        p.wait_log(cause)
    assert len(p.out) == 1
    check_output(outs[0], 1.0, 0.01)
    assert p.process.alive()
    log = p.stop()
    assert log.count('rejected trajectory') == len(cases)
    assert 'received 7, published 1, rejected 6' in log
    recs = read_trajectories(bag_dir(log), INPUT)
    assert len(recs) == 7
    for (cause, _), rec in zip(cases, recs):
        assert any(cause in x for x in rec.problems), (cause, rec.problems)
    assert recs[-1].problems == ()
    assert len(read_trajectories(bag_dir(log), OUTPUT)) == 1


def test_burst_then_sigint_every_received_message_recorded(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """Count published == count recorded; joint states recorded raw; SIGINT closes the bag."""
    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag'), 'sample_period': 0.05})
    js_pub = ros_node.create_publisher(JointState, '/joint_states', QOS)
    wait_for_subscribers(js_pub, 1, DEADLINE, watch=p.watch)
    p.sync()
    n = 30
    goals = [Q1 + 0.01 * k for k in range(n)]
    for k in range(n):
        p.pub.publish(known_trajectory(Q0, goals[k]))
        js = JointState(name=NAMES, position=[0.01 * k, 0.0, 0.0])  # velocity/effort empty
        js_pub.publish(js)
    outs = p.wait_outputs(n)
    for k, out in enumerate(outs):
        check_output(out, 1.0, 0.05, Q0, goals[k])
    log = p.stop(signal.SIGINT)
    path = bag_dir(log)
    counts = {t.name: t.count for t in bag_info(path).topics}
    assert counts[INPUT] == n
    assert counts[OUTPUT] == n
    m = re.search(r'/joint_states: (\d+)\)', log)
    assert m and counts['/joint_states'] == int(m.group(1))
    assert counts['/joint_states'] <= n
    rec_out = read_trajectories(path, OUTPUT)
    for out, rec in zip(outs, rec_out):
        arr = cv.joint_trajectory_to_arrays(out)
        assert_array_equal(rec.t, arr.t)
        assert_array_equal(rec.positions, arr.positions)
    states = decoded(path, '/joint_states')
    assert [s.position[0] for s in states] == pytest.approx([0.01 * k for k in range(len(states))])
    assert all(s.velocity.size == 0 for s in states)


def test_sigterm_right_after_publishing_leaves_consistent_bag(start_node: Any, ros_node: Any,
                                                              tmp_path: Path) -> None:
    """No wait for the outputs (but the first): whatever the node received is processed and
    recorded before exit."""
    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag'), 'storage': 'sqlite3'})
    for k in range(10):
        p.pub.publish(known_trajectory(Q0, Q1 + 0.1 * k))
    p.wait_outputs(1)  # at least one arrived before the signal
    log = p.stop(signal.SIGTERM)
    m = re.search(r'received (\d+), published (\d+), rejected (\d+)', log)
    assert m, log
    received, published = int(m.group(1)), int(m.group(2))
    assert received == published >= 1
    path = bag_dir(log)
    counts = {t.name: t.count for t in bag_info(path).topics}
    assert counts[INPUT] == received
    assert counts[OUTPUT] == published
    assert len(p.out) <= published


def test_parameters_validated_via_service(start_node: Any, ros_node: Any) -> None:
    p = Processor(start_node, ros_node, {})
    for value in (0.0, 1.5, -0.5, float('nan')):
        (res,) = p.set_parameters(velocity_scaling=value)
        assert not res.successful
        assert 'velocity_scaling: must be in (0, 1]' in res.reason
    (res,) = p.set_parameters(velocity_scaling='fast')
    assert not res.successful and 'must be a number' in res.reason
    (res,) = p.set_parameters(sample_period=0.0)
    assert not res.successful and 'sample_period: must be in [1e-05, 10]' in res.reason
    (res,) = p.set_parameters(bag_path='/tmp/elsewhere')
    assert not res.successful and 'read-only' in res.reason
    assert p.get_parameter('velocity_scaling') == 1.0
    results = p.set_parameters(velocity_scaling=0.25, sample_period=0.02)
    assert [r.successful for r in results] == [True, True], [r.reason for r in results]
    (res,) = p.set_parameters(velocity_scaling=1)  # an integer is a valid factor
    assert res.successful, res.reason
    (res,) = p.set_parameters(velocity_scaling=0.25)
    assert res.successful
    p.pub.publish(known_trajectory())
    (out,) = p.wait_outputs(1)
    check_output(out, 0.25, 0.02)
    p.stop()


@pytest.mark.parametrize('params, reason', [
    ({'velocity_scaling': 1.5}, 'velocity_scaling: must be in (0, 1]'),
    ({'sample_period': -0.01}, 'sample_period: must be in [1e-05, 10]'),
    ({'storage': 'rosbag1'}, 'storage: must be one of mcap, sqlite3'),
    ({'input_topic': 'bad topic!'}, 'invalid topic name'),
    ({'record_topics': ['/x=nope_msgs/msg/Nope']}, "unknown message type 'nope_msgs/msg/Nope'"),
    ({'record_topics': ['/x:std_msgs/msg/Int32']}, 'cannot start'),  # rcl cannot parse it unquoted
])
def test_bad_start_parameters_exit_nonzero(start_node: Any, params: dict[str, Any], reason: str) -> None:
    proc = start_node('trajectory_processor_node', params=params, name='bad_start')
    rc = proc.wait(DEADLINE)
    log = proc.log_text()
    assert rc == 1, log
    assert 'cannot start' in log and reason in log, log
    assert 'Traceback' not in log


def test_existing_bag_path_never_overwritten(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    base = tmp_path / 'runs'
    base.mkdir()
    (base / 'keep.txt').write_text('precious')
    p = Processor(start_node, ros_node, {'bag_path': str(base)})
    p.pub.publish(known_trajectory())
    p.wait_outputs(1)
    log = p.stop()
    assert f'{base} exists, not overwritten' in log
    path = bag_dir(log)
    assert path.parent == base and path.name.startswith('trajectory_processor_')
    assert (base / 'keep.txt').read_text() == 'precious'
    assert len(read_trajectories(path, OUTPUT)) == 1


def test_to_cdr_exact_for_rclpy_messages() -> None:
    """serialize_message pads empty float64[]; to_cdr gives bytes rclpy and rosbags both accept."""
    msg = known_trajectory()
    msg.points[0].accelerations = []
    data = to_cdr(msg, JOINT_TRAJECTORY)
    assert deserialize_message(data, JointTrajectory) == msg
    assert len(serialize_message(msg)) >= len(data)
    # other field kinds: bytes, fixed arrays, byte and char scalars, uint8[] lists
    from sensor_msgs.msg import Image, NavSatFix
    from std_msgs.msg import Byte, Char, UInt8MultiArray

    fix = NavSatFix(latitude=1.5)
    fix.position_covariance[3] = 2.0
    for m, t in ((Image(height=2, width=3, encoding='rgb8', step=9, data=bytes(range(18))), 'sensor_msgs/msg/Image'),
                 (fix, 'sensor_msgs/msg/NavSatFix'), (Byte(data=b'\x07'), 'std_msgs/msg/Byte'),
                 (Char(data=65), 'std_msgs/msg/Char'),
                 (UInt8MultiArray(data=[1, 2, 3]), 'std_msgs/msg/UInt8MultiArray'),
                 (JointState(name=['a'], position=[1.0]), 'sensor_msgs/msg/JointState')):
        assert deserialize_message(to_cdr(m, t), type(m)) == m, t


@pytest.mark.skipif(not FIXTURE_BAG.exists(), reason=f'fixture bag {FIXTURE_BAG} not recorded yet')
def test_replay_fixture_bag_reproduces_recorded_output(start_node: Any, ros_node: Any) -> None:
    meta = yaml.safe_load((FIXTURE_BAG / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    custom = meta.get('custom_data') or {}
    f = float(custom.get('velocity_scaling', 0.5))
    dt = float(custom.get('sample_period', 0.01))
    recorded_in = read_trajectories(FIXTURE_BAG, INPUT)
    recorded_out = read_trajectories(FIXTURE_BAG, OUTPUT)
    assert recorded_out, 'fixture bag has no processed output'
    with AnyReader([FIXTURE_BAG]) as reader:
        conns = [c for c in reader.connections if c.topic == INPUT]
        raw_inputs = [bytes(d) for _, _, d in reader.messages(connections=conns)]
    assert len(raw_inputs) == len(recorded_in)
    p = Processor(start_node, ros_node, {'velocity_scaling': f, 'sample_period': dt})
    for data in raw_inputs:
        p.pub.publish(data)  # the recorded bytes, as the planner sent them
    outs = p.wait_outputs(len(recorded_out))
    valid_inputs = [r for r in recorded_in if not r.problems]
    assert len(valid_inputs) == len(recorded_out)
    for out, rec, rin in zip(outs, recorded_out, valid_inputs):
        arr = cv.joint_trajectory_to_arrays(out)
        assert list(out.joint_names) == rec.joint_names
        assert_allclose(arr.t, rec.t, atol=1e-9)
        assert_allclose(arr.positions, rec.positions, atol=1e-12)
        assert_allclose(arr.velocities, rec.velocities, atol=1e-12)
        assert_allclose(arr.accelerations, rec.accelerations, atol=1e-12)
        assert rec.duration == pytest.approx(rin.duration / f, abs=1e-9)
    p.stop()


# =========================================================================== both nodes
A_3R = (2.5, 1.5, np.radians(30.0))       # paper Table 1: position and yaw of the tool
B_3R = (1.5, 2.5, np.arctan2(0.7, 0.714))


def _pose_3r(x: float, y: float, psi: float) -> Any:
    from geometry_msgs.msg import PoseStamped

    msg = PoseStamped()
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = np.sin(psi / 2), np.cos(psi / 2)
    return msg


def _fk_3r(q: np.ndarray) -> np.ndarray:
    """Unit-link planar 3R: (N, 3) joints -> (N, 3) rows (x, y, phi)."""
    c = np.cumsum(q, axis=1)
    return np.stack([np.cos(c).sum(1), np.sin(c).sum(1), c[:, 2]], axis=1)


def _on_line_phi(q: np.ndarray, atol: float) -> None:
    """Paper example oracle: tool on the straight line A->B, phi linear along it."""
    xyphi = _fk_3r(q)
    a, b = np.array(A_3R), np.array(B_3R)
    d = b[:2] - a[:2]
    lam = (xyphi[:, :2] - a[:2]) @ d / (d @ d)
    assert np.max(np.linalg.norm(xyphi[:, :2] - (a[:2] + lam[:, None] * d), axis=1)) < atol
    assert np.max(np.abs(xyphi[:, 2] - (a[2] + lam * (b[2] - a[2])))) < atol


def plan_through_both(client: Any, planned: Collector, p: Processor, goal: Any, watch: list[Any]) -> int:
    """Plan A -> ``goal`` until one plan's output comes out of the processor; return the attempts.

    Nothing tells the test when the processor's input has matched the planner's publisher (both
    ends in other processes; our own subscriptions are matched, see launch.wait_discovered),
    so a plan published before that may never reach the processor: ask again until one does.
    From then on every trajectory the planner publishes reaches the processor. ``goal(k)`` is
    the goal of attempt k. Callers count the bag from the processor's own totals.
    """
    from nav_msgs.srv import GetPlan

    attempts = [0]

    def plan_one() -> Any:
        n = len(planned)
        req = GetPlan.Request(start=_pose_3r(*A_3R), goal=goal(attempts[0]))
        attempts[0] += 1
        assert call_service(client, req, DEADLINE, watch=watch).plan.poses
        end = list(planned.wait_for(n + 1, DEADLINE, watch=watch)[n].points[-1].positions)
        return lambda out: list(out.points[-1].positions) == end   # the processor keeps the end

    return deliver(plan_one, p.out, PROBE_TIMEOUT, DEADLINE, what='a plan through both nodes', watch=watch)


def processor_totals(log: str) -> tuple[int, int, int]:
    """(received, published, rejected) from the processor's shutdown line."""
    m = re.search(r'received (\d+), published (\d+), rejected (\d+)', log)
    assert m, log
    return int(m.group(1)), int(m.group(2)), int(m.group(3))


def test_round_trip_planner_processor_bag(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """As a user runs it: plan the paper example, processor at f = 0.5, read both topics back."""
    from nav_msgs.srv import GetPlan

    planner = start_node('geodesic_planner_node', params={'robot': 'planar_3r'}, name='planner')
    planned = Collector(ros_node, JointTrajectory, INPUT, QOS)
    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'velocity_scaling': 0.5, 'sample_period': 0.01, 'bag_path': str(bag)})
    watch = [planner, p.process]
    client = ros_node.create_client(GetPlan, '/geodesic_planner/plan')
    wait_for_service(client, DEADLINE, watch=watch)
    wait_until(lambda: planned.subscription.get_publisher_count() > 0, DEADLINE, what='planner publisher', watch=watch)
    wait_discovered(ros_node, PLANNER, DEADLINE, watch=watch)   # its publisher matched `planned`
    attempts = plan_through_both(client, planned, p, lambda k: _pose_3r(*B_3R), watch)
    plan_msg, out = planned.messages[-1], p.out.messages[-1]   # same request every attempt

    pin, pout = cv.joint_trajectory_to_arrays(plan_msg), cv.joint_trajectory_to_arrays(out)
    assert list(out.joint_names) == list(plan_msg.joint_names)
    ns = np.array([x.time_from_start.sec * 10**9 + x.time_from_start.nanosec for x in out.points])
    assert_array_equal(ns[:-1], np.arange(len(ns) - 1) * 10_000_000)          # every 0.01 s
    plan_end_ns = plan_msg.points[-1].time_from_start.sec * 10**9 + plan_msg.points[-1].time_from_start.nanosec
    assert abs(ns[-1] - 2 * plan_end_ns) <= 1                                  # twice as long
    assert_array_equal(pout.positions[-1], pin.positions[-1])                   # same end
    assert_array_equal(pout.velocities[-1], 0.0)                               # at rest
    assert_array_equal(pout.accelerations[-1], 0.0)
    # same path: output at 2 t_k is the planner's point k; every output point on the paper's line
    k = np.arange(len(pin.t) - 1)
    assert_allclose(pout.positions[2 * k], pin.positions[k], atol=1e-9)
    assert_allclose(pout.velocities[2 * k], 0.5 * pin.velocities[k], atol=1e-9)
    assert_allclose(pout.accelerations[2 * k], 0.25 * pin.accelerations[k], atol=1e-9)
    _on_line_phi(pout.positions, atol=1e-5)

    log = p.stop(signal.SIGINT)
    assert bag_dir(log) == bag
    received, published, rejected = processor_totals(log)
    assert 1 <= received == published <= attempts and rejected == 0, log
    rec_ins, rec_outs = decoded(bag, INPUT), decoded(bag, OUTPUT)
    assert len(rec_ins) == len(rec_outs) == received
    rec_in, rec_out = rec_ins[-1], rec_outs[-1]
    assert list(rec_in.joint_names) == list(plan_msg.joint_names)
    assert_array_equal(np.array([x.positions for x in rec_in.points]), pin.positions)
    assert_array_equal(np.array([x.accelerations for x in rec_out.points]), pout.accelerations)
    assert [x.time_from_start.nanosec for x in rec_out.points] == [x.time_from_start.nanosec for x in out.points]
    assert planner.stop() == 0


def on_disk(bag: Path, scratch: Path) -> dict[str, int]:
    """Messages per topic that a recording in progress has already written to its storage file
    (what would survive a SIGKILL): a copy of the directory, repaired."""
    import shutil
    import uuid

    from geodesic_planner.io.bags import repair
    from geodesic_planner.core.errors import BagError

    probe = scratch / f'probe_{uuid.uuid4().hex}'
    shutil.copytree(bag, probe)
    try:
        return repair(probe).messages
    except BagError:
        return {}
    finally:
        shutil.rmtree(probe, ignore_errors=True)


def test_sigkill_then_repair_recovers_flushed_messages(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """After SIGKILL the bag has no metadata; geodesic-bag repair restores everything flushed."""
    from geodesic_planner.io.bags import repair

    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'bag_path': str(bag)})
    for k in range(5):
        p.pub.publish(known_trajectory(Q0, Q1 + 0.1 * k))
    outs = p.wait_outputs(5)
    wait_until(lambda: sum(on_disk(bag, tmp_path).values()) == 10, 10.0,
               what='the recorder to flush 10 messages', watch=p.watch)
    assert p.process.stop(signal.SIGKILL) == -signal.SIGKILL
    assert not (bag / 'metadata.yaml').exists()
    report = repair(bag)
    assert report.repaired
    assert report.messages[INPUT] == 5 and report.messages[OUTPUT] == 5
    for out, rec in zip(outs, read_trajectories(bag, OUTPUT)):
        assert_array_equal(rec.positions, cv.joint_trajectory_to_arrays(out).positions)


def test_concurrent_publishers_every_trajectory_recorded(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """4 publishers x 15 trajectories at once: 60 received, 60 published, 60 + 60 in the bag."""
    import threading

    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag'), 'sample_period': 0.1})
    pubs = [p.pub] + [ros_node.create_publisher(JointTrajectory, INPUT, QOS) for _ in range(3)]
    for pub in pubs:
        wait_for_subscribers(pub, 1, DEADLINE, watch=p.watch)
    p.sync()
    goals = {(w, k): Q1 + np.array([0.01 * w, 0.001 * k, 0.0]) for w in range(4) for k in range(15)}

    def work(w: int) -> None:
        for k in range(15):
            pubs[w].publish(known_trajectory(Q0, goals[(w, k)]))

    threads = [threading.Thread(target=work, args=(w,)) for w in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    outs = p.wait_outputs(60)
    log = p.stop()
    assert 'received 60, published 60, rejected 0' in log
    path = bag_dir(log)
    counts = {t.name: t.count for t in bag_info(path).topics}
    assert counts[INPUT] == 60 and counts[OUTPUT] == 60
    ends = sorted(tuple(np.round(r.positions[-1], 12)) for r in read_trajectories(path, OUTPUT))
    expected = sorted(tuple(np.round(min_jerk(np.array([T_END]), T_END, Q0, g)[0][0], 12)) for g in goals.values())
    assert ends == expected
    assert len(outs) == 60


def test_record_extra_topics_typed_and_discovered(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """record_topics: 'name=pkg/msg/Type' subscribed at once, a bare name once its type is known."""
    from std_msgs.msg import Int32, String

    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'bag_path': str(bag),
                                         'record_topics': [INPUT, '/counter=std_msgs/msg/Int32', '/chatter']})
    p.wait_log('waiting for publishers to learn the types of /chatter')
    counter = ros_node.create_publisher(Int32, '/counter', QOS)
    chatter = ros_node.create_publisher(String, '/chatter', QOS)
    # /chatter is subscribed once its type is known from our publisher: our publisher matching
    # a subscription means that it exists (created after the node had discovered our writer)
    wait_for_subscribers(counter, 1, DEADLINE, watch=p.watch)
    wait_for_subscribers(chatter, 1, DEADLINE, watch=p.watch)
    p.sync()
    p.wait_log('recording /chatter [std_msgs/msg/String]')
    for k in range(7):
        counter.publish(Int32(data=k))
        chatter.publish(String(data=f'hello {k}'))
    p.pub.publish(known_trajectory())
    p.wait_outputs(1)
    wait_until(lambda: on_disk(bag, tmp_path).get('/chatter') == 7 and on_disk(bag, tmp_path).get('/counter') == 7,
               DEADLINE, what='7 + 7 messages recorded', watch=p.watch)
    log = p.stop()
    assert bag_dir(log) == bag
    counts = {t.name: t.count for t in bag_info(bag).topics}
    assert counts == {INPUT: 1, '/counter': 7, '/chatter': 7}  # output not in record_topics
    assert [m.data for m in decoded(bag, '/counter')] == list(range(7))
    assert [m.data for m in decoded(bag, '/chatter')] == [f'hello {k}' for k in range(7)]


def _plans_under_load(start_node: Any, ros_node: Any, tmp_path: Path, clients: int, per_client: int) -> None:
    """clients x per_client plan requests (every 4th unreachable) at once: every trajectory the
    planner publishes is processed once and lands in the bag (input count == output count)."""
    import threading

    from nav_msgs.srv import GetPlan

    planner = start_node('geodesic_planner_node', params={'robot': 'planar_3r'}, name='planner')
    planned = Collector(ros_node, JointTrajectory, INPUT, QOS)
    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'velocity_scaling': 0.5, 'bag_path': str(bag)})
    watch = [planner, p.process]
    cls = [ros_node.create_client(GetPlan, '/geodesic_planner/plan') for _ in range(clients)]
    for c in cls:
        wait_for_service(c, DEADLINE, watch=watch)
    wait_until(lambda: planned.subscription.get_publisher_count() > 0, DEADLINE, what='planner publisher', watch=watch)
    # the planner knows `planned` and every client (created before this barrier)
    wait_discovered(ros_node, PLANNER, DEADLINE, watch=watch)
    # warm-up goals between the load's (1.5, 2.5 - 0.02 k): every message is told apart
    plan_through_both(cls[0], planned, p, lambda k: _pose_3r(1.5, 2.495 - 0.001 * k, B_3R[2]), watch)
    n0_planned, n0_out = len(planned), len(p.out)
    answers: list[bool] = []
    lock = threading.Lock()

    def work(w: int) -> None:
        for k in range(per_client):
            bad = (w + k) % 4 == 3
            goal = _pose_3r(10.0, 0.0, 0.0) if bad else _pose_3r(1.5, 2.5 - 0.02 * k, B_3R[2] - 0.01 * w)
            res = call_service(cls[w], GetPlan.Request(start=_pose_3r(*A_3R), goal=goal), 4 * DEADLINE, watch=watch)
            with lock:
                answers.append(bool(res.plan.poses) != bad)  # good -> a plan, bad -> empty

    threads = [threading.Thread(target=work, args=(w,)) for w in range(clients)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    n_req = clients * per_client
    assert len(answers) == n_req and all(answers)
    n_good = sum(1 for w in range(clients) for k in range(per_client) if (w + k) % 4 != 3)
    planned.wait_for(n0_planned + n_good, DEADLINE, watch=watch)
    p.wait_outputs(n0_out + n_good)
    log = p.stop()
    received, published, rejected = processor_totals(log)
    # every plan from the warm-up plan that went through on (earlier attempts may be lost)
    assert n_good + 1 <= received <= len(planned) and received == published and rejected == 0, log
    counts = {t.name: t.count for t in bag_info(bag).topics}
    assert counts[INPUT] == counts[OUTPUT] == received
    rec_in = read_trajectories(bag, INPUT)
    assert len(rec_in) == received
    for msg, rec in zip(list(planned.messages)[-received:], rec_in):  # in order, as received
        assert_array_equal(rec.positions, cv.joint_trajectory_to_arrays(msg).positions)
    assert planner.stop() == 0


def test_plans_under_load_all_recorded(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    _plans_under_load(start_node, ros_node, tmp_path, clients=4, per_client=4)


@pytest.mark.slow
def test_plans_under_load_all_recorded_long(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    _plans_under_load(start_node, ros_node, tmp_path, clients=4, per_client=25)
