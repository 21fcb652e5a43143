"""Round trips and validation of geodesic_planner.ros.conversions (messages only, no DDS)."""
from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped
from numpy.testing import assert_allclose
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker

from geodesic_planner.core.errors import RequestError
from geodesic_planner.ros import conversions as cv
from geodesic_planner.core.transforms import make_transform, so3_exp

pytestmark = pytest.mark.ros


def _random_transforms(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.stack([make_transform(rng.uniform(-2, 2, 3), so3_exp(rng.uniform(-3, 3, 3)))
                     for _ in range(n)])


# --------------------------------------------------------------------------- poses

def test_pose_round_trip() -> None:
    for T in _random_transforms(50):
        back = cv.pose_to_matrix(cv.matrix_to_pose(T))
        assert_allclose(back, T, atol=1e-12)


def test_pose_stamped_round_trip_and_frames() -> None:
    T = _random_transforms(1, seed=3)[0]
    msg = cv.matrix_to_pose_stamped(T, 'base_link')
    assert msg.header.frame_id == 'base_link'
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)
    assert_allclose(cv.pose_stamped_to_matrix(msg, 'base_link'), T, atol=1e-12)
    msg.header.frame_id = ''                      # empty = base frame
    assert_allclose(cv.pose_stamped_to_matrix(msg, 'base_link'), T, atol=1e-12)
    msg.header.frame_id = 'world'
    with pytest.raises(RequestError, match="frame_id 'world' is not the base frame 'base_link'"):
        cv.pose_stamped_to_matrix(msg, 'base_link', 'goal')


def test_quaternion_normalised_when_close_rejected_otherwise() -> None:
    msg = PoseStamped()
    msg.pose.orientation.z = np.sin(0.3)
    msg.pose.orientation.w = np.cos(0.3)
    exact = cv.pose_to_matrix(msg.pose)
    msg.pose.orientation.z *= 1.0005
    msg.pose.orientation.w *= 1.0005
    assert_allclose(cv.pose_to_matrix(msg.pose), exact, atol=1e-12)
    msg.pose.orientation.z *= 1.01
    msg.pose.orientation.w *= 1.01
    with pytest.raises(RequestError, match='not normalised'):
        cv.pose_to_matrix(msg.pose, 'goal')
    msg.pose.orientation.w = float('nan')
    with pytest.raises(RequestError, match='NaN'):
        cv.pose_to_matrix(msg.pose)
    msg = PoseStamped()
    msg.pose.orientation.w = 1.0
    msg.pose.position.y = float('inf')
    with pytest.raises(RequestError, match='position contains NaN or inf'):
        cv.pose_to_matrix(msg.pose)


def _zero_quaternion_pose() -> PoseStamped:
    msg = PoseStamped()                            # note: Quaternion's default is w = 1
    msg.pose.orientation.w = 0.0
    return msg


def test_current_state_marker() -> None:
    msg = _zero_quaternion_pose()                  # empty frame, quaternion (0, 0, 0, 0)
    assert cv.is_current_state_pose(msg)
    msg.header.frame_id = 'base_link'
    assert not cv.is_current_state_pose(msg)
    assert not cv.is_current_state_pose(PoseStamped())
    with pytest.raises(RequestError):              # a zero quaternion is not a pose
        cv.pose_to_matrix(_zero_quaternion_pose().pose)


def test_path_round_trip() -> None:
    Ts = _random_transforms(20, seed=1)
    path = cv.poses_to_path(Ts, 'base')
    assert path.header.frame_id == 'base'
    assert len(path.poses) == 20
    assert all(p.header.frame_id == 'base' for p in path.poses)
    assert_allclose(cv.path_to_matrices(path), Ts, atol=1e-12)
    back = deserialize_message(serialize_message(path), type(path))
    assert_allclose(cv.path_to_matrices(back), Ts, atol=1e-12)
    assert len(cv.poses_to_path(np.zeros((0, 4, 4)), 'base').poses) == 0


def test_path_markers() -> None:
    Ts = _random_transforms(7, seed=2)
    arr = cv.path_markers(Ts, 'base', axis_length=0.2, line_width=0.02)
    kinds = [(m.action, m.type, m.id) for m in arr.markers]
    assert kinds[0][0] == Marker.DELETEALL
    assert kinds[1:] == [(Marker.ADD, Marker.LINE_STRIP, 0), (Marker.ADD, Marker.LINE_LIST, 1),
                         (Marker.ADD, Marker.LINE_LIST, 2)]
    line = arr.markers[1]
    assert line.header.frame_id == 'base'
    assert line.scale.x == 0.02
    assert_allclose([[p.x, p.y, p.z] for p in line.points], Ts[:, :3, 3], atol=1e-15)
    for marker, T in ((arr.markers[2], Ts[0]), (arr.markers[3], Ts[-1])):
        pts = np.array([[p.x, p.y, p.z] for p in marker.points])
        assert pts.shape == (6, 3)
        assert len(marker.colors) == 6
        assert_allclose(pts[0::2], np.tile(T[:3, 3], (3, 1)), atol=1e-15)
        assert_allclose(pts[1::2], T[:3, 3] + 0.2 * T[:3, :3].T, atol=1e-15)
    serialize_message(arr)                         # a valid message


# --------------------------------------------------------------------------- joint states

def test_joint_state_any_order_and_extra_joints() -> None:
    names = ['j1', 'j2', 'j3']
    msg = JointState(name=['gripper', 'j3', 'j1', 'j2'], position=[9.0, 0.3, 0.1, 0.2])
    assert_allclose(cv.joint_state_to_vector(msg, names), [0.1, 0.2, 0.3], atol=0)
    back = cv.vector_to_joint_state(names, np.array([0.1, 0.2, 0.3]))
    assert_allclose(cv.joint_state_to_vector(back, names), [0.1, 0.2, 0.3], atol=0)


@pytest.mark.parametrize(('name', 'position', 'velocity', 'match'), [
    (['j1', 'j2', 'j3'], [0.1, 0.2], [], '3 names but 2 positions'),
    (['j1', 'j2', 'j3'], [0.1, 0.2, 0.3], [1.0], '3 names but 1 velocity values'),
    (['j1', 'j1', 'j3'], [0.1, 0.2, 0.3], [], 'duplicate joint names'),
    (['j1', 'j2', 'x'], [0.1, 0.2, 0.3], [], r"missing robot joints \['j3'\]"),
    (['a', 'b', 'c'], [0.1, 0.2, 0.3], [], 'none of the robot joints'),
    (['j1', 'j2', 'j3'], [0.1, float('nan'), 0.3], [], r"non-finite position for joints \['j2'\]"),
    (['j1', 'j2', 'j3'], [0.1, 0.2, float('inf')], [], 'non-finite'),
])
def test_joint_state_malformed(name: list[str], position: list[float], velocity: list[float],
                               match: str) -> None:
    msg = JointState(name=name, position=position, velocity=velocity)
    with pytest.raises(RequestError, match=match):
        cv.joint_state_to_vector(msg, ['j1', 'j2', 'j3'])


# --------------------------------------------------------------------------- trajectories

def _arrays(n: int = 11, dof: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 1.234567891, n)
    return t, rng.normal(size=(n, dof)), rng.normal(size=(n, dof)), rng.normal(size=(n, dof))


def test_joint_trajectory_round_trip() -> None:
    t, q, dq, ddq = _arrays()
    msg = cv.arrays_to_joint_trajectory(['a', 'b', 'c'], t, q, dq, ddq, frame_id='base')
    # _arrays() ends moving: a round trip of any data, not a trajectory for a controller
    assert cv.validate_joint_trajectory(msg, require_rest_at_end=False) == []
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 0)
    msg = deserialize_message(serialize_message(msg), JointTrajectory)
    arr = cv.joint_trajectory_to_arrays(msg)
    assert arr.joint_names == ['a', 'b', 'c']
    assert_allclose(arr.t, t, atol=1e-9)            # ns resolution
    assert_allclose(arr.positions, q, atol=0)
    assert_allclose(arr.velocities, dq, atol=0)
    assert_allclose(arr.accelerations, ddq, atol=0)


def test_joint_trajectory_positions_only() -> None:
    t, q, _, _ = _arrays()
    arr = cv.joint_trajectory_to_arrays(cv.arrays_to_joint_trajectory(['a', 'b', 'c'], t, q))
    assert arr.velocities is None and arr.accelerations is None
    assert_allclose(arr.positions, q, atol=0)


def test_duration_round_trip() -> None:
    for s in (0.0, 1e-9, 0.5, 1.999999999, 2.0, 1234.000000001):
        d = cv.seconds_to_duration(s)
        assert 0 <= d.nanosec < 1_000_000_000
        assert abs(cv.duration_to_seconds(d) - s) < 1e-9


def _mutations() -> list[tuple[str, str]]:
    return [('names_empty', 'no joint names'), ('names_dup', 'duplicate'),
            ('no_points', 'no points'), ('short_positions', 'positions, expected 3'),
            ('short_velocities', 'velocities, expected 3'), ('nan_acc', 'accelerations contain NaN or inf'),
            ('time_equal', 'not after'), ('time_back', 'not after')]


@pytest.mark.parametrize(('mutation', 'match'), _mutations())
def test_validate_rejects_one_mutation(mutation: str, match: str) -> None:
    t, q, dq, ddq = _arrays()
    msg = cv.arrays_to_joint_trajectory(['a', 'b', 'c'], t, q, dq, ddq)
    if mutation == 'names_empty':
        msg.joint_names = []
    elif mutation == 'names_dup':
        msg.joint_names = ['a', 'a', 'c']
    elif mutation == 'no_points':
        msg.points = []
    elif mutation == 'short_positions':
        msg.points[3].positions = [0.0, 0.0]
    elif mutation == 'short_velocities':
        msg.points[4].velocities = [0.0]
    elif mutation == 'nan_acc':
        msg.points[2].accelerations = [0.0, float('nan'), 0.0]
    elif mutation == 'time_equal':
        msg.points[5].time_from_start = msg.points[4].time_from_start
    elif mutation == 'time_back':
        msg.points[-1].time_from_start = cv.seconds_to_duration(0.1)
    problems = cv.validate_joint_trajectory(msg)
    assert any(match in p for p in problems), problems


@pytest.mark.parametrize('names,positions,kind', [
    (['a', 'b', 'c'], [0.0, 0.0], 'length'),
    (['a', 'a', 'b', 'c'], [0.0] * 4, 'duplicate'),
    (['x', 'y'], [0.0, 0.0], 'none of'),
    (['a', 'b'], [0.0, 0.0], 'missing'),
    (['a', 'b', 'c'], [0.0, float('nan'), 0.0], 'non-finite'),
])
def test_joint_state_errors_say_their_kind(names, positions, kind) -> None:
    from sensor_msgs.msg import JointState

    from geodesic_planner.core.errors import JOINT_STATE_PROBLEMS, JointStateError
    msg = JointState(name=names, position=positions)
    with pytest.raises(JointStateError) as info:
        cv.joint_state_to_vector(msg, ['a', 'b', 'c'])
    assert info.value.kind == kind and kind in JOINT_STATE_PROBLEMS
