"""The planner's log line per plan, and one summary per second instead while requests wait.

One ``plan: ...`` line per successful plan is what people read when they plan one motion at a
time. Under load (other requests waiting when a plan is done) a line per plan is a flood nobody
reads, and it is not free: rclpy's logger looks its caller up in the source files on every call
(``inspect.getframeinfo`` and ``os.path.realpath``: about 40 file-system calls), 0.5-0.9 ms of CPU
per line on the development machine, 5-8 % of what the node spends on a plan. So while requests
wait, successful plans are counted instead and :class:`PlanLog` writes one ``plans: ...`` summary
at most every ``period`` s, and always before the next ``plan:`` line, so that every plan is in
a line: its own or a summary's; :meth:`PlanLog.flush_due` (the node's 1 s timer) writes the last
one when no plan follows. Failures always get their own error line, after the pending summary.
"""
from __future__ import annotations

import math
import threading
import time
from typing import Any, Protocol

__all__ = ['PlanLog']


class Logger(Protocol):
    """What :class:`PlanLog` needs of an rclpy logger."""

    def info(self, message: str) -> object:
        """Log ``message`` at info severity."""


class PlanLog:
    """Plan lines for ``logger``: one per plan, or a summary per ``period`` s while busy.

    Thread-safe: plans are reported from the executor's threads, :meth:`flush_due` from a timer.
    """

    def __init__(self, logger: Logger, period: float = 1.0) -> None:
        self._logger, self._period = logger, period
        self._lock = threading.Lock()
        self._since = time.monotonic()       # start of the plans counted in the pending summary
        self._request_ms: list[float] = []
        self._points: list[int] = []
        self._path_error = 0.0
        self._clearance = math.inf

    def success(self, result: Any, published: bool, request_ms: float, busy: bool) -> None:  # noqa: ANN401
        """Log a successful plan (``PlanResult``): its own line unless ``busy`` (requests are
        waiting), then counted for the summary, written once ``period`` s have passed."""
        with self._lock:
            now = time.monotonic()
            if not busy:
                self._flush(now)
                self._logger.info(plan_line(result, published, request_ms))
                return
            if not self._request_ms:
                self._since = now
            self._request_ms.append(request_ms)
            self._points.append(int(result.points))
            self._path_error = max(self._path_error, float(result.path_error))
            if not math.isnan(result.min_clearance):
                self._clearance = min(self._clearance, float(result.min_clearance))
            if now - self._since >= self._period:
                self._flush(now)

    def flush(self) -> None:
        """Write the pending summary now, if any plan is counted in it (before a failure's line)."""
        with self._lock:
            self._flush(time.monotonic())

    def flush_due(self) -> None:
        """Write the pending summary if its first plan is ``period`` s old (from a timer)."""
        with self._lock:
            now = time.monotonic()
            if now - self._since >= self._period:
                self._flush(now)

    def _flush(self, now: float) -> None:
        if not self._request_ms:
            return
        ms = sorted(self._request_ms)
        clearance = f', clearance >= {self._clearance:.3g} m' if math.isfinite(self._clearance) else ''
        self._logger.info(
            f'plans: {len(ms)} in {now - self._since:.2f} s while requests waited (one line each '
            f'when none wait): request p50 {ms[len(ms) // 2]:.1f} ms, max {ms[-1]:.1f} ms; '
            f'{min(self._points)}-{max(self._points)} points; path error up to '
            f'{self._path_error:.2g} m{clearance}')
        self._request_ms, self._points = [], []
        self._path_error, self._clearance = 0.0, math.inf


def plan_line(result: Any, published: bool, request_ms: float) -> str:  # noqa: ANN401
    """The ``plan: ...`` line of one successful plan (``PlanResult``)."""
    blends = (f', blend deviation up to {max(result.blend_deviation):.2g} m'
              if result.blend_deviation else '')
    return (f'plan: {result.points} points, {result.duration:.2f} s, '
            f'{"published" if published else "not published (execute: false)"}, solver '
            f'{result.solver_method} ({result.solver_iterations} it, {result.mesh_size} nodes), '
            f'{result.solver_ms:.1f} ms, path error {result.path_error:.2g} m{blends}, clearance '
            f'{result.min_clearance:.3g} m (request '
            f'{request_ms:.1f} ms: ' + ', '.join(f'{k} {v:.1f}' for k, v in result.stage_ms.items()) + ')')
