"""Per-joint limits from a MoveIt-style ``joint_limits.yaml``.

The file MoveIt (and Pilz) read beside the URDF::

    default_velocity_scaling_factor: 0.5        # optional
    default_acceleration_scaling_factor: 0.5    # optional
    joint_limits:
      shoulder_pan_joint:
        has_velocity_limits: true
        max_velocity: 2.0                       # rad/s (m/s for a prismatic joint)
        has_acceleration_limits: true
        max_acceleration: 4.0                   # rad/s^2
        has_jerk_limits: false
        max_jerk: 0.0                           # rad/s^3

The block may also sit under ``robot_description_planning:`` (the ROS parameter namespace MoveIt
uses). A limit counts only when its ``has_*_limits`` flag is true. Joints the robot does not have
are ignored (a gripper's, say); robot joints the file does not name keep the model's limits.
"""
from __future__ import annotations

import math
import os
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..core.errors import RequestError
from ..core.kinematics import Chain

__all__ = ['MAX_FILE_BYTES', 'JointLimits', 'apply_joint_limits', 'load_joint_limits', 'parse_joint_limits']

#: Largest joint_limits.yaml read, bytes (a real one is a few kB).
MAX_FILE_BYTES = 1 << 20

_KINDS = (('velocity', 'max_velocity'), ('acceleration', 'max_acceleration'), ('jerk', 'max_jerk'))


@dataclass(frozen=True)
class JointLimits:
    """Limits by joint name; a joint or a kind absent from the file is absent here.

    Attributes:
        max_velocity, max_acceleration, max_jerk: joint name -> limit (rad/s, rad/s^2, rad/s^3;
            m/s... for prismatic joints), only where the file's ``has_*_limits`` is true.
        default_velocity_scaling_factor, default_acceleration_scaling_factor: in (0, 1]; 1 when unset.
    """

    max_velocity: Mapping[str, float]
    max_acceleration: Mapping[str, float]
    max_jerk: Mapping[str, float]
    default_velocity_scaling_factor: float = 1.0
    default_acceleration_scaling_factor: float = 1.0

    def per_joint(self, kind: str, joint_names: Sequence[str]) -> np.ndarray:
        """Limits of one kind ('velocity', 'acceleration', 'jerk') in the given joint order; NaN where unset."""
        table = {'velocity': self.max_velocity, 'acceleration': self.max_acceleration, 'jerk': self.max_jerk}[kind]
        return np.array([table.get(name, math.nan) for name in joint_names], dtype=float)


def _flag(value: object, where: str) -> bool:
    if isinstance(value, bool):
        return value
    raise RequestError(f'{where}: expected true or false, got {value!r}')


def _positive(value: object, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RequestError(f'{where}: expected a number, got {value!r}')
    x = float(value)
    if not (math.isfinite(x) and x > 0):
        raise RequestError(f'{where}: must be finite and > 0, got {value!r}')
    return x


def _scaling(data: Mapping[str, Any], key: str) -> float:
    if key not in data:
        return 1.0
    x = _positive(data[key], key)
    if x > 1.0:
        raise RequestError(f'{key}: must lie in (0, 1], got {x!r}')
    return x


def parse_joint_limits(data: object) -> JointLimits:
    """Limits from the parsed YAML document (see the module docstring for the format).

    Raises:
        RequestError: not a mapping, no ``joint_limits`` block, or a bad value (the message names the
            joint and the key).
    """
    if isinstance(data, Mapping) and 'robot_description_planning' in data:
        data = data['robot_description_planning']
    if not isinstance(data, Mapping) or not isinstance(data.get('joint_limits'), Mapping):
        raise RequestError('joint limits: expected a mapping with a "joint_limits" block')
    tables: dict[str, dict[str, float]] = {key: {} for _, key in _KINDS}
    for name, entry in data['joint_limits'].items():
        if not isinstance(name, str) or not isinstance(entry, Mapping):
            raise RequestError(f'joint_limits: entry {str(name)[:80]!r} must be a mapping of limits')
        for kind, key in _KINDS:
            flag = f'has_{kind}_limits'
            if flag in entry and _flag(entry[flag], f'joint_limits.{name}.{flag}'):
                if key not in entry:
                    raise RequestError(f'joint_limits.{name}: {flag} is true but {key} is missing')
                tables[key][name] = _positive(entry[key], f'joint_limits.{name}.{key}')
    return JointLimits(
        max_velocity=tables['max_velocity'], max_acceleration=tables['max_acceleration'],
        max_jerk=tables['max_jerk'],
        default_velocity_scaling_factor=_scaling(data, 'default_velocity_scaling_factor'),
        default_acceleration_scaling_factor=_scaling(data, 'default_acceleration_scaling_factor'))


def load_joint_limits(path: str | os.PathLike[str]) -> JointLimits:
    """Read a joint_limits.yaml: a regular file of at most :data:`MAX_FILE_BYTES`.

    Raises:
        RequestError: missing, not a regular file, too large, not YAML, or bad values.
    """
    p = Path(path)
    try:
        st = p.stat()
    except OSError as err:
        raise RequestError(f'joint limits file {str(p)[:200]!r}: {err.strerror or err}') from err
    if not stat.S_ISREG(st.st_mode):
        raise RequestError(f'joint limits file {str(p)[:200]!r}: not a regular file')
    if st.st_size > MAX_FILE_BYTES:
        raise RequestError(f'joint limits file {str(p)[:200]!r}: {st.st_size} bytes, more than {MAX_FILE_BYTES}')
    with p.open('rb') as fh:
        text = fh.read(MAX_FILE_BYTES + 1)
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise RequestError(f'joint limits file {str(p)[:200]!r}: not valid YAML ({err})') from err
    return parse_joint_limits(data)


def apply_joint_limits(robot: Chain, limits: JointLimits) -> tuple[Chain, list[str]]:
    """The robot with the file's velocity and acceleration limits, and notes for the log.

    A file's velocity limit replaces the model's only where it is tighter: the URDF's ``velocity``
    is the drive's rating, which a configuration file may lower but not raise (a raise is ignored,
    with a note). Acceleration limits (a URDF has none) replace the model's. Jerk limits are not
    part of the model; read them with ``limits.per_joint('jerk', robot.joint_names)``.
    """
    notes: list[str] = []
    names = robot.joint_names
    unknown = sorted(set(limits.max_velocity) | set(limits.max_acceleration) | set(limits.max_jerk))
    unknown = [n for n in unknown if n not in names]
    if unknown:
        notes.append(f'joint limits for joints the robot does not have are ignored: {", ".join(unknown[:10])}')
    vel = limits.per_joint('velocity', names)
    raised = ~np.isnan(vel) & (vel > robot.max_velocity)
    for i in np.flatnonzero(raised):
        notes.append(f'joint {names[i]!r}: max_velocity {vel[i]:g} is above the model\'s {robot.max_velocity[i]:g}; '
                     'keeping the model\'s')
    max_velocity = np.where(np.isnan(vel), robot.max_velocity, np.minimum(vel, robot.max_velocity))
    acc = limits.per_joint('acceleration', names)
    max_acceleration = np.where(np.isnan(acc), robot.max_acceleration, acc)
    return robot.with_limits(max_velocity=max_velocity.tolist(), max_acceleration=max_acceleration.tolist()), notes
