"""Robot presets (load_robot): names and paths that must be refused with a reason."""
from __future__ import annotations

from planning_checks import expect_error

from geodesic_planner import load_robot
from geodesic_planner.core.errors import RequestError


def test_regression_load_robot_nul() -> None:
    """Found by the fuzzer (open()'s bare ValueError)."""
    expect_error('regression', lambda: load_robot('a\x00b.urdf'), RequestError,
                 r"^robot: cannot read URDF 'a\\x00b\.urdf': embedded null byte$")
