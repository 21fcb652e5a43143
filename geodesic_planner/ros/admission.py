"""Admission and order of plan requests: a bounded queue that refuses visibly when full.

The planner node serves its plan services from a pool of executor threads. Each request takes a
ticket on arrival (:meth:`PlanQueue.enter`): at most ``depth`` requests may hold one (waiting or
planning); beyond that the request is refused at once, and the refusal is counted, so that work
the node cannot take is answered and visible instead of piling up unseen in DDS. Ticket holders
plan one at a time, in arrival order (:meth:`PlanQueue.wait_turn`); one that waits longer than its
deadline gives its turn up and is answered as timed out. No ROS here: plain threads.
"""
from __future__ import annotations

import threading


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
        self._cond = threading.Condition()
        self._next = 0          # next ticket to hand out
        self._serving = 0       # ticket whose turn it is
        self._given_up: set[int] = set()
        self._inside = 0
        self.refused = 0        # requests refused because the queue was full, since start
        self.peak = 0           # largest number of requests inside at once

    @property
    def inside(self) -> int:
        """Requests holding a ticket now (waiting or planning)."""
        with self._cond:
            return self._inside

    def enter(self) -> int | None:
        """A ticket, or None when ``depth`` requests are already inside (counted in ``refused``)."""
        with self._cond:
            if self._inside >= self.depth:
                self.refused += 1
                return None
            self._inside += 1
            self.peak = max(self.peak, self._inside)
            ticket = self._next
            self._next += 1
            return ticket

    def wait_turn(self, ticket: int, timeout: float) -> bool:
        """Wait until it is ``ticket``'s turn (True), or give the turn up after ``timeout`` s (False)."""
        with self._cond:
            if self._cond.wait_for(lambda: self._serving == ticket, timeout):
                return True
            self._given_up.add(ticket)
            self._inside -= 1
            return False

    def leave(self, ticket: int) -> None:
        """``ticket`` is done: the next request still waiting gets its turn."""
        with self._cond:
            if ticket != self._serving:
                raise RuntimeError(f'ticket {ticket} left out of turn (serving {self._serving})')
            self._inside -= 1
            self._serving += 1
            while self._serving in self._given_up:
                self._given_up.discard(self._serving)
                self._serving += 1
            self._cond.notify_all()
