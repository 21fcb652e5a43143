"""Conversions between ROS messages and numpy arrays (no maths beyond unit handling).

Messages <-> arrays for the planner node: JointTrajectory, Pose/PoseStamped <-> 4x4 transforms,
nav_msgs/Path of tool poses, a MarkerArray for RViz, and JointState -> joint vector in robot order.
Invalid input raises :class:`geodesic_planner.core.errors.RequestError` with a message naming the cause.
"""
from __future__ import annotations

import array
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point, Pose, PoseStamped
from nav_msgs.msg import Path
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from ..core.cancel import checkpoint
from ..core.errors import FrameError, JointStateError, RequestError, quoted
from ..core.transforms import make_transform, matrix_to_quat, pose_to_transform, quat_to_matrix
from ..timing.validate import trajectory_problems

#: Points (trajectory points, poses, marker points) built between two cancellation checkpoints
#: (:mod:`geodesic_planner.core.cancel`): about 15 ms of work on the 2-core machine.
CHECK_EVERY = 1000


@dataclass(frozen=True)
class TrajectoryArrays:
    """A joint trajectory as arrays: times (N,) in s; positions/velocities/accelerations (N, dof)."""

    joint_names: list[str]
    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None


def _darray(row: np.ndarray) -> array.array:
    """array.array('d') of a 1-D float array (the fast path of the message setters)."""
    return array.array('d', np.ascontiguousarray(row, dtype=np.float64).tobytes())


def seconds_to_duration(t: float) -> Duration:
    """builtin_interfaces/Duration from seconds (rounded to the nanosecond)."""
    ns = round(float(t) * 1e9)
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def duration_to_seconds(d: Duration) -> float:
    """Seconds of a builtin_interfaces/Duration."""
    return d.sec + d.nanosec * 1e-9


def time_from_start_ns(t: np.ndarray) -> np.ndarray:
    """The ``time_from_start`` a JointTrajectory carries for times ``t`` (N,) s: integer ns (N,),
    rounded like :func:`seconds_to_duration` (half to even)."""
    return np.rint(np.asarray(t, dtype=float).reshape(-1) * 1e9).astype(np.int64)


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
    # time_from_start in integer ns, split with floor division; written into each point's own
    # Duration (no extra objects).
    ns = time_from_start_ns(t)
    secs, nanosecs = np.divmod(ns, 1_000_000_000)
    points = []
    # array.array('d') rows skip the generated setters' per-element checks (much faster).
    for i, (sec, nanosec) in enumerate(zip(secs.tolist(), nanosecs.tolist())):
        if i % CHECK_EVERY == 0:
            checkpoint()       # a long message is built in a cancellable plan (core.cancel)
        pt = JointTrajectoryPoint()
        pt.positions = _darray(pos[i])
        if vel is not None:
            pt.velocities = _darray(vel[i])
        if acc is not None:
            pt.accelerations = _darray(acc[i])
        d = pt.time_from_start
        d.sec = sec
        d.nanosec = nanosec
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


def validate_joint_trajectory(msg: JointTrajectory, *, require_rest_at_end: bool = True) -> list[str]:
    """Problems joint_trajectory_controller would reject the message for (empty list: valid).

    The message's fields handed to the one trajectory validator,
    :func:`geodesic_planner.timing.validate.trajectory_problems` (the bag tools use it too).
    """
    points = msg.points
    ns = np.fromiter((p.time_from_start.sec * 1_000_000_000 + p.time_from_start.nanosec for p in points),
                     dtype=np.int64, count=len(points))
    return trajectory_problems(
        list(msg.joint_names), ns * 1e-9,
        [p.positions for p in points], [p.velocities for p in points], [p.accelerations for p in points],
        require_rest_at_end=require_rest_at_end)


# --------------------------------------------------------------------------- poses


def pose_to_matrix(pose: Pose, what: str = 'pose') -> np.ndarray:
    """4x4 transform of a geometry_msgs/Pose, validated.

    The quaternion is normalised when its norm is within 1e-3 of 1
    (:func:`geodesic_planner.core.transforms.check_quaternion`).

    Args:
        pose: position in m, orientation quaternion (x, y, z, w).
        what: name used in error messages.
    Returns:
        Transform, shape (4, 4).
    Raises:
        RequestError: NaN/inf, zero or unnormalised quaternion.
    """
    p, o = pose.position, pose.orientation
    return pose_to_transform([p.x, p.y, p.z], [o.x, o.y, o.z, o.w], what)


def matrix_to_pose(T: np.ndarray) -> Pose:
    """geometry_msgs/Pose of a 4x4 transform (position in m, unit quaternion with w >= 0)."""
    T = np.asarray(T, dtype=float)
    q = matrix_to_quat(T[:3, :3])
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in T[:3, 3])
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = (
        float(v) for v in q)
    return pose


def check_frame(frame_id: str, base_frame: str, what: str = 'pose') -> None:
    """Accept an empty frame_id (meaning the base frame) or exactly ``base_frame``.

    Raises:
        FrameError: any other frame (no TF lookup is done).
    """
    if frame_id not in ('', base_frame):
        raise FrameError(
            f"{what}: frame_id {quoted(frame_id)} is not the base frame '{base_frame}' "
            f"(poses must be given in '{base_frame}' or with an empty frame_id; no TF lookup is done)")


def pose_stamped_to_matrix(msg: PoseStamped, base_frame: str, what: str = 'pose') -> np.ndarray:
    """4x4 transform of a PoseStamped expressed in ``base_frame`` (empty frame_id = base frame).

    Returns:
        Transform base -> pose, shape (4, 4).
    Raises:
        RequestError: other frame, NaN/inf, invalid quaternion.
    """
    check_frame(msg.header.frame_id, base_frame, what)
    return pose_to_matrix(msg.pose, what)


#: What an all-zero start pose means (the hint of an unset start orientation).
_CURRENT_STATE = 'an all-zero pose (quaternion and position) starts from the current joint state'


def _zero_quaternion(msg: PoseStamped) -> bool:
    """An empty frame_id and an all-zero quaternion (x = y = z = w = 0)."""
    o = msg.pose.orientation
    return msg.header.frame_id == '' and o.x == 0.0 and o.y == 0.0 and o.z == 0.0 and o.w == 0.0


def _check_unset_orientation(msg: PoseStamped, what: str, marker: str) -> None:
    """Refuse an all-zero quaternion under a position that is not zero: a pose whose orientation
    was left unset, not the ``marker`` (which is all zero, position included).

    Raises:
        RequestError: naming ``what``, the position and the fix.
    """
    p = msg.pose.position
    if p.x != 0.0 or p.y != 0.0 or p.z != 0.0:
        raise RequestError(
            f'{what}: the orientation is unset (an all-zero quaternion) at position '
            f'[{p.x:g}, {p.y:g}, {p.z:g}]: give a unit quaternion (x, y, z, w; w: 1.0 for no rotation); '
            f'{marker}')


def is_current_state_pose(msg: PoseStamped, what: str = 'start') -> bool:
    """True for the "start from the current joint state" marker: empty frame_id, all-zero quaternion
    and position.

    Raises:
        RequestError: an empty frame_id and an all-zero quaternion under a position that is not
            zero: a pose was given, its orientation unset (named ``what``).
    """
    if not _zero_quaternion(msg):
        return False
    _check_unset_orientation(msg, what, _CURRENT_STATE)
    return True


def is_empty_pose(msg: PoseStamped, what: str = 'pose') -> bool:
    """True for a PoseStamped left unset in a request (PlanTrajectory, PlanSequence).

    Unset means an empty frame_id and either all zeros (quaternion and position: the marker GetPlan
    uses too) or the default-constructed pose (position 0, quaternion x = y = z = 0, w = 1): that
    pose would put the tool at the base frame's origin, inside the robot, so it is read as "not
    given".

    Raises:
        RequestError: an empty frame_id and an all-zero quaternion under a position that is not
            zero: a pose was given, its orientation unset (named ``what``).
    """
    p, o = msg.pose.position, msg.pose.orientation
    if _zero_quaternion(msg):
        _check_unset_orientation(msg, what, _CURRENT_STATE if what == 'start' else
                                 f'an all-zero pose (quaternion and position) means "no {what}"')
        return True
    return (msg.header.frame_id == '' and p.x == 0.0 and p.y == 0.0 and p.z == 0.0
            and o.x == 0.0 and o.y == 0.0 and o.z == 0.0 and o.w == 1.0)


def matrix_to_pose_stamped(T: np.ndarray, frame_id: str, stamp: Time | None = None) -> PoseStamped:
    """PoseStamped of a 4x4 transform in ``frame_id`` (stamp zero unless given)."""
    msg = PoseStamped()
    msg.header = Header(frame_id=frame_id, stamp=stamp if stamp is not None else Time())
    msg.pose = matrix_to_pose(T)
    return msg


def poses_to_path(Ts: np.ndarray, frame_id: str, stamp: Time | None = None) -> Path:
    """nav_msgs/Path of transforms, shape (N, 4, 4), all in ``frame_id`` with the same stamp."""
    Ts = np.asarray(Ts, dtype=float).reshape(-1, 4, 4)
    header = Header(frame_id=frame_id, stamp=stamp if stamp is not None else Time())
    # Default-constructed messages filled through their setters: keyword construction builds
    # (and drops) a default value for every field it is given, about 2.5x slower here.
    poses = []
    for i in range(0, len(Ts), CHECK_EVERY):
        checkpoint()
        block = Ts[i:i + CHECK_EVERY]
        for p, q in zip(block[:, :3, 3].tolist(), matrix_to_quat(block[:, :3, :3]).tolist()):
            ps = PoseStamped()
            ps.header = header
            pose = ps.pose
            pos, ori = pose.position, pose.orientation
            pos.x, pos.y, pos.z = p
            ori.x, ori.y, ori.z, ori.w = q
            poses.append(ps)
    return Path(header=header, poses=poses)


def path_to_matrices(msg: Path) -> np.ndarray:
    """Transforms of a nav_msgs/Path, shape (N, 4, 4) (quaternions are normalised, not validated)."""
    out = np.zeros((len(msg.poses), 4, 4))
    for i, ps in enumerate(msg.poses):
        p, o = ps.pose.position, ps.pose.orientation
        q = np.array([o.x, o.y, o.z, o.w], dtype=float)
        out[i] = make_transform([p.x, p.y, p.z], quat_to_matrix(q / np.linalg.norm(q)))
    return out


# --------------------------------------------------------------------------- markers

_AXIS_COLORS = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))  # x red, y green, z blue


def _point(v: np.ndarray) -> Point:
    return Point(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def path_markers(
    Ts: np.ndarray,
    frame_id: str,
    *,
    ns: str = 'geodesic_planner',
    line_width: float = 0.01,
    axis_length: float = 0.1,
    stamp: Time | None = None,
) -> MarkerArray:
    """MarkerArray for RViz: DELETEALL, the tool path as a line strip, axes at start and goal.

    Marker ids in ``ns``: 0 line strip (orange), 1 start axes, 2 goal axes (LINE_LIST, x/y/z in
    red/green/blue). The leading DELETEALL clears markers of an earlier plan.

    Args:
        Ts: tool poses along the path, shape (N, 4, 4), N >= 1; base frame, m.
        frame_id: frame of the markers (the base frame).
        line_width: line width in m.
        axis_length: length of each axis in m.
        stamp: header stamp (zero: RViz uses the latest transform).
    """
    Ts = np.asarray(Ts, dtype=float).reshape(-1, 4, 4)
    header = Header(frame_id=frame_id, stamp=stamp if stamp is not None else Time())
    clear = Marker(header=header, ns=ns, action=Marker.DELETEALL)
    line = Marker(header=header, ns=ns, id=0, type=Marker.LINE_STRIP, action=Marker.ADD)
    line.pose.orientation.w = 1.0
    line.scale.x = float(line_width)
    line.color = ColorRGBA(r=1.0, g=0.5, b=0.0, a=1.0)
    line.points = []
    for i, p in enumerate(Ts[:, :3, 3]):
        if i % CHECK_EVERY == 0:
            checkpoint()
        line.points.append(_point(p))
    markers = [clear, line]
    for mid, T in ((1, Ts[0]), (2, Ts[-1])):
        axes = Marker(header=header, ns=ns, id=mid, type=Marker.LINE_LIST, action=Marker.ADD)
        axes.pose.orientation.w = 1.0
        axes.scale.x = float(line_width)
        alpha = 1.0 if mid == 1 else 0.6
        for k, (r, g, b) in enumerate(_AXIS_COLORS):
            axes.points.append(_point(T[:3, 3]))
            axes.points.append(_point(T[:3, 3] + axis_length * T[:3, k]))
            color = ColorRGBA(r=r, g=g, b=b, a=alpha)
            axes.colors.extend([color, color])
        axes.color = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
        markers.append(axes)
    return MarkerArray(markers=markers)


# --------------------------------------------------------------------------- joint states


def _names(names: Sequence[str], limit: int = 10) -> str:
    """A list of user-given names for a message: at most ``limit`` names, each cut short."""
    shown = ', '.join(quoted(n, 40) for n in names[:limit])
    more = f', ... ({len(names)} names)' if len(names) > limit else ''
    return f'[{shown}{more}]'


def joint_state_to_vector(msg: JointState, joint_names: Sequence[str],
                          what: str = 'joint state') -> np.ndarray:
    """Joint positions of a sensor_msgs/JointState in the robot's order, validated.

    The message may list joints in any order and may contain joints the robot does not have
    (they are ignored); it must contain every robot joint exactly once.

    Args:
        msg: joint state (name, position; velocity/effort empty or sized like name).
        joint_names: the robot's joint names, length dof.
        what: how messages name the joint state (e.g. ``start_joints``).
    Returns:
        Positions, shape (dof,), rad or m.
    Raises:
        JointStateError (a RequestError with its ``kind``): names/positions of different
            lengths, duplicate names, missing robot joints, NaN/inf positions of robot joints.
    """
    names = list(msg.name)
    n = len(names)
    if len(msg.position) != n:
        raise JointStateError(f'{what}: {n} names but {len(msg.position)} positions', kind='length')
    for field in ('velocity', 'effort'):
        m = len(getattr(msg, field))
        if m not in (0, n):
            raise JointStateError(f'{what}: {n} names but {m} {field} values (expected 0 or {n})', kind='length')
    index = {name: i for i, name in enumerate(names)}
    if len(index) != n:
        dups = sorted({x for x in names if names.count(x) > 1})
        raise JointStateError(f'{what}: duplicate joint names {_names(dups)}', kind='duplicate')
    missing = [j for j in joint_names if j not in index]
    if missing:
        if len(missing) == len(joint_names):
            raise JointStateError(
                f'{what}: none of the robot joints {list(joint_names)} (got {_names(names)})', kind='none of')
        raise JointStateError(f'{what}: missing robot joints {missing} (got {_names(names)})', kind='missing')
    q = np.array([msg.position[index[j]] for j in joint_names], dtype=float)
    bad = [j for j, v in zip(joint_names, q) if not np.isfinite(v)]
    if bad:
        raise JointStateError(f'{what}: non-finite position for joints {bad}', kind='non-finite')
    return q


def vector_to_joint_state(joint_names: Sequence[str], q: np.ndarray,
                          stamp: Time | None = None) -> JointState:
    """sensor_msgs/JointState with positions ``q`` (dof,) for ``joint_names`` (velocity/effort empty)."""
    msg = JointState()
    msg.header.stamp = stamp if stamp is not None else Time()
    msg.name = list(joint_names)
    msg.position = _darray(np.asarray(q, dtype=float).reshape(-1))
    return msg
