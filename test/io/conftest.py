"""Fixtures shared by the bag tests."""
from __future__ import annotations

import pytest

from geodesic_planner.io.bags import make_typestore


@pytest.fixture
def ts():
    """A ROS 2 Jazzy typestore (rosbags), one per test."""
    return make_typestore()
