"""Synthetic point clouds for the tests: a simulated depth camera ray casting boxes, and points on
the robot's own capsules.

The camera looks along its frame's +z (the optical frame's convention: x right, y down); each
pixel's ray is cast against axis-aligned boxes of the base frame (slab method), the nearest hit is
taken with Gaussian noise along the ray, misses are NaN (as depth cameras report them), and a
fraction of the hits is dropped to NaN too. Nothing here uses the code under test.
"""
from __future__ import annotations

import numpy as np


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4x4 pose of a camera at ``eye`` whose +z looks at ``target`` (base frame; image x horizontal)."""
    up = np.array([0.0, 0.0, 1.0])
    z = np.asarray(target, float) - np.asarray(eye, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, y, z], axis=1)
    T[:3, 3] = eye
    return T


def depth_camera(boxes: list[tuple[np.ndarray, np.ndarray]], camera: np.ndarray, *, width: int = 160,
                 height: int = 120, fov: float = 1.2, noise: float = 0.002, nan_fraction: float = 0.02,
                 rng: np.random.Generator | None = None, dtype: type = np.float32) -> np.ndarray:
    """An organised cloud (height, width, 3) in the camera frame of boxes (lo, hi) in the base frame."""
    rng = rng or np.random.default_rng(0)
    f = 0.5 * width / np.tan(0.5 * fov)
    u, v = np.meshgrid(np.arange(width) + 0.5 - 0.5 * width, np.arange(height) + 0.5 - 0.5 * height)
    d_cam = np.stack([u / f, v / f, np.ones_like(u)], axis=-1).reshape(-1, 3)
    d_cam /= np.linalg.norm(d_cam, axis=1, keepdims=True)
    d = d_cam @ camera[:3, :3].T
    o = camera[:3, 3]
    best = np.full(len(d), np.inf)
    with np.errstate(divide='ignore', invalid='ignore'):
        for lo, hi in boxes:
            t1, t2 = (np.asarray(lo) - o) / d, (np.asarray(hi) - o) / d
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            hit = (near <= far) & (far > 0) & (near > 0)
            best = np.where(hit & (near < best), near, best)
    t = best + rng.normal(0.0, noise, len(best))
    t[~np.isfinite(best)] = np.nan
    t[rng.random(len(t)) < nan_fraction] = np.nan
    return (d_cam * t[:, None]).reshape(height, width, 3).astype(dtype)


def capsule_points(frames: np.ndarray, half_lengths: np.ndarray, radius: float, n: int,
                   rng: np.random.Generator, jitter: float = 0.0) -> np.ndarray:
    """n points on the surfaces of capsules (frames (B, 4, 4), axis along z, half lengths (B,)),
    pushed out by up to ``jitter`` m, in the base frame."""
    b = rng.integers(0, len(frames), n)
    z = rng.uniform(-1.0, 1.0, n) * half_lengths[b]
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    local = np.c_[np.zeros(n), np.zeros(n), z] + direction * (radius + rng.uniform(0.0, jitter, n))[:, None]
    return np.einsum('nij,nj->ni', frames[b, :3, :3], local) + frames[b, :3, 3]
