"""ROS 2 node ``trajectory_processor``: resample and slow down planned trajectories, record a bag.

Interface (``~`` = ``/trajectory_processor`` by default):

* subscription ``input_topic`` (trajectory_msgs/JointTrajectory, default
  ``/geodesic_planner/joint_trajectory``), reliable, volatile, **keep_all**, ``raw=True``: the
  exact CDR bytes are recorded first, then decoded with
  ``rclpy.serialization.deserialize_message``. keep_all rather than keep_last 10: with a depth of
  10, a burst of 30 trajectories lost 19 in the reader queue before the node saw them; with
  keep_all a reliable publisher is flow-controlled instead (nothing dropped). A publisher whose
  QoS cannot match (best effort) is logged as a warning. Other recorded topics (``/joint_states``
  ...) are subscribed raw, keep_all, **best effort**: that matches reliable and best-effort
  publishers alike (sensor data is usually published best effort). ("Best available" was decided
  once, when the subscription was created: with no publisher yet it became reliable, and a
  best-effort ``/joint_states`` publisher started later was never recorded.)
* publisher ``output_topic`` (default ``~/joint_trajectory``, remap it to a controller),
  reliable, volatile, depth 10: the input resampled every ``sample_period`` s and slowed down by
  ``velocity_scaling`` f (times / f, velocities * f, accelerations * f**2, same path), positions,
  velocities and accelerations at every point, last point exactly at the (scaled) end; header
  copied from the input. See :mod:`geodesic_planner.timing.resample` for the interpolation.
* the log says ``input TOPIC: N publisher(s) matched`` (also for other recorded topics) when a
  subscription matches publishers: a volatile reader receives only what is published after it
  has itself matched the writer (Fast DDS drops earlier samples even when the writer already saw
  the reader); the same count is on ``/diagnostics`` (``input publishers matched``), which scripts
  wait on before the first plan (logs are for people); lost messages reported by the rmw are
  logged as errors.
* an invalid input (what joint_trajectory_controller would reject: empty/duplicate joint names,
  no points, wrong sizes, non-finite values, non-increasing ``time_from_start``) is logged as an
  error naming the cause, recorded as received, and not published. The node keeps going.
* the output is bounded before anything of its size is allocated: an input whose processed form
  would have more than ``max_output_points`` points, or more than 16 x ``max_output_points``
  joint values per field (many joints), is refused the same way (``rejected trajectory: output
  too large: ...`` with the numbers), and counted in ``rejected`` and ``rejected too large``.
* the output is checked by the same validator as the input
  (:func:`geodesic_planner.timing.validate.trajectory_problems`) before it is published: an
  input that passes but whose interpolation is not finite (positions of +-1e308 overflow) is
  refused (``rejected trajectory: output would be invalid: ...``). Nothing invalid is published.

Parameters (:data:`geodesic_planner.ros.params.PROCESSOR_PARAMETERS`, from the schema shared with
the planner node): ``input_topic``, ``output_topic``, ``bag_path``, ``storage``,
``record_topics`` are read-only (fixed at start); ``sample_period`` (s, > 0),
``velocity_scaling`` ((0, 1]) and ``max_output_points`` (integer > 0, default 100000) may be
changed at run time, invalid values are rejected with a reason (``<name>: <problem>``). An
``input_topic`` that resolves (remappings applied) to the ``output_topic`` is refused at start:
the node would process its own output forever.

Recording (``bag_path`` non-empty): a new rosbag2 directory per run, never an existing one
(:func:`geodesic_planner.io.bags.new_bag_path`: an existing non-empty ``bag_path`` gets a timestamped
bag inside or next to it; the log says where). ``record_topics`` (default: input, output,
``/joint_states``) may name other topics as ``name`` (type taken from the ROS graph once a
publisher appears) or ``name=pkg/msg/Type`` (``name:pkg/msg/Type`` works too, but needs quotes
inside a YAML list on the command line). Input and other topics are recorded as the raw bytes
received; the node's own output as the exact CDR of the published message (rosbags
serialisation; ``serialize_message`` would pad empty arrays). Timestamps are receive/publish
times of the node's clock. Data reach the file at least every 0.5 s (see
:mod:`geodesic_planner.io.bags.recorder`): after SIGKILL ``geodesic-bag repair`` recovers all but the last
0.5 s. On SIGINT/SIGTERM the node takes every message already delivered to it (processing
the backlog for up to 2 s, then recording the rest raw without processing, see :func:`_drain`),
closes the bag (metadata written) and exits with 0. The closing log line gives the counts:
``received N, published P, rejected R, recorded unprocessed at shutdown U`` (N = P + R + U), and
the per-topic counts are what the storage file holds. When the bag cannot be written (disk
full), every failure is logged (the first at once, then at most one line per second with the
count since the last one), counted on ``/diagnostics`` (``bag write failures``, ``bag messages
lost``), and summarised in the closing line (``bag write failures F, not recorded: topic: n``);
the bag then holds N - (inputs not recorded) inputs and P - (outputs not recorded) outputs,
and ``metadata.yaml`` says so. (See :mod:`geodesic_planner.io.bags.recorder`; the node's side is
:mod:`geodesic_planner.ros.recording`.)

Executor model: one SingleThreadedExecutor, spun by ``spin_once`` in the main thread; callbacks
(input, recorded topics, parameter services) therefore never run concurrently and the recorder
sees one writer (it is thread-safe anyway for its own flush thread). Signals only set a flag;
see :func:`main` for the shutdown order. An unexpected exception while processing an input is
logged as an internal error and the input counted as rejected (it is already recorded); the
node keeps going.
"""
from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import NameValidationException, ParameterException
from rclpy.event_handler import (QoSMessageLostInfo, QoSRequestedIncompatibleQoSInfo, QoSSubscriptionMatchedInfo,
                                  SubscriptionEventCallbacks)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from trajectory_msgs.msg import JointTrajectory

from ..core.errors import ConfigError, GeodesicPlannerError
from ..timing.resample import process_trajectory, sample_count
from ..timing.validate import trajectory_problems
from .conversions import arrays_to_joint_trajectory, joint_trajectory_to_arrays, validate_joint_trajectory
from . import params, runtime
from .diagnostics import NodeStatus
from .matching import log_messages_lost, log_publishers_matched, matched_logger, wait_for_matched_subscriptions
from .params import PROCESSOR_PARAMETERS
from .recording import JOINT_STATES_TOPIC, BagRecording

NODE_NAME = 'trajectory_processor'
DRAIN_TIMEOUT = 2.0  # s spent at shutdown processing messages already received
RECORD_DRAIN_TIMEOUT = 5.0  # s more at shutdown recording (without processing) the remaining ones
#: The value bound: an output may hold OUTPUT_JOINTS x max_output_points joint values per field.
OUTPUT_JOINTS = 16

def _qos(reliability: ReliabilityPolicy = ReliabilityPolicy.RELIABLE, *, keep_all: bool = False) -> QoSProfile:
    """Volatile QoS, depth 10; ``keep_all`` for subscriptions whose every message must be recorded."""
    history = HistoryPolicy.KEEP_ALL if keep_all else HistoryPolicy.KEEP_LAST
    return QoSProfile(depth=10, history=history, reliability=reliability,
                      durability=DurabilityPolicy.VOLATILE)


class TrajectoryProcessorNode(params.SchemaNode):
    """The ``trajectory_processor`` node (see the module docstring).

    Raises:
        ConfigError: invalid parameter values or topic names at start (as the planner's).
        BagError: the bag cannot be created.
    """

    def __init__(self, **kwargs: Any) -> None:  # noqa: ANN401 rclpy Node options, passed through
        super().__init__(NODE_NAME, **kwargs)
        # Registered before declaring: initial overrides (-p ...) are validated too.
        self.add_on_set_parameters_callback(self._on_set_parameters)
        # record_topics is declared below: its default needs the resolved topic names.
        params.declare(self, [n for n in PROCESSOR_PARAMETERS if n != 'record_topics'])
        params.check_unknown(self, PROCESSOR_PARAMETERS)   # a mistyped name: a warning, later refused
        self._lock = threading.Lock()
        self.received = 0
        self.published = 0
        self.rejected = 0
        self.unprocessed = 0
        self.too_large = 0
        #: set at shutdown once DRAIN_TIMEOUT is spent: inputs are recorded, not processed
        self.record_only = False

        self.status = NodeStatus(self)
        self.status.set(input_publishers_matched=0, output_subscriptions_matched=0,
                        received=0, published=0, rejected=0, rejected_too_large=0)
        try:
            input_topic = self.get_parameter('input_topic').value
            output_topic = self.get_parameter('output_topic').value
            if self.resolve_topic_name(input_topic) == self.resolve_topic_name(output_topic):
                msg = (f'input_topic {input_topic!r} and output_topic {output_topic!r} are the same topic '
                       f'{self.resolve_topic_name(output_topic)}: the processor would process its own output')
                raise ConfigError(msg)
            events = SubscriptionEventCallbacks(matched=self._on_input_matched,
                                                message_lost=self._on_input_lost,
                                                incompatible_qos=self._on_input_incompatible)
            self.input_sub = self.create_subscription(
                JointTrajectory, input_topic, self._on_input, _qos(keep_all=True),
                event_callbacks=events, raw=True)
            self.output_pub = self.create_publisher(
                JointTrajectory, output_topic, _qos(),
                event_callbacks=matched_logger(
                    self, f'output {self.resolve_topic_name(output_topic)}',
                    on_count=lambda n: self.status.set(output_subscriptions_matched=n)))
        except (ValueError, TypeError, RuntimeError, NameValidationException) as err:
            msg = f'invalid topic name: {err}'
            raise ConfigError(msg) from err
        self.input_topic = self.input_sub.topic_name
        self.output_topic = self.output_pub.topic_name

        default_record = [self.input_topic, self.output_topic, JOINT_STATES_TOPIC]
        params.declare(self, ['record_topics'], {'record_topics': default_record})

        self.bag = BagRecording(self, self.status, NODE_NAME, self.input_topic, self.output_topic)
        if self.get_parameter('bag_path').value:
            self.bag.start()
        else:
            self.bag.parse_record_topics()  # validated even when recording is off
        self.get_logger().info(
            f'processing {self.input_topic} -> {self.output_topic}: sample_period '
            f'{float(self.get_parameter("sample_period").value):g} s, velocity_scaling '
            f'{float(self.get_parameter("velocity_scaling").value):g}')

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, changes: list[Parameter]) -> SetParametersResult:
        reason = params.rejection(changes, PROCESSOR_PARAMETERS)
        if reason is not None:
            self.get_logger().warning(f'parameter update rejected: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def close_bag(self) -> None:
        """Finish the bag (metadata written) and log what it holds and the node's counts. Idempotent.

        See :meth:`geodesic_planner.ros.recording.BagRecording.close` for the closing line.
        """
        self.bag.close(f'received {self.received}, published {self.published}, rejected {self.rejected}, '
                       f'recorded unprocessed at shutdown {self.unprocessed}')

    # ------------------------------------------------------------------ processing
    def _on_input_matched(self, status: QoSSubscriptionMatchedInfo) -> None:
        # A volatile reader gets only what is published after *it* matched the writer, and only
        # this node knows when that is: the count goes to /diagnostics for scripts to wait on.
        log_publishers_matched(self, f'input {self.input_topic}', status)
        self.status.set(input_publishers_matched=status.current_count)

    def _on_input_lost(self, status: QoSMessageLostInfo) -> None:
        log_messages_lost(self, f'input {self.input_topic}', status)

    def _on_input_incompatible(self, status: QoSRequestedIncompatibleQoSInfo) -> None:
        self.get_logger().warning(
            f'input {self.input_topic}: {status.total_count_change} publisher(s) with incompatible QoS '
            f'(policy id {status.last_policy_kind}; the input is reliable): their messages are not received')

    def _on_input(self, raw: bytes) -> None:
        self.received += 1
        self.bag.record(self.input_topic, raw)
        if self.record_only:
            self.unprocessed += 1
            return
        try:
            self._process(raw)
        except Exception as err:  # noqa: BLE001 - boundary: one bad input never ends the node
            self.rejected += 1
            self.get_logger().error(f'rejected trajectory: internal error: {type(err).__name__}: {err}')
        self.status.set(received=self.received, published=self.published, rejected=self.rejected,
                        rejected_too_large=self.too_large)

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self.get_logger().error(f'rejected trajectory: {reason}')

    def _too_large(self, t: np.ndarray, dof: int, f: float, dt: float) -> str | None:
        """Why the output would exceed max_output_points (None: it fits); nothing allocated."""
        limit = int(self.get_parameter('max_output_points').value)
        span = float(t[-1] - t[0]) / f  # s, slowed down (inf on overflow)
        points = sample_count(span, dt)       # what resample.sample_times will give (inf if dt is tiny)
        if not points <= limit:
            return (f'output too large: {span:.6g} s at sample_period {dt:g} s (velocity_scaling {f:g}) '
                    f'would be up to {points:.6g} points, max_output_points is {limit}')
        if points * dof > OUTPUT_JOINTS * limit:
            return (f'output too large: {points:.0f} points x {dof} joints = {points * dof:.6g} values per '
                    f'field, more than {OUTPUT_JOINTS} x max_output_points = {OUTPUT_JOINTS * limit}')
        return None

    def _process(self, raw: bytes) -> None:
        """Decode, validate, resample, publish and record one input (already recorded raw)."""
        try:
            msg = deserialize_message(raw, JointTrajectory)
        except Exception as err:  # noqa: BLE001  (rmw deserialisation errors are not typed)
            self._reject(f'cannot deserialize {len(raw)} bytes: {err}')
            return
        problems = validate_joint_trajectory(msg)
        if problems:
            more = f' (+{len(problems) - 5} more)' if len(problems) > 5 else ''
            self._reject(f'{"; ".join(problems[:5])}{more}')
            return
        f = float(self.get_parameter('velocity_scaling').value)
        dt = float(self.get_parameter('sample_period').value)
        arrays = joint_trajectory_to_arrays(msg)
        too_large = self._too_large(arrays.t, len(arrays.joint_names), f, dt)
        if too_large is not None:
            self.too_large += 1
            self._reject(too_large)
            return
        try:
            with np.errstate(over='ignore', invalid='ignore'):  # non-finite results are refused below
                t, q, dq, ddq = process_trajectory(
                    arrays.t, arrays.positions, arrays.velocities, arrays.accelerations, sample_period=dt,
                    velocity_scaling=f, max_samples=int(self.get_parameter('max_output_points').value))
        except GeodesicPlannerError as err:
            self._reject(str(err))
            return
        problems = trajectory_problems(arrays.joint_names, t, q, dq, ddq)  # the input's validator
        if problems:
            more = f' (+{len(problems) - 5} more)' if len(problems) > 5 else ''
            self._reject(f'output would be invalid: {"; ".join(problems[:5])}{more}')
            return
        out = arrays_to_joint_trajectory(arrays.joint_names, t, q, dq, ddq, frame_id=msg.header.frame_id)
        out.header.stamp = msg.header.stamp
        wait_for_matched_subscriptions(self, self.output_pub)
        self.output_pub.publish(out)
        self.published += 1
        self.bag.record_output(out)
        span_in = arrays.t[-1] - arrays.t[0]
        self.get_logger().info(
            f'received trajectory: {arrays.t.size} points, {span_in:.3g} s -> published {t.size} points, '
            f'{t[-1] - t[0]:.3g} s (velocity_scaling {f:g}, sample_period {dt:g} s)')


def main(args: list[str] | None = None) -> int:
    """Console script ``trajectory_processor_node``: spin until SIGINT/SIGTERM, then close the bag.

    Shutdown order (as in the planner node): SIGINT/SIGTERM only set a flag (Python handlers,
    installed before ``rclpy.init``; rclpy's own handlers, which shut the context down at once,
    are not installed), so a signal never interrupts a callback or a bag write half-way. The
    spin loop then stops within 0.1 s, messages already delivered are taken and recorded
    (:func:`_drain`), the bag is closed (metadata written), the executor is shut down, the
    node's entities are destroyed while the context is still valid, and only then is rclpy shut
    down. (Destroying subscriptions after the context was shut down by rclpy's handler crashed,
    rarely, in ``destroy_subscription`` after load.) ``kill -USR1 <pid>`` dumps every thread's
    stack to stderr (faulthandler).

    Returns:
        0 on a clean exit (signal, also one that arrives while starting), 1 when the parameters
        are invalid or the bag cannot be created (one ``cannot start`` line, no traceback).
    """
    with runtime.stop_on_signals() as stop:
        if not runtime.init(NODE_NAME, args):
            return 1
        return _run(stop)


def _drain(node: TrajectoryProcessorNode, executor: SingleThreadedExecutor) -> None:
    """At shutdown: take every message already delivered to the node's readers, so it is recorded.

    A reliable publisher counts a message as delivered once it is in the node's reader queue
    (keep_all), so a backlog there must reach the bag too. The backlog is processed and
    published as usual for up to DRAIN_TIMEOUT s; what is left after that is only recorded (raw,
    as received; counted as "recorded unprocessed"), for up to RECORD_DRAIN_TIMEOUT s more.
    Draining stops as soon as a 0.05 s spin finds nothing.
    """
    start = time.monotonic()
    while rclpy.ok():
        before = node.received + node.bag.callbacks
        executor.spin_once(timeout_sec=0.05)
        if node.received + node.bag.callbacks == before:
            return
        elapsed = time.monotonic() - start
        if not node.record_only and elapsed >= DRAIN_TIMEOUT:
            node.record_only = True
            node.get_logger().warning(
                f'shutdown: still receiving after {DRAIN_TIMEOUT:g} s of processing; recording the '
                'remaining inputs without processing them')
        if elapsed >= DRAIN_TIMEOUT + RECORD_DRAIN_TIMEOUT:
            node.get_logger().warning(
                f'shutdown: inputs still arriving after {DRAIN_TIMEOUT + RECORD_DRAIN_TIMEOUT:g} s; '
                'closing the bag (later messages are not recorded)')
            return


def _run(stop: threading.Event) -> int:
    """Create the node, spin until ``stop`` is set, drain, close the bag, tear down in order."""
    node: TrajectoryProcessorNode | None = None
    executor: SingleThreadedExecutor | None = None
    rc = 0
    try:
        node = TrajectoryProcessorNode()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        status = node.status
        guard = runtime.UniqueNameGuard(node, stop, lambda state: status.set(name_check=state))
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        if guard.refusal is not None:
            rc = 1
        else:
            node.get_logger().info('shutting down (signal received)')
        _drain(node, executor)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (GeodesicPlannerError, ParameterException) as err:
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {err}')
        rc = 1
    except OSError as err:  # the bag path (permissions, ...) when not already a BagError
        rclpy.logging.get_logger(NODE_NAME).error(f'cannot start: {err}')
        rc = 1
    finally:
        if node is not None:
            try:
                node.close_bag()
            except Exception as err:  # noqa: BLE001 - never skip the teardown below
                node.get_logger().error(f'closing the bag failed: {type(err).__name__}: {err}')
                rc = rc or 1
        if executor is not None:
            executor.shutdown(timeout_sec=2.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return rc


if __name__ == '__main__':
    raise SystemExit(main())
