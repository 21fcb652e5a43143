"""Run launch/geodesic_planner.launch.py without ``ros2 launch`` (the venv has no ROS 2 CLI).

``python -m tools.launch_nodes [namespace:=NS] [planner_config:=FILE] [processor_config:=FILE]
[joint_limits:=FILE]`` (from the repository root; ``--show-args`` lists the arguments, ``--print``
prints the two command lines instead of running them). Inside the loopback-only namespace::

    bash scripts/netns.sh .venv/bin/python -m tools.launch_nodes namespace:=robot1

The launch file's plain-data description (``describe(...)``, the same that ``ros2 launch`` turns
into launch_ros Nodes) gives each node's console script and ``--ros-args``; both run as children
of this process, their output on this terminal (launch's ``output='screen'``). SIGINT (Ctrl-C)
or SIGTERM is passed on to both as SIGINT (then SIGTERM, then SIGKILL, 10 s apart); if one node
exits by itself, the other is stopped and the exit code is 1. Exit codes: 0 both nodes stopped
cleanly, 1 a node failed, 2 bad arguments. No rclpy here.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import shlex
import signal
import subprocess
import sys
import time
import types
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tools.process import bin_dir

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'geodesic_planner.launch.py'
#: s between SIGINT, SIGTERM and SIGKILL when stopping a node
STOP_GRACE = 10.0
_POLL = 0.05


class UsageError(Exception):
    """A bad command line (exit code 2)."""


def load_launch(path: Path = LAUNCH_FILE) -> types.ModuleType:
    """The launch file as a module, loaded as ``ros2 launch`` loads it (not in sys.modules)."""
    spec = importlib.util.spec_from_file_location('geodesic_planner_launch', path)
    if spec is None or spec.loader is None:
        msg = f'cannot load {path}'
        raise UsageError(msg)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def parse_launch_arguments(tokens: Sequence[str], known: Sequence[str]) -> dict[str, str]:
    """``['namespace:=robot1', ...]`` -> ``{'namespace': 'robot1'}``, as ``ros2 launch`` takes them.

    Raises:
        UsageError: a token without ``:=``, an unknown name, or a name given twice.
    """
    values: dict[str, str] = {}
    for token in tokens:
        name, sep, value = token.partition(':=')
        if not sep or not name:
            msg = f"{token!r}: launch arguments are NAME:=VALUE (one of {', '.join(known)})"
            raise UsageError(msg)
        if name not in known:
            msg = f"unknown launch argument {name!r} (one of {', '.join(known)})"
            raise UsageError(msg)
        if name in values:
            msg = f'launch argument {name!r} given twice'
            raise UsageError(msg)
        values[name] = value
    return values


def command_lines(module: types.ModuleType, values: dict[str, str]) -> list[tuple[str, list[str]]]:
    """(full node name, argv) of each node the launch file describes for these arguments.

    Raises:
        UsageError: an invalid namespace, or a parameter file that does not exist.
    """
    for name in ('planner_config', 'processor_config', 'joint_limits'):
        value = values.get(name, '')
        if value and not Path(value).is_file():
            msg = f'{name}: {value}: no such file'
            raise UsageError(msg)
    try:
        specs = module.describe(**values)
    except ValueError as err:
        raise UsageError(str(err)) from None
    return [(spec.full_name, [str(bin_dir() / spec.executable), '--ros-args', *spec.ros_arguments()])
            for spec in specs]


def _signal_group(popen: subprocess.Popen[Any], sig: signal.Signals) -> None:
    try:
        os.killpg(popen.pid, sig)
    except (ProcessLookupError, PermissionError):
        if popen.poll() is None:
            popen.send_signal(sig)


def stop_all(children: dict[str, subprocess.Popen[Any]]) -> None:
    """SIGINT to every running node at once, then SIGTERM, then SIGKILL, ``STOP_GRACE`` s apart."""
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        running = [p for p in children.values() if p.poll() is None]
        if not running:
            return
        for popen in running:
            _signal_group(popen, sig)
        deadline = time.monotonic() + STOP_GRACE
        while time.monotonic() < deadline and any(p.poll() is None for p in running):
            time.sleep(_POLL)


def run(lines: list[tuple[str, list[str]]]) -> int:
    """Start the nodes, wait for a signal or a node's exit, stop them; the exit code."""
    stop_requested: list[int] = []

    def on_signal(signum: int, _frame: object) -> None:
        stop_requested.append(signum)

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    children: dict[str, subprocess.Popen[Any]] = {}
    failed: list[str] = []
    try:
        for name, argv in lines:
            if stop_requested:
                break
            print(f'launch_nodes: starting {name}: {shlex.join(argv)}', file=sys.stderr, flush=True)
            # own process group: a terminal's Ctrl-C reaches this process only, which passes it on
            children[name] = subprocess.Popen(argv, stdin=subprocess.DEVNULL, process_group=0)
        while not stop_requested:
            exited = [(n, p.returncode) for n, p in children.items() if p.poll() is not None]
            if exited:
                failed = [f'{n} exited with code {rc}' for n, rc in exited]
                break
            time.sleep(_POLL)
    finally:
        stop_all(children)
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if failed:
        print(f'ERROR: {"; ".join(failed)} (the other nodes were stopped)', file=sys.stderr)
        return 1
    bad = [f'{n} exited with code {p.returncode}' for n, p in children.items() if p.returncode != 0]
    if bad:
        print(f'ERROR: {"; ".join(bad)} when stopped', file=sys.stderr)
        return 1
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m tools.launch_nodes``: the exit code (0 ok, 1 a node failed, 2 bad arguments)."""
    parser = argparse.ArgumentParser(
        prog='python -m tools.launch_nodes',
        description='Start the nodes of launch/geodesic_planner.launch.py as `ros2 launch` would, '
                    'without the ROS 2 CLI (the venv has none). Ctrl-C stops both.')
    parser.add_argument('arguments', nargs='*', metavar='NAME:=VALUE',
                        help='launch arguments: namespace, planner_config, processor_config, joint_limits')
    parser.add_argument('--show-args', action='store_true', help='list the launch arguments and exit')
    parser.add_argument('--print', action='store_true', dest='print_only',
                        help='print the two command lines and exit')
    args = parser.parse_args(argv)
    try:
        module = load_launch()
        if args.show_args:
            for name, (default, description) in module.ARGUMENTS.items():
                print(f"'{name}':\n    {description}\n    (default: '{default}')")
            return 0
        lines = command_lines(module, parse_launch_arguments(args.arguments, list(module.ARGUMENTS)))
    except UsageError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 2
    if args.print_only:
        for _, line in lines:
            print(shlex.join(line))
        return 0
    return run(lines)


if __name__ == '__main__':
    sys.exit(main())
