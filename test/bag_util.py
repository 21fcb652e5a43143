"""Bag test helpers: messages as plain objects with the message's attributes (like rclpy's)."""
from __future__ import annotations

import contextlib
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace as Msg

import numpy as np
import pytest

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


@contextlib.contextmanager
def tmpfs(path: Path, size: str = '256k') -> Iterator[Path]:
    """A tmpfs of ``size`` mounted on ``path`` (created) for the block; skips the test without one.

    The suite runs in a private mount namespace as root (scripts/netns.sh: ``unshare --mount``),
    so mounting here changes nothing outside the test process and its children.
    """
    path.mkdir(parents=True, exist_ok=True)
    if not shutil.which('mount'):
        pytest.skip('no mount command: cannot make a small file system to fill')
    done = subprocess.run(['mount', '-t', 'tmpfs', '-o', f'size={size}', 'tmpfs', str(path)],
                          capture_output=True, text=True, timeout=30, check=False)
    if done.returncode != 0:
        pytest.skip(f'cannot mount a {size} tmpfs on {path} (needs root in a private mount namespace, '
                    f'as scripts/test.sh gives): {done.stderr.strip()}')
    try:
        yield path
    finally:
        subprocess.run(['umount', '-l', str(path)], capture_output=True, timeout=30, check=False)


def fill(fs: Path, leave: int) -> Path:
    """A file on the file system of ``fs`` that leaves about ``leave`` bytes free; returns it."""
    free = shutil.disk_usage(fs).free
    filler = fs / 'filler'
    with filler.open('wb') as fh:
        fh.write(b'\0' * max(0, free - leave))
    return filler
