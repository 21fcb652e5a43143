"""ROS 2 node ``geodesic_planner``: pose-to-pose geodesic plans as JointTrajectory messages.

Interface (names relative to the node, ``~`` = ``/geodesic_planner`` by default):

* service ``~/plan_trajectory`` (PlanTrajectory.srv documents every field): start (pose, joints,
  or unset = the current joint state), goal, via poses, ``blend_radius``, scaling factors and
  ``execute``; the reply: the PlanErrorCode (:data:`geodesic_planner.core.codes.ERROR_CODES`), the reason, the
  trajectory, the tool path, the solver's figures, the blend deviations, the followable
  ``fraction`` of the line. With a joint state known, an explicit start is solved seeded from it
  and refused (START_STATE_MISMATCH) beyond ``allowed_start_tolerance``.
* service ``~/plan_sequence`` (PlanSequence): LIN, CIRC and PTP items with blends, one
  trajectory (:mod:`~geodesic_planner.ros.sequence_service`).
* service ``~/plan`` (nav_msgs/srv/GetPlan, compatibility; every success is published, no
  start-state check): start/goal in the base frame (an empty frame_id and an all-zero quaternion:
  the current joint state); ``tolerance`` (m, 0: the default) is the allowed distance to the
  nearest reachable pose. ``plan``: the tool poses at the sample times.
* topic ``~/joint_trajectory`` (trajectory_msgs/JointTrajectory), reliable, volatile, depth 10:
  one message per successful plan, published as soon as it is validated (before the tool path
  and the reply), after at most 1 s for subscriptions the graph shows but that have not matched
  yet. Volatile on purpose: a controller that connects later must not execute an old plan.
* topic ``~/path_markers`` (visualization_msgs/MarkerArray), reliable, transient_local, depth 1:
  the tool path line strip and start/goal axes of the latest plan (RViz started later sees it);
  built only while a reader is matched (:mod:`~geodesic_planner.ros.path_markers`).
* collisions: every plan is checked against the robot's own links and the scene; the reply gives
  ``min_clearance`` and ``ik_branch``; the scene: :mod:`~geodesic_planner.ros.scene_services`.
* subscription ``/robot_description`` (std_msgs/String, reliable, transient local): the URDF
  used while the ``robot`` parameter is empty (until it arrives, plans fail with PLANNING_FAILED
  saying so).
* subscription ``/joint_states`` (sensor_msgs/JointState, any joint order, extra joints ignored),
  best effort, depth 10: every robot joint exactly once with a finite position, or the message is
  ignored with a rate-limited warning naming the cause (the last valid state is kept).

Parameters (:data:`geodesic_planner.ros.params.PLANNER_PARAMETERS`, from the schema shared with
the processor node; ``ros2 param describe`` shows its descriptions) are checked one by one
against the schema, then together in the on-set callback, which builds a new
:class:`~geodesic_planner.ros.planning.PlannerConfig` or rejects the change with a reason;
nothing changes on rejection. ``robot``/``robot_description``/``base_link``/``tip_link`` may change
at run time (the model is reloaded); to change the robot and ``joint_names`` together use
``set_parameters_atomically`` (the per-parameter service checks each change against the others'
current values). Invalid values at start: one ``cannot start: ...`` error line and exit code 1.

The pipeline (parameters -> configuration, request -> messages): :mod:`geodesic_planner.ros.planning`.

Executor model, on rclpy's public API: a MultiThreadedExecutor spun by the main thread, with
``max_queued_requests + 3`` threads, serves both plan services in a ReentrantCallbackGroup and
the parameter services (the node's default group: a parameter change never waits behind a plan).

Queue and overload (:class:`~geodesic_planner.ros.admission.PlanQueue`): at most
``max_queued_requests`` requests wait or plan, one plan at a time in arrival order; one more is
answered at once (PLANNING_FAILED, "planner overloaded", counted on /diagnostics); one that waits
longer than ``plan_timeout`` is answered TIMED_OUT. Services are reliable KEEP_ALL, so every
request the node takes is answered (``docs/reliability.md``). ``/joint_states`` is taken off the
plan path (:mod:`~geodesic_planner.ros.joint_states`; why: ``docs/benchmarks.md``, "Node on stock
rclpy"). The configuration is an immutable :class:`~geodesic_planner.ros.planning.PlannerConfig`
that a request reads once at its start; a parameter change builds a new one under a lock.

Bounded time (:class:`~geodesic_planner.ros.admission.PlanWorker`): a plan still computing after
``plan_timeout`` is answered TIMED_OUT at once, cancelled (:mod:`geodesic_planner.core.cancel`) and
never published; the next plan waits for it to stop (at most ``CANCEL_WAIT`` s), then gets its own
whole ``plan_timeout``. ``kill -USR1 <pid>`` dumps every thread's stack to stderr (faulthandler).
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory
from nav_msgs.msg import Path
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header, String
from trajectory_msgs.msg import JointTrajectory

from ..core.collision import CollisionModel
from ..core.errors import GeodesicPlannerError, PlanTimeoutError, quoted
from ..core.request import PlanRequest
from . import params, runtime
from .admission import PlanQueue, PlanWorker, WorkerBusyError
from .diagnostics import NodeStatus
from .matching import MatchBeforePublish, matched_logger
from .params import PLANNER_PARAMETERS
from .path_markers import LatestPathMarkers
from .plan_log import PlanLog
from .joint_states import JointStateListener, RateLimitedWarnings
from .scene_services import SceneServices
from .sensor_maps import SensorMaps, node_sensors
from .sequence_service import SequenceService
from .planning import (CODE_NAMES, ConfigError, Outcome, PlannerConfig, PlanResult,
                       build_config, compute_plan)
from .service_requests import get_plan_request, plan_trajectory_request

NODE_NAME = 'geodesic_planner'
#: Longest wait of a plan for an abandoned one to stop, s (its cancellation checkpoints stop it
#: within tens of ms: docs/testing.md).
CANCEL_WAIT = 2.0


class GeodesicPlannerNode(params.SchemaNode):
    """The ``geodesic_planner`` node (see the module docstring for its interface).

    Raises:
        ConfigError: the initial parameters are invalid or the robot cannot be loaded.
    """

    def __init__(self, **kwargs: Any) -> None:  # noqa: ANN401 rclpy Node options, passed through
        super().__init__(NODE_NAME, **kwargs)
        params.declare(self, PLANNER_PARAMETERS)
        params.check_unknown(self, PLANNER_PARAMETERS)   # a mistyped name: a warning, later refused
        self._config_lock = threading.Lock()
        self._topic_description = ''
        self._description_topic = self.resolve_topic_name('/robot_description')
        self._config: PlannerConfig | None = self._build(self._parameter_values(), None)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.warnings = RateLimitedWarnings(self.get_logger())
        self._abandoned = 0
        self._stop_ms_max = 0.0
        self.worker = PlanWorker(CANCEL_WAIT, self._stopped)

        self.status = NodeStatus(self)
        self.status.set(trajectory_subscriptions_matched=0)
        self.trajectory_pub = self.create_publisher(
            JointTrajectory, '~/joint_trajectory',
            QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE),
            event_callbacks=matched_logger(
                self, self.resolve_topic_name('~/joint_trajectory'),
                on_count=lambda n: self.status.set(trajectory_subscriptions_matched=n)))
        self._await_subscriptions = MatchBeforePublish(self, self.trajectory_pub)
        self.path_markers = LatestPathMarkers(self)    # built only for a matched reader
        self.plan_log = PlanLog(self.get_logger())
        self._plan_log_timer = self.create_timer(1.0, self.plan_log.flush_due)
        # /joint_states: a hidden node spun in a thread of its own (ros/joint_states.py)
        self.joint_states = JointStateListener(
            self, self.resolve_topic_name('/joint_states'),
            lambda: self._config.joint_names if self._config is not None else None, self.warnings)
        # Both services: a reentrant group on a pool of max_queued_requests + 3 threads, so that a
        # thread is always free to take the next request, and the PlanQueue (admission, one plan
        # at a time, in order). KEEP_ALL: DDS never overwrites a request or a reply in a burst.
        self.queue = PlanQueue(int(self.get_parameter('max_queued_requests').value))
        self._refused_logged = 0
        self.status.set(max_queued_requests=self.queue.depth, requests_refused_queue_full=0,
                        requests_timed_out_waiting=0, plans_abandoned=0)
        service_qos = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                 reliability=ReliabilityPolicy.RELIABLE,
                                 durability=DurabilityPolicy.VOLATILE)
        plans = ReentrantCallbackGroup()
        self.plan_srv = self.create_service(GetPlan, '~/plan', self._on_plan,
                                            qos_profile=service_qos, callback_group=plans)
        self.plan_trajectory_srv = self.create_service(
            PlanTrajectory, '~/plan_trajectory', self._on_plan_trajectory,
            qos_profile=service_qos, callback_group=plans)
        self.sequence = SequenceService(self, self._serve, service_qos, plans)
        # The URDF as robot_state_publisher publishes it (used while the robot parameter is empty).
        self.description_sub = self.create_subscription(
            String, self._description_topic, self._on_robot_description,
            QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self.scene = SceneServices(
            self, self._update_collision, lambda: self._config.collision if self._config else None,
            lambda: list(self.get_parameter('package_dirs').value or []),
            lambda: self._config.frame_id if self._config else 'base_link')
        self.sensor_maps = SensorMaps(
            self, node_sensors(self), self._update_collision,
            lambda: (c.collision, c.frame_id) if (c := self._config) is not None and c.collision is not None else None,
            lambda: self.current_joints(self._config.joint_names) if self._config is not None else None,
            self.warnings)
        if self.sensor_maps.sensors and not self.get_parameter('collision_check').value:
            raise ConfigError('point_cloud_topics: the clouds need collision_check true')
        self.scene.maps = self.sensor_maps
        self.scene.publish_markers()
        services = ', '.join(map(self.resolve_service_name, ('~/plan_trajectory', '~/plan_sequence', '~/plan')))
        c = self._config
        if c is None:
            self.get_logger().info(f'robot parameter empty: waiting for the URDF on '
                                   f'{self._description_topic}; serving {services}')
        else:
            self.get_logger().info(
                f"robot '{c.robot.name}' ({c.robot.dof} joints {list(c.joint_names)}), base frame "
                f"'{c.frame_id}', metric {self.get_parameter('metric').value}, velocity_scaling "
                f'{c.velocity_scaling:g}; serving {services}')

    # ------------------------------------------------------------------ parameters
    def _parameter_values(self, changes: list[Parameter] | tuple[()] = ()) -> dict[str, Any]:
        values = {name: self.get_parameter(name).value for name in PLANNER_PARAMETERS}
        for p in changes:
            if p.name in values:
                values[p.name] = p.value
        return values

    def _build(self, values: dict[str, Any], previous: PlannerConfig | None) -> PlannerConfig | None:
        """A configuration for ``values``; None while the model must come from /robot_description
        and has not arrived. Logs the configuration's notes (limits) when they change.

        Raises:
            ConfigError: an invalid value (the message names the parameter).
        """
        if not str(values['robot']).strip() and not str(values['robot_description']).strip():
            if not self._topic_description:
                for name in PLANNER_PARAMETERS:   # still check every value on its own
                    reason = params.problem(name, values[name])
                    if reason is not None:
                        raise ConfigError(reason)
                return None
            values = dict(values, robot_description=self._topic_description)
        config = build_config(values, previous)
        if previous is None or config.notes != previous.notes:
            for note in config.notes:
                self.get_logger().warning(note)
        return config

    def _update_collision(self, change: Callable[[CollisionModel], CollisionModel]) -> CollisionModel:
        """Apply a scene change to the configuration's collision model (in one step)."""
        with self._config_lock:
            config = self._config
            if config is None or config.collision is None:
                raise ConfigError('no scene: ' + ('no robot model yet' if config is None else
                                                  'the collision_check parameter is false'))
            model = change(config.collision)
            self._config = replace(config, collision=model)
            return model

    def _on_robot_description(self, msg: String) -> None:
        text = msg.data
        values = self._parameter_values()
        if str(values['robot']).strip() or str(values['robot_description']).strip():
            self._topic_description = text
            self.get_logger().info(f'{self._description_topic}: URDF received ({len(text)} '
                                   'characters), not used: the robot parameter is set')
            return
        with self._config_lock:
            old = self._topic_description
            self._topic_description = text
            try:
                self._config = self._build(values, self._config)
            except ConfigError as err:
                self._topic_description = old
                self.get_logger().error(f'{self._description_topic}: URDF refused, keeping the '
                                        f'current model: {err}')
                return
            except Exception as err:  # noqa: BLE001 - boundary: never let a callback crash the node
                self._topic_description = old
                self.get_logger().error(f'{self._description_topic}: internal error: '
                                        f'{type(err).__name__}: {err}')
                return
        c = self._config
        assert c is not None
        self.get_logger().info(
            f"robot '{c.robot.name}' from {self._description_topic} ({c.robot.dof} joints "
            f"{list(c.joint_names)}), base frame '{c.frame_id}'")

    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        ours = [p for p in changes if p.name in PLANNER_PARAMETERS]
        if not ours:
            return SetParametersResult(successful=True)
        reason = params.rejection(ours, PLANNER_PARAMETERS)
        if reason is None and any(p.name == 'collision_check' and p.value is False for p in ours) \
                and self.sensor_maps.sensors:
            reason = 'collision_check: must stay true while point_cloud_topics are configured'
        if reason is None:
            with self._config_lock:
                try:
                    self._config = self._build(self._parameter_values(ours), self._config)
                except ConfigError as err:
                    reason = str(err)
                except Exception as err:  # noqa: BLE001 - boundary: never let a callback crash the node
                    self.get_logger().error(f'internal error: {type(err).__name__}: {err}')
                    reason = f'internal error: {type(err).__name__}: {err}'
        if reason is not None:
            self.get_logger().warning(f'parameter update rejected: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        names = ', '.join(f'{p.name}={quoted(p.value) if isinstance(p.value, str) else p.value!r}'
                          for p in ours if p.name != 'robot_description')
        self.get_logger().info(f'parameters updated: {names or "robot_description"}')
        self.scene.publish_markers()
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ joint states
    def start_state_thread(self) -> None:
        """Serve /joint_states from a thread of its own (ros/joint_states.py)."""
        self.joint_states.start()

    def destroy_node(self) -> None:
        """Stop the state thread, then destroy both nodes."""
        self.joint_states.destroy()
        super().destroy_node()

    def current_joints(self, names: tuple[str, ...]) -> np.ndarray | None:
        """Latest valid joint state for ``names`` (None if none, or if it was read for other names)."""
        return self.joint_states.current(names)

    # ------------------------------------------------------------------ service
    def _on_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> GetPlan.Response:
        """nav_msgs/GetPlan (compatibility, unchanged): every successful plan is published; the
        reply holds only the tool path (no poses on failure, the reason is logged); an explicit
        start pose is solved from the home seed and not checked against the joint state."""
        t0 = time.perf_counter()
        stamp = self.get_clock().now().to_msg()
        config = self._config
        response.plan = Path(header=Header(frame_id=config.frame_id if config else '', stamp=stamp))
        outcome = self._serve(lambda c: (get_plan_request(c, request), None, None), True, stamp, t0,
                              check_start=False)
        if outcome.result is not None:
            response.plan = outcome.result.path
        return response

    def _on_plan_trajectory(self, request: PlanTrajectory.Request,
                            response: PlanTrajectory.Response) -> PlanTrajectory.Response:
        """geodesic_planner_interfaces/PlanTrajectory: error code, reason, trajectory and tool
        path in the reply; published only when ``execute`` is true."""
        t0 = time.perf_counter()
        stamp = self.get_clock().now().to_msg()
        outcome = self._serve(lambda c: plan_trajectory_request(c, request), bool(request.execute),
                              stamp, t0)
        response.error_code = PlanErrorCode(val=outcome.code)
        response.message = outcome.message
        response.planning_time = time.perf_counter() - t0
        result = outcome.result
        response.fraction = 1.0 if result is not None else outcome.fraction
        response.min_clearance = math.nan
        if result is not None:
            response.trajectory = result.trajectory
            response.tool_path = result.path
            response.solver_method = result.solver_method
            response.path_error = result.path_error
            response.blend_deviation = list(result.blend_deviation)
            response.min_clearance = result.min_clearance
            response.ik_branch = result.ik_branch
        return response

    def _serve(self, parse: Callable[[PlannerConfig], tuple[PlanRequest, float | None, float | None]],
               execute: bool, stamp: Time, t0: float, check_start: bool = True) -> Outcome:
        """Parse, plan (bounded by ``plan_timeout``), publish if ``execute``; log the outcome.

        ``check_start``: seed an explicit start's IK with the joint state and check the plan's
        first point against it (PlanTrajectory); False keeps GetPlan's behaviour.
        """
        stale = ''
        try:
            config = self._config
            if config is None:
                raise ConfigError(f'no robot model yet: the robot parameter is empty and no URDF has '
                                  f'arrived on {self._description_topic}')
            request, fv, fa = parse(config)
            stale = self.sensor_maps.check(config.collision)      # StaleMapError: refused
            current_q = self.current_joints(config.joint_names)
            if not check_start and (request.start is not None or request.start_joints is not None):
                current_q = None
            ticket = self.queue.enter()
            if ticket is None:
                return self._refuse()
            if not self.queue.wait_turn(ticket, config.plan_timeout):
                self.status.set(requests_timed_out_waiting=self.queue.timed_out)
                raise PlanTimeoutError(
                    f'timed out after {config.plan_timeout:g} s waiting for the requests ahead of '
                    'it (plan_timeout)')
            try:     # its turn: one plan at a time; the plan's own plan_timeout starts now
                outcome = self._plan(config, request, current_q, fv, fa, execute, stamp)
            finally:
                self.queue.leave(ticket)
        except GeodesicPlannerError as err:
            outcome = Outcome.failure(err)
        except Exception as err:  # noqa: BLE001 - boundary: answer and keep serving
            outcome = Outcome(PlanErrorCode.PLANNING_FAILED, f'internal error: {type(err).__name__}: {err}')
        total_ms = (time.perf_counter() - t0) * 1e3
        result = outcome.result
        if stale and result is not None:
            self.warnings.warn('stale clouds', stale)
            outcome = replace(outcome, message=f'{stale}; {outcome.message}')
        if result is None:
            self.plan_log.flush()
            self.get_logger().error(f'plan failed ({CODE_NAMES.get(outcome.code, outcome.code)}, '
                                    f'{total_ms:.1f} ms): {outcome.message}')
            return outcome
        self.path_markers.offer(result.tool_poses, result.path.header.frame_id)
        # its own line, or counted in a summary while other requests wait (ros/plan_log.py)
        self.plan_log.success(result, outcome.published, total_ms, busy=self.queue.inside > 0)
        return outcome

    def _refuse(self) -> Outcome:
        """Answer a request the queue cannot take: counted, on /diagnostics, logged rate-limited."""
        refused = self.queue.refused
        self.status.set(requests_refused_queue_full=refused)
        if self.warnings.due('overload'):
            self.get_logger().warning(
                f'planner overloaded: refused {refused - self._refused_logged} request(s) since the '
                f'last report ({refused} since start): {self.queue.depth} already queued or planning '
                '(max_queued_requests)')
            self._refused_logged = refused
        return Outcome(PlanErrorCode.PLANNING_FAILED,
                       f'planner overloaded: {self.queue.depth} requests already queued or planning '
                       '(max_queued_requests); refused without planning, try again later')

    def _plan(self, config: PlannerConfig, request: PlanRequest, current_q: np.ndarray | None,
              velocity_factor: float | None, acceleration_factor: float | None, execute: bool,
              stamp: Time) -> Outcome:
        """Plan through the :class:`~.admission.PlanWorker` (at most ``plan_timeout`` s), publish
        if ``execute``; an abandoned plan is cancelled and never published."""
        def compute(commit: Callable[[Callable[[], object]], bool]) -> PlanResult:
            def publish(msg: JointTrajectory) -> bool:
                if not execute:
                    return True
                self._await_subscriptions()
                return commit(lambda: self.trajectory_pub.publish(msg))
            return compute_plan(config, request, current_q, stamp, publish,
                                velocity_factor=velocity_factor, acceleration_factor=acceleration_factor)

        try:
            run = self.worker.run(compute, config.plan_timeout)
        except WorkerBusyError as busy:
            raise PlanTimeoutError(f'planner busy: {busy}') from None
        if run.abandoned:
            self._abandoned += 1
            self.status.set(plans_abandoned=self._abandoned)
            return Outcome(PlanErrorCode.TIMED_OUT,
                           f'timed out after {config.plan_timeout:g} s (plan_timeout); the '
                           f'computation is cancelled and its result discarded '
                           f'({self._abandoned} so far)')
        err = run.error
        if isinstance(err, GeodesicPlannerError):
            return Outcome.failure(err)
        if err is not None:
            after = ' (after publishing the trajectory)' if run.committed else ''
            return Outcome(PlanErrorCode.PLANNING_FAILED,
                           f'internal error{after}: {type(err).__name__}: {err}')
        return Outcome(PlanErrorCode.SUCCESS, '', run.result, run.committed)

    def _stopped(self, seconds: float) -> None:
        """An abandoned plan ended ``seconds`` after its cancellation (diagnostics, log)."""
        ms = seconds * 1e3
        self._stop_ms_max = max(self._stop_ms_max, ms)
        self.status.set(abandoned_plan_stop_ms_last=f'{ms:.1f}',
                        abandoned_plan_stop_ms_max=f'{self._stop_ms_max:.1f}')
        self.get_logger().info(f'abandoned plan stopped {ms:.1f} ms after its cancellation')


def main(args: list[str] | None = None) -> int:
    """Console script ``geodesic_planner_node``: spin until SIGINT/SIGTERM.

    See :mod:`geodesic_planner.ros.runtime` for the shutdown order (running callbacks get up to
    2 s to finish).

    Returns:
        0 after a signal (also one that arrives while starting), 1 when the parameters or the
        robot model are invalid at start (one error line, no traceback).
    """
    with runtime.stop_on_signals() as stop:
        if not runtime.init(NODE_NAME, args):
            return 1
        node = None
        executor = None
        try:
            node = GeodesicPlannerNode()
            # a thread per queued request plus three: one always free to take (and refuse) the
            # next request, the parameter services, the /robot_description subscription
            executor = MultiThreadedExecutor(num_threads=node.queue.depth + 3 + bool(node.sensor_maps.sensors))
            executor.add_node(node)
            guard = runtime.UniqueNameGuard(node, stop, lambda state: node.status.set(name_check=state))
            node.start_state_thread()
            runtime.spin_until(stop, executor, node.get_logger())
            if guard.refusal is not None:
                return 1
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
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
