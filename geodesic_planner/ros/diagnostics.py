"""A node's state on ``/diagnostics`` (diagnostic_msgs/DiagnosticArray), for people and programs.

Each node keeps one :class:`NodeStatus`: named values (endpoint matches, request counters) that it
publishes as one ``DiagnosticStatus`` named after the node (``/geodesic_planner``), whenever a
value changes and at least every ``period`` s, as ``diagnostic_updater`` does. rqt_runtime_monitor
and the diagnostic aggregator show it; scripts and tests wait on it instead of reading logs (for
example until the processor's input has matched the planner's publisher, which no graph query
tells: ``input publishers matched``).
"""
from __future__ import annotations

import threading

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

TOPIC = '/diagnostics'
OK, WARN, ERROR = DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR


class NodeStatus:
    """The node's named values, published on ``/diagnostics`` on change and every ``period`` s.

    Thread-safe: callbacks and worker threads may call :meth:`set`.
    """

    def __init__(self, node: Node, period: float = 1.0) -> None:
        self._node = node
        self._name = node.get_fully_qualified_name()
        self._lock = threading.Lock()
        self._values: dict[str, str] = {}
        self._level = OK
        self._message = 'ok'
        self._publisher = node.create_publisher(
            DiagnosticArray, TOPIC, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
        self._timer = node.create_timer(period, self.publish)

    def set(self, level: bytes | None = None, message: str | None = None, **values: object) -> None:
        """Change values (and optionally the level and summary message), then publish if anything changed."""
        with self._lock:
            new = {key.replace('_', ' '): str(value) for key, value in values.items()}
            changed = any(self._values.get(k) != v for k, v in new.items())
            self._values.update(new)
            if level is not None and level != self._level:
                self._level, changed = level, True
            if message is not None and message != self._message:
                self._message, changed = message, True
        if changed:
            self.publish()

    def publish(self) -> None:
        """Publish the current status now."""
        with self._lock:
            values = [KeyValue(key=k, value=v) for k, v in self._values.items()]
            status = DiagnosticStatus(level=self._level, name=self._name, message=self._message,
                                      hardware_id='', values=values)
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self._node.get_clock().now().to_msg()
        try:
            self._publisher.publish(msg)
        except Exception as err:  # noqa: BLE001 - a closing context must not break the caller
            self._node.get_logger().debug(f'diagnostics not published: {err}')
