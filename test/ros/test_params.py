"""The parameter schema shared by both nodes (no node started)."""
from __future__ import annotations

import math

import pytest

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter

from geodesic_planner.ros import params


def test_both_nodes_declare_from_one_table() -> None:
    for name in params.PLANNER_PARAMETERS + params.PROCESSOR_PARAMETERS:
        spec = params.SCHEMA[name]
        assert spec.description, name
    shared = set(params.PLANNER_PARAMETERS) & set(params.PROCESSOR_PARAMETERS)
    assert shared == {'sample_period', 'velocity_scaling'}
    assert params.defaults(shared) == {'sample_period': 0.01, 'velocity_scaling': 1.0}


@pytest.mark.parametrize('name, value, reason', [
    ('velocity_scaling', 0.0, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', 1.5, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', math.nan, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', 'fast', 'velocity_scaling: must be a number'),
    ('velocity_scaling', True, 'velocity_scaling: must be a number'),
    ('sample_period', -0.01, 'sample_period: must be in [1e-05, 10]'),
    ('sample_period', 5e-324, 'sample_period: must be in [1e-05, 10]'),
    ('plan_timeout', math.inf, 'plan_timeout: must be in [1e-06, 3600]'),
    ('plan_timeout', 1e300, 'plan_timeout: must be in [1e-06, 3600]'),
    ('orientation_weight', 1e300, 'orientation_weight: must be in [0.001, 1000]'),
    ('position_weight', 0.0, 'position_weight: must be in [0.001, 1000]'),
    ('max_tool_speed', -1.0, 'max_tool_speed: must be finite and >= 0'),
    ('allowed_start_tolerance', math.nan, 'allowed_start_tolerance: must be finite and >= 0'),
    ('metric', 'euclid', 'metric: must be one of paper, position'),
    ('storage', 'rosbag1', 'storage: must be one of mcap, sqlite3'),
    ('max_velocity', [1.0, -2.0], 'max_velocity: every value must be finite and > 0'),
    ('max_acceleration', ['a'], 'max_acceleration: expected an array of numbers'),
    ('joint_names', [1, 2], 'joint_names: expected an array of strings'),
    ('record_topics', [':'], 'record_topics: must be a list of topic names'),
    ('input_topic', '', 'input_topic: must be a non-empty topic name'),
])
def test_invalid_values_named(name: str, value: object, reason: str) -> None:
    found = params.problem(name, value)
    assert found is not None and found.startswith(reason), found


@pytest.mark.parametrize('name, value', [
    ('velocity_scaling', 1), ('velocity_scaling', 0.25), ('sample_period', 0.02),
    ('sample_period', 1e-5), ('plan_timeout', 3600), ('orientation_weight', 1000),
    ('max_tool_speed', 0.0), ('allowed_start_tolerance', 0),
    ('max_velocity', []), ('max_velocity', [1, 2.5]), ('joint_names', []), ('storage', 'sqlite3'),
    ('record_topics', ['/a', '/b=std_msgs/msg/String']), ('robot', 'anything'),
])
def test_valid_values_pass(name: str, value: object) -> None:
    assert params.problem(name, value) is None


def test_rejection_checks_only_owned_names() -> None:
    bad = Parameter('velocity_scaling', Parameter.Type.DOUBLE, 2.0)
    assert params.rejection([bad], params.PROCESSOR_PARAMETERS).startswith('velocity_scaling:')
    assert params.rejection([bad], ['sample_period']) is None
    unset = Parameter('sample_period')
    assert params.rejection([unset], ['sample_period']) == 'sample_period: cannot be undeclared'


def test_descriptors_type_numbers_dynamically() -> None:
    assert params.SCHEMA['velocity_scaling'].descriptor().dynamic_typing
    assert params.SCHEMA['max_velocity'].descriptor().dynamic_typing
    assert not params.SCHEMA['robot'].descriptor().dynamic_typing
    assert params.SCHEMA['bag_path'].descriptor().read_only
