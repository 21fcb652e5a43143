"""The planner's path markers (ros.path_markers): built only for a matched reader, and a reader that
matches later still gets the latest plan's markers."""
from __future__ import annotations

import uuid
from typing import Any

import numpy as np
import pytest

pytest.importorskip('rclpy')

from numpy.testing import assert_allclose
from visualization_msgs.msg import Marker, MarkerArray

from geodesic_planner.core.transforms import make_transform, so3_exp
from geodesic_planner.ros.path_markers import LatestPathMarkers
from tools.graph import Collector, latched_qos
from tools.process import wait_until

pytestmark = pytest.mark.ros

DEADLINE = 20.0


def _poses(offset: float, n: int) -> np.ndarray:
    """n tool poses along x from ``offset``, m."""
    return np.stack([make_transform([offset + 0.01 * i, 0.2, 0.3], so3_exp([0.0, 0.0, 0.1 * i]))
                     for i in range(n)])


def _line(msg: MarkerArray) -> np.ndarray:
    line = next(m for m in msg.markers if m.type == Marker.LINE_STRIP)
    return np.array([[p.x, p.y, p.z] for p in line.points])


def test_markers_wait_for_a_reader_and_it_gets_the_latest_plan(ros_node: Any) -> None:
    topic = f'/path_markers_{uuid.uuid4().hex[:8]}'
    markers = LatestPathMarkers(ros_node, topic)
    first, latest = _poses(0.0, 5), _poses(0.5, 7)
    # no reader: nothing is built or published
    assert markers.offer(first, 'base_link') is False
    assert markers.offer(latest, 'base_link') is False
    assert markers.published == 0
    # a reader that matches now gets the latest plan's markers (the matched event publishes them)
    reader = Collector(ros_node, MarkerArray, topic, latched_qos())
    msg = reader.wait_for(1, DEADLINE)[0]
    assert markers.published == 1
    assert msg.markers[1].header.frame_id == 'base_link'
    assert_allclose(_line(msg), latest[:, :3, 3], atol=1e-12)
    # with the reader matched, a new plan's markers are published at once
    newer = _poses(-0.3, 3)
    assert markers.offer(newer, 'tool_base') is True
    msgs = reader.wait_for(2, DEADLINE)
    assert_allclose(_line(msgs[-1]), newer[:, :3, 3], atol=1e-12)
    assert msgs[-1].markers[1].header.frame_id == 'tool_base'
    wait_until(lambda: markers.published == 2, DEADLINE, what='two publishes')
    ros_node.destroy_subscription(reader.subscription)
    ros_node.destroy_publisher(markers.publisher)
