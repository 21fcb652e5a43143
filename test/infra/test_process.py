"""Tests of tools/process.py (start, wait, stop, exit codes; no ROS) and of the graph helpers
against one real node (tools/graph.py, marked ros)."""
from __future__ import annotations

import os
import signal
import sys
import textwrap
from pathlib import Path

import pytest

from tools.process import NodeProcess, ToolError, format_param, popen_node, ros_args_for, wait_until

# Each child touches a file once its signal handlers are in place: the test waits on that file,
# a real state, and reads the log only afterwards.
CHILD_IGNORES_SIGINT = textwrap.dedent("""\
    import pathlib, signal, sys, time
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    {extra}
    print('ready', flush=True)
    print('to stderr', file=sys.stderr, flush=True)
    pathlib.Path(sys.argv[1]).touch()
    while True:
        time.sleep(0.05)
    """)


def _child(tmp_path: Path, code: str, name: str) -> NodeProcess:
    ready = tmp_path / f'{name}.ready'
    proc = popen_node(name, name=name, argv=[sys.executable, '-c', code, str(ready)],
                      log_dir=tmp_path)
    wait_until(ready.exists, 30, what=f'{name} to start', watch=[proc])
    return proc


def test_exit_code_and_output_of_a_child_that_ends_itself(tmp_path: Path) -> None:
    proc = popen_node('ends', name='ends', log_dir=tmp_path,
                      argv=[sys.executable, '-c', 'import sys; print("out"); sys.exit(5)'])
    assert proc.wait(30) == 5
    assert proc.returncode == 5 and not proc.alive()
    assert proc.log_text().strip() == 'out'
    assert proc.log_path.parent == tmp_path and proc.log_path.name.startswith('ends.')
    assert 'exited with 5' in proc.describe() and str(proc.log_path) in proc.describe()
    assert proc.stop() == 5 and proc.signals_sent == []     # already gone: nothing sent


def test_wait_times_out_with_the_log_tail(tmp_path: Path) -> None:
    proc = _child(tmp_path, CHILD_IGNORES_SIGINT.format(extra=''), 'sleeper')
    try:
        assert proc.alive() and 'running' in proc.describe()
        with pytest.raises(ToolError, match=r'(?s)sleeper .*did not exit within 0\.1 s.*ready'):
            proc.wait(0.1)
    finally:
        proc.stop(timeout=1.0)


def test_ros_args_and_environment_reach_the_child(tmp_path: Path) -> None:
    code = ('import json, os, sys; print(json.dumps([sys.argv[1:], os.environ["GP_X"], '
            'os.environ["PYTHONUNBUFFERED"], os.getpgid(0) == os.getpid()]))')
    proc = popen_node('args', '-r', '__node:=x', params={'a': 0.5, 'b': 'true'}, name='args',
                      env={'GP_X': 'y'}, log_dir=tmp_path, argv=[sys.executable, '-c', code])
    assert proc.wait(30) == 0
    assert proc.log_text().strip() == ('[["--ros-args", "-r", "__node:=x", "-p", "a:=0.5", "-p", '
                                       '"b:=\'true\'"], "y", "1", true]')


def test_stop_escalates_to_sigterm_when_sigint_ignored(tmp_path: Path) -> None:
    proc = _child(tmp_path, CHILD_IGNORES_SIGINT.format(extra=''), 'ignores_int')
    rc = proc.stop(timeout=1.0)
    assert rc == -signal.SIGTERM
    assert proc.signals_sent == [signal.SIGINT, signal.SIGTERM]
    text = proc.log_text()
    assert 'ready' in text and 'to stderr' in text       # stdout and stderr both captured


def test_stop_escalates_to_sigkill_when_sigint_and_sigterm_ignored(tmp_path: Path) -> None:
    code = CHILD_IGNORES_SIGINT.format(extra='signal.signal(signal.SIGTERM, signal.SIG_IGN)')
    proc = _child(tmp_path, code, 'ignores_int_term')
    rc = proc.stop(timeout=0.5)
    assert rc == -signal.SIGKILL
    assert proc.signals_sent == [signal.SIGINT, signal.SIGTERM, signal.SIGKILL]
    assert not proc.alive()


def test_stop_with_sigint_only_when_child_exits_cleanly(tmp_path: Path) -> None:
    code = textwrap.dedent("""\
        import pathlib, signal, sys, time
        # Python leaves SIGINT ignored if it was ignored when it started (a suite run in the
        # background, e.g. `cmd &` from a script): install the KeyboardInterrupt handler anyway
        signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            pathlib.Path(sys.argv[1]).touch()   # inside the try: a SIGINT right after it is handled
            while True:
                time.sleep(0.05)
        except KeyboardInterrupt:
            print('got SIGINT', flush=True)
            sys.exit(0)
        """)
    proc = _child(tmp_path, code, 'clean')
    assert proc.stop(timeout=10.0) == 0
    assert proc.signals_sent == [signal.SIGINT]
    assert 'got SIGINT' in proc.log_text()


def test_stop_reaches_the_whole_process_group(tmp_path: Path) -> None:
    pidfile = tmp_path / 'grandchild.pid'
    code = textwrap.dedent(f"""\
        import pathlib, subprocess, sys, time
        g = subprocess.Popen([sys.executable, '-c', 'import time\\nwhile True: time.sleep(0.05)'])
        open({str(pidfile)!r}, 'w').write(str(g.pid))
        pathlib.Path(sys.argv[1]).touch()
        while True:
            time.sleep(0.05)
        """)
    proc = _child(tmp_path, code, 'parent')
    grandchild = int(pidfile.read_text())
    proc.stop(timeout=5.0)

    def gone() -> bool:
        try:
            os.kill(grandchild, 0)
        except ProcessLookupError:
            return True
        # A zombie (exited, parent gone, not yet reaped by init) counts as gone.
        stat = Path(f'/proc/{grandchild}/stat')
        return stat.exists() and stat.read_text().split(')')[-1].split()[0] == 'Z'
    wait_until(gone, 10, what='the grandchild to exit')


def test_wait_until_fails_loudly_and_fast_on_dead_process(tmp_path: Path) -> None:
    with pytest.raises(ToolError, match=r'timed out after 0\.1 s waiting for the moon'):
        wait_until(lambda: False, 0.1, what='the moon')
    proc = popen_node('dies', name='dies', log_dir=tmp_path,
                      argv=[sys.executable, '-c', 'print("last words"); raise SystemExit(3)'])
    with pytest.raises(AssertionError, match=r'(?s)dies .*exited with 3.*last words'):
        wait_until(lambda: False, 60, what='never', watch=[proc])
    assert wait_until(lambda: 42, 1) == 42


def test_popen_node_missing_console_script_is_clear(tmp_path: Path) -> None:
    with pytest.raises(ToolError, match=r'console script .*no_such_node not found'):
        popen_node('no_such_node', log_dir=tmp_path)


def test_one_node_process_for_demo_and_tests() -> None:
    import tools.demo
    from ros import launch

    assert launch.NodeProcess is NodeProcess and launch.popen_node is popen_node
    assert tools.demo.NodeProcess is NodeProcess


def test_format_param_and_ros_args() -> None:
    assert format_param(True) == 'true'
    assert format_param(3) == '3'
    assert format_param(1.0) == '1.0'
    assert format_param(0.5) == '0.5'
    assert format_param(float('inf')) == '.inf'
    assert format_param('ur5e') == 'ur5e'
    assert format_param('/tmp/a b/bag') == '/tmp/a b/bag'
    assert format_param('') == "''"
    assert format_param('true') == "'true'"        # would be read as a bool
    assert format_param('1.5') == "'1.5'"          # would be read as a double
    assert format_param("it's: x") == "'it''s: x'"
    assert format_param([1.0, 2.0]) == '[1.0, 2.0]'
    assert format_param(['a', 'b']) == '[a, b]'
    assert ros_args_for() == []
    assert ros_args_for(['-r', '__node:=x'], {'robot': 'planar_3r', 'velocity_scaling': 0.5}) == [
        '--ros-args', '-r', '__node:=x', '-p', 'robot:=planar_3r', '-p', 'velocity_scaling:=0.5']


@pytest.mark.ros
def test_real_node_serves_is_matched_and_exits_cleanly_on_sigint(tmp_path: Path) -> None:
    """The helpers against a real node: its service, its endpoints matched to ours, SIGINT -> 0."""
    from nav_msgs.srv import GetPlan
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory

    from tools.graph import (Collector, RclpyRuntime, wait_for_service, wait_reader_matched,
                             wait_writer_matched)

    runtime = RclpyRuntime()
    proc = popen_node('geodesic_planner_node', params={'robot': 'planar_3r'}, log_dir=tmp_path)
    try:
        Collector(runtime.node, JointTrajectory, '/geodesic_planner/joint_trajectory')
        runtime.node.create_publisher(JointState, '/joint_states', 10)
        client = runtime.node.create_client(GetPlan, '/geodesic_planner/plan')
        wait_for_service(client, 60, watch=[proc])
        wait_writer_matched(proc, '/geodesic_planner/joint_trajectory', 1, 60)
        with pytest.raises(ToolError, match='2 subscription'):
            wait_writer_matched(proc, '/geodesic_planner/joint_trajectory', 2, 0.2)
        wait_reader_matched(proc, '/joint_states', 1, 60)
        assert proc.stop(timeout=10.0) == 0, proc.log_text()
        assert proc.signals_sent == [signal.SIGINT]
        assert 'planar_3r' in proc.log_text()        # output captured (read after the exit)
    finally:
        proc.stop(timeout=2.0)
        runtime.shutdown()


@pytest.mark.ros
def test_helper_executor_survives_an_exception_out_of_spin() -> None:
    """The session's executor thread keeps serving after an exception came out of ``spin()``
    (a callback that raises here; InvalidHandle from a destroyed entity in real runs)."""
    from std_msgs.msg import Int32

    from tools.graph import Collector, RclpyRuntime, wait_for_subscribers

    runtime = RclpyRuntime()
    try:
        node = runtime.node

        def boom(msg: Int32) -> None:
            raise RuntimeError(f'callback failed on {msg.data}')

        node.create_subscription(Int32, '/gp_boom', boom, 10)
        got = Collector(node, Int32, '/gp_after', 10)
        boom_pub = node.create_publisher(Int32, '/gp_boom', 10)
        after_pub = node.create_publisher(Int32, '/gp_after', 10)
        wait_for_subscribers(boom_pub, 1, 30)
        wait_for_subscribers(after_pub, 1, 30)
        boom_pub.publish(Int32(data=1))
        wait_until(lambda: runtime.spin_errors, 30, what='the exception out of spin()')
        after_pub.publish(Int32(data=2))
        assert got.wait_for(1, 30)[0].data == 2
        assert 'callback failed on 1' in str(runtime.spin_errors[0])
    finally:
        runtime.shutdown()
