"""PlanWorker (ros.admission, issue 26 #1): an abandoned plan is cancelled, never commits, and
the next run waits only for it to stop; PlanQueue: admission, order, give-up. Plain threads: no
ROS needed."""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest

from geodesic_planner.core.cancel import checkpoint
from geodesic_planner.ros.admission import PlanQueue, PlanWorker, WorkerBusyError


def spinning(commit_after: float | None = None, cooperative: bool = True,
             log: list[str] | None = None) -> Callable[[Callable[[Callable[[], object]], bool]], str]:
    """A computation that runs until cancelled (checking every 1 ms) or, if ``commit_after`` is
    given, commits once after that many seconds and returns."""
    def compute(commit: Callable[[Callable[[], object]], bool]) -> str:
        t0 = time.monotonic()
        while True:
            if cooperative:
                checkpoint()
            if commit_after is not None and time.monotonic() - t0 >= commit_after:
                ok = commit(lambda: (log if log is not None else []).append('published'))
                return 'committed' if ok else 'refused'
            time.sleep(0.001)
    return compute


def test_a_quick_run_returns_its_result() -> None:
    run = PlanWorker(1.0).run(lambda commit: 42, 5.0)
    assert (run.result, run.error, run.abandoned, run.committed) == (42, None, False, False)


def test_errors_are_handed_back() -> None:
    def fail(commit: object) -> None:
        raise ValueError('bad')
    run = PlanWorker(1.0).run(fail, 5.0)
    assert isinstance(run.error, ValueError) and not run.abandoned


def test_an_abandoned_run_is_cancelled_and_the_next_one_waits_only_for_it_to_stop() -> None:
    stops: list[float] = []
    worker = PlanWorker(2.0, stops.append)
    t0 = time.monotonic()
    run = worker.run(spinning(), 0.05)
    assert run.abandoned and run.result is None and not run.committed
    nxt = worker.run(lambda commit: 'next', 5.0)
    assert nxt.result == 'next'
    assert len(stops) == 1 and 0.0 <= stops[0] < 1.0
    assert time.monotonic() - t0 < 2.0       # not the abandoned computation's natural end: never


def test_an_abandoned_run_never_commits() -> None:
    log: list[str] = []
    done = threading.Event()
    worker = PlanWorker(2.0, lambda _s: done.set())
    # not cooperative: it would run past its timeout and then try to publish
    run = worker.run(spinning(commit_after=0.3, cooperative=False, log=log), 0.05)
    assert run.abandoned
    assert done.wait(5.0)                    # it ended (refused to commit, returned)
    assert log == []


def test_a_run_that_committed_is_not_abandoned() -> None:
    log: list[str] = []
    run = PlanWorker(2.0).run(lambda commit: (commit(lambda: log.append('published')),
                                              time.sleep(0.2), 'rest')[-1], 0.05)
    assert not run.abandoned and run.committed and run.result == 'rest' and log == ['published']


def test_a_computation_that_ignores_cancellation_makes_the_next_run_busy() -> None:
    release = threading.Event()

    def stubborn(commit: object) -> None:
        release.wait(10.0)
    worker = PlanWorker(0.1)
    assert worker.run(stubborn, 0.05).abandoned
    with pytest.raises(WorkerBusyError, match=r'not stopped within 0\.1 s'):
        worker.run(lambda commit: None, 5.0)
    release.set()
    assert worker.run(lambda commit: 'free again', 5.0).result == 'free again'


def test_runs_share_one_thread_even_after_a_failed_callback(capfd: pytest.CaptureFixture[str]) -> None:
    """One worker thread serves every run (its per-thread scratch buffers are reused), and an
    ``on_stopped`` that raises is reported on stderr without ending it."""
    def thread(commit: object) -> threading.Thread:
        return threading.current_thread()

    def raising(_seconds: float) -> None:
        raise RuntimeError('on_stopped failed')

    worker = PlanWorker(2.0, raising)
    first = worker.run(thread, 5.0).result
    assert first is not threading.current_thread() and worker.run(thread, 5.0).result is first
    assert worker.run(spinning(), 0.05).abandoned      # its on_stopped raises in the worker thread
    after = worker.run(thread, 5.0)
    assert after.error is None and after.result is first
    assert 'RuntimeError: on_stopped failed' in capfd.readouterr().err


# --------------------------------------------------------------------------- PlanQueue

def test_queue_refuses_beyond_its_depth_and_serves_in_ticket_order() -> None:
    queue = PlanQueue(3)
    tickets = [queue.enter() for _ in range(4)]
    assert tickets == [0, 1, 2, None] and queue.refused == 1 and queue.inside == 3 and queue.peak == 3
    order: list[int] = []

    def wait(ticket: int) -> None:
        assert queue.wait_turn(ticket, 10.0)
        order.append(ticket)
        queue.leave(ticket)
    threads = [threading.Thread(target=wait, args=(t,)) for t in (2, 1)]   # started out of order
    for thread in threads:
        thread.start()
    time.sleep(0.05)
    assert order == []                          # ticket 0 holds the turn
    assert queue.wait_turn(0, 1.0)              # its turn at once
    queue.leave(0)
    for thread in threads:
        thread.join(10.0)
    assert order == [1, 2] and queue.inside == 0
    with pytest.raises(RuntimeError, match='out of turn'):
        queue.leave(5)


def test_a_waiter_that_gives_up_is_skipped_and_only_the_next_one_is_woken() -> None:
    queue = PlanQueue(4)
    first, late, third = queue.enter(), queue.enter(), queue.enter()
    assert (first, late, third) == (0, 1, 2)
    assert not queue.wait_turn(late, 0.05)      # gives up behind ticket 0
    assert queue.timed_out == 1 and queue.inside == 2
    woken = threading.Event()
    waiter = threading.Thread(target=lambda: queue.wait_turn(third, 10.0) and woken.set())
    waiter.start()
    time.sleep(0.05)
    assert not woken.is_set()
    queue.leave(first)                          # ticket 1 gave up: ticket 2's turn, and its event
    assert woken.wait(5.0)
    waiter.join(5.0)
    queue.leave(third)
    assert queue.inside == 0 and queue.enter() == 3 and queue.wait_turn(3, 0.0)
