"""GeodesicPlanner: the public contract, bad inputs with precise errors, weighted metrics, and
redundant (7-joint) arms: by default exactly on line + slerp (test_redundant.py has the rest), with
an explicit ε the geodesic of G + εI (within 0.1 mm and 1 mrad of line + slerp on ordinary moves)."""
from __future__ import annotations

import os
import re
from math import pi as PI
from typing import Any

import numpy as np
import pytest
import urdf_util as U
from numpy.testing import assert_allclose
from planning_checks import (
    HOSTILE_POSES,
    PANDA_AT_LIMITS,
    Q3_A,
    Q3_B,
    S_CHECK,
    SOLVE_TIME_LIMIT,
    check_path,
    check_trajectory,
    expect_error,
    guarded,
)

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import (
    BVPError,
    GeodesicPlannerError,
    IKError,
    LimitError,
    PathFollowError,
    RequestError,
    SingularMetricError,
)
from geodesic_planner.core.metric import DEFAULT_REDUNDANT_EPSILON
from geodesic_planner.core.transforms import so3_exp

DATA = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data'))
IIWA = os.path.join(DATA, 'iiwa_like_7r.urdf')
IIWA_HOME = np.array([0.2, 0.6, -0.1, -1.2, 0.1, 0.8, 0.3])


def min_sv(robot):
    return lambda q: np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1]


@pytest.fixture(scope='module')
def ur5e():
    robot = load_robot('ur5e')
    return robot, GeodesicPlanner(robot)


# ---------------------------------------------------------------------- contract
def test_plan_contract(ur5e):
    robot, planner = ur5e
    q_a = robot.home + np.array([0.2, -0.2, 0.3, 0.1, 0.2, -0.1])
    q_b = q_a + np.array([0.3, 0.1, -0.2, 0.2, 0.1, 0.3])
    path = planner.plan(robot.fk(q_a), robot.fk(q_b), start_joints=q_a, goal_joints=q_b)
    assert path.robot is robot
    assert path.joint_names == robot.joint_names
    assert_allclose(path.q_start, q_a, atol=0)   # joints win over poses
    assert_allclose(path.q_goal, q_b, atol=0)
    s = np.linspace(0, 1, 7)
    out = path.evaluate(s)
    assert len(out) == 4 and all(a.shape == (7, 6) for a in out)
    assert_allclose(path.ee_poses(s), robot.fk(out[0]), atol=1e-15)
    rep = path.solver
    assert rep.status == 0 and isinstance(rep.message, str)
    # a 6-joint arm on a reachable line: the pulled-back task geodesic, verified without a Newton step
    assert rep.method == 'pullback' and rep.iterations == 0
    assert 0 < rep.path_error <= planner.path_tolerance
    assert rep.mesh_size >= 3 and rep.time_ms > 0 and np.isfinite(rep.max_residual)
    assert set(rep.as_dict()) >= {'status', 'iterations', 'max_residual', 'time_ms', 'method', 'path_error'}
    path2 = planner.plan_joints(q_a, q_b)
    assert_allclose(path2.evaluate(s)[0], out[0], atol=1e-12)


def test_planner_is_reusable_and_deterministic(ur5e):
    robot, planner = ur5e
    T_a = robot.fk(robot.home + 0.1)
    T_b = robot.fk(robot.home - 0.1)
    s = np.linspace(0, 1, 11)
    q1 = planner.plan(T_a, T_b).evaluate(s)[0]
    planner.plan(T_b, T_a)
    q2 = planner.plan(T_a, T_b).evaluate(s)[0]
    assert_allclose(q1, q2, atol=0)


# ---------------------------------------------------------------------- bad inputs
def _bad_rotation():
    T = np.eye(4)
    T[:3, :3] = [[1, 0.2, 0], [0, 1, 0], [0, 0, 1]]
    T[:3, 3] = [0.3, 0.2, 0.4]
    return T


@pytest.mark.parametrize('kwargs, error, match', [
    ({'start_joints': [0.0] * 5, 'goal_joints': [0.0] * 6}, RequestError,
     r"start_joints: robot 'ur5e' has 6 joints .* got 5 values"),
    ({'start_joints': [0.0] * 6, 'goal_joints': [0.0] * 7}, RequestError,
     r"goal_joints: robot 'ur5e' has 6 joints .* got 7 values"),
    ({'start_joints': [0.0, float('nan'), 0, 0, 0, 0], 'goal_joints': [0.0] * 6}, RequestError,
     'start_joints: joint values contain NaN'),
    ({'start_joints': [0.0] * 6, 'goal_joints': [0.0, 0, 0, float('inf'), 0, 0]}, RequestError,
     'goal_joints: joint values contain NaN or inf'),
    ({'start': _bad_rotation(), 'goal_joints': [0.0] * 6}, RequestError,
     'start pose: rotation part is not a proper rotation'),
    ({'start_joints': [0.0] * 6, 'goal': np.full((4, 4), np.nan)}, RequestError,
     'goal pose: transform contains NaN'),
    ({'start_joints': [0.0] * 6, 'goal': np.eye(3)}, RequestError,
     r'goal pose: expected a 4x4 homogeneous transform'),
    ({'goal_joints': [0.0] * 6}, RequestError, 'start: give a start pose or start_joints'),
    ({'start_joints': [0.0] * 6}, RequestError, 'goal: give a goal pose or goal_joints'),
])
def test_bad_inputs_raise_precise_errors(ur5e, kwargs, error, match):
    _, planner = ur5e
    args = {'start': None, 'goal': None, **kwargs}
    with pytest.raises(error, match=match):
        planner.plan(args.pop('start'), args.pop('goal'), **args)


def test_unreachable_goal_raises_ik_error(ur5e):
    robot, planner = ur5e
    T = robot.fk(robot.home)
    far = T.copy()
    far[:3, 3] = [1.5, 1.5, 1.5]
    with pytest.raises(IKError, match=r"IK failed for robot 'ur5e'.*target position \[1\.5, 1\.5, 1\.5\]"):
        planner.plan(T, far)
    with pytest.raises(GeodesicPlannerError):  # one family for nodes/CLIs to catch
        planner.plan(far, T)


@pytest.mark.parametrize('kwargs, match', [
    ({'metric': 'euclid'}, "unknown metric 'euclid'"),
    ({'nodes': 2}, r'nodes must be in \[3, max_nodes\]'),
    ({'nodes': 50, 'max_nodes': 20}, r'nodes must be in \[3, max_nodes\]'),
    ({'position_weight': -1.0}, 'position_weight must be finite and >= 0'),
])
def test_bad_planner_options(kwargs, match):
    with pytest.raises(RequestError, match=match):
        GeodesicPlanner(load_robot('ur5e'), **kwargs)


# ---------------------------------------------------------------------- weighted metric
def test_weighted_metric_geodesic_is_still_line_and_slerp():
    """wp² dp² + wo² ‖dR‖² is still a product of flat R³ and bi-invariant SO(3): line + slerp,
    constant speed √(wp² |Δp|² + 2 wo² θ²)."""
    robot = load_robot('ur5e')
    wp, wo = 2.0, 0.4
    planner = GeodesicPlanner(robot, position_weight=wp, orientation_weight=wo)
    (q_a, T_a, T_b), = U.moderate_moves(U.ur5e_fk_batch, min_sv(robot), robot.home, robot.lower,
                                        robot.upper, seed=51, n=1)
    path = planner.plan(None, T_b, start_joints=q_a)
    s = np.linspace(0, 1, 101)
    q, dq, _, _ = path.evaluate(s)
    q_oracle = U.continuation_ik(U.ur5e_fk_batch, U.line_slerp_oracle(T_a, T_b, s), q_a)
    assert np.abs(q - q_oracle).max() <= 1e-5
    Rrel = T_a[:3, :3].T @ T_b[:3, :3]
    theta = np.arccos(np.clip((np.trace(Rrel) - 1) / 2, -1, 1))
    exact = np.sqrt(wp**2 * np.sum((T_b[:3, 3] - T_a[:3, 3]) ** 2) + 2 * wo**2 * theta**2)
    assert_allclose(path.metric_speed(s), exact, rtol=1e-6)


# ---------------------------------------------------------------------- redundant arms
REDUNDANT = {
    'panda': (lambda: load_robot('panda'), U.panda_fk_batch, None),
    'iiwa_like_7r_urdf': (lambda: load_robot(IIWA), U.arm_fk_batch(U.IIWA), IIWA_HOME),
}


@pytest.fixture(scope='module', params=list(REDUNDANT))
def redundant(request):
    make, fkb, home = REDUNDANT[request.param]
    robot = make()
    home = robot.home if home is None else home
    moves = U.moderate_moves(fkb, min_sv(robot), home, robot.lower, robot.upper, seed=61, n=4)
    return robot, fkb, moves


def test_seven_joints_plan_near_line_and_slerp_with_epsilon(redundant):
    """An explicit ε plans the geodesic of G + εI (the 7-joint default before issue 21)."""
    robot, fkb, moves = redundant
    planner = GeodesicPlanner(robot, epsilon=DEFAULT_REDUNDANT_EPSILON)
    assert planner.redundant is None
    s = np.linspace(0, 1, 201)
    for q_a, T_a, T_b in moves:
        path = planner.plan(None, T_b, start_joints=q_a)
        assert path.solver.status == 0 and path.solver.method == 'collocation'
        q = path.evaluate(s)[0]
        # ends exact, the path within 0.1 mm and 1 mrad of line + slerp
        assert np.abs(U.pose_residual(fkb(path.q_goal[None])[0], T_b)).max() < 1e-9
        dp, dr = U.tool_deviation(fkb, q, T_a, T_b, s)
        assert dp <= 1e-4 and dr <= 1e-3, (dp, dr)
        assert robot.within_limits(q).all()
        # a geodesic of G + εI: constant speed, ODE residual at the collocation tolerance
        sp = path.metric_speed(s)
        assert_allclose(sp, sp.mean(), rtol=1e-5)
        _, _, a, _ = path.evaluate(s)
        Ga = np.linalg.norm(np.einsum('nij,nj->ni', path.metric.tensor(robot, q), a), axis=1).max()
        assert path.residual(s).max() < 50 * planner.tol * (1.0 + Ga)


def test_seven_joint_default_tolerance_is_converged(redundant):
    """No closed form with ε > 0: the default-tolerance solution agrees with a tight one."""
    robot, fkb, moves = redundant
    q_a, T_a, T_b = moves[0]
    s = np.linspace(0, 1, 201)
    eps = DEFAULT_REDUNDANT_EPSILON
    q = GeodesicPlanner(robot, epsilon=eps).plan(None, T_b, start_joints=q_a).evaluate(s)[0]
    tight = GeodesicPlanner(robot, epsilon=eps, tol=1e-9).plan(None, T_b, start_joints=q_a)
    assert tight.solver.max_residual <= 1e-9
    assert np.abs(q - tight.evaluate(s)[0]).max() <= 1e-5
    assert np.abs(fkb(q)[:, :3, 3] - fkb(tight.evaluate(s)[0])[:, :3, 3]).max() <= 1e-6


def test_seven_joints_poses_only(redundant):
    """Both ends as poses (IK at the start, the goal chosen by the planner): exact line + slerp."""
    robot, fkb, moves = redundant
    planner = GeodesicPlanner(robot)
    s = np.linspace(0, 1, 1001)
    for _, T_a, T_b in moves:
        path = planner.plan(T_a, T_b)
        assert path.solver.method == 'redundant'
        q = path.evaluate(s)[0]
        assert np.abs(U.pose_residual(fkb(q[[0, -1]]), np.stack([T_a, T_b]))).max() < 1e-9
        dp, dr = U.tool_deviation(fkb, q, T_a, T_b, s)
        assert dp <= 1e-8 and dr <= 1e-8, (dp, dr)


def test_tool_deviation_shrinks_linearly_with_epsilon():
    """The ε I term pulls the path off line + slerp by an amount ∝ ε (for small ε)."""
    robot = load_robot('panda')
    (q_a, T_a, T_b), = U.moderate_moves(U.panda_fk_batch, min_sv(robot), robot.home, robot.lower,
                                        robot.upper, seed=62, n=1)
    s = np.linspace(0, 1, 101)
    dev = []
    for eps in (1e-2, 1e-3, 1e-4):
        path = GeodesicPlanner(robot, epsilon=eps).plan(None, T_b, start_joints=q_a)
        dev.append(U.tool_deviation(U.panda_fk_batch, path.evaluate(s)[0], T_a, T_b, s)[0])
    assert dev[0] > dev[1] > dev[2] > 0
    assert 5 < dev[0] / dev[1] < 20 and 5 < dev[1] / dev[2] < 20, dev


# ---------------------------------------------------------------------- singular ends, threads
def test_singular_start_configuration_is_reported():
    """UR5e with q5 = 0: wrist joints 4 and 6 aligned, J has rank 5. The line to this goal cannot
    be followed out of it: refused with fraction 0, the singularity and the tool's place (issue 36)."""
    robot = load_robot('ur5e')
    q_a = np.array([0.1, -1.2, 1.3, -1.5, 0.0, 0.4])
    x, y, z = U.ur5e_fk_batch(q_a[None])[0, :3, 3]
    match = (rf"passes through a singularity of robot 'ur5e' at its start \(0 % of the way, "
             rf"tool at {x:.4f}, {y:.4f}, {z:.4f} m;.*followable fraction 0\.0000")
    with pytest.raises(PathFollowError, match=match) as info:
        GeodesicPlanner(robot).plan_joints(q_a, q_a + 0.2)
    assert info.value.fraction < 5e-5


def test_shared_planner_across_threads_gives_sequential_results():
    """One planner used by several threads at once (as the ROS node does) plans the same paths."""
    from concurrent.futures import ThreadPoolExecutor
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(71)
    moves = [(robot.home + rng.uniform(-0.3, 0.3, 6), robot.home + rng.uniform(-0.3, 0.3, 6)) for _ in range(6)]
    s = np.linspace(0, 1, 31)
    sequential = [np.array(planner.plan_joints(a, b).evaluate(s)) for a, b in moves]
    with ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(lambda m: np.array(planner.plan_joints(*m).evaluate(s)), moves * 3))
    for k, got in enumerate(parallel):
        assert_allclose(got, sequential[k % len(moves)], atol=0, rtol=0)


def test_urdf_arm_with_singular_home_plans_ordinary_move_from_poses():
    """UR5e kinematics as a URDF with a base offset and a tool; the move is 0.10 m and 27 deg
    (the ur5e preset, whose home is a regular configuration, plans the same move fine)."""
    base = U.xyz_rpy((0.3, 0.1, 0.2), (0.1, 0.2, 0.3))
    tool = U.xyz_rpy((0.0, 0.02, 0.1), (0.3, 0.0, 0.0))
    from geodesic_planner.core.urdf import chain_from_urdf
    urdf = chain_from_urdf(U.dh_to_urdf('ur5e_urdf', U.UR5E_DH, ['revolute'] * 6, base=base, tool=tool,
                                        lower=[-6.28] * 6, upper=[6.28] * 6))
    fkb = lambda qs: U.dh_fk_batched(U.UR5E_DH, ['revolute'] * 6, qs, base=base, tool=tool)  # noqa: E731
    q_a = np.array([0.3737, -1.8888, 1.1868, -1.61, -1.8254, 0.3261])
    q_b = np.array([0.4405, -1.5781, 0.7632, -1.4363, -1.9549, 0.8495])
    T_a, T_b = fkb(np.stack([q_a, q_b]))
    path = GeodesicPlanner(urdf).plan(T_a, T_b)
    s = np.linspace(0, 1, 101)
    dp, dr = U.tool_deviation(fkb, path.evaluate(s)[0], T_a, T_b, s)
    assert dp < 1e-6 and dr < 1e-5


# ---------------------------------------------------------------------- the pulled-back geodesic
# On a non-redundant arm (epsilon = 0) whose line + slerp stays reachable, the geodesic is that
# task-space geodesic pulled back by IK (docs/maths.md#oracles): the planner verifies it at the mesh nodes
# instead of running Newton iterations. These tests compare it with exact oracles.
KR6 = os.path.join(DATA, 'kr6_like.urdf')


def _line_move(robot, q0, dp, rotvec):
    from geodesic_planner.core.transforms import so3_exp
    T_a = robot.fk(q0)
    T_b = T_a.copy()
    T_b[:3, 3] += dp
    T_b[:3, :3] = T_b[:3, :3] @ so3_exp(np.asarray(rotvec, dtype=float))
    return T_a, T_b


def _tool_error(path, T_a, T_b, samples=2001):
    from geodesic_planner.core.transforms import line_slerp, pose_error
    s = np.linspace(0.0, 1.0, samples)
    dp, dr = pose_error(path.ee_poses(s), line_slerp(T_a, T_b, s))
    return float(dp.max()), float(dr.max())


PULLBACK_CASES = {
    'ur5e': ('ur5e', [0.3, -1.2, 1.4, -1.5, -1.4, 0.2], [0.2, -0.1, 0.15], [0.0, 0.0, np.pi / 6]),
    'kr6_like.urdf': (KR6, [0.2, -0.6, 0.9, 0.3, 0.8, -0.2], [0.1, 0.12, -0.08], [0.2, -0.1, 0.3]),
    'kr6 long': (KR6, [0.2, -0.6, 0.9, 0.3, 0.8, -0.2], [0.25, 0.2, -0.1], [0.4, -0.3, 0.5]),
}


@pytest.mark.parametrize('case', sorted(PULLBACK_CASES))
@pytest.mark.parametrize('path_tolerance', [1e-9, 1e-7])
def test_pullback_path_within_path_tolerance_of_line_slerp(case, path_tolerance):
    """The returned path stays within path_tolerance (m and rad, the metric's units) of the exact
    geodesic's tool path, line + slerp at the same s, everywhere (not only at the nodes)."""
    name, q0, dp, rot = PULLBACK_CASES[case]
    robot = load_robot(name)
    planner = GeodesicPlanner(robot, path_tolerance=path_tolerance)
    T_a, T_b = _line_move(robot, np.array(q0), dp, rot)
    path = planner.plan(T_a, T_b, start_joints=q0)
    rep = path.solver
    assert rep.method == 'pullback' and rep.iterations == 0 and rep.status == 0
    assert rep.path_error <= path_tolerance
    e_pos, e_rot = _tool_error(path, T_a, T_b)
    assert e_pos <= path_tolerance + 1e-11 and e_rot <= path_tolerance + 1e-11, (e_pos, e_rot)
    # the metric speed of a geodesic is constant
    speed = path.metric_speed(np.linspace(0, 1, 501))
    assert np.ptp(speed) <= 1e-6 * speed.mean()


def test_pullback_mesh_follows_the_tolerance():
    """A tighter path_tolerance refines the mesh; the paper's 3R (start near full stretch) needs it."""
    from geodesic_planner.io.requests import load_request
    req = load_request(os.path.join(os.path.dirname(DATA), os.pardir, 'msg_examples', 'paper_3r.yaml'))
    loose = GeodesicPlanner(req.robot, path_tolerance=1e-6).plan(req.start, req.goal)
    tight = GeodesicPlanner(req.robot, path_tolerance=1e-10).plan(req.start, req.goal)
    assert loose.solver.method == tight.solver.method == 'pullback'
    assert loose.solver.mesh_size < tight.solver.mesh_size
    for path, tol in ((loose, 1e-6), (tight, 1e-10)):
        e_pos, e_rot = _tool_error(path, req.start, req.goal)
        assert e_pos <= tol + 1e-12 and e_rot <= tol + 1e-12, (tol, e_pos, e_rot)


def test_interpolation_error_estimate_matches_the_true_midpoint_error():
    """interpolation_error's estimate h²/24 (S'' - a) against the exact error at the midpoints (IK
    of line + slerp there), measured in the metric."""
    from geodesic_planner.core.geodesic import interpolation_error
    from geodesic_planner.core.ik import gauss_newton_batch
    from geodesic_planner.core.polynomials import QuinticHermite
    from geodesic_planner.core.transforms import line_slerp
    robot = load_robot(KR6)
    planner = GeodesicPlanner(robot)
    q0 = np.array([0.2, -0.6, 0.9, 0.3, 0.8, -0.2])
    T_a, T_b = _line_move(robot, q0, [0.25, 0.2, -0.1], [0.4, -0.3, 0.5])
    q_a, q_b, _, _ = planner.resolve_ends(T_a, T_b, start_joints=q0)
    s = np.linspace(0.0, 1.0, 5)                      # coarse on purpose: errors of 1e-8..1e-6
    q, v, exact = planner.initial_guess(q_a, q_b, s)
    assert exact
    a = planner.equations.acceleration(q, v)
    est, _ = interpolation_error(planner.equations, s, q, v, a)
    mid = 0.5 * (s[1:] + s[:-1])
    q_mid_spline = QuinticHermite(s, q, v, a)(mid, order=0)[0]
    q_mid_true, res, _, _ = gauss_newton_batch(robot, line_slerp(T_a, T_b, mid), q_mid_spline)
    assert res.max() < 1e-12
    e = q_mid_spline - q_mid_true
    G = planner.metric.tensor(robot, q_mid_true)
    true = np.sqrt(np.einsum('ni,nij,nj->n', e, G, e))
    assert true.min() > 1e-10                          # a real error to estimate
    assert_allclose(est, true, rtol=0.2)


def test_pullback_path_is_the_collocation_solution():
    """The verified pull-back and an independent solve_bvp run on the same ends agree."""
    from geodesic_planner.core.geodesic import solve_geodesic_bvp
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T_a, T_b = _line_move(robot, q0, [0.2, -0.1, 0.15], [0.0, 0.0, np.pi / 6])
    path = planner.plan(T_a, T_b, start_joints=q0)
    assert path.solver.method == 'pullback'
    s0 = np.linspace(0.0, 1.0, 11)
    q_lin = q0 + s0[:, None] * (path.q_goal - q0)
    s, q, _, _, rep = solve_geodesic_bvp(planner.equations, q0, path.q_goal, s0, q_lin,
                                         np.broadcast_to(path.q_goal - q0, q_lin.shape), tol=1e-8)
    assert rep.status == 0 and rep.iterations >= 1
    assert_allclose(path.evaluate(s, order=0)[0], q, atol=1e-7)


def test_redundant_or_unreachable_lines_fall_back_to_collocation():
    """epsilon > 0 (7 joints) is not a pull-back: solve_bvp runs (Newton iterations >= 1)."""
    robot = load_robot('panda')
    planner = GeodesicPlanner(robot, epsilon=DEFAULT_REDUNDANT_EPSILON)
    q0 = robot.home + np.array([0.1, 0.1, -0.1, 0.2, 0.1, -0.1, 0.1])
    T_a, T_b = _line_move(robot, q0, [0.1, -0.1, 0.1], [0.0, 0.2, 0.2])
    rep = planner.plan(T_a, T_b, start_joints=q0).solver
    assert rep.method == 'collocation' and rep.iterations >= 1 and rep.max_residual <= planner.tol
    assert np.isnan(rep.path_error)


def test_path_tolerance_validated():
    with pytest.raises(RequestError, match='path_tolerance must be a number > 0'):
        GeodesicPlanner(load_robot('ur5e'), path_tolerance=0.0)
    with pytest.raises(RequestError, match='path_tolerance'):
        GeodesicPlanner(load_robot('ur5e'), path_tolerance=float('nan'))


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
@pytest.mark.parametrize(('start', 'goal', 'cause'), [
    ([np.nan, 0.5, 0.1], Q3_B, r"^start_joints: joint values contain NaN or inf: \[nan, 0\.5, 0\.1\]$"),
    (Q3_A, [0.1, np.inf, 0.2], r'^goal_joints: joint values contain NaN or inf'),
    (Q3_A, [0.1, 0.2], r"^goal_joints: robot 'planar_3r' has 3 joints \['joint1', 'joint2', 'joint3'\], got 2 values$"),
    ([0.0] * 4, Q3_B, r"^start_joints: robot 'planar_3r' has 3 joints .*got 4 values$"),
    (['a', 'b', 'c'], Q3_B, r'^start_joints: not a numeric joint vector'),
])
def test_regression_bad_joints(planar: GeodesicPlanner, start: Any, goal: Any, cause: str) -> None:
    expect_error('regression', lambda: planar.plan(None, None, start, goal), RequestError, cause)


def test_regression_joints_outside_limits(planar: GeodesicPlanner) -> None:
    expect_error('regression', lambda: planar.plan(None, None, [3.2, 0.5, 0.1], Q3_B), LimitError,
                 r"^start joints: joint 'joint1' = 3\.2 is outside its limits \[-3\.14159, 3\.14159\]$")
    expect_error('regression', lambda: planar.plan(None, None, Q3_A, [0.9, -3.5, 0.1]), LimitError,
                 r"^goal joints: joint 'joint2' = -3\.5 is outside its limits")
    # Without the limit check the same request is planned (the limits are the only objection).
    free = GeodesicPlanner(load_robot('planar_3r'), check_limits=False)
    path = guarded('regression', lambda: free.plan(None, None, [3.2, 0.5, 0.1], [2.9, 0.7, 0.3])).value
    check_path(free, path, np.array([3.2, 0.5, 0.1]), np.array([2.9, 0.7, 0.3]))


@pytest.mark.parametrize(('name', 'build', 'cause'), [(h[0], h[1], h[2]) for h in HOSTILE_POSES])
def test_regression_bad_pose(planar: GeodesicPlanner, name: str, build: Any, cause: str) -> None:
    T = planar.robot.fk(np.array(Q3_A))
    expect_error('regression', lambda: planar.plan(build(T, 0.5), T), RequestError, r'^start pose: .*' + cause)
    expect_error('regression', lambda: planar.plan(T, build(T, 0.5)), RequestError, r'^goal pose: .*' + cause)


def test_regression_unreachable_pose(planar: GeodesicPlanner) -> None:
    """5 m from the base of an arm of reach 3 m: the nearest reachable pose is the stretched arm
    pointing at it, 2 m away (the orientation matches), so IKError reports residual 2."""
    T = np.eye(4)
    T[0, 3] = 5.0
    err = expect_error('regression', lambda: planar.plan(planar.robot.fk(np.array(Q3_A)), T), IKError,
                       r"^IK failed for robot 'planar_3r': nearest reachable pose is 2 away \(tolerance 0\.001\); "
                       r'target position \[5\.0, 0\.0, 0\.0\] m')
    assert err.residual == pytest.approx(2.0, abs=1e-9)
    # The RRPP cannot turn its tool about every axis: a nearby pose with another orientation.
    rrpp = load_robot('rrpp')
    T_b = rrpp.fk(rrpp.home) @ np.block([[so3_exp(np.array([0.3, 0.0, 0.0])), np.zeros((3, 1))], [0, 0, 0, 1]])
    expect_error('regression', lambda: GeodesicPlanner(rrpp).plan(rrpp.fk(rrpp.home), T_b), IKError,
                 r"^IK failed for robot 'rrpp': nearest reachable pose is [0-9.]+ away")


def test_regression_start_equals_goal(planar: GeodesicPlanner, ur5e_planner: GeodesicPlanner) -> None:
    """start == goal: a valid zero-length path that stays put, and a trajectory of duration 0."""
    ur5e = ur5e_planner
    for planner, q in ((planar, np.array(Q3_A)), (ur5e, ur5e.robot.home + 0.1)):
        T = planner.robot.fk(q)
        for args in ((None, None, q, q), (T, T)):
            path = guarded('regression', lambda: planner.plan(*args)).value
            check_path(planner, path, q if args[0] is None else None, q if args[0] is None else None,
                       args[0], args[1])
            assert path.length == 0.0
            qs = path.evaluate(S_CHECK)[0]
            np.testing.assert_array_equal(qs, np.broadcast_to(path.q_start, qs.shape))
            traj = path.timed()
            assert traj.duration == 0.0
            check_trajectory(path, traj, planner.robot.max_velocity, planner.robot.max_acceleration)


@pytest.mark.parametrize(('robot_name', 'q_s', 'end'), [
    ('planar_3r', [0.3, 0.0, 0.2], 'start'),       # stretched: θ2 = 0
    ('planar_3r', [0.3, PI, 0.2], 'goal'),         # folded: θ2 = π
    ('ur5e', [0.1, -1.2, 0.0, -1.0, 0.5, 0.3], 'start'),   # elbow stretched
    ('ur5e', [0.1, -1.2, 1.0, -1.0, 0.0, 0.3], 'goal'),    # wrist: θ5 = 0
])
def test_regression_singular_end(robot_name: str, q_s: list[float], end: str) -> None:
    robot = load_robot(robot_name)
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    q_s = np.array(q_s)
    q_o = q_s + np.where(q_s > 1.0, -0.2, 0.2)
    args = (q_s, q_o) if end == 'start' else (q_o, q_s)
    if robot_name == 'planar_3r':      # fewer than 6 joints: the geodesic BVP, which needs G regular
        expect_error('regression', lambda: planner.plan(None, None, *args), SingularMetricError,
                     rf"^metric paper \(wp=1, wo=1\) is singular for robot '{robot_name}' at the {end} q=")
    elif end == 'start':               # the elbow exactly stretched: this line needs an infinite start rate
        expect_error('regression', lambda: planner.plan(None, None, *args), PathFollowError,
                     r"passes through a singularity of robot 'ur5e' at its start \(0 % of the way, tool at ")
    else:                              # q5 = 0: the pose does not fix joints 4 and 6; the line ends elsewhere
        expect_error('regression', lambda: planner.plan(None, None, *args), PathFollowError,
                     r"(singularity of robot 'ur5e' at (its end \()?100 % of the way|goal_joints are at a singularity)")


def test_regression_near_singular_diverging_solve() -> None:
    """Found by the fuzzer: both ends near the UR5e elbow singularity (θ3 ≈ 2π). The solve may fail
    but must say why (it once was a SingularMetricError 'at a point of the path', then the
    solver's words): since issue 21, the singularity on the line and where it is."""
    planner = GeodesicPlanner(load_robot('ur5e'), time_limit=SOLVE_TIME_LIMIT)
    q_a, q_b = [1.45, -1.462, 6.248, 6.042, 2.332, 1.891], [1.638, -1.573, 5.883, 6.264, 2.357, 1.701]
    out = guarded('regression', lambda: planner.plan(None, None, q_a, q_b))
    if out.value is not None:
        check_path(planner, out.value, np.array(q_a), np.array(q_b))
    else:
        assert isinstance(out.error, PathFollowError), out.error
        # the elbow's limit 2π is its stretched singularity: either is the reason, with the place
        assert re.search(r'(passes through a singularity|would pass its limit) .* at \d+(\.\d+)? % of the way',
                         str(out.error)), out.error


def test_regression_time_limit() -> None:
    """A budget that is already spent when the solver starts: BVPError naming the limit."""
    planner = GeodesicPlanner(load_robot('planar_3r'), time_limit=1e-9)
    err = expect_error('regression', lambda: planner.plan(None, None, Q3_A, Q3_B), BVPError,
                       r"^geodesic solver exceeded its time limit of 1e-09 s for robot 'planar_3r'$")
    assert err.status == -2


def test_regression_missing_or_too_few_ends(planar: GeodesicPlanner) -> None:
    T = planar.robot.fk(np.array(Q3_A))
    expect_error('regression', lambda: planar.plan(None, T), RequestError,
                 r'^start: give a start pose or start_joints$')
    expect_error('regression', lambda: planar.plan(T, None), RequestError, r'^goal: give a goal pose or goal_joints$')
    expect_error('regression', lambda: planar.plan_through([T]), RequestError,
                 r'^plan_through: needs at least 2 poses \(start and goal\), got 1$')


@pytest.mark.parametrize(('kwargs', 'cause'), [
    ({'metric': 'dp2'}, r"^metric: unknown metric 'dp2'"),
    ({'position_weight': np.nan}, r'position_weight must be finite'),
    ({'epsilon': -1.0}, r'epsilon must be finite and >= 0'), ({'nodes': 2}, r'nodes must be in \[3, max_nodes\]'),
    ({'time_limit': 0.0}, r'time_limit must be > 0 s or None'),
    ({'ik_tolerance': np.nan}, r'tolerance must be a positive number'),
])
def test_regression_bad_planner_options(kwargs: dict[str, Any], cause: str) -> None:
    robot = load_robot('planar_3r')

    def make_and_plan() -> Any:  # a few options are only checked when used
        return GeodesicPlanner(robot, **kwargs).plan(robot.fk(np.array(Q3_A)), robot.fk(np.array(Q3_B)))
    expect_error('regression', make_and_plan, RequestError, cause)


def test_regression_nan_tolerance(planar: GeodesicPlanner) -> None:
    T_a, T_b = planar.robot.fk(np.array([Q3_A, Q3_B]))
    expect_error('regression', lambda: planar.plan(T_a, T_b, tolerance=np.nan), RequestError, r'tolerance.*nan')


@pytest.mark.parametrize(('robot_name', 'q'), [('rrpp', None), ('ur5e', [0.3, -1.2, 1.0, -1.0, 0.5, 0.3])])
def test_regression_roundoff_length_path(robot_name: str, q: list[float] | None) -> None:
    """Found by the fuzzer: plan(T, T) returned goal joints a few ulp from the start and timed()
    made a 1.05 µs law of it (sdot = 1e6, sddot = 0)."""
    robot = load_robot(robot_name)
    T = robot.fk(robot.home if q is None else np.array(q))
    path = GeodesicPlanner(robot).plan(T, T)
    assert path.length == 0.0 or path.timed().duration == 0.0, \
        f'length {path.length:.3g}, duration {path.timed().duration:.3g} s'


def test_regression_plan_validates_goal_late(planar: GeodesicPlanner) -> None:
    """Found by the fuzzer: plan() solved the start IK before validating the goal, so with an
    unreachable start a NaN goal was reported as the start's IKError."""
    T_far = np.eye(4)
    T_far[0, 3] = 5.0
    T_nan = np.eye(4)
    T_nan[0, 3] = np.nan
    expect_error('regression', lambda: planar.plan(T_far, T_nan), RequestError,
                 r'^goal pose: transform contains NaN or inf$')
    expect_error('regression', lambda: planar.plan(T_far, None, None, [np.nan] * 3), RequestError,
                 r'^goal_joints: joint values contain NaN or inf')


def test_regression_same_pose_self_motion() -> None:
    """Found by the fuzzer: plan(T, T) on the panda at its joint limits made a 1.3e-3 rad
    self-motion (the goal IK, seeded with an inexact start solution, went on converging)."""
    robot = load_robot('panda')
    path = GeodesicPlanner(robot).plan(*[robot.fk(np.array(PANDA_AT_LIMITS))] * 2)
    moved = float(np.abs(path.evaluate(S_CHECK)[0] - path.q_start).max())
    assert moved == 0.0 and path.length == 0.0, f'joints moved by {moved:.3g} rad'
    assert path.timed().duration == 0.0


@pytest.mark.parametrize('robot_name', ['planar_3r', 'rrpp', 'ur5e', 'panda'])
@pytest.mark.parametrize('ratio', [1e-3, 1e-1, 10.0, 1e2])
def test_every_accepted_weight_ratio_plans(robot_name, ratio):
    """The node accepts orientation_weight / position_weight in [1e-3, 1e2] (WEIGHT_RATIO): each
    such metric must plan on every preset. (Regression: panda at ratio 10 raised numpy's
    LinAlgError out of the Gauss-Newton guess, whose regularisation did not scale with the weights.)"""
    from geodesic_planner.core.transforms import pose_error
    robot = load_robot(robot_name)
    planner = GeodesicPlanner(robot, orientation_weight=ratio)
    rng = np.random.default_rng(1)
    for _ in range(3):
        q0 = np.clip(robot.home + rng.uniform(-0.3, 0.3, robot.dof), robot.lower, robot.upper)
        q1 = np.clip(q0 + rng.uniform(-0.3, 0.3, robot.dof), robot.lower, robot.upper)
        path = planner.plan(None, robot.fk(q1), start_joints=q0)
        dp, dr = pose_error(path.ee_poses(np.array([1.0]))[0], robot.fk(q1))
        assert dp < 1e-6 and dr < 1e-6


# ---------------------------------------------------------------------- method='collocation'
def _no_pullback(planner: GeodesicPlanner, monkeypatch: pytest.MonkeyPatch) -> None:
    """Make any IK between the two ends (the pull-back's batched IK at the mesh nodes) fail loudly."""
    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError('IK at the mesh nodes with method="collocation"')
    monkeypatch.setattr(planner, 'initial_guess', refuse)
    monkeypatch.setattr('geodesic_planner.core.pullback.gauss_newton_batch', refuse)
    monkeypatch.setattr('geodesic_planner.core.pullback.dls_batch', refuse)


@pytest.mark.parametrize('robot_name', ['planar_3r', 'ur5e'])
def test_method_collocation_uses_ik_only_at_the_ends(robot_name: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the default takes the pull-back, 'collocation' solves the BVP from the two IK ends."""
    robot = load_robot(robot_name)
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    if robot_name == 'planar_3r':
        T_a, T_b = robot.fk(np.array([Q3_A, Q3_B]))
    else:
        T_a, T_b = _line_move(robot, np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2]), [0.2, -0.1, 0.15],
                              [0.0, 0.0, np.pi / 6])
    assert planner.plan(T_a, T_b).solver.method == 'pullback'
    _no_pullback(planner, monkeypatch)
    path = planner.plan(T_a, T_b, method='collocation')
    rep = path.solver
    assert rep.method == 'collocation' and rep.status == 0 and rep.iterations >= 1
    assert np.isnan(rep.path_error)
    # Ends at the goal pose, geodesic equations (library residual and finite differences of fk),
    # constant metric speed: the same checks as every planned path.
    check_path(planner, path, None, None, T_a, T_b)
    assert_allclose(robot.fk(path.q_goal), T_b, atol=1e-9)


def test_methods_agree_on_the_paper_3r_example() -> None:
    """The pull-back (exact to path_tolerance, 1e-9 m) and collocation (tol 1e-5, which keeps the
    tool within about 1e-8 m of the geodesic) give the same path."""
    robot = load_robot('planar_3r')
    planner = GeodesicPlanner(robot)
    T_a, T_b = robot.fk(np.array([Q3_A, Q3_B]))
    auto = planner.plan(T_a, T_b)
    colloc = planner.plan(T_a, T_b, method='collocation')
    assert (auto.solver.method, colloc.solver.method) == ('pullback', 'collocation')
    s = np.linspace(0.0, 1.0, 2001)
    q_p, q_c = auto.evaluate(s, order=0)[0], colloc.evaluate(s, order=0)[0]
    assert np.abs(q_p - q_c).max() <= 1e-7
    assert np.abs(robot.fk(q_p)[:, :3, 3] - robot.fk(q_c)[:, :3, 3]).max() <= 1e-8
    assert colloc.length == pytest.approx(auto.length, rel=1e-8)


def test_method_collocation_through_via_points(monkeypatch: pytest.MonkeyPatch) -> None:
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    qs = robot.home + np.array([[0, 0, 0, 0, 0, 0], [0.3, 0.1, 0, 0, 0, 0], [0.3, 0.1, 0.2, 0, 0.3, 0]])
    poses = list(robot.fk(qs))
    auto = planner.plan_through(poses, qs[0])
    assert auto.solver.method == 'pullback'
    _no_pullback(planner, monkeypatch)
    path = planner.plan_through(poses, qs[0], method='collocation')
    assert path.solver.method == 'collocation' and all(p.solver.method == 'collocation' for p in path.pieces)
    check_path(planner, path, qs[0], None, None, poses[-1])
    s = np.linspace(0.0, 1.0, 1001)
    assert np.abs(auto.evaluate(s, order=0)[0] - path.evaluate(s, order=0)[0]).max() <= 1e-6


@pytest.mark.parametrize('method', ['pullback', 'Collocation', '', None, 3])
def test_invalid_method_is_a_request_error(planar: GeodesicPlanner, method: Any) -> None:
    with pytest.raises(RequestError, match="method must be one of 'auto', 'collocation'"):
        planar.plan(None, None, Q3_A, Q3_B, method=method)
    with pytest.raises(RequestError, match='method must be one of'):
        planar.plan_joints(Q3_A, Q3_B, method=method)
    with pytest.raises(RequestError, match='method must be one of'):
        planar.plan_through([None, planar.robot.fk(np.array(Q3_B))], Q3_A, method=method)


def test_a_geodesic_that_overshoots_a_limit_between_nodes_is_refused():
    """Found by the fuzz tests (test_fuzz_plan_joints, in CI): a goal with two joints exactly on
    their lower limits; the collocation geodesic passes the prismatic joint's limit by 3.2e-6 m
    between its last two nodes and turns back. Checked at the nodes and a few points between,
    the path was returned; the check now finds the turning point."""
    from geodesic_planner import chain_from_dh
    from geodesic_planner.core.errors import LimitError

    tool = np.eye(4)
    tool[2, 3] = 0.258744940713201
    robot = chain_from_dh('dh4s', [(0.0, 0.0, 0.5408209156193913, 1.5421067995858024),
                                   (0.0, 0.0, 0.0, PI / 2),
                                   (0.0, 0.0, 1.2889962859066229, 1.094042428748227),
                                   (-2.8365184687945253, 0.0, 0.5376042457933637, 1.094042428748227)],
                          ['prismatic', 'revolute', 'revolute', 'revolute'], tool=tool,
                          lower=[-0.2, -2.0, -PI, -PI], upper=[0.3, 1.0, PI, PI],
                          max_velocity=0.862041499259387, max_acceleration=6.744793482341451)
    planner = GeodesicPlanner(robot, metric='paper', position_weight=0.3, orientation_weight=1.0, epsilon=1e-3)
    q_a = [-0.14194411358248968, -1.7807, -1.341302983450162, 0.7341915033626707]
    q_b = [-0.2, -2.0, -1.341302983450162, 1.0354039378056323]
    with pytest.raises(LimitError, match=r"joint 'joint1' reaches -0\.2000[0-9]+ at s = 0\.9[0-9]+"):
        planner.plan_joints(q_a, q_b)
    # the same geodesic without the limit check: out by 3.2e-6 m between the last two nodes
    path = GeodesicPlanner(robot, metric='paper', position_weight=0.3, orientation_weight=1.0, epsilon=1e-3,
                           check_limits=False).plan_joints(q_a, q_b)
    q = path.evaluate(np.linspace(0.0, 1.0, 20001), order=0)[0]
    assert 3e-6 < robot.lower[0] - q[:, 0].min() < 3.5e-6
