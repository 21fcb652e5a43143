"""Point clouds into the collision scene: the cell as sensors see it.

A sensor's cloud becomes one scene object, an occupancy octree (:func:`cloud_map`):

1. points with a NaN or inf coordinate are skipped (depth cameras mark misses so), the rest are
   taken into the base frame by the sensor's pose (:class:`Sensor`);
2. the robot's own image is removed (:class:`SelfFilter`): every point inside one of the robot's
   collision bodies grown by ``padding``, at the joint state given;
3. the voxels of side ``resolution`` (on octomap's grid: multiples of the side from the base
   frame's origin) that hold at least one point left become the occupied cells of a
   ``coal.OcTree`` (:class:`~.collision_bodies.Shape` of kind ``'octree'``), a scene object named
   after the sensor (its topic): the collision check measures the robot against those cells like
   against any other object, and names the pair ``(link, sensor)``.

Each cloud *replaces* its sensor's map (:func:`with_map`): nothing is remembered from earlier
clouds, so an obstacle that moves away disappears with the next cloud, and what the sensor does
not see now (behind an object, out of its view) is not in the map. (OctoMap's free-space clearing
by ray casting, which keeps a persistent map, is not used.)

The self filter's bodies are the collision model's (URDF geometry or the presets' capsules) at
their poses for ``q``; "grown by the padding" is exact for spheres and capsules, and for boxes,
cylinders, cones (their bounding cylinder) and convex hulls of meshes it moves each face out by
the padding (a little more than the padding near edges and corners: more is removed, never less).
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import coal
import numpy as np

from .collision import CollisionModel
from .collision_bodies import SceneObject, Shape
from .collision_scene import with_object_replaced
from .errors import ConfigError, PlanningFailedError, RequestError, quoted

__all__ = ['DEFAULT_MAX_POINTS', 'DEFAULT_RESOLUTION', 'DEFAULT_SELF_FILTER_PADDING', 'CloudMap', 'SelfFilter',
           'Sensor', 'StaleMapError', 'cloud_map', 'map_summary', 'sensors', 'voxel_centres', 'with_map']

#: Default voxel side of the occupancy octrees, m.
DEFAULT_RESOLUTION = 0.02
#: Default growth of the robot's bodies for the self filter, m.
DEFAULT_SELF_FILTER_PADDING = 0.03
#: Default largest number of points in one cloud (width x height).
DEFAULT_MAX_POINTS = 1_000_000
#: octomap's keys are 16 bits: a point farther than this many voxel sides from the origin along an
#: axis has no cell (it is skipped and counted).
GRID_HALF = 32768
_BITS = 17                     # per axis in a packed key (the keys shifted to 0 .. 2 GRID_HALF - 1)


class StaleMapError(PlanningFailedError):
    """A configured sensor's map is older than ``max_cloud_age`` (or it has sent no cloud yet)."""


@dataclass(frozen=True, eq=False)
class Sensor:
    """A point-cloud source.

    Attributes:
        topic: where its clouds arrive; its map's name (the scene object's id, the pair's name).
        frame: the sensor's frame (the clouds' frame_id when they are not in the base frame).
        pose: 4x4, the sensor frame in the robot's base frame.
    """

    topic: str
    frame: str
    pose: np.ndarray


def sensors(topics: Sequence[str], frames: Sequence[str], poses: Sequence[float]) -> tuple[Sensor, ...]:
    """The sensors of parameter values: one frame and 7 pose values (x y z qx qy qz qw, base frame)
    per topic.

    Raises:
        ConfigError: counts that do not match, empty or repeated names, NaN/inf or a quaternion
            that is not of unit length (within 1e-3).
    """
    from .transforms import pose_to_transform

    topics, frames = list(topics), list(frames)
    values = [float(v) for v in poses]
    if len(frames) != len(topics):
        raise ConfigError(f'point_cloud_frames: one frame per topic of point_cloud_topics ({len(topics)}), '
                          f'got {len(frames)}')
    if len(values) != 7 * len(topics):
        raise ConfigError(f'point_cloud_poses: 7 values (x y z qx qy qz qw, the sensor in the base frame) per '
                          f'topic of point_cloud_topics ({len(topics)}): {7 * len(topics)} values, got {len(values)}')
    out = []
    for i, (topic, frame) in enumerate(zip(topics, frames)):
        if not topic or not frame:
            raise ConfigError(f'point_cloud_topics / point_cloud_frames [{i}]: empty name')
        if topic in topics[:i]:
            raise ConfigError(f'point_cloud_topics: {quoted(topic)} given twice')
        x = values[7 * i:7 * i + 7]
        if not all(math.isfinite(v) for v in x):
            raise ConfigError(f'point_cloud_poses[{7 * i}:{7 * i + 7}] ({topic}): NaN or inf in {x}')
        norm = math.sqrt(sum(v * v for v in x[3:]))
        if abs(norm - 1.0) > 1e-3:
            raise ConfigError(f'point_cloud_poses[{7 * i + 3}:{7 * i + 7}] ({topic}): the quaternion must have '
                              f'unit length, got {norm:.6g}')
        out.append(Sensor(topic, frame, pose_to_transform(x[:3], [v / norm for v in x[3:]])))
    return tuple(out)


# --------------------------------------------------------------------------- self filter

#: points in a body's frame (N, 3), a limit (m) -> the bound (N,); values above the limit may be any
#: value above it
Bound = Callable[[np.ndarray, float], np.ndarray]
#: Points x faces evaluated at once by a hull's bound: a block stays in the cache, and its product
#: stays below OpenBLAS's threading threshold (its threads spin, a cost on a loaded machine).
_BLOCK = 65_536


def _hull_bound(points: np.ndarray) -> Bound | None:
    """max over the convex hull's faces of the signed distance to the face's plane (None: flat)."""
    from scipy.spatial import ConvexHull, QhullError

    points = np.asarray(points, dtype=float)
    try:
        eq = ConvexHull(np.asarray(points, dtype=float)).equations       # unit normals, n.x + d <= 0 inside
    except (QhullError, ValueError):
        return None
    normals, offsets = eq[:, :3].copy(), eq[:, 3].copy()
    box = _box_bound(0.5 * (points.max(axis=0) - points.min(axis=0)), 0.5 * (points.max(axis=0) + points.min(axis=0)))

    rows = max(1, _BLOCK // len(normals))

    def hull(x: np.ndarray, limit: float) -> np.ndarray:
        out = box(x, limit)                   # the hull's bounding box first: the faces only near it
        near = np.flatnonzero(out <= limit)
        for start in range(0, len(near), rows):
            idx = near[start:start + rows]
            out[idx] = np.maximum(out[idx], (x[idx] @ normals.T + offsets).max(axis=1))
        return out
    return hull


def _box_bound(half: np.ndarray, center: np.ndarray | None = None) -> Bound:
    c = np.zeros(3) if center is None else center
    return lambda x, limit: (np.abs(x - c) - half).max(axis=1)


def distance_bound(geometry: object) -> Bound:
    """For a coal geometry: a function of points in its frame, (N, 3) -> (N,), that is at most the
    points' distance from it outside and <= 0 inside (1-Lipschitz): exact for spheres and capsules,
    the largest face-plane distance for boxes, cylinders, cones (their bounding cylinder) and convex
    hulls (with their bounding box's), the local bounding box for anything else (:data:`Bound`)."""
    g = geometry
    if isinstance(g, coal.Sphere):
        r = float(g.radius)
        return lambda x, limit: np.linalg.norm(x, axis=1) - r
    if isinstance(g, coal.Capsule):
        h, r = float(g.halfLength), float(g.radius)

        def capsule(x: np.ndarray, limit: float) -> np.ndarray:
            axis = np.zeros_like(x)
            axis[:, 2] = np.clip(x[:, 2], -h, h)
            return np.linalg.norm(x - axis, axis=1) - r
        return capsule
    if isinstance(g, coal.Box):
        return _box_bound(np.asarray(g.halfSide, dtype=float))
    if isinstance(g, (coal.Cylinder, coal.Cone)):
        h, r = float(g.halfLength), float(g.radius)
        return lambda x, limit: np.maximum(np.hypot(x[:, 0], x[:, 1]) - r, np.abs(x[:, 2]) - h)
    found = None
    if isinstance(g, coal.ConvexBase):
        found = _hull_bound(np.asarray(g.points(), dtype=float))
    elif isinstance(g, coal.BVHModelBase):
        found = _hull_bound(np.asarray(g.vertices(), dtype=float))
    if found is not None:
        return found
    other: Any = g
    other.computeLocalAABB()
    lo = np.asarray(other.aabb_local.min_, dtype=float)
    hi = np.asarray(other.aabb_local.max_, dtype=float)
    return _box_bound(0.5 * (hi - lo), 0.5 * (hi + lo))


class SelfFilter:
    """Removes the robot's own image from clouds: the points inside its bodies grown by ``padding``.

    Args:
        model: the collision model whose robot bodies are used (its scene objects are not).
        padding: growth of every body, m (finite, >= 0).
    """

    def __init__(self, model: CollisionModel, padding: float) -> None:
        if not (math.isfinite(padding) and padding >= 0.0):
            raise RequestError(f'self-filter padding must be finite and >= 0 m, got {padding!r}')
        self.robot = model.robot
        self.padding = float(padding)
        bodies = model.robot_bodies
        self._segment = np.array([b.segment for b in bodies], dtype=int)
        self._offset = np.array([b.offset for b in bodies]).reshape(-1, 4, 4)
        self._center = np.array([b.center for b in bodies]).reshape(-1, 3)
        self._radius = np.array([b.radius for b in bodies], dtype=float)
        self._bounds = [distance_bound(b.geometry) for b in bodies]

    def inside(self, points: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Which points (base frame, (N, 3), m) lie on the robot at ``q`` (its bodies grown by the
        padding): a boolean mask (N,)."""
        return self.bound(points, q, self.padding) <= self.padding

    def bound(self, points: np.ndarray, q: np.ndarray, limit: float) -> np.ndarray:
        """A 1-Lipschitz lower bound of the points' distances from the robot at ``q``, (N,), m: per
        body the larger of its :func:`distance_bound` and the distance from its bounding sphere, the
        least over the bodies; ``inf`` where it is above ``limit``. A point is on the robot where
        it is at most the padding."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        out = np.full(len(P), np.inf)
        if not len(self._bounds) or not len(P):
            return out
        S = self.robot.segment_frames(self.robot.check_joints(np.asarray(q, dtype=float)[None], 'q'))[0]
        frames = S[self._segment] @ self._offset                              # (B, 4, 4)
        centers = np.einsum('bij,bj->bi', S[self._segment, :3, :3], self._center) + S[self._segment, :3, 3]
        reach = self._radius + limit
        lo, hi = (centers - reach[:, None]).min(axis=0), (centers + reach[:, None]).max(axis=0)
        near = np.flatnonzero(np.all((lo <= P) & (hi >= P), axis=1))          # the robot's box
        sub = P[near]
        best = np.full(len(sub), np.inf)
        for b, bound in enumerate(self._bounds):
            d = sub - centers[b]
            sphere = np.sqrt(np.einsum('ij,ij->i', d, d)) - self._radius[b]
            idx = np.flatnonzero(sphere <= limit)
            if not idx.size:
                continue
            local = (sub[idx] - frames[b, :3, 3]) @ frames[b, :3, :3]         # R^T (p - t)
            best[idx] = np.minimum(best[idx], np.maximum(bound(local, limit), sphere[idx]))
        best[best > limit] = np.inf
        out[near] = best
        return out


# --------------------------------------------------------------------------- maps

@dataclass(frozen=True)
class CloudMap:
    """One sensor's map, made of its latest cloud.

    Attributes:
        id: the sensor's name (topic): the scene object's id.
        object: the octree scene object (None: no point left to occupy a cell).
        received: points in the cloud; finite: those without NaN/inf (and within the grid);
        robot: those removed as the robot's own; voxels: occupied cells.
        resolution: the voxel side, m.
    """

    id: str
    object: SceneObject | None
    received: int
    finite: int
    robot: int
    voxels: int
    resolution: float

    @property
    def kept(self) -> int:
        """Points inserted into the map."""
        return self.finite - self.robot


def voxel_centres(points: np.ndarray, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """The centres (K, 3) of the voxels of side ``resolution`` that hold at least one of ``points``
    (base frame, (N, 3), finite), in octomap's grid; with the mask (N,) of the points the grid
    holds (within :data:`GRID_HALF` sides of the origin)."""
    packed, ok = _voxel_keys(np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3).T), resolution)
    return _centres(np.unique(packed), resolution), ok


def _voxel_keys(xyz: np.ndarray, resolution: float) -> tuple[np.ndarray, np.ndarray]:
    """The packed voxel keys of the points (rows x, y, z, (3, N)) the grid holds, and their mask (N,)."""
    k = xyz * (1.0 / resolution)
    np.floor(k, out=k)
    ok = np.ones(k.shape[1], dtype=bool)
    if k.size and (k.min() < -GRID_HALF or k.max() >= GRID_HALF):
        for a in range(3):
            ok &= (k[a] >= -GRID_HALF) & (k[a] < GRID_HALF)
        k = k[:, ok]
    key = k.astype(np.int64)
    key += GRID_HALF
    packed = key[0] << (2 * _BITS)
    packed |= key[1] << _BITS
    packed |= key[2]
    return packed, ok


def _centres(keys: np.ndarray, resolution: float) -> np.ndarray:
    """The centres (K, 3) of packed voxel keys (K,)."""
    mask = (1 << _BITS) - 1
    cells = np.stack([keys >> (2 * _BITS), (keys >> _BITS) & mask, keys & mask], axis=1) - GRID_HALF
    return (cells + 0.5) * resolution


def _filtered_keys(packed: np.ndarray, xyz: np.ndarray, resolution: float, self_filter: SelfFilter,
                   q: np.ndarray) -> tuple[np.ndarray, int]:
    """The occupied voxels' keys once the robot's points are removed, and the points removed.

    The filter's bound is 1-Lipschitz, so a voxel whose centre's bound is beyond the padding by
    more than half its diagonal holds no point on the robot, one whose bound is below the padding by
    as much holds only such points; the points of the voxels between are tested one by one. The
    answer is the point-by-point one.
    """
    pad, half = self_filter.padding, 0.5 * math.sqrt(3.0) * resolution
    voxels = np.unique(packed)
    g = self_filter.bound(_centres(voxels, resolution), q, pad + half)
    inner = g + half <= pad
    border = ~inner & (g - half <= pad)
    special = np.flatnonzero(inner | border)
    if not special.size:
        return voxels, 0
    keys = voxels[special]                                              # sorted
    pos = np.minimum(np.searchsorted(keys, packed), len(keys) - 1)
    member = np.flatnonzero(keys[pos] == packed)
    on_border = border[special][pos[member]]
    tested = member[on_border]
    kept = tested[~self_filter.inside(xyz[:, tested].T, q)]
    removed = len(member) - len(kept)
    keep = ~(inner | border)
    return np.union1d(voxels[keep], packed[kept]), removed


def cloud_map(sensor_id: str, points: np.ndarray, to_base: np.ndarray, resolution: float, *,
              self_filter: SelfFilter | None = None, q: np.ndarray | None = None) -> CloudMap:
    """One cloud -> its sensor's map (see the module's doc).

    Args:
        sensor_id: the map's name.
        points: (N, 3), float32 or float64, in the frame ``to_base`` maps into the base frame; rows
            with NaN or inf are skipped.
        to_base: 4x4.
        resolution: voxel side, m (finite, > 0).
        self_filter, q: remove the robot at joint state q (both or neither).
    Raises:
        RequestError: points not (N, 3), a bad resolution or transform, a filter without q.
    """
    pts = np.asarray(points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise RequestError(f'cloud {quoted(sensor_id)}: points must be (N, 3), got shape {pts.shape}')
    if not (math.isfinite(resolution) and resolution > 0.0):
        raise RequestError(f'octree resolution must be finite and > 0 m, got {resolution!r}')
    T = np.asarray(to_base, dtype=float)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise RequestError(f'cloud {quoted(sensor_id)}: the sensor pose must be a finite 4x4 transform')
    if self_filter is not None and q is None:
        raise RequestError(f'cloud {quoted(sensor_id)}: the self filter needs a joint state')
    received = len(pts)
    cols = pts.T                                          # x, y, z rows (views)
    total = cols[0] + cols[1] + cols[2]                   # NaN or inf in any coordinate (or huge)
    finite = np.flatnonzero(np.isfinite(total))
    picked = np.empty((3, len(finite)))                   # a row at a time (3x faster than cols[:, finite])
    for axis in range(3):
        picked[axis] = cols[axis][finite] if len(finite) < received else cols[axis]
    xyz = np.einsum('ij,jn->in', T[:3, :3], picked)
    xyz += T[:3, 3:4]
    packed, in_grid = _voxel_keys(xyz, float(resolution))
    outside = int(len(in_grid) - in_grid.sum())
    removed = 0
    if self_filter is not None and len(packed):
        if outside:
            xyz = xyz[:, in_grid]
        keys, removed = _filtered_keys(packed, xyz, float(resolution), self_filter, np.asarray(q, dtype=float))
    else:
        keys = np.unique(packed)
    centres = _centres(keys, float(resolution))
    obj = None
    if len(centres):
        obj = SceneObject(sensor_id, Shape('octree', (float(resolution),), vertices=centres))
    return CloudMap(sensor_id, obj, received, len(finite) - outside, removed, len(centres), float(resolution))


def with_map(model: CollisionModel, sensor_id: str, obj: SceneObject | None) -> CollisionModel:
    """``model`` with the object named ``sensor_id`` replaced by ``obj`` (removed when None; ``obj`` comes
    last): :func:`~.collision_scene.with_object_replaced`, the other objects' bodies and pairs reused."""
    return with_object_replaced(model, sensor_id, obj)


def map_summary(found: CloudMap, age: float) -> str:
    """One line about a map: points, voxels and the age of its cloud (s)."""
    return (f'octree: {found.kept} points in {found.voxels} voxels of {found.resolution:g} m from a cloud of '
            f'{found.received} points ({found.received - found.finite} NaN or out of range, {found.robot} '
            f'on the robot), {age:.3f} s old')
