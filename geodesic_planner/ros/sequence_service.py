"""The planner node's ``~/plan_sequence`` (geodesic_planner_interfaces/srv/PlanSequence): a sequence
of LIN, CIRC and PTP motions with blends (:mod:`geodesic_planner.core.motions`) as one trajectory.

Why a service of its own rather than more fields in PlanTrajectory: a sequence item carries its
own motion type, goal, CIRC point, PTP metric and blend radius, as MoveIt keeps
MotionSequenceRequest apart from MotionPlanRequest; PlanTrajectory's contract stays as it is for
its clients. The request goes through the node's one pipeline (queue, worker, timing, collision
check, trajectory message, publication when ``execute``).
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from geodesic_planner_interfaces.msg import MotionSequenceItem, PlanErrorCode
from geodesic_planner_interfaces.srv import PlanSequence

from ..core.errors import RequestError
from ..core.motions import MOTION_TYPES, MotionItem
from ..core.ptp import MassModel, mass_from_urdf
from ..core.robots import urdf_text
from ..core.request import MAX_ITEMS, PlanRequest
from . import conversions as cv
from .service_requests import request_factor

__all__ = ['MAX_ITEMS', 'SequenceService', 'sequence_request']
#: circ_constraint values.
CIRC_CONSTRAINTS = ('interim', 'center')


def _item(config: Any, msg: MotionSequenceItem, i: int) -> MotionItem:  # noqa: ANN401
    what = f'items[{i}]'
    motion = msg.motion.strip().upper()
    if motion not in MOTION_TYPES:
        raise RequestError(f'{what}.motion must be one of {", ".join(MOTION_TYPES)}, got {msg.motion!r}')
    goal = goal_joints = None
    if len(msg.goal_joints.name) or len(msg.goal_joints.position):
        if not cv.is_empty_pose(msg.goal, f'{what}.goal'):
            raise RequestError(f'{what}: give goal or goal_joints, not both')
        goal_joints = cv.joint_state_to_vector(msg.goal_joints, config.joint_names, f'{what}.goal_joints')
    elif not cv.is_empty_pose(msg.goal, f'{what}.goal'):
        goal = cv.pose_stamped_to_matrix(msg.goal, config.frame_id, f'{what}.goal')
    point = interim = centre = None
    if motion == 'CIRC':
        if msg.circ_constraint not in CIRC_CONSTRAINTS:
            raise RequestError(f'{what}.circ_constraint must be "interim" or "center", got {msg.circ_constraint!r}')
        point = np.array([msg.circ_point.x, msg.circ_point.y, msg.circ_point.z], dtype=float)
        if not np.all(np.isfinite(point)):
            raise RequestError(f'{what}.circ_point must be finite')
        interim, centre = (point, None) if msg.circ_constraint == 'interim' else (None, point)
    return MotionItem(motion, goal, goal_joints, interim, centre, msg.ptp or 'kinetic_energy',
                      float(msg.blend_radius))


def sequence_request(config: Any, msg: PlanSequence.Request, mass: MassModel | None  # noqa: ANN401
                     ) -> tuple[PlanRequest, float | None, float | None]:
    """The library request (with its items) and the scaling factors (None: default).

    Raises:
        RequestError: no items or too many, a malformed item (named by its index), both a start
            pose and start joints, a factor outside [0, 1]; FrameError: not the base frame.
    """
    if not msg.items:
        raise RequestError('items: the sequence has no items')
    if len(msg.items) > MAX_ITEMS:
        raise RequestError(f'items: {len(msg.items)} items, more than {MAX_ITEMS}')
    start = start_joints = None
    if len(msg.start_joints.name) or len(msg.start_joints.position):
        if not cv.is_empty_pose(msg.start, 'start'):
            raise RequestError('start: give start or start_joints, not both')
        start_joints = cv.joint_state_to_vector(msg.start_joints, config.joint_names, 'start_joints')
    elif not cv.is_empty_pose(msg.start, 'start'):
        start = cv.pose_stamped_to_matrix(msg.start, config.frame_id, 'start')
    items = [_item(config, it, i) for i, it in enumerate(msg.items)]
    request = PlanRequest(config.robot, start, None, start_joints, None, items=items, mass=mass,
                          around=config.around())
    return (request, request_factor(msg.velocity_scaling_factor, 'velocity_scaling_factor'),
            request_factor(msg.acceleration_scaling_factor, 'acceleration_scaling_factor'))


class SequenceService:
    """``~/plan_sequence`` on ``node``, answered through ``serve`` (the node's ``_serve``)."""

    def __init__(self, node: Any, serve: Callable[..., Any], qos: Any, group: Any) -> None:  # noqa: ANN401
        self._node, self._serve = node, serve
        self._mass: tuple[tuple, MassModel | None] = ((), None)
        self.srv = node.create_service(PlanSequence, '~/plan_sequence', self._on_request,
                                       qos_profile=qos, callback_group=group)

    def _mass_for(self, config: Any) -> MassModel | None:  # noqa: ANN401
        """The URDF's mass model for the configuration's robot (remembered per robot key)."""
        key = config.robot_key
        if self._mass[0] != key:
            self._mass = (key, mass_from_urdf(config.robot, urdf_text(key[0], key[1]))[0])
        return self._mass[1]

    def _on_request(self, request: PlanSequence.Request, response: PlanSequence.Response) -> PlanSequence.Response:
        t0 = time.perf_counter()
        stamp = self._node.get_clock().now().to_msg()
        outcome = self._serve(lambda c: sequence_request(c, request, self._mass_for(c)), bool(request.execute),
                              stamp, t0)
        response.error_code = PlanErrorCode(val=outcome.code)
        response.message = outcome.message
        response.failed_item = int(outcome.item)
        response.planning_time = time.perf_counter() - t0
        response.min_clearance = math.nan
        result = outcome.result
        if result is not None:
            response.message = '; '.join(result.notes)
            response.trajectory = result.trajectory
            response.tool_path = result.path
            response.blend_deviation = list(result.blend_deviation)
            response.min_clearance = result.min_clearance
        return response
