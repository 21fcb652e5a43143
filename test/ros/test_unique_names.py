"""Two nodes of one name (issues 13 #4 and 26 #2): the younger one stops, the older keeps serving.

At start-up (the namesake is discovered at once) and later: a namesake discovered only after the
newcomer's start-up window (the older node is paused with SIGSTOP while the newcomer starts, so
no discovery traffic can flow until it resumes) must stop the newcomer all the same. And when two
claims carry the same start time, the tie-break by instance id decides, the same way on both.
"""
from __future__ import annotations

import os
import signal
import threading
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory

from tools.graph import StatusWatch

from geodesic_planner.ros.runtime import UniqueNameGuard

from .launch import call_service, popen_node, wait_until, warm_up_client
from .test_plan_trajectory import plan_request
from .test_planner_node import GOAL_3R, START_3R, pose_3r

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0


@pytest.mark.parametrize('executable, name', [('geodesic_planner_node', 'geodesic_planner'),
                                              ('trajectory_processor_node', 'trajectory_processor')])
def test_second_node_of_a_name_refuses_to_start(helper: Any, tmp_path: Path, executable: str,
                                                name: str) -> None:
    ns = f'/dup_{name}'
    full = f'{ns}/{name}'
    status = StatusWatch(helper)
    first = popen_node(executable, '-r', f'__ns:={ns}', name='first', log_dir=tmp_path)
    second = None
    try:
        # the first node has looked for namesakes for its whole start-up window and found none
        status.wait(full, 'name check', lambda v: v == 'unique', DEADLINE, watch=[first])
        second = popen_node(executable, '-r', f'__ns:={ns}', name='second', log_dir=tmp_path)
        assert second.wait(DEADLINE) == 1, second.log_text()
        log = second.log_text()
        assert f'cannot start: another node named {full} is already running' in log, log
        assert 'Traceback' not in log
        assert first.alive(), first.log_text()
        if executable == 'geodesic_planner_node':      # and it still plans
            _plans(helper, full, first)
    finally:
        helper.destroy_subscription(status.subscription)
        if second is not None and second.alive():
            second.stop()
        assert first.stop() == 0, first.log_text()


def _plans(helper: Any, full: str, node: Any) -> None:
    """The planner ``full`` answers a plan request with SUCCESS."""
    client = helper.create_client(PlanTrajectory, f'{full}/plan_trajectory')
    try:
        warm_up_client(client, plan_request(goal=pose_3r(*GOAL_3R, frame='__warmup__')),
                       DEADLINE, watch=[node])
        resp = call_service(client, plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)),
                            DEADLINE, watch=[node])
        assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
    finally:
        helper.destroy_client(client)


@pytest.mark.parametrize('executable, name', [('geodesic_planner_node', 'geodesic_planner'),
                                              ('trajectory_processor_node', 'trajectory_processor')])
def test_namesake_discovered_late_stops_the_younger(helper: Any, tmp_path: Path, executable: str,
                                                    name: str) -> None:
    ns = f'/late_{name}'
    full = f'{ns}/{name}'
    status = StatusWatch(helper)
    first = popen_node(executable, '-r', f'__ns:={ns}', name='older', log_dir=tmp_path)
    second = None
    late = None
    try:
        status.wait(full, 'name check', lambda v: v == 'unique', DEADLINE, watch=[first])
        os.killpg(first.pid, signal.SIGSTOP)        # no discovery traffic from the older node now
        try:
            late = StatusWatch(helper)              # only the newcomer can publish from now on
            second = popen_node(executable, '-r', f'__ns:={ns}', name='younger', log_dir=tmp_path)
            # the newcomer's start-up window passed without a namesake in its graph
            late.wait(full, 'name check', lambda v: v == 'unique', DEADLINE, watch=[second])
            assert second.alive(), second.log_text()
        finally:
            os.killpg(first.pid, signal.SIGCONT)
        assert second.wait(DEADLINE) == 1, second.log_text()
        log = second.log_text()
        assert f'another node named {full} is already running' in log, log
        assert 'Traceback' not in log
        assert first.alive(), first.log_text()
        if executable == 'geodesic_planner_node':
            _plans(helper, full, first)
        status.wait(full, 'name check', lambda v: v == 'unique', DEADLINE, watch=[first])
    finally:
        for watch in (status, late):
            if watch is not None:
                helper.destroy_subscription(watch.subscription)
        if second is not None and second.alive():
            second.stop()
        os.killpg(first.pid, signal.SIGCONT)
        assert first.stop() == 0, first.log_text()


def test_equal_start_times_tie_break_by_id() -> None:
    """Two guards of one name with the same start time, each in a participant of its own (as two
    processes are): exactly the larger id stops, and the other one has seen its claim and stays."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    contexts = [rclpy.Context() for _ in range(2)]
    for context in contexts:
        rclpy.init(context=context)
    nodes = [Node('twin', namespace='/tie', context=c) for c in contexts]
    executors = [SingleThreadedExecutor(context=c) for c in contexts]
    stops = [threading.Event() for _ in nodes]
    threads = []
    try:
        guards = [UniqueNameGuard(n, stop, start_ns=1_700_000_000_123_456_789)
                  for n, stop in zip(nodes, stops)]
        younger = max(range(2), key=lambda i: guards[i].instance_id)
        for node, executor in zip(nodes, executors):
            executor.add_node(node)
            threads.append(threading.Thread(target=executor.spin, daemon=True))
            threads[-1].start()
        wait_until(stops[younger].is_set, DEADLINE, what='the larger id to stop')
        assert guards[younger].refusal is not None and 'another node named /tie/twin' in guards[younger].refusal
        wait_until(lambda: guards[1 - younger].namesakes_seen == 1, DEADLINE,
                   what='the smaller id to see the other claim')
        assert not stops[1 - younger].is_set() and guards[1 - younger].refusal is None
    finally:
        for executor in executors:
            executor.shutdown(timeout_sec=2.0)
        for thread in threads:
            thread.join(timeout=5.0)
        for node in nodes:
            node.destroy_node()
        for context in contexts:
            context.try_shutdown()
