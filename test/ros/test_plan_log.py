"""The planner's plan lines (ros.plan_log): one per plan when none waits, else a summary per
period; every plan is in a line, and a summary comes before the next plan line or failure."""
from __future__ import annotations

import math
import time
from types import SimpleNamespace

from geodesic_planner.ros.plan_log import PlanLog, plan_line


class Lines:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def info(self, message: str) -> None:
        self.lines.append(message)


def result(points: int = 50, path_error: float = 1e-9, clearance: float = 0.2) -> SimpleNamespace:
    return SimpleNamespace(points=points, duration=0.5, solver_method='pullback', solver_iterations=3,
                           mesh_size=33, solver_ms=1.0, path_error=path_error, blend_deviation=(),
                           min_clearance=clearance, stage_ms={'plan': 1.5, 'timing': 0.8})


def test_one_line_per_plan_when_none_waits() -> None:
    out = Lines()
    log = PlanLog(out)
    log.success(result(), True, 6.0, busy=False)
    log.success(result(points=70), False, 7.0, busy=False)
    assert out.lines == [plan_line(result(), True, 6.0), plan_line(result(points=70), False, 7.0)]
    assert out.lines[0].startswith('plan: 50 points, 0.50 s, published, solver pullback')
    assert '(request 6.0 ms: plan 1.5, timing 0.8)' in out.lines[0]
    assert 'not published (execute: false)' in out.lines[1]


def test_busy_plans_are_summarised_before_the_next_plan_line() -> None:
    out = Lines()
    log = PlanLog(out, period=3600.0)
    for i, (points, err, clearance) in enumerate([(40, 1e-9, 0.3), (60, 2e-8, 0.1), (50, 1e-9, math.nan)]):
        log.success(result(points, err, clearance), True, 10.0 + i, busy=True)
    assert out.lines == []                              # within the period: counted only
    log.success(result(), True, 5.0, busy=False)        # none waits: the summary, then its own line
    assert len(out.lines) == 2 and out.lines[1].startswith('plan: 50 points')
    summary = out.lines[0]
    assert summary.startswith('plans: 3 in ')
    assert 'request p50 11.0 ms, max 12.0 ms; 40-60 points; path error up to 2e-08 m, clearance >= 0.1 m' in summary
    log.flush()                                         # nothing pending: nothing written
    assert len(out.lines) == 2


def test_a_summary_per_period_and_the_last_one_from_the_timer() -> None:
    out = Lines()
    log = PlanLog(out, period=0.05)
    log.success(result(), True, 5.0, busy=True)
    log.flush_due()
    assert out.lines == []                              # not yet a period old
    time.sleep(0.06)
    log.success(result(), True, 5.0, busy=True)         # a period after the first: written
    assert len(out.lines) == 1 and out.lines[0].startswith('plans: 2 in ')
    log.success(result(), True, 5.0, busy=True)
    time.sleep(0.06)
    log.flush_due()                                     # no plan follows: the timer writes it
    assert len(out.lines) == 2 and out.lines[1].startswith('plans: 1 in ')


def test_flush_before_a_failure_line() -> None:
    out = Lines()
    log = PlanLog(out, period=3600.0)
    log.success(result(), True, 5.0, busy=True)
    log.flush()
    assert len(out.lines) == 1 and out.lines[0].startswith('plans: 1 in ')
