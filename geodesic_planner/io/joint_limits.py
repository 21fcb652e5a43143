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

from ..core.errors import GeodesicPlannerError, RequestError
from ..core.kinematics import Chain

__all__ = ['MAX_FILE_BYTES', 'JointLimits', 'MergedLimits', 'apply_joint_limits', 'load_joint_limits', 'merge_limits',
           'parse_joint_limits']

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


@dataclass(frozen=True)
class MergedLimits:
    """A robot's limits after every source, lowest priority first: the model's (URDF or preset), a
    joint_limits.yaml, then explicit per-joint values.

    Attributes:
        max_velocity, max_acceleration: (dof,), rad/s (m/s), rad/s^2 (m/s^2).
        max_jerk: (dof,) rad/s^3 (m/s^3), or None (no jerk limit: none given, or not for every
            joint, which a note says).
        default_velocity_factor, default_acceleration_factor: the file's default scaling factors
            (1 without one).
        notes: what was ignored or assumed, for the log.
    """

    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_jerk: np.ndarray | None
    default_velocity_factor: float = 1.0
    default_acceleration_factor: float = 1.0
    notes: tuple[str, ...] = ()


def _per_joint(name: str, value: Sequence[float] | np.ndarray | None, default: np.ndarray, dof: int) -> np.ndarray:
    """Per-joint limits from a value: empty -> default, 1 value -> all joints."""
    vals = [] if value is None else list(value)
    if not vals:
        return np.asarray(default, dtype=float).copy()
    arr = np.array(vals, dtype=float)
    if arr.size not in (1, dof):
        raise RequestError(f'{name}: {arr.size} values for a robot with {dof} joints '
                           f'(give {dof} values, one value for all joints, or none for defaults)')
    return np.broadcast_to(arr, (dof,)).copy()


def merge_limits(robot: Chain, joint_limits: str, max_velocity: Sequence[float] | None,
                 max_acceleration: Sequence[float] | None, max_jerk: Sequence[float] | None, *,
                 accel_known: bool) -> MergedLimits:
    """Merge the model's limits, a joint_limits.yaml (path, '' for none) and explicit values
    (empty: keep; one value: every joint).

    ``accel_known``: the model's acceleration limits are real (a preset), not a URDF's default
    (URDF has none): joints left without a known one get a note.

    Raises:
        RequestError: a value count that fits no joint count; the file's errors (named
            ``joint_limits:``).
    """
    dof = robot.dof
    known = np.full(dof, bool(accel_known))
    velocity, acceleration = robot.max_velocity, robot.max_acceleration
    fv = fa = 1.0
    notes: list[str] = []
    jerk = np.full(dof, np.nan)
    if joint_limits.strip():
        try:
            limits = load_joint_limits(joint_limits)
        except GeodesicPlannerError as err:
            raise RequestError(f'joint_limits: {err}') from err
        limited, file_notes = apply_joint_limits(robot, limits)
        known |= ~np.isnan(limits.per_joint('acceleration', robot.joint_names))
        velocity, acceleration = limited.max_velocity.copy(), limited.max_acceleration.copy()
        jerk = limits.per_joint('jerk', robot.joint_names)
        fv, fa = limits.default_velocity_scaling_factor, limits.default_acceleration_scaling_factor
        notes += [f'joint_limits: {n}' for n in file_notes]
    jerk = _per_joint('max_jerk', max_jerk, jerk, dof)
    final_jerk: np.ndarray | None = jerk
    if np.isnan(jerk).any():
        final_jerk = None
        if not np.isnan(jerk).all():
            missing = [n for n, x in zip(robot.joint_names, jerk) if np.isnan(x)]
            notes.append(f'jerk limits not applied: joints {missing} have none (joint_limits gives '
                         'some joints one; set max_jerk for every joint to limit the jerk)')
    vel = _per_joint('max_velocity', max_velocity, velocity, dof)
    acc = _per_joint('max_acceleration', max_acceleration, acceleration, dof)
    if list(max_acceleration or []):
        known[:] = True
    if not known.all():
        missing = [n for n, k in zip(robot.joint_names, known) if not k]
        used = sorted({f'{a:g}' for a, k in zip(acc, known) if not k})
        notes.append(
            f'no acceleration limit for joints {missing} from the model, joint_limits or '
            f'max_acceleration: using the default {", ".join(used)} rad/s^2 (m/s^2 for prismatic '
            'joints); set them in a joint_limits.yaml')
    return MergedLimits(vel, acc, final_jerk, fv, fa, tuple(notes))
