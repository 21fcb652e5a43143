"""CIRC: the arc's geometry against exact circles, the tool on the circle, every refusal.

Oracles: circles built from a known centre, radius and plane (the library gets only three points,
or two and the centre); the tool's distance from that centre and from that plane, and its
orientation against the slerp computed here; pinocchio's FK of a UR5e URDF (test/pin_oracle.py);
the reach of the UR5e's published DH table (test/urdf_util.py); the same arc on the unrestricted
arm for where a joint limit is passed.
"""
from __future__ import annotations

import math
import re

import numpy as np
import pin_oracle as P
import pytest
import urdf_util as U
from numpy.testing import assert_allclose

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.circ import (ARC_TOLERANCE, MIN_CHORD_OFFSET, RADIUS_TOLERANCE, arc_about,
                                        arc_through, plan_arc)
from geodesic_planner.core.errors import IKError, LimitError, PathFollowError, RequestError
from geodesic_planner.core.kinematics import chain_from_dh
from geodesic_planner.core.motions import MotionItem, plan_item
from geodesic_planner.core.transforms import so3_exp, so3_log


def circle(centre: np.ndarray, radius: float, normal: np.ndarray, start_dir: np.ndarray):
    """theta (rad) -> point on the circle, turning positively about ``normal``."""
    n = normal / np.linalg.norm(normal)
    u = start_dir - (start_dir @ n) * n
    u /= np.linalg.norm(u)
    w = np.cross(n, u)
    return lambda th: centre + radius * (math.cos(th) * u + math.sin(th) * w), n


RNG_CASES = [(np.array([0.3, -0.2, 0.5]), 0.15, np.array([0.2, 0.3, 1.0]), np.array([1.0, 0.0, 0.0])),
             (np.array([-1.0, 2.0, 0.1]), 2.5, np.array([1.0, -1.0, 0.2]), np.array([0.0, 1.0, 0.0]))]


@pytest.mark.parametrize('centre,radius,normal,start_dir', RNG_CASES)
@pytest.mark.parametrize('angles', [(0.0, 0.7, 1.9), (0.0, 2.0, math.radians(250.0)), (0.0, 3.0, 5.9)])
def test_arc_through_three_points_is_their_circle(centre, radius, normal, start_dir, angles) -> None:
    at, n = circle(centre, radius, normal, start_dir)
    arc = arc_through(at(angles[0]), at(angles[1]), at(angles[2]))
    assert_allclose(arc.centre, centre, rtol=0, atol=1e-12 * max(1.0, radius))
    assert arc.radius == pytest.approx(radius, abs=1e-12)
    assert_allclose(arc.normal, n, atol=1e-12)                   # turns from start to interim first
    assert arc.angle == pytest.approx(angles[2], abs=1e-12)       # 250 and 338 degrees: over 180
    s = np.linspace(0.0, 1.0, 101)
    p = arc.derivatives(s)[0]
    assert_allclose(p, np.array([at(angles[2] * x) for x in s]), atol=1e-12 * max(1.0, radius))


def test_arc_about_a_centre_is_the_shorter_arc() -> None:
    at, n = circle(np.array([0.1, 0.2, 0.3]), 0.4, np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 0.0]))
    arc = arc_about(at(0.0), np.array([0.1, 0.2, 0.3]), at(4.0))     # 4 rad one way = 2.28 the other
    assert arc.angle == pytest.approx(2.0 * math.pi - 4.0, abs=1e-12)
    assert_allclose(arc.normal, -n, atol=1e-12)
    assert_allclose(arc.derivatives(np.ones(1))[0][0], at(4.0), atol=1e-12)


def test_arc_about_moves_a_slightly_off_centre_onto_the_bisector() -> None:
    c = np.array([0.0, 0.0, 0.0])
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0 + 0.5 * RADIUS_TOLERANCE, 0.0])
    arc = arc_about(a, c, b)
    p = arc.derivatives(np.array([0.0, 1.0]))[0]
    assert_allclose(p, [a, b], atol=1e-12)                  # meets both ends exactly
    assert np.linalg.norm(arc.centre - c) < RADIUS_TOLERANCE


@pytest.mark.parametrize('make,words', [
    (lambda: arc_through([0, 0, 0], [1, 1, 1], [2, 2, 2]), 'collinear'),
    (lambda: arc_through([0, 0, 0], [0, 0, 0], [1, 0, 0]), 'collinear'),
    (lambda: arc_through([1, 0, 0], [0, 1, 0], [1, 0, 0]), 'full circle'),
    (lambda: arc_about([1, 0, 0], [0, 0, 0], [0, 1.001, 0]), 'different distances'),
    (lambda: arc_about([1, 0, 0], [0, 0, 0], [1, 0, 0]), 'full circle'),
    (lambda: arc_about([1, 0, 0], [0, 0, 0], [-1, 0, 0]), 'opposite'),
])
def test_every_refusal_says_why(make, words) -> None:
    with pytest.raises(RequestError, match=words):
        make()


def test_ur5e_arc_over_180_degrees_stays_on_the_circle_with_the_slerp() -> None:
    robot = load_robot('ur5e')
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T_a = robot.fk(q0)
    centre = T_a[:3, 3] + np.array([0.0, 0.1, 0.02])
    normal = np.array([0.1, 0.0, 1.0])
    n = normal / np.linalg.norm(normal)
    rel = T_a[:3, 3] - centre
    rel_p = rel - (rel @ n) * n                                   # the start's projection
    centre = centre + (rel @ n) * n                               # the centre in the start's plane
    r = float(np.linalg.norm(rel_p))
    at, n = circle(centre, r, normal, rel_p)
    p_i, p_b = at(math.radians(110.0)), at(math.radians(230.0))
    T_b = T_a @ np.block([[so3_exp(np.array([0.2, -0.1, 0.4])), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]])
    T_b[:3, 3] = p_b
    path = plan_arc(robot, q0, T_b, arc_through(T_a[:3, 3], p_i, p_b))
    s = np.linspace(0.0, 1.0, 4001)
    T = robot.fk(path.evaluate(s, 0)[0])
    rel = T[:, :3, 3] - centre
    height = rel @ n
    assert np.abs(height).max() < ARC_TOLERANCE                   # in the plane
    assert np.abs(np.linalg.norm(rel - height[:, None] * n, axis=1) - r).max() < ARC_TOLERANCE
    w = so3_log(T_a[:3, :3].T @ T_b[:3, :3])
    R_slerp = T_a[:3, :3] @ so3_exp(s[:, None] * w)
    assert np.abs(T[:, :3, :3] - R_slerp).max() < ARC_TOLERANCE   # orientation: the slerp at the same s
    # the arc at a constant rate: the tool at theta = 230 deg * s
    assert_allclose(T[:, :3, 3], np.array([at(math.radians(230.0) * x) for x in s]), atol=ARC_TOLERANCE)
    assert_allclose(T[-1], T_b, atol=1e-9)
    traj = path.timed()
    assert traj.duration > 0.0


def test_planar_3r_arc_in_its_plane() -> None:
    robot = load_robot('planar_3r')
    q0 = np.array([0.3, 0.9, 0.6])
    T_a = robot.fk(q0)
    centre = T_a[:3, 3] * (1.0 - 0.3 / np.linalg.norm(T_a[:3, 3]))   # 0.3 m towards the base: in reach
    r = float(np.linalg.norm(T_a[:3, 3] - centre))
    at, _ = circle(centre, r, np.array([0.0, 0.0, 1.0]), T_a[:3, 3] - centre)
    T_b = T_a.copy()
    T_b[:3, 3] = at(1.2)
    c, sn = math.cos(0.3), math.sin(0.3)
    T_b[:3, :3] = T_a[:3, :3] @ np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])
    path = plan_arc(robot, q0, T_b, arc_about(T_a[:3, 3], centre, T_b[:3, 3]))
    p = robot.fk(path.evaluate(np.linspace(0.0, 1.0, 2001), 0)[0])[:, :3, 3]
    assert np.abs(np.linalg.norm(p - centre, axis=1) - r).max() < ARC_TOLERANCE
    assert np.abs(p[:, 2]).max() < 1e-12


Q_UR = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])


def chord_offset(a: np.ndarray, p: np.ndarray, b: np.ndarray) -> float:
    """Distance (m) of p from the straight line through a and b: twice the triangle's area (Heron)
    over the chord."""
    x, y, z = np.linalg.norm(p - a), np.linalg.norm(b - p), np.linalg.norm(b - a)
    k = (x + y + z) * (-x + y + z) * (x - y + z) * (x + y - z)
    return math.sqrt(max(k, 0.0)) / (2.0 * z)


def test_an_interim_point_on_the_rounded_midpoint_is_refused_in_metres() -> None:
    """Issue 36 item 5a: the start-goal midpoint rounded to 6 decimals planned a straight line
    (a circle of 38 km) with status success."""
    robot = load_robot('ur5e')
    T_a = robot.fk(Q_UR)
    T_b = T_a.copy()
    T_b[:3, 3] += [0.0, 0.2, 0.05]
    mid = np.round(0.5 * (T_a[:3, 3] + T_b[:3, 3]), 6)
    offset = chord_offset(T_a[:3, 3], mid, T_b[:3, 3])
    assert 0.0 < offset < 1e-6
    with pytest.raises(RequestError, match=r'the three points are \(nearly\) collinear') as info:
        plan_item(GeodesicPlanner(robot), MotionItem('CIRC', goal=T_b, interim=mid), Q_UR)
    msg = str(info.value)
    assert f'the interim point is {offset:.2g} m from the straight line through start and goal' in msg
    assert f'at least {MIN_CHORD_OFFSET:g} m needed' in msg and MIN_CHORD_OFFSET == 1e-4


@pytest.mark.parametrize('scale', [0.999, 0.5])
def test_a_centre_nearly_between_start_and_goal_is_refused_in_metres(scale: float) -> None:
    """Start and goal on a circle of 0.2 m, nearly opposite: the centre is ``scale`` times the
    tolerance from their chord."""
    def ends(h: float) -> tuple[np.ndarray, np.ndarray]:
        half = math.sqrt(0.2**2 - h**2)
        return np.array([half, h, 0.3]), np.array([-half, h, 0.3])
    c = np.array([0.0, 0.0, 0.3])
    h = scale * MIN_CHORD_OFFSET
    with pytest.raises(RequestError, match='opposite about it') as info:
        arc_about(ends(h)[0], c, ends(h)[1])
    assert f'the centre is {h:.2g} m from the straight line' in str(info.value)
    h = 1.5 * MIN_CHORD_OFFSET                                    # beyond the tolerance: planned
    arc = arc_about(ends(h)[0], c, ends(h)[1])
    assert arc.angle == pytest.approx(math.pi - 2.0 * math.asin(h / 0.2), abs=1e-9)


def test_an_interim_point_just_beyond_the_tolerance_is_planned_on_its_circle() -> None:
    """The interim point 1.5e-4 m from a 0.2 m chord: a circle of 33 m, built here, followed to
    1e-8 m by pinocchio's FK of the UR5e URDF; the interim point is the arc's middle (s = 0.5)."""
    from test_real_arms import ARMS, arm
    _, base, tip, _ = ARMS['ur5e']
    _, robot, m = arm('ur5e')
    kin = P.Kinematics(m, robot.joint_names, base, tip)
    T_a = kin.pose_and_jacobian(Q_UR)[0]
    d = np.array([0.0, 0.96, 0.28])                               # chord direction (unit)
    v = np.array([0.6, -0.224, 0.768])                            # from the chord towards the centre
    v -= (v @ d) * d
    v /= np.linalg.norm(v)
    h, half = 1.5 * MIN_CHORD_OFFSET, 0.1
    R = (h * h + half * half) / (2.0 * h)
    mid = T_a[:3, 3] + half * d
    centre = mid + (R - h) * v
    interim = centre - R * v
    p_b = T_a[:3, 3] + 2.0 * half * d
    n = np.cross(d, v)
    T_b = T_a @ np.block([[so3_exp(np.array([0.1, 0.0, -0.2])), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]])
    T_b[:3, 3] = p_b
    assert chord_offset(T_a[:3, 3], interim, p_b) == pytest.approx(h, rel=1e-6)
    path = plan_item(GeodesicPlanner(robot), MotionItem('CIRC', goal=T_b, interim=interim), Q_UR)
    s = np.linspace(0.0, 1.0, 1001)
    q = path.evaluate(s, 0)[0]
    p = np.array([kin.pose_and_jacobian(qk)[0][:3, 3] for qk in q])
    rel = p - centre
    height = rel @ n
    assert np.abs(height).max() < ARC_TOLERANCE
    assert np.abs(np.linalg.norm(rel - height[:, None] * n, axis=1) - R).max() < ARC_TOLERANCE
    assert np.linalg.norm(p[500] - interim) < ARC_TOLERANCE
    assert np.linalg.norm(p[-1] - p_b) < ARC_TOLERANCE


def test_a_circ_goal_out_of_reach_is_an_ik_error_with_the_distance() -> None:
    """Issue 36 item 5b: was PathFollowError '(a joint limit, a singularity or out of reach)'. The
    goal is farther from the shoulder than the UR5e's links reach (the DH table's lengths)."""
    robot = load_robot('ur5e')
    T_a = robot.fk(Q_UR)
    T_b = T_a.copy()
    T_b[:3, 3] += [-0.9, 0.0, 0.0]
    interim = 0.5 * (T_a[:3, 3] + T_b[:3, 3]) + [0.0, 0.1, 0.1]
    lengths = sum(abs(row[1]) + abs(row[2]) for row in U.UR5E_DH[1:])
    beyond = np.linalg.norm(T_b[:3, 3] - [0.0, 0.0, U.UR5E_DH[0][1]]) - lengths
    assert beyond > 0.3
    with pytest.raises(IKError, match='is out of reach of robot') as info:
        plan_item(GeodesicPlanner(robot), MotionItem('CIRC', goal=T_b, interim=interim), Q_UR)
    assert not isinstance(info.value, PathFollowError)
    found = re.search(r'the nearest reachable pose is ([0-9.e+-]+) m and', str(info.value))
    assert found is not None, str(info.value)
    assert float(found.group(1)) >= beyond


def test_an_arc_through_a_joint_limit_names_the_joint_and_the_fraction() -> None:
    """The 230 degree arc of the UR5e test above on an arm whose elbow stops at 1.75 rad: the
    elbow rises to 1.86 and back on the unrestricted arm; the refusal is where it reaches 1.75."""
    robot = load_robot('ur5e')
    T_a = robot.fk(Q_UR)
    centre = T_a[:3, 3] + np.array([0.0, 0.1, 0.02])
    n = np.array([0.1, 0.0, 1.0]) / np.linalg.norm([0.1, 0.0, 1.0])
    rel = T_a[:3, 3] - centre
    centre = centre + (rel @ n) * n
    at, _ = circle(centre, float(np.linalg.norm(T_a[:3, 3] - centre)), n, T_a[:3, 3] - centre)
    T_b = T_a @ np.block([[so3_exp(np.array([0.2, -0.1, 0.4])), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]])
    T_b[:3, 3] = at(math.radians(230.0))
    arc = arc_through(T_a[:3, 3], at(math.radians(110.0)), T_b[:3, 3])
    s = np.linspace(0.0, 1.0, 20001)
    elbow = plan_arc(robot, Q_UR, T_b, arc).evaluate(s, 0)[0][:, 2]
    limit = 1.75
    k = int(np.argmax(elbow > limit))
    assert k > 0 and elbow.max() > limit + 0.05 and elbow[-1] < limit
    expected = float(np.interp(limit, elbow[k - 1:k + 1], s[k - 1:k + 1]))
    upper = np.full(6, 2 * np.pi)
    upper[2] = limit
    stop = chain_from_dh('ur5e_stop', U.UR5E_DH, ['revolute'] * 6, joint_names=robot.joint_names,
                         lower=np.full(6, -2 * np.pi), upper=upper)
    assert np.allclose(stop.fk(Q_UR), T_a, atol=1e-14)
    with pytest.raises(LimitError, match=r"CIRC: the arc cannot be followed by robot 'ur5e_stop': joint "
                       r"'elbow_joint' would pass its limit 1\.75 at") as info:
        plan_arc(stop, Q_UR, T_b, arc)
    err = info.value
    assert isinstance(err, PathFollowError) and abs(err.fraction - expected) < 1e-3, (err.fraction, expected)
    assert f'at {100 * err.fraction:.3g} % of the way' in str(err)
