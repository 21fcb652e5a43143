"""Sequences of LIN, CIRC and PTP with blends (Pilz's MotionSequenceRequest rules).

Oracles: the line and the circle the items are built from (their geometry is computed here, not
read from the planner), forward kinematics of the timed motion, and the rules' arithmetic.
"""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.blend import BlendedPath
from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.motions import MotionItem, plan_sequence
from geodesic_planner.core.transforms import segment_distance

Q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
R = 0.03


def shifted(T: np.ndarray, dp) -> np.ndarray:
    out = T.copy()
    out[:3, 3] = T[:3, 3] + np.asarray(dp, dtype=float)
    return out


@pytest.fixture(scope='module')
def lin_circ_lin():
    """ur5e: LIN 15 cm along x, CIRC a quarter circle about a centre 10 cm along y, LIN back
    along y; blends of 3 cm at both inner goals."""
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    T0 = robot.fk(Q0)
    T1 = shifted(T0, [0.15, 0.0, 0.0])
    centre = T1[:3, 3] + np.array([0.0, 0.1, 0.0])
    T2 = shifted(T1, [0.1, 0.1, 0.0])                     # a quarter turn about the centre
    T3 = shifted(T2, [0.0, 0.15, -0.05])
    items = [MotionItem('LIN', goal=T1, blend_radius=R), MotionItem('CIRC', goal=T2, centre=centre, blend_radius=R),
             MotionItem('LIN', goal=T3)]
    path = plan_sequence(planner, items, start_joints=Q0)
    return robot, path, (T0, T1, T2, T3), centre


def test_blends_stay_within_the_radius_without_stopping(lin_circ_lin) -> None:
    robot, path, poses, _ = lin_circ_lin
    assert isinstance(path, BlendedPath) and len(path.zones) == 2
    traj = path.timed()
    t = np.linspace(0.0, traj.duration, 4001)
    q, dq, _ = traj.at_time(t)
    p = robot.fk(q)[:, :3, 3]
    speed = np.linalg.norm(np.einsum('nij,nj->ni', robot.jacobian(q)[:, :3], dq), axis=1)
    s = traj.s_of_t(t)[0]
    for zone, T in zip(path.zones, poses[1:3]):
        inside = (s >= zone.s_start) & (s <= zone.s_end)
        assert inside.sum() > 10
        assert np.linalg.norm(p[inside] - T[:3, 3], axis=1).max() <= R * (1 + 1e-9)
        assert speed[inside].min() > 0.05 * speed.max()            # no stop inside the blend


def test_outside_the_blends_the_geometry_is_exact(lin_circ_lin) -> None:
    robot, path, (T0, T1, T2, T3), centre = lin_circ_lin
    z1, z2 = path.zones
    edges = [(0.0, z1.s_start), (z1.s_end, z2.s_start), (z2.s_end, 1.0)]
    s0 = np.linspace(*edges[0], 400)
    p0 = robot.fk(path.evaluate(s0, 0)[0])[:, :3, 3]
    assert segment_distance(p0, T0[:3, 3], T1[:3, 3]).max() < 1e-8           # LIN: on the line
    s1 = np.linspace(*edges[1], 400)
    p1 = robot.fk(path.evaluate(s1, 0)[0])[:, :3, 3]
    assert np.abs(np.linalg.norm(p1 - centre, axis=1) - 0.1).max() < 1e-8     # CIRC: on the circle
    assert np.abs(p1[:, 2] - T1[2, 3]).max() < 1e-8                            # in its plane
    s2 = np.linspace(*edges[2], 400)
    p2 = robot.fk(path.evaluate(s2, 0)[0])[:, :3, 3]
    assert segment_distance(p2, T2[:3, 3], T3[:3, 3]).max() < 1e-8


def test_a_bad_item_fails_the_sequence_with_its_index() -> None:
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    T0 = robot.fk(Q0)
    T1 = shifted(T0, [0.1, 0.0, 0.0])
    items = [MotionItem('LIN', goal=T1),
             MotionItem('CIRC', goal=shifted(T1, [0.1, 0.0, 0.0]), interim=T1[:3, 3] + [0.05, 0.0, 0.0])]
    with pytest.raises(RequestError, match=r'sequence item 1 \(CIRC\): .*collinear'):
        plan_sequence(planner, items, start_joints=Q0)
    with pytest.raises(RequestError, match=r'sequence item 0 \(SPLINE\): motion must be one of'):
        plan_sequence(planner, [MotionItem('SPLINE', goal=T1)], start_joints=Q0)


def test_pilz_radius_rules() -> None:
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    T0 = robot.fk(Q0)
    T1, T2 = shifted(T0, [0.1, 0.0, 0.0]), shifted(T0, [0.1, 0.08, 0.0])
    with pytest.raises(RequestError, match='last item'):
        plan_sequence(planner, [MotionItem('LIN', goal=T1, blend_radius=0.01)], start_joints=Q0)
    # goals 0.08 m apart: radii 0.05 + 0.04 overlap
    items = [MotionItem('LIN', goal=T1, blend_radius=0.05), MotionItem('LIN', goal=T2, blend_radius=0.04),
             MotionItem('LIN', goal=T0)]
    with pytest.raises(RequestError, match=r'sequence item 0: .*overlap'):
        plan_sequence(planner, items, start_joints=Q0)


def test_ptp_without_inertias_says_it_took_the_joint_line() -> None:
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    q1 = Q0 + 0.3
    path = plan_sequence(planner, [MotionItem('PTP', goal_joints=q1)], start_joints=Q0)
    s = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(path.evaluate(s, 0)[0], Q0 + s[:, None] * 0.3, atol=1e-12)
    assert path.notes and 'joint line' in path.notes[0]


def test_a_ptp_blends_into_a_lin() -> None:
    """Blends join any two item types: a PTP (joint line) blended into a LIN, within the radius
    and without the joints resting; the LIN's exact portion stays on its line."""
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    q1 = Q0 + np.array([0.25, -0.1, 0.15, 0.1, -0.2, 0.1])
    T1 = robot.fk(q1)
    T2 = shifted(T1, [0.0, 0.15, 0.0])
    path = plan_sequence(planner, [MotionItem('PTP', goal_joints=q1, ptp='joint_line', blend_radius=0.03),
                                   MotionItem('LIN', goal=T2)], start_joints=Q0)
    assert isinstance(path, BlendedPath) and len(path.zones) == 1
    zone = path.zones[0]
    assert zone.max_distance <= 0.03 * (1 + 1e-9)
    traj = path.timed()
    t = np.linspace(0.0, traj.duration, 3001)
    s = traj.s_of_t(t)[0]
    _, dq, _ = traj.at_time(t)
    inside = (s >= zone.s_start) & (s <= zone.s_end)
    assert np.linalg.norm(dq[inside], axis=1).min() > 0.05 * np.linalg.norm(dq, axis=1).max()
    s_lin = np.linspace(zone.s_end, 1.0, 300)
    p = robot.fk(path.evaluate(s_lin, 0)[0])[:, :3, 3]
    assert segment_distance(p, T1[:3, 3], T2[:3, 3]).max() < 1e-8
