"""The planner's ``/joint_states`` listener: the latest valid joint state, taken off the plan path.

``/joint_states`` (up to hundreds of Hz) is taken by a hidden node of its own, spun by an
EventsExecutor in a thread of its own (:meth:`JointStateListener.start`): a state message never
waits behind a plan, and it costs the plan executor nothing. The hidden node takes no global
arguments (a ``__node`` remap must not rename it too), so the topic is resolved by the owner, with
the user's remappings. Its (empty) parameter services stay: a client's round trip with them is how
a tool knows the node has matched its endpoints (tools/graph.py).

A message must name every robot joint exactly once with a finite position (any order, extra joints
ignored); else it is ignored with a warning per kind of problem, rate-limited
(:class:`~geodesic_planner.core.errors.JointStateError`), and the last valid state is kept.
"""
from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from ..core.errors import JointStateError
from . import conversions as cv

__all__ = ['JointStateListener', 'RateLimitedWarnings']


class RateLimitedWarnings:
    """Warnings at most once per ``period`` s per kind (the first one at once)."""

    def __init__(self, logger: Any, period: float = 2.0) -> None:  # noqa: ANN401 an rclpy logger
        self._logger, self._period = logger, period
        self._last: dict[str, float] = {}

    def due(self, kind: str) -> bool:
        """True (and the kind's clock restarted) when a warning of ``kind`` may be logged now."""
        now = time.monotonic()
        if now - self._last.get(kind, -math.inf) >= self._period:
            self._last[kind] = now
            return True
        return False

    def warn(self, kind: str, text: str) -> None:
        """Log ``text`` if a warning of ``kind`` is due."""
        if self.due(kind):
            self._logger.warning(text)


class JointStateListener:
    """The latest valid joint state of the robot, from ``topic``, in chain order.

    Args:
        owner: the planner node (its context, name, namespace and logger).
        topic: the resolved ``/joint_states`` topic.
        joint_names: returns the current configuration's joint names (None: no robot yet).
        warnings: where rejected messages are reported.
    """

    def __init__(self, owner: Node, topic: str, joint_names: Callable[[], tuple[str, ...] | None],
                 warnings: RateLimitedWarnings) -> None:
        self._owner, self._joint_names, self._warnings = owner, joint_names, warnings
        self._state: tuple[np.ndarray, tuple[str, ...]] | None = None
        self.node = Node(f'_{owner.get_name()}_joint_states', namespace=owner.get_namespace(),
                         context=owner.context, use_global_arguments=False)
        self.subscription = self.node.create_subscription(
            JointState, topic, self._on_message,
            QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE))
        self._executor: Executor | None = None     # an EventsExecutor (a factory function)
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def start(self) -> None:
        """Spin the hidden node in a thread of its own."""
        self._executor = EventsExecutor(context=self._owner.context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name='joint_states', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        executor = self._executor
        assert executor is not None
        while self._owner.context.ok() and not self._stop.is_set():
            try:
                executor.spin_once(timeout_sec=0.1)
            except ExternalShutdownException:
                return
            except Exception as err:  # noqa: BLE001 - boundary: one bad message never ends the thread
                if not self._owner.context.ok():
                    return
                self._owner.get_logger().error(f'/joint_states: internal error: {type(err).__name__}: {err}')

    def destroy(self) -> None:
        """Stop, join and shut down the thread's executor (never while it spins), then the node."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self._executor is not None and (self._thread is None or not self._thread.is_alive()):
            self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()

    def _on_message(self, msg: JointState) -> None:
        names = self._joint_names()
        if names is None:
            return
        try:
            q = cv.joint_state_to_vector(msg, names)
        except JointStateError as err:
            self._warnings.warn(err.kind, f'ignoring /joint_states message: {err}')
            return
        except Exception as err:  # noqa: BLE001 - boundary
            self._warnings.warn('internal', f'ignoring /joint_states message: internal error: '
                                f'{type(err).__name__}: {err}')
            return
        self._state = (q, names)

    def current(self, names: tuple[str, ...]) -> np.ndarray | None:
        """Latest valid joint state for ``names`` (None if none, or if it was read for other names)."""
        state = self._state
        if state is None or state[1] != names:
            return None
        return state[0]
