"""Around obstacles, first step (issue 39, section 2): OMPL's RRTConnect finds a way in joint space.

Oracle: the way's segments sampled densely (every 0.5 mrad of the largest joint move) by the
model's exact distances, each above the padding; the direct joint line is refused by the same
continuous check (the premise: the box blocks it).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from geodesic_planner import load_robot
from geodesic_planner.core.around import find_way
from geodesic_planner.core.cancel import CancelToken, Cancelled, cancellable
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import PathInCollisionError
from geodesic_planner.core.kinematics import trans
from geodesic_planner.core.ptp import JointLinePath

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
MESHES = DATA / 'meshes'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
UR5_SRDF = MESHES / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
Q_A = np.array([0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
Q_B = np.array([-0.8, -1.2, 1.4, -1.8, -1.57, 0.0])


@pytest.fixture(scope='module')
def blocked():
    robot = load_robot(str(UR5_URDF), tip_link='tool0')
    model = CollisionModel.for_robot(robot, UR5_URDF.read_text(), package_dirs=[str(MESHES)],
                                     srdf=UR5_SRDF.read_text())
    mid = robot.fk(0.5 * (Q_A + Q_B))[:3, 3]
    box = SceneObject('box', Shape('box', (0.12, 0.12, 0.12)), trans(*mid))
    return robot, model.with_objects([box])


def test_find_way_goes_around_a_box_the_joint_line_hits(blocked) -> None:
    robot, model = blocked
    with pytest.raises(PathInCollisionError):
        model.check_path(JointLinePath(robot, Q_A, Q_B))
    way = find_way(model, Q_A, Q_B, 5.0, seed=1)
    assert np.array_equal(way.waypoints[0], Q_A) and np.array_equal(way.waypoints[-1], Q_B)
    assert len(way.waypoints) >= 3
    for a, b in zip(way.waypoints[:-1], way.waypoints[1:]):
        k = max(int(np.abs(b - a).max() / 5e-4), 2)
        q = a + np.linspace(0.0, 1.0, k)[:, None] * (b - a)
        d, _ = model.distances(q)
        assert d.min() > model.padding, d.min()


def test_a_cancelled_plan_stops_the_search(blocked) -> None:
    robot, model = blocked
    token = CancelToken()
    token.cancel('plan_timeout passed')
    with cancellable(token), pytest.raises(Cancelled, match='plan_timeout passed'):
        find_way(model, Q_A, Q_B, 5.0, seed=1)


# ---------------------------------------------------------------- made good, and the PTP item

def _pin_energy(q: np.ndarray, s: np.ndarray) -> float:
    """The path's action int q'^T M q' ds from pinocchio's crba on the URDF (trapezoid on the
    samples' finite differences: an oracle independent of the planner's quadrature and mass model)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(UR5_URDF))
    data = model.createData()
    dq = np.diff(q, axis=0) / np.diff(s)[:, None]
    mid = 0.5 * (q[1:] + q[:-1])
    e = 0.0
    for qm, v, h in zip(mid, dq, np.diff(s)):
        M = pin.crba(model, data, qm)
        M = np.triu(M) + np.triu(M, 1).T
        e += float(v @ M @ v) * h
    return e


def _dense_clear(model, q: np.ndarray) -> float:
    """The smallest coal distance over configurations q (N, dof)."""
    return float(model.distances(q)[0].min())


@pytest.fixture(scope='module')
def mass():
    from geodesic_planner.core.ptp import UrdfMass
    robot = load_robot(str(UR5_URDF), tip_link='tool0')
    return UrdfMass(robot, UR5_URDF.read_text())


def test_a_blocked_ptp_item_goes_around_smooth_and_clear_everywhere(blocked, mass) -> None:
    from geodesic_planner.core.around import AroundOptions
    from geodesic_planner.core.motions import MotionItem, plan_sequence
    from geodesic_planner.core.planner import GeodesicPlanner

    robot, model = blocked
    path = plan_sequence(GeodesicPlanner(robot), [MotionItem('PTP', goal_joints=Q_B)], start_joints=Q_A,
                         mass=mass, around=AroundOptions(model, 1.0))
    assert 'went around obstacles' in path.notes[0] and 'min_clearance' in path.notes[0]
    s = np.linspace(0.0, 1.0, 4001)
    q, dq, ddq, dddq = path.evaluate(s)
    assert np.allclose(q[0], Q_A, atol=1e-12) and np.allclose(q[-1], Q_B, atol=1e-12)
    assert all(np.all(np.isfinite(a)) for a in (dq, ddq, dddq))
    assert _dense_clear(model, q) >= model.padding
    assert np.all(q >= robot.lower) and np.all(q <= robot.upper)
    # smooth: the third derivative is continuous (finite differences of the second agree with it)
    h = s[1] - s[0]
    assert np.allclose(np.diff(ddq, axis=0) / h, 0.5 * (dddq[1:] + dddq[:-1]), atol=1e-3 * (1 + np.abs(dddq).max()))


def test_energy_below_ompl_simplified_on_a_fixed_scene(blocked, mass) -> None:
    from geodesic_planner.core.around import plan_around

    robot, model = blocked
    found = plan_around(model, mass.terms, Q_A, Q_B, 2.0)
    s = np.linspace(0.0, 1.0, 2001)
    ours = _pin_energy(found.path.evaluate(s, 0)[0], s)
    ompl = find_way(model, Q_A, Q_B, 2.0, simplify=1.0)      # RRTConnect + OMPL's simplifier
    # the polyline at constant speed in the mass metric: its energy is its length squared
    length = 0.0
    for a, b in zip(ompl.waypoints[:-1], ompl.waypoints[1:]):
        u = np.linspace(0.0, 1.0, 401)
        e = _pin_energy(a + u[:, None] * (b - a), u)
        length += np.sqrt(e)
    assert ours < 0.8 * length ** 2, (ours, length ** 2)


def test_off_the_blocked_ptp_is_the_direct_path_and_refused(blocked, mass) -> None:
    from geodesic_planner.core.motions import MotionItem, plan_sequence
    from geodesic_planner.core.planner import GeodesicPlanner

    robot, model = blocked
    path = plan_sequence(GeodesicPlanner(robot), [MotionItem('PTP', goal_joints=Q_B)], start_joints=Q_A, mass=mass)
    with pytest.raises(PathInCollisionError):
        model.check_path(path)


def test_no_way_is_refused_within_the_budget(blocked, mass, tmp_path) -> None:
    """The joint limits box the move in (0.05 rad around the ends), the box blocks it: no way."""
    import time
    import xml.etree.ElementTree as ET

    from geodesic_planner.core.around import AroundOptions
    from geodesic_planner.core.errors import PlanningFailedError
    from geodesic_planner.core.motions import MotionItem, plan_sequence
    from geodesic_planner.core.planner import GeodesicPlanner

    robot, model = blocked
    lo, hi = np.minimum(Q_A, Q_B) - 0.05, np.maximum(Q_A, Q_B) + 0.05
    tree = ET.parse(UR5_URDF)
    for joint in tree.getroot().findall('joint'):
        if joint.get('name') in robot.joint_names:
            i = robot.joint_names.index(joint.get('name'))
            joint.find('limit').set('lower', repr(float(lo[i])))
            joint.find('limit').set('upper', repr(float(hi[i])))
    urdf = tmp_path / 'ur5_boxed.urdf'
    tree.write(urdf)
    boxed = load_robot(str(urdf), tip_link='tool0')
    assert np.allclose(boxed.lower, lo)
    tight = CollisionModel.for_robot(boxed, urdf.read_text(), package_dirs=[str(MESHES)],
                                     srdf=UR5_SRDF.read_text()).with_objects(model.objects)
    t0 = time.monotonic()
    with pytest.raises(PlanningFailedError, match=r'no collision-free path found in 0\.5 s'):
        plan_sequence(GeodesicPlanner(boxed), [MotionItem('PTP', goal_joints=Q_B)], start_joints=Q_A, mass=mass,
                      around=AroundOptions(tight, 0.5))
    assert time.monotonic() - t0 < 0.5 + 0.5


def test_a_goal_in_collision_keeps_its_code(blocked, mass) -> None:
    from geodesic_planner.core.around import AroundOptions
    from geodesic_planner.core.errors import GoalInCollisionError
    from geodesic_planner.core.motions import MotionItem, plan_sequence
    from geodesic_planner.core.planner import GeodesicPlanner

    robot, model = blocked
    q_mid = 0.5 * (Q_A + Q_B)        # the box sits at the tool there
    with pytest.raises(GoalInCollisionError):
        plan_sequence(GeodesicPlanner(robot), [MotionItem('PTP', goal_joints=q_mid)], start_joints=Q_A, mass=mass,
                      around=AroundOptions(model, 0.5))


def test_a_cancelled_ptp_item_stops(blocked, mass) -> None:
    from geodesic_planner.core.around import AroundOptions
    from geodesic_planner.core.motions import MotionItem, plan_sequence
    from geodesic_planner.core.planner import GeodesicPlanner

    robot, model = blocked
    token = CancelToken()
    token.cancel('client gone')
    with cancellable(token), pytest.raises(Cancelled, match='client gone'):
        plan_sequence(GeodesicPlanner(robot), [MotionItem('PTP', goal_joints=Q_B)], start_joints=Q_A, mass=mass,
                      around=AroundOptions(model, 5.0))


def test_the_obstacle_term_finds_every_pair_coal_finds_near(blocked) -> None:
    """contacts() skips pairs by bounds (bounding spheres, and a body's sphere against a box
    itself): at random configurations among a table, a wall and the box, it returns exactly the
    pairs whose coal distance (computed here for every pair) is below the threshold."""
    import coal

    from geodesic_planner.core.obstacle_penalty import contacts

    robot, model = blocked
    scene = model.with_objects([*model.objects,
                                SceneObject('table', Shape('box', (1.4, 1.4, 0.04)), trans(0.3, 0.0, -0.03)),
                                SceneObject('wall', Shape('box', (0.03, 1.0, 1.0)), trans(0.55, 0.0, 0.4))])
    rng = np.random.default_rng(7)
    qs = rng.uniform(np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi), (60, robot.dof))
    below = 0.05
    found = contacts(scene, qs, below)
    table = scene.pair_table
    P = scene.body_frames(qs)[0]
    expected = set()
    for n in range(len(qs)):
        for p, (i, j) in enumerate(zip(table.first, table.second)):
            r = coal.DistanceResult()
            d = coal.distance(table.geometry[i], coal.Transform3s(P[n, i, :3, :3], P[n, i, :3, 3]),
                              table.geometry[j], coal.Transform3s(P[n, j, :3, :3], P[n, j, :3, 3]),
                              coal.DistanceRequest(), r)
            if d < below:
                expected.add((n, p))
    assert len(expected) > 20
    assert set(zip(found.n.tolist(), found.pair.tolist())) == expected
