"""geodesic_planner.core.transforms against independent oracles (axis-angle formulas, scipy's Rotation,
the matrix exponential)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from planning_checks import expect_error, guarded
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.transforms import (
    check_quaternion,
    hat,
    line_slerp,
    make_transform,
    matrix_to_quat,
    pose_error,
    pose_from_mapping,
    pose_to_transform,
    quat_to_matrix,
    so3_exp,
    so3_log,
    transform_to_pose,
)

RNG_SEED = 20161


def axis_angle_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula written out (oracle)."""
    u = axis / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def random_axes_angles(n: int, rng: np.random.Generator, max_angle: float = np.pi):
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    return axes, rng.uniform(0.0, max_angle, size=n)


def test_hat_is_cross_product():
    rng = np.random.default_rng(RNG_SEED)
    w, v = rng.normal(size=(2, 5, 3))
    assert_allclose(np.einsum('nij,nj->ni', hat(w), v), np.cross(w, v), atol=1e-15)


def test_quat_to_matrix_matches_axis_angle_and_scipy():
    rng = np.random.default_rng(RNG_SEED)
    axes, angles = random_axes_angles(50, rng)
    quats = np.concatenate([axes * np.sin(angles / 2)[:, None], np.cos(angles / 2)[:, None]], axis=1)
    R = quat_to_matrix(quats)
    for k in range(50):
        assert_allclose(R[k], axis_angle_matrix(axes[k], angles[k]), atol=1e-14)
    assert_allclose(R, Rotation.from_quat(quats).as_matrix(), atol=1e-14)


def test_matrix_to_quat_round_trip_and_sign_convention():
    rng = np.random.default_rng(RNG_SEED + 1)
    axes, angles = random_axes_angles(200, rng)
    # include angles close to pi and exactly pi about each axis (numerically delicate)
    axes = np.concatenate([axes, np.eye(3), np.eye(3)])
    angles = np.concatenate([angles, np.full(3, np.pi), np.full(3, np.pi - 1e-9)])
    R = np.array([axis_angle_matrix(a, t) for a, t in zip(axes, angles)])
    q = matrix_to_quat(R)
    assert q.shape == (R.shape[0], 4)
    assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    assert np.all(q[:, 3] >= 0.0)
    expected = np.concatenate([axes * np.sin(angles / 2)[:, None], np.cos(angles / 2)[:, None]], axis=1)
    # q and -q are the same rotation: compare up to sign
    sign = np.where(np.sum(q * expected, axis=1) < 0, -1.0, 1.0)
    assert_allclose(q * sign[:, None], expected, atol=1e-12)
    assert_allclose(quat_to_matrix(q), R, atol=1e-14)


def test_matrix_to_quat_batched_shape():
    R = np.broadcast_to(np.eye(3), (2, 3, 3, 3))
    q = matrix_to_quat(R)
    assert q.shape == (2, 3, 4)
    assert_allclose(q, np.broadcast_to([0, 0, 0, 1.0], (2, 3, 4)), atol=0)


def test_so3_exp_matches_matrix_exponential():
    rng = np.random.default_rng(RNG_SEED + 2)
    w = rng.normal(size=(30, 3)) * rng.uniform(0, 3, size=(30, 1))
    w = np.concatenate([w, [[0, 0, 0], [1e-10, 0, 0], [0, 2e-9, -1e-9]]])
    R = so3_exp(w)
    for k in range(w.shape[0]):
        assert_allclose(R[k], expm(hat(w[k])), atol=1e-13)


def test_so3_log_inverts_exp():
    rng = np.random.default_rng(RNG_SEED + 3)
    axes, angles = random_axes_angles(100, rng, max_angle=np.pi - 1e-6)
    w = axes * angles[:, None]
    assert_allclose(so3_log(so3_exp(w)), w, atol=1e-12)
    assert_allclose(so3_log(np.eye(3)), np.zeros(3), atol=0)
    # angle pi: either sign of the axis is right
    wpi = so3_log(axis_angle_matrix(np.array([0, 0, 1.0]), np.pi))
    assert_allclose(np.abs(wpi), [0, 0, np.pi], atol=1e-12)


def test_line_slerp_is_line_and_constant_rate_rotation():
    rng = np.random.default_rng(RNG_SEED + 4)
    Ra = axis_angle_matrix(rng.normal(size=3), 1.1)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = 2.0
    Rb = Ra @ axis_angle_matrix(axis, angle)        # body-frame rotation by `angle` about `axis`
    Ta, Tb = make_transform([0.1, -0.2, 0.3], Ra), make_transform([1.0, 0.5, -0.7], Rb)
    s = np.linspace(0.0, 1.0, 57)
    T = line_slerp(Ta, Tb, s)
    assert T.shape == (57, 4, 4)
    assert_allclose(T[0], Ta, atol=1e-15)
    assert_allclose(T[-1], Tb, atol=1e-14)
    assert_allclose(T[:, :3, 3], Ta[:3, 3] + s[:, None] * (Tb[:3, 3] - Ta[:3, 3]), atol=1e-15)
    for k, sk in enumerate(s):
        assert_allclose(T[k, :3, :3], Ra @ axis_angle_matrix(axis, sk * angle), atol=1e-13)
    assert_allclose(T[:, 3], np.broadcast_to([0, 0, 0, 1.0], (57, 4)), atol=0)


def test_pose_error_distance_and_angle():
    Ra = axis_angle_matrix(np.array([1.0, 2.0, 3.0]), 0.4)
    for angle in (0.0, 1e-7, 0.3, 2.5, np.pi):
        Rb = Ra @ axis_angle_matrix(np.array([-1.0, 0.5, 0.2]), angle)
        dp, dr = pose_error(make_transform([0, 0, 0], Ra), make_transform([3.0, 4.0, 0.0], Rb))
        assert_allclose(dp, 5.0, rtol=1e-15)
        assert_allclose(dr, angle, atol=1e-12 if angle < 3 else 1e-7)


def test_check_quaternion_normalises_within_tolerance():
    q = check_quaternion([0.0, 0.0, 0.0, 1.0005])
    assert_allclose(q, [0, 0, 0, 1.0], atol=1e-15)
    with pytest.raises(RequestError, match=r'not normalised \(norm 1\.01'):
        check_quaternion([0.0, 0.0, 0.0, 1.01], 'goal.orientation')
    with pytest.raises(RequestError, match=r'goal.orientation'):
        check_quaternion([0.0, 0.0, 0.0, 1.01], 'goal.orientation')
    with pytest.raises(RequestError, match='NaN or inf'):
        check_quaternion([0.0, float('nan'), 0.0, 1.0])
    with pytest.raises(RequestError, match='needs 4 numbers'):
        check_quaternion([0.0, 0.0, 1.0])
    with pytest.raises(RequestError, match='not normalised'):
        check_quaternion([0.0, 0.0, 0.0, 0.0])


def test_pose_from_mapping_yaml_form_and_defaults():
    yaw = np.deg2rad(30.0)
    T = pose_from_mapping({'position': {'x': 2.5, 'y': 1.5, 'z': 0.0},
                           'orientation': {'x': 0.0, 'y': 0.0, 'z': np.sin(yaw / 2), 'w': np.cos(yaw / 2)}})
    assert_allclose(T[:3, 3], [2.5, 1.5, 0.0], atol=0)
    assert_allclose(T[:3, 0], [np.cos(yaw), np.sin(yaw), 0.0], atol=1e-15)  # n of paper Table 1
    assert_allclose(T[3], [0, 0, 0, 1.0], atol=0)
    T0 = pose_from_mapping({'position': {'y': 1.0}})  # ROS defaults: missing = 0, identity orientation
    assert_allclose(T0, make_transform([0, 1.0, 0], np.eye(3)), atol=0)


@pytest.mark.parametrize('pose, match', [
    ({'position': {'x': float('nan')}}, 'position contains NaN'),
    ({'position': {'x': 'abc'}}, 'non-numeric'),
    ({'position': [1, 2, 3]}, 'must be mappings'),
    ({'orientation': {'x': 0.5, 'w': 0.5}}, 'not normalised'),
    ([1, 2, 3], 'expected a mapping'),
])
def test_pose_from_mapping_rejects_bad_input(pose, match):
    with pytest.raises(RequestError, match=match):
        pose_from_mapping(pose, 'start')


def test_pose_to_transform_and_back():
    rng = np.random.default_rng(RNG_SEED + 5)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    q *= np.sign(q[3])
    T = pose_to_transform([1.0, 2.0, 3.0], q)
    assert_allclose(T[:3, :3], Rotation.from_quat(q).as_matrix(), atol=1e-14)
    p, q2 = transform_to_pose(T)
    assert_allclose(p, [1.0, 2.0, 3.0], atol=0)
    assert_allclose(q2, q, atol=1e-14)
    with pytest.raises(RequestError, match='position needs 3 numbers'):
        pose_to_transform([1.0, 2.0], q)


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
@pytest.mark.parametrize(('quat', 'cause'), [
    ([0.0, 0.0, 0.0, 0.0], r'quaternion is not normalised \(norm 0,'),
    ([0.0, 0.0, 0.0, 2.0], r'quaternion is not normalised \(norm 2,'),
    ([0.0, 0.0, 0.6, 0.6], r'quaternion is not normalised \(norm 0\.848528'),
    ([0.0, 0.0, np.nan, 1.0], r'quaternion contains NaN or inf'),
    ([0.0, 0.0, 1.0], r'a quaternion needs 4 numbers'),
])
def test_regression_bad_quaternion(quat: list[float], cause: str) -> None:
    expect_error('regression', lambda: pose_to_transform([2.5, 1.5, 0.0], quat, 'goal'), RequestError,
                 r'^goal\.orientation: ' + cause)


def test_regression_quaternion_just_unnormalised_is_normalised() -> None:
    psi = math.atan2(0.5, 0.866)
    q = np.array([0.0, 0.0, math.sin(psi / 2), math.cos(psi / 2)]) * (1 + 9e-4)
    T = guarded('regression', lambda: pose_to_transform([2.5, 1.5, 0.0], q)).value
    np.testing.assert_allclose(T[:3, :3], [[math.cos(psi), -math.sin(psi), 0], [math.sin(psi), math.cos(psi), 0],
                                           [0, 0, 1]], atol=1e-15)
