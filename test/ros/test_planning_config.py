"""The planner's configuration from parameter values (no DDS): limits from joint_limits.yaml."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner.ros import params
from geodesic_planner.ros.planning import build_config


def _config(tmp_path: Path, limits: dict, **values: object):
    path = tmp_path / 'joint_limits.yaml'
    path.write_text(yaml.safe_dump({'joint_limits': limits}))
    v = params.defaults(params.PLANNER_PARAMETERS)
    v.update(robot='planar_3r', joint_limits=str(path), **values)
    return build_config(v)


def _jerk(j: float | None) -> dict:
    return {'has_jerk_limits': j is not None, 'max_jerk': j or 0.0}


def test_jerk_limits_from_the_yaml(tmp_path: Path) -> None:
    config = _config(tmp_path, {f'joint{i}': _jerk(10.0 * i) for i in (1, 2, 3)})
    np.testing.assert_array_equal(config.max_jerk, [10.0, 20.0, 30.0])
    # max_jerk overrides the file
    config = _config(tmp_path, {f'joint{i}': _jerk(10.0 * i) for i in (1, 2, 3)}, max_jerk=[5.0])
    np.testing.assert_array_equal(config.max_jerk, [5.0, 5.0, 5.0])


def test_partial_jerk_limits_are_not_applied_and_said_so(tmp_path: Path) -> None:
    config = _config(tmp_path, {'joint1': _jerk(10.0), 'joint2': _jerk(None), 'joint3': _jerk(30.0)})
    assert config.max_jerk is None
    assert any("jerk limits not applied: joints ['joint2']" in n for n in config.notes), config.notes


def test_no_jerk_limit_by_default() -> None:
    v = params.defaults(params.PLANNER_PARAMETERS)
    assert build_config(v).max_jerk is None
