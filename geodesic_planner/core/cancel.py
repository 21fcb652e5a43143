"""Cooperative cancellation: a computation given up from outside stops at its next checkpoint.

A node that abandons a plan (its ``plan_timeout`` passed) cannot kill the thread computing it;
instead it sets the plan's :class:`CancelToken`, and the library, which calls :func:`checkpoint`
at bounded intervals (every IK round, every evaluation of the geodesic solver, every mesh
refinement round, every timing pass, every thousand trajectory points), raises
:class:`Cancelled` there. The token reaches the checkpoints through a context variable set by
:func:`cancellable`, so no signature between the node and the loops has to carry it; code run
outside a :func:`cancellable` block is never cancelled, and a checkpoint then costs one lookup.

:class:`Cancelled` derives from ``BaseException`` (as ``asyncio.CancelledError`` does), so the
``except Exception`` of a fallback or a boundary does not swallow it.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar


class Cancelled(BaseException):
    """The computation was cancelled through its :class:`CancelToken` (the message says why)."""


class CancelToken:
    """Set once from any thread (:meth:`cancel`); read at every :func:`checkpoint` of the work.

    Attributes:
        cancelled_at: ``time.monotonic()`` of the :meth:`cancel` call, None before.
    """

    def __init__(self) -> None:
        self._event = threading.Event()
        self.reason = ''
        self.cancelled_at: float | None = None

    @property
    def cancelled(self) -> bool:
        """True once :meth:`cancel` was called."""
        return self._event.is_set()

    def cancel(self, reason: str = 'cancelled') -> None:
        """Ask the computation to stop at its next checkpoint (later calls change nothing)."""
        if not self._event.is_set():
            self.reason = reason
            self.cancelled_at = time.monotonic()
            self._event.set()


_current: ContextVar[CancelToken | None] = ContextVar('geodesic_planner_cancel_token', default=None)


@contextmanager
def cancellable(token: CancelToken) -> Iterator[CancelToken]:
    """Run the block with ``token`` checked by every :func:`checkpoint` (in this thread)."""
    reset = _current.set(token)
    try:
        yield token
    finally:
        _current.reset(reset)


def checkpoint() -> None:
    """Raise :class:`Cancelled` if the current computation's token was cancelled."""
    token = _current.get()
    if token is not None and token.cancelled:
        raise Cancelled(token.reason)
