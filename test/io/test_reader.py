"""Reading trajectories and bag summaries (io.bags.reader)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from bag_util import IN, JS, example, joint_state, trajectory
from geodesic_planner.cli import bag as bag_cli
from geodesic_planner.core.errors import BagError
from geodesic_planner.io.bags import (
    JOINT_STATE,
    JOINT_TRAJECTORY,
    BagRecorder,
    bag_info,
    read_trajectories,
    to_cdr,
)


def test_invalid_trajectory_recorded_with_problems(tmp_path, ts):
    t = np.array([0.0, 1.0, 1.0])
    q = np.zeros((3, 3))
    bad = trajectory(t, q)
    bad.points[1].positions = [0.0, 1.0]
    bad.points[2].positions = [0.0, float('nan'), 0.0]
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY}) as rec:
        rec.write(IN, 1, to_cdr(bad, JOINT_TRAJECTORY, ts))
    (r,) = read_trajectories(tmp_path / 'b')
    assert 'point 1: 2 positions, expected 3 (one per joint)' in r.problems
    assert 'point 2: positions contain NaN or inf' in r.problems
    assert any('not after' in p for p in r.problems)
    assert np.isnan(r.positions[1]).all()
    assert r.velocities is None


def test_read_errors(tmp_path, ts):
    with pytest.raises(BagError, match='no such bag'):
        read_trajectories(tmp_path / 'missing')
    (tmp_path / 'plain').mkdir()
    with pytest.raises(BagError, match='not a bag'):
        bag_info(tmp_path / 'plain')
    with BagRecorder(tmp_path / 'b', topics={JS: JOINT_STATE}) as rec:
        rec.write(JS, 1, to_cdr(joint_state(0), JOINT_STATE, ts))
    with pytest.raises(BagError, match='topic /nope not in bag'):
        read_trajectories(tmp_path / 'b', topic='/nope')
    with pytest.raises(BagError, match='not a trajectory_msgs/msg/JointTrajectory topic'):
        read_trajectories(tmp_path / 'b', topic=JS)
    assert read_trajectories(tmp_path / 'b') == []
    (tmp_path / 'b' / 'metadata.yaml').unlink()
    with pytest.raises(BagError, match='interrupted; run `geodesic-bag repair'):
        read_trajectories(tmp_path / 'b')


def test_bag_info_summary(tmp_path, ts):
    rng = np.random.default_rng(5)
    t, q, dq, ddq = example(rng, 6)
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY, JS: JOINT_STATE}) as rec:
        for i in range(4):
            rec.write(JS, 2_000_000_000 + i * 100_000_000, to_cdr(joint_state(i), JOINT_STATE, ts))
        rec.write(IN, 2_050_000_000, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        rec.write(IN, 2_060_000_000, to_cdr(trajectory(t, q), JOINT_TRAJECTORY, ts))
    info = bag_info(tmp_path / 'b')
    assert info.storage == 'mcap'
    assert info.message_count == 6
    assert info.duration == pytest.approx(0.3)
    topics = {x.name: x for x in info.topics}
    assert topics[JS].count == 4
    assert topics[JS].duration == pytest.approx(0.3)
    assert topics[IN].count == 2
    s0, s1 = info.trajectories
    assert (s0.points, s0.dof, s0.index, s1.index) == (6, 3, 0, 1)
    assert s0.duration == pytest.approx(t[-1] - t[0], abs=1e-9)
    assert s0.peak_velocity == np.abs(dq).max()
    assert s0.peak_acceleration == np.abs(ddq).max()
    assert np.isnan(s1.peak_velocity)
    text = bag_cli.format_info(info)
    assert f'{IN} #0 at +0.050 s: 6 points, 3 joints' in text
    assert f'peak |v| {np.abs(dq).max():.4g}' in text


EXAMPLES = Path(__file__).resolve().parents[2] / 'msg_examples'


def _yaml_trajectory(path: Path):
    data = yaml.safe_load(path.read_text())
    pts = data['points']
    t = np.array([p['time_from_start']['sec'] + p['time_from_start']['nanosec'] * 1e-9 for p in pts])
    arrays = [np.array([p[k] for p in pts], dtype=float) for k in ('positions', 'velocities', 'accelerations')]
    return data['joint_names'], t, *arrays


def _fk_3r(q):
    c = np.cumsum(q, axis=1)
    return np.stack([np.cos(c).sum(1), np.sin(c).sum(1), c[:, 2]], axis=1)


def test_yaml_examples_are_the_paper_trajectory_before_and_after_scaling():
    names, t, q, dq, ddq = _yaml_trajectory(EXAMPLES / 'joint_trajectory.yaml')
    names2, t2, q2, dq2, ddq2 = _yaml_trajectory(EXAMPLES / 'joint_trajectory_processed.yaml')
    assert names == names2 == ['joint1', 'joint2', 'joint3']
    assert np.all(np.diff(t) > 0) and t[0] == 0.0
    assert_allclose(dq[[0, -1]], 0.0, atol=1e-9)
    assert_allclose(ddq[[0, -1]], 0.0, atol=1e-9)
    # paper example: tool on the straight line A -> B with phi linear along it (exact oracle)
    a, b = np.array([2.5, 1.5, np.radians(30)]), np.array([1.5, 2.5, np.arctan2(0.7, 0.714)])
    xyphi = _fk_3r(q)
    lam = (xyphi[:, :2] - a[:2]) @ (b - a)[:2] / np.sum((b - a)[:2] ** 2)
    assert_allclose(xyphi, a + lam[:, None] * (b - a), atol=1e-5)
    assert_allclose(lam[[0, -1]], [0.0, 1.0], atol=1e-5)
    # processed at f = 0.5: twice as long, point k at 0.5 k s is the original at 0.25 k s
    assert t2[-1] == pytest.approx(2 * t[-1], abs=2e-9)
    n = min(len(t), len(t2)) - 1
    assert_allclose(t2[:n], 2 * t[:n], atol=1e-9)
    assert_allclose(q2[:n], q[:n], atol=2e-9)
    assert_allclose(dq2[:n], 0.5 * dq[:n], atol=2e-9)
    assert_allclose(ddq2[:n], 0.25 * ddq[:n], atol=2e-9)
