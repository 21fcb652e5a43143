"""Collision scenes from YAML files: the objects the planner keeps the robot away from.

    objects:
      - id: table                      # unique, not empty
        type: box                      # box | sphere | cylinder | cone (shape_msgs/SolidPrimitive)
        dimensions: [1.2, 0.8, 0.04]   # box x y z; sphere radius; cylinder, cone height radius (m)
        pose: {position: [0.5, 0.0, -0.03], orientation: [0, 0, 0, 1]}   # base frame; x y z w
      - id: bin
        mesh: meshes/bin.stl           # STL/DAE/OBJ: relative to the YAML file, absolute, file://
        scale: [1, 1, 1]               #   or package://PKG/...; scale optional (default 1, 1, 1)
        pose: {position: {x: 0.6, y: 0.3, z: 0.0}, orientation: {x: 0, y: 0, z: 0, w: 1}}
      - id: gripper
        type: cylinder
        dimensions: [0.12, 0.04]
        attached: true                 # pose in the tool frame: moves with the tool
        pose: {position: [0, 0, 0.06]}

``pose`` takes lists (position x y z in m, orientation x y z w) or the geometry_msgs/Pose mapping
form; a missing orientation is the identity, a missing position the origin, a missing pose both.
Shapes follow shape_msgs/SolidPrimitive: every shape is centred on its frame, cylinders and cones
along z (the cone's tip towards +z).

Every refusal is a :class:`~geodesic_planner.core.errors.RequestError` naming the object (index
and id) and the key.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from urllib.parse import unquote

import numpy as np

from ..core.collision import MAX_OBJECTS, SceneObject, Shape
from ..core.errors import RequestError, quoted
from ..core.transforms import pose_from_mapping, pose_to_transform
from .requests import read_yaml

#: Most objects one scene file may hold: as many as a collision model takes.
MAX_SCENE_OBJECTS = MAX_OBJECTS
#: Primitive kinds of shape_msgs/SolidPrimitive -> the names of their dimensions, in order (m).
PRIMITIVE_DIMENSIONS: dict[str, tuple[str, ...]] = {
    'box': ('x', 'y', 'z'),
    'sphere': ('radius',),
    'cylinder': ('height', 'radius'),
    'cone': ('height', 'radius'),
}
#: Mesh file formats (suffix, lower case).
MESH_SUFFIXES = ('.stl', '.dae', '.obj')
OBJECT_KEYS = frozenset({'id', 'type', 'dimensions', 'mesh', 'scale', 'pose', 'attached'})
POSE_KEYS = frozenset({'position', 'orientation'})


def check_dimensions(kind: str, dimensions: Sequence[float], what: str) -> tuple[float, ...]:
    """Dimensions of a primitive, validated: the count its kind needs, each finite and > 0 (m).

    Args:
        kind: 'box', 'sphere', 'cylinder' or 'cone'.
        dimensions: box (x, y, z), sphere (radius,), cylinder and cone (height, radius); m.
        what: how the message names the dimensions (e.g. ``scene: objects[0] ('table'): dimensions``).
    Raises:
        RequestError: unknown kind, wrong count, NaN/inf or a value <= 0.
    """
    if kind not in PRIMITIVE_DIMENSIONS:
        raise RequestError(f'{what}: unknown primitive type {quoted(kind)} '
                           f'(known: {", ".join(PRIMITIVE_DIMENSIONS)})')
    names = PRIMITIVE_DIMENSIONS[kind]
    dims = tuple(float(d) for d in dimensions)
    if len(dims) != len(names):
        raise RequestError(f'{what}: a {kind} needs {len(names)} dimension{"s" * (len(names) > 1)} '
                           f'({", ".join(names)}; m), got {len(dims)}')
    for name, d in zip(names, dims):
        if not math.isfinite(d) or d <= 0.0:
            raise RequestError(f'{what}: {kind} {name} must be finite and > 0 m, got {d!r}')
    return dims


def check_scale(scale: Sequence[float], what: str) -> tuple[float, float, float]:
    """A mesh's scale along x, y, z: three finite numbers > 0.

    Raises:
        RequestError: wrong count, NaN/inf or a value <= 0.
    """
    values = tuple(float(v) for v in scale)
    if len(values) != 3:
        raise RequestError(f'{what}: needs 3 numbers (x, y, z), got {len(values)}')
    if not all(math.isfinite(v) and v > 0.0 for v in values):
        raise RequestError(f'{what}: every factor must be finite and > 0, got {list(values)}')
    return values[0], values[1], values[2]


def resolve_mesh(ref: str, what: str, *, base_dir: str | None = None,
                 package_dirs: Sequence[str] = ()) -> str:
    """Absolute path of a mesh file named by a path, a ``file://`` URI or a ``package://`` URI.

    ``package://PKG/rel`` is looked up as ``DIR/PKG/rel`` (or ``DIR/rel`` when DIR itself is named
    PKG) for each DIR of ``package_dirs`` in order, then in PKG's share directory of the ament
    index when ``ament_index_python`` is installed.

    Args:
        ref: the reference as written.
        what: how the message names it (e.g. ``collision object 'bin': mesh_resource``).
        base_dir: directory a relative path is relative to; None: relative paths are refused.
        package_dirs: directories that hold packages (or are a package's directory).
    Returns:
        The absolute path of an existing STL, DAE or OBJ file.
    Raises:
        RequestError: empty, relative without base_dir, another URI scheme, another suffix, or no
            such file (the message lists where it looked).
    """
    if not ref:
        raise RequestError(f'{what}: empty mesh reference')
    if ref.startswith('package://'):
        rest = ref[len('package://'):]
        package, _, rel = rest.partition('/')
        if not package or not rel:
            raise RequestError(f'{what}: {quoted(ref)} is not package://PACKAGE/PATH')
        candidates = []
        for d in package_dirs:
            candidates.append(os.path.join(d, package, rel))
            if os.path.basename(os.path.normpath(d)) == package:
                candidates.append(os.path.join(d, rel))
        share = _ament_share_directory(package)
        if share is not None:
            candidates.append(os.path.join(share, rel))
    elif '://' in ref and not ref.startswith('file://'):
        raise RequestError(f'{what}: {quoted(ref)}: only file paths, file:// and package:// URIs are '
                           f'supported')
    else:
        path = unquote(ref[len('file://'):]) if ref.startswith('file://') else ref
        if path.startswith('localhost/'):
            path = path[len('localhost'):]
        if not os.path.isabs(path):
            if base_dir is None:
                raise RequestError(f'{what}: {quoted(ref)} is a relative path; give an absolute path, '
                                   f'a file:// or a package:// URI')
            path = os.path.join(base_dir, path)
        candidates = [path]
    suffix = os.path.splitext(ref)[1].lower()
    if suffix not in MESH_SUFFIXES:
        raise RequestError(f'{what}: {quoted(ref)} is not a mesh file this planner reads '
                           f'(STL, DAE or OBJ)')
    for c in candidates:
        if os.path.isfile(c):
            return os.path.abspath(c)
    if not candidates:
        raise RequestError(f'{what}: mesh file {quoted(ref)} not found (no package directory given, and '
                           f'the package is not in the ament index)')
    looked = ', '.join(quoted(c, 120) for c in candidates[:5])
    more = f' and {len(candidates) - 5} more' if len(candidates) > 5 else ''
    raise RequestError(f'{what}: mesh file {quoted(ref)} not found (looked at {looked}{more})')


def _ament_share_directory(package: str) -> str | None:
    """PKG's share directory from the ament index, or None (no index, unknown package)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:
        return None
    try:
        return str(get_package_share_directory(package))
    except (PackageNotFoundError, ValueError, LookupError, OSError):
        return None


def _numbers(value: object, what: str) -> list[float]:
    """A YAML list of numbers (not booleans) as floats."""
    if not isinstance(value, (list, tuple)) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise RequestError(f'{what}: expected a list of numbers, got {quoted(value)}')
    return [float(v) for v in value]


def parse_pose(value: object, what: str) -> np.ndarray:
    """4x4 transform of a scene pose: lists (``position: [x, y, z]``, ``orientation: [x, y, z, w]``)
    or the geometry_msgs/Pose mapping form; each part may be either. Missing orientation: identity;
    missing position: origin.

    Raises:
        RequestError: unknown keys, wrong counts, NaN/inf, an unnormalised quaternion.
    """
    if value is None:
        return np.eye(4)
    if not isinstance(value, Mapping):
        raise RequestError(f'{what}: expected a mapping with position and orientation, got {quoted(value)}')
    unknown = sorted(str(k) for k in value if k not in POSE_KEYS)
    if unknown:
        raise RequestError(f'{what}: unknown keys {unknown} (known: orientation, position)')
    pos, ori = value.get('position'), value.get('orientation')
    if (pos is None or isinstance(pos, Mapping)) and (ori is None or isinstance(ori, Mapping)):
        for key, part, fields in (('position', pos, 'xyz'), ('orientation', ori, 'xyzw')):
            extra = sorted(str(k) for k in (part or {}) if k not in fields)
            if extra:
                raise RequestError(f'{what}.{key}: unknown keys {extra} (known: {", ".join(fields)})')
        return pose_from_mapping(value, what)    # the geometry_msgs/Pose form, as requests read it
    p = [0.0, 0.0, 0.0] if pos is None else _pose_part(pos, 'xyz', f'{what}.position')
    q = [0.0, 0.0, 0.0, 1.0] if ori is None else _pose_part(ori, 'xyzw', f'{what}.orientation')
    return pose_to_transform(p, q, what)


def _pose_part(part: object, fields: str, what: str) -> list[float]:
    if isinstance(part, Mapping):
        extra = sorted(str(k) for k in part if k not in fields)
        if extra:
            raise RequestError(f'{what}: unknown keys {extra} (known: {", ".join(fields)})')
        try:
            return [float(part.get(k, 0.0)) for k in fields]
        except (TypeError, ValueError) as err:
            raise RequestError(f'{what}: non-numeric value ({err})') from err
    values = _numbers(part, what)
    if len(values) != len(fields):
        raise RequestError(f'{what}: needs {len(fields)} numbers ({", ".join(fields)}), got {len(values)}')
    return values


def parse_object(entry: object, index: int, base_dir: str = '.', *,
                 package_dirs: Sequence[str] = ()) -> SceneObject:
    """One object of a scene file (see the module docstring).

    Raises:
        RequestError: naming ``objects[index]`` and the id, and the key at fault.
    """
    where = f'scene: objects[{index}]'
    if not isinstance(entry, Mapping):
        raise RequestError(f'{where}: expected a mapping (id, type or mesh, ...), got {quoted(entry)}')
    oid = entry.get('id')
    if not isinstance(oid, str) or not oid:
        raise RequestError(f'{where}: id: every object needs a non-empty string id, got {quoted(oid)}')
    where = f'{where} ({quoted(oid)})'
    unknown = sorted(str(k) for k in entry if k not in OBJECT_KEYS)
    if unknown:
        raise RequestError(f'{where}: unknown keys {unknown} (known: {", ".join(sorted(OBJECT_KEYS))})')
    attached = entry.get('attached', False)
    if not isinstance(attached, bool):
        raise RequestError(f'{where}: attached: expected true or false, got {quoted(attached)}')
    pose = parse_pose(entry.get('pose'), f'{where}: pose')
    kind = entry.get('type')
    if 'mesh' in entry:
        if kind not in (None, 'mesh'):
            raise RequestError(f'{where}: type: {quoted(kind)} with a mesh (give one of type and mesh)')
        if 'dimensions' in entry:
            raise RequestError(f'{where}: dimensions: not used with a mesh (use scale)')
        ref = entry['mesh']
        if not isinstance(ref, str):
            raise RequestError(f'{where}: mesh: expected a path or URI, got {quoted(ref)}')
        path = resolve_mesh(ref, f'{where}: mesh', base_dir=base_dir, package_dirs=package_dirs)
        scale = (1.0, 1.0, 1.0) if entry.get('scale') is None else check_scale(
            _numbers(entry['scale'], f'{where}: scale'), f'{where}: scale')
        shape = _shape(where, lambda: Shape('mesh', mesh=path, scale=scale))
    else:
        if kind is None:
            raise RequestError(f'{where}: type: missing (box, sphere, cylinder, cone), or give a mesh')
        if not isinstance(kind, str) or kind not in PRIMITIVE_DIMENSIONS:
            raise RequestError(f'{where}: type: unknown type {quoted(kind)} '
                               f'(known: {", ".join(PRIMITIVE_DIMENSIONS)}, or a mesh)')
        if 'scale' in entry:
            raise RequestError(f'{where}: scale: only used with a mesh (a {kind} has dimensions)')
        if 'dimensions' not in entry:
            raise RequestError(f'{where}: dimensions: missing ({", ".join(PRIMITIVE_DIMENSIONS[kind])}; m)')
        dims = check_dimensions(kind, _numbers(entry['dimensions'], f'{where}: dimensions'),
                                f'{where}: dimensions')
        shape = _shape(where, lambda: Shape(kind, dimensions=dims))
    return SceneObject(oid, shape, pose, attached=attached)


def _shape(where: str, make: Callable[[], Shape]) -> Shape:
    """``make()``, with the Shape's own refusal (if any) prefixed with the object."""
    try:
        return make()
    except RequestError as err:
        raise RequestError(f'{where}: {err}') from err


def parse_scene(data: object, base_dir: str = '.', *,
                package_dirs: Sequence[str] = ()) -> list[SceneObject]:
    """The objects of a decoded scene file (a mapping with the list ``objects``).

    Args:
        data: the YAML document, decoded.
        base_dir: directory relative mesh paths are relative to (the YAML file's).
        package_dirs: directories searched for ``package://PKG/...`` meshes before the ament index.
    Returns:
        The objects, in the file's order; poses 4x4 (base frame, or tool frame when attached).
    Raises:
        RequestError: not a mapping, unknown top-level keys, more than MAX_SCENE_OBJECTS objects,
            duplicate ids, or any object's refusal (see :func:`parse_object`).
    """
    if not isinstance(data, Mapping):
        raise RequestError(f'scene: expected a mapping with the list "objects" at the top level, '
                           f'got {quoted(data)}')
    unknown = sorted(str(k) for k in data if k != 'objects')
    if unknown:
        raise RequestError(f'scene: unknown keys {unknown} (known: objects)')
    entries = data.get('objects')
    if entries is None:
        raise RequestError('scene: objects: missing (a list of objects; [] for none)')
    if not isinstance(entries, list):
        raise RequestError(f'scene: objects: expected a list, got {quoted(entries)}')
    if len(entries) > MAX_SCENE_OBJECTS:
        raise RequestError(f'scene: objects: {len(entries)} objects, at most {MAX_SCENE_OBJECTS}')
    objects: list[SceneObject] = []
    first: dict[str, int] = {}
    for i, entry in enumerate(entries):
        obj = parse_object(entry, i, base_dir, package_dirs=package_dirs)
        if obj.id in first:
            raise RequestError(f'scene: objects[{i}]: id: {quoted(obj.id)} is already the id of '
                               f'objects[{first[obj.id]}] (ids must be unique)')
        first[obj.id] = i
        objects.append(obj)
    return objects


def load_scene(path: str, *, package_dirs: Sequence[str] = ()) -> list[SceneObject]:
    """Read and parse a YAML scene file; relative mesh paths are relative to its directory.

    Raises:
        RequestError: unreadable file, malformed YAML, or an invalid scene (see :func:`parse_scene`).
    """
    data = read_yaml(path, f'scene {quoted(path)}', f'scene {quoted(path)}')
    return parse_scene(data, os.path.dirname(os.path.abspath(path)), package_dirs=package_dirs)


__all__ = [
    'MAX_SCENE_OBJECTS',
    'MESH_SUFFIXES',
    'PRIMITIVE_DIMENSIONS',
    'check_dimensions',
    'check_scale',
    'load_scene',
    'parse_object',
    'parse_pose',
    'parse_scene',
    'resolve_mesh',
]
