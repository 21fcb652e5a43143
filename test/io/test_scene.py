"""Scene files (geodesic_planner.io.scene): what is read, and every refusal with its message."""
from __future__ import annotations

import copy
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.transforms import make_transform, quat_to_matrix
from geodesic_planner.io.scene import MAX_SCENE_OBJECTS, load_scene, parse_scene, resolve_mesh

ROOT = Path(__file__).resolve().parents[2]
#: A tetrahedron as an ASCII STL (the mesh files only need to exist for the scene reader).
STL = ('solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n'
       'endfacet\nendsolid t\n')


def _yaw(deg: float) -> list[float]:
    h = np.radians(deg) / 2.0
    return [0.0, 0.0, float(np.sin(h)), float(np.cos(h))]


def _scene(*objects: dict[str, Any]) -> dict[str, Any]:
    return {'objects': list(objects)}


BOX = {'id': 'table', 'type': 'box', 'dimensions': [1.2, 0.8, 0.04],
       'pose': {'position': [0.5, 0.0, -0.03], 'orientation': [0, 0, 0, 1]}}


@pytest.fixture
def mesh_dir(tmp_path: Path) -> Path:
    (tmp_path / 'meshes').mkdir()
    (tmp_path / 'meshes' / 'bin.stl').write_text(STL)
    return tmp_path


# --------------------------------------------------------------------------- what is read


def test_primitives_with_their_dimensions_and_poses() -> None:
    objects = parse_scene(_scene(
        BOX,
        {'id': 'ball', 'type': 'sphere', 'dimensions': [0.1], 'pose': {'position': [1, 2, 3]}},
        {'id': 'post', 'type': 'cylinder', 'dimensions': [0.5, 0.05],
         'pose': {'position': [0, 1, 0], 'orientation': _yaw(90)}},
        {'id': 'cone', 'type': 'cone', 'dimensions': [0.2, 0.1]},
    ))
    assert [o.id for o in objects] == ['table', 'ball', 'post', 'cone']
    assert [(o.shape.kind, o.shape.dimensions) for o in objects] == [
        ('box', (1.2, 0.8, 0.04)), ('sphere', (0.1,)), ('cylinder', (0.5, 0.05)), ('cone', (0.2, 0.1))]
    assert not any(o.attached for o in objects)
    assert_allclose(objects[0].pose, make_transform([0.5, 0.0, -0.03], np.eye(3)), atol=1e-15)
    assert_allclose(objects[1].pose, make_transform([1, 2, 3], np.eye(3)), atol=1e-15)  # no orientation
    assert_allclose(objects[2].pose, make_transform([0, 1, 0], quat_to_matrix(np.array(_yaw(90)))),
                    atol=1e-15)
    assert_allclose(objects[3].pose, np.eye(4), atol=0)                                  # no pose


def test_both_pose_forms_give_the_same_transform() -> None:
    q = _yaw(30)
    lists = {'position': [0.1, -0.2, 0.3], 'orientation': q}
    mapping = {'position': {'x': 0.1, 'y': -0.2, 'z': 0.3},
               'orientation': dict(zip('xyzw', q))}
    mixed = {'position': {'x': 0.1, 'y': -0.2, 'z': 0.3}, 'orientation': q}
    poses = [parse_scene(_scene({'id': 'b', 'type': 'sphere', 'dimensions': [0.1], 'pose': p}))[0].pose
             for p in (lists, mapping, mixed)]
    expected = make_transform([0.1, -0.2, 0.3], quat_to_matrix(np.array(q)))
    for pose in poses:
        assert_allclose(pose, expected, atol=1e-15)
    # the mapping form as geometry_msgs/Pose has it: missing fields are 0, a missing orientation identity
    partial = parse_scene(_scene({'id': 'b', 'type': 'sphere', 'dimensions': [0.1],
                                  'pose': {'position': {'z': 0.5}}}))[0].pose
    assert_allclose(partial, make_transform([0, 0, 0.5], np.eye(3)), atol=0)


def test_quaternion_close_to_unit_is_normalised() -> None:
    q = np.array(_yaw(40)) * 1.0005                     # within the package's 1e-3 rule
    pose = parse_scene(_scene({'id': 'b', 'type': 'sphere', 'dimensions': [0.1],
                               'pose': {'orientation': q.tolist()}}))[0].pose
    assert_allclose(pose[:3, :3], quat_to_matrix(np.array(_yaw(40))), atol=1e-12)


def test_attached_object_keeps_its_tool_frame_pose() -> None:
    (obj,) = parse_scene(_scene({'id': 'gripper', 'type': 'cylinder', 'dimensions': [0.12, 0.04],
                                 'attached': True, 'pose': {'position': [0, 0, 0.06]}}))
    assert obj.attached is True
    assert_allclose(obj.pose, make_transform([0, 0, 0.06], np.eye(3)), atol=0)


def test_relative_mesh_path_is_relative_to_the_yaml_file(mesh_dir: Path, tmp_path: Path) -> None:
    path = mesh_dir / 'scene.yaml'
    path.write_text(yaml.safe_dump(_scene({'id': 'bin', 'mesh': 'meshes/bin.stl', 'scale': [2, 2, 0.5]})))
    elsewhere = tmp_path / 'cwd'
    elsewhere.mkdir()
    cwd = os.getcwd()
    os.chdir(elsewhere)                                # not relative to the working directory
    try:
        (obj,) = load_scene(str(path))
    finally:
        os.chdir(cwd)
    assert obj.shape.kind == 'mesh'
    assert obj.shape.mesh == str(mesh_dir / 'meshes' / 'bin.stl')
    assert os.path.isabs(obj.shape.mesh)
    assert tuple(obj.shape.scale) == (2.0, 2.0, 0.5)
    (obj,) = parse_scene(_scene({'id': 'bin', 'mesh': 'meshes/bin.stl'}), str(mesh_dir))
    assert tuple(obj.shape.scale) == (1.0, 1.0, 1.0)                                # default scale


def test_file_and_package_uris(mesh_dir: Path) -> None:
    target = str(mesh_dir / 'meshes' / 'bin.stl')
    (obj,) = parse_scene(_scene({'id': 'bin', 'mesh': f'file://{target}', 'type': 'mesh'}))
    assert obj.shape.mesh == target
    # package://PKG/rel: DIR/PKG/rel for a directory holding packages, DIR/rel for PKG's own directory
    pkg = mesh_dir.name
    for dirs in ([str(mesh_dir.parent)], [str(mesh_dir)]):
        (obj,) = parse_scene(_scene({'id': 'bin', 'mesh': f'package://{pkg}/meshes/bin.stl'}),
                             package_dirs=dirs)
        assert obj.shape.mesh == target


def test_package_uri_falls_back_to_the_ament_index(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip('ament_index_python')
    prefix = tmp_path / 'prefix'
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages').mkdir(parents=True)
    (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / 'cell_meshes').write_text('')
    (prefix / 'share' / 'cell_meshes' / 'meshes').mkdir(parents=True)
    (prefix / 'share' / 'cell_meshes' / 'meshes' / 'bin.stl').write_text(STL)
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(prefix))
    assert resolve_mesh('package://cell_meshes/meshes/bin.stl', 'mesh') == str(
        prefix / 'share' / 'cell_meshes' / 'meshes' / 'bin.stl')


def test_example_scene_file() -> None:
    """msg_examples/scene_box.yaml: a 0.3 m cube across the paper's 3R line, at its midpoint."""
    (box,) = load_scene(str(ROOT / 'msg_examples' / 'scene_box.yaml'))
    assert (box.id, box.shape.kind, box.shape.dimensions, box.attached) == ('box', 'box', (0.3, 0.3, 0.3), False)
    assert_allclose(box.pose, make_transform([2.0, 2.0, 0.0], np.eye(3)), atol=0)
    request = yaml.safe_load((ROOT / 'msg_examples' / 'paper_3r.yaml').read_text())
    a = np.array([request['start']['position'][k] for k in 'xyz'])
    b = np.array([request['goal']['position'][k] for k in 'xyz'])
    assert_allclose((a + b) / 2.0, box.pose[:3, 3], atol=1e-12)   # on the line, so the line is blocked


def test_empty_scene_and_the_largest_one() -> None:
    assert parse_scene({'objects': []}) == []
    many = [{'id': f'o{i}', 'type': 'sphere', 'dimensions': [0.01]} for i in range(MAX_SCENE_OBJECTS)]
    assert len(parse_scene({'objects': many})) == MAX_SCENE_OBJECTS


# --------------------------------------------------------------------------- refusals


def _mutated(change: dict[str, Any], drop: tuple[str, ...] = ()) -> dict[str, Any]:
    obj = copy.deepcopy(BOX)
    obj.update(change)
    for key in drop:
        del obj[key]
    return _scene({'id': 'first', 'type': 'sphere', 'dimensions': [0.1]}, obj)


REFUSED = [
    # (case, scene, message (regular expression))
    ('not a mapping', [BOX], r"^scene: expected a mapping with the list \"objects\""),
    ('top-level key', {'objects': [], 'frame': 'world'}, r"^scene: unknown keys \['frame'\]"),
    ('no objects', {}, r'^scene: objects: missing'),
    ('objects not a list', {'objects': {'id': 'a'}}, r'^scene: objects: expected a list'),
    ('too many', {'objects': [{'id': f'o{i}', 'type': 'sphere', 'dimensions': [0.1]}
                              for i in range(MAX_SCENE_OBJECTS + 1)]},
     rf'^scene: objects: {MAX_SCENE_OBJECTS + 1} objects, at most {MAX_SCENE_OBJECTS}$'),
    ('object not a mapping', _scene('table'), r'^scene: objects\[0\]: expected a mapping'),
    ('no id', _mutated({}, drop=('id',)), r'^scene: objects\[1\]: id: every object needs a non-empty string id'),
    ('empty id', _mutated({'id': ''}), r'^scene: objects\[1\]: id: every object needs a non-empty string id'),
    ('id not a string', _mutated({'id': 7}), r'^scene: objects\[1\]: id: .*got \'7\''),
    ('duplicate id', _mutated({'id': 'first'}),
     r"^scene: objects\[1\]: id: 'first' is already the id of objects\[0\] \(ids must be unique\)$"),
    ('unknown key', _mutated({'colour': 'red'}),
     r"^scene: objects\[1\] \('table'\): unknown keys \['colour'\] \(known: attached, dimensions, id, mesh, "),
    ('unknown type', _mutated({'type': 'torus'}),
     r"^scene: objects\[1\] \('table'\): type: unknown type 'torus' \(known: box, sphere, cylinder, cone"),
    ('no type', _mutated({}, drop=('type',)), r"^scene: objects\[1\] \('table'\): type: missing"),
    ('no dimensions', _mutated({}, drop=('dimensions',)),
     r"^scene: objects\[1\] \('table'\): dimensions: missing \(x, y, z; m\)"),
    ('dimensions not numbers', _mutated({'dimensions': ['a', 1, 1]}),
     r"^scene: objects\[1\] \('table'\): dimensions: expected a list of numbers"),
    ('dimensions boolean', _mutated({'dimensions': [True, 1, 1]}),
     r"^scene: objects\[1\] \('table'\): dimensions: expected a list of numbers"),
    ('box with 2 dimensions', _mutated({'dimensions': [1, 1]}),
     r"^scene: objects\[1\] \('table'\): dimensions: a box needs 3 dimensions \(x, y, z; m\), got 2$"),
    ('sphere with 2 dimensions', _mutated({'type': 'sphere', 'dimensions': [1, 1]}),
     r"dimensions: a sphere needs 1 dimension \(radius; m\), got 2$"),
    ('cylinder with 3 dimensions', _mutated({'type': 'cylinder', 'dimensions': [1, 1, 1]}),
     r"dimensions: a cylinder needs 2 dimensions \(height, radius; m\), got 3$"),
    ('cone with 1 dimension', _mutated({'type': 'cone', 'dimensions': [1]}),
     r"dimensions: a cone needs 2 dimensions \(height, radius; m\), got 1$"),
    ('zero dimension', _mutated({'dimensions': [1.2, 0.0, 0.04]}),
     r"^scene: objects\[1\] \('table'\): dimensions: box y must be finite and > 0 m, got 0.0$"),
    ('negative dimension', _mutated({'type': 'cylinder', 'dimensions': [0.5, -0.1]}),
     r"dimensions: cylinder radius must be finite and > 0 m, got -0.1$"),
    ('NaN dimension', _mutated({'dimensions': [float('nan'), 1, 1]}),
     r"dimensions: box x must be finite and > 0 m, got nan$"),
    ('infinite dimension', _mutated({'type': 'sphere', 'dimensions': [float('inf')]}),
     r"dimensions: sphere radius must be finite and > 0 m, got inf$"),
    ('scale on a primitive', _mutated({'scale': [1, 1, 1]}),
     r"^scene: objects\[1\] \('table'\): scale: only used with a mesh"),
    ('attached not a boolean', _mutated({'attached': 'yes please'}),
     r"^scene: objects\[1\] \('table'\): attached: expected true or false"),
    ('pose not a mapping', _mutated({'pose': [0, 0, 0]}),
     r"^scene: objects\[1\] \('table'\): pose: expected a mapping with position and orientation"),
    ('pose key', _mutated({'pose': {'position': [0, 0, 0], 'rotation': [0, 0, 0, 1]}}),
     r"^scene: objects\[1\] \('table'\): pose: unknown keys \['rotation'\]"),
    ('position key', _mutated({'pose': {'position': {'x': 1, 'h': 2}}}),
     r"^scene: objects\[1\] \('table'\): pose.position: unknown keys \['h'\]"),
    ('position count', _mutated({'pose': {'position': [0, 0]}}),
     r"^scene: objects\[1\] \('table'\): pose.position: needs 3 numbers \(x, y, z\), got 2$"),
    ('orientation count', _mutated({'pose': {'orientation': [0, 0, 1]}}),
     r"^scene: objects\[1\] \('table'\): pose.orientation: needs 4 numbers \(x, y, z, w\), got 3$"),
    ('NaN position', _mutated({'pose': {'position': [0, float('nan'), 0]}}),
     r"^scene: objects\[1\] \('table'\): pose: position contains NaN or inf"),
    ('NaN position, mapping', _mutated({'pose': {'position': {'x': float('nan')}}}),
     r"^scene: objects\[1\] \('table'\): pose: position contains NaN or inf"),
    ('unnormalised quaternion', _mutated({'pose': {'orientation': [0, 0, 0.5, 0.5]}}),
     r"^scene: objects\[1\] \('table'\): pose.orientation: quaternion is not normalised \(norm 0.707107, "
     r"expected 1 within 0.001\)$"),
    ('unnormalised quaternion, mapping', _mutated({'pose': {'orientation': {'x': 0, 'y': 0, 'z': 0}}}),
     r"^scene: objects\[1\] \('table'\): pose.orientation: quaternion is not normalised \(norm 0, "),
    ('mesh and type', _mutated({'mesh': '/nonexistent/bin.stl'}),
     r"^scene: objects\[1\] \('table'\): type: 'box' with a mesh \(give one of type and mesh\)$"),
    ('mesh and dimensions', _mutated({'mesh': '/nonexistent/bin.stl'}, drop=('type',)),
     r"^scene: objects\[1\] \('table'\): dimensions: not used with a mesh \(use scale\)$"),
    ('mesh not a string', _mutated({'mesh': ['bin.stl']}, drop=('type', 'dimensions')),
     r"^scene: objects\[1\] \('table'\): mesh: expected a path or URI"),
    ('missing mesh file', _mutated({'mesh': '/nonexistent/bin.stl'}, drop=('type', 'dimensions')),
     r"^scene: objects\[1\] \('table'\): mesh: mesh file '/nonexistent/bin.stl' not found \(looked at "
     r"'/nonexistent/bin.stl'\)$"),
    ('mesh format', _mutated({'mesh': '/nonexistent/bin.ply'}, drop=('type', 'dimensions')),
     r"^scene: objects\[1\] \('table'\): mesh: '/nonexistent/bin.ply' is not a mesh file this planner "
     r"reads \(STL, DAE or OBJ\)$"),
    ('mesh URI scheme', _mutated({'mesh': 'http://example.com/bin.stl'}, drop=('type', 'dimensions')),
     r"mesh: 'http://example.com/bin.stl': only file paths, file:// and package:// URIs are supported$"),
    ('package URI without a path', _mutated({'mesh': 'package://cell'}, drop=('type', 'dimensions')),
     r"mesh: 'package://cell' is not package://PACKAGE/PATH$"),
    ('package not found', _mutated({'mesh': 'package://no_such_pkg_xyz/bin.stl'}, drop=('type', 'dimensions')),
     r"mesh: mesh file 'package://no_such_pkg_xyz/bin.stl' not found \(no package directory given, and "
     r"the package is not in the ament index\)$"),
]


@pytest.mark.parametrize(('scene', 'message'), [case[1:] for case in REFUSED], ids=[case[0] for case in REFUSED])
def test_refusals_name_the_object_and_the_key(scene: object, message: str) -> None:
    with pytest.raises(RequestError, match=message):
        parse_scene(scene, '/nonexistent')


def test_mesh_scale_refusals(mesh_dir: Path) -> None:
    for scale, message in (([1, 1], r'scale: needs 3 numbers \(x, y, z\), got 2$'),
                           ([1, 0, 1], r'scale: every factor must be finite and > 0, got \[1.0, 0.0, 1.0\]$'),
                           ([1, float('nan'), 1], r'scale: every factor must be finite and > 0'),
                           ('big', r'scale: expected a list of numbers')):
        with pytest.raises(RequestError, match=r"^scene: objects\[0\] \('bin'\): " + message):
            parse_scene(_scene({'id': 'bin', 'mesh': 'meshes/bin.stl', 'scale': scale}), str(mesh_dir))


def test_package_uri_lists_where_it_looked(tmp_path: Path) -> None:
    with pytest.raises(RequestError, match=(
            rf"mesh: mesh file 'package://cell/m/bin.stl' not found \(looked at '{tmp_path}/a/cell/m/bin.stl', "
            rf"'{tmp_path}/cell/m/bin.stl'")):
        parse_scene(_scene({'id': 'bin', 'mesh': 'package://cell/m/bin.stl'}),
                    package_dirs=[str(tmp_path / 'a'), str(tmp_path)])


def test_relative_mesh_without_a_base_directory_is_refused() -> None:
    with pytest.raises(RequestError, match=r"^mesh_resource: 'bin.stl' is a relative path; give an absolute path"):
        resolve_mesh('bin.stl', 'mesh_resource')


def test_long_ids_are_cut_in_messages() -> None:
    with pytest.raises(RequestError, match=r"objects\[0\] \('x{80}'\.\.\. \(5000 characters\)\): type: missing"):
        parse_scene(_scene({'id': 'x' * 5000}))


def test_load_scene_file_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)       # a short name: long paths are cut in messages
    with pytest.raises(RequestError, match=r"^cannot read scene 'missing.yaml': No such file"):
        load_scene('missing.yaml')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('objects: [\n  - id: a\n')
    with pytest.raises(RequestError, match=r"^malformed YAML in scene '.*bad.yaml' at line \d+, column \d+"):
        load_scene(str(bad))
    empty = tmp_path / 'empty.yaml'
    empty.write_text('')
    with pytest.raises(RequestError, match=r'^scene: expected a mapping with the list "objects" at the top level, '
                                           r"got 'None'"):
        load_scene(str(empty))
