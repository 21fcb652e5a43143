"""Baselines: the paper's cubic-polynomial method and Cartesian line + IK at every sample.

Oracles: cubic Hermite coefficients worked out by hand on a one-joint arm, closed-form planar 3R
inverse kinematics written here (independent of geodesic_planner.core.ik), and the line + slerp poses.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from geodesic_planner import chain_from_dh, load_robot
from geodesic_planner.core.baselines import (
    CartesianIKPath,
    PolynomialPath,
    cartesian_ik_path,
    line_twist,
    polynomial_path,
)
from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.transforms import line_slerp, pose_error


def yaw_pose(x: float, y: float, yaw: float) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    T[0, 3], T[1, 3] = x, y
    return T


def ik_3r(T: np.ndarray, seed: np.ndarray | None = None) -> np.ndarray:
    """Closed-form planar 3R IK (links 1 m), elbow branch theta2 > 0."""
    phi = math.atan2(T[1, 0], T[0, 0])
    wx, wy = T[0, 3] - math.cos(phi), T[1, 3] - math.sin(phi)
    t2 = math.acos((wx * wx + wy * wy - 2.0) / 2.0)
    t1 = math.atan2(wy, wx) - math.atan2(math.sin(t2), 1.0 + math.cos(t2))
    return np.array([t1, t2, phi - t1 - t2])


PAPER_A = yaw_pose(2.5, 1.5, math.atan2(0.5, 0.866))
PAPER_B = yaw_pose(1.5, 2.5, math.atan2(0.7, 0.714))


# ------------------------------------------------------------------ one-joint arm, by hand
def test_polynomial_one_joint_arm_hand_checked():
    """1R arm, link 1 m, from q = 0 to q = pi/2 with 3 via points.

    The line goes from (1, 0) to (0, 1) with yaw 0 -> pi/2. Twist per unit s: v = (-1, 1, 0),
    w = (0, 0, pi/2). J(q) = (-sin q, cos q, 0, 0, 0, 1)^T, so pinv(J) twist = (sin q + cos q + pi/2) / 2:
        q = 0:    v0 = (1 + pi/2) / 2       = 1.2853981634
        q = pi/4: v1 = (sqrt 2 + pi/2) / 2  = 1.4925049446
        q = pi/2: v2 = (1 + pi/2) / 2       = 1.2853981634
    The middle via point (0.5, 0.5, yaw pi/4) is matched by q = pi/4 (nearest on the circle, exact yaw).
    Segment [0, 0.5], h = 0.5, dq = pi/4:
        c2 = (3 dq / h - 2 v0 - v1) / h = (4.7123889804 - 2.5707963268 - 1.4925049446) / 0.5 = 1.2981754180
        c3 = (-2 dq / h + v0 + v1) / h^2 = (-3.1415926536 + 2.7779031085) / 0.25 = -1.4547581824
        jerk = 6 c3 = -8.7285490944
    By symmetry the second segment has c1 = v1, c2 = -1.2981754180 - 3 c3 h... checked through values.
    """
    robot = chain_from_dh('one_r', [(0.0, 0.0, 1.0, 0.0)], ['revolute'])
    T_a, T_b = robot.fk(np.array([0.0])), robot.fk(np.array([math.pi / 2]))
    calls = []

    def ik(rob, T, seed):
        calls.append(seed.copy())
        return np.array([math.atan2(T[1, 0], T[0, 0])])

    path = polynomial_path(robot, T_a, T_b, np.array([0.0]), n_via=3, ik=ik)
    np.testing.assert_allclose(path.s_via, [0.0, 0.5, 1.0])
    np.testing.assert_allclose(path.q_via[:, 0], [0.0, math.pi / 4, math.pi / 2], atol=1e-12)
    np.testing.assert_allclose(path.dq_via[:, 0], [1.2853981634, 1.4925049446, 1.2853981634], atol=1e-9)
    np.testing.assert_allclose(calls[0], [0.0])          # seeded from the previous via point
    np.testing.assert_allclose(calls[1], [math.pi / 4])
    c = path.coefficients()
    assert c.shape == (2, 4, 1)
    np.testing.assert_allclose(c[0, :, 0], [0.0, 1.2853981634, 1.2981754180, -1.4547581824], atol=1e-9)
    # Second segment: starts at pi/4 with v1; the same hand formulas.
    h, dq, v1, v2 = 0.5, math.pi / 4, 1.4925049446, 1.2853981634
    c2 = (3 * dq / h - 2 * v1 - v2) / h
    c3 = (-2 * dq / h + v1 + v2) / h**2
    np.testing.assert_allclose(c[1, :, 0], [math.pi / 4, v1, c2, c3], atol=1e-9)
    # evaluate(): values and derivatives of the cubics (jerk = 6 c3, piecewise constant).
    s = np.array([0.0, 0.2, 0.5, 0.7, 1.0])
    q, d1, d2, d3 = path.evaluate(s)
    u = 0.2
    assert q[1, 0] == pytest.approx(1.2853981634 * u + 1.2981754180 * u**2 - 1.4547581824 * u**3, abs=1e-9)
    assert d1[1, 0] == pytest.approx(1.2853981634 + 2 * 1.2981754180 * u - 3 * 1.4547581824 * u**2, abs=1e-9)
    assert d2[1, 0] == pytest.approx(2 * 1.2981754180 - 6 * 1.4547581824 * u, abs=1e-9)
    assert d3[0, 0] == pytest.approx(-8.7285490944, abs=1e-8)
    assert d3[1, 0] == pytest.approx(-8.7285490944, abs=1e-8)
    assert d3[3, 0] == pytest.approx(6 * c3, abs=1e-8)
    np.testing.assert_allclose(q[[0, 2, 4], 0], [0.0, math.pi / 4, math.pi / 2], atol=1e-12)


# ------------------------------------------------------------------ planar 3R (paper example)
@pytest.fixture(scope='module')
def robot_3r():
    return load_robot('planar_3r')


def test_polynomial_3r_via_points_on_the_line_with_constant_ee_velocity(robot_3r):
    q_a = ik_3r(PAPER_A)
    path = polynomial_path(robot_3r, PAPER_A, PAPER_B, q_a)   # default IK: geodesic_planner.core.ik
    assert isinstance(path, PolynomialPath)
    assert path.q_via.shape == (11, 3)
    np.testing.assert_allclose(path.s_via, np.linspace(0, 1, 11))
    # Via points: independent closed-form IK of the line + slerp poses.
    poses = line_slerp(PAPER_A, PAPER_B, path.s_via)
    expect = np.array([ik_3r(T) for T in poses])
    np.testing.assert_allclose(path.q_via, expect, atol=1e-9)
    # Paper Table 2 ends.
    np.testing.assert_allclose(path.q_via[0], [0.258, 0.583, -0.317], atol=1e-3)
    np.testing.assert_allclose(path.q_via[-1], [0.969, 0.380, -0.574], atol=1.5e-3)
    # End-effector twist at every via point (ends included, as the paper): J q' = [p_B - p_A; 0 0 dphi].
    twist = line_twist(PAPER_A, PAPER_B)
    dphi = math.atan2(0.7, 0.714) - math.atan2(0.5, 0.866)
    np.testing.assert_allclose(twist, [-1.0, 1.0, 0.0, 0.0, 0.0, dphi], atol=1e-12)
    J = robot_3r.jacobian(path.q_via)
    np.testing.assert_allclose(np.einsum('nij,nj->ni', J, path.dq_via), np.tile(twist, (11, 1)), atol=1e-10)
    # One cubic Hermite per joint and segment: matches q and q' at both ends of each segment.
    q, dq, _, dddq = path.evaluate(path.s_via)
    np.testing.assert_allclose(q, path.q_via, atol=1e-12)
    np.testing.assert_allclose(dq, path.dq_via, atol=1e-12)
    c = path.coefficients()
    h = 0.1
    dQ = np.diff(path.q_via, axis=0)
    v0, v1 = path.dq_via[:-1], path.dq_via[1:]
    np.testing.assert_allclose(c[:, 2], (3 * dQ / h - 2 * v0 - v1) / h, atol=1e-9)
    np.testing.assert_allclose(c[:, 3], (-2 * dQ / h + v0 + v1) / h**2, atol=1e-8)
    # Jerk is piecewise constant: 6 c3 in the middle of each segment.
    mid = path.s_via[:-1] + 0.05
    np.testing.assert_allclose(path.evaluate(mid)[3], 6 * c[:, 3], atol=1e-7)
    # The tool leaves the line between via points (that is the paper's point), but not by much.
    s = np.linspace(0, 1, 1001)
    dp, _ = pose_error(path.ee_poses(s), line_slerp(PAPER_A, PAPER_B, s))
    assert 1e-6 < dp.max() < 5e-3


def test_polynomial_end_velocity_zero_option(robot_3r):
    q_a = ik_3r(PAPER_A)
    path = polynomial_path(robot_3r, PAPER_A, PAPER_B, q_a, end_velocity='zero')
    _, dq, _, _ = path.evaluate(np.array([0.0, 1.0]))
    np.testing.assert_allclose(dq, 0.0, atol=1e-12)
    paper = polynomial_path(robot_3r, PAPER_A, PAPER_B, q_a)
    assert np.abs(paper.dq_via[[0, -1]]).max() > 0.5


def test_polynomial_ik_from_home_when_no_start_joints(robot_3r):
    path = polynomial_path(robot_3r, PAPER_A, PAPER_B)
    np.testing.assert_allclose(path.q_via[0], ik_3r(PAPER_A), atol=1e-9)


def test_cartesian_ik_3r_samples_are_closed_form_ik(robot_3r):
    q_a = ik_3r(PAPER_A)
    path = cartesian_ik_path(robot_3r, PAPER_A, PAPER_B, q_a, samples=100)
    assert isinstance(path, CartesianIKPath)
    np.testing.assert_allclose(path.s_samples, np.linspace(0, 1, 100))
    expect = np.array([ik_3r(T) for T in line_slerp(PAPER_A, PAPER_B, path.s_samples)])
    np.testing.assert_allclose(path.q_samples, expect, atol=1e-9)
    q, dq, ddq, dddq = path.evaluate(path.s_samples)
    np.testing.assert_allclose(q, expect, atol=1e-9)
    assert q.shape == dq.shape == ddq.shape == dddq.shape == (100, 3)
    # Between samples the spline of the exact IK stays close to the line, converging ~h^4.
    s = np.linspace(0, 1, 2001)
    errs = []
    for n in (25, 50, 100):
        p = cartesian_ik_path(robot_3r, PAPER_A, PAPER_B, q_a, samples=n)
        dp, dr = pose_error(p.ee_poses(s), line_slerp(PAPER_A, PAPER_B, s))
        errs.append(dp.max())
    assert errs[2] < 1e-5
    assert errs[0] / errs[2] > 8.0  # at least ~h^1.5 convergence (expected ~h^4 inside, less at ends)
    # The derivative of the spline approximates the exact line speed |p'| = |AB| = sqrt(2).
    J = robot_3r.jacobian(q)
    v = np.einsum('nij,nj->ni', J[:, :3], dq)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), math.sqrt(2.0), rtol=1e-3)


def test_baselines_are_timed_like_geodesics(robot_3r):
    q_a = ik_3r(PAPER_A)
    path = polynomial_path(robot_3r, PAPER_A, PAPER_B, q_a)
    traj = path.timed()
    t, q, dq, ddq = traj.sample(0.01)
    assert t[-1] == traj.duration
    assert np.all(np.abs(dq) <= robot_3r.max_velocity * (1 + 1e-9))
    assert np.all(np.abs(ddq) <= robot_3r.max_acceleration * (1 + 1e-9))
    np.testing.assert_allclose(q[-1], path.q_via[-1], atol=1e-12)


@pytest.mark.parametrize('kwargs, match', [
    ({'n_via': 1}, 'n_via'),
    ({'n_via': 2.5}, 'n_via'),
    ({'end_velocity': 'fast'}, 'end_velocity'),
    ({'q_start': [0.1, 0.2]}, 'q_start'),
    ({'T_start': np.full((4, 4), np.nan)}, 'T_start'),
    ({'T_goal': np.eye(3)}, 'T_goal'),
])
def test_polynomial_bad_arguments(robot_3r, kwargs, match):
    args = {'T_start': PAPER_A, 'T_goal': PAPER_B, 'q_start': ik_3r(PAPER_A)} | kwargs
    with pytest.raises(RequestError, match=match):
        polynomial_path(robot_3r, **args)


def test_cartesian_bad_samples(robot_3r):
    with pytest.raises(RequestError, match='samples'):
        cartesian_ik_path(robot_3r, PAPER_A, PAPER_B, samples=1)
    with pytest.raises(RequestError, match='s: values'):
        cartesian_ik_path(robot_3r, PAPER_A, PAPER_B, samples=5).evaluate(np.array([1.5]))


def test_rrpp_polynomial_follows_nearest_reachable_line():
    """4 joints: via points are least-squares IK; joint rates from the pseudo-inverse."""
    robot = load_robot('rrpp')
    q_a = np.array([0.123, -1.539, 0.276, -0.640])
    q_b = np.array([0.129, -1.629, 0.239, -0.643])
    T_a, T_b = robot.fk(q_a), robot.fk(q_b)
    path = polynomial_path(robot, T_a, T_b, q_a, q_goal=q_b)
    np.testing.assert_allclose(path.q_via[[0, -1]], [q_a, q_b], atol=0)
    J = robot.jacobian(path.q_via)
    # Least squares: the residual of J q' - twist is orthogonal to the range of J.
    r = np.einsum('nij,nj->ni', J, path.dq_via) - path.twist
    np.testing.assert_allclose(np.einsum('nij,ni->nj', J, r), 0.0, atol=1e-10)
    dp, dr = pose_error(robot.fk(path.q_via), line_slerp(T_a, T_b, path.s_via))
    assert dp.max() < 2e-3 and dr.max() < 2e-3
