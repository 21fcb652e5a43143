"""Arms with more than 6 joints: the tool exactly on line + slerp, the redundancy resolved by least
joint motion (docs/maths.md#redundant-arms).

Every check is against computations independent of the library: the arms' forward kinematics written
out in test/urdf_util.py (Panda and xArm 7 from their published modified DH, the iiwa-like URDF from
its DH table, an 8-joint arm: the xArm 7 with one more wrist joint), Jacobians by finite differences
of that FK, IK by Newton's method on it, and energies by quadrature of finite differences. Moves: a
start drawn within the limits away from singularities and the goal pose of a nearby configuration
(issue 21), kept when an IK continuation of the oracle follows its line + slerp.
"""
from __future__ import annotations

import os

import numpy as np
import pytest
import urdf_util as U
from planning_checks import check_path, check_trajectory

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import PathFollowError
from geodesic_planner.core.kinematics import REVOLUTE, chain_from_dh
from geodesic_planner.core.metric import Metric
from geodesic_planner.core.redundant import LineTask, RedundantEquations
from geodesic_planner.core import redundant_solve as solve
from geodesic_planner.core.redundant_solve import redundant_path

DATA = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data'))
#: Line and slerp errors allowed (issue 21), m and rad.
EXACT = 1e-8
#: Dense samples of s for the tool's errors (not only the mesh nodes).
S_DENSE = np.linspace(0.0, 1.0, 2001)


def xarm7():
    return chain_from_dh('xarm7_like', U.XARM7_MDH, [REVOLUTE] * 7, modified=True, lower=U.XARM7_LOWER,
                         upper=U.XARM7_UPPER, max_velocity=np.pi)


#: An 8-joint arm (two null-space directions): the xArm 7 with one more wrist joint.
ROWS8 = [*U.XARM7_MDH, (np.pi / 2, 0.0, 0.08, 0.0)]


def eight_joints():
    return chain_from_dh('arm8', ROWS8, [REVOLUTE] * 8, modified=True, lower=[-3.0] * 8, upper=[3.0] * 8)


ARMS = {
    'panda': (lambda: load_robot('panda'), U.panda_fk_batch),
    'iiwa_like_7r_urdf': (lambda: load_robot(os.path.join(DATA, 'iiwa_like_7r.urdf')), U.arm_fk_batch(U.IIWA)),
    'xarm7_like': (xarm7, U.xarm7_fk_batch),
    'eight_joints': (eight_joints, lambda qs: U.dh_fk_batched(ROWS8, ['revolute'] * 8, qs, modified=True)),
}


def fd_jacobian(fkb, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Geometric Jacobian (base frame, rows [v; ω]) by central differences of an FK, (dof,) -> (6, dof)."""
    n = q.size
    T = fkb(np.concatenate([q + h * np.eye(n), q - h * np.eye(n)]))
    dp = (T[:n, :3, 3] - T[n:, :3, 3]) / (2 * h)
    W = (T[:n, :3, :3] - T[n:, :3, :3]) / (2 * h) @ fkb(q[None])[0, :3, :3].T
    w = 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]], axis=1)
    return np.concatenate([dp, w], axis=1).T


def null_space(fkb, q: np.ndarray) -> np.ndarray:
    """Orthonormal null-space basis (dof, dof − 6) of the finite-difference Jacobian at q."""
    return np.linalg.svd(fd_jacobian(fkb, q))[2][6:].T


def followable(fkb, T_a: np.ndarray, T_b: np.ndarray, q_a: np.ndarray) -> bool:
    """The oracle's IK, continued along line + slerp from q_a in 40 steps, follows it without a jump
    and away from singularities."""
    try:
        qs = U.continuation_ik(fkb, U.line_slerp_oracle(T_a, T_b, np.linspace(0.0, 1.0, 41)), q_a)
    except AssertionError:
        return False
    sv = min(np.linalg.svd(fd_jacobian(fkb, q), compute_uv=False)[-1] for q in qs[::5])
    return bool(np.abs(np.diff(qs, axis=0)).max() < 0.1 and sv > 0.02)


def random_moves(robot, fkb, seed: int, count: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(q_a, T_a, T_b): a start within the limits (10 % margin, revolute ranges cut to ±π) with
    the Jacobian's smallest singular value >= 0.05, and the pose of a configuration nearby (every
    joint moved by up to 0.25 rad), its line + slerp followable."""
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    lo, hi = lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)
    moves = []
    for _ in range(50 * count):
        q_a = rng.uniform(lo, hi)
        q_b = np.clip(q_a + rng.uniform(-0.25, 0.25, robot.dof), lo, hi)
        if min(np.linalg.svd(fd_jacobian(fkb, q), compute_uv=False)[-1] for q in (q_a, q_b)) < 0.05:
            continue
        T_a, T_b = fkb(np.stack([q_a, q_b]))
        if followable(fkb, T_a, T_b, q_a):
            moves.append((q_a, T_a, T_b))
        if len(moves) == count:
            return moves
    raise AssertionError('could not draw enough followable moves')


@pytest.fixture(scope='module', params=list(ARMS))
def arm(request):
    make, fkb = ARMS[request.param]
    robot = make()
    seed = 2100 + list(ARMS).index(request.param)
    return robot, fkb, GeodesicPlanner(robot), random_moves(robot, fkb, seed, 6)


def tool_errors(fkb, path, T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """Largest line (m) and slerp (rad) errors of the path's tool on S_DENSE, by the oracle's FK."""
    return U.tool_deviation(fkb, path.evaluate(S_DENSE, order=0)[0], T_a, T_b, S_DENSE)


# ---------------------------------------------------------------------- the equation
def test_equations_against_finite_differences(arm):
    """J, dJ[u], a = −J⁺ J̇ q' (J q' constant, a ⊥ null space) and q''' against finite differences."""
    robot, fkb, _, moves = arm
    eq = RedundantEquations(robot, Metric())
    rng = np.random.default_rng(5)
    for q_a, _, _ in moves[:3]:
        q, v, u = q_a, rng.normal(size=robot.dof), rng.normal(size=robot.dof)
        X, T = robot.generators(q[None])
        J = eq.jacobian(X, T)[0]
        np.testing.assert_allclose(J, fd_jacobian(fkb, q), atol=1e-8)
        h = 1e-6
        rate = (eq.jacobian(*robot.generators((q + h * u)[None])) - eq.jacobian(*robot.generators((q - h * u)[None])))
        np.testing.assert_allclose(eq.rate(X, T, u[None])[0], rate[0] / (2 * h), atol=1e-8)
        a = eq.acceleration(q[None], v[None])[0]
        # d/ds [J(q(s)) q'(s)] = 0 on q(s) = q + s v + s² a / 2, by differences of the oracle's Jacobian.
        h = 1e-4
        twist = [fd_jacobian(fkb, q + d * v + d * d / 2 * a) @ (v + d * a) for d in (-h, h)]
        assert np.abs((twist[1] - twist[0]) / (2 * h)).max() < 1e-5 * (1.0 + np.sum(v * v))
        assert np.abs(null_space(fkb, q).T @ a).max() < 1e-7 * (1.0 + np.abs(a).max())
        a2, jerk = eq.jerk(q[None], v[None])
        np.testing.assert_allclose(a2[0], a, rtol=1e-12, atol=1e-12)
        h = 1e-5
        ahead = eq.acceleration((q + h * v + h * h / 2 * a)[None], (v + h * a)[None])[0]
        back = eq.acceleration((q - h * v + h * h / 2 * a)[None], (v - h * a)[None])[0]
        np.testing.assert_allclose(jerk[0], (ahead - back) / (2 * h), atol=1e-6 * (1.0 + np.abs(jerk).max()))


# ---------------------------------------------------------------------- exact line + slerp
def test_goal_pose_exact_line_and_slerp(arm):
    """From start joints to a goal pose: line and slerp errors <= 1e-8 on 2001 samples (oracle FK),
    the start exactly the given joints, the goal on the pose, a valid path (planning_checks), and
    its timing within the robot's limits."""
    robot, fkb, planner, moves = arm
    for q_a, T_a, T_b in moves:
        path = planner.plan(None, T_b, start_joints=q_a)
        assert path.solver.method == 'redundant', path.solver.message
        dp, dr = tool_errors(fkb, path, T_a, T_b)
        assert dp <= EXACT and dr <= EXACT, (dp, dr)
        assert path.solver.path_error <= planner.path_tolerance
        assert np.array_equal(path.q_start, q_a)
        assert np.abs(U.pose_residual(fkb(path.q_goal[None])[0], T_b)).max() < 1e-9
        assert np.array_equal(path.ik_goal.q, path.q_goal)
        check_path(planner, path, q_a, None, T_b=T_b)
        check_trajectory(path, path.timed(), robot.max_velocity, robot.max_acceleration)


def test_goal_joints_reached_exactly(arm):
    """With goal joints the path ends exactly there (bitwise), the tool on line + slerp."""
    robot, fkb, planner, moves = arm
    for q_a, _, T_b in moves[:3]:
        q_b = U.newton_ik(fkb, T_b, planner.plan(None, T_b, start_joints=q_a).q_goal + 0.05)
        path = planner.plan_joints(q_a, q_b)
        assert path.solver.method == 'redundant', path.solver.message
        assert np.array_equal(path.q_start, q_a) and np.array_equal(path.q_goal, q_b)
        assert np.array_equal(path.evaluate(np.array([0.0, 1.0]), order=0)[0], np.stack([q_a, q_b]))
        dp, dr = tool_errors(fkb, path, *fkb(np.stack([q_a, q_b])))
        assert dp <= EXACT and dr <= EXACT, (dp, dr)


def test_six_joints_unchanged():
    """On a 6-joint arm the construction has no null space: it is the pull-back geodesic, and the
    planner still plans the pull-back."""
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    assert planner.redundant is None
    q_a = robot.home + np.array([0.1, 0.2, -0.1, 0.2, 0.3, -0.2])
    q_b = q_a + np.array([0.2, -0.1, 0.15, 0.1, -0.2, 0.3])
    pullback = planner.plan_joints(q_a, q_b)
    assert pullback.solver.method == 'pullback'
    task = LineTask.between(robot.fk(q_a), robot.fk(q_b))
    path = redundant_path(RedundantEquations(robot, Metric()), task, q_a, q_b, free_end=False,
                          path_tolerance=1e-9, t0=0.0)
    s = np.linspace(0.0, 1.0, 501)
    np.testing.assert_allclose(path.evaluate(s, order=0)[0], pullback.evaluate(s, order=0)[0], atol=1e-9)
    np.testing.assert_allclose(path.evaluate(s)[2], pullback.evaluate(s)[2], atol=1e-6)


# ---------------------------------------------------------------------- the criterion
def energy(fkb, qs: np.ndarray) -> float:
    """∫₀¹ |q'|² ds of samples qs (uniform in s), by differences and the trapezoid rule."""
    dq = np.gradient(qs, 1.0 / (len(qs) - 1), axis=0, edge_order=2)
    e = np.sum(dq * dq, axis=1)
    return float(np.sum(0.5 * (e[1:] + e[:-1])) / (len(qs) - 1))


def perturbed(fkb, qs: np.ndarray, s: np.ndarray, T_a, T_b, shape: np.ndarray, delta: float) -> np.ndarray:
    """qs moved by delta · shape(s) along the oracle's null space and put back on line + slerp by
    the oracle's Newton IK (minimal-norm steps): another path with the tool exactly on the line."""
    targets = U.line_slerp_oracle(T_a, T_b, s)
    out = [U.newton_ik(fkb, T, q + delta * w * null_space(fkb, q)[:, 0]) for q, T, w in zip(qs, targets, shape)]
    return np.array(out)


@pytest.mark.parametrize('free', [True, False], ids=['goal pose', 'goal joints'])
def test_least_joint_motion(arm, free):
    """The path is stationary and a minimum of E = ∫|q'|² among paths with the tool on the line:
    E of paths moved along the null space by ±δ (the end too, to a goal pose) grows like δ² with no
    linear term; to a goal pose the path ends without self-motion speed (Nᵀ q'(1) = 0) and beats
    the path to the IK's goal configuration."""
    robot, fkb, planner, moves = arm
    q_a, T_a, T_b = moves[0]
    path = planner.plan(None, T_b, start_joints=q_a)
    if not free:
        path = planner.plan_joints(q_a, path.q_goal)
    s = np.linspace(0.0, 1.0, 201)
    qs = path.evaluate(s, order=0)[0]
    shape = s if free else np.sin(np.pi * s)
    E0 = energy(fkb, qs)
    Ep, Em = (energy(fkb, perturbed(fkb, qs, s, T_a, T_b, shape, d)) for d in (0.03, -0.03))
    curvature = Ep + Em - 2 * E0
    assert curvature > 1e-4 * E0, (E0, Ep, Em)
    assert abs(Ep - Em) < 0.05 * curvature, (E0, Ep, Em)
    if free:
        h = 1e-4
        q1 = path.evaluate(np.array([1.0 - 2 * h, 1.0 - h, 1.0]), order=0)[0]
        dq_end = (3 * q1[2] - 4 * q1[1] + q1[0]) / (2 * h)
        assert np.abs(null_space(fkb, q1[2]).T @ dq_end).max() < 1e-5 * np.abs(dq_end).max()
        ik_goal = planner._goal_ik(T_b, q_a, None).q
        E_fixed = energy(fkb, planner.plan_joints(q_a, ik_goal).evaluate(s, order=0)[0])
        assert E0 - E_fixed <= 1e-9, (E0, E_fixed)


def test_limit_of_the_epsilon_geodesics():
    """The geodesics of G + εI between the same joints approach the least-motion path as ε → 0,
    about linearly in ε (the criterion is their limit)."""
    robot, fkb = load_robot('panda'), U.panda_fk_batch
    q_a, _, T_b = random_moves(robot, fkb, 2150, 1)[0]
    exact = GeodesicPlanner(robot).plan(None, T_b, start_joints=q_a)
    s = np.linspace(0.0, 1.0, 201)
    q0 = exact.evaluate(s, order=0)[0]
    gaps = []
    for eps in (1e-3, 1e-4, 1e-5):
        path = GeodesicPlanner(robot, epsilon=eps, tol=1e-8).plan_joints(q_a, exact.q_goal)
        assert path.solver.method == 'collocation'
        gaps.append(float(np.abs(path.evaluate(s, order=0)[0] - q0).max()))
    assert gaps[0] > gaps[1] > gaps[2], gaps
    assert 4.0 < gaps[0] / gaps[1] < 25.0 and 4.0 < gaps[1] / gaps[2] < 25.0, gaps


# ---------------------------------------------------------------------- other requests
def test_self_motion_keeps_the_tool_still(arm):
    """Goal joints on the start's self-motion manifold (same pose): the tool stays put while the
    joints move exactly from start to goal."""
    robot, fkb, planner, moves = arm
    q_a, T_a, _ = moves[1]
    q_b = U.newton_ik(fkb, T_a, q_a + 0.2 * null_space(fkb, q_a)[:, 0])
    assert np.abs(q_b - q_a).max() > 0.05
    path = planner.plan_joints(q_a, q_b)
    assert path.solver.method == 'redundant'
    assert np.array_equal(path.q_goal, q_b)
    T = fkb(path.evaluate(S_DENSE, order=0)[0])
    dp, dr = U.tool_deviation(fkb, path.evaluate(S_DENSE, order=0)[0], T_a, T_a, S_DENSE)
    assert dp <= EXACT and dr <= EXACT, (dp, dr)
    assert np.abs(T[:, :3, 3] - T_a[:3, 3]).max() <= EXACT


def test_via_points_chain_the_chosen_goals(arm):
    """plan_through: each piece starts exactly where the previous one chose to end, each on its
    own line + slerp."""
    robot, fkb, planner, moves = arm
    q_a, T_a, T_b = moves[2]
    T_c = fkb((planner.plan(None, T_b, start_joints=q_a).q_goal + 0.1)[None])[0]
    path = planner.plan_through([T_a, T_b, T_c], start_joints=q_a)
    assert len(path.pieces) == 2
    assert np.array_equal(path.pieces[0].q_goal, path.pieces[1].q_start)
    for piece, (T_from, T_to) in zip(path.pieces, ((T_a, T_b), (T_b, T_c))):
        assert piece.solver.method == 'redundant'
        dp, dr = tool_errors(fkb, piece, T_from, T_to)
        assert dp <= EXACT and dr <= EXACT, (dp, dr)


def test_free_goal_outside_the_limits_keeps_the_ik_goal():
    """When the least-motion goal configuration lies outside a joint's limits, the planner ends at
    the goal IK's configuration instead (still exactly on line + slerp)."""
    fkb = U.xarm7_fk_batch
    wide = xarm7()
    for q_a, T_a, T_b in random_moves(wide, fkb, 2160, 6):
        free = GeodesicPlanner(wide).plan(None, T_b, start_joints=q_a)
        ik = GeodesicPlanner(wide)._goal_ik(T_b, q_a, None).q
        fixed = GeodesicPlanner(wide).plan_joints(q_a, ik).evaluate(S_DENSE, order=0)[0]
        k = int(np.argmax(np.abs(free.q_goal - ik)))
        if abs(free.q_goal[k] - ik[k]) < 0.01:
            continue
        # a limit on joint k between the IK's goal (and the whole path there) and the free goal
        side = np.sign(free.q_goal[k] - ik[k])
        edge = fixed[:, k].max() if side > 0 else fixed[:, k].min()
        bound = 0.5 * (edge + free.q_goal[k])
        if side * (free.q_goal[k] - edge) < 0.01:
            continue
        lower, upper = list(U.XARM7_LOWER), list(U.XARM7_UPPER)
        (upper if side > 0 else lower)[k] = bound
        narrow = chain_from_dh('xarm7_narrow', U.XARM7_MDH, [REVOLUTE] * 7, modified=True, lower=lower,
                               upper=upper, max_velocity=np.pi)
        planner = GeodesicPlanner(narrow)
        path = planner.plan(None, T_b, start_joints=q_a)
        assert path.solver.method == 'redundant'
        np.testing.assert_array_equal(path.q_goal, planner._goal_ik(T_b, q_a, None).q)
        assert side * (bound - path.evaluate(S_DENSE, order=0)[0][:, k]).min() >= -1e-9
        dp, dr = tool_errors(fkb, path, T_a, T_b)
        assert dp <= EXACT and dr <= EXACT, (dp, dr)
        return
    pytest.fail('no move whose free goal lies beyond the fixed path on some joint')


def test_singular_start_is_refused_at_its_start_and_collocation_plans_when_asked():
    """At a singular start (xArm 7 stretched straight up) no finite joint motion moves the tool along
    this line: refused with fraction 0, the singularity and the tool's place (issue 36: never a path
    off the line); method='collocation' plans the geodesic of G + εI when asked, and says so."""
    robot = xarm7()
    q_a = np.zeros(7)
    q_b = q_a + np.array([0.1, 0.2, -0.1, 0.3, 0.1, 0.2, 0.1])
    assert np.linalg.svd(fd_jacobian(U.xarm7_fk_batch, q_a), compute_uv=False)[-1] < 1e-9
    x, y, z = U.xarm7_fk_batch(q_a[None])[0, :3, 3]
    match = rf'singularity of .* at its start \(0 % of the way, tool at {x:.4f}, {y:.4f}, {z:.4f} m'
    with pytest.raises(PathFollowError, match=match) as info:
        GeodesicPlanner(robot).plan_joints(q_a, q_b)
    assert info.value.fraction < 5e-5
    assert GeodesicPlanner(robot).plan_joints(q_a, q_b, method='collocation').solver.method == 'collocation'


def test_a_traced_line_seeds_the_least_motion_solve():
    """The planner's second try of the least-motion solve starts from the line traced step by step
    (core/trace.py; it replaced the continuation's seeds): from those seeds alone (a large move,
    panda) the least-motion path is planned exactly."""
    import time

    from geodesic_planner.core.continuation import LineFollow
    from geodesic_planner.core.trace import line_curve, trace
    robot = load_robot('panda')
    q_a = np.array([-1.055544, 0.246749, -1.36684, -1.487687, 1.874364, 1.577671, 1.516279])
    q_b = np.array([-1.568835, 0.860377, -1.969733, -1.947109, 2.226746, 1.260852, 0.906539])
    T_a, T_b = U.panda_fk_batch(np.stack([q_a, q_b]))
    planner = GeodesicPlanner(robot)
    task = LineTask.between(robot.fk(q_a), robot.fk(q_b))
    traced = trace(robot, line_curve(task.poses, task.twist), q_a, metric=planner.metric).path
    assert traced is not None and traced.solver.method == 'trace'
    seeds = LineFollow(traced.s_nodes, traced.q_nodes, 1.0, None)
    path = solve.plan_redundant(planner.redundant, task, q_a, traced.q_goal, None, planner.resolve_ends(
        None, T_b, start_joints=q_a)[3], t0=time.perf_counter(), path_tolerance=1e-9, max_nodes=2000,
        time_limit=10.0, check_limits=None, seeds=seeds)
    assert path is not None and path.solver.method == 'redundant'
    dp, dr = tool_errors(U.panda_fk_batch, path, T_a, T_b)
    assert dp <= EXACT and dr <= EXACT, (dp, dr)
