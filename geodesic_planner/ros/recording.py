"""The ``trajectory_processor`` node's bag: which topics, the recorder, the write failures.

:class:`BagRecording` reads ``record_topics``, opens a new bag
(:class:`geodesic_planner.io.bags.BagRecorder`), subscribes the other recorded topics raw (best
effort, keep_all), learns the types of topics named without one from the ROS graph, writes every
message with the node's clock, reports write failures (log, rate-limited, and ``/diagnostics``)
and closes the bag with the summary line. What is recorded, and when, is described in
:mod:`geodesic_planner.ros.processor_node` ("Recording").
"""
from __future__ import annotations

import functools
import importlib
import threading
import time
from typing import Any

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import NameValidationException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.timer import Timer
from trajectory_msgs.msg import JointTrajectory

from ..io.bags import JOINT_STATE, JOINT_TRAJECTORY, BagRecorder, make_typestore, new_bag_path, to_cdr
from ..core.errors import BagError, ConfigError, GeodesicPlannerError
from .diagnostics import NodeStatus
from .matching import log_messages_lost, log_publishers_matched

JOINT_STATES_TOPIC = '/joint_states'
KNOWN_TYPES = {JOINT_STATES_TOPIC: JOINT_STATE}
FAILURE_LOG_PERIOD = 1.0  # s, at most one bag write failure line per period


class _FailureLog:
    """Bag write failures for people: the first one at once, then at most one line per period.

    Every failure is counted; the lines in between are summed into the next one (or into the
    one :meth:`tick` writes once the period is over). Thread-safe: the recorder reports the
    failures of its background flushes from its own thread.
    """

    def __init__(self, node: Node, period: float = FAILURE_LOG_PERIOD) -> None:
        self._logger = node.get_logger()
        self._period = period
        self._lock = threading.Lock()
        self._last = -float('inf')
        self._held = 0
        self._held_text = ''
        self.total = 0

    def report(self, text: str) -> None:
        """One failure (``text`` says what and why)."""
        with self._lock:
            self.total += 1
            now = time.monotonic()
            if now - self._last < self._period:
                self._held += 1
                self._held_text = text
                return
            self._last, held, self._held = now, self._held, 0
        more = f' (and {held} more since the last report)' if held else ''
        self._logger.error(f'bag write failure: {text}{more}')

    def tick(self) -> None:
        """Write the failures held back, once the period since the last line is over."""
        with self._lock:
            now = time.monotonic()
            if not self._held or now - self._last < self._period:
                return
            self._last, held, text, self._held = now, self._held, self._held_text, 0
        self._logger.error(f'bag write failure: {held} more since the last report, the last: {text}')


class BagRecording:
    """What the node records: the recorder, its failure log, the raw subscriptions, type discovery.

    ``node`` is the recording node (its parameters ``record_topics``, ``bag_path``, ``storage``,
    its clock, log and graph); ``name`` goes into the bag's name and metadata (``recorded_by``);
    ``input_topic`` and ``output_topic`` are the node's resolved trajectory topics. Nothing is
    recorded before :meth:`start`. ``callbacks`` counts the messages given to :meth:`record`
    (the node's shutdown drain watches it).
    """

    def __init__(self, node: Node, status: NodeStatus, name: str, input_topic: str, output_topic: str) -> None:
        self._node = node
        self._status = status
        self._name = name
        self.input_topic = input_topic
        self.output_topic = output_topic
        self._typestore = make_typestore()
        self.callbacks = 0
        self.recorder: BagRecorder | None = None
        self.failure_log = _FailureLog(node)
        self._failure_timer: Timer | None = None
        self._extra_subs: dict[str, Any] = {}
        self._pending_types: list[str] = []
        self._discovery_timer: Timer | None = None

    def _resolve(self, topic: str) -> str:
        try:
            return self._node.resolve_topic_name(topic)
        except (NameValidationException, ValueError, RuntimeError) as err:
            msg = f'invalid topic name in record_topics: {topic!r} ({err})'
            raise ConfigError(msg) from err

    def parse_record_topics(self) -> tuple[dict[str, str], dict[str, str], list[str]]:
        """record_topics -> (own trajectory topics, other typed topics, topics of unknown type).

        Raises:
            ConfigError: bad topic name, unknown message type, wrong type for input/output.
        """
        topics: dict[str, str] = {}
        extra: dict[str, str] = {}
        pending: list[str] = []
        for entry in self._node.get_parameter('record_topics').value:
            name, _, msgtype = entry.replace('=', ':', 1).partition(':')
            topic = self._resolve(name)
            if topic in (self.input_topic, self.output_topic):
                if msgtype and msgtype != JOINT_TRAJECTORY:
                    msg = f'record_topics: {topic} is a {JOINT_TRAJECTORY} topic, not {msgtype}'
                    raise ConfigError(msg)
                topics[topic] = JOINT_TRAJECTORY
            elif msgtype or topic in KNOWN_TYPES:
                extra[topic] = msgtype or KNOWN_TYPES[topic]
                if extra[topic] not in self._typestore.fielddefs:
                    msg = f'record_topics: unknown message type {extra[topic]!r} for {topic}'
                    raise ConfigError(msg)
            elif topic not in pending:
                pending.append(topic)
        return topics, extra, pending

    def start(self) -> None:
        """Open a new bag under ``bag_path`` and subscribe the other recorded topics.

        Raises:
            ConfigError: bad ``record_topics``, a message type not available in Python.
            BagError: the bag cannot be created.
        """
        node = self._node
        base = node.get_parameter('bag_path').value
        storage = node.get_parameter('storage').value
        topics, extra, self._pending_types = self.parse_record_topics()
        path = new_bag_path(base, prefix=self._name)
        custom = {'recorded_by': self._name, 'input_topic': self.input_topic,
                  'output_topic': self.output_topic}
        for name in ('sample_period', 'velocity_scaling'):  # values at start (they may change later)
            custom[name] = repr(float(node.get_parameter(name).value))
        self.recorder = BagRecorder(path, storage=storage, topics={**topics, **extra},
                                    typestore=self._typestore, custom_data=custom,
                                    on_error=self.failure_log.report)
        self.recorder.open()
        self._status.set(bag_write_failures=0, bag_messages_lost=0)
        self._failure_timer = node.create_timer(FAILURE_LOG_PERIOD, self._report_failures)
        where = path if str(path) == str(base) else f'{path} ({base} exists, not overwritten)'
        node.get_logger().info(f'recording {", ".join(self.recorder.topics)} to {where} [{storage}]')
        for topic, msgtype in extra.items():
            self._subscribe_raw(topic, msgtype)
        if self._pending_types:
            pending = ', '.join(self._pending_types)
            node.get_logger().info(f'waiting for publishers to learn the types of {pending}')
            self._discovery_timer = node.create_timer(0.5, self._discover_types)

    def _subscribe_raw(self, topic: str, msgtype: str) -> None:
        pkg, _, name = msgtype.partition('/msg/')
        try:
            cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
        except (ImportError, AttributeError) as err:
            msg = f'cannot record {topic}: message type {msgtype} not available in Python ({err})'
            raise ConfigError(msg) from err
        # Best effort matches reliable and best-effort publishers, whenever they appear.
        events = SubscriptionEventCallbacks(
            matched=functools.partial(log_publishers_matched, self._node, topic),
            message_lost=functools.partial(log_messages_lost, self._node, topic))
        qos = QoSProfile(depth=10, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.BEST_EFFORT,
                         durability=DurabilityPolicy.VOLATILE)
        self._extra_subs[topic] = self._node.create_subscription(
            cls, topic, functools.partial(self.record, topic), qos, event_callbacks=events, raw=True)

    def _discover_types(self) -> None:
        types = dict(self._node.get_topic_names_and_types())
        for topic in list(self._pending_types):
            found = types.get(topic)
            if not found:
                continue
            msgtype = found[0]
            self._pending_types.remove(topic)
            try:
                assert self.recorder is not None
                self.recorder.add_topic(topic, msgtype)
                self._subscribe_raw(topic, msgtype)
                self._node.get_logger().info(f'recording {topic} [{msgtype}]')
            except GeodesicPlannerError as err:
                self._node.get_logger().error(f'cannot record {topic}: {err}')
        if not self._pending_types and self._discovery_timer is not None:
            self._discovery_timer.cancel()

    def _now_ns(self) -> int:
        return self._node.get_clock().now().nanoseconds

    def record(self, topic: str, data: bytes) -> None:
        """Record one message received on ``topic`` (raw CDR), if that topic is recorded."""
        self.callbacks += 1
        if self.recorder is None or topic not in self.recorder.topics:
            return
        self._write(topic, data)

    def record_output(self, msg: JointTrajectory) -> None:
        """Record the node's published output as its exact CDR, if the output topic is recorded."""
        if self.recorder is not None and self.output_topic in self.recorder.topics:
            self._write(self.output_topic, to_cdr(msg, JOINT_TRAJECTORY, self._typestore))

    def _write(self, topic: str, data: bytes) -> None:
        """Record one message; a failure is reported (rate-limited) and counted, never raised."""
        assert self.recorder is not None
        try:
            self.recorder.write(topic, self._now_ns(), data)
        except BagError as err:
            self.failure_log.report(str(err))
            self._report_failures()

    def _report_failures(self) -> None:
        """Held-back failure lines to the log, failure counts to /diagnostics."""
        self.failure_log.tick()
        recorder = self.recorder
        if recorder is not None:
            self._status.set(bag_write_failures=recorder.failures,
                             bag_messages_lost=sum(recorder.lost.values()))

    def close(self, summary: str) -> None:
        """Finish the bag (metadata written) and log what it holds, then ``summary``. Idempotent.

        The closing line's counts are what the storage file holds, also after write failures
        (then summarised in the same line) or when the bag could not be finished.
        """
        recorder, self.recorder = self.recorder, None
        if recorder is None:
            return
        if self._failure_timer is not None:
            self._failure_timer.cancel()
        state = 'bag closed'
        logger = self._node.get_logger()
        try:
            recorder.close()
        except BagError as err:
            logger.error(str(err))
            state = 'bag NOT finished (repair it)'
        self.failure_log.tick()
        on_disk = recorder.counts
        counts = ', '.join(f'{t}: {n}' for t, n in on_disk.items())
        failures = ''
        if recorder.failures:
            lost = ', '.join(f'{t}: {n}' for t, n in recorder.lost.items()) or 'none'
            failures = (f'; bag write failures {recorder.failures}, not recorded: {lost} '
                        f'(last error: {recorder.last_error})')
        log = logger.error if state != 'bag closed' or recorder.failures else logger.info
        log(f'{state}: {recorder.path} ({sum(on_disk.values())} messages; {counts}); {summary}{failures}')
