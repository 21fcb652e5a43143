"""The planner's ``~/path_markers`` topic: the latest plan's tool path for RViz, built only for a reader.

The topic is reliable and transient local with depth 1, so an RViz started later still gets a
marker array. Building one (a line strip through every tool pose, axes at the ends) costs about
0.2 ms of Python per plan, and publishing it as much again; a planner serving tens of plans per
second with no RViz open would spend it on nobody. So :meth:`LatestPathMarkers.offer` keeps the
latest plan's tool poses and builds and publishes its markers only while a subscription is
matched; when one matches later (the publisher's matched event), the latest plan's markers are
published then. A reader therefore always ends up with the latest plan's markers.
"""
from __future__ import annotations

import threading

import numpy as np
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from visualization_msgs.msg import MarkerArray

from . import conversions as cv

__all__ = ['LatestPathMarkers']


class LatestPathMarkers:
    """Publisher of ``topic`` (relative to ``node``) carrying the latest plan's path markers.

    Thread-safe: :meth:`offer` is called from the plan's thread, the matched event from an
    executor thread.
    """

    def __init__(self, node: Node, topic: str = '~/path_markers') -> None:
        self._lock = threading.Lock()
        self._latest: tuple[np.ndarray, str] | None = None   # tool poses (N, 4, 4), frame
        self.published = 0
        self.publisher = node.create_publisher(
            MarkerArray, topic,
            QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.TRANSIENT_LOCAL),
            event_callbacks=PublisherEventCallbacks(matched=self._on_matched))

    def offer(self, tool_poses: np.ndarray, frame_id: str) -> bool:
        """A new plan's tool poses (N, 4, 4), base frame ``frame_id``, m: its markers are published
        now if a subscription is matched (True), else when one matches."""
        with self._lock:
            self._latest = (tool_poses, frame_id)
        if self.publisher.get_subscription_count() == 0:
            return False
        self._publish_latest()
        return True

    def _on_matched(self, status: object) -> None:
        if getattr(status, 'current_count_change', 0) > 0:
            self._publish_latest()

    def _publish_latest(self) -> None:
        with self._lock:
            latest = self._latest
            if latest is None:
                return
            self.publisher.publish(cv.path_markers(*latest))
            self.published += 1
