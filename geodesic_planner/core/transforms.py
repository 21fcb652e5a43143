"""Rigid transforms: quaternions (x, y, z, w), rotation matrices, SO(3) exp/log, line + slerp.

All functions take and return numpy arrays; batched where the docstring says ``(..., )``.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import RequestError

#: A quaternion whose norm differs from 1 by less than this is normalised silently.
QUAT_NORM_TOLERANCE = 1e-3


def hat(w: np.ndarray) -> np.ndarray:
    """Skew matrix of vectors ``w`` of shape (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    out = np.zeros(w.shape[:-1] + (3, 3))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def so3_exp(w: np.ndarray) -> np.ndarray:
    """Rotation matrices exp(hat(w)) for rotation vectors ``w`` (..., 3) in rad -> (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = hat(w)
    small = th < 1e-8
    th_safe = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th**2 / 6.0, np.sin(th_safe) / th_safe)
    b = np.where(small, 0.5 - th**2 / 24.0, (1.0 - np.cos(th_safe)) / th_safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def so3_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of rotation matrices ``R`` (..., 3, 3) -> (..., 3); angle in [0, pi]."""
    R = np.asarray(R, dtype=float)
    q = matrix_to_quat(R)
    # q = (x, y, z, w), w >= 0 from matrix_to_quat
    v = q[..., :3]
    s = np.linalg.norm(v, axis=-1)
    ang = 2.0 * np.arctan2(s, q[..., 3])
    scale = np.where(s < 1e-12, 2.0, ang / np.where(s < 1e-12, 1.0, s))
    return v * scale[..., None]


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices from unit quaternions (x, y, z, w) of shape (..., 4) -> (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    x, y, z, w = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - z * w)
    R[..., 0, 2] = 2 * (x * z + y * w)
    R[..., 1, 0] = 2 * (x * y + z * w)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - x * w)
    R[..., 2, 0] = 2 * (x * z - y * w)
    R[..., 2, 1] = 2 * (y * z + x * w)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w), w >= 0, of rotation matrices (..., 3, 3) -> (..., 4)."""
    R = np.asarray(R, dtype=float)
    m = R.reshape((-1, 3, 3))
    out = np.empty((m.shape[0], 4))
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    # Candidates: pick the largest of w, x, y, z for numerical stability.
    cand = np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1)
    k = np.argmax(cand, axis=1)
    for i in range(m.shape[0]):
        r = m[i]
        if k[i] == 0:
            s = np.sqrt(max(tr[i] + 1.0, 0.0)) * 2
            out[i] = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
        elif k[i] == 1:
            s = np.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 0.0)) * 2
            out[i] = [0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s, (r[2, 1] - r[1, 2]) / s]
        elif k[i] == 2:
            s = np.sqrt(max(1.0 + r[1, 1] - r[0, 0] - r[2, 2], 0.0)) * 2
            out[i] = [(r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s, (r[0, 2] - r[2, 0]) / s]
        else:
            s = np.sqrt(max(1.0 + r[2, 2] - r[0, 0] - r[1, 1], 0.0)) * 2
            out[i] = [(r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s, (r[1, 0] - r[0, 1]) / s]
    out *= np.where(out[:, 3:4] < 0, -1.0, 1.0)
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(R.shape[:-2] + (4,))


def make_transform(position: npt.ArrayLike, rotation: npt.ArrayLike) -> np.ndarray:
    """4x4 homogeneous transform from a position (3,) in m and a rotation matrix (3, 3)."""
    T = np.eye(4)
    T[:3, :3] = rotation
    T[:3, 3] = position
    return T


def check_quaternion(q: npt.ArrayLike, what: str = 'orientation') -> np.ndarray:
    """Validate a quaternion (x, y, z, w): finite, norm within QUAT_NORM_TOLERANCE of 1 (then normalised).

    Raises:
        RequestError: NaN/inf, zero, or norm too far from 1 (the message gives the norm).
    """
    arr = np.asarray(q, dtype=float).reshape(-1)
    if arr.shape != (4,):
        raise RequestError(f'{what}: a quaternion needs 4 numbers (x, y, z, w), got {arr.size}')
    if not np.all(np.isfinite(arr)):
        raise RequestError(f'{what}: quaternion contains NaN or inf: {arr.tolist()}')
    norm = float(np.linalg.norm(arr))
    if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
        unset = ': all zero, the orientation is unset (w: 1 for no rotation)' if norm == 0.0 else ''
        raise RequestError(
            f'{what}: quaternion is not normalised (norm {norm:.6g}, expected 1 within '
            f'{QUAT_NORM_TOLERANCE:g}){unset}')
    return arr / norm


def pose_to_transform(position: npt.ArrayLike, orientation: npt.ArrayLike, what: str = 'pose') -> np.ndarray:
    """4x4 transform from a position (x, y, z) in m and a quaternion (x, y, z, w); validated.

    Raises:
        RequestError: non-finite position or invalid quaternion.
    """
    p = np.asarray(position, dtype=float).reshape(-1)
    if p.shape != (3,):
        raise RequestError(f'{what}: position needs 3 numbers (x, y, z), got {p.size}')
    if not np.all(np.isfinite(p)):
        raise RequestError(f'{what}: position contains NaN or inf: {p.tolist()}')
    quat = check_quaternion(orientation, f'{what}.orientation')
    return make_transform(p, quat_to_matrix(quat))


def pose_from_mapping(pose: Mapping[str, Any], what: str = 'pose') -> np.ndarray:
    """4x4 transform from a geometry_msgs/Pose in YAML/dict form.

    ``{'position': {'x':..,'y':..,'z':..}, 'orientation': {'x':..,'y':..,'z':..,'w':..}}``;
    missing position fields default to 0 and a missing orientation to identity, as in ROS.

    Raises:
        RequestError: wrong structure or invalid values.
    """
    if not isinstance(pose, Mapping):
        raise RequestError(f'{what}: expected a mapping with position/orientation, got {type(pose).__name__}')
    pos = pose.get('position', {}) or {}
    ori = pose.get('orientation', {'w': 1.0}) or {'w': 1.0}
    if not isinstance(pos, Mapping) or not isinstance(ori, Mapping):
        raise RequestError(f'{what}: position and orientation must be mappings')
    try:
        p = [float(pos.get(k, 0.0)) for k in 'xyz']
        q = [float(ori.get(k, 0.0)) for k in 'xyzw']
    except (TypeError, ValueError) as err:
        raise RequestError(f'{what}: non-numeric value ({err})') from err
    return pose_to_transform(p, q, what)


def transform_to_pose(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position (3,) m, quaternion (x, y, z, w)) of a 4x4 transform."""
    T = np.asarray(T, dtype=float)
    return T[..., :3, 3].copy(), matrix_to_quat(T[..., :3, :3])


def line_slerp(T_a: np.ndarray, T_b: np.ndarray, s: np.ndarray,
               rotation_vector: np.ndarray | None = None) -> np.ndarray:
    """Task-space geodesic: straight line for position, constant-rate rotation (slerp).

    Args:
        T_a, T_b: 4x4 start and goal transforms.
        s: path parameter, shape (N,), in [0, 1].
        rotation_vector: ``so3_log(R_aᵀ R_b)`` (rad, start frame) if already known.
    Returns:
        Transforms, shape (N, 4, 4).
    """
    s = np.asarray(s, dtype=float).reshape(-1)
    w = so3_log(T_a[:3, :3].T @ T_b[:3, :3]) if rotation_vector is None else rotation_vector
    out = np.zeros((s.size, 4, 4))
    out[:, :3, :3] = T_a[:3, :3] @ so3_exp(s[:, None] * w)
    out[:, :3, 3] = T_a[:3, 3] + s[:, None] * (T_b[:3, 3] - T_a[:3, 3])
    out[:, 3, 3] = 1.0
    return out


def segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) from points ``p`` (N, 3) to the segment from ``a`` to ``b`` (3,), shape (N,)."""
    p = np.asarray(p, dtype=float).reshape(-1, 3)
    a = np.asarray(a, dtype=float)
    ab = np.asarray(b, dtype=float) - a
    rel = p - a
    length = float(np.linalg.norm(ab))
    if length == 0.0:
        return np.linalg.norm(rel, axis=1)
    u = ab / length
    t = np.clip(rel @ u, 0.0, length)
    return np.linalg.norm(rel - t[:, None] * u, axis=1)


def pose_error(T_a: np.ndarray, T_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position distance (m) and rotation angle (rad) between transforms (..., 4, 4)."""
    dp = np.linalg.norm(T_a[..., :3, 3] - T_b[..., :3, 3], axis=-1)
    Rrel = np.swapaxes(T_a[..., :3, :3], -1, -2) @ T_b[..., :3, :3]
    c = np.trace(Rrel, axis1=-2, axis2=-1) - 1.0
    sv = np.stack([Rrel[..., 2, 1] - Rrel[..., 1, 2], Rrel[..., 0, 2] - Rrel[..., 2, 0],
                   Rrel[..., 1, 0] - Rrel[..., 0, 1]], axis=-1)
    return dp, np.arctan2(np.linalg.norm(sv, axis=-1), c)  # accurate for small and large angles


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def check_transform(T: object, what: str) -> np.ndarray:
    """Validate a 4x4 homogeneous transform (finite, orthonormal rotation); returns a float array.

    Raises:
        RequestError: wrong shape, NaN/inf, or a rotation that is not orthonormal.
    """
    try:
        arr = np.asarray(T, dtype=float)
    except (TypeError, ValueError) as err:
        raise RequestError(f'{what}: not a numeric 4x4 transform ({err})') from err
    if arr.shape != (4, 4):
        raise RequestError(f'{what}: expected a 4x4 homogeneous transform, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise RequestError(f'{what}: transform contains NaN or inf')
    R = arr[:3, :3]
    orth = float(np.abs(R.T @ R - np.eye(3)).max())
    if orth > 1e-6 or np.linalg.det(R) < 0:
        raise RequestError(f'{what}: rotation part is not a proper rotation (|RᵀR − I| = {orth:.3g})')
    if not np.all(np.abs(arr[3] - _LAST_ROW) <= 1e-8 + 1e-5 * _LAST_ROW):   # np.allclose, cheaper
        raise RequestError(f'{what}: last row must be [0, 0, 0, 1]')
    return arr
