"""Collision objects as messages: geodesic_planner_interfaces/CollisionObject <-> SceneObject, and
the scene as RViz markers.

A CollisionObject holds one shape: ``mesh_resource`` when set, else ``mesh`` when it has triangles,
else ``primitive`` (BOX, SPHERE, CYLINDER, CONE; PRISM is not supported). Invalid messages raise
:class:`~geodesic_planner.core.errors.RequestError` naming the object's id and the field.
"""
from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geodesic_planner_interfaces.msg import CollisionObject
from geometry_msgs.msg import Point, Vector3
from shape_msgs.msg import Mesh, MeshTriangle, SolidPrimitive
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from ..core.collision import SceneObject, Shape
from ..core.errors import RequestError, quoted
from ..io.scene import check_dimensions, resolve_mesh
from .conversions import matrix_to_pose, pose_to_matrix

#: shape_msgs/SolidPrimitive type -> our primitive kind.
PRIMITIVE_KINDS: dict[int, str] = {SolidPrimitive.BOX: 'box', SolidPrimitive.SPHERE: 'sphere',
                                   SolidPrimitive.CYLINDER: 'cylinder', SolidPrimitive.CONE: 'cone'}
PRIMITIVE_TYPES: dict[str, int] = {kind: t for t, kind in PRIMITIVE_KINDS.items()}
#: Marker namespace of the scene's objects.
SCENE_NS = 'scene'
#: Colours (r, g, b, a) of fixed and of attached objects.
OBJECT_COLOR = (0.3, 0.6, 1.0, 0.6)
ATTACHED_COLOR = (1.0, 0.6, 0.1, 0.8)
#: Segments around the axis of a cone or capsule drawn as triangles.
ROUND_SEGMENTS = 32


# --------------------------------------------------------------------------- message -> library


def collision_object_to_scene(msg: CollisionObject, package_dirs: Sequence[str] = ()) -> SceneObject:
    """The scene object of a CollisionObject, validated.

    Args:
        msg: the object; pose in m (base frame, or tool frame when ``attached``), dimensions in m.
        package_dirs: directories searched for ``package://PKG/...`` mesh resources before the
            ament index.
    Returns:
        The object; a mesh file as its resolved absolute path.
    Raises:
        RequestError: empty id; NaN/inf or an unnormalised quaternion in the pose; no shape, an
            unknown primitive type or PRISM, a wrong dimension count, NaN/inf or a dimension <= 0;
            mesh vertices with NaN/inf or triangles naming a vertex the mesh does not have; a
            mesh_scale with NaN/inf or a negative factor; a mesh file that is not found.
    """
    if not msg.id:
        raise RequestError('collision object: empty id (every object needs a unique, non-empty id)')
    what = f'collision object {quoted(msg.id)}'
    pose = pose_to_matrix(msg.pose, f'{what}: pose')
    if msg.mesh_resource:
        scale = _mesh_scale(msg.mesh_scale, what)
        path = resolve_mesh(msg.mesh_resource, f'{what}: mesh_resource', package_dirs=package_dirs)
        shape = _shape(what, lambda: Shape('mesh', mesh=path, scale=scale))
    elif len(msg.mesh.triangles) > 0:
        scale = _mesh_scale(msg.mesh_scale, what)
        vertices, triangles = _mesh_arrays(msg.mesh, what)
        shape = _shape(what, lambda: Shape('mesh', vertices=vertices, triangles=triangles, scale=scale))
    else:
        kind = _primitive_kind(msg.primitive.type, what)
        dims = check_dimensions(kind, [float(d) for d in msg.primitive.dimensions],
                                f'{what}: primitive.dimensions')
        shape = _shape(what, lambda: Shape(kind, dimensions=dims))
    try:
        return SceneObject(msg.id, shape, pose, attached=bool(msg.attached))
    except RequestError as err:
        raise RequestError(f'{what}: {err}') from err


def _primitive_kind(type_: int, what: str) -> str:
    if type_ in PRIMITIVE_KINDS:
        return PRIMITIVE_KINDS[type_]
    known = 'BOX 1, SPHERE 2, CYLINDER 3, CONE 4'
    if type_ == 0:
        raise RequestError(f'{what}: no shape: mesh_resource is empty, mesh has no triangles and '
                           f'primitive.type is 0 (set one; primitive types: {known})')
    if type_ == SolidPrimitive.PRISM:
        raise RequestError(f'{what}: primitive.type PRISM (5) is not supported (use {known}, or a mesh)')
    raise RequestError(f'{what}: primitive.type {type_} is unknown (known: {known})')


def _mesh_scale(scale: Vector3, what: str) -> tuple[float, float, float]:
    """mesh_scale with 0 meaning 1; NaN/inf or a negative factor refused."""
    values = (float(scale.x), float(scale.y), float(scale.z))
    if not all(math.isfinite(v) and v >= 0.0 for v in values):
        raise RequestError(f'{what}: mesh_scale must be finite and >= 0 (0 means 1), got {list(values)}')
    x, y, z = (v if v > 0.0 else 1.0 for v in values)
    return x, y, z


def _mesh_arrays(mesh: Mesh, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) m and triangles (T, 3) int64 of a shape_msgs/Mesh, validated."""
    vertices = np.array([(p.x, p.y, p.z) for p in mesh.vertices], dtype=float).reshape(-1, 3)
    bad = np.flatnonzero(~np.all(np.isfinite(vertices), axis=1))
    if bad.size:
        raise RequestError(f'{what}: mesh.vertices[{int(bad[0])}] contains NaN or inf '
                           f'({bad.size} such vertices)')
    triangles = np.array([tuple(t.vertex_indices) for t in mesh.triangles], dtype=np.int64).reshape(-1, 3)
    n = len(vertices)
    out = np.flatnonzero(np.any(triangles >= n, axis=1))
    if out.size:
        i = int(out[0])
        raise RequestError(f'{what}: mesh.triangles[{i}] refers to vertex {int(triangles[i].max())}, but '
                           f'the mesh has {n} vertices ({out.size} such triangles)')
    return vertices, triangles


def _shape(what: str, make: Callable[[], Shape]) -> Shape:
    """``make()``, with the Shape's own refusal (if any) prefixed with the object."""
    try:
        return make()
    except RequestError as err:
        raise RequestError(f'{what}: {err}') from err


# --------------------------------------------------------------------------- library -> message


def scene_to_collision_object(obj: SceneObject) -> CollisionObject:
    """The CollisionObject of a scene object (a mesh file as its absolute path in mesh_resource).

    Raises:
        RequestError: a shape the message cannot hold (a capsule).
    """
    msg = CollisionObject(id=obj.id, attached=bool(obj.attached), pose=matrix_to_pose(obj.pose))
    shape = obj.shape
    if shape.kind in PRIMITIVE_TYPES:
        msg.primitive = SolidPrimitive(type=PRIMITIVE_TYPES[shape.kind],
                                       dimensions=[float(d) for d in shape.dimensions])
    elif shape.kind == 'mesh' and shape.mesh is not None:
        msg.mesh_resource = shape.mesh
        sx, sy, sz = (float(s) for s in shape.scale)
        msg.mesh_scale = Vector3(x=sx, y=sy, z=sz)
    elif shape.kind == 'mesh' and shape.vertices is not None and shape.triangles is not None:
        # Shape holds its vertices already scaled: the message carries them as they are, scale 1.
        msg.mesh = Mesh(
            vertices=[Point(x=x, y=y, z=z) for x, y, z in np.asarray(shape.vertices, dtype=float).tolist()],
            triangles=[MeshTriangle(vertex_indices=t) for t in np.asarray(shape.triangles).tolist()])
        msg.mesh_scale = Vector3(x=1.0, y=1.0, z=1.0)
    else:
        raise RequestError(f'scene object {quoted(obj.id)}: a {shape.kind} has no '
                           f'geodesic_planner_interfaces/CollisionObject form (box, sphere, cylinder, '
                           f'cone or mesh)')
    return msg


# --------------------------------------------------------------------------- markers


def marker_ids(ids: Sequence[str]) -> dict[str, int]:
    """A marker id for each object id: its CRC-32 (31 bits), the same in every call; the rare
    clash goes to the next free number, taken in the order of the sorted ids."""
    out: dict[str, int] = {}
    used: set[int] = set()
    for oid in sorted(set(ids)):
        mid = zlib.crc32(oid.encode('utf-8')) & 0x7FFFFFFF
        while mid in used:
            mid = (mid + 1) & 0x7FFFFFFF
        used.add(mid)
        out[oid] = mid
    return out


def scene_markers(objects: Sequence[SceneObject], body_poses: Mapping[str, np.ndarray] | None,
                  frame_id: str, stamp: Time | None = None, *, tool_frame: str = '') -> MarkerArray:
    """The scene for RViz: a DELETEALL (so removed objects vanish), then one marker per object.

    Namespace ``scene``; marker ids from :func:`marker_ids` (stable per object id). Box, sphere and
    cylinder are CUBE, SPHERE and CYLINDER markers; cones, capsules and meshes given by vertices are
    TRIANGLE_LISTs; a mesh file is a MESH_RESOURCE (``file://`` its path). Fixed objects are drawn
    blue, attached ones orange.

    Args:
        objects: the scene's objects.
        body_poses: object id -> its pose in ``frame_id`` (4x4, m), e.g. from the collision model's
            ``body_poses(q)``; used for attached objects.
        frame_id: the base frame.
        stamp: header stamp (zero: RViz uses the latest transform).
        tool_frame: the tool frame's name. An attached object without a pose in ``body_poses`` is
            drawn at its pose in this frame (RViz moves it with the tool); without either it is
            left out.
    """
    header = Header(frame_id=frame_id, stamp=stamp if stamp is not None else Time())
    markers = [Marker(header=header, ns=SCENE_NS, action=Marker.DELETEALL)]
    ids = marker_ids([o.id for o in objects])
    poses = body_poses or {}
    for obj in objects:
        marker_header, pose = header, obj.pose
        if obj.attached:
            if obj.id in poses:
                pose = np.asarray(poses[obj.id], dtype=float)
            elif tool_frame:
                marker_header = Header(frame_id=tool_frame, stamp=header.stamp)
            else:
                continue
        marker = _shape_marker(obj.shape)
        marker.header = marker_header
        marker.ns = SCENE_NS
        marker.id = ids[obj.id]
        marker.action = Marker.ADD
        marker.pose = matrix_to_pose(pose)
        marker.frame_locked = marker_header is not header
        r, g, b, a = ATTACHED_COLOR if obj.attached else OBJECT_COLOR
        marker.color = ColorRGBA(r=r, g=g, b=b, a=a)
        markers.append(marker)
    return MarkerArray(markers=markers)


def _shape_marker(shape: Shape) -> Marker:
    """A marker of the shape's type and size, in the shape's frame (pose, colour, ids not set)."""
    marker = Marker()
    d = [float(v) for v in shape.dimensions]
    if shape.kind == 'box':
        marker.type = Marker.CUBE
        marker.scale = Vector3(x=d[0], y=d[1], z=d[2])
    elif shape.kind == 'sphere':
        marker.type = Marker.SPHERE
        marker.scale = Vector3(x=2.0 * d[0], y=2.0 * d[0], z=2.0 * d[0])
    elif shape.kind == 'cylinder':
        marker.type = Marker.CYLINDER
        marker.scale = Vector3(x=2.0 * d[1], y=2.0 * d[1], z=d[0])
    elif shape.kind == 'mesh' and shape.mesh is not None:
        marker.type = Marker.MESH_RESOURCE
        marker.mesh_resource = 'file://' + shape.mesh
        sx, sy, sz = (float(s) for s in shape.scale)
        marker.scale = Vector3(x=sx, y=sy, z=sz)
    else:
        marker.type = Marker.TRIANGLE_LIST
        marker.scale = Vector3(x=1.0, y=1.0, z=1.0)
        corners = _triangle_corners(shape)
        marker.points = [Point(x=x, y=y, z=z) for x, y, z in corners.tolist()]
    return marker


def _triangle_corners(shape: Shape) -> np.ndarray:
    """Corners of the triangles that draw a cone, a capsule or a vertex mesh, (3 T, 3) m."""
    if shape.kind == 'mesh':
        vertices = np.asarray(shape.vertices, dtype=float)     # already scaled by Shape
        return vertices[np.asarray(shape.triangles, dtype=np.int64).reshape(-1)]
    if shape.kind == 'cone':
        h, r = shape.dimensions
        profile = [(0.0, h / 2.0), (r, -h / 2.0), (0.0, -h / 2.0)]     # tip at +z, as SolidPrimitive
    elif shape.kind == 'capsule':
        length, r = shape.dimensions
        arc = np.linspace(0.0, np.pi / 2.0, ROUND_SEGMENTS // 4 + 1)
        top = [(r * math.sin(a), length / 2.0 + r * math.cos(a)) for a in arc]
        profile = top + [(x, -z) for x, z in reversed(top)]
    else:
        raise RequestError(f'no marker for a shape of kind {quoted(shape.kind)}')
    return _revolve(profile)


def _revolve(profile: Sequence[tuple[float, float]]) -> np.ndarray:
    """Triangles (as corners, (3 T, 3)) of the surface swept by a (radius, z) profile about z."""
    phi = np.linspace(0.0, 2.0 * np.pi, ROUND_SEGMENTS + 1)
    rings = [np.stack([r * np.cos(phi), r * np.sin(phi), np.full_like(phi, z)], axis=1) for r, z in profile]
    tris = []
    for k in range(len(profile) - 1):
        a, b = rings[k][:-1], rings[k][1:]            # upper ring
        c, d = rings[k + 1][:-1], rings[k + 1][1:]    # lower ring
        if profile[k + 1][0] > 0.0:                   # no zero-area triangles at a tip (radius 0)
            tris.append(np.stack([a, c, d], axis=1))
        if profile[k][0] > 0.0:
            tris.append(np.stack([a, d, b], axis=1))  # outward faces, counter-clockwise
    return np.concatenate(tris).reshape(-1, 3)


__all__ = [
    'PRIMITIVE_KINDS',
    'PRIMITIVE_TYPES',
    'SCENE_NS',
    'collision_object_to_scene',
    'marker_ids',
    'scene_markers',
    'scene_to_collision_object',
]
