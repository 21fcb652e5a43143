"""Inverse kinematics at the path ends: paper Table 2, a closed form written here, exact poses on
6- and 7-joint arms, branch consistency, nearest reachable pose for the RRPP, clear errors."""
from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose
from planning_checks import PANDA_AT_LIMITS, expect_error

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import IKError, RequestError
from geodesic_planner.core.ik import check_transform, planar_3r_ik, solve_ik
from geodesic_planner.core.kinematics import chain_from_dh
from geodesic_planner.core.transforms import pose_error

DATA = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data'))
KR6 = os.path.join(DATA, 'kr6_like.urdf')
IIWA = os.path.join(DATA, 'iiwa_like_7r.urdf')
# ordinary (non-singular) configurations to move around
NICE = {'ur5e': None, 'panda': None, KR6: np.array([0.0, -1.2, 1.0, 0.0, 0.8, 0.0]),
        IIWA: np.array([0.2, 0.6, -0.1, -1.2, 0.1, 0.8, 0.3])}


def planar_pose(x: float, y: float, nx: float, ny: float) -> np.ndarray:
    """Pose in the plane from a position and the (unnormalised) direction n of paper Table 1."""
    c, s = np.array([nx, ny]) / np.hypot(nx, ny)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def my_3r_ik(x, y, phi, elbow):
    """Closed-form planar 3R IK with unit links (written here, independent of ik.py)."""
    wx, wy = x - np.cos(phi), y - np.sin(phi)
    c2 = (wx**2 + wy**2 - 2.0) / 2.0
    t2 = elbow * np.arccos(c2)
    t1 = np.arctan2(wy, wx) - np.arctan2(np.sin(t2), 1 + np.cos(t2))
    return np.array([t1, t2, phi - t1 - t2])


TABLE1_A = planar_pose(2.5, 1.5, 0.866, 0.5)
TABLE1_B = planar_pose(1.5, 2.5, 0.714, 0.7)


# ---------------------------------------------------------------------- planar 3R
def test_paper_table2_reproduced():
    robot = load_robot('planar_3r')
    qa = solve_ik(robot, TABLE1_A)
    qb = solve_ik(robot, TABLE1_B, qa.q)
    # Table 2 to its 3 printed decimals (signs restored, docs/maths.md#robots); default branch θ2 > 0
    assert_allclose(qa.q, [0.258, 0.583, -0.317], atol=6e-4)
    assert_allclose(qb.q, [0.969, 0.380, -0.574], atol=6e-4)
    for sol, T in ((qa, TABLE1_A), (qb, TABLE1_B)):
        assert sol.success and sol.reason == ''
        dp, dr = pose_error(robot.fk(sol.q), T)
        assert dp < 1e-12 and dr < 1e-12
        assert sol.residual < 1e-12


@pytest.mark.parametrize('elbow', [1, -1])
def test_planar_3r_closed_form_matches_independent_formula(elbow):
    robot = load_robot('planar_3r')
    rng = np.random.default_rng(elbow + 5)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 3)
        q[1] = elbow * rng.uniform(0.1, 2.8)
        T = robot.fk(q)
        got = planar_3r_ik(T, elbow=elbow)
        phi = np.arctan2(T[1, 0], T[0, 0])
        mine = my_3r_ik(T[0, 3], T[1, 3], phi, elbow)
        wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi  # noqa: E731
        assert_allclose(wrap(got - mine), 0.0, atol=1e-10)
        assert_allclose(wrap(got - q), 0.0, atol=1e-9)
        assert_allclose(robot.fk(got), T, atol=1e-12)


def test_planar_3r_unreachable():
    robot = load_robot('planar_3r')
    T = planar_pose(3.5, 0.0, 1.0, 0.0)
    assert planar_3r_ik(T) is None
    with pytest.raises(IKError, match=r"IK failed for robot 'planar_3r': nearest reachable pose is") as info:
        solve_ik(robot, T)
    assert info.value.residual > 0.4  # at least 0.5 m short in position
    assert info.value.iterations > 0
    sol = solve_ik(robot, T, raise_on_failure=False)
    assert not sol.success and 'nearest reachable pose' in sol.reason
    assert_allclose(sol.position_error, 0.5, atol=1e-6)   # stretched arm reaches x = 3


def test_planar_3r_seed_selects_branch():
    robot = load_robot('planar_3r')
    q_down = my_3r_ik(2.5, 1.5, np.deg2rad(30.0), -1)
    sol = solve_ik(robot, planar_pose(2.5, 1.5, np.cos(np.pi / 6), np.sin(np.pi / 6)), q_down + 0.05)
    assert sol.q[1] < 0
    assert_allclose(sol.q, q_down, atol=1e-9)


# ---------------------------------------------------------------------- spatial arms
@pytest.mark.parametrize('name', ['ur5e', KR6, 'panda'], ids=os.path.basename)
def test_reachable_poses_solved_exactly(name):
    robot = load_robot(name)
    home = robot.home if NICE[name] is None else NICE[name]
    rng = np.random.default_rng(11)
    for _ in range(10):
        q = np.clip(home + rng.uniform(-0.5, 0.5, robot.dof), robot.lower, robot.upper)
        T = robot.fk(q)
        for seed in (None, q + rng.uniform(-0.1, 0.1, robot.dof)):
            sol = solve_ik(robot, T, seed)
            assert sol.success
            dp, dr = pose_error(robot.fk(sol.q), T)
            assert dp < 1e-9 and dr < 1e-9, (dp, dr)
            assert_allclose([sol.position_error, sol.orientation_error], [dp, dr], atol=1e-12)
            assert robot.within_limits(sol.q)
            if seed is not None and robot.dof == 6:
                assert_allclose(sol.q, q, atol=1e-7)  # the seed's branch


def test_reachable_poses_solved_exactly_from_singular_default_seed():
    robot = load_robot(IIWA)
    rng = np.random.default_rng(1)
    worst = 0.0
    for _ in range(40):
        q = np.clip(NICE[IIWA] + rng.uniform(-0.5, 0.5, 7), robot.lower, robot.upper)
        T = robot.fk(q)
        sol = solve_ik(robot, T)
        worst = max(worst, *pose_error(robot.fk(sol.q), T))
    assert worst < 1e-9, f'IK pose error up to {worst:.3g}'


def test_reachable_panda_pose_not_accepted_at_a_joint_limit_local_minimum():
    robot = load_robot('panda')
    q = np.array([0.305, 0.331, 2.018, -2.574, -0.542, 2.728, -2.648])
    assert robot.within_limits(q)
    T = robot.fk(q)
    sol = solve_ik(robot, T, raise_on_failure=False)
    dp, dr = pose_error(robot.fk(sol.q), T)
    # either solved exactly, or honestly reported as not solved
    assert (sol.success and dp < 1e-9 and dr < 1e-9) or not sol.success, (sol.success, dp, dr)


def test_unreachable_spatial_pose():
    robot = load_robot('ur5e')
    T = robot.fk(robot.home)
    T[:3, 3] = [2.0, 0.5, 0.3]
    with pytest.raises(IKError, match=r"IK failed for robot 'ur5e'.*target position \[2\.0, 0\.5, 0\.3\] m") as info:
        solve_ik(robot, T)
    assert info.value.residual > 0.5


def test_solution_outside_joint_limits_is_an_error():
    """A planar 2R arm whose joints may only bend one way cannot reach a pose made with the other."""
    robot = chain_from_dh('two_r', [(0.0, 0.0, 1.0, 0.0)] * 2, ['revolute'] * 2, lower=[0.0, 0.0],
                          upper=[1.0, 1.0])
    T = robot.fk(np.array([-0.5, 0.3]))
    with pytest.raises(IKError, match=r"IK failed for robot 'two_r'"):
        solve_ik(robot, T)
    sol = solve_ik(robot, robot.fk(np.array([0.4, 0.3])))
    assert_allclose(sol.q, [0.4, 0.3], atol=1e-9)


# ---------------------------------------------------------------------- fewer than 6 joints
RRPP_A = (np.array([-0.501, -0.901, -0.699]), np.array([[0.100, -0.102, -0.990], [-0.810, 0.569, -0.141],
                                                          [0.577, 0.816, -0.026]]))


def rrpp_table5_pose() -> np.ndarray:
    """Table 5 pose A, its printed (n o a) projected onto SO(3) (polar decomposition)."""
    U_, _, Vt = np.linalg.svd(RRPP_A[1])
    T = np.eye(4)
    T[:3, :3] = U_ @ Vt
    T[:3, 3] = RRPP_A[0]
    return T


def test_rrpp_nearest_reachable_pose():
    """Four joints cannot reach every pose: the answer is the least-squares nearest one in the
    embedding (gradient Jᵀ (f(q) − f*) = 0), its residual reported, and it is Table 6's A."""
    robot = load_robot('rrpp')
    T = rrpp_table5_pose()
    sol = solve_ik(robot, T, tolerance=5e-3)
    assert sol.success
    assert 1e-6 < sol.residual < 5e-3  # the 3-decimal pose is not exactly reachable
    assert_allclose(sol.q, [0.123, -1.539, 0.276, -0.640], atol=1e-3)
    f = lambda M: np.concatenate([M[:3, 3], M[:3, 0], M[:3, 1], M[:3, 2]])  # noqa: E731
    e = f(robot.fk(sol.q)) - f(T)
    assert_allclose(np.linalg.norm(e), sol.residual, rtol=1e-9)
    grad = robot.jacobian12(sol.q).T @ e
    assert np.abs(grad).max() < 1e-10 * max(1.0, sol.residual)
    with pytest.raises(IKError, match=r'nearest reachable pose is .* away \(tolerance 1e-07\)'):
        solve_ik(robot, T, tolerance=1e-7)


# ---------------------------------------------------------------------- input validation
def test_seed_with_wrong_joint_count():
    robot = load_robot('ur5e')
    with pytest.raises(RequestError, match="IK seed: robot 'ur5e' has 6 joints"):
        solve_ik(robot, robot.fk(robot.home), [0.0] * 4)


def _rot(T, R):
    T = T.copy()
    T[:3, :3] = R
    return T


@pytest.mark.parametrize('T, match', [
    (np.eye(3), r'expected a 4x4 homogeneous transform, got shape \(3, 3\)'),
    (np.full((4, 4), np.nan), 'NaN or inf'),
    (_rot(np.eye(4), 2 * np.eye(3)), 'not a proper rotation'),
    (_rot(np.eye(4), np.diag([1.0, 1.0, -1.0])), 'not a proper rotation'),          # a reflection
    (_rot(np.eye(4), [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]), 'not a proper rotation'),  # shear
    (np.vstack([np.eye(4)[:3], [[0, 0, 1, 1]]]), r'last row must be \[0, 0, 0, 1\]'),
    ('abc', 'not a numeric 4x4 transform'),
])
def test_check_transform_rejects(T, match):
    with pytest.raises(RequestError, match=match):
        check_transform(T, 'goal pose')
    with pytest.raises(RequestError, match='goal pose'):
        check_transform(T, 'goal pose')


def test_planar_3r_branches_batch_matches_single_and_reaches_targets():
    from geodesic_planner.core.ik import nearest_branch, planar_3r_branches
    robot = load_robot('planar_3r')
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, (40, 3))
    q[:, 1] = np.sign(q[:, 1]) * np.clip(np.abs(q[:, 1]), 0.1, 2.8)
    T = robot.fk(q)
    both = planar_3r_branches(T)
    assert both.shape == (2, 40, 3)
    for k in range(40):
        assert_allclose(both[0, k], planar_3r_ik(T[k], elbow=1), atol=0)
        assert_allclose(both[1, k], planar_3r_ik(T[k], elbow=-1), atol=0)
    assert_allclose(robot.fk(both[0]), T, atol=1e-12)
    assert_allclose(robot.fk(both[1]), T, atol=1e-12)
    # the branch nearest the true joints is the true joints (up to 2π)
    near = nearest_branch(both, q)
    assert_allclose((near - q + np.pi) % (2 * np.pi) - np.pi, 0.0, atol=1e-9)
    far = planar_pose(3.5, 0.0, 1.0, 0.0)[None]
    assert np.isnan(planar_3r_branches(far)).all()


def test_gauss_newton_batch_converges_on_reachable_targets():
    from geodesic_planner.core.ik import gauss_newton_batch
    robot = load_robot('ur5e')
    rng = np.random.default_rng(4)
    q_true = robot.home + rng.uniform(-0.4, 0.4, (25, 6))
    seeds = q_true + rng.uniform(-0.05, 0.05, q_true.shape)
    q, res, X, T = gauss_newton_batch(robot, robot.fk(q_true), seeds)
    assert res.max() < 1e-12
    assert_allclose(T, robot.fk(q), atol=1e-15)          # returned kinematics are at the returned q
    assert_allclose(X, robot.generators(q)[0], atol=1e-15)
    assert_allclose(q, q_true, atol=1e-9)                 # near seeds: the same solution


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
@pytest.mark.parametrize('tol', [-1.0, 0.0, np.nan, 1.5])
def test_regression_nonpositive_tol(tol: float) -> None:
    """Found by the fuzzer (tol <= 0 or NaN was accepted, then plan() raised a bare ValueError)."""
    robot = load_robot('ur5e')
    expect_error('regression', lambda: GeodesicPlanner(robot, tol=tol), RequestError,
                 r'^tol \(collocation tolerance\) must be a number in \(0, 1\), got')


@pytest.mark.parametrize(('target', 'cause'), [
    (np.eye(3), r'^IK target: expected a 4x4 homogeneous transform, got shape \(3, 3\)$'),
    (None, r'^IK target: expected a 4x4 homogeneous transform, got shape \(\)$'),
    (np.full((4, 4), np.nan), r'^IK target: transform contains NaN or inf$')])
def test_regression_solve_ik_bad_target(target: Any, cause: str) -> None:
    """Found by the fuzzer (a bare ValueError, an IndexError, an IKError 'nan away')."""
    from geodesic_planner.core.ik import solve_ik
    robot = load_robot('ur5e')
    expect_error('regression', lambda: solve_ik(robot, target, None), RequestError, cause)


def test_regression_ik_inexact_at_limits() -> None:
    """IK reaches an exactly reachable panda pose (fk of joints on their limits) to the exact residual:
    bounded damped least-squares steps (DLS_MAX_STEP) keep the first step from pinning the iterate
    against the limits, where it would stall at an embedding residual of about 5e-4."""
    from geodesic_planner.core.ik import solve_ik
    robot = load_robot('panda')
    sol = solve_ik(robot, robot.fk(np.array(PANDA_AT_LIMITS)))
    assert sol.residual <= 1e-9, f'IK residual {sol.residual:.3g} for an exactly reachable pose'
