"""A client's view of running nodes: an rclpy runtime in a thread, and waits on the ROS graph.

The demo and the ROS tests talk to the nodes through one helper participant (:class:`RclpyRuntime`:
a context and a ``MultiThreadedExecutor`` spinning in a daemon thread). They synchronise on what
the graph and the nodes' replies show, never on the nodes' log lines. rclpy is imported lazily,
so ``tools`` stays importable without ROS.
"""
from __future__ import annotations

import itertools
import os
import sys
import threading
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, ClassVar

from tools.process import DEFAULT_TIMEOUT, NodeProcess, ToolError, _check_alive, wait_until

if TYPE_CHECKING:
    from rclpy.node import Node

__all__ = [
    'Collector',
    'RclpyRuntime',
    'call_service',
    'latched_qos',
    'rosout_collector',
    'wait_for_publishers',
    'wait_for_service',
    'wait_for_subscribers',
    'wait_reader_matched',
    'wait_writer_matched',
    'warm_up_client',
]


def wait_for_service(client: Any, timeout: float = DEFAULT_TIMEOUT, *,  # noqa: ANN401
                     watch: Iterable[NodeProcess] = ()) -> None:
    """Wait until the service of an rclpy client is available."""
    wait_until(client.service_is_ready, timeout, what=f'service {client.srv_name}', watch=watch)


def wait_for_subscribers(pub: Any, n: int = 1, timeout: float = DEFAULT_TIMEOUT, *,  # noqa: ANN401
                         watch: Iterable[NodeProcess] = ()) -> int:
    """Wait until an rclpy publisher has at least ``n`` matched subscriptions; return the count."""
    return wait_until(lambda: pub.get_subscription_count() >= n and pub.get_subscription_count(),
                      timeout, what=f'{n} subscriber(s) on {pub.topic_name}', watch=watch)


def wait_for_publishers(node: Any, topic: str, n: int = 1, timeout: float = DEFAULT_TIMEOUT, *,  # noqa: ANN401
                        watch: Iterable[NodeProcess] = ()) -> int:
    """Wait until ``topic`` has at least ``n`` publishers in the graph; return the count."""
    return wait_until(lambda: node.count_publishers(topic) >= n and node.count_publishers(topic),
                      timeout, what=f'{n} publisher(s) on {topic}', watch=watch)


def warm_up_client(client: Any, request: Any, deadline: float, *,  # noqa: ANN401
                   watch: Iterable[NodeProcess] = ()) -> int:
    """Wait for the service, then until one harmless ``request`` gets its response (retried).

    ``wait_for_service`` only says that the server reads our requests; until the server's
    response writer has matched our response reader, rmw_fastrtps drops the response ("failed to
    send response (timeout): client will not receive response"), which happens under load. So a
    new client is used only after one round trip. Returns the number of requests sent.
    """
    watch = list(watch)
    wait_for_service(client, deadline, watch=watch)
    sent = 0

    def round_trip() -> bool:
        nonlocal sent
        sent += 1
        future = client.call_async(request)
        try:
            wait_until(future.done, 3.0, what='warm-up response', watch=watch)
            return True
        except ToolError:
            client.remove_pending_request(future)
            return False

    wait_until(round_trip, deadline, what=f'a warm-up round trip on {client.srv_name}', watch=watch)
    return sent


def call_service(client: Any, request: Any, timeout: float = DEFAULT_TIMEOUT, *,  # noqa: ANN401
                 watch: Iterable[NodeProcess] = ()) -> Any:  # noqa: ANN401
    """Call an rclpy service (its node must be spun elsewhere, e.g. by :class:`RclpyRuntime`).

    Returns:
        The response.

    Raises:
        ToolError: when no response arrives before the deadline.
    """
    future = client.call_async(request)
    try:
        wait_until(future.done, timeout, what=f'a response from {client.srv_name}', watch=watch)
    except ToolError:
        future.cancel()
        raise
    exc = future.exception()
    if exc is not None:
        raise exc
    return future.result()


class Collector:
    """Subscription that keeps every message received, with a way to wait for them.

    Example::

        got = Collector(ros_node, JointTrajectory, '/geodesic_planner/joint_trajectory', qos)
        msg = got.wait_for(1)[0]
    """

    def __init__(self, node: Any, msg_type: Any, topic: str, qos: Any = 10, *,  # noqa: ANN401
                 raw: bool = False) -> None:
        self.topic = topic
        self.messages: list[Any] = []
        self._lock = threading.Lock()
        self.subscription = node.create_subscription(msg_type, topic, self._callback, qos, raw=raw)

    def _callback(self, msg: Any) -> None:  # noqa: ANN401
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


def latched_qos(depth: int = 1) -> Any:  # noqa: ANN401
    """Reliable, transient-local QoS: a late subscriber still gets the last ``depth`` messages
    (as robot_state_publisher's /robot_description and /rosout's history)."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    return QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)


def rosout_collector(node: Any) -> Collector:  # noqa: ANN401
    """Every /rosout message, including the history published before the subscription."""
    from rcl_interfaces.msg import Log
    return Collector(node, Log, '/rosout', latched_qos(1000))


class StatusWatch:
    """The latest ``/diagnostics`` status of every node (geodesic_planner.ros.diagnostics).

    Example::

        watch = StatusWatch(runtime.node)
        watch.wait('/trajectory_processor', 'input publishers matched', lambda v: int(v) >= 1)
    """

    def __init__(self, node: Any) -> None:  # noqa: ANN401
        from diagnostic_msgs.msg import DiagnosticArray

        self._latest: dict[str, dict[str, str]] = {}
        self._lock = threading.Lock()
        self.subscription = node.create_subscription(DiagnosticArray, '/diagnostics', self._callback, 50)

    def _callback(self, msg: Any) -> None:  # noqa: ANN401
        with self._lock:
            for status in msg.status:
                self._latest[status.name] = {kv.key: kv.value for kv in status.values}

    def values(self, name: str) -> dict[str, str]:
        """The latest values of the node ``name`` (fully qualified, e.g. ``/geodesic_planner``)."""
        with self._lock:
            return dict(self._latest.get(name, {}))

    def wait(self, name: str, key: str, predicate: Callable[[str], bool], timeout: float = DEFAULT_TIMEOUT, *,
             watch: Iterable[NodeProcess] = ()) -> None:
        """Wait until node ``name`` reports a value ``key`` for which ``predicate`` holds."""
        def holds() -> bool:
            value = self.values(name).get(key)
            return value is not None and predicate(value)
        wait_until(holds, timeout, what=f'{name} to report {key!r} as wanted on /diagnostics', watch=watch)


class RclpyRuntime:
    """rclpy context + a MultiThreadedExecutor spinning in a daemon thread.

    The newest runtime not yet shut down is :attr:`current` (what :func:`wait_writer_matched`
    uses when given none).
    """

    current: ClassVar[RclpyRuntime | None] = None

    def __init__(self, name: str = 'gp_test_helper') -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import MultiThreadedExecutor

        self.context = Context()
        rclpy.init(context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=4, context=self.context)
        self._names = itertools.count()
        #: exceptions that came out of the executor (it kept spinning; see _spin)
        self.spin_errors: list[BaseException] = []
        self.node = self.create_node(name)
        self._thread = threading.Thread(target=self._spin, name='rclpy-executor', daemon=True)
        self._thread.start()
        RclpyRuntime.current = self

    def _spin(self) -> None:
        """Spin until shutdown, whatever comes out of the executor.

        Tests destroy their clients and subscriptions while this thread spins; when the executor
        was using one at that moment, rclpy raises out of ``spin()`` (``InvalidHandle``; ros2/rclpy
        #1206, #1355), and so does a callback that raises. Ending the thread there would lose every
        later reply and message of the session: record the error, say so, spin on.
        """
        from rclpy.executors import ExternalShutdownException

        while self.context.ok():
            try:
                self.executor.spin()
                return
            except ExternalShutdownException:
                return
            except Exception as err:  # noqa: BLE001 - the executor must outlive any one callback
                if not self.context.ok():
                    return
                self.spin_errors.append(err)
                sys.stderr.write(f'rclpy executor: {type(err).__name__}: {err} (spinning on)\n')

    def create_node(self, base: str = 'gp_test_node') -> Any:  # noqa: ANN401
        """A new helper node (unique name), added to the spinning executor."""
        from rclpy.node import Node

        node = Node(f'{base}_{os.getpid()}_{next(self._names)}', context=self.context)
        self.executor.add_node(node)
        return node

    def destroy_node(self, node: Any) -> None:  # noqa: ANN401
        self.executor.remove_node(node)
        node.destroy_node()

    def shutdown(self) -> None:
        import rclpy

        if RclpyRuntime.current is self:
            RclpyRuntime.current = None
        self.executor.shutdown(timeout_sec=5.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
        self._thread.join(timeout=5.0)


_UNKNOWN = '_NODE_NAME_UNKNOWN_'


def _full_name(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


def _barrier(runtime: RclpyRuntime, topic: str, side: str, timeout: float,
             watch: list[NodeProcess]) -> None:
    """One parameter-service round trip with every other node having a ``side`` endpoint on
    ``topic`` (``'publishers'`` or ``'subscriptions'``), each through a client created now."""
    from rcl_interfaces.srv import GetParameters

    node = runtime.node
    ours = {_full_name(nd.get_namespace(), nd.get_name()) for nd in runtime.executor.get_nodes()}
    info_of = (node.get_publishers_info_by_topic if side == 'publishers'
               else node.get_subscriptions_info_by_topic)

    def others() -> list[Any]:
        infos = info_of(topic)
        # A participant's node names arrive after its endpoints; until then they read
        # _NODE_NAME_UNKNOWN_, and we need the name to reach the node's parameter service.
        if any(i.node_name == _UNKNOWN for i in infos):
            return []
        return [i for i in infos if _full_name(i.node_namespace, i.node_name) not in ours]
    infos = wait_until(others, timeout, what=f'named {side} on {topic} in another process',
                       watch=watch)
    for full in sorted({_full_name(i.node_namespace, i.node_name) for i in infos}):
        client = node.create_client(GetParameters, f'{full}/get_parameters')
        try:
            warm_up_client(client, GetParameters.Request(), timeout, watch=watch)
        finally:
            node.destroy_client(client)


def _runtime(runtime: RclpyRuntime | None) -> RclpyRuntime:
    runtime = runtime or RclpyRuntime.current
    if runtime is None:
        raise ToolError('waiting on the graph needs a running RclpyRuntime')
    return runtime


def wait_writer_matched(process: NodeProcess, topic: str, n: int = 1,
                        timeout: float = DEFAULT_TIMEOUT, *, watch: Iterable[NodeProcess] = (),
                        runtime: RclpyRuntime | None = None) -> None:
    """Wait until the publisher on ``topic`` will deliver to ``n`` subscriptions, ours included.

    A volatile reader gets only what is published after the *writer* has matched it, and our
    side seeing the publisher says nothing about that. So, from the waiting side:

    1. the graph shows at least ``n`` subscriptions on ``topic``;
    2. each of our subscriptions on ``topic`` has matched a publisher (reader side);
    3. one round trip with the parameter service (``~/get_parameters``) of every other node
       publishing on ``topic``, through a client created now. A participant announces its
       readers in creation order on one reliable, ordered discovery channel, and the server
       answers only once it has matched the client's response reader; so a reply proves that
       node has processed our earlier subscriptions, which pairs them with its writers.

    Subscriptions of other processes are covered by step 1 and by the node itself, which waits
    for the subscriptions its graph shows to match before publishing (``ros/matching.py``).

    Args:
        process: the node publishing on ``topic`` (watched, with ``watch``, while waiting).
        topic: absolute topic name.
        n: subscriptions that must receive the next message.
        timeout: deadline of each step, s.
        watch: further processes that must stay alive.
        runtime: the helper participant; default :attr:`RclpyRuntime.current`.

    Raises:
        ToolError: a step timed out or a watched process died.
    """
    _wait_matched(_runtime(runtime), topic, n, timeout, [process, *watch], readers_side=True)


def wait_reader_matched(process: NodeProcess, topic: str, n: int = 1,
                        timeout: float = DEFAULT_TIMEOUT, *, watch: Iterable[NodeProcess] = (),
                        runtime: RclpyRuntime | None = None) -> None:
    """Wait until the subscription on ``topic`` will receive from ``n`` publishers, ours included.

    The mirror of :func:`wait_writer_matched`: a volatile reader drops what was sent before it had
    matched the writer itself. The graph shows at least ``n`` publishers on ``topic``, each of
    our publishers on it has matched a subscription, and every other node subscribing to
    ``topic`` has answered a parameter request whose request writer was announced after our
    publishers (same ordered discovery channel), so its readers are paired with them.

    Raises:
        ToolError: a step timed out or a watched process died.
    """
    _wait_matched(_runtime(runtime), topic, n, timeout, [process, *watch], readers_side=False)


def _wait_matched(runtime: RclpyRuntime, topic: str, n: int, timeout: float, watch: list[NodeProcess], *,
                  readers_side: bool) -> None:
    """The steps of wait_writer_matched (readers_side) and wait_reader_matched (the mirror)."""
    ours, theirs = ('subscription', 'publisher') if readers_side else ('publisher', 'subscription')
    count = runtime.node.count_subscribers if readers_side else runtime.node.count_publishers
    wait_until(lambda: count(topic) >= n, timeout, what=f'{n} {ours}(s) on {topic} in the graph', watch=watch)
    for nd in runtime.executor.get_nodes():
        for entity in (nd.subscriptions if readers_side else nd.publishers):
            if entity.topic_name == topic:
                matched = entity.get_publisher_count if readers_side else entity.get_subscription_count
                wait_until(lambda m=matched: m() >= 1, timeout,
                           what=f'our {ours} on {topic} to match a {theirs}', watch=watch)
    _barrier(runtime, topic, 'publishers' if readers_side else 'subscriptions', timeout, watch)


def wait_discovered(node: Node, target: str, timeout: float = DEFAULT_TIMEOUT, *,
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
