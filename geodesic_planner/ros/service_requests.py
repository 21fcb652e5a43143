"""Service requests -> the library's :class:`~geodesic_planner.core.request.PlanRequest`: GetPlan
and PlanTrajectory (PlanSequence: :mod:`.sequence_service`), checked field by field.

Invalid fields raise :class:`~geodesic_planner.core.errors.RequestError` (FrameError for a pose in
another frame) naming the field.
"""
from __future__ import annotations

import math

import numpy as np
from geodesic_planner_interfaces.srv import PlanTrajectory
from geometry_msgs.msg import PoseStamped
from nav_msgs.srv import GetPlan
from sensor_msgs.msg import JointState

from ..core.errors import RequestError
from ..core.request import MAX_VIA_POSES, PlanRequest
from . import conversions as cv
from .planning import PlannerConfig

__all__ = ['MAX_VIA_POSES', 'get_plan_request', 'plan_trajectory_request', 'request_factor']


def _tolerance(value: float) -> float | None:
    tol = float(value)
    if not math.isfinite(tol) or tol < 0.0:
        raise RequestError(f'tolerance: must be finite and >= 0 m, got {tol!r}')
    return tol if tol > 0.0 else None


def request_factor(value: float, what: str) -> float | None:
    """A request's scaling factor in (0, 1], or None for 0 (the default)."""
    f = float(value)
    if not (math.isfinite(f) and 0.0 <= f <= 1.0):
        raise RequestError(f'{what}: must be in [0, 1] (0: the default), got {f!r}')
    return f if f > 0.0 else None


def _blend_radius(value: float) -> float:
    """A request's blend radius in m (0: rest at every via pose)."""
    r = float(value)
    if not (math.isfinite(r) and r >= 0.0):
        raise RequestError(f'blend_radius: must be finite and >= 0 m (0: stop at every via pose), '
                           f'got {r!r}')
    return r


def get_plan_request(config: PlannerConfig, msg: GetPlan.Request) -> PlanRequest:
    """The library request of a nav_msgs/GetPlan request (start = current state when unset).

    Raises:
        RequestError: NaN/inf, bad quaternion, negative tolerance; FrameError: not the base frame.
    """
    goal = cv.pose_stamped_to_matrix(msg.goal, config.frame_id, 'goal')
    tolerance = _tolerance(msg.tolerance)
    start = None
    if not cv.is_current_state_pose(msg.start, 'start'):
        start = cv.pose_stamped_to_matrix(msg.start, config.frame_id, 'start')
    return PlanRequest(config.robot, start, goal, tolerance=tolerance)


def plan_trajectory_request(config: PlannerConfig, msg: PlanTrajectory.Request
                            ) -> tuple[PlanRequest, float | None, float | None]:
    """The library request and the scaling factors (None: default) of a PlanTrajectory request.

    Raises:
        RequestError: a pose or joint state that is malformed, both a pose and joints for one end,
            no goal, too many via poses, a factor outside [0, 1], a negative, NaN or infinite
            blend_radius; FrameError: not the base frame.
    """
    names = config.joint_names
    blend_radius = _blend_radius(msg.blend_radius)     # checked even without via poses

    def end(pose: PoseStamped, joints: JointState, what: str) -> tuple[np.ndarray | None, np.ndarray | None]:
        given_pose = not cv.is_empty_pose(pose, what)
        if len(joints.name) or len(joints.position):
            if given_pose:
                raise RequestError(f'{what}: give {what} or {what}_joints, not both')
            return None, cv.joint_state_to_vector(joints, names, f'{what}_joints')
        if given_pose:
            return cv.pose_stamped_to_matrix(pose, config.frame_id, what), None
        return None, None

    start, start_joints = end(msg.start, msg.start_joints, 'start')
    goal, goal_joints = end(msg.goal, msg.goal_joints, 'goal')
    if len(msg.via_poses) > MAX_VIA_POSES:
        raise RequestError(f'via_poses: {len(msg.via_poses)} poses, more than {MAX_VIA_POSES}')
    via = [cv.pose_stamped_to_matrix(v, config.frame_id, f'via_poses[{i}]')
           for i, v in enumerate(msg.via_poses)]
    request = PlanRequest(config.robot, start, goal, start_joints, goal_joints, via,
                          blend_radius=blend_radius)
    request.check()
    return (request, request_factor(msg.velocity_scaling_factor, 'velocity_scaling_factor'),
            request_factor(msg.acceleration_scaling_factor, 'acceleration_scaling_factor'))
