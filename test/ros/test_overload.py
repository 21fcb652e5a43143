"""Floods of plan requests through the real planner node: every request answered, refusals visible.

The model of outcomes is complete (issue 26 #3): every reply is a success, a refusal because the
queue was full (PLANNING_FAILED, "planner overloaded"), or a refusal in time (TIMED_OUT, naming
plan_timeout: the request waited its whole plan_timeout for its turn, or its plan was abandoned).
Which refusals a loaded machine produces is not asserted; the invariants are: replies received =
requests sent (nothing lost); successful replies = trajectories published, each once (a sentinel
plan must be the next message); each kind of refusal = the node's own /diagnostics counter of it.
The figures go to docs/reliability.md.
"""
from __future__ import annotations

import time
from typing import Any

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory
from rcl_interfaces.msg import Log
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from tools.graph import StatusWatch

from .launch import (Collector, call_service, popen_node, wait_until,
                     warm_up_client)
from .test_plan_trajectory import plan_request
from .test_planner_node import GOAL_3R, START_3R, _rss_mb, pose_3r

pytestmark = [pytest.mark.ros, pytest.mark.timeout(600)]

DEADLINE = 120.0
#: Clients' QoS: KEEP_ALL, so that a client's own writer never overwrites a request it has not sent.
CLIENT_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
OVERLOADED = 'planner overloaded'


def kind(reply: PlanTrajectory.Response) -> str:
    """'ok', 'refused' (queue full), 'timed_out' (plan_timeout) or 'other' (a failure of the test)."""
    code = reply.error_code.val
    if code == PlanErrorCode.SUCCESS:
        return 'ok'
    if code == PlanErrorCode.PLANNING_FAILED and reply.message.startswith(OVERLOADED):
        return 'refused'
    if code == PlanErrorCode.TIMED_OUT and 'plan_timeout' in reply.message:
        return 'timed_out'
    return 'other'


def flood(helper: Any, ns: str, params: dict[str, Any], tmp: Any, n_requests: int, n_clients: int,
          request: PlanTrajectory.Request) -> dict[str, Any]:
    """Start a planner in ``ns``, send ``n_requests`` at once from ``n_clients``, count everything."""
    name = f'{ns}/geodesic_planner'
    proc = popen_node('geodesic_planner_node', '-r', f'__ns:={ns}', params=params,
                      name=ns.strip('/'), log_dir=tmp)
    watch = [proc]
    traj = Collector(helper, JointTrajectory, f'{name}/joint_trajectory',
                     QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    rosout = Collector(helper, Log, '/rosout', QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    status = StatusWatch(helper)
    clients = [helper.create_client(PlanTrajectory, f'{name}/plan_trajectory', qos_profile=CLIENT_QOS)
               for _ in range(n_clients)]
    try:
        wait_until(lambda: traj.subscription.get_publisher_count() > 0, DEADLINE,
                   what='trajectory publisher matched', watch=watch)
        for c in clients:       # one harmless round trip each (an unknown frame: refused)
            warm_up_client(c, plan_request(goal=pose_3r(*GOAL_3R, frame='__warmup__')), DEADLINE,
                           watch=watch)
        rss_before = _rss_mb(proc.pid)
        n0 = len(traj)
        t0 = time.monotonic()
        futures = [clients[i % n_clients].call_async(request) for i in range(n_requests)]
        wait_until(lambda: all(f.done() for f in futures), DEADLINE,
                   what=f'replies to all {n_requests} requests', watch=watch)
        seconds = time.monotonic() - t0
        replies = [f.result() for f in futures]
        codes = [r.error_code.val for r in replies]
        kinds = [kind(r) for r in replies]
        ok, refused, timed_out = (kinds.count(k) for k in ('ok', 'refused', 'timed_out'))
        # exactly the successful plans were published: a sentinel plan is the next message
        traj.wait_for(n0 + ok, DEADLINE, watch=watch)
        sentinel = call_service(clients[0], _sentinel(), DEADLINE, watch=watch)
        assert sentinel.error_code.val == PlanErrorCode.SUCCESS, sentinel.message
        msgs = traj.wait_for(n0 + ok + 1, DEADLINE, watch=watch)
        assert len(msgs) == n0 + ok + 1 and msgs[-1] == sentinel.trajectory
        if refused:
            status.wait(name, 'requests refused queue full', lambda v: int(v) == refused, DEADLINE,
                        watch=watch)
            wait_until(lambda: any(OVERLOADED in m.msg for m in rosout.messages), DEADLINE,
                       what='the overload warning', watch=watch)
        # every refusal in time is counted by the node: waited too long, or abandoned
        status.wait(name, 'requests timed out waiting',
                    lambda v: int(v) + int(status.values(name).get('plans abandoned', '-1')) == timed_out,
                    DEADLINE, watch=watch)
        return {'sent': n_requests, 'answered': len(replies), 'ok': ok, 'refused': refused,
                'timed_out': timed_out, 'other': kinds.count('other'), 'codes': sorted(set(codes)),
                'messages': sorted({r.message[:60] for r in replies if r.error_code.val != 1}),
                'seconds': seconds, 'rss_before': rss_before, 'rss_after': _rss_mb(proc.pid),
                'published': len(msgs) - n0 - 1}
    finally:
        for c in clients:
            helper.destroy_client(c)
        helper.destroy_subscription(traj.subscription)
        helper.destroy_subscription(rosout.subscription)
        helper.destroy_subscription(status.subscription)
        assert proc.stop() == 0, proc.log_text()


def _sentinel() -> PlanTrajectory.Request:
    return plan_request(pose_3r(*START_3R), pose_3r(GOAL_3R[0], GOAL_3R[1] - 0.02, GOAL_3R[2]),
                        execute=True)


def test_burst_of_500_every_request_answered(helper: Any, tmp_path: Any) -> None:
    req = plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), execute=True)
    got = flood(helper, '/burst', {'robot': 'planar_3r'}, tmp_path, 500, 10, req)
    print(f'burst of 500: {got}')
    assert got['answered'] == 500                       # lost = 0
    assert got['other'] == 0, got['messages']           # answered = planned + refused visibly
    assert got['ok'] + got['refused'] + got['timed_out'] == 500
    assert got['ok'] >= 1 and got['published'] == got['ok']
    assert got['rss_after'] - got['rss_before'] < 50.0, got      # MB


def test_full_queue_refuses_at_once_and_says_so(helper: Any, tmp_path: Any) -> None:
    """Two places and plans that take about a second each: of 20 requests sent at once, the two
    that got in are planned and published, the other 18 are refused at once and counted."""
    req = plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R), execute=True)
    # the paper move lasts about 2.25 s: 4e-5 s per point gives ~56000 points (about a second to build)
    got = flood(helper, '/small', {'robot': 'planar_3r', 'max_queued_requests': 2,
                                   'sample_period': 4e-5, 'plan_timeout': 60.0}, tmp_path, 20, 4, req)
    print(f'burst of 20 into a queue of 2: {got}')
    assert got['answered'] == 20 and got['other'] == 0, got['messages']
    assert got['ok'] + got['refused'] + got['timed_out'] == 20 and got['published'] == got['ok']
    # at most two requests inside at once and 60 s to plan: the 18 sent beside the first two are
    # refused at once (a request sent after a plan ended would be planned: not asserted away)
    assert got['ok'] >= 2 and got['refused'] >= 1 and got['timed_out'] == 0
