"""Admission, order and bounded time of plan requests: a queue that refuses visibly when full,
and a worker that gives a plan up at its deadline and stops it.

The planner node serves its plan services from a pool of executor threads. Each request takes a
ticket on arrival (:meth:`PlanQueue.enter`): at most ``depth`` requests may hold one (waiting or
planning); beyond that the request is refused at once, and the refusal is counted, so that work
the node cannot take is answered and visible instead of piling up unseen in DDS. Ticket holders
plan one at a time, in arrival order (:meth:`PlanQueue.wait_turn`); one that waits longer than its
deadline gives its turn up and is answered as timed out.

The holder of the turn plans through :meth:`PlanWorker.run`: the computation runs in the worker's
thread (one, kept for the node's life: its per-thread scratch buffers, :func:`~geodesic_planner.core.compiled.scratch`,
serve every plan), and the caller waits at most its timeout. A computation still running then is abandoned:
its :class:`~geodesic_planner.core.cancel.CancelToken` is cancelled, so it stops at its next
checkpoint, and whatever it would still commit (publish) is refused. The next run first waits
for that worker to end, at most ``stop_wait`` s, so one pathological request costs the next one
its cancellation time, never its whole timeout. No ROS here: plain threads.
"""
from __future__ import annotations

import queue
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

from ..core.cancel import CancelToken, cancellable

T = TypeVar('T')


class PlanQueue:
    """At most ``depth`` requests inside (waiting or planning); one plans at a time, in order.

    Thread-safe. Use ``ticket = enter()`` (None: full, refuse), then ``wait_turn(ticket, s)``
    (False: deadline passed, the turn was given up; do not call ``leave``), then ``leave(ticket)``
    when the request is done with the planner.
    """

    def __init__(self, depth: int) -> None:
        if depth < 1:
            raise ValueError(f'queue depth must be >= 1, got {depth}')
        self.depth = depth
        self._lock = threading.Lock()
        self._turns: dict[int, threading.Event] = {}   # waiting ticket -> set when its turn comes
        self._next = 0          # next ticket to hand out
        self._serving = 0       # ticket whose turn it is
        self._given_up: set[int] = set()
        self._inside = 0
        self.refused = 0        # requests refused because the queue was full, since start
        self.timed_out = 0      # requests that gave their turn up at their deadline, since start
        self.peak = 0           # largest number of requests inside at once

    @property
    def inside(self) -> int:
        """Requests holding a ticket now (waiting or planning)."""
        with self._lock:
            return self._inside

    def enter(self) -> int | None:
        """A ticket, or None when ``depth`` requests are already inside (counted in ``refused``)."""
        with self._lock:
            if self._inside >= self.depth:
                self.refused += 1
                return None
            self._inside += 1
            self.peak = max(self.peak, self._inside)
            ticket = self._next
            self._next += 1
            return ticket

    def wait_turn(self, ticket: int, timeout: float) -> bool:
        """Wait until it is ``ticket``'s turn (True), or give the turn up after ``timeout`` s (False).

        Each waiter waits on an event of its own, set by :meth:`leave` when its turn comes: a
        finished plan wakes the next request only, not every waiting one.
        """
        with self._lock:
            if self._serving == ticket:
                return True
            turn = self._turns[ticket] = threading.Event()
        if turn.wait(timeout):
            return True
        with self._lock:
            self._turns.pop(ticket, None)
            if self._serving == ticket:        # the turn came as the wait ended: take it
                return True
            self._given_up.add(ticket)
            self._inside -= 1
            self.timed_out += 1
            return False

    def leave(self, ticket: int) -> None:
        """``ticket`` is done: the next request still waiting gets its turn."""
        with self._lock:
            if ticket != self._serving:
                raise RuntimeError(f'ticket {ticket} left out of turn (serving {self._serving})')
            self._inside -= 1
            self._serving += 1
            while self._serving in self._given_up:
                self._given_up.discard(self._serving)
                self._serving += 1
            turn = self._turns.pop(self._serving, None)
        if turn is not None:
            turn.set()


class WorkerBusyError(RuntimeError):
    """An abandoned computation has not stopped within ``stop_wait`` s (the next run refused)."""


@dataclass(frozen=True)
class Run(Generic[T]):
    """What one :meth:`PlanWorker.run` came to.

    Attributes:
        result: the computation's return value (None if it raised or was abandoned).
        error: what it raised (None on success or when abandoned).
        abandoned: the timeout passed before it ended and before it committed anything.
        committed: a ``commit`` of the computation went through (e.g. it published).
    """

    result: T | None
    error: BaseException | None
    abandoned: bool
    committed: bool


class PlanWorker:
    """Runs one computation at a time in a worker thread, abandoned and cancelled at a timeout.

    ``compute(commit)`` gets a ``commit(action) -> bool`` that runs ``action`` (e.g. a publish)
    unless the run was abandoned, atomically with abandoning: an abandoned run never commits,
    and a run that committed is not abandoned (its caller waits for the rest of it).
    ``on_stopped(seconds)`` is called from an abandoned run's worker when it ends, with the time
    from its cancellation to its end.
    """

    def __init__(self, stop_wait: float, on_stopped: Callable[[float], object] = lambda _s: None) -> None:
        self.stop_wait = stop_wait
        self._on_stopped = on_stopped
        self._running = threading.Lock()   # taken before a computation starts, released as it ends
        self._commit = threading.Lock()    # "commit" and "abandon" exclude each other
        self._jobs: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None   # started by the first run

    def _serve(self) -> None:
        """The worker thread: runs the computations handed to it, one at a time, forever (daemon)."""
        while True:
            job = self._jobs.get()
            try:
                job()
            except Exception:  # noqa: BLE001 - an on_stopped that raised: reported, the thread serves on
                traceback.print_exc()

    def _start(self) -> None:
        if self._thread is None or not self._thread.is_alive():
            thread = threading.Thread(target=self._serve, name='geodesic_plan', daemon=True)
            thread.start()
            self._thread = thread

    def run(self, compute: Callable[[Callable[[Callable[[], object]], bool]], T], timeout: float) -> Run[T]:
        """Run ``compute`` in a worker, waiting at most ``timeout`` s for it (see the class).

        Raises:
            WorkerBusyError: the previous, abandoned run has not ended within ``stop_wait`` s.
        """
        if not self._running.acquire(timeout=self.stop_wait):
            raise WorkerBusyError(f'a plan abandoned earlier has not stopped within {self.stop_wait:g} s')
        box: dict[str, object] = {}
        state = {'abandoned': False, 'committed': False}
        done = threading.Event()
        token = CancelToken()

        def commit(action: Callable[[], object]) -> bool:
            with self._commit:
                if state['abandoned']:
                    return False
                action()
                state['committed'] = True
                return True

        def work() -> None:
            try:
                with cancellable(token):
                    box['result'] = compute(commit)
            except BaseException as err:  # noqa: BLE001 - handed to the caller (or dropped if abandoned)
                box['error'] = err
            finally:
                try:
                    if token.cancelled_at is not None:
                        self._on_stopped(time.monotonic() - token.cancelled_at)
                finally:      # even when on_stopped raises: the next run must not wait for this one
                    self._running.release()
                    done.set()

        try:
            self._start()
        except BaseException:
            self._running.release()
            raise
        self._jobs.put(work)
        if not done.wait(timeout):
            with self._commit:
                state['abandoned'] = not state['committed']
                if state['abandoned']:
                    token.cancel(f'abandoned after {timeout:g} s')
            if state['abandoned']:
                return Run(None, None, True, False)
            done.wait()   # it committed: the rest is bounded work without a solver
        err = box.get('error')
        return Run(box.get('result'), err if isinstance(err, BaseException) else None,  # type: ignore[arg-type]
                   False, state['committed'])
