"""Collision bodies: the shapes of the robot's links and of the cell, as coal geometries.

A body is a shape rigidly attached to one segment of the chain (see
:meth:`.kinematics.Chain.segment_frames`): segment 0 is the base (scene objects live there, at
their pose in the base frame), segment k moves with joint k, segment ``dof`` carries the tool and
the objects attached to it.

The robot's bodies come from the URDF's ``<collision>`` elements, read by urdfdom through
pinocchio (boxes, cylinders, spheres, meshes: STL, DAE, OBJ through assimp; ``package://`` looked up
in ``package_dirs``). A model without them (the DH presets) gets a capsule along each segment, from
its joint to the next, of radius ``link_radius``. Meshes are checked through their convex hulls
(coal's qhull): a hull holds its mesh, so its distances are lower bounds of the mesh's, and they
cost about 1/100 of an exact mesh query. ``exact_meshes`` keeps the triangles.

The collision library is coal (the successor of FCL, pinocchio's); every distance is its GJK/EPA.
"""
from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import coal
import numpy as np

from .errors import KinematicsError, RequestError, quoted
from .kinematics import Chain, rotation_z_to
from .urdf_xml import UrdfModel, read_urdf

#: Solid primitives and their dimensions, in shape_msgs/SolidPrimitive's order and meaning.
PRIMITIVES: dict[str, tuple[str, ...]] = {
    'box': ('x', 'y', 'z'),
    'sphere': ('radius',),
    'cylinder': ('height', 'radius'),
    'cone': ('height', 'radius'),
    'capsule': ('length', 'radius'),
}
#: Largest SRDF accepted, characters.
MAX_SRDF_BYTES = 10_000_000
#: Largest mesh accepted, vertices (real collision meshes have a few thousand).
MAX_MESH_VERTICES = 1_000_000
#: Largest occupancy octree accepted, occupied voxels (a 2 cm map of a 2 m cube has 1,000,000).
MAX_OCTREE_VOXELS = 2_000_000
#: An octree is checked as tiles of at most this many voxels along each axis, each a coal octree
#: with a bounding sphere of its own: the check measures exactly only the tiles near a link (coal's
#: distance to one octree of a whole table costs about 0.3 ms whatever the distance).
OCTREE_TILE = 8
#: Most tiles of one octree (larger tiles beyond it: the model's pairs grow with the tiles).
MAX_OCTREE_TILES = 256


@dataclass(frozen=True, eq=False)
class Shape:
    """A solid in its own frame (m): a primitive, a mesh (a file or vertices + triangles), or an
    occupancy octree (the cells a point cloud occupies: :mod:`.point_cloud`).

    Attributes:
        kind: ``'box'`` (x, y, z edge lengths, centred), ``'sphere'`` (radius), ``'cylinder'`` and
            ``'cone'`` (height, radius; along z, centred: shape_msgs/SolidPrimitive), ``'capsule'``
            (length of the axis segment along z, radius), ``'mesh'``, ``'octree'`` (dimensions:
            the voxel side; vertices: the occupied voxels' centres).
        dimensions: the primitive's dimensions, m.
        mesh: a mesh file (STL, DAE, OBJ), a resolved path.
        vertices, triangles: a mesh given inline, (V, 3) m and (T, 3) vertex indices; an
            octree's voxel centres (K, 3), m (on the grid of the voxel side: k + 1/2 sides).
        scale: mesh scale per axis.
        octree: an octree's coal geometries, built once by the shape (empty for other kinds):
            one ``coal.makeOctree`` per tile of :data:`OCTREE_TILE` voxels along each axis, with
            the tile's bounding sphere (centre (3,), radius), in the shape's frame.
    Raises:
        RequestError: an unknown kind, wrong or non-positive dimensions, a bad mesh.
    """

    kind: str
    dimensions: tuple[float, ...] = ()
    mesh: str | None = None
    vertices: np.ndarray | None = field(default=None, repr=False)
    triangles: np.ndarray | None = field(default=None, repr=False)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    octree: tuple[tuple[Any, np.ndarray, float], ...] = field(default=(), repr=False)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Shape):
            return NotImplemented
        arrays = all(np.array_equal(a, b) if a is not None and b is not None else a is b
                     for a, b in ((self.vertices, other.vertices), (self.triangles, other.triangles)))
        return (self.kind, self.dimensions, self.mesh, self.scale) == \
            (other.kind, other.dimensions, other.mesh, other.scale) and arrays

    __hash__ = None  # type: ignore[assignment]  # mutable arrays inside

    def __post_init__(self) -> None:
        if self.kind == 'mesh':
            _check_mesh(self)
            return
        if self.kind == 'octree':
            _build_octree(self)
            return
        names = PRIMITIVES.get(self.kind)
        if names is None:
            raise RequestError(f'shape: unknown type {quoted(self.kind)} (known: '
                               f'{", ".join([*PRIMITIVES, "mesh"])})')
        dims = tuple(float(d) for d in self.dimensions)
        if len(dims) != len(names):
            raise RequestError(f'{self.kind}: needs {len(names)} dimensions ({", ".join(names)}), got {len(dims)}')
        for n, d in zip(names, dims):
            if not (math.isfinite(d) and d > 0.0):
                raise RequestError(f'{self.kind}: {n} must be finite and > 0 m, got {d!r}')
        object.__setattr__(self, 'dimensions', dims)


def _build_octree(shape: Shape) -> None:
    """Check an octree's resolution and voxel centres, and build its coal geometry."""
    dims = tuple(float(d) for d in shape.dimensions)
    if len(dims) != 1 or not (math.isfinite(dims[0]) and dims[0] > 0.0):
        raise RequestError(f'octree: needs 1 dimension (the voxel side, finite and > 0 m), got {shape.dimensions!r}')
    v = np.asarray(shape.vertices if shape.vertices is not None else np.zeros((0, 3)), dtype=float)
    if v.ndim != 2 or v.shape[1] != 3 or not 1 <= len(v) <= MAX_OCTREE_VOXELS or not np.all(np.isfinite(v)):
        raise RequestError(f'octree: voxel centres must be 1 to {MAX_OCTREE_VOXELS} finite points (K, 3), got '
                           f'shape {v.shape}')
    object.__setattr__(shape, 'dimensions', dims)
    object.__setattr__(shape, 'vertices', v)
    res, side = dims[0], OCTREE_TILE
    cell = np.floor(v * (1.0 / res)).astype(np.int64)
    cell -= cell.min(axis=0)
    while True:     # tiles twice as large until there are at most MAX_OCTREE_TILES
        t = cell // side
        key = (t[:, 0] * (int(t[:, 1].max()) + 1) + t[:, 1]) * (int(t[:, 2].max()) + 1) + t[:, 2]
        order = np.argsort(key, kind='stable')
        starts = np.flatnonzero(np.r_[True, key[order][1:] != key[order][:-1]])
        if len(starts) <= MAX_OCTREE_TILES:
            break
        side *= 2
    c = v[order]                                      # the tiles' voxels one after the other
    lo, hi = np.minimum.reduceat(c, starts) - 0.5 * res, np.maximum.reduceat(c, starts) + 0.5 * res
    mid, radius = 0.5 * (lo + hi), (0.5 * np.linalg.norm(hi - lo, axis=1)).tolist()
    ends = [*starts[1:].tolist(), len(c)]
    object.__setattr__(shape, 'octree', tuple((coal.makeOctree(c[a:b], res), mid[k], radius[k])
                                              for k, (a, b) in enumerate(zip(starts.tolist(), ends))))


def _check_mesh(shape: Shape) -> None:
    scale = tuple(float(s) for s in shape.scale)
    if len(scale) != 3 or not all(math.isfinite(s) and s > 0.0 for s in scale):
        raise RequestError(f'mesh: scale must be 3 finite numbers > 0, got {shape.scale!r}')
    object.__setattr__(shape, 'scale', scale)
    if shape.mesh is not None:
        if not os.path.isfile(shape.mesh):
            raise RequestError(f'mesh: file {quoted(shape.mesh)} not found')
        return
    if shape.vertices is None or shape.triangles is None:
        raise RequestError('mesh: give a file or vertices and triangles')
    v = np.asarray(shape.vertices, dtype=float)
    t = np.asarray(shape.triangles)
    if v.ndim != 2 or v.shape[1] != 3 or not 4 <= len(v) <= MAX_MESH_VERTICES or not np.all(np.isfinite(v)):
        raise RequestError(f'mesh: vertices must be 4 to {MAX_MESH_VERTICES} finite points (V, 3), got '
                           f'shape {v.shape}')
    if t.ndim != 2 or t.shape[1] != 3 or len(t) == 0 or not np.issubdtype(t.dtype, np.integer):
        raise RequestError(f'mesh: triangles must be integer vertex indices (T, 3), got shape {t.shape}')
    if t.min() < 0 or t.max() >= len(v):
        raise RequestError(f'mesh: a triangle refers to vertex {int(t.max() if t.max() >= len(v) else t.min())}, '
                           f'outside 0..{len(v) - 1}')
    object.__setattr__(shape, 'vertices', v * np.asarray(scale))
    object.__setattr__(shape, 'triangles', t.astype(np.int64))


@dataclass(frozen=True, eq=False)
class SceneObject:
    """An object of the cell.

    Attributes:
        id: unique name.
        shape: its solid.
        pose: 4x4, the shape's frame in the robot's base frame; when ``attached``, in the tool
            frame (the chain's tip link), and the object moves with the tool.
        attached: carried by the tool (a gripper, a part).
    """

    id: str
    shape: Shape
    pose: np.ndarray = field(default_factory=lambda: np.eye(4), repr=False)
    attached: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id:
            raise RequestError('scene object: id must be a non-empty string')
        pose = np.asarray(self.pose, dtype=float)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise RequestError(f'scene object {quoted(self.id)}: pose must be a finite 4x4 transform')
        object.__setattr__(self, 'pose', pose)


@dataclass(frozen=True, eq=False)
class Body:
    """One collision body: a coal geometry fixed to a segment of the chain.

    Attributes:
        name: the link's name (robot) or the object's id.
        segment: 0 (base) .. dof (tool), see :meth:`Chain.segment_frames`.
        offset: 4x4, segment frame -> the geometry's frame.
        geometry: the coal geometry.
        center, radius: a sphere holding the body, centre in the segment frame (m) and radius (m).
        kind: ``'link'``, ``'object'`` (scene, on the base) or ``'attached'`` (on the tool).
        shape: the solid, for drawing (None for URDF geometry).
    """

    name: str
    segment: int
    offset: np.ndarray = field(repr=False)
    geometry: Any = field(repr=False)
    center: np.ndarray = field(repr=False)
    radius: float
    kind: str = 'link'
    shape: Shape | None = field(default=None, repr=False)


def geometry_of(shape: Shape, *, exact_meshes: bool = False) -> tuple[Any, np.ndarray, float]:
    """The coal geometry of a shape, and a bounding sphere (centre (3,), radius) in its frame, m."""
    d = shape.dimensions
    if shape.kind == 'box':
        return coal.Box(*d), np.zeros(3), 0.5 * math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    if shape.kind == 'sphere':
        return coal.Sphere(d[0]), np.zeros(3), d[0]
    if shape.kind == 'cylinder':
        return coal.Cylinder(d[1], d[0]), np.zeros(3), math.hypot(0.5 * d[0], d[1])
    if shape.kind == 'cone':
        return coal.Cone(d[1], d[0]), np.zeros(3), math.hypot(0.5 * d[0], d[1])
    if shape.kind == 'capsule':
        return coal.Capsule(d[1], d[0]), np.zeros(3), 0.5 * d[0] + d[1]
    if shape.mesh is not None:
        try:
            bvh = coal.MeshLoader().load(shape.mesh, np.asarray(shape.scale))
        except Exception as err:
            raise RequestError(f'mesh {quoted(shape.mesh)} cannot be read: {err}') from err
    else:
        assert shape.vertices is not None and shape.triangles is not None  # checked by Shape
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(shape.triangles), len(shape.vertices))
        bvh.addVertices(shape.vertices)
        bvh.addTriangles(shape.triangles)
        bvh.endModel()
    return _mesh_geometry(bvh, exact_meshes, shape.mesh or 'inline mesh')


def _mesh_geometry(bvh: Any,  # noqa: ANN401 - a coal BVH model
                    exact: bool, what: str) -> tuple[Any, np.ndarray, float]:
    """A mesh as coal checks it (its convex hull unless ``exact``) and its vertices' bounding sphere."""
    v = np.asarray(bvh.vertices(), dtype=float)
    if len(v) == 0:
        raise RequestError(f'mesh {quoted(what)} has no vertices')
    center = 0.5 * (v.min(axis=0) + v.max(axis=0))
    radius = float(np.linalg.norm(v - center, axis=1).max())
    if exact:
        return bvh, center, radius
    try:
        bvh.buildConvexHull(True, 'Qt')
        return bvh.convex, center, radius
    except Exception:  # noqa: BLE001 - a flat mesh has no hull: keep its triangles
        return bvh, center, radius


def object_body(obj: SceneObject, robot: Chain, *, exact_meshes: bool = False) -> Body:
    """The body of a scene object: on the base at its pose, or on the tool segment when attached."""
    geometry, c, r = geometry_of(obj.shape, exact_meshes=exact_meshes)
    if obj.attached:
        offset = robot.tool_offset() @ obj.pose
        return Body(obj.id, robot.dof, offset, geometry, offset[:3, :3] @ c + offset[:3, 3], r, 'attached', obj.shape)
    return Body(obj.id, 0, obj.pose, geometry, obj.pose[:3, :3] @ c + obj.pose[:3, 3], r, 'object', obj.shape)


def object_bodies(obj: SceneObject, robot: Chain, *, exact_meshes: bool = False) -> list[Body]:
    """The bodies of a scene object: :func:`object_body`, or one body per tile of an octree (all
    named after the object; the tiles' coal geometries are the shape's, shared by every model)."""
    if obj.shape.kind != 'octree':
        return [object_body(obj, robot, exact_meshes=exact_meshes)]
    segment, offset = (robot.dof, robot.tool_offset() @ obj.pose) if obj.attached else (0, obj.pose)
    kind = 'attached' if obj.attached else 'object'
    return [Body(obj.id, segment, offset, tree, offset[:3, :3] @ c + offset[:3, 3], r, kind, obj.shape)
            for tree, c, r in obj.shape.octree]


def capsule_bodies(robot: Chain, link_radius: float) -> list[Body]:
    """A capsule (or, where a segment has no length, a sphere) along every segment of the chain,
    from its joint to the next joint (the tool for the last), named ``link_0`` (the base) .. ``link_<dof>``."""
    bodies = []
    ends = robot.segment_ends()
    for k, p in enumerate(ends):
        length = float(np.linalg.norm(p))
        offset = np.eye(4)
        offset[:3, 3] = 0.5 * p
        if length < 1e-9:
            shape = Shape('sphere', (link_radius,))
        else:
            shape = Shape('capsule', (length, link_radius))
            offset[:3, :3] = rotation_z_to(p / length)
        geometry, _, r = geometry_of(shape)
        bodies.append(Body(f'link_{k}', k, offset, geometry, offset[:3, 3].copy(), r, 'link', shape))
    return bodies


def urdf_bodies(robot: Chain, urdf: str, *, package_dirs: Sequence[str] = (),
                exact_meshes: bool = False) -> list[Body]:
    """The bodies of the URDF's ``<collision>`` elements, each on the segment that moves its link.

    Links off the chain (gripper fingers) are taken at their joints' zero; links above the
    chain's base, or beside it, are fixed to the base.

    Raises:
        KinematicsError: urdfdom refuses the document, or a mesh cannot be found or read.
    """
    import pinocchio as pin   # loaded only for URDF geometry (about 0.3 s)

    try:
        model = pin.buildModelFromXML(urdf)
        geom = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.COLLISION,
                                           package_dirs=[str(d) for d in package_dirs])
    except (ValueError, RuntimeError) as err:
        raise KinematicsError(f'URDF collision geometry: {err} (package_dirs: {list(package_dirs)})') from err
    data = model.createData()
    gdata = pin.GeometryData(geom)
    q0 = pin.neutral(model)
    pin.forwardKinematics(model, data, q0)
    pin.updateFramePlacements(model, data)
    pin.updateGeometryPlacements(model, data, geom, gdata, q0)
    doc = read_urdf(urdf)
    segment_of = _segments(doc, robot)
    if not model.existFrame(robot.base_link):
        raise KinematicsError(f'URDF collision geometry: no link {quoted(robot.base_link)}')
    world_base = np.linalg.inv(data.oMf[model.getFrameId(robot.base_link)].homogeneous)
    S0 = robot.segment_frames(np.zeros((1, robot.dof)))[0]
    bodies = []
    for i, go in enumerate(geom.geometryObjects):
        link = model.frames[go.parentFrame].name
        k = segment_of.get(link, 0)
        offset = np.linalg.inv(S0[k]) @ world_base @ gdata.oMg[i].homogeneous
        g = go.geometry
        if isinstance(g, coal.BVHModelBase):
            g, c, r = _mesh_geometry(g, exact_meshes, go.meshPath)
        else:
            g.computeLocalAABB()
            c, r = np.asarray(g.aabb_center, dtype=float), float(g.aabb_radius)
        bodies.append(Body(link, k, offset, g, offset[:3, :3] @ c + offset[:3, 3], r, 'link'))
    return bodies


def _segments(doc: UrdfModel, robot: Chain) -> dict[str, int]:
    """Link name -> the segment that moves it (0: fixed to the base)."""
    actuated = []
    link = robot.tip_link
    while link != robot.base_link and link in doc.parent_joint:
        j = doc.parent_joint[link]
        if j.type in ('revolute', 'continuous', 'prismatic') and (j.mimic is None or j.mimic[1] != 0.0):
            actuated.append(j.name)
        link = j.parent
    actuated.reverse()
    if len(actuated) != robot.dof:
        raise KinematicsError(f'URDF collision geometry: the chain from {quoted(robot.base_link)} to '
                              f'{quoted(robot.tip_link)} has {len(actuated)} joints, the model {robot.dof}')
    index = {name: k + 1 for k, name in enumerate(actuated)}
    out = {}
    for name in doc.links:
        link, k = name, 0
        while link in doc.parent_joint and link != robot.base_link:
            j = doc.parent_joint[link]
            if j.name in index:
                k = index[j.name]
                break
            link = j.parent
        out[name] = k
    return out


def srdf_disabled(srdf: str) -> dict[tuple[str, str], str]:
    """The ``<disable_collisions link1 link2 reason>`` pairs of an SRDF document (MoveIt's).

    Returns:
        sorted link-name pair -> reason (``'SRDF'`` plus the file's reason when it gives one).
    Raises:
        RequestError: the text is not XML with a ``robot`` root.
    """
    if len(srdf) > MAX_SRDF_BYTES:
        raise RequestError(f'SRDF: {len(srdf)} characters, at most {MAX_SRDF_BYTES}')
    if '<!DOCTYPE' in srdf or '<!ENTITY' in srdf:
        raise RequestError('SRDF: a DOCTYPE or entity declaration is not accepted')
    try:
        root = ET.fromstring(srdf)
    except ET.ParseError as err:
        raise RequestError(f'SRDF: not XML ({err})') from err
    if root.tag != 'robot':
        raise RequestError(f'SRDF: the root element is {quoted(root.tag)}, expected "robot"')
    out = {}
    for el in root.iter('disable_collisions'):
        a, b = el.get('link1'), el.get('link2')
        if not a or not b:
            raise RequestError('SRDF: <disable_collisions> needs link1 and link2')
        reason = el.get('reason')
        out[pair_key(a, b)] = f'SRDF ({reason})' if reason else 'SRDF'
    return out


def pair_key(a: str, b: str) -> tuple[str, str]:
    """The sorted name pair (a pair's key in ``pairs`` and ``skipped``)."""
    return (a, b) if a <= b else (b, a)
