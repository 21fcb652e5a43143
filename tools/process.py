"""Start a node (or any command) in its own process group, wait with deadlines, stop it.

No ``launch``/``ros2`` CLI (not on PyPI): nodes are console scripts of this venv started with
``subprocess.Popen`` in a new process group, their output captured to a log file that is for
people to read (failure messages quote its tail), never something to wait on. No rclpy here.
"""
from __future__ import annotations

import contextlib
import itertools
import math
import os
import signal
import subprocess
import sys
import sysconfig
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

__all__ = [
    'DEFAULT_TIMEOUT',
    'NodeProcess',
    'ToolError',
    'bin_dir',
    'format_param',
    'popen_node',
    'ros_args_for',
    'wait_until',
]

T = TypeVar('T')

#: Default deadline (s) of a wait; generous for 2 loaded cores.
DEFAULT_TIMEOUT = 30.0
_POLL = 0.02


class ToolError(AssertionError):
    """A tooling step failed: a wait timed out, a watched process died, a script is missing.

    An AssertionError, so that pytest reports it as a failed check; the demo reports its message.
    """


def bin_dir() -> Path:
    """Directory holding this venv's console scripts (``.venv/bin``)."""
    return Path(sysconfig.get_path('scripts'))


def format_param(value: object) -> str:
    """Format a parameter value for ``-p name:=VALUE`` (parsed as YAML by rcl).

    bool -> ``true``/``false``; int; float always with a decimal point (rcl tells int from
    double); inf/nan as YAML ``.inf``/``.nan``; lists/tuples as YAML flow sequences; strings
    as-is unless YAML would read them as something else, then single-quoted.
    """
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return '.nan'
        if math.isinf(value):
            return '.inf' if value > 0 else '-.inf'
        return repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(format_param(v) for v in value) + ']'
    if isinstance(value, str):
        try:
            plain = value != '' and '\n' not in value and yaml.safe_load(value) == value
        except yaml.YAMLError:
            plain = False
        return value if plain else "'" + value.replace("'", "''") + "'"
    if hasattr(value, 'tolist'):  # numpy arrays and scalars
        return format_param(value.tolist())
    raise TypeError(f'cannot format parameter value {value!r} of type {type(value).__name__}')


def ros_args_for(ros_args: Iterable[str] = (), params: Mapping[str, Any] | None = None) -> list[str]:
    """Command-line tail ``--ros-args [ros_args...] -p k:=v ...`` (empty when nothing to pass)."""
    tail = list(ros_args)
    for key, value in (params or {}).items():
        tail += ['-p', f'{key}:={format_param(value)}']
    return ['--ros-args', *tail] if tail else []


class NodeProcess:
    """A node (or any command) started in its own process group, output in a log file.

    Attributes:
        name: label used in messages.
        argv: the command line.
        popen: the :class:`subprocess.Popen`.
        log_path: file receiving stdout and stderr.
        signals_sent: signals sent by :meth:`stop`, in order (to see escalation).
    """

    def __init__(self, name: str, argv: list[str], popen: subprocess.Popen, log_path: Path) -> None:
        self.name = name
        self.argv = argv
        self.popen = popen
        self.log_path = log_path
        self.signals_sent: list[signal.Signals] = []

    @property
    def pid(self) -> int:
        return self.popen.pid

    @property
    def returncode(self) -> int | None:
        """Exit code once exited (negative: killed by that signal), else None."""
        return self.popen.poll()

    def alive(self) -> bool:
        return self.popen.poll() is None

    def log_text(self) -> str:
        """Everything the process wrote to stdout and stderr so far (for people and reports)."""
        try:
            return self.log_path.read_text(errors='replace')
        except FileNotFoundError:
            return ''

    def log_tail(self, lines: int = 40) -> str:
        return '\n'.join(self.log_text().splitlines()[-lines:])

    def describe(self) -> str:
        rc = self.returncode
        state = 'running' if rc is None else f'exited with {rc}'
        return f'{self.name} (pid {self.pid}, {state}, log {self.log_path})'

    def _signal(self, sig: signal.Signals) -> None:
        self.signals_sent.append(sig)
        try:
            os.killpg(self.popen.pid, sig)  # the whole group: children too
        except ProcessLookupError:
            pass
        except PermissionError:
            self.popen.send_signal(sig)

    def wait(self, timeout: float) -> int:
        """Wait for exit; raise :class:`ToolError` (with the log tail) after ``timeout`` s."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise ToolError(f'{self.describe()} did not exit within {timeout} s; log tail:\n'
                            f'{self.log_tail()}') from None

    def stop(self, sig: signal.Signals = signal.SIGINT, timeout: float = 10.0) -> int:
        """Send ``sig`` to the process group, then SIGTERM, then SIGKILL, ``timeout`` s apart.

        Returns:
            The exit code (negative when killed by a signal, e.g. -9).
        """
        for s in dict.fromkeys((sig, signal.SIGTERM, signal.SIGKILL)):
            if self.popen.poll() is not None:
                break
            self._signal(s)
            try:
                self.popen.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                continue
        if self.popen.poll() is None:  # SIGKILL always ends it, but never hang here
            self.popen.wait(timeout=timeout)
        # Reap stragglers left in the group (e.g. a grandchild that ignored the signals).
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.popen.pid, signal.SIGKILL)
        return self.popen.returncode


_counter = itertools.count()


def popen_node(executable: str, *ros_args: str, params: Mapping[str, Any] | None = None,
               name: str | None = None, env: Mapping[str, str] | None = None,
               log_dir: Path | None = None, argv: list[str] | None = None) -> NodeProcess:
    """Start a console script of this venv (or ``argv`` verbatim) with ROS arguments.

    Args:
        executable: console script name in :func:`bin_dir` (e.g. ``geodesic_planner_node``), or
            a path to an executable.
        *ros_args: extra tokens after ``--ros-args`` (e.g. ``'-r', '__node:=other'``).
        params: parameters, passed as ``-p name:=value`` (see :func:`format_param`).
        name: label for messages and the log file name; default: the executable's name.
        env: extra environment variables (added to this process's environment).
        log_dir: where the log goes (``<name>.<n>.log``); default: a temporary directory.
        argv: run this command instead (``executable`` then only names it); ros args appended.

    Returns:
        The running :class:`NodeProcess`.

    Raises:
        ToolError: the console script is not installed.
    """
    label = name or Path(executable).name
    if argv is None:
        path = Path(executable) if os.sep in executable else bin_dir() / executable
        if not path.exists():
            raise ToolError(f'console script {path} not found: run bash scripts/setup_env.sh '
                            '(pip install --no-deps -e .) after adding it to setup.py')
        argv = [str(path)]
    argv = [*argv, *ros_args_for(ros_args, params)]
    log_dir = Path(log_dir) if log_dir is not None else Path(tempfile.mkdtemp(prefix='gp_node_'))
    log_dir.mkdir(parents=True, exist_ok=True)
    log_path = log_dir / f'{label}.{next(_counter)}.log'
    full_env = dict(os.environ)
    full_env.update({'PYTHONUNBUFFERED': '1', 'RCUTILS_COLORIZED_OUTPUT': '0',
                     'RCUTILS_LOGGING_BUFFERED_STREAM': '0',
                     'ROS_LOG_DIR': str(log_dir / 'ros_log')})
    full_env.update(env or {})
    group: dict[str, Any] = ({'process_group': 0} if sys.version_info >= (3, 11)
                             else {'start_new_session': True})
    with open(log_path, 'wb') as log:
        popen = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log,
                                 stderr=subprocess.STDOUT, env=full_env, **group)
    return NodeProcess(label, argv, popen, log_path)


def _check_alive(watch: Iterable[NodeProcess]) -> None:
    for proc in watch:
        if not proc.alive():
            raise ToolError(f'{proc.describe()} died; log tail:\n{proc.log_tail()}')


def wait_until(predicate: Callable[[], T], timeout: float = DEFAULT_TIMEOUT, *,
               what: str | None = None, watch: Iterable[NodeProcess] = (),
               interval: float = _POLL) -> T:
    """Poll ``predicate`` until it returns something truthy; return that value.

    Args:
        predicate: called repeatedly (no arguments).
        timeout: deadline in s.
        what: description for the failure message (default: the predicate's name).
        watch: processes that must stay alive meanwhile (fail at once, with their log, if one dies).
        interval: poll period in s.

    Raises:
        ToolError: on timeout or when a watched process died.
    """
    watch = list(watch)
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        _check_alive(watch)
        if time.monotonic() >= deadline:
            desc = what or getattr(predicate, '__name__', repr(predicate))
            extra = ''.join(f'\n{p.describe()}; log tail:\n{p.log_tail()}' for p in watch)
            raise ToolError(f'timed out after {timeout} s waiting for {desc}{extra}')
        time.sleep(interval)
