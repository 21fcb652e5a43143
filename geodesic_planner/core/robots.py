"""Robot presets (data only): DH tables of the paper's examples and of common arms.

``load_robot(name_or_path)`` returns a :class:`~geodesic_planner.core.kinematics.Chain` for a preset
name or a URDF file. Units: m, rad; limits in rad/s (m/s) and rad/s^2 (m/s^2).
"""
from __future__ import annotations

import os
import stat
from collections.abc import Callable

import numpy as np

from .errors import KinematicsError, RequestError
from .ik import planar_3r_closed_form
from .kinematics import PRISMATIC, REVOLUTE, Chain, chain_from_dh, rot_x, rot_z, trans

R, P = REVOLUTE, PRISMATIC
PI = np.pi


def planar_3r() -> Chain:
    """Planar 3R arm of the paper's Fig. 4: three revolute joints about z, links of 1 m.

    Has a closed-form IK (paper Table 2; ``ik.planar_3r_closed_form``).
    """
    chain = chain_from_dh(
        'planar_3r', [(0.0, 0.0, 1.0, 0.0)] * 3, [R, R, R],
        lower=[-PI] * 3, upper=[PI] * 3, max_velocity=1.0, max_acceleration=2.0,
        base_link='base_link', tip_link='tool0')
    chain.closed_form_ik = planar_3r_closed_form
    return chain


def rrpp() -> Chain:
    """Simplified XHK5140 boring/milling machine (paper Fig. 7): R, R, P, P (modified DH, docs/maths.md#robots)."""
    a1 = a3 = d5 = 1.0
    rows = [
        (0.0, 0.0, 0.0, 0.0),
        (float(np.arccos(1.0 / np.sqrt(3.0))), a1, 0.0, 0.0),
        (0.0, 0.0, 0.0, 0.0),
        (-PI / 2, a3, 0.0, PI),
    ]
    tool = rot_x(PI) @ rot_z(-PI / 2) @ trans(z=d5)
    return chain_from_dh(
        'rrpp', rows, [R, R, P, P], modified=True, tool=tool,
        joint_names=['theta1', 'theta2', 'd3', 'd4'],
        lower=[-PI, -PI, -2.0, -2.0], upper=[PI, PI, 2.0, 2.0],
        max_velocity=[1.0, 1.0, 0.5, 0.5], max_acceleration=[2.0, 2.0, 1.0, 1.0],
        home=[0.123, -1.539, 0.276, -0.640], tip_link='tool')


def ur5e() -> Chain:
    """Universal Robots UR5e, published standard DH parameters; limits ±2π rad, π rad/s."""
    d = [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996]
    a = [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0]
    alpha = [PI / 2, 0.0, 0.0, PI / 2, -PI / 2, 0.0]
    rows = [(0.0, d[i], a[i], alpha[i]) for i in range(6)]
    names = ['shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint',
             'wrist_1_joint', 'wrist_2_joint', 'wrist_3_joint']
    return chain_from_dh(
        'ur5e', rows, [R] * 6, joint_names=names, lower=[-2 * PI] * 6, upper=[2 * PI] * 6,
        max_velocity=PI, max_acceleration=5.0,
        home=[0.0, -PI / 2, PI / 2, -PI / 2, -PI / 2, 0.0], base_link='base_link', tip_link='tool0')


def panda() -> Chain:
    """Franka Emika Panda (7 joints), Franka's published modified DH and limits; tool = flange."""
    rows = [
        (0.0, 0.0, 0.333, 0.0),
        (-PI / 2, 0.0, 0.0, 0.0),
        (PI / 2, 0.0, 0.316, 0.0),
        (PI / 2, 0.0825, 0.0, 0.0),
        (-PI / 2, -0.0825, 0.384, 0.0),
        (PI / 2, 0.0, 0.0, 0.0),
        (PI / 2, 0.088, 0.0, 0.0),
    ]
    tool = trans(z=0.107)
    return chain_from_dh(
        'panda', rows, [R] * 7, modified=True, tool=tool,
        joint_names=[f'panda_joint{i}' for i in range(1, 8)],
        lower=[-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973],
        upper=[2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973],
        max_velocity=[2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61],
        max_acceleration=[15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0],
        home=[0.0, -PI / 4, 0.0, -3 * PI / 4, 0.0, PI / 2, PI / 4],
        base_link='panda_link0', tip_link='panda_link8')


PRESETS: dict[str, Callable[[], Chain]] = {
    'planar_3r': planar_3r,
    'rrpp': rrpp,
    'ur5e': ur5e,
    'panda': panda,
}


def is_urdf_path(robot: str) -> bool:
    """True when ``robot`` names a URDF file (a ``.urdf`` name or a path), not a preset."""
    return robot.endswith('.urdf') or os.sep in robot


def urdf_text(robot: str, robot_description: str = '') -> str | None:
    """The URDF a model comes from: ``robot_description`` when not empty, else the file ``robot``
    names (:func:`is_urdf_path`), else None (a preset).

    Raises:
        RequestError: the file cannot be read (:func:`read_urdf_file`).
    """
    if robot_description.strip():
        return robot_description
    return read_urdf_file(robot) if is_urdf_path(robot) else None


def read_urdf_file(path: str, *, param: str = 'robot', kind: str = 'URDF') -> str:
    """The text of a URDF file (or an SRDF: ``param``, ``kind`` name it in the errors): a regular
    file (never a FIFO or device) of bounded size, UTF-8.

    Raises:
        RequestError: missing, unreadable, not a regular file, too large, or not UTF-8.
    """
    from .urdf import MAX_URDF_BYTES
    shown = repr(path[:200])
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise RequestError(f'{param}: {kind} {shown} is not a regular file')
        if info.st_size > MAX_URDF_BYTES:
            raise RequestError(f'{param}: {kind} {shown} has {info.st_size} bytes, more than {MAX_URDF_BYTES}')
        # O_NONBLOCK: should the path become a FIFO after the check, open() still returns at once.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, 'rb') as fh:
            data = fh.read(MAX_URDF_BYTES + 1)
    except (OSError, ValueError) as err:  # ValueError: a NUL byte in the path
        why = getattr(err, 'strerror', None) or str(err)
        raise RequestError(f'{param}: cannot read {kind} {shown}: {why}') from err
    if len(data) > MAX_URDF_BYTES:
        raise RequestError(f'{param}: {kind} {shown} has more than {MAX_URDF_BYTES} bytes')
    try:
        return data.decode('utf-8')
    except UnicodeDecodeError as err:
        raise RequestError(f'{param}: {kind} {shown} is not UTF-8 text ({err.reason} at byte {err.start})') from err


def load_robot(name_or_path: str, *, base_link: str | None = None, tip_link: str | None = None) -> Chain:
    """A robot model from a preset name (``planar_3r``, ``rrpp``, ``ur5e``, ``panda``) or a URDF file.

    Args:
        name_or_path: preset name, or path to a ``.urdf`` file.
        base_link, tip_link: chain ends for a URDF (defaults: root link, the single leaf).

    Raises:
        RequestError: unknown preset name / missing file.
        KinematicsError: the URDF is not a usable serial chain.
    """
    if not isinstance(name_or_path, str) or not name_or_path:
        raise RequestError(f'robot: expected a preset name or URDF path, got {name_or_path!r}')
    if name_or_path in PRESETS:
        if base_link is not None or tip_link is not None:
            raise RequestError(f'robot: base_link/tip_link apply to URDF models, not to the preset '
                               f'{name_or_path!r}')
        return PRESETS[name_or_path]()
    if is_urdf_path(name_or_path):
        from .urdf import chain_from_urdf
        return chain_from_urdf(read_urdf_file(name_or_path), base_link=base_link, tip_link=tip_link)
    raise RequestError(
        f'robot: unknown robot {name_or_path!r}; presets are {sorted(PRESETS)}, or give a .urdf path')


__all__ = ['PRESETS', 'KinematicsError', 'load_robot', 'panda', 'planar_3r', 'rrpp', 'ur5e']
