"""Test helpers for real ROS 2 nodes: start console scripts, stop them, wait on the ROS graph.

The helpers live in ``tools/`` (shared with the demo, outside the installed library):
:mod:`tools.process` starts a console script of this venv with ``subprocess.Popen`` in a new
process group (output in a log file, for people) and stops it; :mod:`tools.graph` holds the
helper rclpy participant and the waits on the graph and on replies. Every wait has a deadline
and fails loudly (naming what it waited for); nothing sleeps for a fixed time, and nothing
waits on a node's log lines.

Fixtures (registered by ``test/ros/conftest.py``):
    start_node: ``start_node(executable, *ros_args, params={...}, name=None, env=None)``
        -> :class:`NodeProcess`; every node is stopped at teardown, its log dumped if the test failed.
    rclpy: session-scoped helper :class:`rclpy.node.Node`, spinning in a background thread.
    ros_node: a fresh helper node per test on the same executor (destroyed afterwards).
"""
from __future__ import annotations

from tools.graph import (Collector, RclpyRuntime, call_service, deliver, latched_qos, rosout_collector,
                         wait_discovered, wait_for_publishers, wait_for_service,
                         wait_for_subscribers, wait_reader_matched, wait_writer_matched,
                         warm_up_client)
from tools.process import (DEFAULT_TIMEOUT, NodeProcess, ToolError, bin_dir, format_param, popen_node,
                           ros_args_for, wait_until)

__all__ = [
                         'DEFAULT_TIMEOUT',
                         'Collector',
                         'NodeProcess',
                         'RclpyRuntime',
                         'ToolError',
                         'bin_dir',
                         'call_service',
                         'deliver',
                         'format_param',
                         'latched_qos',
                         'popen_node',
                         'ros_args_for',
                         'rosout_collector',
                         'wait_discovered',
                         'wait_for_publishers',
                         'wait_for_service',
                         'wait_for_subscribers',
                         'wait_reader_matched',
                         'wait_until',
                         'wait_writer_matched',
                         'warm_up_client',
]
