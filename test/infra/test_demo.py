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


def test_demo_via_sequence_and_radius() -> None:
    from geodesic_planner import load_robot
    from tools.demo import demo_poses, paper_poses, via_blend_radius, via_sequence

    robot = load_robot('planar_3r')
    poses = via_sequence(robot)
    assert len(poses) == 5
    np.testing.assert_array_equal(poses[0], paper_poses()[0])
    np.testing.assert_array_equal(poses[-1], paper_poses()[1])
    wrist = [np.linalg.norm(T[:2, 3] - T[:2, 0]) for T in poses]   # tool minus the last (unit) link
    assert max(wrist[1:-1]) < 1.8 and max(wrist) < 2.0               # reachable: within 2 m
    # 0.3 of the shortest segment (via 3 -> goal: sqrt(0.1^2 + 0.3^2) m), to the mm below
    assert via_blend_radius(poses) == 0.094 == math.floor(300 * math.hypot(0.1, 0.3)) / 1000
    other = load_robot('rrpp')
    seq = via_sequence(other)
    start, goal = demo_poses(other)
    np.testing.assert_allclose(seq[0], start, atol=1e-12)
    np.testing.assert_allclose(seq[-1], goal, atol=1e-12)


def test_demo_via_blend_summary_on_known_motion() -> None:
    from geodesic_planner import load_robot
    from tools.demo import via_blend_summary

    robot = load_robot('planar_3r')
    t = np.linspace(0.0, 1.0, 5)
    q = np.zeros((5, 3))
    q[:, 0] = np.linspace(0.0, 0.4, 5)                 # joint 1 only: radius 3 arc
    dq = np.zeros((5, 3))
    dq[:, 0] = [0.0, 0.4, 0.4, 0.4, 0.0]
    T = robot.fk(q)
    poses = [T[0], T[2], T[4]]                          # the middle sample is the via pose
    s = via_blend_summary(t, q, dq, robot, poses)
    assert s['points'] == 5 and s['duration_s'] == 1.0
    assert s['closest_to_via_m'] == [0.0]
    assert s['tool_speed_at_via_m_s'] == pytest.approx([1.2], abs=1e-12)      # 3 m x 0.4 rad/s
    assert s['peak_tool_speed_m_s'] == pytest.approx(1.2, abs=1e-12)
    # samples 1 and 3 sit at the middle of their 0.2 rad chords: sagitta 3 (1 - cos 0.1)
    assert s['max_distance_from_polyline_m'] == pytest.approx(3 * (1 - math.cos(0.1)), abs=1e-12)


@pytest.mark.parametrize('name', ['planar_3r', 'rrpp', 'ur5e', 'panda'])
def test_demo_boxes_refused_on_every_branch_then_free_for_every_preset(name: str) -> None:
    """The collision step's box, planned as the node plans a preset (capsules, default padding, the
    default IK branch then the others): across, the motion is refused on the way (not at the start
    or goal) on every branch; aside, the default branch is free."""
    from geodesic_planner import GeodesicPlanner, load_robot
    from geodesic_planner.core.branches import first_clear, start_branches
    from geodesic_planner.core.collision import DEFAULT_PADDING, CollisionModel, SceneObject, Shape
    from geodesic_planner.core.errors import PathInCollisionError
    from geodesic_planner.core.robots import PRESETS
    from tools.demo import demo_poses
    from tools.demo_collision import demo_boxes

    assert sorted(PRESETS) == ['panda', 'planar_3r', 'rrpp', 'ur5e']        # a new preset: add it here
    robot = load_robot(name)
    start, goal = demo_poses(robot)
    boxes = demo_boxes(robot, start, goal)
    planner = GeodesicPlanner(robot)
    model = CollisionModel.for_robot(robot, padding=DEFAULT_PADDING)

    def attempt(q: np.ndarray | None) -> tuple:
        path = planner.plan(start, goal) if q is None else planner.plan(None, goal, start_joints=q)
        return path, path.timed()

    def branches(first: object) -> list[np.ndarray]:
        return start_branches(planner, start, first.q_start)   # type: ignore[attr-defined]

    def scene(centre: np.ndarray) -> CollisionModel:
        pose = np.eye(4)
        pose[:3, 3] = centre
        return model.with_objects([SceneObject('box', Shape('box', (boxes.edge,) * 3), pose)])

    assert 0.01 <= boxes.edge <= 0.3
    path, _ = attempt(None)
    ends = path.evaluate(np.array([0.0, 1.0]), 0)[0]
    assert np.all(scene(boxes.across).distances(ends)[0] > DEFAULT_PADDING)   # start and goal clear
    with pytest.raises(PathInCollisionError, match="'box' and 'link_") as err:
        first_clear(attempt, scene(boxes.across), branches)
    assert 0.0 < err.value.fraction < 1.0
    _, _, found, branch = first_clear(attempt, scene(boxes.aside), branches)
    assert branch == 'default' and found.min_clearance > DEFAULT_PADDING
    if name == 'planar_3r':     # msg_examples/scene_box.yaml's box, and its place aside
        assert boxes.edge == 0.3
        np.testing.assert_allclose(boxes.across, [2.0, 2.0, 0.0], atol=1e-12)
        np.testing.assert_allclose(boxes.aside, [2.3, 2.3, 0.0], atol=1e-12)


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
    # The via example (PlanTrajectory, plan only): stopping vs blended.
    assert (out / 'via_blend.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    via = summary['via_blend']
    r = via['blend_radius_m']
    stop, blend = via['stopping'], via['blended']
    assert len(via['poses']) == 5 and r == 0.094
    assert re.search(r'via poses \(3, PlanTrajectory\): stopping [\d.]+ s, blended', result.stdout)
    assert all(d < 1e-6 for d in stop['closest_to_via_m'])          # it passes each via pose
    assert all(v < 1e-3 * stop['peak_tool_speed_m_s'] for v in stop['tool_speed_at_via_m_s'])  # at rest
    assert stop['max_distance_from_polyline_m'] < 1e-6
    assert len(blend['blend_deviation_m']) == 3
    assert all(0.0 < d <= r for d in blend['blend_deviation_m'])
    assert all(d <= r for d in blend['closest_to_via_m'])
    assert blend['max_distance_from_polyline_m'] <= max(blend['blend_deviation_m']) + 1e-9
    assert all(v > 0.05 * blend['peak_tool_speed_m_s'] for v in blend['tool_speed_at_via_m_s'])  # no stop
    assert via['time_saved_s'] == pytest.approx(stop['duration_s'] - blend['duration_s'], abs=1e-12)
    assert blend['duration_s'] <= stop['duration_s']           # not stopping saves time
    # Collisions: a 0.3 m box across the line at (2, 2) is refused, at (2.3, 2.3) it is planned.
    col = summary['collision']
    refused, planned = col['refused'], col['planned']
    assert refused['error_code'] == -2, refused          # INVALID_MOTION_PLAN
    assert "'box'" in refused['message'] and "'link_3'" in refused['message'], refused['message']
    # the tool (the end of link_3's capsule, radius 0.05) at (2.5 - s, 1.5 + s) comes within
    # radius + padding 0.01 of the box's corner (2.15, 1.85) at s_tip: refused no later
    assert 0.2 < refused['fraction'] <= 0.35 - 0.06 / math.sqrt(2.0) + 1e-6
    assert planned['error_code'] == 1 and planned['ik_branch'] == 'default'
    # moved aside: the nearest box corner (2.15, 2.15) is 0.3 / sqrt(2) from the line, the tool
    # passes its foot (2, 2); min_clearance is that less the capsule radius, within 10 % below
    exact = 0.3 / math.sqrt(2.0) - 0.05
    assert 0.9 * exact - 1e-6 <= planned['min_clearance_m'] <= exact + 1e-6, planned
    assert col['min_clearance_aside_samples_m'] >= planned['min_clearance_m'] - 1e-9
    assert re.search(r'collision: box across the motion refused at [\d.]+ % of the way', result.stdout)
    assert (out / 'collision.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    # The motion types (library): each on its geometry, the blends save time, PTP of least energy.
    motions = summary['motions']
    assert motions['accuracy']['LIN']['deviation_m'] < 1e-8
    assert motions['accuracy']['CIRC (200 deg through an interim point)']['deviation_m'] < 1e-8
    seq = motions['sequence']
    assert seq['blended']['duration_s'] < seq['stopping']['duration_s']
    assert all(d <= 0.03 * (1 + 1e-9) for d in seq['blended']['zones_max_distance_m'])
    assert motions['ptp']['kinetic_energy']['action'] <= motions['ptp']['joint_line']['action']
    # a PTP blocked by a box goes around it: clear of the padding where the joint line is not
    around = motions['around']
    assert around['direct_min_m'] < 0.01 <= around['min_clearance_m'], around
    assert 'PTP went around obstacles' in around['note']
    for name in ('sequence.png', 'ptp.png', 'around.png'):
        assert (out / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert (out / 'bag' / 'metadata.yaml').is_file()
    from geodesic_planner.io.bags import read_trajectories
    topics = sorted({r.topic for r in read_trajectories(out / 'bag')})
    assert topics == ['/geodesic_planner/joint_trajectory', '/trajectory_processor/joint_trajectory']


@pytest.mark.ros
def test_demo_end_to_end_with_another_robot(tmp_path: Path) -> None:
    """``--robot ur5e`` (documented for every preset): the whole demo passes, its box refused on the
    way (INVALID_MOTION_PLAN, not GOAL_IN_COLLISION) and planned once moved aside."""
    out = tmp_path / 'demo'
    result = subprocess.run([sys.executable, '-m', 'tools.demo', '--output', str(out), '--robot', 'ur5e'],
                            cwd=ROOT, capture_output=True, text=True, timeout=240)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['robot'] == 'ur5e' and len(summary['joint_names']) == 6
    for part in (summary['planned'], summary['processed']):
        assert part['max_tool_path_deviation_m'] < 1e-6 and part['goal_position_error_m'] < 1e-9
    col = summary['collision']
    assert col['refused']['error_code'] == -2, col['refused']         # INVALID_MOTION_PLAN
    assert "'box' and 'link_" in col['refused']['message'] and 0.0 < col['refused']['fraction'] < 1.0
    assert col['planned']['error_code'] == 1 and col['planned']['ik_branch'] == 'default'
    assert col['planned']['min_clearance_m'] > col['padding_m']
    for name in ('trajectory.png', 'via_blend.png', 'collision.png', 'sequence.png', 'ptp.png'):
        assert (out / name).read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_demo_pose_json_position_and_quaternion() -> None:
    from tools.demo import paper_poses, pose_json

    start, _ = paper_poses()                      # yaw 30 deg about z at (2.5, 1.5, 0)
    got = pose_json(start)
    assert got['position'] == [2.5, 1.5, 0.0]
    np.testing.assert_allclose(got['quaternion_xyzw'], [0.0, 0.0, math.sin(math.radians(15.0)),
                                                        math.cos(math.radians(15.0))], atol=1e-15)
