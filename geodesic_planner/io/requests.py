"""Planning requests from YAML files (the format of ``msg_examples/*.yaml``).

    robot: planar_3r            # preset name or URDF path (relative to the YAML file)
    metric: paper               # optional: paper | position; position_weight, orientation_weight, epsilon
    start:                      # geometry_msgs/Pose as `ros2 service call` writes it
      position: {x: 2.5, y: 1.5, z: 0.0}
      orientation: {x: 0.0, y: 0.0, z: 0.2588, w: 0.9659}
    goal: {...}                 # or start_joints: [...] / goal_joints: [...]
    via: [{...}, ...]           # optional intermediate poses (piecewise geodesic)
    blend_radius: 0.02          # optional, m: pass each via pose within this distance without stopping
    tolerance: 0.001            # optional: allowed distance to the nearest reachable pose
    method: auto                # optional: auto (pull-back where it applies) | collocation (IK at the ends only)

Or, instead of goal/via, a sequence of motions (LIN, CIRC, PTP; core/motions.py), each from where
the previous one ended, blended at its goal within its own ``blend_radius`` (the last one 0)::

    sequence:
      - {motion: LIN, goal: {...}, blend_radius: 0.03}
      - {motion: CIRC, goal: {...}, center: [x, y, z], blend_radius: 0.03}    # or interim: [x, y, z]
      - {motion: PTP, goal_joints: [...], ptp: kinetic_energy}                # or joint_line; or a goal
"""
from __future__ import annotations

import os
import stat
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
import yaml

from ..core.errors import RequestError
from ..core.kinematics import Chain
from ..core.motions import MotionItem
from ..core.planner import check_method
from ..core.ptp import mass_from_urdf
from ..core.request import MAX_ITEMS, MAX_VIA_POSES, PlanRequest
from ..core.robots import load_robot, urdf_text
from ..core.transforms import pose_from_mapping

KNOWN_KEYS = {'robot', 'metric', 'position_weight', 'orientation_weight', 'epsilon', 'start', 'goal',
              'start_joints', 'goal_joints', 'via', 'tolerance', 'base_link', 'tip_link', 'description',
              'method', 'blend_radius', 'sequence'}
#: Keys of a sequence item.
ITEM_KEYS = {'motion', 'goal', 'goal_joints', 'interim', 'center', 'ptp', 'blend_radius'}
#: Largest request or scene YAML file read, bytes: a request of MAX_VIA_POSES via poses or
#: MAX_ITEMS sequence items, or a scene of MAX_OBJECTS objects, is well under it.
MAX_YAML_BYTES = 1 << 20


def parse_request(data: object, base_dir: str = '.', *,
                  robot_loader: Callable[..., Chain] = load_robot) -> PlanRequest:
    """PlanRequest from a decoded YAML mapping.

    ``robot_loader`` builds the robot (``load_robot``'s signature); a batch worker passes one
    that keeps the robots it has built.

    Raises:
        RequestError: missing/unknown keys, bad values, unknown robot; KinematicsError for a bad URDF.
    """
    if not isinstance(data, Mapping):
        raise RequestError(f'request: expected a mapping at the top level, got {type(data).__name__}')
    unknown = sorted(set(data) - KNOWN_KEYS)
    if unknown:
        raise RequestError(f'request: unknown keys {unknown}; known keys are {sorted(KNOWN_KEYS)}')
    if 'robot' not in data:
        raise RequestError('request: missing "robot" (preset name or URDF path)')
    robot_ref = data['robot']
    if not isinstance(robot_ref, str):
        raise RequestError(f'request: robot must be a string, got {robot_ref!r}')
    if robot_ref.endswith('.urdf') and not os.path.isabs(robot_ref):
        robot_ref = os.path.join(base_dir, robot_ref)
    robot = robot_loader(robot_ref, base_link=data.get('base_link'), tip_link=data.get('tip_link'))

    def pose(key: str) -> np.ndarray | None:
        return None if data.get(key) is None else pose_from_mapping(data[key], key)

    def joints(key: str) -> np.ndarray | None:
        return None if data.get(key) is None else robot.check_joints(data[key], key)

    via = data.get('via') or []
    if not isinstance(via, list):
        raise RequestError('request: via must be a list of poses')
    if len(via) > MAX_VIA_POSES:
        raise RequestError(f'request: via: {len(via)} poses, more than {MAX_VIA_POSES}')
    opts: dict[str, Any] = {}
    if 'metric' in data:
        opts['metric'] = str(data['metric'])
    for key in ('position_weight', 'orientation_weight', 'epsilon'):
        if key in data:
            opts[key] = _number(data[key], key)
    tol = None if data.get('tolerance') is None else _number(data['tolerance'], 'tolerance')
    try:
        method = check_method(data.get('method', 'auto'))
    except RequestError as err:
        raise RequestError(f'request: {err}') from err
    blend = 0.0 if data.get('blend_radius') is None else _number(data['blend_radius'], 'blend_radius')
    if blend < 0.0:
        raise RequestError(f'request: blend_radius must be >= 0 m, got {blend!r}')
    req = PlanRequest(robot, pose('start'), pose('goal'), joints('start_joints'), joints('goal_joints'),
                      [pose_from_mapping(v, f'via[{i}]') for i, v in enumerate(via)], tol, opts, method,
                      blend, robot_source=robot_ref)
    if req.start is None and req.start_joints is None:
        raise RequestError('request: give start (a Pose) or start_joints')
    if data.get('sequence') is not None:
        if req.goal is not None or req.goal_joints is not None or req.via:
            raise RequestError('request: a sequence replaces goal, goal_joints and via (give one or the other)')
        req.items = parse_items(data['sequence'], robot)
        if any(it.motion == 'PTP' and it.ptp == 'kinetic_energy' for it in req.items):
            req.mass = mass_from_urdf(robot, urdf_text(robot_ref))[0]
    else:
        try:
            req.check()
        except RequestError as err:
            raise RequestError(f'request: {err}') from err
    return req


def _point(value: object, what: str) -> np.ndarray:
    """A point from [x, y, z] or {x: .., y: .., z: ..}, m."""
    if isinstance(value, Mapping):
        value = [value.get(k) for k in ('x', 'y', 'z')]
    try:
        out = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError) as err:
        raise RequestError(f'request: {what} must be [x, y, z] or {{x, y, z}}, got {value!r}') from err
    if not np.all(np.isfinite(out)):
        raise RequestError(f'request: {what} must be finite, got {value!r}')
    return out


def parse_items(raw: object, robot: Chain) -> list[MotionItem]:
    """The motions of a request's ``sequence`` (see the module's doc).

    Raises:
        RequestError: not a list of mappings, an unknown key, a bad value (naming the item).
    """
    if not isinstance(raw, list) or not raw:
        raise RequestError('request: sequence must be a non-empty list of motions')
    if len(raw) > MAX_ITEMS:
        raise RequestError(f'request: sequence: {len(raw)} items, more than {MAX_ITEMS}')
    items = []
    for i, entry in enumerate(raw):
        what = f'sequence[{i}]'
        if not isinstance(entry, Mapping):
            raise RequestError(f'request: {what} must be a mapping, got {type(entry).__name__}')
        unknown = sorted(set(entry) - ITEM_KEYS)
        if unknown:
            raise RequestError(f'request: {what}: unknown keys {unknown}; known keys are {sorted(ITEM_KEYS)}')
        goal = None if entry.get('goal') is None else pose_from_mapping(entry['goal'], f'{what}.goal')
        joints = None if entry.get('goal_joints') is None else robot.check_joints(entry['goal_joints'],
                                                                                  f'{what}.goal_joints')
        items.append(MotionItem(
            str(entry.get('motion', '')).upper(), goal, joints,
            None if entry.get('interim') is None else _point(entry['interim'], f'{what}.interim'),
            None if entry.get('center') is None else _point(entry['center'], f'{what}.center'),
            str(entry.get('ptp', 'kinetic_energy')),
            0.0 if entry.get('blend_radius') is None else _number(entry['blend_radius'], f'{what}.blend_radius')))
    return items


def _number(value: object, what: str) -> float:
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise RequestError(f'request: {what} must be a number, got {value!r}') from err
    if not np.isfinite(out):
        raise RequestError(f'request: {what} must be finite, got {value!r}')
    return out


def load_request(path: str) -> PlanRequest:
    """Read and parse a YAML request file.

    Raises:
        RequestError: unreadable file, malformed YAML, or an invalid request.
    """
    data = read_yaml(path, f'request {path!r}', repr(path))
    return parse_request(data, os.path.dirname(os.path.abspath(path)))


def read_yaml(path: str, what: str, in_what: str) -> object:
    """The document of a YAML file: a regular file (never a FIFO or a device) of at most
    :data:`MAX_YAML_BYTES`.

    Args:
        path: the file.
        what, in_what: how the errors name it: ``cannot read <what>``, ``malformed YAML in
            <in_what> at line L, column C``.
    Raises:
        RequestError: unreadable, not a regular file, too large, not UTF-8, malformed YAML.
    """
    try:
        info = os.stat(path)
    except (OSError, ValueError) as err:  # ValueError: a NUL byte in the path
        raise RequestError(f'cannot read {what}: {getattr(err, "strerror", None) or err}') from err
    if not stat.S_ISREG(info.st_mode):
        raise RequestError(f'cannot read {what}: not a regular file')
    if info.st_size > MAX_YAML_BYTES:
        raise RequestError(f'{what}: {info.st_size} bytes, more than {MAX_YAML_BYTES}')
    try:
        # O_NONBLOCK: should the path become a FIFO after the check, open() still returns at once.
        with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK), 'rb') as fh:
            raw = fh.read(MAX_YAML_BYTES + 1)
    except OSError as err:
        raise RequestError(f'cannot read {what}: {err.strerror or err}') from err
    if len(raw) > MAX_YAML_BYTES:
        raise RequestError(f'{what}: more than {MAX_YAML_BYTES} bytes')
    try:
        return yaml.safe_load(raw.decode('utf-8'))
    except UnicodeDecodeError as err:
        raise RequestError(f'{what}: not UTF-8 (byte {err.start})') from err
    except RecursionError as err:
        raise RequestError(f'{what}: nested too deeply') from err
    except yaml.YAMLError as err:
        mark = getattr(err, 'problem_mark', None)
        where = f' at line {mark.line + 1}, column {mark.column + 1}' if mark else ''
        raise RequestError(f'malformed YAML in {in_what}{where}: {getattr(err, "problem", err)}') from err
