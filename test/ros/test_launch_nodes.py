"""tools/launch_nodes.py: the launch file's nodes run from the venv, without ``ros2 launch``.

The command lines are the launch description's (``describe(...)`` and ``ros_arguments()``); the
``ros`` tests start the launcher as a user would (``python -m tools.launch_nodes namespace:=...``),
plan through the two nodes it started, stop it with SIGINT and check that both nodes are gone;
and a node that fails at start-up stops the other and makes the launcher exit 1.
"""
from __future__ import annotations

import shlex
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tools.launch_nodes import load_launch
from tools.process import bin_dir, popen_node, wait_until

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / 'config'
DEADLINE = 60.0
ENV = {'PYTHONPATH': str(ROOT)}


def launcher(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'tools.launch_nodes', *args], capture_output=True, text=True,
                          cwd=ROOT, timeout=DEADLINE, check=False)


def test_print_gives_the_launch_descriptions_command_lines() -> None:
    limits = str(CONFIG / 'joint_limits.yaml')
    done = launcher('--print', 'namespace:=robot1', f'joint_limits:={limits}')
    assert done.returncode == 0, done.stderr
    lines = [shlex.split(line) for line in done.stdout.splitlines()]
    specs = load_launch().describe(namespace='robot1', joint_limits=limits)
    assert lines == [[str(bin_dir() / s.executable), '--ros-args', *s.ros_arguments()] for s in specs]
    # what ros2 launch would pass: the namespace, the config file, the argument after it
    planner = lines[0]
    assert planner[planner.index('__ns:=/robot1') - 1] == '-r'
    assert planner[planner.index('--params-file') + 1] == str(CONFIG / 'geodesic_planner.yaml')
    assert planner.index('--params-file') < planner.index(f'joint_limits:={limits}')


def test_show_args_lists_the_launch_files_arguments() -> None:
    done = launcher('--show-args')
    assert done.returncode == 0, done.stderr
    for name in load_launch().ARGUMENTS:
        assert f"'{name}':" in done.stdout


@pytest.mark.parametrize('args, reason', [
    (['nspace:=robot1'], "unknown launch argument 'nspace'"),
    (['robot1'], "'robot1': launch arguments are NAME:=VALUE"),
    (['namespace:=1robot'], "namespace: '1robot' is not a valid ROS namespace"),
    (['namespace:=a', 'namespace:=b'], "launch argument 'namespace' given twice"),
    (['planner_config:=/nonexistent/planner.yaml'], 'planner_config: /nonexistent/planner.yaml: no such file'),
])
def test_bad_arguments_one_error_line_exit_2(args: list[str], reason: str) -> None:
    done = launcher(*args)
    assert done.returncode == 2
    assert done.stdout == ''
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f'ERROR: {reason}'), done.stderr


def _children(pid: int) -> set[int]:
    """Pids whose parent is ``pid`` (from /proc)."""
    found = set()
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
        if int(fields[1]) == pid:
            found.add(int(stat.parent.name))
    return found


@pytest.mark.ros
@pytest.mark.timeout(240)
def test_launcher_runs_both_nodes_and_stops_them_on_sigint(ros_node: Any, tmp_path: Path) -> None:
    pytest.importorskip('rclpy')
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.srv import GetPlan
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from trajectory_msgs.msg import JointTrajectory

    from tools.graph import Collector, call_service, deliver, wait_for_service

    proc = popen_node('launch_nodes', argv=[sys.executable, '-m', 'tools.launch_nodes', 'namespace:=robot9'],
                      env=ENV, log_dir=tmp_path)
    try:
        wanted = {('geodesic_planner', '/robot9'), ('trajectory_processor', '/robot9')}
        wait_until(lambda: wanted <= set(ros_node.get_node_names_and_namespaces()), DEADLINE,
                   what=f'nodes {sorted(wanted)} in the graph', watch=[proc])
        def two_children() -> set[int]:
            found = _children(proc.pid)
            return found if len(found) == 2 else set()

        nodes = wait_until(two_children, DEADLINE, what="the launcher's two children", watch=[proc])

        # a plan asked of the planner comes out of the processor of the same namespace
        out = Collector(ros_node, JointTrajectory, '/robot9/trajectory_processor/joint_trajectory',
                        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        client = ros_node.create_client(GetPlan, '/robot9/geodesic_planner/plan')
        wait_for_service(client, DEADLINE, watch=[proc])
        attempt = [0]

        def pose(x: float, y: float, psi: float) -> Any:
            msg = PoseStamped()
            msg.pose.position.x, msg.pose.position.y = x, y
            msg.pose.orientation.z, msg.pose.orientation.w = np.sin(psi / 2), np.cos(psi / 2)
            return msg

        def plan() -> Any:
            goal = (1.5, 2.5 - 0.001 * attempt[0])   # each attempt its own goal (planar 3R, unit links)
            attempt[0] += 1
            req = GetPlan.Request(start=pose(2.5, 1.5, np.radians(30.0)), goal=pose(*goal, np.arctan2(0.7, 0.714)))
            assert call_service(client, req, DEADLINE, watch=[proc]).plan.poses

            def reached(msg: Any) -> bool:
                c = np.cumsum(msg.points[-1].positions)
                return bool(np.allclose([np.cos(c).sum(), np.sin(c).sum()], goal, atol=1e-6))
            return reached

        deliver(plan, out, 5.0, DEADLINE, what='a plan through /robot9', watch=[proc])
        ros_node.destroy_client(client)
    finally:
        code = proc.stop(signal.SIGINT, timeout=30.0)
    assert code == 0, proc.log_tail()
    assert proc.signals_sent == [signal.SIGINT], proc.log_tail()   # it stopped by itself on SIGINT
    assert not [pid for pid in nodes if Path(f'/proc/{pid}').exists()], 'a node outlived the launcher'


@pytest.mark.ros
@pytest.mark.timeout(120)
def test_a_node_that_fails_stops_the_other(tmp_path: Path) -> None:
    config = tmp_path / 'planner.yaml'
    config.write_text((CONFIG / 'geodesic_planner.yaml').read_text().replace(
        'robot: planar_3r', 'robot: no_such_robot'))
    assert 'no_such_robot' in config.read_text()
    proc = popen_node('launch_nodes', argv=[sys.executable, '-m', 'tools.launch_nodes', f'planner_config:={config}'],
                      env=ENV, log_dir=tmp_path)
    try:
        code = proc.wait(DEADLINE)
    finally:
        proc.stop()
    assert code == 1, proc.log_tail()
    errors = [line for line in proc.log_text().splitlines() if line.startswith('ERROR: ')]
    assert errors == ['ERROR: /geodesic_planner exited with code 1 (the other nodes were stopped)'], proc.log_tail()
    assert 'cannot start' in proc.log_text()   # the planner's own reason, on the launcher's output
