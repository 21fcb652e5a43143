"""MoveIt-style joint_limits.yaml: parsing, validation, and how it combines with the robot model."""
from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import yaml
from numpy.testing import assert_array_equal

from geodesic_planner import load_robot
from geodesic_planner.core.errors import RequestError
from geodesic_planner.io.joint_limits import (MAX_FILE_BYTES, apply_joint_limits, load_joint_limits,
                                              parse_joint_limits)

UR5E = load_robot('ur5e')
GOOD = {
    'default_velocity_scaling_factor': 0.5,
    'joint_limits': {
        'shoulder_pan_joint': {'has_velocity_limits': True, 'max_velocity': 0.5,
                               'has_acceleration_limits': True, 'max_acceleration': 1.5,
                               'has_jerk_limits': True, 'max_jerk': 20.0},
        'elbow_joint': {'has_velocity_limits': False, 'max_velocity': 0.01,
                        'has_acceleration_limits': True, 'max_acceleration': 2},
        'gripper_finger_joint': {'has_velocity_limits': True, 'max_velocity': 0.1},
    },
}


def test_only_flagged_limits_count_and_order_follows_the_robot() -> None:
    limits = parse_joint_limits(GOOD)
    names = UR5E.joint_names
    vel = limits.per_joint('velocity', names)
    acc = limits.per_joint('acceleration', names)
    jerk = limits.per_joint('jerk', names)
    i_pan, i_elbow = names.index('shoulder_pan_joint'), names.index('elbow_joint')
    assert vel[i_pan] == 0.5 and math.isnan(vel[i_elbow])          # has_velocity_limits: false
    assert acc[i_pan] == 1.5 and acc[i_elbow] == 2.0
    assert jerk[i_pan] == 20.0 and np.isnan(np.delete(jerk, i_pan)).all()
    assert limits.default_velocity_scaling_factor == 0.5
    assert limits.default_acceleration_scaling_factor == 1.0


def test_moveit_parameter_namespace_is_accepted() -> None:
    limits = parse_joint_limits({'robot_description_planning': GOOD})
    assert limits.max_velocity == {'shoulder_pan_joint': 0.5, 'gripper_finger_joint': 0.1}


def test_apply_tightens_velocity_sets_acceleration_and_notes_the_rest() -> None:
    loose = {'joint_limits': {**GOOD['joint_limits'],
                              'wrist_1_joint': {'has_velocity_limits': True, 'max_velocity': 1e3}}}
    robot, notes = apply_joint_limits(UR5E, parse_joint_limits(loose))
    names = UR5E.joint_names
    expected_v = UR5E.max_velocity.copy()
    expected_v[names.index('shoulder_pan_joint')] = 0.5
    expected_a = UR5E.max_acceleration.copy()
    expected_a[names.index('shoulder_pan_joint')] = 1.5
    expected_a[names.index('elbow_joint')] = 2.0
    assert_array_equal(robot.max_velocity, expected_v)
    assert_array_equal(robot.max_acceleration, expected_a)
    assert any('gripper_finger_joint' in n and 'ignored' in n for n in notes)
    assert any("'wrist_1_joint'" in n and 'keeping the model' in n for n in notes)
    assert robot.joint_names == names


@pytest.mark.parametrize(('data', 'cause'), [
    ([], 'joint_limits'),
    ({'limits': {}}, 'joint_limits'),
    ({'joint_limits': {'a': 3}}, "entry 'a'"),
    ({'joint_limits': {'a': {'has_velocity_limits': True}}}, 'max_velocity is missing'),
    ({'joint_limits': {'a': {'has_velocity_limits': 'yes', 'max_velocity': 1}}}, 'true or false'),
    ({'joint_limits': {'a': {'has_acceleration_limits': True, 'max_acceleration': 0}}}, '> 0'),
    ({'joint_limits': {'a': {'has_acceleration_limits': True, 'max_acceleration': math.inf}}}, 'finite'),
    ({'joint_limits': {'a': {'has_jerk_limits': True, 'max_jerk': '5'}}}, 'expected a number'),
    ({'joint_limits': {}, 'default_velocity_scaling_factor': 1.5}, r'\(0, 1\]'),
])
def test_bad_documents_are_refused_with_the_place_named(data: object, cause: str) -> None:
    with pytest.raises(RequestError, match=cause):
        parse_joint_limits(data)


def test_file_sources_are_bounded(tmp_path: Path) -> None:
    good = tmp_path / 'joint_limits.yaml'
    good.write_text(yaml.safe_dump(GOOD))
    assert load_joint_limits(good).max_acceleration['elbow_joint'] == 2.0
    with pytest.raises(RequestError, match='not a regular file'):
        load_joint_limits(tmp_path)
    fifo = tmp_path / 'fifo'
    os.mkfifo(fifo)
    with pytest.raises(RequestError, match='not a regular file'):   # never blocks on open
        load_joint_limits(fifo)
    big = tmp_path / 'big.yaml'
    big.write_bytes(b'#' * (MAX_FILE_BYTES + 1))
    with pytest.raises(RequestError, match='more than'):
        load_joint_limits(big)
    with pytest.raises(RequestError, match='No such file'):
        load_joint_limits(tmp_path / 'missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('joint_limits: [unclosed')
    with pytest.raises(RequestError, match='not valid YAML'):
        load_joint_limits(bad)


def test_merge_limits_priorities_and_notes(tmp_path) -> None:
    """Model < file < explicit values; jerk only when every joint has one (else a note); a value
    count that fits no joint count is refused."""
    import numpy as np
    import pytest as _pytest

    from geodesic_planner import load_robot
    from geodesic_planner.core.errors import RequestError
    from geodesic_planner.io.joint_limits import merge_limits

    robot = load_robot('ur5e')
    names = robot.joint_names
    path = tmp_path / 'joint_limits.yaml'
    path.write_text(f'joint_limits:\n  {names[0]}: {{has_velocity_limits: true, max_velocity: 0.5,\n'
                    '    has_jerk_limits: true, max_jerk: 9.0}\n')
    lim = merge_limits(robot, str(path), [], [], [], accel_known=True)
    assert lim.max_velocity[0] == 0.5 and np.array_equal(lim.max_velocity[1:], robot.max_velocity[1:])
    assert lim.max_jerk is None and any('jerk limits not applied' in n for n in lim.notes)
    lim = merge_limits(robot, str(path), [0.3], [2.0], [7.0], accel_known=True)
    assert np.all(lim.max_velocity == 0.3) and np.all(lim.max_acceleration == 2.0)
    assert lim.max_jerk is not None and np.all(lim.max_jerk == 7.0)
    lim = merge_limits(robot, '', [], [], [], accel_known=False)
    assert any('no acceleration limit' in n for n in lim.notes)
    with _pytest.raises(RequestError, match='max_velocity: 2 values'):
        merge_limits(robot, '', [1.0, 2.0], [], [], accel_known=True)
