"""min_clearance (core/clearance.py, through CollisionModel.check_path; issue 37): a property of the
path, at most 1 mm below its true minimum and never above, the same for every time law.

The oracle is dense and independent of the library's distances: coal's distance between the
checked bodies, placed here (the presets' link capsules from the chain's joint origins, the UR5's
meshes' convex hulls placed by pinocchio, the scene's primitives at their poses), at 2001 values of
s along the path and again on a fine grid around every near-minimum, for every pair the model
checks. Reported values must lie in [oracle - 1 mm, oracle].
"""
from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest
from test_collision import MESHES, UR5_SRDF, UR5_URDF, CoalOracle
from test_real_arm_moves import random_move

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.branches import check_trajectory
from geodesic_planner.core.collision import (CLEARANCE_RESOLUTION, DEFAULT_LINK_RADIUS, CollisionModel, SceneObject,
                                             Shape)
from geodesic_planner.core.errors import CollisionError, GeodesicPlannerError
from geodesic_planner.core.kinematics import rot_z, trans

coal = pytest.importorskip('coal')

#: The guarantee: min_clearance in [true - 1 mm, true].
BAND = 1e-3
#: Dense samples of s, and the fine grid around each near-minimum (its two neighbouring intervals).
DENSE, FINE = 2001, 201
#: The oracle's own slack (m): coal's distances and the fine grid's sampling near a minimum.
SLACK = 2e-6


def capsule_oracle(robot: Any, radius: float = DEFAULT_LINK_RADIUS):
    """Bodies of a model without geometry, placed here: link_k a capsule (a sphere where it has no
    length) of ``radius`` from joint k's origin to joint k + 1's (the base's origin before joint 0,
    the tool after the last). Returns q (dof,) -> {name: (coal geometry, coal transform)}."""
    def place(q: np.ndarray) -> dict[str, tuple[Any, Any]]:
        Tj, T = robot.frames(q[None])
        points = [np.zeros(3), *Tj[0, :, :3, 3], T[0, :3, 3]]
        out = {}
        for k, (a, b) in enumerate(itertools.pairwise(points)):
            length = float(np.linalg.norm(b - a))
            if length < 1e-9:
                out[f'link_{k}'] = (coal.Sphere(radius), coal.Transform3s(np.eye(3), a))
                continue
            z = (b - a) / length
            x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
            x /= np.linalg.norm(x)
            R = np.stack([x, np.cross(z, x), z], axis=1)
            out[f'link_{k}'] = (coal.Capsule(radius, length), coal.Transform3s(R, 0.5 * (a + b)))
        return out
    return place


def hull_oracle(oracle: CoalOracle):
    """The UR5's link hulls placed by pinocchio (test_collision's CoalOracle)."""
    def place(q: np.ndarray) -> dict[str, tuple[Any, Any]]:
        X = oracle.placements(q)
        return {link: (oracle.hull[link], X[link]) for link in X}
    return place


def scene_geometry(obj: SceneObject) -> tuple[Any, Any]:
    kind, dims = obj.shape.kind, obj.shape.dimensions
    geometry = (coal.Box(*dims) if kind == 'box' else coal.Sphere(dims[0]) if kind == 'sphere'
                else coal.Cylinder(dims[1], dims[0]))
    return geometry, coal.Transform3s(obj.pose[:3, :3], obj.pose[:3, 3])


def oracle_min(model: CollisionModel, place, path: Any) -> float:
    """The smallest distance over the path between the pairs the model checks, by coal."""
    fixed = {o.id: scene_geometry(o) for o in model.objects}
    request, result = coal.DistanceRequest(), coal.DistanceResult()

    def d(s: np.ndarray) -> np.ndarray:
        qs = path.evaluate(s, order=0)[0]
        out = np.empty(len(s))
        for n, q in enumerate(qs):
            bodies = {**place(q), **fixed}
            out[n] = min(coal.distance(*bodies[a], *bodies[b], request, result) for a, b in model.pairs)
        return out
    s = np.linspace(0.0, 1.0, DENSE)
    dense = d(s)
    best = float(dense.min())
    near = np.flatnonzero((dense <= best + 2e-3)
                          & (dense <= np.r_[np.inf, dense[:-1]]) & (dense <= np.r_[dense[1:], np.inf]))
    for i in near:           # each near local minimum, on a fine grid over its two intervals
        fine = np.linspace(s[max(i - 1, 0)], s[min(i + 1, DENSE - 1)], FINE)
        best = min(best, float(d(fine).min()))
    return best


def planned_move(robot: Any, model: CollisionModel, seed: int) -> Any:
    """A seeded line move (test_real_arm_moves' draws) whose start the model finds clear."""
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(seed)
    for _ in range(100):
        q_a, q_b = random_move(robot, rng)
        try:
            model.check_state(q_a)
            return planner.plan(None, robot.fk(q_b), start_joints=q_a)
        except GeodesicPlannerError:
            continue
    raise AssertionError('no move found')


def near_objects(path: Any, model: CollisionModel) -> list[SceneObject]:
    """A sphere and a box beside the tool's line (at s = 0.37 and 0.71): each at the first offset
    (8 cm on, by 1 cm, on either side across the motion) where the arm passes 1-2 cm beyond the
    padding from it (the library's distances on 201 samples: the set-up, not the oracle)."""
    s = np.array([0.37, 0.71])
    T = path.ee_poses(s)
    along = path.ee_poses(np.array([1.0]))[0, :3, 3] - path.ee_poses(np.array([0.0]))[0, :3, 3]
    side = np.cross(along, T[0, :3, 2])
    side /= np.linalg.norm(side)
    qs = path.evaluate(np.linspace(0.0, 1.0, 201), order=0)[0]
    own = model.distances(qs)[0]

    def clear(o: SceneObject) -> bool:      # where the object is the closest, 1 cm beyond the padding
        d = model.with_objects([o]).distances(qs)[0]
        return bool(np.all((d > model.padding + 0.01) | (d == own)))
    shapes = [('ball', Shape('sphere', (0.04,)), np.eye(4)), ('crate', Shape('box', (0.06, 0.08, 0.1)), rot_z(0.4))]
    out = []
    for (name, shape, turn), T_k in zip(shapes, T):
        for gap in np.arange(0.08, 0.6, 0.01):
            candidates = [SceneObject(name, shape, trans(*(T_k[:3, 3] + sign * gap * side)) @ turn) for sign in (1, -1)]
            fits = [o for o in candidates if clear(o)]
            if fits:
                out.append(fits[0])
                break
    assert len(out) == 2
    return out


def planar_case() -> tuple[Any, CollisionModel, Any]:
    """The planar 3R's line (test_collision's line_path) past a post above its plane and a box."""
    robot = load_robot('planar_3r')
    path = GeodesicPlanner(robot).plan(trans(0.5, 1.0) @ rot_z(np.pi / 2), trans(1.5, 1.0) @ rot_z(np.pi / 2))
    post = SceneObject('post', Shape('sphere', (0.03,)), trans(0.9317, 0.6, 0.13))
    box = SceneObject('box', Shape('box', (0.1, 0.1, 0.1)), trans(1.3, 1.17, 0.0) @ rot_z(0.3))
    return path, CollisionModel.for_robot(robot).with_objects([post, box]), capsule_oracle(robot)


@pytest.fixture(scope='module')
def cases() -> dict[str, tuple[Any, CollisionModel, Any]]:
    """name -> (path, model with its scene, the oracle's placement of the robot's bodies)."""
    out = {'planar_3r + post, box': planar_case()}
    ur5e = load_robot('ur5e')
    model = CollisionModel.for_robot(ur5e)
    path = planned_move(ur5e, model, 3701)
    out['ur5e self'] = (path, model, capsule_oracle(ur5e))
    out['ur5e + ball, crate'] = (path, model.with_objects(near_objects(path, model)), capsule_oracle(ur5e))
    ur5 = load_robot(str(UR5_URDF), base_link='base_link', tip_link='tool0')
    ur5_model = CollisionModel.for_robot(ur5, UR5_URDF.read_text(), package_dirs=[str(MESHES)],
                                         srdf=UR5_SRDF.read_text())
    place = hull_oracle(CoalOracle(ur5.joint_names))
    path = planned_move(ur5, ur5_model, 3702)
    out['ur5 meshes self'] = (path, ur5_model, place)
    out['ur5 meshes + ball, crate'] = (path, ur5_model.with_objects(near_objects(path, ur5_model)), place)
    return out


CASES = ['planar_3r + post, box', 'ur5e self', 'ur5e + ball, crate', 'ur5 meshes self', 'ur5 meshes + ball, crate']


@pytest.mark.parametrize('name', CASES)
def test_min_clearance_is_within_1mm_below_a_dense_oracle(cases, name: str) -> None:
    path, model, place = cases[name]
    try:
        found = check_trajectory(model, path.timed())
    except CollisionError as err:
        raise AssertionError(f'the case must be clear: {err}') from err
    truth = oracle_min(model, place, path)
    assert truth > model.padding, truth
    assert CLEARANCE_RESOLUTION == BAND
    assert found.min_clearance <= truth + SLACK, (found.min_clearance, truth)           # never above
    assert found.min_clearance >= truth - BAND - SLACK, (found.min_clearance, truth)    # within 1 mm
    # the closest exact distance found, at the pair and place named, brackets the truth from above
    assert truth - SLACK <= found.closest <= found.min_clearance + BAND + SLACK, (found.closest, truth)
    q = path.evaluate(np.array([found.fraction]), order=0)[0][0]
    bodies = {**place(q), **{o.id: scene_geometry(o) for o in model.objects}}
    at = coal.distance(*bodies[found.pair[0]], *bodies[found.pair[1]], coal.DistanceRequest(), coal.DistanceResult())
    assert abs(at - found.closest) <= SLACK, (at, found.closest, found.pair)
    summary = found.summary()
    assert f"'{found.pair[0]}'" in summary and f"'{found.pair[1]}'" in summary, summary
    assert f'{100 * found.fraction:.1f} % of the way' in summary and f'{found.min_clearance:.4f} m' in summary


@pytest.mark.parametrize('name', CASES)
def test_min_clearance_is_the_paths_whatever_the_time_law(cases, name: str) -> None:
    path, model, _ = cases[name]
    fast, slow = path.timed(), path.timed(max_tool_speed=0.05)
    assert slow.duration > 1.5 * fast.duration                     # another time law indeed
    a, b = check_trajectory(model, fast), check_trajectory(model, slow)
    assert (a.min_clearance, a.closest, a.pair, a.fraction) == (b.min_clearance, b.closest, b.pair, b.fraction)
    assert a.summary() == b.summary()
    # the place as each trajectory's time
    for traj, found in ((fast, a), (slow, b)):
        assert 0.0 <= found.time <= traj.duration
        assert abs(float(traj.s_of_t(found.time)[0][0]) - found.fraction) <= 1e-9
    # deferred (the node: after publishing) and at once agree bit for bit
    late = check_trajectory(model, slow, refine=False).refined()
    assert (late.min_clearance, late.pair, late.fraction) == (a.min_clearance, a.pair, a.fraction)
