"""CIRC: the arc's geometry against exact circles, the tool on the circle, every refusal.

Oracles: circles built from a known centre, radius and plane (the library gets only three points,
or two and the centre); the tool's distance from that centre and from that plane, and its
orientation against the slerp computed here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from geodesic_planner import load_robot
from geodesic_planner.core.circ import (ARC_TOLERANCE, RADIUS_TOLERANCE, arc_about, arc_through,
                                        plan_arc)
from geodesic_planner.core.errors import RequestError
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
