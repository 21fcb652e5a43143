"""The demo's collision step: a box across the tool's line is refused, then moved aside and planned.

Steps (inside :func:`tools.demo.run_demo`, while the planner node runs):

1. ``~/set_collision_object`` puts a box across the motion (:func:`demo_boxes`: placed and sized
   from the robot's geometry, checked with the library's collision model before it is sent);
2. ``~/plan_trajectory`` from the demo's start pose to its goal pose: refused with
   INVALID_MOTION_PLAN, the message naming the box and the link that would hit it, ``fraction``
   the place on the way;
3. the same service moves the box aside (same id), and the same request succeeds, with
   ``min_clearance`` in the reply;
4. after the nodes stop, :func:`collision_summary` recomputes the clearance along the planned
   motion against both box places with the library's collision model, and writes
   ``DIR/collision.png`` (the arm along the way, the two boxes, the clearance against the fraction
   of the way).

Demo tooling, not part of the installed library.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from geodesic_planner.core.collision import DEFAULT_PADDING, CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import GeodesicPlannerError
from geodesic_planner.core.kinematics import Chain

__all__ = ['BOX_ID', 'CollisionDemoError', 'DemoBoxes', 'collision_summary', 'demo_boxes', 'fraction_along',
           'nearest_body', 'run_collision_step', 'say_summary']

BOX_ID = 'box'
SET_OBJECT_SERVICE = '/geodesic_planner/set_collision_object'


class CollisionDemoError(GeodesicPlannerError):
    """The collision step did not go as the demo expects (no refusal, or no plan once moved)."""
#: Largest edge of the demo's box, m (planar_3r: the 0.3 m cube of msg_examples/scene_box.yaml).
MAX_EDGE = 0.3
#: Smallest edge accepted at the middle of the tool's line before other places are tried, m.
MIN_EDGE = 0.05
#: Clearance the box keeps from the start and goal configurations beyond the padding, m.
END_MARGIN = 0.01
#: Clearance the box moved aside keeps from the arm along the whole motion beyond the padding, m.
ASIDE_MARGIN = 0.05
#: Places tried along the tool's line (s) and along the tool link, from the tool (0) to the last
#: joint (1).
LINE_FRACTIONS = (0.5, 0.4, 0.6, 0.3, 0.7, 0.2, 0.8)
LINK_FRACTIONS = (0.0, 0.25, 0.5, 0.75, 1.0)


@dataclass(frozen=True)
class DemoBoxes:
    """Where the demo puts its box (base frame, m), checked with the library's collision model.

    Attributes:
        edge: the cube's edge.
        across: its centre across the motion: a point the tool link passes through on the way
            (on every IK branch: the tool link follows the tool's pose), clear of the start and goal.
        aside: its centre moved aside, clear of the whole planned motion.
        place: where ``across`` is, in words.
        fraction: where the tool link passes ``across``, as the path parameter s.
    """

    edge: float
    across: np.ndarray
    aside: np.ndarray
    place: str
    fraction: float


def demo_boxes(robot: Chain, start: np.ndarray, goal: np.ndarray, padding: float = DEFAULT_PADDING
               ) -> DemoBoxes:
    """The box of the collision step, from the robot's own geometry.

    The demo's line is planned with the library (:class:`GeodesicPlanner`, the node's default
    branch). Across: the middle of the tool's line when a cube of at least :data:`MIN_EDGE` fits
    there, clear of the start and goal configurations by ``padding`` + :data:`END_MARGIN`; else the
    point of the tool link's sweep (the segment from the last joint to the tool, at the line's
    poses: every IK branch passes it) farthest from both. The edge is the largest that stays clear,
    at most :data:`MAX_EDGE`, to the cm below. Aside: moved from there away from the base,
    perpendicular to the line, by a growing multiple of the edge until the whole motion clears it by
    ``padding`` + :data:`ASIDE_MARGIN`. Both are then checked as the node checks a plan
    (:func:`~geodesic_planner.core.branches.check_trajectory`): across refused on the way (not at
    the start or goal), aside free.

    planar_3r: the 0.3 m cube at (2, 2, 0), then at (2.3, 2.3, 0) (``msg_examples/scene_box.yaml``).

    Raises:
        CollisionDemoError: no place or size passes these checks.
        GeodesicPlannerError: the line cannot be planned.
    """
    from geodesic_planner import GeodesicPlanner
    from geodesic_planner.core.branches import check_trajectory
    from geodesic_planner.core.errors import PathInCollisionError
    from geodesic_planner.core.transforms import line_slerp

    path = GeodesicPlanner(robot).plan(start, goal)
    trajectory = path.timed()
    model = CollisionModel.for_robot(robot, padding=padding)
    ends = path.evaluate(np.array([0.0, 1.0]), 0)[0]
    back = np.linalg.inv(robot.tool_offset())[:3, 3]        # the last joint, tool frame
    candidates = [(0.5, 0.0)] + [(s, lam) for s in LINE_FRACTIONS for lam in LINK_FRACTIONS
                                 if (s, lam) != (0.5, 0.0)]
    T = line_slerp(start, goal, np.array([s for s, _ in candidates]))
    points = np.einsum('nij,nj->ni', T[:, :3, :3], np.outer([lam for _, lam in candidates], back)) + T[:, :3, 3]
    dot = Shape('sphere', dimensions=(1e-4,))     # a point, as coal sees it
    clear = np.array([min(nearest_body(model, q, dot, _at(p))[0] for q in ends) for p in points]) + 1e-4
    edges = np.floor(100.0 * np.minimum(MAX_EDGE, 2.0 * (clear - padding - END_MARGIN) / math.sqrt(3))) / 100.0
    k = 0 if edges[0] >= MIN_EDGE else int(np.argmax(edges))
    edge = float(edges[k])
    if edge <= 0.0:
        raise CollisionDemoError(f'{robot.name}: no cube fits on the tool link\'s way clear of the start '
                                 f'and goal configurations (at most {float(clear.max()):.3f} m from them)')
    s_k, lam_k = candidates[k]
    across = points[k]
    place = ('the middle of the tool\'s line' if k == 0 else
             f'the tool link at s = {s_k:g}, {lam_k * float(np.linalg.norm(back)):.3f} m behind the tool')
    try:
        check_trajectory(model.with_objects([_box(across, edge)]), trajectory)
    except PathInCollisionError:
        pass
    except GeodesicPlannerError as err:
        raise CollisionDemoError(f'{robot.name}: the box ({edge:g} m) at {place} is not refused on the way: '
                                 f'{err}') from None
    else:
        raise CollisionDemoError(f'{robot.name}: the box ({edge:g} m) at {place} does not stop the line')
    aside = _aside(robot, model, path, trajectory, start, goal, across, edge)
    return DemoBoxes(edge, across, aside, place, s_k)


def _solid(shape: Shape, pose: np.ndarray) -> tuple[Any, Any]:
    """coal's geometry and transform of a shape at a pose (4x4, base frame)."""
    import coal

    from geodesic_planner.core.collision_bodies import geometry_of
    return geometry_of(shape)[0], coal.Transform3s(pose[:3, :3], pose[:3, 3])


def nearest_body(model: CollisionModel, q: np.ndarray, shape: Shape, pose: np.ndarray
                 ) -> tuple[float, str, np.ndarray, np.ndarray]:
    """The robot's body nearest a solid (``shape`` at ``pose``, base frame) at the configuration q:
    (distance m, negative in penetration; the body's name; its nearest point; the solid's, (3,) m).

    Over the bodies of ``model`` that have a shape (:meth:`CollisionModel.shapes`: the presets'
    capsules), by coal, as the model's check computes them.
    """
    import coal

    geometry, tf = _solid(shape, pose)
    poses, best = model.body_poses(q), (math.inf, '', np.full(3, np.nan), np.full(3, np.nan))
    for name, body_shape in model.shapes().items():
        if name not in poses or name == BOX_ID:
            continue
        result = coal.DistanceResult()
        d = coal.distance(*_solid(body_shape, poses[name]), geometry, tf, coal.DistanceRequest(), result)
        if d < best[0]:
            best = (float(d), name, np.array(result.getNearestPoint1()), np.array(result.getNearestPoint2()))
    return best


def _at(centre: np.ndarray) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = centre
    return pose


def _aside(robot: Chain, model: CollisionModel, path: Any, trajectory: Any,  # noqa: ANN401
           start: np.ndarray, goal: np.ndarray, across: np.ndarray, edge: float) -> np.ndarray:
    """The box moved from ``across`` away from the base, perpendicular to the line, by sqrt(2),
    2 sqrt(2), ... edges until the sampled motion clears it by the padding + :data:`ASIDE_MARGIN`
    and the node's check finds it free."""
    from geodesic_planner.core.branches import check_trajectory

    u = goal[:3, 3] - start[:3, 3]
    u = u / max(float(np.linalg.norm(u)), 1e-12)
    away = across - (across @ u) * u
    if np.linalg.norm(away) < 1e-6:
        away = np.cross(u, [0.0, 0.0, 1.0]) if abs(u[2]) < 0.9 else np.cross(u, [1.0, 0.0, 0.0])
    away = away / np.linalg.norm(away)
    qs = path.evaluate(np.linspace(0.0, 1.0, 101), 0)[0]
    cube = Shape('box', dimensions=(edge, edge, edge))
    for k in range(1, 11):
        centre = across + k * math.sqrt(2.0) * edge * away
        if min(nearest_body(model, q, cube, _at(centre))[0] for q in qs) < model.padding + ASIDE_MARGIN:
            continue
        try:
            check_trajectory(model.with_objects([_box(centre, edge)]), trajectory)
        except GeodesicPlannerError:
            continue
        return centre
    raise CollisionDemoError(f'{robot.name}: no place aside found for the box ({edge:g} m) within '
                             f'{10 * math.sqrt(2.0) * edge:.2f} m of {np.array2string(across, precision=3)}')


def fraction_along(points: np.ndarray, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
    """Where each point (N, 3) lies along the segment start -> goal (3,), as a fraction of its length
    (the projection, not clipped)."""
    ab = goal - start
    return (points - start) @ ab / float(ab @ ab)


def _box(centre: np.ndarray, edge: float) -> SceneObject:
    pose = np.eye(4)
    pose[:3, 3] = centre
    return SceneObject(BOX_ID, Shape('box', dimensions=(edge, edge, edge)), pose)


def _collision_object(centre: np.ndarray, edge: float) -> Any:  # noqa: ANN401
    from geodesic_planner_interfaces.msg import CollisionObject
    from shape_msgs.msg import SolidPrimitive

    msg = CollisionObject(id=BOX_ID)
    msg.primitive = SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[edge] * 3)
    msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = (float(c) for c in centre)
    msg.pose.orientation.w = 1.0
    return msg


def run_collision_step(node: Any, plan_client: Any, robot: Chain,  # noqa: ANN401
                       start: np.ndarray, goal: np.ndarray, timeout: float,
                       wait: Callable[[Any, str], Any], say: Callable[[str], None]) -> dict[str, Any]:
    """Steps 1-3 (see the module's doc) through the running planner node.

    Args:
        node: the demo's rclpy node (clients are created on it).
        plan_client: its PlanTrajectory client.
        robot, start, goal: the model and the demo's tool poses (4x4, base frame).
        timeout: s, for each service.
        wait: (future, what) -> result, waiting while the nodes live.
        say: progress lines.
    Returns:
        the box, both replies' numbers and the planned trajectory's arrays.
    Raises:
        CollisionDemoError: the line was not refused with INVALID_MOTION_PLAN, or the moved box
            was not planned.
    """
    from geodesic_planner_interfaces.msg import PlanErrorCode
    from geodesic_planner_interfaces.srv import PlanTrajectory, SetCollisionObject

    from geodesic_planner.ros.conversions import joint_trajectory_to_arrays, matrix_to_pose_stamped
    from tools.graph import wait_for_service

    boxes = demo_boxes(robot, start, goal)
    edge, across, aside = boxes.edge, boxes.across, boxes.aside
    say(f'box ({edge:g} m) placed at {boxes.place}, checked with the library\'s collision model: '
        f'clear of the start and goal, refused on the way; moved aside, free')
    set_client = node.create_client(SetCollisionObject, SET_OBJECT_SERVICE)
    wait_for_service(set_client, timeout)
    replies = []
    for centre, where in ((across, 'across the motion'), (aside, 'aside')):
        put = wait(set_client.call_async(SetCollisionObject.Request(object=_collision_object(centre, edge))),
                   SET_OBJECT_SERVICE)
        if put is None or not put.success:
            raise CollisionDemoError(f'{SET_OBJECT_SERVICE} refused the box: '
                                     f'{"no reply" if put is None else put.message}')
        say(f'box ({edge:g} m) {where} at {np.array2string(centre, precision=2)}; '
            f'calling {plan_client.srv_name} with the demo\'s start and goal')
        req = PlanTrajectory.Request(start=matrix_to_pose_stamped(start, ''),
                                     goal=matrix_to_pose_stamped(goal, ''))
        reply = wait(plan_client.call_async(req), plan_client.srv_name)
        if reply is None:
            raise CollisionDemoError(f'no reply from {plan_client.srv_name}')
        replies.append(reply)
        code = reply.error_code.val
        say(f'  -> error code {code}: {reply.message or "SUCCESS"}'
            + (f' (min_clearance {reply.min_clearance:.4f} m, IK branch {reply.ik_branch})'
               if code == PlanErrorCode.SUCCESS else ''))
    refused, planned = replies
    if refused.error_code.val != PlanErrorCode.INVALID_MOTION_PLAN:
        raise CollisionDemoError(f'the box across the motion was not refused as a collision: error code '
                                 f'{refused.error_code.val} ({refused.message})')
    if planned.error_code.val != PlanErrorCode.SUCCESS:
        raise CollisionDemoError(f'the box aside still stops the plan: {planned.message}')
    return {
        'edge_m': edge, 'across': across, 'aside': aside, 'place': boxes.place,
        'refused': {'error_code': int(refused.error_code.val), 'message': refused.message,
                    'fraction': float(refused.fraction)},
        'planned': {'error_code': int(planned.error_code.val), 'min_clearance_m': float(planned.min_clearance),
                    'ik_branch': planned.ik_branch},
        'trajectory': joint_trajectory_to_arrays(planned.trajectory),
    }


def collision_summary(output: Path, robot: Chain, start: np.ndarray, goal: np.ndarray,
                      step: dict[str, Any], padding: float) -> dict[str, Any]:
    """Step 4: the clearance along the planned motion against both boxes, ``DIR/collision.png``, and
    the part of summary.json (box places, the refusal, the clearances)."""
    from geodesic_planner.io.collision_plot import ArmView, Closest, plot_collision

    arr = step['trajectory']
    index = [list(arr.joint_names).index(n) for n in robot.joint_names]
    q = arr.positions[:, index]
    tool = robot.fk(q)[:, :3, 3]
    s = fraction_along(tool, start[:3, 3], goal[:3, 3])
    model = CollisionModel.for_robot(robot, padding=padding)
    clearance, pairs = {}, {}
    for key in ('across', 'aside'):
        clearance[key], pairs[key] = model.with_objects([_box(step[key], step['edge_m'])]).distances(q)
    below = np.flatnonzero(clearance['across'] <= padding)
    first_contact = float(s[below[0]]) if below.size else math.nan
    refused = step['refused']
    n_min = int(np.argmin(clearance['aside']))
    pair = pairs['aside'][n_min]
    a, b = _nearest_points(model, q[n_min], step['aside'], step['edge_m'], pair)
    reported = float(step['planned']['min_clearance_m'])      # the node's, where the samples come closest
    closest = Closest(reported if math.isfinite(reported) else float(clearance['aside'][n_min]), pair, a, b,
                      float(s[n_min]))
    views = [ArmView('start', _solids(model, q[0]), 'C2'), ArmView('goal', _solids(model, q[-1]), 'C0')]
    if math.isfinite(refused['fraction']):
        n_ref = int(np.argmin(np.abs(s - refused['fraction'])))
        views.append(ArmView(f'at the refusal ({100 * refused["fraction"]:.1f} %)', _solids(model, q[n_ref]), 'C3'))
    cube = Shape('box', dimensions=(step['edge_m'],) * 3)
    to_box = {key: np.array([nearest_body(model, qn, cube, _at(step[key]))[0] for qn in q])
              for key in ('across', 'aside')}
    traces = [('across the motion', step['across'], step['edge_m'], to_box['across'], refused['fraction']),
              ('moved aside', step['aside'], step['edge_m'], to_box['aside'], math.nan)]
    plot_collision(output / 'collision.png', _arm_points(robot, q), tool, s, traces, padding, views=views,
                   closest=closest,
                   title=f'{robot.name}: a box across the motion is refused; moved aside, the line is planned '
                         f'(node\'s min_clearance {step["planned"]["min_clearance_m"]:.4f} m)')
    return {
        'box_edge_m': step['edge_m'],
        'box_across_m': step['across'].tolist(),
        'box_aside_m': step['aside'].tolist(),
        'box_place': step.get('place', ''),
        'refused': refused,
        'planned': step['planned'],
        'padding_m': padding,
        'first_sample_within_padding_fraction': first_contact,
        'min_clearance_across_samples_m': float(clearance['across'].min()),
        'min_clearance_aside_samples_m': float(clearance['aside'][n_min]),
        'closest_pair_aside_samples': list(pair),
        'closest_fraction_aside_samples': closest.fraction,
    }


def _solids(model: CollisionModel, q: np.ndarray) -> list[tuple[Shape, np.ndarray]]:
    """The robot's checked solids (shape, pose 4x4 base frame) at one configuration."""
    poses, shapes = model.body_poses(q), model.shapes()
    return [(shapes[name], poses[name]) for name in model.body_names if name in shapes and name in poses]


def _nearest_points(model: CollisionModel, q: np.ndarray, centre: np.ndarray, edge: float,
                    pair: tuple[str, str]) -> tuple[np.ndarray, np.ndarray]:
    """The nearest points (3,) of the pair's two bodies (the box or robot links) at q, by coal."""
    import coal

    poses, shapes = model.body_poses(q), model.shapes()
    solids = {name: (shapes[name], poses[name]) for name in model.body_names if name in shapes and name in poses}
    solids[BOX_ID] = (Shape('box', dimensions=(edge, edge, edge)), _at(centre))
    if not all(name in solids for name in pair):
        return np.full(3, np.nan), np.full(3, np.nan)
    result = coal.DistanceResult()
    coal.distance(*_solid(*solids[pair[0]]), *_solid(*solids[pair[1]]), coal.DistanceRequest(), result)
    return np.array(result.getNearestPoint1()), np.array(result.getNearestPoint2())


def _arm_points(robot: Chain, q: np.ndarray) -> np.ndarray:
    """(N, dof + 2, 3): the base, each joint's origin and the tool, m, base frame."""
    S = robot.segment_frames(q)[:, :, :3, 3]
    return np.concatenate([S, robot.fk(q)[:, None, :3, 3]], axis=1)


def say_summary(part: dict[str, Any], say: Callable[[str], None]) -> None:
    """One line per outcome of the collision step."""
    ref, ok = part['refused'], part['planned']
    say(f'  collision: box across the motion refused at {100 * ref["fraction"]:.1f} % of the way '
        f'(first sample within the padding: {100 * part["first_sample_within_padding_fraction"]:.1f} %); '
        f'moved aside, planned with min_clearance {ok["min_clearance_m"]:.4f} m '
        f'(samples {part["min_clearance_aside_samples_m"]:.4f} m)')
