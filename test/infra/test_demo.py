"""Tests of the demo (tools/demo.py): its pure helpers, and the main job end to end (ros)."""
from __future__ import annotations

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_demo_paper_poses_match_the_paper() -> None:
    from numpy.testing import assert_allclose

    from tools.demo import paper_poses

    start, goal = paper_poses()
    assert_allclose(start[:3, 3], [2.5, 1.5, 0.0], atol=0)
    assert_allclose(goal[:3, 3], [1.5, 2.5, 0.0], atol=0)
    assert_allclose(start[:3, 0], [math.sqrt(3) / 2, 0.5, 0.0], atol=1e-15)   # n = (0.866, 0.5, 0)
    n_goal = np.array([0.714, 0.7, 0.0]) / math.hypot(0.714, 0.7)
    assert_allclose(goal[:3, 0], n_goal, atol=1e-15)
    for T in (start, goal):
        assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-15)
        assert_allclose(T[:3, 2], [0, 0, 1], atol=0)


def test_demo_segment_deviation_exact() -> None:
    from tools.demo import segment_deviation

    a, b = np.array([0.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0])
    pts = np.array([[1.0, 0.0, 0.0], [1.0, 3.0, 4.0], [-3.0, 4.0, 0.0], [5.0, 0.0, 4.0]])
    np.testing.assert_allclose(segment_deviation(pts, a, b), [0.0, 5.0, 5.0, 5.0], atol=1e-15)
    np.testing.assert_allclose(segment_deviation(pts[:1], a, a), [1.0], atol=1e-15)


def test_demo_trajectory_summary_on_known_motion() -> None:
    from geodesic_planner import load_robot
    from tools.demo import trajectory_summary

    robot = load_robot('planar_3r')
    t = np.linspace(0.0, 2.0, 5)
    q = np.zeros((5, 3))
    q[:, 0] = np.linspace(0.0, 0.4, 5)                 # joint 1 only: the tool moves on a circle
    dq = np.zeros((5, 3))
    dq[:, 0] = [0.0, 0.3, -0.5, 0.1, 0.0]
    start, goal = robot.fk(q[0]), robot.fk(q[-1])
    s = trajectory_summary(t, q, dq, robot, start, goal)
    assert s['points'] == 5 and s['duration_s'] == 2.0
    assert s['peak_joint_speed'] == [0.5, 0.0, 0.0]
    assert s['start_position_error_m'] == 0.0 and s['goal_position_error_m'] < 1e-15
    # Radius 3 arc through 0.4 rad: sagitta at its middle = 3 (1 - cos 0.2), hit by the middle point.
    assert abs(s['max_tool_path_deviation_m'] - 3 * (1 - math.cos(0.2))) < 1e-12


@pytest.mark.ros
def test_demo_end_to_end(tmp_path: Path) -> None:
    """The main job as the README runs it (inside the namespace): both nodes, bag, summary, plot."""
    out = tmp_path / 'demo'
    result = subprocess.run([sys.executable, '-m', 'tools.demo', '--output', str(out)], cwd=ROOT,
                            capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stdout + result.stderr
    for line in ('starting planner node', 'starting trajectory processor node', 'planner ready',
                 'stopping the processor', 'bag read back'):
        assert line in result.stdout, result.stdout
    summary = json.loads((out / 'summary.json').read_text())
    planned, processed = summary['planned'], summary['processed']
    # What was received live (printed) is what the bag holds.
    live = re.search(r'plan received: (\d+) points, ([\d.]+) s', result.stdout)
    live2 = re.search(r'processed trajectory received: (\d+) points, ([\d.]+) s', result.stdout)
    assert live and live2, result.stdout
    assert int(live[1]) == planned['points'] and int(live2[1]) == processed['points']
    assert float(live[2]) == pytest.approx(planned['duration_s'], abs=5e-4)
    assert float(live2[2]) == pytest.approx(processed['duration_s'], abs=5e-4)
    assert planned['topic'] == '/geodesic_planner/joint_trajectory'
    assert processed['topic'] == '/trajectory_processor/joint_trajectory'
    # Processing at velocity_scaling 0.5: twice the duration, half the peak speeds, points every 0.01 s.
    assert processed['duration_s'] == pytest.approx(2 * planned['duration_s'], abs=1e-9)
    assert processed['points'] == math.ceil(processed['duration_s'] / 0.01 - 1e-9) + 1
    np.testing.assert_allclose(processed['peak_joint_speed'],
                               0.5 * np.array(planned['peak_joint_speed']), rtol=2e-3)
    for part in (planned, processed):
        assert part['max_tool_path_deviation_m'] < 1e-6      # the geodesic keeps the tool on the line
        assert part['start_position_error_m'] < 1e-9
        assert part['goal_position_error_m'] < 1e-9
        assert all(0 < v <= 1.0 + 1e-9 for v in part['peak_joint_speed'])  # planar_3r limit 1 rad/s
    assert (out / 'trajectory.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert (out / 'bag' / 'metadata.yaml').is_file()
    from geodesic_planner.io.bags import read_trajectories
    topics = sorted({r.topic for r in read_trajectories(out / 'bag')})
    assert topics == ['/geodesic_planner/joint_trajectory', '/trajectory_processor/joint_trajectory']
