"""core/point_cloud.py: clouds -> self-filtered occupancy octrees, checked like every scene object.

Judged against independent computations: the voxels against a set of floored coordinates, coal's
distance to a grid-aligned box-shaped cloud against the same box as a primitive, the self filter
against coal's distances of the points from the links, and the refusal of a line through a box
seen by a simulated depth camera against the same box given as a primitive.
"""
from __future__ import annotations

import math
from pathlib import Path

import coal
import numpy as np
import pytest

from cloud_util import capsule_points, depth_camera, look_at
from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.branches import check_trajectory
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import (ConfigError, PathInCollisionError, RequestError,
                                          StartInCollisionError)
from geodesic_planner.core.point_cloud import SelfFilter, cloud_map, sensors, voxel_centres, with_map

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
RES = 0.02


@pytest.fixture(scope='module')
def ur5e() -> tuple:
    robot = load_robot('ur5e')
    return robot, CollisionModel.for_robot(robot)


@pytest.fixture(scope='module')
def ur5() -> tuple:
    robot = load_robot(str(UR5_URDF), base_link='base_link', tip_link='tool0')
    return robot, CollisionModel.for_robot(robot, UR5_URDF.read_text(), package_dirs=[str(DATA / 'meshes')])


def _coal_point_distance(geometry: object, frame: np.ndarray, p: np.ndarray) -> float:
    req, res = coal.DistanceRequest(), coal.DistanceResult()
    return float(coal.distance(geometry, coal.Transform3s(frame[:3, :3], frame[:3, 3]), coal.Sphere(1e-12),
                               coal.Transform3s(np.eye(3), p), req, res))


def test_voxels_are_the_cells_that_hold_a_point_nan_skipped_float32() -> None:
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.3, 0.5, (3000, 3)).astype(np.float32)
    pts[rng.random(3000) < 0.1, rng.integers(0, 3)] = np.nan
    pts[7] = [np.inf, 0, 0]
    found = cloud_map('/cam', pts, np.eye(4), RES)
    good = pts[np.all(np.isfinite(pts), axis=1)].astype(float)
    cells = {tuple(math.floor(c / RES) for c in p) for p in good.tolist()}
    got = {tuple(math.floor(c / RES) for c in p) for p in found.object.shape.vertices.tolist()}
    assert got == cells
    assert found.received == 3000 and found.finite == len(good) and found.voxels == len(cells)
    # the tiles' coal octrees hold exactly those cells
    boxes = np.concatenate([np.asarray(tree.toBoxes())[:, :3] for tree, _, _ in found.object.shape.octree])
    assert {tuple(math.floor(c / RES) for c in p) for p in boxes.tolist()} == cells
    assert len(boxes) == len(cells)


def test_sensor_pose_takes_points_into_the_base_frame() -> None:
    sensor = sensors(['/cam'], ['cam_link'], [0.5, -0.2, 1.0, 0.0, 0.0, math.sin(0.4), math.cos(0.4)])[0]
    rng = np.random.default_rng(2)
    local = rng.uniform(-1, 1, (500, 3))
    found = cloud_map('/cam', local, sensor.pose, RES)
    c, s = math.cos(0.8), math.sin(0.8)
    base = local @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T + [0.5, -0.2, 1.0]
    assert np.array_equal(found.object.shape.vertices, voxel_centres(base, RES)[0])


def test_octree_distance_equals_the_box_it_fills(ur5e: tuple, ur5: tuple) -> None:
    """A grid-aligned box filled with points: the octree's occupied cells are that box exactly, so
    coal's distance from every link to the octree equals the distance to the box primitive."""
    rng = np.random.default_rng(3)
    lo, hi = np.array([0.30, -0.20, -0.10]), np.array([0.50, 0.10, 0.20])
    pts = rng.uniform(lo + 1e-6, hi - 1e-6, (40000, 3))
    octree = cloud_map('box', pts, np.eye(4), RES).object
    assert octree.shape.vertices.shape[0] == 10 * 15 * 15
    box = SceneObject('box', Shape('box', tuple(hi - lo)), np.block([[np.eye(3), ((lo + hi) / 2)[:, None]],
                                                                     [np.zeros((1, 3)), np.ones((1, 1))]]))
    for robot, model in (ur5e, ur5):
        a, b = model.with_objects([octree]), model.with_objects([box])
        qs = rng.uniform(robot.lower, robot.upper, (60, robot.dof))
        P_a = a._poses(qs)[0]     # per-pair coal distances over every configuration
        P_b = b._poses(qs)[0]
        for _p, pair in enumerate(a._pair_names):
            if 'box' not in pair:
                continue
            q_pair = b._pair_names.index(pair)
            for n in range(len(qs)):
                da = min(a._coal_distance(P_a, n, k, {}) for k, key in enumerate(a._pair_names) if key == pair)
                db = b._coal_distance(P_b, n, q_pair, {})
                if db > 1e-6:
                    assert da == pytest.approx(db, abs=1e-5), (pair, n)   # GJK's tolerance
                else:
                    assert da <= 1e-6
            break


def test_self_filter_on_capsules_is_the_padding_exactly(ur5e: tuple) -> None:
    robot, model = ur5e
    pad = 0.03
    flt = SelfFilter(model, pad)
    rng = np.random.default_rng(4)
    q = rng.uniform(robot.lower, robot.upper)
    S = robot.segment_frames(q[None])[0]
    bodies = model.robot_bodies
    frames = np.array([S[b.segment] @ b.offset for b in bodies])
    pts = frames[rng.integers(0, len(frames), 4000), :3, 3] + rng.uniform(-0.15, 0.15, (4000, 3))
    inside = flt.inside(pts, q)
    d = np.array([min(_coal_point_distance(b.geometry, F, p) for b, F in zip(bodies, frames)) for p in pts])
    clear = np.abs(d - pad) > 1e-9
    assert np.array_equal(inside[clear], d[clear] <= pad)
    assert 50 < inside.sum() < 3950


def test_self_filter_on_mesh_hulls_removes_every_point_within_the_padding(ur5: tuple) -> None:
    robot, model = ur5
    pad = 0.03
    flt = SelfFilter(model, pad)
    rng = np.random.default_rng(5)
    q = rng.uniform(robot.lower, robot.upper)
    S = robot.segment_frames(q[None])[0]
    bodies = model.robot_bodies
    frames = np.array([S[b.segment] @ b.offset for b in bodies])
    pts = frames[rng.integers(0, len(frames), 3000), :3, 3] + rng.normal(0.0, 0.12, (3000, 3))
    inside = flt.inside(pts, q)
    d = np.array([min(_coal_point_distance(b.geometry, F, p) for b, F in zip(bodies, frames)) for p in pts])
    assert np.all(inside[d <= pad])          # never less than the padding
    assert not np.any(inside[d > 2.5 * pad])  # faces moved out: a little more near edges only
    assert inside.sum() > 200


def _lin(robot, start: np.ndarray, shift: np.ndarray) -> object:
    planner = GeodesicPlanner(robot)
    T0 = robot.fk(start[None])[0]
    T1 = T0.copy()
    T1[:3, 3] += shift
    return planner.plan(T0, T1, start_joints=start).timed()


def _scene_boxes() -> tuple[list[tuple[np.ndarray, np.ndarray]], tuple[np.ndarray, np.ndarray]]:
    """A table below the arm and a box standing on it across the tool's line from _start."""
    table = (np.array([-1.0, -0.8, -0.15]), np.array([0.3, 0.8, -0.10]))
    box = (np.array([-0.42, 0.02, -0.10]), np.array([-0.28, 0.12, 0.43]))
    return [table, box], box


CAMERA = look_at(np.array([-1.5, 0.1, 0.9]), np.array([-0.35, 0.07, 0.1]))


def _camera_map(boxes: list, pose: np.ndarray, seed: int, **kw: object) -> object:
    cloud = depth_camera(boxes, pose, width=200, height=150, rng=np.random.default_rng(seed))
    return cloud_map('/camera/points', cloud.reshape(-1, 3), pose, RES, **kw)


def _start(robot) -> np.ndarray:
    return np.array([0.0, -1.9, 1.9, -1.57, -1.57, 0.0])[:robot.dof]


def test_box_seen_only_as_points_refuses_the_line_like_the_primitive(ur5e: tuple) -> None:
    robot, model = ur5e
    q0 = _start(robot)
    tool = robot.fk(q0[None])[0][:3, 3]
    boxes, (lo, hi) = _scene_boxes()
    shift = np.array([0.0, 0.40, 0.0])
    assert lo[1] > tool[1] and hi[1] < tool[1] + shift[1] and lo[0] < tool[0] < hi[0]   # the line crosses it
    cam = CAMERA
    seen = _camera_map(boxes, cam, 6, self_filter=SelfFilter(model, 0.03), q=q0)
    primitive = SceneObject('box', Shape('box', tuple(hi - lo)),
                            np.block([[np.eye(3), ((lo + hi) / 2)[:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]))
    traj = _lin(robot, q0, shift)
    with pytest.raises(PathInCollisionError) as by_points:
        check_trajectory(model.with_objects([seen.object]), traj)
    with pytest.raises(PathInCollisionError) as by_box:
        check_trajectory(model.with_objects([primitive]), traj)
    assert '/camera/points' in by_points.value.pair and 'box' in by_box.value.pair
    # the cloud's cells lie within a voxel diagonal (and the noise) of the box's faces
    assert abs(by_points.value.fraction - by_box.value.fraction) * np.linalg.norm(shift) <= RES * math.sqrt(3) + 0.01


def test_the_robot_in_the_cloud_does_not_block_and_a_box_removed_stops_blocking(ur5e: tuple) -> None:
    robot, model = ur5e
    q0 = _start(robot)
    rng = np.random.default_rng(7)
    S = robot.segment_frames(q0[None])[0]
    caps = [(S[b.segment] @ b.offset, b.geometry.halfLength) for b in model.robot_bodies
            if isinstance(b.geometry, coal.Capsule)]
    arm = capsule_points(np.array([c[0] for c in caps]), np.array([c[1] for c in caps]),
                         float(model.robot_bodies[1].geometry.radius), 20000, rng, jitter=0.02)
    boxes, _ = _scene_boxes()
    cam = CAMERA
    cloud = depth_camera(boxes, cam, width=200, height=150, rng=rng).reshape(-1, 3)
    in_cam = (arm - cam[:3, 3]) @ cam[:3, :3]
    points = np.concatenate([cloud, in_cam.astype(np.float32)])
    traj = _lin(robot, q0, np.array([0.0, 0.40, 0.0]))
    flt = SelfFilter(model, 0.03)
    unfiltered = cloud_map('/camera/points', points, cam, RES)
    with pytest.raises(StartInCollisionError) as err:          # without the filter: its own image
        check_trajectory(model.with_objects([unfiltered.object]), traj)
    assert '/camera/points' in err.value.pair
    filtered = cloud_map('/camera/points', points, cam, RES, self_filter=flt, q=q0)
    assert filtered.robot >= 20000
    scene = model.with_objects([filtered.object])
    with pytest.raises(PathInCollisionError):                  # the box still blocks the line
        check_trajectory(scene, traj)
    # the box is taken away: the next cloud replaces the map, and the line is clear
    later = depth_camera(boxes[:1], cam, width=200, height=150, rng=rng).reshape(-1, 3)
    nxt = cloud_map('/camera/points', np.concatenate([later, in_cam.astype(np.float32)]), cam, RES,
                    self_filter=flt, q=q0)
    scene = with_map(scene, '/camera/points', nxt.object)
    assert [o.id for o in scene.objects] == ['/camera/points']
    found = check_trajectory(scene, traj)
    assert found.min_clearance > model.padding
    assert with_map(scene, '/camera/points', None).objects == ()


def test_refusals_name_the_value() -> None:
    with pytest.raises(RequestError, match=r'points must be \(N, 3\)'):
        cloud_map('/c', np.zeros((4, 2)), np.eye(4), RES)
    with pytest.raises(RequestError, match='resolution'):
        cloud_map('/c', np.zeros((4, 3)), np.eye(4), 0.0)
    with pytest.raises(RequestError, match='joint state'):
        cloud_map('/c', np.zeros((4, 3)), np.eye(4), RES, self_filter=object())  # type: ignore[arg-type]
    assert cloud_map('/c', np.full((5, 3), np.nan), np.eye(4), RES).object is None
    with pytest.raises(ConfigError, match='one frame per topic'):
        sensors(['/a', '/b'], ['f'], [0.0] * 14)
    with pytest.raises(ConfigError, match='7 values'):
        sensors(['/a'], ['f'], [0.0] * 6)
    with pytest.raises(ConfigError, match='unit length'):
        sensors(['/a'], ['f'], [0, 0, 0, 0, 0, 0, 2.0])
    with pytest.raises(ConfigError, match='given twice'):
        sensors(['/a', '/a'], ['f', 'g'], [0, 0, 0, 0, 0, 0, 1.0] * 2)
    with pytest.raises(RequestError, match='octree'):
        Shape('octree', (RES,), vertices=np.zeros((0, 3)))
