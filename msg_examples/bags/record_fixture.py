"""Record the fixture bag ``msg_examples/bags/paper_3r_scaling_0.5`` with both nodes.

Run inside the loopback namespace from the repository root::

    bash scripts/netns.sh .venv/bin/python msg_examples/bags/record_fixture.py

What it does: starts ``geodesic_planner_node`` (planar_3r, defaults) and
``trajectory_processor_node`` (velocity_scaling 0.5, sample_period 0.01, mcap bag), publishes a
few ``/joint_states``, asks the planner for the paper's example A -> B (Chen, Li & Tang 2016,
Table 1) and back B -> A, publishes one invalid trajectory (duplicate joint names) on the
planner's topic, waits for the processor's outputs, stops both nodes with SIGINT and copies the
bag here. The test ``test/ros/test_processor.py::test_replay_fixture_bag_reproduces_recorded_output``
replays its input trajectories.
"""
from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.srv import GetPlan
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from geodesic_planner.cli.bag import format_info
from geodesic_planner.io.bags import bag_info

HERE = Path(__file__).resolve().parent
TARGET = HERE / 'paper_3r_scaling_0.5'
INPUT = '/geodesic_planner/joint_trajectory'
OUTPUT = '/trajectory_processor/joint_trajectory'
A = (2.5, 1.5, math.radians(30.0))
B = (1.5, 2.5, math.atan2(0.7, 0.714))
QA = [0.258, 0.583, -0.317]  # paper Table 2 (elbow branch), rad
DEADLINE = 60.0


def pose(x: float, y: float, psi: float) -> PoseStamped:
    msg = PoseStamped()
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(psi / 2), math.cos(psi / 2)
    return msg


def start(script: str, params: dict[str, str], log: Path) -> subprocess.Popen:
    exe = Path(sysconfig.get_path('scripts')) / script
    args = [str(exe), '--ros-args'] + [a for k, v in params.items() for a in ('-p', f'{k}:={v}')]
    env = dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0')
    with open(log, 'wb') as out:
        return subprocess.Popen(args, stdout=out, stderr=subprocess.STDOUT, env=env, process_group=0)


def spin_until(executor: SingleThreadedExecutor, predicate, what: str) -> None:  # noqa: ANN001
    deadline = time.monotonic() + DEADLINE
    while not predicate():
        if time.monotonic() > deadline:
            raise SystemExit(f'ERROR: timed out waiting for {what}')
        executor.spin_once(timeout_sec=0.05)


def stop(proc: subprocess.Popen) -> int:
    proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait()


def main() -> int:
    work = Path(tempfile.mkdtemp(prefix='gp_fixture_'))
    bag = work / 'bag'
    planner = start('geodesic_planner_node', {'robot': 'planar_3r'}, work / 'planner.log')
    processor = start('trajectory_processor_node',
                      {'velocity_scaling': '0.5', 'sample_period': '0.01', 'bag_path': str(bag)},
                      work / 'processor.log')
    rclpy.init()
    node = rclpy.create_node('fixture_recorder')
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    outputs: list[JointTrajectory] = []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(JointTrajectory, OUTPUT, outputs.append, qos)
    js_pub = node.create_publisher(JointState, '/joint_states', qos)
    bad_pub = node.create_publisher(JointTrajectory, INPUT, qos)
    client = node.create_client(GetPlan, '/geodesic_planner/plan')
    try:
        spin_until(executor, client.service_is_ready, 'the plan service')
        log = work / 'processor.log'
        # volatile topics: the processor's readers must have matched the writers themselves
        spin_until(executor, lambda: node.count_publishers(OUTPUT) >= 1
                   and f'input {INPUT}: 2 publisher(s) matched' in log.read_text()
                   and '/joint_states: 1 publisher(s) matched' in log.read_text(),
                   'the processor to match the planner, this script and /joint_states')
        for _ in range(5):
            js_pub.publish(JointState(name=['joint1', 'joint2', 'joint3'], position=QA))
        for start_pose, goal_pose in ((A, B), (B, A)):
            future = client.call_async(GetPlan.Request(start=pose(*start_pose), goal=pose(*goal_pose)))
            spin_until(executor, future.done, 'a plan')
            if not future.result().plan.poses:
                raise SystemExit('ERROR: the planner returned an empty plan')
        spin_until(executor, lambda: len(outputs) >= 2, 'two processed trajectories')
        bad = JointTrajectory(joint_names=['joint1', 'joint1', 'joint3'])
        bad.points = outputs[0].points[:3]
        bad_pub.publish(bad)
        spin_until(executor, lambda: 'rejected trajectory' in (work / 'processor.log').read_text(),
                   'the processor to reject the invalid trajectory')
    finally:
        rc_proc = stop(processor)
        rc_plan = stop(planner)
        node.destroy_node()
        rclpy.try_shutdown()
    print((work / 'processor.log').read_text())
    if rc_proc != 0 or rc_plan != 0:
        print(f'ERROR: exit codes processor {rc_proc}, planner {rc_plan}', file=sys.stderr)
        return 1
    if TARGET.exists():
        shutil.rmtree(TARGET)
    shutil.copytree(bag, TARGET)
    print(format_info(bag_info(TARGET)))
    size = sum(p.stat().st_size for p in TARGET.iterdir())
    print(f'{TARGET}: {size / 1024:.1f} kB')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
