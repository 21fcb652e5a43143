"""Fixtures for ROS tests: start real nodes, a spinning helper node in the test process.

See ``test/ros/launch.py`` for the helpers (``wait_until``, ``wait_for_service``,
``wait_for_subscribers``, ``call_service``, ``Collector``, ...).
"""
from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from .launch import NodeProcess, RclpyRuntime, popen_node


@pytest.hookimpl(tryfirst=True, hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo) -> Iterator[None]:
    """Keep each phase's report on the item (``item.rep_setup``, ``item.rep_call``)."""
    outcome = yield
    report = outcome.get_result()
    setattr(item, f'rep_{report.when}', report)


def _failed(item: pytest.Item) -> bool:
    return any(getattr(getattr(item, f'rep_{when}', None), 'failed', False)
               for when in ('setup', 'call'))


@pytest.fixture
def start_node(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[Any]:
    """``start_node(executable, *ros_args, params={...}, name=None, env=None) -> NodeProcess``.

    Starts a console script of this venv with ``--ros-args [ros_args] -p k:=v ...`` in a new
    process group, output in ``tmp_path/<name>.<n>.log``. At teardown every node still running
    is stopped (SIGINT, then SIGTERM, then SIGKILL); if the test failed, every log is dumped.
    """
    started: list[NodeProcess] = []

    def _start(executable: str, *ros_args: str, params: dict[str, Any] | None = None,
               name: str | None = None, env: dict[str, str] | None = None) -> NodeProcess:
        proc = popen_node(executable, *ros_args, params=params, name=name, env=env,
                          log_dir=tmp_path)
        started.append(proc)
        return proc

    yield _start

    for proc in started:
        if proc.alive():
            proc.stop()
    if _failed(request.node):
        for proc in started:
            sys.stderr.write(f'\n===== {proc.describe()} =====\n{proc.log_text()}\n')


@pytest.fixture(scope='session')
def rclpy_runtime() -> Iterator[RclpyRuntime]:
    """rclpy initialised once for the session, with an executor spinning in a background thread."""
    runtime = RclpyRuntime()
    yield runtime
    runtime.shutdown()


@pytest.fixture(scope='session')
def rclpy(rclpy_runtime: RclpyRuntime) -> Any:
    """Session-wide helper node (rclpy.node.Node), spun by a MultiThreadedExecutor in a thread.

    Entities created on it (clients, subscriptions) are served by that thread; prefer
    ``ros_node`` for per-test entities so that they are destroyed after the test.
    """
    return rclpy_runtime.node


@pytest.fixture(scope='module')
def helper(rclpy_runtime: RclpyRuntime, request: pytest.FixtureRequest) -> Iterator[Any]:
    """A helper node for one test module (named after it), on the session's spinning executor."""
    node = rclpy_runtime.create_node(request.module.__name__.rsplit('.', 1)[-1])
    yield node
    rclpy_runtime.destroy_node(node)


@pytest.fixture
def ros_node(rclpy_runtime: RclpyRuntime) -> Iterator[Any]:
    """A fresh helper node for one test, on the session's spinning executor; destroyed after."""
    node = rclpy_runtime.create_node()
    yield node
    rclpy_runtime.destroy_node(node)
