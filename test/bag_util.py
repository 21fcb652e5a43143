"""Bag test helpers: messages as plain objects with the message's attributes (like rclpy's)."""
from __future__ import annotations

import shutil
from pathlib import Path
from types import SimpleNamespace as Msg

import numpy as np

IN, OUT, JS = '/geodesic_planner/joint_trajectory', '/trajectory_processor/joint_trajectory', '/joint_states'


def _duration(t: float) -> Msg:
    ns = round(t * 1e9)
    return Msg(sec=ns // 10**9, nanosec=ns % 10**9)


def trajectory(t, q, dq=None, ddq=None, names=('j1', 'j2', 'j3'), frame_id='base', stamp=(0, 0)):
    """A JointTrajectory as a plain object with the message's attributes (like an rclpy message)."""
    points = [Msg(positions=list(q[i]), velocities=[] if dq is None else list(dq[i]),
                 accelerations=[] if ddq is None else list(ddq[i]), effort=[],
                 time_from_start=_duration(ti)) for i, ti in enumerate(t)]
    return Msg(header=Msg(stamp=Msg(sec=stamp[0], nanosec=stamp[1]), frame_id=frame_id),
              joint_names=list(names), points=points)


def joint_state(i: int) -> Msg:
    return Msg(header=Msg(stamp=Msg(sec=i, nanosec=0), frame_id=''), name=['j1', 'j2', 'j3'],
              position=[0.1 * i, 0.2, 0.3], velocity=[], effort=[])


def example(rng: np.random.Generator, n: int):
    t = np.cumsum(rng.uniform(0.1, 0.5, n)) - 0.1
    t[0] = 0.0
    return t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))


def copy_as_killed(src: Path, dst: Path) -> None:
    """What a SIGKILL leaves: the files as they are now, no close(), no metadata.yaml."""
    shutil.copytree(src, dst)
    assert not (dst / 'metadata.yaml').exists()
