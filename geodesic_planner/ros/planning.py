"""The planner node's pipeline: parameters -> configuration, request -> trajectory messages.

No executor, threads or ROS I/O here: :func:`build_config` turns parameter values into an
immutable :class:`PlannerConfig` (or a :class:`ConfigError` naming the parameter), and
:func:`compute_plan` turns one GetPlan request into the JointTrajectory, tool Path and markers
through the library (``GeodesicPlanner.plan``, ``path.timed``, ``trajectory.sample``).

Timing: ``path.timed(max_velocity * f, max_acceleration * f**2)`` with ``f = velocity_scaling``.
For rest-to-rest timing under box limits this is exactly time scaling as joint_trajectory_controller
applies it (durations / f, velocities * f, accelerations * f**2, same path), sampled every
``sample_period`` s with positions, velocities and accelerations at every point.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from .. import GeodesicPlanner, load_robot
from ..core.errors import GeodesicPlannerError, LimitError, RequestError
from ..core.kinematics import Chain
from . import conversions as cv
from . import params
from .params import PLANNER_PARAMETERS

#: Largest number of points in a published trajectory (bounds memory and time per request).
MAX_POINTS = 100_000

_ROBOT_KEYS = ('robot', 'robot_description', 'base_link', 'tip_link')


class ConfigError(GeodesicPlannerError, ValueError):
    """A parameter value is invalid (the message names the parameter and the reason)."""


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


@dataclass(frozen=True)
class PlanResult:
    """Messages of one successful plan and its figures for the log line."""

    trajectory: JointTrajectory
    path: Path
    markers: MarkerArray
    points: int
    duration: float
    solver_iterations: int
    solver_ms: float
    #: ms per stage: 'plan' (library), 'timing' (timed + sample), 'trajectory' (message and
    #: its validation), 'publish' (on_trajectory), 'tool path' (fk, Path and markers)
    stage_ms: dict[str, float]
    #: SolverReport.method ('pullback' or 'collocation') and mesh size
    solver_method: str = ''
    mesh_size: int = 0


def _limits(name: str, value: Sequence[float] | np.ndarray | None, default: np.ndarray, dof: int) -> np.ndarray:
    """Per-joint limits from a checked parameter value: empty -> default, 1 value -> all joints."""
    vals = [] if value is None else list(value)
    if not vals:
        return np.asarray(default, dtype=float).copy()
    arr = np.array(vals, dtype=float)
    if arr.size not in (1, dof):
        raise ConfigError(f'{name}: {arr.size} values for a robot with {dof} joints '
                          f'(give {dof} values, one value for all joints, or none for defaults)')
    return np.broadcast_to(arr, (dof,)).copy()


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


def build_config(values: dict[str, Any], previous: PlannerConfig | None = None) -> PlannerConfig:
    """Validate parameter values and build a :class:`PlannerConfig`.

    The robot model and the planner are reused from ``previous`` when their parameters are
    unchanged.

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
    max_velocity = _limits('max_velocity', values['max_velocity'], robot.max_velocity, robot.dof)
    max_acceleration = _limits('max_acceleration', values['max_acceleration'],
                               robot.max_acceleration, robot.dof)
    planner_key = robot_key + (names, metric, pw, ow)
    if previous is not None and previous.planner_key == planner_key:
        planner = previous.planner
    else:
        try:
            planner = GeodesicPlanner(robot, metric=metric, position_weight=pw,
                                      orientation_weight=ow)
        except GeodesicPlannerError as err:
            raise ConfigError(f'cannot build the planner: {err}') from err
    return PlannerConfig(
        robot=robot, planner=planner, robot_key=robot_key + (names,), planner_key=planner_key,
        joint_names=tuple(robot.joint_names), frame_id=frame_id or robot.base_link,
        max_velocity=max_velocity, max_acceleration=max_acceleration,
        velocity_scaling=scaling, sample_period=sample_period, plan_timeout=plan_timeout)


# --------------------------------------------------------------------------- planning

def _tolerance(value: float) -> float | None:
    tol = float(value)
    if not math.isfinite(tol) or tol < 0.0:
        raise RequestError(f'tolerance: must be finite and >= 0 m, got {tol!r}')
    return tol if tol > 0.0 else None


class PlanAbandonedError(Exception):
    """Raised by :func:`compute_plan` when ``on_trajectory`` declines the trajectory."""


def compute_plan(config: PlannerConfig, request: GetPlan.Request,
                 current_q: np.ndarray | None, stamp: Time | None = None,
                 on_trajectory: Callable[[JointTrajectory], bool] | None = None) -> PlanResult:
    """Plan for one GetPlan request (no ROS I/O: messages in, messages out).

    Args:
        config: configuration snapshot.
        request: start/goal poses (base frame) and tolerance (m).
        current_q: latest valid joint state in chain order, shape (dof,), or None.
        stamp: builtin_interfaces/Time for the Path header.
        on_trajectory: called with the validated trajectory before the tool path is built (the
            node publishes it there, so that a controller gets it as early as possible);
            returning False abandons the plan.
    Raises:
        GeodesicPlannerError: invalid or unreachable request, solver failure (message names the cause).
        PlanAbandonedError: ``on_trajectory`` returned False.
    """
    goal = cv.pose_stamped_to_matrix(request.goal, config.frame_id, 'goal')
    tolerance = _tolerance(request.tolerance)
    if cv.is_current_state_pose(request.start):
        if current_q is None:
            raise RequestError(
                'start: "current joint state" requested (empty frame_id, zero quaternion) but no '
                f'valid /joint_states message with the joints {list(config.joint_names)} '
                'has been received')
        outside = [f'{name}={q:.6g} not in [{lo:.6g}, {hi:.6g}]' for name, q, lo, hi in zip(
            config.joint_names, current_q, config.robot.lower, config.robot.upper)
            if not (lo - 1e-9 <= q <= hi + 1e-9)]
        if outside:
            raise RequestError(f'start: current joint state outside the joint limits: '
                               f'{", ".join(outside)}')
        start, start_joints = None, current_q
    else:
        start = cv.pose_stamped_to_matrix(request.start, config.frame_id, 'start')
        start_joints = None
    kwargs: dict[str, Any] = {'start_joints': start_joints}
    if tolerance is not None:
        kwargs['tolerance'] = tolerance
    t0 = time.perf_counter()
    path = config.planner.plan(start, goal, **kwargs)
    t1 = time.perf_counter()
    f = config.velocity_scaling
    trajectory = path.timed(max_velocity=config.max_velocity * f,
                            max_acceleration=config.max_acceleration * f * f)
    points = int(trajectory.duration / config.sample_period) + 2
    if points > MAX_POINTS:
        raise LimitError(
            f'the trajectory would have {points} points ({trajectory.duration:.3g} s every '
            f'{config.sample_period:g} s), more than {MAX_POINTS}: increase sample_period')
    t, q, dq, ddq = trajectory.sample(config.sample_period)
    t2 = time.perf_counter()
    msg = cv.arrays_to_joint_trajectory(list(config.joint_names), t, q, dq, ddq)
    problems = cv.validate_joint_trajectory(msg)
    if problems:
        raise RuntimeError(f'generated trajectory is invalid: {problems[:3]}')
    t3 = time.perf_counter()
    if on_trajectory is not None and not on_trajectory(msg):
        raise PlanAbandonedError
    t4 = time.perf_counter()
    tool = config.robot.fk(q)
    path_msg = cv.poses_to_path(tool, config.frame_id, stamp)
    markers = cv.path_markers(tool, config.frame_id)
    t5 = time.perf_counter()
    solver = path.solver
    stages = {'plan': (t1 - t0) * 1e3, 'timing': (t2 - t1) * 1e3,
              'trajectory': (t3 - t2) * 1e3, 'publish': (t4 - t3) * 1e3,
              'tool path': (t5 - t4) * 1e3}
    return PlanResult(msg, path_msg, markers, len(t), float(trajectory.duration),
                      int(solver.iterations), float(solver.time_ms), stages,
                      solver.method, int(solver.mesh_size))
