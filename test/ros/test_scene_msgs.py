"""geodesic_planner.ros.scene_msgs: CollisionObject <-> SceneObject, scene markers (messages only, no DDS)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('rclpy')

from geodesic_planner_interfaces.msg import CollisionObject
from geometry_msgs.msg import Point, Pose, Vector3
from numpy.testing import assert_allclose
from rclpy.serialization import deserialize_message, serialize_message
from shape_msgs.msg import Mesh, MeshTriangle, SolidPrimitive
from visualization_msgs.msg import Marker, MarkerArray

from geodesic_planner.core.collision import SceneObject, Shape
from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.transforms import make_transform, so3_exp
from geodesic_planner.ros import scene_msgs as sm
from geodesic_planner.ros.conversions import matrix_to_pose

pytestmark = pytest.mark.ros

STL = ('solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n'
       'endfacet\nendsolid t\n')
TETRA_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
TETRA_TRIANGLES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def _pose(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return make_transform(rng.uniform(-2, 2, 3), so3_exp(rng.uniform(-3, 3, 3)))


def _primitive_msg(type_: int, dims: list[float], oid: str = 'thing') -> CollisionObject:
    return CollisionObject(id=oid, pose=matrix_to_pose(_pose(1)),
                           primitive=SolidPrimitive(type=type_, dimensions=dims))


def _mesh_msg(vertices: np.ndarray = TETRA_VERTICES, triangles: np.ndarray = TETRA_TRIANGLES,
              scale: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> CollisionObject:
    mesh = Mesh(vertices=[Point(x=x, y=y, z=z) for x, y, z in vertices.tolist()],
                triangles=[MeshTriangle(vertex_indices=t) for t in triangles.tolist()])
    return CollisionObject(id='tetra', mesh=mesh, mesh_scale=Vector3(x=scale[0], y=scale[1], z=scale[2]))


@pytest.fixture
def mesh_file(tmp_path: Path) -> Path:
    path = tmp_path / 'cell' / 'meshes' / 'bin.stl'
    path.parent.mkdir(parents=True)
    path.write_text(STL)
    return path


# --------------------------------------------------------------------------- round trips


@pytest.mark.parametrize(('kind', 'dims'), [('box', (1.2, 0.8, 0.04)), ('sphere', (0.1,)),
                                            ('cylinder', (0.5, 0.05)), ('cone', (0.2, 0.1))])
@pytest.mark.parametrize('attached', [False, True])
def test_primitive_round_trip(kind: str, dims: tuple[float, ...], attached: bool) -> None:
    obj = SceneObject('thing', Shape(kind, dimensions=dims), _pose(2), attached=attached)
    msg = sm.scene_to_collision_object(obj)
    assert msg.primitive.type == {'box': SolidPrimitive.BOX, 'sphere': SolidPrimitive.SPHERE,
                                  'cylinder': SolidPrimitive.CYLINDER, 'cone': SolidPrimitive.CONE}[kind]
    assert tuple(msg.primitive.dimensions) == dims
    assert (msg.id, msg.attached, msg.mesh_resource, len(msg.mesh.triangles)) == ('thing', attached, '', 0)
    back = sm.collision_object_to_scene(deserialize_message(serialize_message(msg), CollisionObject))
    assert (back.id, back.shape.kind, back.shape.dimensions, back.attached) == ('thing', kind, dims, attached)
    assert_allclose(back.pose, obj.pose, atol=1e-12)


def test_mesh_file_by_path_file_uri_and_package_uri(mesh_file: Path) -> None:
    cell = mesh_file.parents[1]
    for ref, dirs in ((str(mesh_file), ()), (f'file://{mesh_file}', ()),
                      ('package://cell/meshes/bin.stl', (str(cell.parent),)),
                      ('package://cell/meshes/bin.stl', (str(cell),))):
        msg = CollisionObject(id='bin', mesh_resource=ref, mesh_scale=Vector3(x=2.0, y=0.0, z=0.5))
        obj = sm.collision_object_to_scene(msg, package_dirs=dirs)
        assert (obj.shape.kind, obj.shape.mesh) == ('mesh', str(mesh_file))
        assert tuple(obj.shape.scale) == (2.0, 1.0, 0.5)                 # a factor of 0 means 1
        back = sm.scene_to_collision_object(obj)
        assert back.mesh_resource == str(mesh_file)                      # the resolved path
        assert (back.mesh_scale.x, back.mesh_scale.y, back.mesh_scale.z) == (2.0, 1.0, 0.5)
        assert back.primitive.type == 0 and len(back.mesh.triangles) == 0


def test_mesh_resource_wins_over_mesh_and_mesh_over_primitive(mesh_file: Path) -> None:
    msg = _mesh_msg()
    msg.primitive = SolidPrimitive(type=SolidPrimitive.BOX, dimensions=[1.0, 1.0, 1.0])
    assert sm.collision_object_to_scene(msg).shape.kind == 'mesh'
    msg.mesh_resource = str(mesh_file)
    assert sm.collision_object_to_scene(msg).shape.mesh == str(mesh_file)
    msg.mesh_resource = ''
    msg.mesh = Mesh(vertices=msg.mesh.vertices)          # vertices without triangles: the primitive
    assert sm.collision_object_to_scene(msg).shape.kind == 'box'


def test_inline_mesh_round_trip_keeps_the_scale_once() -> None:
    obj = sm.collision_object_to_scene(_mesh_msg(scale=(2.0, 2.0, 3.0)))
    scaled = TETRA_VERTICES * [2.0, 2.0, 3.0]
    assert_allclose(obj.shape.vertices, scaled, atol=0)
    assert np.array_equal(obj.shape.triangles, TETRA_TRIANGLES)
    msg = sm.scene_to_collision_object(obj)
    assert_allclose([(p.x, p.y, p.z) for p in msg.mesh.vertices], scaled, atol=0)
    assert [list(t.vertex_indices) for t in msg.mesh.triangles] == TETRA_TRIANGLES.tolist()
    again = sm.collision_object_to_scene(deserialize_message(serialize_message(msg), CollisionObject))
    assert_allclose(again.shape.vertices, scaled, atol=0)                # not scaled twice


def test_capsule_has_no_message_form() -> None:
    obj = SceneObject('pill', Shape('capsule', dimensions=(0.3, 0.05)), np.eye(4))
    with pytest.raises(RequestError, match=r"^scene object 'pill': a capsule has no .*CollisionObject form"):
        sm.scene_to_collision_object(obj)


# --------------------------------------------------------------------------- refusals

def _nan_pose() -> CollisionObject:
    msg = _primitive_msg(SolidPrimitive.SPHERE, [0.1])
    msg.pose.position.y = float('nan')
    return msg


def _unnormalised() -> CollisionObject:
    msg = _primitive_msg(SolidPrimitive.SPHERE, [0.1])
    msg.pose = Pose()
    msg.pose.orientation.w = 0.9
    return msg


def _nan_vertex() -> CollisionObject:
    vertices = TETRA_VERTICES.copy()
    vertices[2, 1] = np.nan
    return _mesh_msg(vertices)


REFUSED = [
    ('empty id', lambda: _primitive_msg(SolidPrimitive.BOX, [1.0, 1.0, 1.0], oid=''),
     r'^collision object: empty id \(every object needs a unique, non-empty id\)$'),
    ('no shape', lambda: CollisionObject(id='thing'),
     r"^collision object 'thing': no shape: mesh_resource is empty, mesh has no triangles and "
     r'primitive.type is 0'),
    ('PRISM', lambda: _primitive_msg(SolidPrimitive.PRISM, [1.0]),
     r"^collision object 'thing': primitive.type PRISM \(5\) is not supported"),
    ('unknown type', lambda: _primitive_msg(9, [1.0]),
     r"^collision object 'thing': primitive.type 9 is unknown \(known: BOX 1, SPHERE 2, CYLINDER 3, CONE 4\)$"),
    ('box with 2 dimensions', lambda: _primitive_msg(SolidPrimitive.BOX, [1.0, 1.0]),
     r"^collision object 'thing': primitive.dimensions: a box needs 3 dimensions \(x, y, z; m\), got 2$"),
    ('sphere without dimensions', lambda: _primitive_msg(SolidPrimitive.SPHERE, []),
     r"^collision object 'thing': primitive.dimensions: a sphere needs 1 dimension \(radius; m\), got 0$"),
    ('cone with 3 dimensions', lambda: _primitive_msg(SolidPrimitive.CONE, [1.0, 1.0, 1.0]),
     r'primitive.dimensions: a cone needs 2 dimensions \(height, radius; m\), got 3$'),
    ('NaN dimension', lambda: _primitive_msg(SolidPrimitive.CYLINDER, [float('nan'), 0.1]),
     r"^collision object 'thing': primitive.dimensions: cylinder height must be finite and > 0 m, got nan$"),
    ('zero dimension', lambda: _primitive_msg(SolidPrimitive.SPHERE, [0.0]),
     r'primitive.dimensions: sphere radius must be finite and > 0 m, got 0.0$'),
    ('NaN position', _nan_pose, r"^collision object 'thing': pose: position contains NaN or inf"),
    ('unnormalised quaternion', _unnormalised,
     r"^collision object 'thing': pose.orientation: quaternion is not normalised \(norm 0.9, "),
    ('triangle index out of range', lambda: _mesh_msg(triangles=np.array([[0, 1, 2], [1, 2, 7], [4, 5, 6]])),
     r"^collision object 'tetra': mesh.triangles\[1\] refers to vertex 7, but the mesh has 4 vertices "
     r'\(2 such triangles\)$'),
    ('NaN vertex', _nan_vertex, r"^collision object 'tetra': mesh.vertices\[2\] contains NaN or inf"),
    ('negative mesh scale', lambda: _mesh_msg(scale=(1.0, -1.0, 1.0)),
     r"^collision object 'tetra': mesh_scale must be finite and >= 0 \(0 means 1\), got \[1.0, -1.0, 1.0\]$"),
    ('missing mesh file', lambda: CollisionObject(id='bin', mesh_resource='/nonexistent/bin.stl'),
     r"^collision object 'bin': mesh_resource: mesh file '/nonexistent/bin.stl' not found"),
    ('missing package', lambda: CollisionObject(id='bin', mesh_resource='package://no_such_pkg_xyz/bin.stl'),
     r"^collision object 'bin': mesh_resource: mesh file 'package://no_such_pkg_xyz/bin.stl' not found"),
    ('relative mesh path', lambda: CollisionObject(id='bin', mesh_resource='meshes/bin.stl'),
     r"^collision object 'bin': mesh_resource: 'meshes/bin.stl' is a relative path"),
]


@pytest.mark.parametrize(('make', 'message'), [c[1:] for c in REFUSED], ids=[c[0] for c in REFUSED])
def test_refusals_give_the_precise_reason(make: object, message: str) -> None:
    with pytest.raises(RequestError, match=message):
        sm.collision_object_to_scene(make())  # type: ignore[operator]


# --------------------------------------------------------------------------- markers


def _scene(mesh_file: Path) -> list[SceneObject]:
    return [
        SceneObject('table', Shape('box', dimensions=(1.2, 0.8, 0.04)), _pose(3)),
        SceneObject('ball', Shape('sphere', dimensions=(0.1,)), _pose(4)),
        SceneObject('post', Shape('cylinder', dimensions=(0.5, 0.05)), _pose(5)),
        SceneObject('cone', Shape('cone', dimensions=(0.2, 0.1)), _pose(6)),
        SceneObject('bin', Shape('mesh', mesh=str(mesh_file), scale=(2.0, 2.0, 1.0)), _pose(7)),
        SceneObject('tetra', Shape('mesh', vertices=TETRA_VERTICES, triangles=TETRA_TRIANGLES,
                                   scale=(0.5, 0.5, 0.5)), _pose(8)),
        SceneObject('gripper', Shape('cylinder', dimensions=(0.12, 0.04)), make_transform([0, 0, 0.06], np.eye(3)),
                    attached=True),
    ]


def _pose_matrix(marker: Marker) -> np.ndarray:
    from geodesic_planner.ros.conversions import pose_to_matrix
    return pose_to_matrix(marker.pose)


def test_one_marker_per_object_after_a_deleteall(mesh_file: Path) -> None:
    objects = _scene(mesh_file)
    T_gripper = _pose(9)
    array = sm.scene_markers(objects, {'gripper': T_gripper}, 'base_link')
    first, *markers = array.markers
    assert (first.action, first.ns, first.header.frame_id) == (Marker.DELETEALL, 'scene', 'base_link')
    assert len(markers) == len(objects)
    assert all(m.ns == 'scene' and m.action == Marker.ADD and m.header.frame_id == 'base_link' for m in markers)
    by_id = dict(zip([o.id for o in objects], markers))
    assert [by_id[k].type for k in ('table', 'ball', 'post', 'cone', 'bin', 'tetra', 'gripper')] == [
        Marker.CUBE, Marker.SPHERE, Marker.CYLINDER, Marker.TRIANGLE_LIST, Marker.MESH_RESOURCE,
        Marker.TRIANGLE_LIST, Marker.CYLINDER]
    scale = {k: (m.scale.x, m.scale.y, m.scale.z) for k, m in by_id.items()}
    assert scale['table'] == (1.2, 0.8, 0.04)
    assert scale['ball'] == (0.2, 0.2, 0.2)                               # diameters
    assert scale['post'] == (0.1, 0.1, 0.5)                               # diameter, height
    assert scale['bin'] == (2.0, 2.0, 1.0)
    assert by_id['bin'].mesh_resource == f'file://{mesh_file}'
    for obj in objects[:-1]:
        assert_allclose(_pose_matrix(by_id[obj.id]), obj.pose, atol=1e-12)
    assert_allclose(_pose_matrix(by_id['gripper']), T_gripper, atol=1e-12)   # attached: from body_poses
    # the vertex mesh: its triangles' corners, already scaled by Shape
    corners = np.array([(p.x, p.y, p.z) for p in by_id['tetra'].points])
    assert_allclose(corners, 0.5 * TETRA_VERTICES[TETRA_TRIANGLES.reshape(-1)], atol=0)
    assert scale['tetra'] == (1.0, 1.0, 1.0)
    # the cone: tip at +h/2, base disc at -h/2, radius 0.1, as shape_msgs/SolidPrimitive has it
    cone = np.array([(p.x, p.y, p.z) for p in by_id['cone'].points])
    assert len(cone) % 3 == 0 and len(cone) > 0
    assert cone[:, 2].max() == pytest.approx(0.1) and cone[:, 2].min() == pytest.approx(-0.1)
    assert np.hypot(cone[:, 0], cone[:, 1]).max() == pytest.approx(0.1)
    assert_allclose(cone[np.argmax(cone[:, 2]), :2], [0.0, 0.0], atol=0)
    serialize_message(array)                                   # a valid message (type support)


def test_marker_ids_are_stable_per_object_id(mesh_file: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    objects = _scene(mesh_file)
    ids = [m.id for m in sm.scene_markers(objects, None, 'base_link', tool_frame='tool0').markers[1:]]
    assert len(set(ids)) == len(objects)
    shuffled = objects[3:] + objects[:3]
    again = {m.id for m in sm.scene_markers(shuffled[1:], None, 'base_link', tool_frame='tool0').markers[1:]}
    assert again == set(ids) - {sm.marker_ids(['cone'])['cone']}           # one object fewer, the rest kept
    # a clash of two checksums goes to the next free number, the same way whatever the order
    monkeypatch.setattr(sm.zlib, 'crc32', lambda data: 41)
    assert sm.marker_ids(['b', 'a', 'c']) == {'a': 41, 'b': 42, 'c': 43} == sm.marker_ids(['c', 'a', 'b'])


def test_attached_object_without_a_body_pose(mesh_file: Path) -> None:
    gripper = _scene(mesh_file)[-1]
    # in the tool frame when it is named: RViz moves it with the tool
    (_, marker) = sm.scene_markers([gripper], {}, 'base_link', tool_frame='tool0').markers
    assert (marker.header.frame_id, marker.frame_locked) == ('tool0', True)
    assert_allclose(_pose_matrix(marker), gripper.pose, atol=1e-12)
    # otherwise left out (its pose in the tool frame would be drawn at a wrong place)
    assert len(sm.scene_markers([gripper], None, 'base_link').markers) == 1


def test_capsule_is_drawn_as_triangles() -> None:
    obj = SceneObject('pill', Shape('capsule', dimensions=(0.3, 0.05)), np.eye(4))
    (_, marker) = sm.scene_markers([obj], None, 'base_link').markers
    points = np.array([(p.x, p.y, p.z) for p in marker.points])
    assert marker.type == Marker.TRIANGLE_LIST and len(points) % 3 == 0
    assert points[:, 2].max() == pytest.approx(0.2) and points[:, 2].min() == pytest.approx(-0.2)
    assert np.hypot(points[:, 0], points[:, 1]).max() == pytest.approx(0.05)


def test_empty_scene_is_only_the_deleteall() -> None:
    array = sm.scene_markers([], None, 'base_link')
    assert isinstance(array, MarkerArray)
    assert [m.action for m in array.markers] == [Marker.DELETEALL]
