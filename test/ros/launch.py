"""Test helpers for real ROS 2 nodes: start console scripts, stop them, wait on the ROS graph.

No ``launch``/``ros2`` CLI (not on PyPI): nodes are console scripts of this venv started with
``subprocess.Popen`` in a new process group, their output captured to a log file; the test
process talks to them through a helper rclpy node spun by a ``MultiThreadedExecutor`` in a
background thread. Every wait has a deadline and fails loudly (naming what it waited for);
nothing sleeps for a fixed time.

Fixtures (registered by ``test/ros/conftest.py``):
    start_node: ``start_node(executable, *ros_args, params={...}, name=None, env=None)``
        -> :class:`NodeProcess`; every node is stopped at teardown, its log dumped if the test failed.
    rclpy: session-scoped helper :class:`rclpy.node.Node`, spinning in a background thread.
    ros_node: a fresh helper node per test on the same executor (destroyed afterwards).
"""
from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import sysconfig
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

__all__ = [
    'NodeProcess',
    'Collector',
    'bin_dir',
    'call_service',
    'deliver',
    'format_param',
    'popen_node',
    'ros_args_for',
    'wait_for_publishers',
    'wait_for_service',
    'wait_discovered',
    'wait_for_subscribers',
    'wait_until',
    'warm_up_client',
]

T = TypeVar('T')

#: Default deadline (s) for waits on the ROS graph; generous for 2 loaded cores.
DEFAULT_TIMEOUT = 30.0
_POLL = 0.02


# --------------------------------------------------------------------------- processes

def bin_dir() -> Path:
    """Directory holding this venv's console scripts (``.venv/bin``)."""
    return Path(sysconfig.get_path('scripts'))


def format_param(value: Any) -> str:
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
        """Everything the process wrote to stdout and stderr so far."""
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
        """Wait for exit; raise AssertionError (with the log tail) after ``timeout`` s."""
        try:
            return self.popen.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            raise AssertionError(f'{self.describe()} did not exit within {timeout} s; log tail:\n'
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
        try:
            os.killpg(self.popen.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
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
        log_dir: where the log goes; default: a temporary directory.
        argv: run this command instead (``executable`` then only names it); ros args appended.

    Returns:
        The running :class:`NodeProcess`.
    """
    label = name or Path(executable).name
    if argv is None:
        path = Path(executable) if os.sep in executable else bin_dir() / executable
        if not path.exists():
            raise AssertionError(f'console script {path} not found: run bash scripts/setup_env.sh '
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
    with open(log_path, 'wb') as log:
        kwargs: dict[str, Any] = ({'process_group': 0} if sys.version_info >= (3, 11)
                                  else {'start_new_session': True})
        popen = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=log,
                                 stderr=subprocess.STDOUT, env=full_env, **kwargs)
    return NodeProcess(label, argv, popen, log_path)


# --------------------------------------------------------------------------- waiting

def _check_alive(watch: Iterable[NodeProcess]) -> None:
    for proc in watch:
        if not proc.alive():
            raise AssertionError(f'{proc.describe()} died; log tail:\n{proc.log_tail()}')


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
        AssertionError: on timeout or when a watched process died.
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
            raise AssertionError(f'timed out after {timeout} s waiting for {desc}{extra}')
        time.sleep(interval)


def wait_for_service(client: Any, timeout: float = DEFAULT_TIMEOUT, *,
                     watch: Iterable[NodeProcess] = ()) -> None:
    """Wait until the service of an rclpy client is available."""
    wait_until(client.service_is_ready, timeout, what=f'service {client.srv_name}', watch=watch)


def wait_for_subscribers(pub: Any, n: int = 1, timeout: float = DEFAULT_TIMEOUT, *,
                         watch: Iterable[NodeProcess] = ()) -> int:
    """Wait until an rclpy publisher has at least ``n`` matched subscriptions; return the count."""
    return wait_until(lambda: pub.get_subscription_count() >= n and pub.get_subscription_count(),
                      timeout, what=f'{n} subscriber(s) on {pub.topic_name}', watch=watch)


def wait_for_publishers(node: Any, topic: str, n: int = 1, timeout: float = DEFAULT_TIMEOUT, *,
                        watch: Iterable[NodeProcess] = ()) -> int:
    """Wait until ``topic`` has at least ``n`` publishers in the graph; return the count."""
    return wait_until(lambda: node.count_publishers(topic) >= n and node.count_publishers(topic),
                      timeout, what=f'{n} publisher(s) on {topic}', watch=watch)


def warm_up_client(client: Any, request: Any, deadline: float, *, watch: Any = None) -> int:
    """Wait for the service, then until one harmless ``request`` gets its response (retried).

    ``wait_for_service`` only says that the server reads our requests; until the server's
    response writer has matched our response reader, rmw_fastrtps drops the response ("failed to
    send response (timeout): client will not receive response"), which happens under load. So a
    new client is used only after one round trip. Returns the number of requests sent.
    """
    wait_for_service(client, deadline, watch=watch)
    sent = 0

    def round_trip() -> bool:
        nonlocal sent
        sent += 1
        future = client.call_async(request)
        try:
            wait_until(future.done, 3.0, what='warm-up response', watch=watch)
            return True
        except AssertionError:
            client.remove_pending_request(future)
            return False

    wait_until(round_trip, deadline, what=f'a warm-up round trip on {client.srv_name}', watch=watch)
    return sent


def call_service(client: Any, request: Any, timeout: float = DEFAULT_TIMEOUT, *,
                 watch: Iterable[NodeProcess] = ()) -> Any:
    """Call an rclpy service (its node must be spun elsewhere, e.g. the ``rclpy`` fixture).

    Returns:
        The response.

    Raises:
        AssertionError: when no response arrives before the deadline.
    """
    future = client.call_async(request)
    try:
        wait_until(future.done, timeout, what=f'a response from {client.srv_name}', watch=watch)
    except AssertionError:
        future.cancel()
        raise
    exc = future.exception()
    if exc is not None:
        raise exc
    return future.result()


def wait_discovered(node: Any, target: str, timeout: float = DEFAULT_TIMEOUT, *,
                    watch: Iterable[NodeProcess] = ()) -> None:
    """Barrier: return once the node ``target`` (e.g. ``'/trajectory_processor'``) has discovered
    every publisher and subscription created so far in this process's rclpy context.

    After it, the target's readers have matched our writers and its writers our readers, so
    nothing we publish is dropped by a reader that did not know the writer yet (Fast DDS drops
    what a volatile reader receives before it matched the writer), and nothing it publishes
    misses our subscriptions. Needs no log line of the node: one round trip of a *new* client
    of ``target/get_parameters`` (an empty request, nothing logged). A participant announces its
    endpoints in creation order on two reliable, ordered built-in channels (one for writers,
    one for readers), and the target matches each endpoint when it processes its announcement;
    the request is taken only once the target matched our new request writer, the response
    delivered only once it matched our new response reader, both announced after every
    endpoint created before this call. (Our own side still has to see the target's endpoints:
    ``wait_for_subscribers``, ``subscription.get_publisher_count()``.)
    """
    from rcl_interfaces.srv import GetParameters

    client = node.create_client(GetParameters, f'{target}/get_parameters')
    try:
        warm_up_client(client, GetParameters.Request(names=[]), timeout, watch=watch)
    finally:
        node.destroy_client(client)


def deliver(action: Callable[[], Callable[[Any], bool] | None], got: Collector, try_timeout: float,
            timeout: float = DEFAULT_TIMEOUT, *, what: str = 'a message',
            watch: Iterable[NodeProcess] = ()) -> int:
    """Repeat ``action()`` until its message reaches ``got`` within ``try_timeout`` s.

    For a link the test cannot observe (one node's publisher, another node's subscription): the
    first message through proves that both ends have matched; after it nothing is lost
    (reliable). ``action`` returns a predicate that recognises its own message (give each
    attempt different content), or None for "any new message". A message of an earlier attempt
    that arrives late therefore arrives *before* the one recognised (one publisher, in order);
    the caller accounts for attempts that were lost or late (count by content, or from the
    first message known to have gone through). Returns the number of attempts.
    """
    watch = list(watch)
    attempts = 0

    def attempt() -> bool:
        nonlocal attempts
        attempts += 1
        n = len(got)
        predicate = action() or (lambda _msg: True)
        try:
            got.wait_for_message(predicate, n, try_timeout, what=f'the message of attempt {attempts}',
                                 watch=watch)
            return True
        except AssertionError:
            _check_alive(watch)
            return False

    wait_until(attempt, timeout, what=f'{what} on {got.topic}', watch=watch)
    return attempts


class Collector:
    """Subscription that keeps every message received, with a way to wait for them.

    Example::

        got = Collector(ros_node, JointTrajectory, '/geodesic_planner/joint_trajectory', qos)
        msg = got.wait_for(1)[0]
    """

    def __init__(self, node: Any, msg_type: Any, topic: str, qos: Any = 10, *,
                 raw: bool = False) -> None:
        self.topic = topic
        self.messages: list[Any] = []
        self._lock = threading.Lock()
        self.subscription = node.create_subscription(msg_type, topic, self._callback, qos, raw=raw)

    def _callback(self, msg: Any) -> None:
        with self._lock:
            self.messages.append(msg)

    def __len__(self) -> int:
        with self._lock:
            return len(self.messages)

    def wait_for(self, n: int = 1, timeout: float = DEFAULT_TIMEOUT, *,
                 watch: Iterable[NodeProcess] = ()) -> list[Any]:
        """Wait until at least ``n`` messages arrived; return a copy of all received."""
        wait_until(lambda: len(self) >= n, timeout, what=f'{n} message(s) on {self.topic}',
                   watch=watch)
        with self._lock:
            return list(self.messages)

    def wait_for_message(self, predicate: Callable[[Any], bool], start: int = 0,
                         timeout: float = DEFAULT_TIMEOUT, *, what: str = 'a matching message',
                         watch: Iterable[NodeProcess] = ()) -> int:
        """Wait until a message at index >= ``start`` satisfies ``predicate``; return its index.

        Count by content, not by position: e.g. wait for a sentinel's message, then every message
        published before it (one publisher, reliable, in order) has arrived too.
        """
        def find() -> int | None:
            with self._lock:
                msgs = self.messages[start:]
            return next((start + i + 1 for i, m in enumerate(msgs) if predicate(m)), None)

        return wait_until(find, timeout, what=f'{what} on {self.topic}', watch=watch) - 1


# --------------------------------------------------------------------------- rclpy in the test process

class RclpyRuntime:
    """rclpy context + a MultiThreadedExecutor spinning in a daemon thread (one per session)."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor

        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self._names = itertools.count()
        self.node = self.create_node('gp_test_helper')
        self._thread = threading.Thread(target=self._spin, name='rclpy-executor', daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            self.executor.spin()
        except ExternalShutdownException:
            pass

    def create_node(self, base: str = 'gp_test_node') -> Any:
        """A new helper node (unique name), added to the spinning executor."""
        from rclpy.node import Node

        node = Node(f'{base}_{os.getpid()}_{next(self._names)}', context=self.context)
        self.executor.add_node(node)
        return node

    def destroy_node(self, node: Any) -> None:
        self.executor.remove_node(node)
        node.destroy_node()

    def shutdown(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=5.0)
