"""core/collision_scene.py: one object replaced in a collision model equals the model built from scratch.

Judged against ``CollisionModel.with_objects`` of the same scene (the whole build): every field of
the model (bodies, pairs and their order, names, skip reasons, reaches, the capsule tables), the
exact distances of every pair at random configurations, and the verdicts of LIN checks (the code,
the pair, the place, min_clearance).
"""
from __future__ import annotations

from pathlib import Path

import coal
import numpy as np
import pytest

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.branches import check_trajectory
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.collision_scene import with_object_replaced
from geodesic_planner.core.errors import GeodesicPlannerError, RequestError

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
Q0 = np.array([0.0, -1.9, 1.9, -1.57, -1.57, 0.0])
#: per-model scratch and caches: fresh in every model, not compared
SCRATCH = {'_distance_fns', '_request', '_result'}


def _pose(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def _octree(name: str, seed: int, n: int = 3000) -> SceneObject:
    """A map of scattered voxels over the table and a wall beside the arm (several tiles)."""
    rng = np.random.default_rng(seed)
    pts = np.concatenate([rng.uniform([-0.9, -0.6, -0.12], [0.1, 0.6, -0.08], (n, 3)),
                          rng.uniform([-0.6, 0.25, -0.1], [-0.2, 0.3, 0.5], (n // 3, 3))])
    cells = np.unique(np.floor(pts / 0.02), axis=0)
    return SceneObject(name, Shape('octree', (0.02,), vertices=(cells + 0.5) * 0.02))


def _objects() -> list[SceneObject]:
    return [SceneObject('table', Shape('box', (1.2, 1.6, 0.05)), _pose(-0.4, 0.0, -0.13)),
            _octree('/cam', 1),
            SceneObject('tool', Shape('cylinder', (0.1, 0.03)), _pose(0, 0, 0.05), attached=True),
            SceneObject('post', Shape('sphere', (0.05,)), _pose(-0.5, -0.3, 0.2)),
            _octree('/cam2', 5, 800)]


def _same(a: CollisionModel, b: CollisionModel) -> None:
    """Every field of a equal to b's (a field that is new to the model fails here until it is compared)."""
    va, vb = vars(a), vars(b)
    assert va.keys() == vb.keys()
    for key in va.keys() - SCRATCH:
        x, y = va[key], vb[key]
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape, key
            assert np.array_equal(x, y, equal_nan=x.dtype.kind == 'f'), key
        elif key in ('_bodies', '_robot_bodies'):
            assert len(x) == len(y)
            for p, q in zip(x, y):
                assert (p.name, p.segment, p.kind, p.radius, type(p.geometry)) == \
                    (q.name, q.segment, q.kind, q.radius, type(q.geometry)), key
                assert np.array_equal(p.offset, q.offset) and np.array_equal(p.center, q.center), key
        elif key == 'objects':
            assert [o.id for o in x] == [o.id for o in y] and all(o is p for o, p in zip(x, y)), key
        else:
            assert x == y, key
    assert va['_distance_fns'] == {} and va['_request'] is not vb['_request']


def _verdicts(model: CollisionModel, trajs: list) -> list:
    out: list[tuple] = []
    for traj in trajs:
        try:
            found = check_trajectory(model, traj)
            out.append(('clear', found.min_clearance, found.pair, found.fraction))
        except GeodesicPlannerError as err:
            out.append((type(err).__name__, str(err)))
    return out


@pytest.fixture(scope='module')
def ur5e() -> tuple:
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(3)
    trajs = []
    for _ in range(6):
        q = Q0 + rng.uniform(-0.3, 0.3, 6)
        T0 = robot.fk(q[None])[0]
        T1 = T0.copy()
        T1[:3, 3] += rng.normal(size=3) * 0.15
        try:
            trajs.append(planner.plan(T0, T1, start_joints=q).timed())
        except GeodesicPlannerError:
            continue
    assert len(trajs) >= 3
    return robot, CollisionModel.for_robot(robot), trajs


@pytest.mark.parametrize('case', ['replace', 'first', 'middle', 'remove', 'rename', 'absent'])
def test_replaced_equals_built_from_scratch(ur5e: tuple, case: str) -> None:
    robot, bare, trajs = ur5e
    objects = _objects()
    new = {'replace': _octree('/cam2', 9, 2500), 'first': _octree('/cam3', 2), 'middle': _octree('/cam', 4),
           'remove': None, 'rename': SceneObject('box', Shape('box', (0.1, 0.1, 0.4)), _pose(-0.35, 0.1, 0.1)),
           'absent': None}[case]
    target = {'replace': '/cam2', 'first': '/cam3', 'middle': '/cam', 'remove': '/cam', 'rename': 'post',
              'absent': 'nothing'}[case]
    model = bare.with_objects(objects)
    got = with_object_replaced(model, target, new)
    kept = [o for o in objects if o.id != target]
    scratch = bare.with_objects(kept if new is None else [*kept, new])
    _same(got, scratch)
    assert model.objects == tuple(objects)                   # the model it came from is unchanged
    qs = Q0 + np.random.default_rng(4).uniform(-0.6, 0.6, (40, 6))
    d_got, names_got = got.distances(qs)
    d_new, names_new = scratch.distances(qs)
    assert names_got == names_new and np.array_equal(d_got, d_new)
    assert np.all(np.isfinite(d_got)) and any('/cam' in n for p in names_got for n in p)
    verdicts = _verdicts(got, trajs)
    assert verdicts == _verdicts(scratch, trajs)
    assert verdicts != _verdicts(bare, trajs) or case in ('remove', 'absent')   # the scene matters


def test_replaced_on_mesh_hulls_and_from_an_empty_scene() -> None:
    robot = load_robot(str(UR5_URDF), base_link='base_link', tip_link='tool0')
    bare = CollisionModel.for_robot(robot, UR5_URDF.read_text(), package_dirs=[str(DATA / 'meshes')])
    assert any(isinstance(b.geometry, coal.ConvexBase) for b in bare.robot_bodies)
    qs = Q0 + np.random.default_rng(5).uniform(-0.5, 0.5, (20, 6))
    model = bare
    for seed in (1, 2, 3):               # clouds one after the other, as the node swaps them in
        obj = _octree('/cam', seed)
        model = with_object_replaced(model, '/cam', obj)
        scratch = bare.with_objects([obj])
        _same(model, scratch)
        assert model.distances(qs)[0].tolist() == scratch.distances(qs)[0].tolist()
    _same(with_object_replaced(model, '/cam', None), bare)


def test_refusals_are_the_whole_builds(ur5e: tuple) -> None:
    _, bare, _ = ur5e
    model = bare.with_objects(_objects())
    for obj, said in ((SceneObject('post', Shape('sphere', (0.1,))), "two objects named 'post'"),
                      (SceneObject(bare.body_names[2], Shape('sphere', (0.1,))), 'has the name of a robot link')):
        with pytest.raises(RequestError, match=said):
            with_object_replaced(model, '/cam', obj)
