"""ROS 2 node ``geodesic_planner``: pose-to-pose geodesic plans as JointTrajectory messages.

Interface (names relative to the node, ``~`` = ``/geodesic_planner`` by default):

* service ``~/plan`` (nav_msgs/srv/GetPlan): ``start``/``goal`` PoseStamped in the base frame
  (empty frame_id = base frame; any other frame is rejected). A ``start`` with an empty frame_id
  and an all-zero quaternion means "from the current joint state" (latest valid ``/joint_states``).
  ``tolerance`` (m) is the allowed distance between a requested pose and the nearest reachable one
  (arms with fewer than 6 joints); 0 means the library default. The response ``plan`` holds the
  tool poses at the trajectory's sample times (frame_id = base frame), or no poses on failure.
* topic ``~/joint_trajectory`` (trajectory_msgs/JointTrajectory), reliable, volatile, depth 10:
  one message per successful plan, published as soon as it is validated (before the tool path
  is built and before the service answers), after at most 1 s for subscriptions that the graph
  shows but that have not matched yet (a client that subscribes just before calling). Volatile on purpose: a
  controller that connects later must not execute an old plan (transient_local would replay it).
* topic ``~/path_markers`` (visualization_msgs/MarkerArray), reliable, transient_local, depth 1:
  the tool path line strip and start/goal axes of the latest plan (RViz started later sees it).
* subscription ``/joint_states`` (sensor_msgs/JointState, any joint order, extra joints ignored),
  best effort, depth 10 (only the latest state matters; matches reliable and best-effort
  publishers). A message must contain every robot joint exactly once with finite positions;
  malformed messages are ignored with a warning naming the cause (rate-limited per kind of
  problem) and never replace the last valid state. A valid state outside the joint limits is
  kept (it is the robot's state) and plans from it fail with the joints named.

Parameters (see :data:`PARAMETERS`; ``ros2 param describe`` shows the same descriptions) are
validated together in an on-set callback that builds a new :class:`PlannerConfig` or rejects the
change with a reason; nothing changes on rejection. ``robot``/``robot_description``/``base_link``/
``tip_link`` may change at run time (the model is reloaded); to change the robot and
``joint_names`` together use ``set_parameters_atomically`` (the per-parameter service checks each
change against the others' current values). Invalid values at start: one ``cannot start: ...``
error line and exit code 1.

Timing: ``path.timed(max_velocity * f, max_acceleration * f**2)`` with ``f = velocity_scaling``.
For rest-to-rest timing under box limits this is exactly time scaling as joint_trajectory_controller
applies it (durations / f, velocities * f, accelerations * f**2, same path), sampled every
``sample_period`` s with positions, velocities and accelerations at every point.

Executor model (issue 7, revised for issue 6): the plan service and ``/joint_states`` are each
served by a thread of their own, the parameter services by a MultiThreadedExecutor (4 threads).
Each own thread waits on its entity alone (their callback group is never run by the executor).
The plan thread takes one request at a time and answers it before taking the next, so plans are
computed one at a time in request order, and each successful plan is published exactly once, by
the request that computed it, before its response is sent. The state thread takes every
``/joint_states`` message as it arrives, and the parameter services run on the executor, so state
and parameter updates never wait behind a plan. (rclpy's Python executor rebuilds its wait set
and hands each callback to a pool thread: a few ms per plan request, and at 250 Hz of
``/joint_states`` it halved the plan throughput; the own threads skip both.) Shared state is
swapped atomically: the latest joint vector is an immutable tuple, and the configuration (robot,
planner, limits) is an immutable :class:`PlannerConfig` that a request reads once at its start; a
parameter change builds a new one (or rejects it with a reason) under a lock.

Bounded time: each plan runs in a worker thread and the service waits at most ``plan_timeout`` s
for it. A plan still computing then is abandoned: the request fails, and a lock shared by
"publish" and "abandon" guarantees that its trajectory is never published. (If the trajectory
was already out, the request waits for its tool path, which needs no solver, and succeeds.) A
second lock keeps the next plan from running beside an abandoned one still in progress (that
request fails as "planner busy" after at most ``plan_timeout`` s). ``kill -USR1 <pid>`` dumps
every thread's stack to stderr (faulthandler).
"""
from __future__ import annotations

import faulthandler
import math
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import rclpy
from rclpy._rclpy_pybind11 import RCLError
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import CallbackGroup
from rclpy.exceptions import InvalidHandle, ParameterException
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.impl.logging_severity import LoggingSeverity
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from .. import GeodesicPlanner, load_robot
from ..core.errors import GeodesicPlannerError, LimitError, RequestError
from . import conversions as cv
from .matching import matched_logger, wait_for_matched_subscriptions

NODE_NAME = 'geodesic_planner'
#: Robot used when neither ``robot`` nor ``robot_description`` is given: the paper's planar 3R arm.
DEFAULT_ROBOT = 'planar_3r'
METRICS = ('paper', 'position')
#: Largest number of points in a published trajectory (bounds memory and time per request).
MAX_POINTS = 100_000

_ROBOT_KEYS = ('robot', 'robot_description', 'base_link', 'tip_link')
_STRING, _DOUBLE, _DOUBLES, _STRINGS = 'string', 'double', 'double array', 'string array'

#: name -> (default, kind, description, constraints)
PARAMETERS: dict[str, tuple[Any, str, str, str]] = {
    'robot': (DEFAULT_ROBOT, _STRING,
              'Robot model: a preset name (planar_3r, rrpp, ur5e, panda) or a path to a .urdf file. '
              'Ignored when robot_description is not empty.', 'non-empty unless robot_description is set'),
    'robot_description': ('', _STRING,
                          'URDF XML string (as robot_state_publisher publishes it); takes precedence '
                          'over robot when not empty.', ''),
    'base_link': ('', _STRING, 'Base link of the chain in the URDF (empty: the URDF root).', ''),
    'tip_link': ('', _STRING, 'Tool link of the chain in the URDF (empty: the only leaf).', ''),
    'joint_names': ([], _STRINGS,
                    'Joint names used on /joint_states and in published trajectories, in chain order '
                    '(empty: the model names).', 'empty or one unique name per joint'),
    'metric': ('paper', _STRING,
               "Riemannian metric: 'paper' (position + orientation, Chen et al. 2016) or 'position'.",
               "'paper' or 'position'"),
    'position_weight': (1.0, _DOUBLE, 'Weight of the position term of the metric.', '> 0'),
    'orientation_weight': (1.0, _DOUBLE, 'Weight of the orientation term of the metric.', '> 0'),
    'max_velocity': ([], _DOUBLES,
                     'Joint velocity limits, rad/s or m/s (empty: URDF/robot defaults; one value: '
                     'all joints).', 'empty, 1 or dof values, each finite and > 0'),
    'max_acceleration': ([], _DOUBLES,
                         'Joint acceleration limits, rad/s^2 or m/s^2 (empty: robot defaults; one '
                         'value: all joints).', 'empty, 1 or dof values, each finite and > 0'),
    'velocity_scaling': (1.0, _DOUBLE,
                         'Time scaling factor f: durations / f, velocities * f, accelerations * f^2.',
                         'in (0, 1]'),
    'sample_period': (0.01, _DOUBLE, 'Time between trajectory points, s.', 'finite, > 0'),
    'frame_id': ('', _STRING,
                 'Base frame of requests and outputs (empty: the model base link).', ''),
    'plan_timeout': (5.0, _DOUBLE,
                     'Longest time a request waits for its plan, s (late plans fail).', 'finite, > 0'),
}


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


# --------------------------------------------------------------------------- parameters

def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{name}: expected a number, got {value!r}')
    return float(value)


def _positive(name: str, value: Any) -> float:
    x = _number(name, value)
    if not math.isfinite(x) or x <= 0.0:
        raise ConfigError(f'{name}: must be finite and > 0, got {x!r}')
    return x


def _string(name: str, value: Any) -> str:
    if not isinstance(value, str):
        raise ConfigError(f'{name}: expected a string, got {value!r}')
    return value


def _limits(name: str, value: Any, default: np.ndarray, dof: int) -> np.ndarray:
    """Per-joint limits from a parameter value: empty -> default, 1 value -> broadcast, dof values."""
    if value is None:
        value = []
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ConfigError(f'{name}: expected an array of numbers, got {value!r}')
    vals = list(value)
    if not vals:
        return np.asarray(default, dtype=float).copy()
    arr = np.array([_number(name, v) for v in vals], dtype=float)
    if arr.size not in (1, dof):
        raise ConfigError(f'{name}: {arr.size} values for a robot with {dof} joints '
                          f'(give {dof} values, one value for all joints, or none for defaults)')
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0.0):
        raise ConfigError(f'{name}: every value must be finite and > 0, got {arr.tolist()}')
    return np.broadcast_to(arr, (dof,)).copy()


def load_model(robot: str, robot_description: str, base_link: str, tip_link: str) -> Any:
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
        values: parameter name -> value for every name in :data:`PARAMETERS`.
        previous: the configuration in use, if any.
    Raises:
        ConfigError: the first invalid value, with the reason.
    """
    robot_key = tuple(_string(k, values[k]) for k in _ROBOT_KEYS)
    names_value = values['joint_names'] or []
    if isinstance(names_value, (str, bytes)) or not all(isinstance(n, str) for n in names_value):
        raise ConfigError(f'joint_names: expected an array of strings, got {names_value!r}')
    names = tuple(names_value)
    metric = _string('metric', values['metric'])
    if metric not in METRICS:
        raise ConfigError(f"metric: must be one of {list(METRICS)}, got {metric!r}")
    pw = _positive('position_weight', values['position_weight'])
    ow = _positive('orientation_weight', values['orientation_weight'])
    scaling = _number('velocity_scaling', values['velocity_scaling'])
    if not (0.0 < scaling <= 1.0):
        raise ConfigError(f'velocity_scaling: must be in (0, 1], got {scaling!r}')
    sample_period = _positive('sample_period', values['sample_period'])
    plan_timeout = _positive('plan_timeout', values['plan_timeout'])
    frame_id = _string('frame_id', values['frame_id'])

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


class PlanAbandoned(Exception):
    """Raised by :func:`compute_plan` when ``on_trajectory`` declines the trajectory."""


def compute_plan(config: PlannerConfig, request: GetPlan.Request,
                 current_q: np.ndarray | None, stamp: Any = None,
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
        PlanAbandoned: ``on_trajectory`` returned False.
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
        raise PlanAbandoned
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


# --------------------------------------------------------------------------- node

def _log(logger: Any, severity: LoggingSeverity, message: str) -> None:
    """Log like ``logger.info``/``error`` without rclpy's caller lookup.

    rclpy's logger finds its caller through ``inspect`` (source files stat-ed and read) on every
    call, about 0.3 ms; this goes straight to rcutils (about 0.01 ms) with the caller's
    function, file and line. Used for the per-request lines (no throttling or other filters).
    """
    if logger.is_enabled_for(severity):
        frame = sys._getframe(1)
        _rclpy.rclpy_logging_rcutils_log(severity, logger.name, message, frame.f_code.co_name,
                                         frame.f_code.co_filename, frame.f_lineno)


def _joint_state_problem(message: str) -> str:
    """Category of a rejected joint state (warnings are rate-limited per category)."""
    for key in ('duplicate', 'missing', 'none of', 'non-finite'):
        if key in message:
            return key
    return 'length'


class _OwnThreadGroup(CallbackGroup):
    """Callback group of entities served by a thread of their own: an executor never runs (nor
    waits on) them."""

    def can_execute(self, entity: Any) -> bool:
        return False

    def beginning_execution(self, entity: Any) -> bool:
        return False

    def ending_execution(self, entity: Any) -> None:
        pass


class GeodesicPlannerNode(Node):
    """The ``geodesic_planner`` node (see the module docstring for its interface).

    Raises:
        ConfigError: the initial parameters are invalid or the robot cannot be loaded.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        for name, (default, kind, description, constraints) in PARAMETERS.items():
            descriptor = ParameterDescriptor(
                description=description, additional_constraints=f'{kind}; {constraints}'.rstrip('; '))
            # Numbers and arrays are type-checked by build_config instead of rclpy: ints are
            # accepted for doubles, and an empty array of any element type means "defaults".
            descriptor.dynamic_typing = kind != _STRING
            self.declare_parameter(name, default, descriptor)
        self._config_lock = threading.Lock()
        self._config = build_config(self._parameter_values())
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._state: tuple[np.ndarray, tuple[str, ...]] | None = None
        self._last_warn: dict[str, float] = {}
        self._abandoned = 0
        # Held by the worker computing a plan. Normally uncontended (plans are serialised by
        # the service's callback group); it keeps a new plan from running beside an abandoned
        # (timed-out) one that may still be using the same planner object.
        self._planner_lock = threading.Lock()
        self._publish_lock = threading.Lock()
        self._unmatched_graph_count: int | None = None

        self._plan_group = _OwnThreadGroup()
        self._state_group = _OwnThreadGroup()
        self.trajectory_pub = self.create_publisher(
            JointTrajectory, '~/joint_trajectory',
            QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE),
            event_callbacks=matched_logger(self, self.resolve_topic_name('~/joint_trajectory')))
        self.marker_pub = self.create_publisher(
            MarkerArray, '~/path_markers',
            QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.joint_state_sub = self.create_subscription(
            JointState, '/joint_states', self._on_joint_state,
            QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE),
            callback_group=self._state_group)
        self.plan_srv = self.create_service(
            GetPlan, '~/plan', self._on_plan,
            qos_profile=QoSProfile(depth=64, history=HistoryPolicy.KEEP_LAST,
                                   reliability=ReliabilityPolicy.RELIABLE,
                                   durability=DurabilityPolicy.VOLATILE),
            callback_group=self._plan_group)
        self._stop_threads = threading.Event()
        self._threads = [
            threading.Thread(target=self._serve_plans, name='plan_service', daemon=True),
            threading.Thread(target=self._serve_joint_states, name='joint_states', daemon=True)]
        for thread in self._threads:
            thread.start()
        c = self._config
        service = self.resolve_service_name('~/plan')
        self.get_logger().info(
            f"robot '{c.robot.name}' ({c.robot.dof} joints {list(c.joint_names)}), base frame "
            f"'{c.frame_id}', metric {self.get_parameter('metric').value}, velocity_scaling "
            f'{c.velocity_scaling:g}; serving {service}')

    # ------------------------------------------------------------------ parameters
    def _parameter_values(self, changes: Sequence[Parameter] = ()) -> dict[str, Any]:
        values = {name: self.get_parameter(name).value for name in PARAMETERS}
        for p in changes:
            if p.name in values:
                values[p.name] = p.value
        return values

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        ours = [p for p in params if p.name in PARAMETERS]
        if not ours:
            return SetParametersResult(successful=True)
        for p in ours:
            if p.type_ == Parameter.Type.NOT_SET:
                return SetParametersResult(successful=False,
                                           reason=f'{p.name}: cannot be undeclared')
        with self._config_lock:
            try:
                config = build_config(self._parameter_values(ours), self._config)
            except ConfigError as err:
                self.get_logger().warning(f'parameter update rejected: {err}')
                return SetParametersResult(successful=False, reason=str(err))
            except Exception as err:  # noqa: BLE001 - boundary: never let a callback crash the node
                self.get_logger().error(f'internal error: {type(err).__name__}: {err}')
                return SetParametersResult(successful=False,
                                           reason=f'internal error: {type(err).__name__}: {err}')
            self._config = config
        names = ', '.join(f'{p.name}={p.value!r}' for p in ours if p.name != 'robot_description')
        self.get_logger().info(f'parameters updated: {names or "robot_description"}')
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ joint states
    def _warn_rate_limited(self, kind: str, text: str, period: float = 2.0) -> None:
        now = time.monotonic()
        if now - self._last_warn.get(kind, -math.inf) >= period:
            self._last_warn[kind] = now
            self.get_logger().warning(text)

    def _on_joint_state(self, msg: JointState) -> None:
        names = self._config.joint_names
        try:
            q = cv.joint_state_to_vector(msg, names)
        except RequestError as err:
            self._warn_rate_limited(_joint_state_problem(str(err)),
                                    f'ignoring /joint_states message: {err}')
            return
        except Exception as err:  # noqa: BLE001 - boundary
            self._warn_rate_limited('internal', f'ignoring /joint_states message: internal error: '
                                    f'{type(err).__name__}: {err}')
            return
        self._state = (q, names)

    def current_joints(self, names: tuple[str, ...]) -> np.ndarray | None:
        """Latest valid joint state for ``names`` (None if none, or if it was read for other names)."""
        state = self._state
        if state is None or state[1] != names:
            return None
        return state[0]

    # ------------------------------------------------------------------ service
    def _await_subscriptions(self) -> None:
        """Before a one-off publish: let subscriptions the graph shows match the writer.

        A volatile reader gets only what is published after it matched, and a subscriber that
        subscribes just before calling ``~/plan`` may be in the graph but not yet matched. Waits
        at most MATCH_TIMEOUT (1 s); a mismatch that already timed out (e.g. a subscriber with
        incompatible QoS) is not waited for again while the graph count stays the same.
        """
        pub = self.trajectory_pub
        graph = self.count_subscribers(pub.topic_name)
        if pub.get_subscription_count() >= graph or graph == self._unmatched_graph_count:
            return
        t0 = time.monotonic()
        matched = wait_for_matched_subscriptions(self, pub)
        waited_ms = (time.monotonic() - t0) * 1e3
        graph = self.count_subscribers(pub.topic_name)
        self._unmatched_graph_count = graph if matched < graph else None
        if matched < graph:
            self.get_logger().warning(
                f'publishing with {matched} of {graph} subscriptions matched after waiting '
                f'{waited_ms:.0f} ms (QoS incompatible or still discovering?)')
        else:
            self.get_logger().info(f'waited {waited_ms:.1f} ms for {graph} subscriptions to match')

    def _wait_alone(self, entity: Any, kind: str,
                    take: Callable[[], Callable[[], None] | None]) -> None:
        """Own-thread loop: wait on ``entity`` alone (0.1 s at a time, until stopped) and call
        ``take()`` (inside the entity's handle) whenever it is ready.

        Args:
            entity: the service or subscription.
            kind: 'service' or 'subscription'.
            take: takes what is ready; may return a follow-up to run outside the handles (a
                plan, which must not keep the service or the context from being destroyed).
        """
        counts = (1, 0, 0, 0, 0) if kind == 'subscription' else (0, 0, 0, 0, 1)
        wait_set = _rclpy.WaitSet(*counts, 0, self.context.handle)
        add = wait_set.add_subscription if kind == 'subscription' else wait_set.add_service
        while not self._stop_threads.is_set():
            try:
                with self.context.handle, entity.handle:
                    wait_set.clear_entities()
                    add(entity.handle)
                    wait_set.wait(100_000_000)      # 0.1 s: the stop flag is checked between waits
                    follow_up = None
                    if entity.handle.pointer in wait_set.get_ready_entities(kind):
                        follow_up = take()
                if follow_up is not None:
                    follow_up()
            except InvalidHandle:                   # the entity is gone
                return
            except Exception as err:  # noqa: BLE001 - boundary: the thread keeps serving
                if not self.context.ok():           # shutting down
                    return
                _log(self.get_logger(), LoggingSeverity.ERROR,
                     f'internal error in {threading.current_thread().name}: '
                     f'{type(err).__name__}: {err}')
                self._stop_threads.wait(0.1)        # no busy loop if the error repeats

    def _serve_joint_states(self) -> None:
        """State thread: handle every ``/joint_states`` message as it arrives."""
        sub = self.joint_state_sub

        def take() -> Callable[[], None] | None:
            while (taken := sub.handle.take_message(JointState, False)) is not None:
                self._on_joint_state(taken[0])
            return None

        self._wait_alone(sub, 'subscription', take)

    def _serve_plans(self) -> None:
        """Plan thread: answer ``~/plan`` requests one at a time, in order."""
        srv = self.plan_srv

        def take() -> Callable[[], None] | None:
            request, header = srv.handle.service_take_request(GetPlan.Request)
            if header is None:
                return None

            def answer() -> None:
                try:
                    response = self._on_plan(request, GetPlan.Response())
                except Exception as err:  # noqa: BLE001 - boundary: the plan thread keeps serving
                    _log(self.get_logger(), LoggingSeverity.ERROR,
                         f'internal error: {type(err).__name__}: {err}')
                    response = GetPlan.Response()
                try:
                    srv.send_response(response, header)
                except RCLError as err:   # e.g. the client is gone; keep serving the others
                    _log(self.get_logger(), LoggingSeverity.ERROR,
                         f'could not send the plan response: {err}')
            return answer

        self._wait_alone(srv, 'service', take)

    def stop_threads(self, timeout: float = 2.0) -> None:
        """Stop the plan and state threads (a request in progress gets up to ``timeout`` s)."""
        self._stop_threads.set()
        deadline = time.monotonic() + timeout
        for thread in self._threads:
            if thread.is_alive() and thread is not threading.current_thread():
                thread.join(max(0.0, deadline - time.monotonic()))

    def destroy_node(self) -> Any:
        """Stop the own threads, then destroy the node's entities."""
        self.stop_threads()
        return super().destroy_node()

    def _on_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        t0 = time.perf_counter()
        config = self._config
        stamp = self.get_clock().now().to_msg()
        response.plan = Path(header=Header(frame_id=config.frame_id, stamp=stamp))
        current_q = self.current_joints(config.joint_names)
        box: dict[str, Any] = {}
        state = {'abandoned': False, 'published': False}
        done = threading.Event()

        def publish(msg: JointTrajectory) -> bool:
            # Runs in the worker; the lock makes "publish" and "abandon" mutually exclusive.
            self._await_subscriptions()
            with self._publish_lock:
                if state['abandoned']:
                    return False
                self.trajectory_pub.publish(msg)
                state['published'] = True
                return True

        def work() -> None:
            try:
                if not self._planner_lock.acquire(timeout=config.plan_timeout):
                    raise RequestError('planner busy: an earlier request that timed out is '
                                       'still computing')
                try:
                    box['result'] = compute_plan(config, request, current_q, stamp, publish)
                finally:
                    self._planner_lock.release()
            except BaseException as err:  # noqa: BLE001 - handed to the service callback
                box['error'] = err
            finally:
                done.set()

        worker = threading.Thread(target=work, name='geodesic_plan', daemon=True)
        worker.start()
        if not done.wait(config.plan_timeout):
            with self._publish_lock:
                state['abandoned'] = not state['published']
            if state['abandoned']:
                self._abandoned += 1
                _log(self.get_logger(), LoggingSeverity.ERROR,
                     f'plan failed: timed out after {config.plan_timeout:g} s (plan_timeout); the '
                     f'computation is abandoned and its result discarded ({self._abandoned} so far)')
                return response
            done.wait()   # the trajectory is out; its tool path follows (bounded, no solver)
        err = box.get('error')
        if isinstance(err, GeodesicPlannerError):
            _log(self.get_logger(), LoggingSeverity.ERROR, f'plan failed: {err}')
            return response
        if err is not None:
            after = ' (after publishing the trajectory)' if state['published'] else ''
            _log(self.get_logger(), LoggingSeverity.ERROR,
                 f'internal error{after}: {type(err).__name__}: {err}')
            return response
        result: PlanResult = box['result']
        self.marker_pub.publish(result.markers)
        response.plan = result.path
        total_ms = (time.perf_counter() - t0) * 1e3
        _log(self.get_logger(), LoggingSeverity.INFO,
             f'plan: {result.points} points, {result.duration:.2f} s, solver {result.solver_method} '
             f'({result.solver_iterations} it, {result.mesh_size} nodes), {result.solver_ms:.1f} ms '
             f'(request {total_ms:.1f} ms: '
             + ', '.join(f'{k} {v:.1f}' for k, v in result.stage_ms.items()) + ')')
        return response


def main(args: list[str] | None = None) -> int:
    """Console script ``geodesic_planner_node``: spin until SIGINT/SIGTERM.

    Shutdown order: SIGINT/SIGTERM only set a flag (Python handlers; rclpy's own handlers, which
    shut the context down at once, are not installed); the executor then stops within 0.1 s,
    running callbacks get up to 2 s to finish, the node's entities are destroyed while the
    context is still valid, and only then is rclpy shut down.

    Returns:
        0 after a signal (also one that arrives while starting), 1 when the parameters or the
        robot model are invalid at start (one error line, no traceback).
    """
    stop = threading.Event()

    def request_stop(signum: int, _frame: Any) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, request_stop) for sig in (signal.SIGINT, signal.SIGTERM)}
    faulthandler.enable()                                     # stacks on a fatal signal
    faulthandler.register(signal.SIGUSR1, all_threads=True)   # `kill -USR1 pid`: dump stacks
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except RCLError as err:  # e.g. a -p value rcl cannot parse
        print(f'[ERROR] [{NODE_NAME}]: cannot start: {err}', file=sys.stderr)
        return 1
    node = None
    executor = None
    try:
        executor = MultiThreadedExecutor(num_threads=4)
        node = GeodesicPlannerNode()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ConfigError, ParameterException) as err:
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {err}')
        return 1
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)   # lets a running callback finish (bounded)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
