"""Cooperative cancellation (core.cancel, issue 26 #1): checkpoints stop the maths, nowhere else."""
from __future__ import annotations

import threading

import numpy as np
import pytest

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.cancel import Cancelled, CancelToken, cancellable, checkpoint


def test_checkpoint_outside_a_cancellable_block_never_raises() -> None:
    token = CancelToken()
    token.cancel('gone')
    checkpoint()                      # no token in this context
    with cancellable(token), pytest.raises(Cancelled, match='gone'):
        checkpoint()
    checkpoint()                      # the block's token is gone again


def test_an_uncancelled_token_lets_the_work_finish() -> None:
    planner = GeodesicPlanner(load_robot('ur5e'))
    q_a = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    with cancellable(CancelToken()):
        path = planner.plan(None, planner.robot.fk(q_a + 0.2), start_joints=q_a)
    assert path.solver.success


def test_cancelled_is_not_an_exception_so_fallbacks_do_not_swallow_it() -> None:
    assert not issubclass(Cancelled, Exception)
    token = CancelToken()
    token.cancel()
    with cancellable(token), pytest.raises(Cancelled):
        try:
            checkpoint()
        except Exception:   # noqa: BLE001 - what a fallback in the library would write
            pytest.fail('Cancelled was caught as an Exception')


@pytest.mark.parametrize('stage', ['plan', 'collocation', 'timed', 'sample'])
def test_a_cancelled_token_stops_each_stage(stage: str) -> None:
    """Each stage checks the token: cancelled before it starts, it raises at its first checkpoint."""
    robot = load_robot('panda')
    planner = GeodesicPlanner(robot)
    q_a = robot.home + 0.1
    T_b = robot.fk(robot.home - 0.1)
    path = planner.plan(None, T_b, start_joints=q_a)
    trajectory = path.timed()
    work = {'plan': lambda: planner.plan(None, T_b, start_joints=q_a),
            'collocation': lambda: planner.plan(None, T_b, start_joints=q_a, method='collocation'),
            'timed': lambda: path.timed(max_jerk=50.0),
            'sample': lambda: trajectory.sample(1e-4)}[stage]
    token = CancelToken()
    token.cancel('stop')
    with cancellable(token), pytest.raises(Cancelled):
        work()


def test_the_token_is_per_thread_context() -> None:
    """A token set in one thread's context does not stop the same work in another thread."""
    token = CancelToken()
    token.cancel()
    seen: list[str] = []

    def other() -> None:
        checkpoint()
        seen.append('ran')

    with cancellable(token):
        thread = threading.Thread(target=other)
        thread.start()
        thread.join()
    assert seen == ['ran']
