"""Piecewise geodesics through via points (paper eq. 10).

Oracles: every via pose reached exactly (q at the breakpoint = the IK of the via pose on the
start's branch, FK = the pose); metric speed equal on both sides of every junction and equal to
the total length, which for a 6-joint arm is Σ √(|Δp|² + 2θ²) over the pieces; each piece a
geodesic (line + slerp linear in s on its interval for 6-joint arms); an arc through 12 poses
followed chord by chord.
"""
from __future__ import annotations

import numpy as np
import pytest
import urdf_util as U
from numpy.testing import assert_allclose
from planning_checks import expect_error

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import IKError, RequestError
from geodesic_planner.core.metric import Metric


def piece_length(T_a, T_b):
    Rrel = T_a[:3, :3].T @ T_b[:3, :3]
    theta = np.arccos(np.clip((np.trace(Rrel) - 1) / 2, -1, 1))
    return float(np.sqrt(np.sum((T_b[:3, 3] - T_a[:3, 3]) ** 2) + 2 * theta**2))


def metric_speed(path, s):
    """sqrt(q'ᵀ G q') along a path (paper metric), (len(s),)."""
    q, dq, _, _ = path.evaluate(s)
    return np.sqrt(np.einsum('ni,nij,nj->n', dq, Metric().tensor(path.robot, q), dq))


@pytest.fixture(scope='module')
def ur5e():
    robot = load_robot('ur5e')
    return robot, GeodesicPlanner(robot)


@pytest.fixture(scope='module')
def three_poses(ur5e):
    robot, _ = ur5e
    q0 = robot.home + np.array([0.3, -0.2, 0.2, 0.1, 0.3, 0.2])
    T0 = U.ur5e_fk_batch(q0[None])[0]
    T1 = T0.copy()
    T1[:3, 3] += [0.1, 0.05, -0.05]
    T1[:3, :3] = T0[:3, :3] @ U.axis_angle([1, 2, 0], 0.3)
    T2 = T1.copy()
    T2[:3, 3] += [-0.05, 0.1, 0.05]
    T2[:3, :3] = T1[:3, :3] @ U.axis_angle([0, 1, 1], -0.2)
    return q0, [T0, T1, T2]


@pytest.fixture(scope='module')
def via_path(ur5e, three_poses):
    _, planner = ur5e
    q0, poses = three_poses
    return planner.plan_through(poses, start_joints=q0)


def test_via_point_reached_exactly(via_path, three_poses):
    q0, (T0, T1, T2) = three_poses
    path = via_path
    assert path.breakpoints.shape == (3,) and path.breakpoints[0] == 0.0 and path.breakpoints[-1] == 1.0
    b = path.breakpoints[1]
    q_b = path.evaluate(np.array([b]))[0][0]
    assert_allclose(q_b, path.via_joints[1], atol=1e-12)
    assert np.abs(U.pose_residual(U.ur5e_fk_batch(q_b[None])[0], T1)).max() < 1e-9
    # = IK of the via pose on the start's branch (independent Newton, continued along the line)
    q_oracle = U.continuation_ik(U.ur5e_fk_batch, U.line_slerp_oracle(T0, T1, np.linspace(0, 1, 21)), q0)[-1]
    assert_allclose(q_b, q_oracle, atol=1e-9)
    assert_allclose(path.q_start, q0, atol=0)
    assert np.abs(U.pose_residual(U.ur5e_fk_batch(path.q_goal[None])[0], T2)).max() < 1e-9


def test_junctions_at_length_fractions_and_speed_continuous(via_path, three_poses):
    """Trajectory scaling: piece i gets Δs_i = L_i / Σ L, so the metric speed is Σ L everywhere."""
    _, poses = three_poses
    path = via_path
    L = np.array([piece_length(poses[0], poses[1]), piece_length(poses[1], poses[2])])
    assert_allclose(path.breakpoints[1], L[0] / L.sum(), rtol=1e-6)
    assert_allclose(path.length, L.sum(), rtol=1e-6)
    b = path.breakpoints[1]
    eps = 1e-9
    q, dq, _, _ = path.evaluate(np.array([b - eps, b + eps]))
    speed = np.sqrt(np.einsum('ni,nij,nj->n', dq, Metric().tensor(path.robot, q), dq))
    assert_allclose(speed[0], speed[1], rtol=1e-6)
    assert_allclose(speed, L.sum(), rtol=1e-6)
    assert_allclose(metric_speed(path, np.linspace(0, 1, 301)), L.sum(), rtol=1e-6)
    # positions continuous at the junction
    assert_allclose(q[0], q[1], atol=1e-7)


def test_each_piece_is_line_and_slerp(via_path, three_poses):
    q0, poses = three_poses
    path = via_path
    bp = path.breakpoints
    for i in range(2):
        s = np.linspace(bp[i], bp[i + 1], 51)
        u = (s - bp[i]) / (bp[i + 1] - bp[i])
        targets = U.line_slerp_oracle(poses[i], poses[i + 1], u)
        T = U.ur5e_fk_batch(path.evaluate(s)[0])
        assert np.abs(T[:, :3, 3] - targets[:, :3, 3]).max() <= 1e-6
        assert np.abs(U.pose_residual(T, targets)[:, 3:]).max() <= 1e-6


def test_evaluate_contract_and_derivative_scaling(via_path):
    path = via_path
    s = np.linspace(0, 1, 41)
    out = path.evaluate(s)
    assert len(out) == 4 and all(a.shape == (41, 6) for a in out)
    assert path.joint_names == path.robot.joint_names
    assert path.solver.status == 0
    # inside a piece, derivatives are derivatives of the global q(s)
    b = path.breakpoints[1]
    h = 1e-6
    sm = np.linspace(0.05, b - 0.05, 9)
    q_p, q_m = path.evaluate(sm + h)[0], path.evaluate(sm - h)[0]
    assert_allclose((q_p - q_m) / (2 * h), path.evaluate(sm)[1], atol=1e-6)
    with pytest.raises(RequestError, match=r'values must lie in \[0, 1\]'):
        path.evaluate(np.array([0.5, 1.2]))


def test_curvilinear_path_through_twelve_poses_on_an_arc(ur5e):
    """12 via poses on a quarter circle (r = 0.15 m), the tool yawing with the tangent: every via
    pose hit exactly, the tool follows each chord (so it stays within the sagitta of the arc),
    constant metric speed over the whole path."""
    robot, planner = ur5e
    q0 = robot.home + np.array([0.3, -0.2, 0.2, 0.1, 0.3, 0.2])
    T0 = U.ur5e_fk_batch(q0[None])[0]
    r = 0.15
    center = T0[:3, 3] + np.array([0.0, r, 0.0])
    angles = np.linspace(0, np.pi / 2, 12)
    poses = []
    for a in angles:
        T = T0.copy()
        T[:3, 3] = center + r * np.array([np.sin(a), -np.cos(a), 0.0])
        T[:3, :3] = U.axis_angle([0, 0, 1], a) @ T0[:3, :3]
        poses.append(T)
    path = planner.plan_through(poses, start_joints=q0)
    bp = path.breakpoints
    assert bp.shape == (12,)
    # equal pieces: equal fractions of s
    assert_allclose(np.diff(bp), 1 / 11, rtol=1e-6)
    q_via = path.evaluate(bp)[0]
    T_via = U.ur5e_fk_batch(q_via)
    assert np.abs(U.pose_residual(T_via, np.array(poses))).max() < 1e-9
    s = np.linspace(0, 1, 1101)
    p = U.ur5e_fk_batch(path.evaluate(s)[0])[:, :3, 3]
    dist = np.abs(np.linalg.norm(p[:, :2] - center[:2], axis=1) - r)
    sagitta = r * (1 - np.cos((np.pi / 2) / 11 / 2))
    assert dist.max() <= sagitta + 1e-6
    assert dist.max() >= 0.5 * sagitta  # really chords, not the arc itself
    assert_allclose(p[:, 2], center[2], atol=1e-6)
    L = sum(piece_length(poses[i], poses[i + 1]) for i in range(11))
    assert_allclose(metric_speed(path, s), L, rtol=1e-6)


def test_planar_3r_via_point():
    """Planar 3R, poses only: φ and p piecewise linear in s, the via pose hit, default branch."""
    robot = load_robot('planar_3r')

    def pose(x, y, phi):
        c, s_ = np.cos(phi), np.sin(phi)
        return np.array([[c, -s_, 0, x], [s_, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])

    poses = [pose(2.5, 1.5, np.pi / 6), pose(2.0, 2.0, 0.6), pose(1.5, 2.5, np.arctan2(0.7, 0.714))]
    path = GeodesicPlanner(robot).plan_through(poses)
    assert path.q_start[1] > 0
    assert_allclose(path.q_start, [0.258, 0.583, -0.317], atol=6e-4)
    lengths = [np.sqrt(0.5 + 2 * (np.arctan2(poses[i + 1][1, 0], poses[i + 1][0, 0])
                                  - np.arctan2(poses[i][1, 0], poses[i][0, 0])) ** 2) for i in range(2)]
    assert_allclose(path.breakpoints[1], lengths[0] / sum(lengths), rtol=1e-6)
    s = np.linspace(0, 1, 501)
    q = path.evaluate(s)[0]
    T = robot.fk(q)
    for i in range(2):
        sel = (s >= path.breakpoints[i]) & (s <= path.breakpoints[i + 1])
        u = (s[sel] - path.breakpoints[i]) / (path.breakpoints[i + 1] - path.breakpoints[i])
        p_line = poses[i][:3, 3] + u[:, None] * (poses[i + 1][:3, 3] - poses[i][:3, 3])
        assert np.abs(T[sel, :3, 3] - p_line).max() < 1e-6
        phi_a = np.arctan2(poses[i][1, 0], poses[i][0, 0])
        phi_b = np.arctan2(poses[i + 1][1, 0], poses[i + 1][0, 0])
        assert np.abs(q[sel].sum(axis=1) - (phi_a + u * (phi_b - phi_a))).max() < 1e-6


def test_rrpp_via_point_speed_continuous():
    """No closed form (4 joints): via point reached, speed equal across the junction."""
    robot = load_robot('rrpp')
    qs = np.array([[0.123, -1.539, 0.276, -0.640], [0.126, -1.58, 0.26, -0.642], [0.129, -1.629, 0.239, -0.643]])
    poses = list(robot.fk(qs))
    path = GeodesicPlanner(robot).plan_through(poses, start_joints=qs[0])
    assert_allclose(path.via_joints, qs, atol=1e-8)
    b = path.breakpoints[1]
    q, dq, _, _ = path.evaluate(np.array([b - 1e-9, b + 1e-9]))
    G = Metric().tensor(robot, q)
    speed = np.sqrt(np.einsum('ni,nij,nj->n', dq, G, dq))
    assert_allclose(speed[0], speed[1], rtol=1e-5)
    assert_allclose(metric_speed(path, np.linspace(0, 1, 201)), path.length, rtol=1e-5)


def test_repeated_via_pose_is_harmless(ur5e, three_poses):
    _, planner = ur5e
    q0, (T0, T1, T2) = three_poses
    path = planner.plan_through([T0, T1, T1, T2], start_joints=q0)
    assert np.all(np.diff(path.breakpoints) > 0)
    ref = planner.plan_through([T0, T1, T2], start_joints=q0)
    s = np.linspace(0, 1, 51)
    assert_allclose(path.evaluate(s)[0], ref.evaluate(s)[0], atol=1e-7)


@pytest.mark.parametrize('poses, kwargs, error, match', [
    (lambda P: [P[0]], {}, RequestError, r'needs at least 2 poses \(start and goal\), got 1'),
    (lambda P: [None, P[1]], {}, RequestError, 'give the first pose or start_joints'),
    (lambda P: [P[0], np.full((4, 4), np.nan), P[2]], {}, RequestError, 'via point 1: transform contains NaN'),
    (lambda P: [P[0], P[1], np.eye(4) * 2], {}, RequestError, 'via point 2'),
    (lambda P: [P[0], P[1]], {'start_joints': [0.0] * 3}, RequestError, "start_joints: robot 'ur5e' has 6 joints"),
])
def test_plan_through_bad_input(ur5e, three_poses, poses, kwargs, error, match):
    _, planner = ur5e
    with pytest.raises(error, match=match):
        planner.plan_through(poses(three_poses[1]), **kwargs)


def test_plan_through_unreachable_via_point(ur5e, three_poses):
    _, planner = ur5e
    q0, (T0, T1, T2) = three_poses
    far = T1.copy()
    far[:3, 3] = [2.0, 0.0, 0.5]
    with pytest.raises(IKError, match="IK failed for robot 'ur5e'"):
        planner.plan_through([T0, far, T2], start_joints=q0)


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
def test_regression_plan_through_validates_late(planar: GeodesicPlanner) -> None:
    """Found by the fuzzer: plan_through once checked via point i only after solving the pieces
    before it, so a NaN via point was reported as whatever failed first (here the singular start)."""
    robot = planar.robot
    T_s, T_1 = robot.fk(np.array([[0.3, 0.0, 0.2], [0.5, 0.4, 0.2]]))   # start stretched: singular
    T_bad = T_1.copy()
    T_bad[0, 3] = np.nan
    expect_error('regression', lambda: planar.plan_through([T_s, T_1, T_bad]), RequestError,
                 r'^via point 2: transform contains NaN or inf$')


def test_regression_plan_through_roundoff() -> None:
    """Found by the fuzzer: plan_through([T, T]) on the RRPP gave a 2e-16 long path and a 1.05 µs law."""
    robot = load_robot('rrpp')
    T = robot.fk(robot.home)
    path = GeodesicPlanner(robot).plan_through([T, T])
    assert path.length == 0.0 or path.timed().duration == 0.0, \
        f'length {path.length:.3g}, duration {path.timed().duration:.3g} s'
