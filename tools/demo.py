"""The main job: the paper's example through both ROS nodes, recorded, summarised and plotted.

``python -m tools.demo [--output DIR] [--robot planar_3r] [--timeout S]``
(normally through ``bash scripts/demo.sh``, which sets up the venv and the loopback-only network
namespace). Steps:

1. start ``geodesic_planner_node`` (``-p robot:=ROBOT``) and ``trajectory_processor_node``
   (``-p velocity_scaling:=0.5 -p sample_period:=0.01 -p bag_path:=DIR/bag``)
   (:func:`tools.process.popen_node`), output in ``DIR/logs/``;
2. wait for ``/geodesic_planner/plan``, then until both publishers will deliver to us and the
   planner's to the processor (:func:`tools.graph.wait_writer_matched`: the graph and replies,
   never log lines);
3. call the service (nav_msgs/srv/GetPlan) with the paper's planar 3R poses (for another robot:
   from its home pose to the pose of home + 0.3 rad (or m) on every joint);
4. receive the trajectory on ``/geodesic_planner/joint_trajectory`` and the processed one on
   ``/trajectory_processor/joint_trajectory``;
5. stop the processor with SIGINT (the bag is closed);
6. via poses with blends: ask ``/geodesic_planner/plan_trajectory`` (PlanTrajectory, plan only)
   twice for a 5-pose sequence (start, 3 via poses, goal; :func:`via_sequence`), with
   ``blend_radius`` 0 (rest at every via pose) and > 0 (:func:`via_blend_radius`: pass them
   without stopping);
7. collisions (:mod:`tools.demo_collision`): a box across the motion (placed and sized from the
   robot's geometry, checked with the library first) is refused with the pair named, moved aside
   (same service) and planned; then stop the planner;
8. the motion types (:mod:`tools.motions`, library only): ``DIR/sequence.png`` and ``DIR/ptp.png``;
9. read both trajectories back from the bag (:func:`geodesic_planner.io.bags.read_trajectories`),
   print a summary and write ``DIR/summary.json`` (poses as 4x4 matrices and as position +
   quaternion), ``DIR/trajectory.png`` (the joints with their limits, the tool path against the
   straight line), ``DIR/via_blend.png`` (tool path and tool speed of both via plans) and
   ``DIR/collision.png``.

A node that dies or a wait that times out prints the node's log tail and exits with 1.

Demo tooling, not part of the installed library: run from the repository root (``demo.sh`` sets
``PYTHONPATH``). rclpy is imported inside :func:`run_demo`, so the pure helpers can be imported
and tested without ROS.
"""
from __future__ import annotations

import argparse
import itertools
import json
import math
import shutil
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from geodesic_planner.core.collision import DEFAULT_PADDING
from geodesic_planner.core.errors import GeodesicPlannerError
from geodesic_planner.core.kinematics import Chain
from geodesic_planner.core.transforms import transform_to_pose
from tools import netns
from tools.demo_collision import collision_summary, run_collision_step, say_summary
from tools.motions import motions_demo
from tools.process import NodeProcess, ToolError, popen_node, wait_until

__all__ = ['DemoError', 'main', 'paper_poses', 'pose_json', 'run_demo', 'segment_deviation',
           'tool_speed', 'trajectory_summary', 'via_blend_radius', 'via_blend_summary', 'via_sequence']

PLAN_SERVICE = '/geodesic_planner/plan'
PLAN_TRAJECTORY_SERVICE = '/geodesic_planner/plan_trajectory'
PLANNED_TOPIC = '/geodesic_planner/joint_trajectory'
PROCESSED_TOPIC = '/trajectory_processor/joint_trajectory'
VELOCITY_SCALING = 0.5
SAMPLE_PERIOD = 0.01


class DemoError(GeodesicPlannerError):
    """The demo could not complete (a node died, a wait timed out, a result is missing)."""


# --------------------------------------------------------------------------- geometry (pure)

def _yaw_pose(x: float, y: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = [x, y]
    return T


def paper_poses() -> tuple[np.ndarray, np.ndarray]:
    """Start and goal tool poses of the paper's planar 3R example (Table 1), 4x4, base frame, m.

    Start p = (2.5, 1.5, 0), n = (0.866, 0.5, 0) (yaw 30 deg); goal p = (1.5, 2.5, 0),
    n = (0.714, 0.7, 0) (yaw atan2(0.7, 0.714)).
    """
    return _yaw_pose(2.5, 1.5, math.radians(30.0)), _yaw_pose(1.5, 2.5, math.atan2(0.7, 0.714))


def demo_poses(robot: Chain) -> tuple[np.ndarray, np.ndarray]:
    """Start/goal poses for ``robot``: the paper's for planar_3r, else fk(home) -> fk(home + 0.3)."""
    if robot.name == 'planar_3r':
        return paper_poses()
    q0 = np.asarray(robot.home, dtype=float)
    q1 = np.clip(q0 + 0.3, robot.lower, robot.upper)
    return robot.fk(q0), robot.fk(q1)


def via_sequence(robot: Chain) -> list[np.ndarray]:
    """Five tool poses (start, 3 via poses, goal), 4x4, base frame, m, for the via example.

    planar_3r: the paper's start and goal with three via poses zig-zagging between them (wrist
    points within 1.8 m of the base: reachable, and so is every straight segment between them).
    Other robots: fk(home + 0.3 k/4 + 0.1 (-1)^k z) for k = 0..4, z = (1, -1, 1, ...) on the via
    poses only (clipped to the joint limits): the demo's start and goal with a zig-zag between.
    """
    if robot.name == 'planar_3r':
        start, goal = paper_poses()
        return [start, _yaw_pose(2.0, 1.9, math.radians(40.0)), _yaw_pose(1.7, 1.5, math.radians(30.0)),
                _yaw_pose(1.6, 2.2, math.radians(50.0)), goal]
    q0 = np.asarray(robot.home, dtype=float)
    zig = np.where(np.arange(robot.dof) % 2 == 0, 1.0, -1.0)
    qs = [q0 + 0.3 * k / 4 + (0.1 * (-1) ** k * zig if 0 < k < 4 else 0.0) for k in range(5)]
    return [robot.fk(np.clip(q, robot.lower, robot.upper)) for q in qs]


def via_blend_radius(poses: Sequence[np.ndarray]) -> float:
    """Blend radius (m) of the via example: 0.3 of the shortest tool segment, to the mm below
    (so the balls around consecutive via poses stay apart)."""
    p = np.array([T[:3, 3] for T in poses])
    shortest = float(np.linalg.norm(np.diff(p, axis=0), axis=1).min())
    return math.floor(300.0 * shortest) / 1000.0


def tool_speed(robot: Chain, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """Speed of the tool origin (m/s), shape (N,), from joint positions and velocities (N, dof)
    through the base-frame Jacobian's linear rows."""
    return np.linalg.norm(np.einsum('nij,nj->ni', robot.jacobian(q)[:, :3], dq), axis=1)


def via_blend_summary(t: np.ndarray, q: np.ndarray, dq: np.ndarray, robot: Chain,
                      poses: Sequence[np.ndarray]) -> dict[str, Any]:
    """Numbers describing one timed motion through via poses.

    Args:
        t: times, shape (N,), s.
        q, dq: joint positions and velocities, shape (N, dof), robot joint order; rad (m), /s.
        robot: the model (``fk``, ``jacobian``).
        poses: start, via poses, goal, 4x4, base frame.

    Returns:
        points, duration (s), the tool's closest approach to each via pose (m), its largest
        distance from the polyline start-via-goal (m), the tool speed at the point nearest each
        via pose (m/s) and the peak tool speed (m/s).
    """
    tool = robot.fk(q)[:, :3, 3]
    speed = tool_speed(robot, q, dq)
    corners = np.array([T[:3, 3] for T in poses])
    to_via = np.linalg.norm(tool[:, None] - corners[None, 1:-1], axis=2)
    to_line = np.min([segment_deviation(tool, a, b) for a, b in itertools.pairwise(corners)], axis=0)
    near = np.argmin(to_via, axis=0)
    return {
        'points': len(t),
        'duration_s': float(t[-1] - t[0]) if len(t) > 1 else 0.0,
        'closest_to_via_m': [float(d) for d in to_via.min(axis=0)],
        'max_distance_from_polyline_m': float(to_line.max()),
        'tool_speed_at_via_m_s': [float(v) for v in speed[near]],
        'peak_tool_speed_m_s': float(speed.max()),
    }


def pose_json(T: np.ndarray) -> dict[str, list[float]]:
    """A 4x4 pose (base frame, m) as summary.json gives it besides the matrix: ``position`` (m) and
    ``quaternion_xyzw`` (x, y, z, w; w >= 0, as geometry_msgs/Pose orders it)."""
    position, quaternion = transform_to_pose(T)
    return {'position': [float(v) for v in position], 'quaternion_xyzw': [float(v) for v in quaternion]}


def segment_deviation(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point to the segment [a, b].

    Args:
        points: shape (N, 3), m.
        a, b: segment ends, shape (3,), m.

    Returns:
        Distances, shape (N,), m.
    """
    ab = b - a
    denom = float(ab @ ab)
    u = np.zeros(len(points)) if denom == 0.0 else np.clip((points - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(points - (a + u[:, None] * ab), axis=1)


def trajectory_summary(t: np.ndarray, q: np.ndarray, dq: np.ndarray | None, robot: Chain,
                       start: np.ndarray, goal: np.ndarray) -> dict[str, Any]:
    """Numbers describing one timed trajectory.

    Args:
        t: times, shape (N,), s.
        q: joint positions, shape (N, dof), robot joint order; rad or m.
        dq: joint velocities, shape (N, dof), or None.
        robot: the model (``fk``).
        start, goal: requested tool poses, 4x4, base frame.

    Returns:
        points, duration (s), peak |velocity| per joint, tool-path deviation from the straight
        segment start -> goal (m; max over the points), start/goal tool position errors (m).
    """
    tool = robot.fk(q)[:, :3, 3]
    dev = segment_deviation(tool, start[:3, 3], goal[:3, 3])
    peak = np.max(np.abs(dq), axis=0) if dq is not None and len(dq) else np.full(q.shape[1], np.nan)
    return {
        'points': len(t),
        'duration_s': float(t[-1] - t[0]) if len(t) > 1 else 0.0,
        'peak_joint_speed': [float(v) for v in peak],
        'max_tool_path_deviation_m': float(dev.max()),
        'start_position_error_m': float(np.linalg.norm(tool[0] - start[:3, 3])),
        'goal_position_error_m': float(np.linalg.norm(tool[-1] - goal[:3, 3])),
    }


# --------------------------------------------------------------------------- processes

def _start(name: str, executable: str, params: dict[str, Any], log_dir: Path) -> NodeProcess:
    try:
        return popen_node(executable, params=params, name=name, log_dir=log_dir)
    except ToolError as err:
        raise DemoError(str(err)) from None


# --------------------------------------------------------------------------- output

def _reorder(names: Sequence[str], robot_names: Sequence[str], a: np.ndarray | None) -> np.ndarray | None:
    if a is None:
        return None
    missing = [n for n in robot_names if n not in names]
    if missing:
        raise DemoError(f'trajectory lacks joints {missing} (has {list(names)})')
    return a[:, [list(names).index(n) for n in robot_names]]


def _fmt_speeds(v: Sequence[float]) -> str:
    return '[' + ', '.join(f'{x:.3f}' for x in v) + ']'


# --------------------------------------------------------------------------- the pipeline

def _prepare_output(out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    bag = out / 'bag'
    if bag.exists():
        looks_like_bag = bag.is_dir() and ((bag / 'metadata.yaml').exists() or any(
            p.suffix in ('.mcap', '.db3') for p in bag.iterdir()))
        if not looks_like_bag and bag.is_dir() and any(bag.iterdir()):
            raise DemoError(f'{bag} exists and is not a bag from an earlier run: remove it or '
                            'choose another --output')
        shutil.rmtree(bag) if bag.is_dir() else bag.unlink()
    for old in ('summary.json', 'trajectory.png', 'via_blend.png', 'collision.png', 'sequence.png', 'ptp.png'):
        (out / old).unlink(missing_ok=True)
    return bag


def run_demo(output: Path, robot_name: str = 'planar_3r', timeout: float = 60.0,
             say: Callable[[str], None] = print) -> dict[str, Any]:
    """Run the whole pipeline (see the module docstring); return the summary written to JSON.

    Raises:
        DemoError: a node died, a wait timed out, or a result is missing/invalid.
        GeodesicPlannerError: bad robot name, unreadable bag.
    """
    from geodesic_planner.core.robots import load_robot

    robot = load_robot(robot_name)
    start_T, goal_T = demo_poses(robot)
    bag_dir = _prepare_output(output)
    log_dir = output / 'logs'

    from geodesic_planner_interfaces.msg import PlanErrorCode
    from geodesic_planner_interfaces.srv import PlanTrajectory
    from nav_msgs.srv import GetPlan
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from trajectory_msgs.msg import JointTrajectory

    from geodesic_planner.ros.conversions import joint_trajectory_to_arrays, matrix_to_pose_stamped
    from tools.graph import Collector, RclpyRuntime, StatusWatch, wait_for_service, wait_writer_matched

    nodes: list[NodeProcess] = []
    runtime = None
    try:
        say(f'starting planner node (geodesic_planner_node -p robot:={robot_name})...')
        planner = _start('planner', 'geodesic_planner_node', {'robot': robot_name}, log_dir)
        nodes.append(planner)
        say(f'starting trajectory processor node (velocity_scaling {VELOCITY_SCALING}, '
            f'sample_period {SAMPLE_PERIOD} s, bag {bag_dir})...')
        processor = _start('processor', 'trajectory_processor_node',
                           {'velocity_scaling': VELOCITY_SCALING, 'sample_period': SAMPLE_PERIOD,
                            'bag_path': str(bag_dir)}, log_dir)
        nodes.append(processor)

        runtime = RclpyRuntime('geodesic_planner_demo')
        node = runtime.node
        qos = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
        # Subscriptions before any client: wait_writer_matched relies on that order.
        received = {topic: Collector(node, JointTrajectory, topic, qos)
                    for topic in (PLANNED_TOPIC, PROCESSED_TOPIC)}
        status = StatusWatch(node)
        client = node.create_client(GetPlan, PLAN_SERVICE)
        via_client = node.create_client(PlanTrajectory, PLAN_TRAJECTORY_SERVICE)

        t0 = time.monotonic()
        wait_for_service(client, timeout, watch=nodes)
        say(f'planner ready: {PLAN_SERVICE} ({time.monotonic() - t0:.1f} s)')
        # The topics are volatile: the planner's publisher must have matched the processor and
        # us, the processor's publisher us, before the plan is asked for.
        wait_writer_matched(planner, PLANNED_TOPIC, 2, timeout, watch=nodes, runtime=runtime)
        wait_writer_matched(processor, PROCESSED_TOPIC, 1, timeout, watch=nodes, runtime=runtime)
        # Between the two nodes only they know: each reports its side of the match on /diagnostics.
        status.wait('/trajectory_processor', 'input publishers matched', lambda v: int(v) >= 1, timeout,
                    watch=nodes)
        status.wait('/geodesic_planner', 'trajectory subscriptions matched', lambda v: int(v) >= 2, timeout,
                    watch=nodes)
        say(f'processor ready: subscribed to {PLANNED_TOPIC}, publishing {PROCESSED_TOPIC}')

        request = GetPlan.Request()
        request.start = matrix_to_pose_stamped(start_T, '')
        request.goal = matrix_to_pose_stamped(goal_T, '')
        say('calling ' + PLAN_SERVICE + ': start p=' + np.array2string(start_T[:3, 3], precision=3)
            + ', goal p=' + np.array2string(goal_T[:3, 3], precision=3))
        t_call = time.monotonic()
        future = client.call_async(request)
        wait_until(future.done, timeout, what=f'the response of {PLAN_SERVICE}', watch=nodes)
        latency_ms = (time.monotonic() - t_call) * 1e3
        response = future.result()
        if response is None or not response.plan.poses:
            raise DemoError(f'the planner returned an empty plan (see its log: {planner.log_path})')

        planned = received[PLANNED_TOPIC].wait_for(1, timeout, watch=nodes)[0]
        arr = joint_trajectory_to_arrays(planned)
        say(f'plan received: {len(arr.t)} points, {arr.t[-1]:.3f} s '
            f'(service answered in {latency_ms:.0f} ms, tool path {len(response.plan.poses)} poses)')
        processed = received[PROCESSED_TOPIC].wait_for(1, timeout, watch=nodes)[0]
        arr2 = joint_trajectory_to_arrays(processed)
        say(f'processed trajectory received: {len(arr2.t)} points, {arr2.t[-1]:.3f} s')

        say('stopping the processor (SIGINT, the bag is closed)...')
        rc = processor.stop()
        if rc != 0:
            raise DemoError(f'the processor exited with {rc} on SIGINT')

        via_poses = via_sequence(robot)
        radius = via_blend_radius(via_poses)
        wait_for_service(via_client, timeout, watch=[planner])      # the processor has exited
        via_plans: dict[float, Any] = {}
        for r in (0.0, radius):
            req = PlanTrajectory.Request(
                start=matrix_to_pose_stamped(via_poses[0], ''), goal=matrix_to_pose_stamped(via_poses[-1], ''),
                via_poses=[matrix_to_pose_stamped(T, '') for T in via_poses[1:-1]], blend_radius=r)
            say(f'calling {PLAN_TRAJECTORY_SERVICE}: {len(via_poses) - 2} via poses, blend_radius {r:g} m')
            future = via_client.call_async(req)
            wait_until(future.done, timeout, what=f'the response of {PLAN_TRAJECTORY_SERVICE}',
                       watch=[planner])
            reply = future.result()
            if reply is None or reply.error_code.val != PlanErrorCode.SUCCESS:
                reason = 'no reply' if reply is None else f'{reply.error_code.val}: {reply.message}'
                raise DemoError(f'the via plan with blend_radius {r:g} m failed ({reason})')
            via_plans[r] = reply

        def answer(future: Any, what: str) -> Any:  # noqa: ANN401
            wait_until(future.done, timeout, what=f'the response of {what}', watch=[planner])
            return future.result()
        step = run_collision_step(node, via_client, robot, start_T, goal_T, timeout, answer, say)
        say('stopping the planner (SIGINT)...')
        rc = planner.stop()
        if rc != 0:
            raise DemoError(f'the planner exited with {rc} on SIGINT')
    except BaseException as exc:
        for proc in nodes:
            if proc.alive():
                proc.stop(timeout=5.0)
        # The first line only: a ToolError also quotes the log tails, printed below.
        first_line = (str(exc).splitlines() or [''])[0]
        reason = ('interrupted' if isinstance(exc, KeyboardInterrupt)
                  else f'{type(exc).__name__}: {first_line}')
        say(f'demo failed ({reason}); node logs:')
        for proc in nodes:
            tail = proc.log_tail(30)
            say(f'--- {proc.describe()} ---')
            say(tail if tail else '(empty log)')
        if isinstance(exc, ToolError):
            raise DemoError(first_line) from None
        raise
    finally:
        if runtime is not None:
            runtime.shutdown()

    via = _via_blend(output, robot, via_poses, radius,
                     {r: joint_trajectory_to_arrays(reply.trajectory) for r, reply in via_plans.items()},
                     list(via_plans[radius].blend_deviation))
    collision = collision_summary(output, robot, start_T, goal_T, step, DEFAULT_PADDING)
    say('motion types (library): LIN, CIRC, a blended LIN -> CIRC -> LIN sequence, PTP')
    motions = motions_demo(output, say)
    return _summarise(bag_dir, output, robot, start_T, goal_T, latency_ms, {'via_blend': via,
                      'collision': collision, 'motions': motions}, say)


def _via_blend(output: Path, robot: Any, poses: list[np.ndarray], radius: float,  # noqa: ANN401
               arrays: dict[float, Any], deviation: list[float]) -> dict[str, Any]:
    """The via example's part of summary.json, and ``DIR/via_blend.png``."""
    from geodesic_planner.io.plotting import plot_via_blend

    runs, parts = [], {}
    for key, r, label in (('stopping', 0.0, 'blend_radius 0 (stops at each via pose)'),
                          ('blended', radius, f'blend_radius {radius:g} m (no stop)')):
        arr = arrays[r]
        q = _reorder(arr.joint_names, robot.joint_names, arr.positions)
        dq = _reorder(arr.joint_names, robot.joint_names, arr.velocities)
        if q is None or dq is None:
            raise DemoError(f'the via plan ({key}) has no velocities')
        parts[key] = via_blend_summary(arr.t, q, dq, robot, poses)
        runs.append((label, arr.t, robot.fk(q)[:, :3, 3], tool_speed(robot, q, dq)))
    plot_via_blend(output / 'via_blend.png', runs, np.array([T[:3, 3] for T in poses]), radius,
                   title=f'{robot.name}: via poses, stopping vs blended (PlanTrajectory blend_radius)')
    parts['blended']['blend_deviation_m'] = deviation
    return {
        'service': PLAN_TRAJECTORY_SERVICE,
        'poses': [T.tolist() for T in poses],
        'poses_position_quaternion': [pose_json(T) for T in poses],
        'blend_radius_m': radius,
        **parts,
        'time_saved_s': parts['stopping']['duration_s'] - parts['blended']['duration_s'],
    }


def _summarise(bag_dir: Path, output: Path, robot: Any, start_T: np.ndarray,  # noqa: ANN401
               goal_T: np.ndarray, latency_ms: float, extra: dict[str, Any],
               say: Callable[[str], None]) -> dict[str, Any]:
    from geodesic_planner.io.bags import read_trajectories
    from geodesic_planner.io.plotting import plot_trajectories

    records = read_trajectories(bag_dir)
    by_topic: dict[str, Any] = {}
    for rec in records:
        by_topic.setdefault(rec.topic, rec)
    missing = [t for t in (PLANNED_TOPIC, PROCESSED_TOPIC) if t not in by_topic]
    if missing:
        raise DemoError(f'bag {bag_dir} holds no trajectory on {", ".join(missing)} '
                        f'(topics: {", ".join(sorted(by_topic)) or "none"})')
    say(f'bag read back: {len(records)} trajectories in {bag_dir}')

    columns, parts = [], {}
    for key, topic, label in (('planned', PLANNED_TOPIC, 'planned'),
                              ('processed', PROCESSED_TOPIC, f'processed x{VELOCITY_SCALING:g}')):
        rec = by_topic[topic]
        if rec.problems:
            raise DemoError(f'invalid trajectory on {topic} in the bag: {"; ".join(rec.problems)}')
        q = _reorder(rec.joint_names, robot.joint_names, rec.positions)
        dq = _reorder(rec.joint_names, robot.joint_names, rec.velocities)
        parts[key] = {'topic': topic, **trajectory_summary(rec.t, q, dq, robot, start_T, goal_T)}
        columns.append((label, rec))

    summary = {
        'robot': robot.name,
        'joint_names': list(robot.joint_names),
        'start_pose': start_T.tolist(),
        'goal_pose': goal_T.tolist(),
        'start': pose_json(start_T),
        'goal': pose_json(goal_T),
        'velocity_scaling': VELOCITY_SCALING,
        'sample_period_s': SAMPLE_PERIOD,
        'service_latency_ms': latency_ms,
        'bag': str(bag_dir),
        **parts,
        **extra,
    }
    (output / 'summary.json').write_text(json.dumps(summary, indent=1) + '\n')
    plot_trajectories(output / 'trajectory.png', columns, robot=robot,
                      title=f'{robot.name}: geodesic trajectory, planned and processed (from the bag), '
                            'with the joint limits and the tool path')

    p, r = parts['planned'], parts['processed']
    say('')
    say(f'summary ({robot.name}, joints {", ".join(robot.joint_names)}):')
    for name, part in (('planned  ', p), ('processed', r)):
        say(f'  {name}: {part["points"]:5d} points, {part["duration_s"]:7.3f} s, peak joint speeds '
            f'{_fmt_speeds(part["peak_joint_speed"])}, tool-path deviation from the line '
            f'{part["max_tool_path_deviation_m"]:.2e} m')
    say(f'  duration ratio processed/planned: {r["duration_s"] / p["duration_s"]:.4f} '
        f'(1/velocity_scaling = {1 / VELOCITY_SCALING:g})')
    say(f'  goal reached within {max(p["goal_position_error_m"], r["goal_position_error_m"]):.2e} m')
    via = extra['via_blend']
    stop, blend = via['stopping'], via['blended']
    say(f'  via poses ({len(via["poses"]) - 2}, PlanTrajectory): stopping {stop["duration_s"]:.3f} s, '
        f'blended (blend_radius {via["blend_radius_m"]:g} m) {blend["duration_s"]:.3f} s, time saved '
        f'{via["time_saved_s"]:.3f} s; corner cut per via pose '
        + ', '.join(f'{d:.3g}' for d in blend['blend_deviation_m']) + ' m')
    say_summary(extra['collision'], say)
    say(f'wrote {output / "summary.json"}, {output / "trajectory.png"}, {output / "via_blend.png"}, '
        f'{output / "collision.png"}, bag {bag_dir}')
    return summary


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m tools.demo``: returns the exit code (0 ok, 1 error)."""
    parser = argparse.ArgumentParser(
        prog='python -m tools.demo',
        description='Plan the paper\'s example through the planner and processor nodes, record a '
                    'bag, print a summary and write summary.json and trajectory.png.')
    parser.add_argument('--output', default='out/demo', help='output directory (default out/demo)')
    parser.add_argument('--robot', default='planar_3r',
                        help='robot preset: planar_3r (default: the paper\'s poses), rrpp, ur5e or panda '
                             '(from home to home + 0.3 rad or m on every joint; the collision step\'s box '
                             'is placed and sized from the robot\'s geometry)')
    parser.add_argument('--timeout', type=float, default=60.0,
                        help='deadline of each wait, s (default 60)')
    args = parser.parse_args(argv)
    problem = netns.isolation_problem()
    if problem is not None:
        print(f'ERROR: {problem}', file=sys.stderr)
        return 1
    try:
        run_demo(Path(args.output), args.robot, args.timeout,
                 say=lambda line: print(line, flush=True))
    except GeodesicPlannerError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print('ERROR: interrupted', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
