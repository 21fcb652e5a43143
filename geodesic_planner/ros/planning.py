"""The planner node's pipeline: parameters -> configuration, request -> trajectory messages.

No executor, threads or ROS I/O here: :func:`build_config` turns parameter values into an
immutable :class:`PlannerConfig` (or a :class:`ConfigError` naming the parameter);
:mod:`.service_requests` turns a service request into the library's
:class:`~geodesic_planner.core.request.PlanRequest`; :func:`compute_plan` turns that into
the JointTrajectory and the tool Path (and the tool poses the node's markers are built from)
through the library (``PlanRequest.plan``, ``path.timed``, ``trajectory.sample``);
:func:`error_code` (``core/codes.py``) names the PlanErrorCode of any error.

Timing: ``path.timed`` under :func:`~geodesic_planner.timing.law.scaled_limits` of the
configuration (``velocity_scaling``) and the request's factors (0 or GetPlan: the
joint_limits.yaml defaults, else 1). The trajectory is sampled every ``sample_period`` s with
positions, velocities and accelerations at every point.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geodesic_planner_interfaces.msg import PlanErrorCode
from nav_msgs.msg import Path
from trajectory_msgs.msg import JointTrajectory

from .. import GeodesicPlanner, load_robot
from ..core.around import AroundOptions
from ..core.blend import BlendedPath
from ..core.cancel import checkpoint
from ..core.codes import error_code
from ..core.errors import (ConfigError, GeodesicPlannerError, LimitError, PlanningFailedError, RequestError,
                           StartStateError, TrajectoryError)
from ..core.branches import first_clear, start_branches
from ..core.collision import MotionClearance
from ..core.kinematics import Chain
from ..core.path import JointPath
from ..core.robots import is_urdf_path
from ..io.collision_setup import collision_for_parameters
from ..io.joint_limits import merge_limits
from ..core.request import PlanRequest
from ..timing.law import scaled_limits
from ..timing.resample import MAX_POINTS, sample_count
from ..timing.validate import trajectory_problems
from . import conversions as cv
from . import params
from .params import PLANNER_PARAMETERS

#: Largest number of points in a published trajectory (bounds memory and time per request).
#: Accepted range of orientation_weight / position_weight (m); measured to plan on every preset.
WEIGHT_RATIO = (1e-3, 1e2)
#: Largest number of via poses in one request.

_ROBOT_KEYS = ('robot', 'robot_description', 'base_link', 'tip_link')


#: PlanErrorCode value -> constant name (for logs and tests).
CODE_NAMES: dict[int, str] = {
    getattr(PlanErrorCode, name): name for name in dir(PlanErrorCode)
    if name.isupper() and isinstance(getattr(PlanErrorCode, name), int)}


@dataclass(frozen=True)
class PlannerConfig:
    """Everything a request needs, built from the parameters and immutable once built.

    Attributes:
        robot: the kinematic model (joint names as published).
        planner: ``GeodesicPlanner`` for ``robot`` and the metric parameters.
        robot_key: the robot parameters the model was built from.
        planner_key: robot key plus metric parameters.
        joint_names: joint names in chain order (published and read from /joint_states).
        frame_id: base frame.
        max_velocity: unscaled limits, shape (dof,), rad/s or m/s.
        max_acceleration: unscaled limits, shape (dof,), rad/s^2 or m/s^2.
        velocity_scaling: time scaling factor in (0, 1].
        sample_period: s.
        plan_timeout: s.
        max_jerk: unscaled jerk limits, shape (dof,), rad/s^3 (m/s^3), or None (no jerk limit).
        max_tool_speed: m/s, or None (no limit).
        max_tool_angular_speed: rad/s, or None (no limit).
        allowed_start_tolerance: rad (m), 0: no start-state check.
        default_velocity_factor, default_acceleration_factor: the request's scaling factors
            when it gives 0 (joint_limits.yaml's defaults, else 1).
        notes: warnings for the log (limits ignored, joints without an acceleration limit).
    """

    robot: Any
    planner: Any
    robot_key: tuple
    planner_key: tuple
    joint_names: tuple[str, ...]
    frame_id: str
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    velocity_scaling: float
    sample_period: float
    plan_timeout: float
    max_tool_speed: float | None = None
    max_tool_angular_speed: float | None = None
    max_jerk: np.ndarray | None = None
    allowed_start_tolerance: float = 0.0
    default_velocity_factor: float = 1.0
    default_acceleration_factor: float = 1.0
    notes: tuple[str, ...] = ()
    #: the collision model and its scene (None: collision_check off), and the parameters it was
    #: built from (reused while they are unchanged, so run-time scene changes are kept)
    collision: Any = None
    collision_key: tuple = ()
    #: a blocked PTP item goes around the obstacles (needs ``collision``), and the search's budget, s
    ptp_around_obstacles: bool = True
    ptp_planning_timeout: float = 1.0

    def around(self) -> AroundOptions | None:
        """How a blocked PTP item plans around obstacles (None: it is refused)."""
        if self.collision is None or not self.ptp_around_obstacles:
            return None
        return AroundOptions(self.collision, self.ptp_planning_timeout)


@dataclass(frozen=True)
class PlanResult:
    """Messages of one successful plan and its figures for the log line."""

    trajectory: JointTrajectory
    path: Path
    #: the tool poses of ``path``, (N, 4, 4), base frame, m (the node's path markers)
    tool_poses: np.ndarray
    points: int
    duration: float
    solver_iterations: int
    solver_ms: float
    #: ms per stage: 'plan' (library), 'timing' (timed + sample), 'collision' (the checks,
    #: other branches' plans included), 'trajectory' (message and
    #: its validation), 'publish' (on_trajectory), 'tool path' (fk, Path, line deviation)
    stage_ms: dict[str, float]
    #: SolverReport.method ('pullback', 'redundant' or 'collocation') and mesh size
    solver_method: str = ''
    mesh_size: int = 0
    #: largest distance of the tool from the straight segment(s), m (outside any blend zone)
    path_error: float = math.nan
    #: smallest distance between checked bodies over the path, m, at most 1 mm below the true
    #: minimum and never above (nan: not checked; inf: no pair checked); the path's, whatever
    #: the time law (``core.collision.MotionClearance``)
    min_clearance: float = math.nan
    #: the start's IK branch: 'default', 'k of n', or '' (start given as joints or the current state)
    ik_branch: str = ''
    #: per via pose when the request asked for blends (blend_radius > 0), or per sequence item but
    #: the last, else empty: the largest distance (m) of the tool from the stopping path inside its
    #: blend zone (0: passed with a stop)
    blend_deviation: tuple[float, ...] = ()
    #: what was planned otherwise than asked (a sequence's PTP without inertias)
    notes: tuple[str, ...] = ()
    #: the two bodies that come closest (('', '') when not checked) and where, as the path
    #: parameter s in [0, 1] (nan when not checked)
    clearance_pair: tuple[str, str] = ('', '')
    clearance_fraction: float = math.nan
    #: the reply's message on success: the min_clearance line (value, guarantee, closest pair and
    #: place; ``MotionClearance.summary``), empty when collisions are not checked
    message: str = ''


@dataclass(frozen=True)
class Outcome:
    """What one service request came to: PlanErrorCode value, reason, and the plan on success."""

    code: int
    message: str
    result: PlanResult | None = None
    published: bool = False
    fraction: float = -1.0
    item: int = -1      # a sequence's failing item

    def __post_init__(self) -> None:
        # a success says what its plan reports (the min_clearance line) unless given a message
        if self.result is not None and not self.message:
            object.__setattr__(self, 'message', self.result.message)

    @classmethod
    def failure(cls, err: GeodesicPlannerError) -> Outcome:
        """The outcome of a library error: its code, its message and, for a line that cannot be
        followed, the followable fraction (``PathFollowError.fraction``)."""
        return cls(error_code(err), str(err), fraction=float(getattr(err, 'fraction', -1.0)),
                   item=int(getattr(err, 'item', -1)))


def load_model(robot: str, robot_description: str, base_link: str, tip_link: str) -> Chain:
    """Robot model from a URDF string (when not empty) or a preset name / URDF path.

    Raises:
        ConfigError: the model cannot be built (message names the source and the cause).
    """
    base = base_link or None
    tip = tip_link or None
    try:
        if robot_description.strip():
            from ..core.urdf import chain_from_urdf
            return chain_from_urdf(robot_description, base, tip)
        if not robot.strip():
            raise ConfigError('robot: empty (give a preset name or a URDF path, or robot_description)')
        return load_robot(robot, base_link=base, tip_link=tip)
    except ConfigError:
        raise
    except (GeodesicPlannerError, OSError, ValueError) as err:
        source = 'robot_description' if robot_description.strip() else f'robot {robot!r}'
        raise ConfigError(f'cannot load {source}: {err}') from err


def _is_urdf_source(robot: str, robot_description: str) -> bool:
    """True when the model comes from a URDF (which has no acceleration limits), not a preset."""
    return bool(robot_description.strip()) or is_urdf_path(robot)


def build_config(values: dict[str, Any], previous: PlannerConfig | None = None) -> PlannerConfig:
    """Validate parameter values and build a :class:`PlannerConfig`.

    The robot model and the planner are reused from ``previous`` when their parameters are
    unchanged. Limits, lowest priority first: the model's (URDF or preset), ``joint_limits``
    (the file), then ``max_velocity``/``max_acceleration`` when not empty.

    Args:
        values: parameter name -> value for every name in
            :data:`~geodesic_planner.ros.params.PLANNER_PARAMETERS`.
        previous: the configuration in use, if any.
    Raises:
        ConfigError: the first invalid value, with the reason.
    """
    for name in PLANNER_PARAMETERS:
        reason = params.problem(name, values[name])
        if reason is not None:
            raise ConfigError(reason)
    robot_key = tuple(str(values[k]) for k in _ROBOT_KEYS)
    names = tuple(values['joint_names'] or ())
    metric = values['metric']
    pw = float(values['position_weight'])
    ow = float(values['orientation_weight'])
    if not WEIGHT_RATIO[0] <= ow / pw <= WEIGHT_RATIO[1]:
        raise ConfigError(
            f'orientation_weight / position_weight must be in [{WEIGHT_RATIO[0]:g}, '
            f'{WEIGHT_RATIO[1]:g}] m, got {ow:g} / {pw:g} = {ow / pw:g} (beyond it the metric is '
            'numerically singular for some arms)')
    scaling = float(values['velocity_scaling'])
    sample_period = float(values['sample_period'])
    plan_timeout = float(values['plan_timeout'])
    frame_id = str(values['frame_id'])

    if previous is not None and previous.robot_key == robot_key + (names,):
        robot = previous.robot
    else:
        model = load_model(*robot_key)
        if names:
            if len(names) != model.dof or len(set(names)) != len(names) or not all(names):
                raise ConfigError(
                    f'joint_names: need {model.dof} unique non-empty names for the joints '
                    f'{list(model.joint_names)}, got {list(names)}')
            try:
                model = model.with_limits(joint_names=list(names))
            except GeodesicPlannerError as err:
                raise ConfigError(f'joint_names: {err}') from err
        robot = model
    try:
        lim = merge_limits(robot, str(values['joint_limits']), values['max_velocity'],
                           values['max_acceleration'], values['max_jerk'],
                           accel_known=not _is_urdf_source(robot_key[0], robot_key[1]))
    except GeodesicPlannerError as err:
        raise ConfigError(str(err)) from err
    tool_speed = float(values['max_tool_speed'])
    tool_angular_speed = float(values['max_tool_angular_speed'])
    planner_key = robot_key + (names, metric, pw, ow)
    if previous is not None and previous.planner_key == planner_key:
        planner = previous.planner
    else:
        try:
            planner = GeodesicPlanner(robot, metric=metric, position_weight=pw,
                                      orientation_weight=ow)
        except GeodesicPlannerError as err:
            raise ConfigError(f'cannot build the planner: {err}') from err
    try:
        collision, collision_key = collision_for_parameters(
            values, robot, robot_key + (names,), previous.collision if previous else None,
            previous.collision_key if previous else ())
    except GeodesicPlannerError as err:
        raise ConfigError(f'collision model: {err}') from err
    return PlannerConfig(
        robot=robot, planner=planner, robot_key=robot_key + (names,), planner_key=planner_key,
        joint_names=tuple(robot.joint_names), frame_id=frame_id or robot.base_link,
        max_velocity=lim.max_velocity, max_acceleration=lim.max_acceleration,
        velocity_scaling=scaling, sample_period=sample_period, plan_timeout=plan_timeout,
        max_tool_speed=tool_speed or None, max_tool_angular_speed=tool_angular_speed or None,
        max_jerk=lim.max_jerk,
        allowed_start_tolerance=float(values['allowed_start_tolerance']),
        default_velocity_factor=lim.default_velocity_factor,
        default_acceleration_factor=lim.default_acceleration_factor,
        notes=lim.notes, collision=collision, collision_key=collision_key,
        ptp_around_obstacles=bool(values['ptp_around_obstacles']),
        ptp_planning_timeout=float(values['ptp_planning_timeout']))


# --------------------------------------------------------------------------- planning

class PlanAbandonedError(Exception):
    """Raised by :func:`compute_plan` when ``on_trajectory`` declines the trajectory."""


def _start_from_state(config: PlannerConfig, current_q: np.ndarray | None) -> np.ndarray:
    """The current joint state as the start, checked against the joint limits."""
    if current_q is None:
        raise RequestError(
            'start: "current joint state" requested (no start pose or joints given) but no valid '
            f'/joint_states message with the joints {list(config.joint_names)} has been received')
    outside = [f'{name}={q:.6g} not in [{lo:.6g}, {hi:.6g}]' for name, q, lo, hi in zip(
        config.joint_names, current_q, config.robot.lower, config.robot.upper)
        if not (lo - 1e-9 <= q <= hi + 1e-9)]
    if outside:
        raise LimitError(f'start: current joint state outside the joint limits: {", ".join(outside)}')
    return current_q


def check_start_state(config: PlannerConfig, q_start: np.ndarray, current_q: np.ndarray | None) -> None:
    """Refuse a plan whose first point is farther than ``allowed_start_tolerance`` from the robot.

    Raises:
        StartStateError: the largest joint difference exceeds the tolerance (names the joint).
    """
    tol = config.allowed_start_tolerance
    if current_q is None or tol <= 0.0:
        return
    diff = np.abs(np.asarray(q_start, dtype=float) - current_q)
    i = int(np.argmax(diff))
    if diff[i] > tol:
        raise StartStateError(
            f'start: the plan starts {diff[i]:.6g} (rad or m) away from the current joint state at '
            f'joint {config.joint_names[i]!r} (plan {q_start[i]:.6g}, current {current_q[i]:.6g}); '
            f'allowed_start_tolerance is {tol:g}')


def compute_plan(config: PlannerConfig, request: PlanRequest,
                 current_q: np.ndarray | None, stamp: Time | None = None,
                 on_trajectory: Callable[[JointTrajectory], bool] | None = None, *,
                 velocity_factor: float | None = None,
                 acceleration_factor: float | None = None) -> PlanResult:
    """Plan one request (no ROS I/O: a request in, messages out).

    Args:
        config: configuration snapshot.
        request: start (pose, joints, or neither: the current joint state), goal, via poses.
        current_q: latest valid joint state in chain order, shape (dof,), or None. When given, it
            seeds the start pose's IK and the plan's first point is checked against it
            (:func:`check_start_state`).
        stamp: builtin_interfaces/Time for the Path header.
        on_trajectory: called with the validated trajectory before the tool path is built (the
            node publishes it there, so that a controller gets it as early as possible);
            returning False abandons the plan.
        velocity_factor, acceleration_factor: the request's scaling factors in (0, 1]; None: the
            configuration's defaults.
    Raises:
        GeodesicPlannerError: invalid or unreachable request, solver failure (message names the
            cause; :func:`error_code` gives its PlanErrorCode).
        PlanAbandonedError: ``on_trajectory`` returned False.
    """
    if request.start is None and request.start_joints is None:
        request = replace(request, start_joints=_start_from_state(config, current_q))
    t0 = time.perf_counter()
    limits = scaled_limits(config.max_velocity, config.max_acceleration, config.velocity_scaling,
                           velocity_factor or config.default_velocity_factor,
                           acceleration_factor or config.default_acceleration_factor,
                           max_jerk=config.max_jerk, max_tool_speed=config.max_tool_speed,
                           max_tool_angular_speed=config.max_tool_angular_speed)
    spent = {'plan': 0.0, 'timing': 0.0}

    def attempt(q_start: np.ndarray | None) -> tuple[Any, Any]:
        ta = time.perf_counter()
        req = request if q_start is None else replace(request, start=None, start_joints=q_start)
        path = req.plan(config.planner, start_seed=current_q)
        check_start_state(config, path.q_start, current_q)
        tb = time.perf_counter()
        trajectory = path.timed(**limits)
        spent['plan'] += tb - ta
        spent['timing'] += time.perf_counter() - tb
        return path, trajectory

    pose_start = request.start is not None and request.start_joints is None
    found: MotionClearance | None = None
    if config.collision is None:
        path, trajectory = attempt(None)
        branch = 'default' if pose_start else ''
    else:
        T_start = request.start

        def branches(first: JointPath) -> list[np.ndarray]:
            assert T_start is not None
            return start_branches(config.planner, T_start, first.q_start, request.tolerance)
        # min_clearance over the whole path is bounded after the trajectory is published
        path, trajectory, found, branch = first_clear(attempt, config.collision,
                                                      branches if pose_start else None, refine=False)
        branch = branch if pose_start else ''
    t1 = time.perf_counter()
    collision_ms = (t1 - t0 - spent['plan'] - spent['timing']) * 1e3
    points = sample_count(trajectory.duration, config.sample_period)
    if points > MAX_POINTS:
        raise PlanningFailedError(
            f'the trajectory would have {points:.0f} points ({trajectory.duration:.3g} s every '
            f'{config.sample_period:g} s), more than {MAX_POINTS}: increase sample_period or the '
            'scaling factors')
    t, q, dq, ddq = trajectory.sample(config.sample_period)
    t2 = time.perf_counter()
    # checked as the message will carry it (times rounded to ns), before the message is built
    problems = trajectory_problems(config.joint_names, cv.time_from_start_ns(t) * 1e-9, q, dq, ddq)
    if problems:
        raise TrajectoryError(f'generated trajectory is invalid: {problems[:3]}')
    msg = cv.arrays_to_joint_trajectory(list(config.joint_names), t, q, dq, ddq)
    t3 = time.perf_counter()
    if on_trajectory is not None and not on_trajectory(msg):
        raise PlanAbandonedError
    t4 = time.perf_counter()
    whole = None if found is None else found.refined()
    clearance = math.nan if whole is None else whole.min_clearance
    t5 = time.perf_counter()
    poses = np.concatenate([_fk(config.robot, q[i:i + cv.CHECK_EVERY])
                            for i in range(0, len(q), cv.CHECK_EVERY)])
    path_msg = cv.poses_to_path(poses, config.frame_id, stamp)
    path_error = path.line_deviation()
    deviation = blend_deviation(request, path)
    t6 = time.perf_counter()
    solver = path.solver
    stages = {'plan': spent['plan'] * 1e3, 'timing': (spent['timing'] + t2 - t1) * 1e3,
              'collision': collision_ms,
              'trajectory': (t3 - t2) * 1e3, 'publish': (t4 - t3) * 1e3,
              'clearance': (t5 - t4) * 1e3, 'tool path': (t6 - t5) * 1e3}
    return PlanResult(msg, path_msg, poses, len(t), float(trajectory.duration),
                      int(solver.iterations), float(solver.time_ms), stages,
                      solver.method, int(solver.mesh_size), path_error, clearance, branch, deviation,
                      tuple(getattr(path, 'notes', ())),
                      ('', '') if whole is None else whole.pair,
                      math.nan if whole is None else whole.fraction,
                      '' if whole is None else whole.summary())


def _fk(robot: Chain, q: np.ndarray) -> np.ndarray:
    """``robot.fk(q)`` after a cancellation checkpoint (the tool path is built block by block)."""
    checkpoint()
    return robot.fk(q)


def blend_deviation(request: PlanRequest, path: object) -> tuple[float, ...]:
    """Per via pose of ``request`` (in order): the blend zone's largest tool distance from the
    stopping path (m, ``BlendZone.deviation``), 0 where the motion stops; empty when the request
    asks for no blends (``blend_radius`` 0 or no via poses)."""
    if request.items:
        deviation = [0.0] * (len(request.items) - 1)
    elif not request.via or request.blend_radius <= 0.0:
        return ()
    else:
        deviation = [0.0] * len(request.via)
    if isinstance(path, BlendedPath):
        for zone in path.zones:        # zone.via: index among [start, *via, goal]
            deviation[zone.via - 1] = float(zone.deviation)
    return tuple(deviation)
