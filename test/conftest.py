"""Suite-wide pytest configuration: markers, --run-slow, and the network-namespace guard.

Markers:
    ros:    needs rclpy (skipped with a reason when rclpy cannot be imported). These tests start
            real DDS participants, so they never run outside a loopback-only network namespace
            (``bash scripts/test.sh`` provides one; ``colcon test`` does not): there they are
            skipped with the reason, unless ``GEODESIC_PLANNER_NETNS=off``.
    slow:   long runs; skipped unless ``--run-slow`` or ``GP_RUN_SLOW=1``.
    linter: style and consistency checks of the source tree.

Parallel runs (pytest-xdist, ``-n N``; scripts/test.sh passes ``-n 3 --dist loadscope
--no-loadscope-reorder``): every worker gets a ROS domain of its own (``ROS_DOMAIN_ID``,
:func:`tools.netns.worker_domain`), set before any rclpy context exists and inherited by the nodes
it starts, so the workers' nodes never discover each other inside the shared network namespace.
"""
from __future__ import annotations

import os

import pytest

from tools import netns


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption('--run-slow', action='store_true', default=False,
                     help='also run tests marked slow (or set GP_RUN_SLOW=1)')


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        'markers', 'ros: needs rclpy and real DDS; runs only inside the loopback network namespace')
    config.addinivalue_line(
        'markers', 'slow: long run; skipped unless --run-slow or GP_RUN_SLOW=1')
    config.addinivalue_line('markers', 'linter: style/consistency checks of the source tree')
    # colcon test hands its options (--junit-xml=..., its --pytest-args) to pytest in PYTEST_ADDOPTS,
    # read by now. Tests that start pytest again (scripts/test.sh, the conftest checks) must not
    # inherit them: a nested run would get -q twice, or write over this run's junit file.
    os.environ.pop('PYTEST_ADDOPTS', None)
    domain = netns.worker_domain(os.environ.get('PYTEST_XDIST_WORKER'))
    if domain is not None:
        os.environ['ROS_DOMAIN_ID'] = str(domain)
    # rosidl's parser imports lark 0.12, which uses the deprecated sre_parse/sre_constants modules.
    config.addinivalue_line(
        'filterwarnings', r'ignore:module .sre_(parse|constants). is deprecated:DeprecationWarning')


def _rclpy_import_error() -> str | None:
    try:
        import rclpy  # noqa: F401
    except Exception as exc:  # noqa: BLE001 any import failure means skip ROS
        return f'{type(exc).__name__}: {exc}'
    return None


def run_slow_enabled(config: pytest.Config) -> bool:
    """True when slow tests were asked for (--run-slow or GP_RUN_SLOW=1)."""
    return bool(config.getoption('--run-slow')) or os.environ.get('GP_RUN_SLOW', '') == '1'


#: The modules that take longest (waiting on processes or a build, or computing), longest first
#: (measured with tools/timeline.py): a parallel run (scripts/test.sh: --dist loadscope
#: --no-loadscope-reorder) hands them out first, so that they overlap the many short modules
#: instead of ending the run alone.
LONG_FIRST = ('test/infra/test_colcon.py', 'test/ros/test_unique_names.py', 'test/ros/test_planner_node.py',
              'test/ros/test_processor.py', 'test/timing/test_tool_speed.py', 'test/timing/test_jerk.py',
              'test/ros/test_reliability.py', 'test/timing/test_constant_speed.py', 'test/ros/test_overload.py',
              'test/cli/test_compare.py', 'test/io/test_bag_fuzz.py', 'test/core/test_blend.py',
              'test/ros/test_processor_hardening.py', 'test/core/test_long_way.py',
              'test/ros/test_model_sources.py', 'test/infra/test_ament_lint.py')


def _long_first(items: list[pytest.Item]) -> None:
    """Reorder ``items`` in place: LONG_FIRST's modules first (in its order), the rest as collected."""
    def rank(item: pytest.Item) -> int:
        path = item.nodeid.split('::', 1)[0]
        return LONG_FIRST.index(path) if path in LONG_FIRST else len(LONG_FIRST)
    items.sort(key=rank)     # stable: each module's own order is kept


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    _long_first(items)
    if not run_slow_enabled(config):
        skip_slow = pytest.mark.skip(reason='slow: run with --run-slow or GP_RUN_SLOW=1')
        for item in items:
            if 'slow' in item.keywords:
                item.add_marker(skip_slow)

    ros_items = [item for item in items
                 if item.get_closest_marker('ros') is not None
                 and item.get_closest_marker('skip') is None]
    if not ros_items:
        return
    error = _rclpy_import_error()
    if error is not None:
        skip_ros = pytest.mark.skip(reason=f'ros: rclpy cannot be imported ({error})')
        for item in ros_items:
            item.add_marker(skip_ros)
        return
    problem = netns.isolation_problem()
    if problem is not None:
        # Skipped, not an aborted run: the other tests still run (colcon test, a plain pytest).
        skip_ros = pytest.mark.skip(reason=f'ros: {problem}')
        for item in ros_items:
            item.add_marker(skip_ros)
