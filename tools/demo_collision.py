"""The demo's collision step: a box across the tool's line is refused, then moved aside and planned.

Steps (inside :func:`tools.demo.run_demo`, while the planner node runs):

1. ``~/set_collision_object`` puts a box across the line (:func:`demo_boxes`);
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
from pathlib import Path
from typing import Any

import numpy as np

from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import GeodesicPlannerError
from geodesic_planner.core.kinematics import Chain

__all__ = ['BOX_ID', 'CollisionDemoError', 'collision_summary', 'demo_boxes', 'fraction_along',
           'run_collision_step', 'say_summary']

BOX_ID = 'box'
SET_OBJECT_SERVICE = '/geodesic_planner/set_collision_object'


class CollisionDemoError(GeodesicPlannerError):
    """The collision step did not go as the demo expects (no refusal, or no plan once moved)."""


def demo_boxes(robot: Chain, start: np.ndarray, goal: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """The box's edge (m) and its two centres (3,), base frame, m: across the line, then aside.

    planar_3r: a 0.3 m cube at the midpoint (2, 2, 0) of the paper's line (as
    ``msg_examples/scene_box.yaml``), then at (2.3, 2.3, 0): beside the line, 0.21 m from it.
    Other robots: a 0.1 m cube at the midpoint of the tool's line, then 2 m above it.
    """
    mid = 0.5 * (start[:3, 3] + goal[:3, 3])
    if robot.name == 'planar_3r':
        return 0.3, mid, np.array([2.3, 2.3, 0.0])
    return 0.1, mid, mid + np.array([0.0, 0.0, 2.0])


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

    edge, across, aside = demo_boxes(robot, start, goal)
    set_client = node.create_client(SetCollisionObject, SET_OBJECT_SERVICE)
    wait_for_service(set_client, timeout)
    replies = []
    for centre, where in ((across, 'across the line'), (aside, 'aside')):
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
        raise CollisionDemoError(f'the box across the line was not refused as a collision: error code '
                                 f'{refused.error_code.val} ({refused.message})')
    if planned.error_code.val != PlanErrorCode.SUCCESS:
        raise CollisionDemoError(f'the box aside still stops the plan: {planned.message}')
    return {
        'edge_m': edge, 'across': across, 'aside': aside,
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
    from geodesic_planner.io.collision_plot import plot_collision

    arr = step['trajectory']
    index = [list(arr.joint_names).index(n) for n in robot.joint_names]
    q = arr.positions[:, index]
    tool = robot.fk(q)[:, :3, 3]
    s = fraction_along(tool, start[:3, 3], goal[:3, 3])
    model = CollisionModel.for_robot(robot, padding=padding)
    clearance = {}
    for key in ('across', 'aside'):
        d, _ = model.with_objects([_box(step[key], step['edge_m'])]).distances(q)
        clearance[key] = d
    below = np.flatnonzero(clearance['across'] <= padding)
    first_contact = float(s[below[0]]) if below.size else math.nan
    refused = step['refused']
    traces = [('across the line', step['across'], step['edge_m'], clearance['across'], refused['fraction']),
              ('moved aside', step['aside'], step['edge_m'], clearance['aside'], math.nan)]
    plot_collision(output / 'collision.png', _arm_points(robot, q), tool, s, traces, padding,
                   title=f'{robot.name}: a box across the line is refused; moved aside, the line is planned')
    return {
        'box_edge_m': step['edge_m'],
        'box_across_m': step['across'].tolist(),
        'box_aside_m': step['aside'].tolist(),
        'refused': refused,
        'planned': step['planned'],
        'padding_m': padding,
        'first_sample_within_padding_fraction': first_contact,
        'min_clearance_across_samples_m': float(clearance['across'].min()),
        'min_clearance_aside_samples_m': float(clearance['aside'].min()),
    }


def _arm_points(robot: Chain, q: np.ndarray) -> np.ndarray:
    """(N, dof + 2, 3): the base, each joint's origin and the tool, m, base frame."""
    S = robot.segment_frames(q)[:, :, :3, 3]
    return np.concatenate([S, robot.fk(q)[:, None, :3, 3]], axis=1)


def say_summary(part: dict[str, Any], say: Callable[[str], None]) -> None:
    """One line per outcome of the collision step."""
    ref, ok = part['refused'], part['planned']
    say(f'  collision: box across the line refused at {100 * ref["fraction"]:.1f} % of the way '
        f'(first sample within the padding: {100 * part["first_sample_within_padding_fraction"]:.1f} %); '
        f'moved aside, planned with min_clearance {ok["min_clearance_m"]:.4f} m '
        f'(samples {part["min_clearance_aside_samples_m"]:.4f} m)')
