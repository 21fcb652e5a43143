"""Conversions between ROS messages and numpy arrays (no maths beyond unit handling)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Duration
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint


@dataclass(frozen=True)
class TrajectoryArrays:
    """A joint trajectory as arrays: times (N,) in s; positions/velocities/accelerations (N, dof)."""

    joint_names: list[str]
    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None


def seconds_to_duration(t: float) -> Duration:
    """builtin_interfaces/Duration from seconds (rounded to the nanosecond)."""
    ns = int(round(float(t) * 1e9))
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def duration_to_seconds(d: Duration) -> float:
    """Seconds of a builtin_interfaces/Duration."""
    return d.sec + d.nanosec * 1e-9


def arrays_to_joint_trajectory(
    joint_names: list[str],
    t: np.ndarray,
    positions: np.ndarray,
    velocities: np.ndarray | None = None,
    accelerations: np.ndarray | None = None,
    frame_id: str = '',
) -> JointTrajectory:
    """JointTrajectory with header stamp zero ("start on arrival").

    Args:
        joint_names: dof names.
        t: time_from_start of each point, shape (N,), s.
        positions, velocities, accelerations: shape (N, dof); rad (m), rad/s, rad/s^2.
        frame_id: header frame.
    """
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.joint_names = list(joint_names)
    pos = np.asarray(positions, dtype=float)
    vel = None if velocities is None else np.asarray(velocities, dtype=float)
    acc = None if accelerations is None else np.asarray(accelerations, dtype=float)
    points = []
    for i, ti in enumerate(np.asarray(t, dtype=float)):
        pt = JointTrajectoryPoint()
        pt.positions = pos[i].tolist()
        if vel is not None:
            pt.velocities = vel[i].tolist()
        if acc is not None:
            pt.accelerations = acc[i].tolist()
        pt.time_from_start = seconds_to_duration(ti)
        points.append(pt)
    msg.points = points
    return msg


def joint_trajectory_to_arrays(msg: JointTrajectory) -> TrajectoryArrays:
    """Arrays of a JointTrajectory; velocities/accelerations are None unless every point has them."""
    n = len(msg.joint_names)
    t = np.array([duration_to_seconds(p.time_from_start) for p in msg.points], dtype=float)
    pos = np.array([list(p.positions) for p in msg.points], dtype=float).reshape(-1, n)

    def _field(name: str) -> np.ndarray | None:
        rows = [list(getattr(p, name)) for p in msg.points]
        if not rows or any(len(r) != n for r in rows):
            return None
        return np.array(rows, dtype=float).reshape(-1, n)

    return TrajectoryArrays(list(msg.joint_names), t, pos, _field('velocities'), _field('accelerations'))


def validate_joint_trajectory(msg: JointTrajectory) -> list[str]:
    """Problems joint_trajectory_controller would reject the message for (empty list: valid).

    Checks: non-empty joint names (unique), non-empty points, every point's positions (and
    velocities/accelerations when present) sized like joint_names, finite values,
    strictly increasing time_from_start.
    """
    problems: list[str] = []
    n = len(msg.joint_names)
    if n == 0:
        problems.append('empty joint_names')
    if len(set(msg.joint_names)) != n:
        problems.append('duplicate joint names')
    if not msg.points:
        problems.append('no points')
    last = -1.0
    for i, p in enumerate(msg.points):
        if len(p.positions) != n:
            problems.append(f'point {i}: {len(p.positions)} positions for {n} joints')
        for name in ('velocities', 'accelerations'):
            vals = getattr(p, name)
            if len(vals) not in (0, n):
                problems.append(f'point {i}: {len(vals)} {name} for {n} joints')
            if not np.all(np.isfinite(np.asarray(vals, dtype=float))):
                problems.append(f'point {i}: non-finite {name}')
        if not np.all(np.isfinite(np.asarray(p.positions, dtype=float))):
            problems.append(f'point {i}: non-finite positions')
        ti = duration_to_seconds(p.time_from_start)
        if ti <= last:
            problems.append(f'point {i}: time_from_start {ti:.9f} s not after {last:.9f} s')
        last = ti
    return problems
