"""Fixtures shared by the core tests: planners with a wall-clock solve budget."""
from __future__ import annotations

import pytest
from planning_checks import SOLVE_TIME_LIMIT

from geodesic_planner import GeodesicPlanner, load_robot


@pytest.fixture(scope='module')
def planar() -> GeodesicPlanner:
    """Planar 3R planner (paper Fig. 4) with the fuzz solve budget."""
    return GeodesicPlanner(load_robot('planar_3r'), time_limit=SOLVE_TIME_LIMIT)


@pytest.fixture(scope='module')
def ur5e_planner() -> GeodesicPlanner:
    """UR5e planner with the fuzz solve budget."""
    return GeodesicPlanner(load_robot('ur5e'), time_limit=SOLVE_TIME_LIMIT)
