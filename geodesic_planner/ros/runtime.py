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
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Protocol

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.signals import SignalHandlerOptions


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
