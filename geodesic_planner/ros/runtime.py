"""Process plumbing shared by both nodes' ``main``: signals, rclpy start-up, the spin loop.

SIGINT/SIGTERM only set a flag (Python handlers; rclpy's own handlers, which shut the context
down at once, are not installed), so a signal never interrupts a callback, a publish or a bag
write half-way. The spin loop stops within 0.1 s of the flag; the caller then shuts the executor
down (running callbacks get a bounded time), destroys the node while the context is still valid,
and only then shuts rclpy down.
"""
from __future__ import annotations

import faulthandler
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Protocol

import rclpy
from builtin_interfaces.msg import Time
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import Header

#: For how long after start a node checks the graph for namesakes every 0.25 s ('checking' on
#: /diagnostics), s; after it, every 5 s. Discovery on one host takes well under a second.
NAME_CHECK_WINDOW = 3.0
#: Hidden topic (relative to the node) on which every node of a name claims it with its start time.
CLAIM_TOPIC = '~/_name_claim'


@contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT/SIGTERM while the block runs (previous handlers restored after).

    ``kill -USR1 <pid>`` dumps every thread's stack to stderr meanwhile (faulthandler).
    """
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    faulthandler.enable()                                     # stacks on a fatal signal
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    try:
        yield stop
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def init(node_name: str, args: list[str] | None) -> bool:
    """``rclpy.init`` without rclpy's signal handlers.

    Returns:
        False (after one ``cannot start`` line on stderr) when rcl rejects the arguments, e.g. a
        ``-p`` value it cannot parse.
    """
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as err:  # noqa: BLE001 - boundary: rcl's errors have no public type
        print(f'[ERROR] [{node_name}]: cannot start: {err}', file=sys.stderr)
        return False
    return True


class ErrorLogger(Protocol):
    """What :func:`spin_until` needs of a logger (``node.get_logger()``)."""

    def error(self, message: str) -> object:
        """Log ``message`` at error severity."""


def spin_until(stop: threading.Event, executor: Executor, logger: ErrorLogger) -> None:
    """Spin until ``stop`` is set or rclpy shuts down.

    An exception escaping a callback (the executor re-raises it here) is logged and the node
    keeps serving: one bad request or message never ends it.
    """
    while not stop.is_set() and rclpy.ok():
        try:
            executor.spin_once(timeout_sec=0.1)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as err:  # noqa: BLE001 - boundary: the node keeps serving
            logger.error(f'internal error: {type(err).__name__}: {err}')


class UniqueNameGuard:
    """Two nodes of one name never both keep serving: the younger one stops, the older one serves.

    Two planners of one name would both plan and publish every request. Each node publishes a
    claim on the hidden topic ``~/_name_claim`` (std_msgs/Header; reliable, transient local, so
    a namesake discovered at any later time still receives it): ``stamp`` is the node's start
    time (system clock) and ``frame_id`` a random id of the instance. Every node of the name also
    reads the claims. On a claim of another instance, the younger of the two (later stamp; equal
    stamps: the larger id) logs one error line, sets ``refusal`` and ``stop`` (its ``main`` exits
    with code 1); the older logs that the newcomer will stop and keeps serving. This holds
    whenever discovery brings the two together: at start-up or minutes later. ``start_ns``
    (default: now, ``time.time_ns()``) is the start time claimed.

    The graph is also watched (every 0.25 s for :data:`NAME_CHECK_WINDOW` s, then every 5 s):
    ``on_state`` gets 'checking' (start-up window), 'unique' or 'duplicate' (for /diagnostics),
    and a namesake that publishes no claim (another program) is warned about every 5 s.
    """

    def __init__(self, node: Node, stop: threading.Event,
                 on_state: Callable[[str], object] = lambda _state: None,
                 window: float = NAME_CHECK_WINDOW, start_ns: int | None = None) -> None:
        self.refusal: str | None = None
        self._node = node
        self._stop = stop
        self._on_state = on_state
        self._window = window
        self._t0 = time.monotonic()
        self._ticks = 0
        self._state = ''
        self._was_unique = False
        self._seen: set[str] = set()       # ids of the namesakes' claims received
        if start_ns is None:
            start_ns = time.time_ns()
        self._claim = Header(stamp=Time(sec=start_ns // 1_000_000_000, nanosec=start_ns % 1_000_000_000),
                             frame_id=uuid.uuid4().hex)
        qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self._set_state('checking')
        self._subscription = node.create_subscription(Header, CLAIM_TOPIC, self._on_claim, qos)
        self._publisher = node.create_publisher(Header, CLAIM_TOPIC, qos)
        self._publisher.publish(self._claim)
        self._timer = node.create_timer(0.25, self._check)

    @property
    def instance_id(self) -> str:
        """This node's random id (the tie-break between equal start times)."""
        return self._claim.frame_id

    @property
    def namesakes_seen(self) -> int:
        """Other nodes of this name whose claims this one has received."""
        return len(self._seen)

    def _set_state(self, state: str) -> None:
        self._was_unique = self._was_unique or state == 'unique'
        if state != self._state:
            self._state = state
            self._on_state(state)

    def _on_claim(self, other: Header) -> None:
        mine = self._claim
        if other.frame_id == mine.frame_id or other.frame_id in self._seen or self.refusal is not None:
            return
        self._seen.add(other.frame_id)
        key = (mine.stamp.sec, mine.stamp.nanosec, mine.frame_id)
        theirs = (other.stamp.sec, other.stamp.nanosec, other.frame_id)
        full = self._node.get_fully_qualified_name()
        self._set_state('duplicate')
        if key > theirs:
            # 'cannot start' until the node has once found itself alone (its start-up is over);
            # by the graph, not the clock: under load a claim can arrive after the window
            started = 'stopping' if self._was_unique else 'cannot start'
            self.refusal = (f'another node named {full} is already running (started '
                            f'{_seconds_between(theirs, key):.3f} s before this one): two nodes of '
                            'one name would both serve every request; give this one another name '
                            'or namespace')
            self._node.get_logger().error(f'{started}: {self.refusal}')
            self._stop.set()
        else:
            self._node.get_logger().warning(
                f'a second node named {full} started {_seconds_between(key, theirs):.3f} s after '
                'this one: it stops, this one keeps serving')

    def _check(self) -> None:
        self._ticks += 1
        early = time.monotonic() - self._t0 <= self._window
        if not early and self._ticks % 20:
            return                                    # after the window: every 5 s
        node = self._node
        name, ns = node.get_name(), node.get_namespace()
        count = sum(1 for n, s in node.get_node_names_and_namespaces() if n == name and s == ns)
        if count <= 1:
            self._set_state('checking' if early else 'unique')
            return
        self._set_state('duplicate')
        self._publisher.publish(self._claim)   # again: a reader may have missed the history
        claims = self._publisher.get_subscription_count()   # our namesakes read the claims
        if not early and claims < count and self.refusal is None:
            node.get_logger().warning(
                f'{count} nodes named {node.get_fully_qualified_name()} in the graph, '
                f'{count - claims} of them not a geodesic_planner node: each of them serves every '
                'request to this name; stop all but one')


def _seconds_between(older: tuple[int, int, str], younger: tuple[int, int, str]) -> float:
    """Seconds from the ``older`` claim's stamp to the ``younger`` one's."""
    return (younger[0] - older[0]) + (younger[1] - older[1]) * 1e-9
