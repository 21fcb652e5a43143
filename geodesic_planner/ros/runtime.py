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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Protocol

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

#: For how long after start a node looks for another node of its own name, s; finding one in this
#: time makes it refuse to start (exit code 1). Discovery on one host takes well under a second.
NAME_CHECK_WINDOW = 3.0


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
    """Refuses to run a node whose name another node in the graph already has.

    Two planners of one name would both plan and publish every request. For
    :data:`NAME_CHECK_WINDOW` s after start the node checks the graph every 0.25 s; a second node
    of its fully qualified name then means this node is the newcomer: it logs one error, sets
    ``refusal`` and ``stop`` (its ``main`` exits with code 1). Later (one started elsewhere, or
    both at once) it warns every 5 s while the graph shows more than one. ``on_state`` gets
    'checking', 'unique' or 'duplicate' (for /diagnostics).
    """

    def __init__(self, node: Node, stop: threading.Event,
                 on_state: Callable[[str], object] = lambda _state: None,
                 window: float = NAME_CHECK_WINDOW) -> None:
        self.refusal: str | None = None
        self._node = node
        self._stop = stop
        self._on_state = on_state
        self._window = window
        self._t0 = time.monotonic()
        self._ticks = 0
        self._state = ''
        self._set_state('checking')
        self._timer = node.create_timer(0.25, self._check)

    def _set_state(self, state: str) -> None:
        if state != self._state:
            self._state = state
            self._on_state(state)

    def _check(self) -> None:
        self._ticks += 1
        early = time.monotonic() - self._t0 <= self._window
        if not early and self._state != 'duplicate' and self._ticks % 20:
            return                                    # after the window: every 5 s
        node = self._node
        name, ns = node.get_name(), node.get_namespace()
        count = sum(1 for n, s in node.get_node_names_and_namespaces() if n == name and s == ns)
        full = node.get_fully_qualified_name()
        if count <= 1:
            self._set_state('checking' if early else 'unique')
            return
        if early and self.refusal is None:
            self.refusal = (f'another node named {full} is already running ({count} in the graph): '
                            'refusing to start (two nodes of one name would both serve every '
                            'request); give this one another name or namespace')
            node.get_logger().error(f'cannot start: {self.refusal}')
            self._set_state('duplicate')
            self._stop.set()
        elif not early and self._ticks % 20 == 0:
            node.get_logger().warning(
                f'{count} nodes named {full} in the graph: each of them serves every request to '
                'this name; stop all but one')
            self._set_state('duplicate')
