"""The trajectory processor against hostile input and a full disk (issue 13, items 2, 5, 6, 8).

Through the real node (console script, DDS, bags read back with rosbags). Every wait has an event
and a deadline: outputs by content, counters on /diagnostics; log lines are only checked to
exist, after the node has exited or after waiting for them.
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

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from bag_util import fill, tmpfs
from geodesic_planner.io.bags import bag_info, read_trajectories
from geodesic_planner.ros import conversions as cv
from tools.graph import StatusWatch

from .launch import wait_for_subscribers, wait_until
from .test_processor import (DEADLINE, INPUT, KNOTS, NAMES, OUTPUT, PROCESSOR, Q0, Q1, Processor, bag_dir,
                             check_output, decoded, known_trajectory, min_jerk, processor_totals)

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]


def _end(msg: Any) -> list[float]:
    return list(msg.points[-1].positions)


def _goal_end(goal: np.ndarray) -> list[float]:
    return list(min_jerk(np.array([KNOTS[-1]]), KNOTS[-1], Q0, goal)[0][0])


# =========================================================================== item 2: output bound
def test_output_bound_refused_with_reason_counted_and_recorded(start_node: Any, ros_node: Any,
                                                               tmp_path: Path) -> None:
    status = StatusWatch(ros_node)
    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag'), 'sample_period': 0.01})
    q, dq, ddq = min_jerk(KNOTS, KNOTS[-1], Q0, Q1)
    stretched = cv.arrays_to_joint_trajectory(NAMES, KNOTS * 1e4, q, dq * 1e-4, ddq * 1e-8)  # 20000 s
    n_wide = 200
    wide = cv.arrays_to_joint_trajectory([f'j{k}' for k in range(n_wide)], np.array([0.0, 100.0]),
                                         np.zeros((2, n_wide)), np.zeros((2, n_wide)), np.zeros((2, n_wide)))
    assert cv.validate_joint_trajectory(stretched) == [] and cv.validate_joint_trajectory(wide) == []
    p.pub.publish(stretched)
    p.pub.publish(wide)
    p.pub.publish(known_trajectory())
    (out,) = p.wait_outputs(1)   # in order: both refusals came first
    check_output(out, 1.0, 0.01)
    status.wait(PROCESSOR, 'rejected too large', lambda v: v == '2', DEADLINE, watch=p.watch)

    # the bound is exact: 2 s at 0.01 s is 201 points, bounded by floor(200) + 2 = 202
    for value, reason in ((0, 'max_output_points: must be > 0'), (1.5, 'max_output_points: must be an integer')):
        (res,) = p.set_parameters(max_output_points=value)
        assert not res.successful and reason in res.reason
    (res,) = p.set_parameters(max_output_points=202)
    assert res.successful
    p.pub.publish(known_trajectory(Q0, Q1 + 0.1))
    p.out.wait_for_message(lambda m: _end(m) == _goal_end(Q1 + 0.1), timeout=DEADLINE, watch=p.watch)
    (res,) = p.set_parameters(max_output_points=201)
    assert res.successful
    p.pub.publish(known_trajectory(Q0, Q1 + 0.2))   # refused
    (res,) = p.set_parameters(max_output_points=100_000)
    assert res.successful
    p.pub.publish(known_trajectory(Q0, Q1 + 0.3))   # the barrier: published after the refusal
    p.out.wait_for_message(lambda m: _end(m) == _goal_end(Q1 + 0.3), timeout=DEADLINE, watch=p.watch)
    assert [_end(m) for m in p.out.messages] == [_goal_end(Q1), _goal_end(Q1 + 0.1), _goal_end(Q1 + 0.3)]
    status.wait(PROCESSOR, 'rejected too large', lambda v: v == '3', DEADLINE, watch=p.watch)

    log = p.stop()
    assert processor_totals(log) == (6, 3, 3)
    assert ('rejected trajectory: output too large: 20000 s at sample_period 0.01 s (velocity_scaling 1) '
            'would be up to 2e+06 points, max_output_points is 100000') in log
    assert ('rejected trajectory: output too large: 10002 points x 200 joints = 2.0004e+06 values per field, '
            'more than 16 x max_output_points = 1600000') in log
    assert 'would be up to 202 points, max_output_points is 201' in log
    path = bag_dir(log)
    counts = {t.name: t.count for t in bag_info(path).topics}
    assert counts[INPUT] == 6 and counts[OUTPUT] == 3   # every refused input recorded as received


@pytest.mark.parametrize('ros_args, params', [
    ((), {'input_topic': OUTPUT}),                                     # the default output, by name
    ((), {'input_topic': '~/joint_trajectory'}),                       # the same after expansion
    (('-r', '/elsewhere:=/trajectory_processor/joint_trajectory'), {'input_topic': '/elsewhere'}),  # remapped
])
def test_input_topic_equal_to_output_topic_refused_at_start(start_node: Any, ros_args: tuple[str, ...],
                                                            params: dict[str, Any]) -> None:
    proc = start_node('trajectory_processor_node', *ros_args, params=params, name='loop')
    rc = proc.wait(DEADLINE)
    log = proc.log_text()
    assert rc == 1, log
    lines = [line for line in log.splitlines() if 'cannot start' in line]
    assert len(lines) == 1, log
    assert f'are the same topic {OUTPUT}: the processor would process its own output' in lines[0]
    assert 'Traceback' not in log


# =========================================================================== item 6: output validated
def test_non_finite_output_and_empty_joint_name_never_published(start_node: Any, ros_node: Any,
                                                                tmp_path: Path) -> None:
    p = Processor(start_node, ros_node, {'bag_path': str(tmp_path / 'bag')})
    huge = cv.arrays_to_joint_trajectory(['a', 'b'], np.array([0.0, 1.0]),
                                         np.array([[1e308, -1e308], [-1e308, 1e308]]), np.zeros((2, 2)),
                                         np.zeros((2, 2)))
    assert cv.validate_joint_trajectory(huge) == []   # a valid input ...
    unnamed = known_trajectory()
    unnamed.joint_names = ['joint1', '', 'joint3']
    p.pub.publish(huge)
    p.pub.publish(unnamed)
    p.pub.publish(known_trajectory())
    outs = p.wait_outputs(1)
    check_output(outs[0], 1.0, 0.01)
    log = p.stop()
    assert len(p.out) == 1   # nothing else was published before the good one (one publisher, in order)
    assert processor_totals(log) == (3, 1, 2)
    # ... whose output is not
    assert 'rejected trajectory: output would be invalid: point 1: positions contain NaN or inf' in log
    assert 'rejected trajectory: empty joint name at index 1' in log
    recs = read_trajectories(bag_dir(log), OUTPUT)
    assert len(recs) == 1 and recs[0].problems == ()


# =========================================================================== item 8: best effort
def test_best_effort_joint_states_recorded(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """A best-effort publisher that appears after the node started (the usual sensor QoS)."""
    bag = tmp_path / 'bag'
    p = Processor(start_node, ros_node, {'bag_path': str(bag)})
    qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT,
                     durability=DurabilityPolicy.VOLATILE)
    js_pub = ros_node.create_publisher(JointState, '/joint_states', qos)
    wait_for_subscribers(js_pub, 1, DEADLINE, watch=p.watch)   # never matched by a reliable reader
    p.sync()
    n = 20
    for k in range(n):
        js_pub.publish(JointState(name=NAMES, position=[0.1 * k, 0.0, 0.0]))
    p.pub.publish(known_trajectory())
    p.wait_outputs(1)
    from .test_processor import on_disk
    wait_until(lambda: on_disk(bag, tmp_path).get('/joint_states') == n, DEADLINE,
               what=f'{n} joint states in the bag', watch=p.watch)
    log = p.stop()
    states = decoded(bag_dir(log), '/joint_states')
    assert [s.position[0] for s in states] == pytest.approx([0.1 * k for k in range(n)])


# =========================================================================== item 5: full disk
def _closing(log: str) -> tuple[dict[str, int], dict[str, int]]:
    """(per-topic counts, per-topic not recorded) of the closing line."""
    m = re.search(r'bag closed: \S+ \(\d+ messages; ([^)]*)\)', log)
    assert m, log
    counts = {k: int(v) for k, v in (x.rsplit(': ', 1) for x in m.group(1).split(', '))}
    lost: dict[str, int] = {}
    m = re.search(r'bag write failures \d+, not recorded: (.*?) \(last error', log)
    if m and m.group(1) != 'none':
        lost = {k: int(v) for k, v in (x.rsplit(': ', 1) for x in m.group(1).split(', '))}
    return counts, lost


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_full_disk_counts_are_what_is_on_disk(start_node: Any, ros_node: Any, tmp_path: Path, storage: str) -> None:
    status = StatusWatch(ros_node)
    with tmpfs(tmp_path / 'fs', '1m') as fs:
        filler = fill(fs, 100 * 1024)   # about 100 KiB left: room for a few outputs
        p = Processor(start_node, ros_node, {'bag_path': str(fs / 'bag'), 'storage': storage})
        goals = [Q1 + 0.01 * k for k in range(15)]
        for g in goals[:12]:   # ~19 KB per output: more than the space left
            p.pub.publish(known_trajectory(Q0, g))
        p.wait_outputs(12)
        status.wait(PROCESSOR, 'bag write failures', lambda v: int(v) >= 1, DEADLINE, watch=p.watch)
        filler.unlink()   # space again
        for g in goals[12:]:
            p.pub.publish(known_trajectory(Q0, g))
        p.wait_outputs(15)
        log = p.stop(signal.SIGINT)
        assert 'bag write failure: ' in log
        counts, lost = _closing(log)
        received, published, rejected = processor_totals(log)
        assert (received, published, rejected) == (15, 15, 0)
        # Whether anything is lost depends on timing (mcap keeps a failed flush in memory and
        # retries it; if the retry comes after the space is freed, everything reaches the disk).
        # What must hold either way: on disk + not recorded = what went through, and the file agrees.
        assert counts[INPUT] + lost.get(INPUT, 0) == received
        assert counts[OUTPUT] + lost.get(OUTPUT, 0) == published
        path = bag_dir(log)
        assert {t.name: t.count for t in bag_info(path).topics} == counts      # read back from the file
        meta = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
        assert {x['topic_metadata']['name']: x['message_count'] for x in meta['topics_with_message_count']} == counts
        assert meta['message_count'] == sum(counts.values())
        print(f'{storage}: received {received}, on disk {counts}, not recorded {lost}')
