"""Publishing without losing the first message to discovery.

A volatile DDS reader receives only what is published after it has matched the writer, and the
graph (``count_subscribers``) can show a subscription before the writer has matched it. A node
that publishes a one-off message (a planned trajectory) therefore waits, briefly and boundedly,
until every subscription the graph shows on the topic has matched its publisher.

For people reading the log, :func:`matched_logger` logs ``<topic>: N subscription(s) matched``
whenever the publisher's match count changes; programs read the same count on ``/diagnostics``
(:mod:`geodesic_planner.ros.diagnostics`), never in the log. The subscriber side has
:func:`log_publishers_matched` and :func:`log_messages_lost` for subscription events.
"""
from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.event_handler import PublisherEventCallbacks, QoSMessageLostInfo, QoSSubscriptionMatchedInfo
from rclpy.node import Node
from rclpy.publisher import Publisher

#: Longest wait for discovered subscriptions to match before publishing anyway, s.
MATCH_TIMEOUT = 1.0


def wait_for_matched_subscriptions(node: Node, publisher: Publisher, timeout: float = MATCH_TIMEOUT) -> int:
    """Wait until the publisher has matched every subscription the graph shows on its topic.

    Returns the number of matched subscriptions (publishing goes ahead after ``timeout`` s).
    """
    deadline = time.monotonic() + timeout
    while True:
        matched = publisher.get_subscription_count()
        if matched >= node.count_subscribers(publisher.topic_name) or time.monotonic() >= deadline:
            return matched
        time.sleep(0.002)


def matched_logger(node: Node, topic: str,
                   on_count: Callable[[int], None] | None = None) -> PublisherEventCallbacks:
    """Publisher event callbacks that log ``<topic>: N subscription(s) matched`` on every change.

    ``topic`` is the name to log (the publisher's resolved name is not known before creation);
    ``on_count`` is also given the new count (e.g. to put it in the node's diagnostics).
    """
    def on_matched(status: object) -> None:
        if getattr(status, 'current_count_change', 0):
            count = int(getattr(status, 'current_count', 0))
            node.get_logger().info(f'{topic}: {count} subscription(s) matched')
            if on_count is not None:
                on_count(count)
    return PublisherEventCallbacks(matched=on_matched)


def log_publishers_matched(node: Node, topic: str, status: QoSSubscriptionMatchedInfo) -> None:
    """Log ``<topic>: N publisher(s) matched`` when a subscription's match count changed."""
    if status.current_count_change:
        node.get_logger().info(f'{topic}: {status.current_count} publisher(s) matched')


def log_messages_lost(node: Node, topic: str, status: QoSMessageLostInfo) -> None:
    """Log, as an error, the messages the rmw reports lost before a subscription received them."""
    node.get_logger().error(
        f'{topic}: {status.total_count_change} message(s) lost before reception '
        f'({status.total_count} in total)')


class MatchBeforePublish:
    """Before a one-off publish on ``publisher``: let the subscriptions the graph shows match it.

    A subscriber that subscribes just before calling a service may be in the graph but not yet
    matched. Waits at most MATCH_TIMEOUT; a mismatch that already timed out (e.g. a subscriber with
    incompatible QoS) is not waited for again while the graph count stays the same.
    """

    def __init__(self, node: Node, publisher: Publisher) -> None:
        self._node, self._pub = node, publisher
        self._unmatched_graph_count: int | None = None

    def __call__(self) -> None:
        node, pub = self._node, self._pub
        graph = node.count_subscribers(pub.topic_name)
        if pub.get_subscription_count() >= graph or graph == self._unmatched_graph_count:
            return
        t0 = time.monotonic()
        matched = wait_for_matched_subscriptions(node, pub)
        waited_ms = (time.monotonic() - t0) * 1e3
        graph = node.count_subscribers(pub.topic_name)
        self._unmatched_graph_count = graph if matched < graph else None
        if matched < graph:
            node.get_logger().warning(
                f'publishing with {matched} of {graph} subscriptions matched after waiting '
                f'{waited_ms:.0f} ms (QoS incompatible or still discovering?)')
        else:
            node.get_logger().info(f'waited {waited_ms:.1f} ms for {graph} subscriptions to match')
