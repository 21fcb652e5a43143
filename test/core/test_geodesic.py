"""Geodesics against exact oracles (docs/maths.md#oracles).

* The geodesic equations: ∂a/∂q, ∂a/∂q' against finite differences; a = q'' against the
  Christoffel-symbol form of eq. (4) built here from finite differences of G; task-space
  acceleration zero for 6-joint arms and the planar 3R.
* Planar 3R (paper Table 1): the tool moves on the straight line A→B with φ linear in s; the joint
  path equals the closed-form IK along that line; constant metric speed equal to the exact length.
* 6-joint arms (ur5e, the KR6-like URDF): line + slerp, IK along it (independent Newton IK on an
  independent DH product, continued from the start).
* RRPP (no closed form): ODE residual from finite differences, boundary conditions, constant speed,
  zero first variation of the energy, and the tool path bowing off the chord by a fraction of a mm.
"""
from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest
import urdf_util as U
from numpy.testing import assert_allclose
from planning_checks import Q3_A, Q3_B, expect_error

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import BVPError, RequestError
from geodesic_planner.core.geodesic import GeodesicEquations, solve_geodesic_bvp
from geodesic_planner.core.metric import Metric
from geodesic_planner.core.urdf import chain_from_urdf
from geodesic_planner.io.requests import load_request

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DATA = os.path.join(ROOT, 'geodesic_planner', 'data')
KR6 = os.path.join(DATA, 'kr6_like.urdf')
IIWA = os.path.join(DATA, 'iiwa_like_7r.urdf')
PAPER_3R = os.path.join(ROOT, 'msg_examples', 'paper_3r.yaml')
RRPP_A = np.array([0.123, -1.539, 0.276, -0.640])
RRPP_B = np.array([0.129, -1.629, 0.239, -0.643])
#: Required accuracy against the exact oracle: joint path to 1e-5 rad, tool path to 1e-6 m (and rad).
JOINT_TOL, TOOL_TOL = 1e-5, 1e-6


def mixed_urdf():
    rows = [(0.0, 0.412, 0.0, -np.pi / 2), (0.0, 0.154, 0.0, np.pi / 2), (-np.pi / 2, 0.3, 0.0, 0.0),
            (0.0, 0.0, 0.0, -np.pi / 2), (0.0, 0.0, 0.0, np.pi / 2), (0.0, 0.263, 0.0, 0.0)]
    kinds = ['revolute', 'revolute', 'prismatic', 'revolute', 'revolute', 'revolute']
    return chain_from_urdf(U.dh_to_urdf('mixed', rows, kinds, twist_seed=2, continuous=(5,),
                                        base=U.xyz_rpy((0.1, 0, 0.2), (0.2, 0.1, 0.3))))


# (robot factory, metric) pairs for the equation checks
EQUATION_CASES = {
    'planar_3r': (lambda: load_robot('planar_3r'), Metric()),
    'rrpp': (lambda: load_robot('rrpp'), Metric()),
    'ur5e': (lambda: load_robot('ur5e'), Metric()),
    'ur5e_weighted': (lambda: load_robot('ur5e'), Metric(position_weight=2.0, orientation_weight=0.4)),
    'panda_eps': (lambda: load_robot('panda'), Metric(epsilon=1e-3)),
    'kr6_urdf': (lambda: load_robot(KR6), Metric()),
    'iiwa_urdf_eps': (lambda: load_robot(IIWA), Metric(epsilon=1e-2)),
    'mixed_urdf': (mixed_urdf, Metric(position_weight=1.5)),
}


def regular_samples(robot, metric, rng, n, max_cond=1e5):
    """Random (q, v) with a well-conditioned metric (finite differences need it)."""
    lo = np.maximum(np.where(np.isfinite(robot.lower), robot.lower, -np.pi), -2.5)
    hi = np.minimum(np.where(np.isfinite(robot.upper), robot.upper, np.pi), 2.5)
    qs = []
    while len(qs) < n:
        q = rng.uniform(lo, hi)
        if np.linalg.cond(metric.tensor(robot, q)) < max_cond:
            qs.append(q)
    return np.array(qs), rng.normal(size=(n, robot.dof))


# ---------------------------------------------------------------------- the equations
@pytest.mark.parametrize('case', list(EQUATION_CASES))
def test_equation_jacobians_match_finite_differences(case):
    make, metric = EQUATION_CASES[case]
    robot = make()
    eq = GeodesicEquations(robot, metric)
    qs, vs = regular_samples(robot, metric, np.random.default_rng(21), 5)
    a, da_dq, da_dv = eq.evaluate(qs, vs)
    assert a.shape == (5, robot.dof) and da_dq.shape == da_dv.shape == (5, robot.dof, robot.dof)
    h = 1e-6
    fd_q = np.zeros_like(da_dq)
    fd_v = np.zeros_like(da_dv)
    for m in range(robot.dof):
        e = np.zeros(robot.dof)
        e[m] = h
        fd_q[:, :, m] = (eq.acceleration(qs + e, vs) - eq.acceleration(qs - e, vs)) / (2 * h)
        fd_v[:, :, m] = (eq.acceleration(qs, vs + e) - eq.acceleration(qs, vs - e)) / (2 * h)
    for k in range(5):
        for got, fd in ((da_dq[k], fd_q[k]), (da_dv[k], fd_v[k])):
            err = np.linalg.norm(got - fd) / max(np.linalg.norm(fd), 1e-3)
            assert err < 1e-5, f'relative error {err:.3g}'
    assert_allclose(eq.acceleration(qs, vs), a, atol=1e-14)


@pytest.mark.parametrize('case', list(EQUATION_CASES))
def test_jerk_is_the_derivative_of_the_acceleration_along_the_flow(case):
    """jerk(): the third derivative equals ∂a/∂q q' + ∂a/∂q' q'' (the analytic Jacobians, checked
    against finite differences above) and the central difference of a along the geodesic flow."""
    make, metric = EQUATION_CASES[case]
    robot = make()
    eq = GeodesicEquations(robot, metric)
    qs, vs = regular_samples(robot, metric, np.random.default_rng(23), 5)
    a, da_dq, da_dv = eq.evaluate(qs, vs)
    a2, j = eq.jerk(qs, vs)
    # round-off: jerk() is compiled (Cholesky), evaluate() numpy (LU); G's conditioning on the kr6
    assert_allclose(a2, a, rtol=1e-10, atol=1e-12 * np.abs(a).max())
    ref = np.einsum('nij,nj->ni', da_dq, vs) + np.einsum('nij,nj->ni', da_dv, a)
    assert_allclose(j, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    h = 1e-5   # a along the flow: (q ± h v + h²/2 a, v ± h a), O(h²) accurate
    fd = (eq.acceleration(qs + h * vs + 0.5 * h * h * a, vs + h * a)
          - eq.acceleration(qs - h * vs + 0.5 * h * h * a, vs - h * a)) / (2 * h)
    assert np.linalg.norm(j - fd) <= 1e-5 * max(np.linalg.norm(fd), 1.0)


def christoffel_acceleration(robot, metric, q, v, h=1e-6):
    """a^i = −Γ^i_kj v^k v^j with Γ^i_kj = ½ g^im (∂_j g_km + ∂_k g_jm − ∂_m g_kj), ∂G by central
    differences of G (eq. 4)."""
    n = robot.dof
    dG = np.zeros((n, n, n))  # dG[m] = ∂G/∂q_m
    for m in range(n):
        e = np.zeros(n)
        e[m] = h
        dG[m] = (metric.tensor(robot, q + e) - metric.tensor(robot, q - e)) / (2 * h)
    # Σ_kj (∂_j g_km + ∂_k g_jm) v^k v^j = 2 Σ_j v^j (∂_j G v)_m ;  Σ_kj ∂_m g_kj v^k v^j = vᵀ ∂_m G v
    first = 2.0 * np.einsum('j,jmk,k->m', v, dG, v)
    third = np.einsum('k,mkj,j->m', v, dG, v)
    return -np.linalg.solve(metric.tensor(robot, q), 0.5 * (first - third))


@pytest.mark.parametrize('case', list(EQUATION_CASES))
def test_acceleration_matches_christoffel_form(case):
    make, metric = EQUATION_CASES[case]
    robot = make()
    eq = GeodesicEquations(robot, metric)
    qs, vs = regular_samples(robot, metric, np.random.default_rng(22), 5)
    a = eq.acceleration(qs, vs)
    for k in range(5):
        ref = christoffel_acceleration(robot, metric, qs[k], vs[k])
        assert np.linalg.norm(a[k] - ref) <= 1e-6 * max(np.linalg.norm(ref), 1.0)


@pytest.mark.parametrize('name, rows', [('ur5e', slice(0, 6)), (KR6, slice(0, 6)),
                                        ('planar_3r', [0, 1, 5])], ids=['ur5e', 'kr6', 'planar_3r'])
def test_geodesic_acceleration_has_zero_task_acceleration(name, rows):
    """Flat task metric (R³ × SO(3), or (x, y, φ) for the 3R): along a geodesic the tool twist
    ξ = J q' is constant, so dξ/ds = J a + (d/ds J) q' = 0 (d/ds J by finite differences)."""
    robot = load_robot(name)
    metric = Metric()
    eq = GeodesicEquations(robot, metric)
    qs, vs = regular_samples(robot, metric, np.random.default_rng(23), 6, max_cond=1e4)
    a = eq.acceleration(qs, vs)
    h = 1e-6
    for q, v, ak in zip(qs, vs, a):
        Jdot_v = (robot.jacobian(q + h * v) - robot.jacobian(q - h * v)) / (2 * h) @ v
        dxi = (robot.jacobian(q) @ ak + Jdot_v)[rows]
        assert np.abs(dxi).max() < 1e-6 * max(1.0, np.abs(Jdot_v).max())


# ---------------------------------------------------------------------- planar 3R, paper Table 1
def my_3r_ik(x, y, phi):
    """Closed-form planar 3R IK, elbow θ2 > 0 (written here)."""
    wx, wy = x - np.cos(phi), y - np.sin(phi)
    t2 = np.arccos((wx**2 + wy**2 - 2.0) / 2.0)
    t1 = np.arctan2(wy, wx) - np.arctan2(np.sin(t2), 1 + np.cos(t2))
    return np.stack([t1, t2, phi - t1 - t2], axis=-1)


@pytest.fixture(scope='module')
def paper_3r():
    req = load_request(PAPER_3R)
    return req, req.plan()


def test_3r_ends_reproduce_table2(paper_3r):
    req, path = paper_3r
    assert_allclose(path.q_start, [0.258, 0.583, -0.317], atol=6e-4)
    assert_allclose(path.q_goal, [0.969, 0.380, -0.574], atol=6e-4)
    assert_allclose(req.robot.fk(path.q_start), req.start, atol=1e-12)
    assert_allclose(req.robot.fk(path.q_goal), req.goal, atol=1e-12)
    rep = path.solver
    assert rep.status == 0 and rep.mesh_size >= 3 and rep.time_ms > 0
    assert rep.method == 'pullback' and rep.iterations == 0 and rep.path_error <= 1e-9
    assert rep.bc_residual <= 1e-12


def test_3r_geodesic_is_the_straight_line_with_linear_phi(paper_3r):
    req, path = paper_3r
    s = np.linspace(0.0, 1.0, 1000)
    q, dq, ddq, dddq = path.evaluate(s)
    assert q.shape == dq.shape == ddq.shape == dddq.shape == (1000, 3)
    pa, pb = req.start[:3, 3], req.goal[:3, 3]
    phi_a = np.arctan2(req.start[1, 0], req.start[0, 0])
    phi_b = np.arctan2(req.goal[1, 0], req.goal[0, 0])
    p_line = pa + s[:, None] * (pb - pa)
    phi_line = phi_a + s * (phi_b - phi_a)
    # joint path against the closed-form IK along the line
    q_oracle = my_3r_ik(p_line[:, 0], p_line[:, 1], phi_line)
    assert np.abs(q - q_oracle).max() <= JOINT_TOL
    # tool path: FK written here (docs/maths.md#robots)
    t1, t12, t123 = q[:, 0], q[:, 0] + q[:, 1], q.sum(axis=1)
    x = np.cos(t1) + np.cos(t12) + np.cos(t123)
    y = np.sin(t1) + np.sin(t12) + np.sin(t123)
    assert np.abs(np.stack([x, y], axis=1) - p_line[:, :2]).max() <= TOOL_TOL
    assert np.abs(t123 - phi_line).max() <= TOOL_TOL
    assert_allclose(path.ee_poses(s)[:, :3, 3], p_line, atol=TOOL_TOL)


def test_3r_constant_metric_speed_equals_exact_length(paper_3r):
    """g = dx² + dy² + 2dφ² is flat: the geodesic's length is √(|Δp|² + 2Δφ²), its speed constant."""
    req, path = paper_3r
    dphi = np.arctan2(req.goal[1, 0], req.goal[0, 0]) - np.arctan2(req.start[1, 0], req.start[0, 0])
    exact = np.sqrt(np.sum((req.goal[:3, 3] - req.start[:3, 3]) ** 2) + 2 * dphi**2)
    s = np.linspace(0.0, 1.0, 1000)
    q, dq, _, _ = path.evaluate(s)
    G = Metric().tensor(req.robot, q)
    speed = np.sqrt(np.einsum('ni,nij,nj->n', dq, G, dq))
    assert_allclose(speed, exact, rtol=1e-6)
    assert_allclose(path.length, exact, rtol=1e-6)
    assert_allclose(path.metric_speed(s), exact, rtol=1e-6)


def test_3r_tool_acceleration_and_jerk_vanish(paper_3r):
    """Paper Table 3 reports tool jerks 0.042 / 0.022 (its solver's error); the exact value is 0."""
    req, path = paper_3r
    robot = req.robot

    def tool_acc(s):
        q, dq, ddq, _ = path.evaluate(s)
        return (np.einsum('nki,ni->nk', robot.jacobian12(q), ddq) + robot.hessian12(q, dq))[:, :3]

    s = np.linspace(1e-3, 1 - 1e-3, 500)
    h = 1e-4
    jerk = (tool_acc(s + h) - tool_acc(s - h)) / (2 * h)
    assert np.abs(tool_acc(s)).max() < 1e-6
    assert np.abs(jerk).max() < 1e-4
    _, _, ddq, dddq = path.evaluate(np.linspace(0, 1, 1000))
    assert np.abs(ddq.sum(axis=1)).max() < 1e-8   # φ'' = Σ θ''
    assert np.abs(dddq.sum(axis=1)).max() < 1e-6  # φ''' = Σ θ'''


@pytest.mark.parametrize('which', ['3r', 'rrpp'])
def test_evaluate_derivatives_are_derivatives(which, paper_3r):
    """evaluate's q', q'', q''' against central differences of its own lower orders."""
    path = paper_3r[1] if which == '3r' else GeodesicPlanner(load_robot('rrpp')).plan(None, None, RRPP_A, RRPP_B)
    h = 1e-5
    s = np.linspace(2 * h, 1 - 2 * h, 201)
    plus, minus, mid = path.evaluate(s + h), path.evaluate(s - h), path.evaluate(s)
    for k in range(3):
        fd = (plus[k] - minus[k]) / (2 * h)
        scale = max(np.abs(mid[k + 1]).max(), 1e-3)
        assert np.abs(fd - mid[k + 1]).max() <= 1e-5 * scale, f'derivative order {k + 1}'


# ---------------------------------------------------------------------- 6-joint arms: line + slerp
ARMS = {
    'ur5e': (lambda: load_robot('ur5e'), U.ur5e_fk_batch, None),
    'kr6_like_urdf': (lambda: load_robot(KR6), U.arm_fk_batch(U.KR6), np.array([0.0, -1.2, 1.0, 0.0, 0.8, 0.0])),
}


@pytest.fixture(scope='module', params=list(ARMS))
def arm_moves(request):
    make, fkb, home = ARMS[request.param]
    robot = make()
    home = robot.home if home is None else home
    moves = U.moderate_moves(fkb, lambda q: np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1],
                             home, robot.lower, robot.upper, seed=31, n=3)
    return robot, fkb, moves


def _check_line_slerp(robot, fkb, path, q_a, T_a, T_b):
    s = np.linspace(0.0, 1.0, 101)
    targets = U.line_slerp_oracle(T_a, T_b, s)
    q_oracle = U.continuation_ik(fkb, targets, q_a)
    q, dq, _, _ = path.evaluate(s)
    assert np.abs(q - q_oracle).max() <= JOINT_TOL
    T = fkb(q)
    assert np.abs(T[:, :3, 3] - targets[:, :3, 3]).max() <= TOOL_TOL
    assert np.abs(U.pose_residual(T, targets)[:, 3:]).max() <= TOOL_TOL
    # constant metric speed = exact length √(|Δp|² + 2θ²)
    Rrel = T_a[:3, :3].T @ T_b[:3, :3]
    theta = np.arccos(np.clip((np.trace(Rrel) - 1) / 2, -1, 1))
    exact = np.sqrt(np.sum((T_b[:3, 3] - T_a[:3, 3]) ** 2) + 2 * theta**2)
    G = Metric().tensor(robot, q)
    assert_allclose(np.sqrt(np.einsum('ni,nij,nj->n', dq, G, dq)), exact, rtol=1e-6)
    assert_allclose(path.length, exact, rtol=1e-6)


def test_six_joint_geodesic_is_line_and_slerp_from_poses(arm_moves):
    robot, fkb, moves = arm_moves
    planner = GeodesicPlanner(robot)
    for _q_a, T_a, T_b in moves:
        path = planner.plan(T_a, T_b)
        assert path.solver.status == 0
        # the planner chose its own start branch; the oracle continues from there
        assert np.abs(U.pose_residual(fkb(path.q_start[None])[0], T_a)).max() < 1e-9
        assert np.abs(U.pose_residual(fkb(path.q_goal[None])[0], T_b)).max() < 1e-9
        _check_line_slerp(robot, fkb, path, path.q_start, T_a, T_b)


def test_six_joint_geodesic_is_line_and_slerp_from_start_joints(arm_moves):
    robot, fkb, moves = arm_moves
    planner = GeodesicPlanner(robot)
    for q_a, T_a, T_b in moves:
        path = planner.plan(None, T_b, start_joints=q_a)
        assert_allclose(path.q_start, q_a, atol=0)
        _check_line_slerp(robot, fkb, path, q_a, T_a, T_b)


def test_collocation_solver_converges_from_a_poor_guess():
    """solve_geodesic_bvp itself (not the line + slerp guess): from joint-space linear
    interpolation it must still find the line + slerp geodesic."""
    robot = load_robot('ur5e')
    eq = GeodesicEquations(robot, Metric())
    q_a = robot.home + np.array([0.2, -0.3, 0.3, 0.1, 0.2, 0.1])
    q_b = q_a + np.array([0.3, 0.2, -0.3, 0.2, -0.2, 0.3])
    s0 = np.linspace(0.0, 1.0, 11)
    out = solve_geodesic_bvp(eq, q_a, q_b, s0, q_a + s0[:, None] * (q_b - q_a),
                             np.tile(q_b - q_a, (11, 1)), tol=1e-8)
    s_sol, q_sol, report = out[0], out[1], out[-1]
    assert report.status == 0 and report.iterations > 1
    T_a, T_b = U.ur5e_fk_batch(np.stack([q_a, q_b]))
    q_oracle = U.continuation_ik(U.ur5e_fk_batch, U.line_slerp_oracle(T_a, T_b, s_sol), q_a)
    assert np.abs(q_sol - q_oracle).max() <= 1e-7
    # and the joint-linear guess was far from it
    assert np.abs(q_a + s_sol[:, None] * (q_b - q_a) - q_oracle).max() > 1e-2


# ---------------------------------------------------------------------- RRPP (no closed form)
@pytest.fixture(scope='module')
def rrpp_path():
    robot = load_robot('rrpp')
    return robot, GeodesicPlanner(robot).plan(None, None, start_joints=RRPP_A, goal_joints=RRPP_B)


def test_rrpp_boundary_conditions_exact(rrpp_path):
    _, path = rrpp_path
    q = path.evaluate(np.array([0.0, 1.0]))[0]
    assert_allclose(q[0], RRPP_A, atol=1e-15)
    assert_allclose(q[1], RRPP_B, atol=1e-15)
    assert_allclose(path.q_start, RRPP_A, atol=0)
    assert_allclose(path.q_goal, RRPP_B, atol=0)


def test_rrpp_ode_residual_small(rrpp_path):
    """G q'' + Jᵀ H(q, q') = 0 with q'' a finite difference of the path's own q'."""
    robot, path = rrpp_path
    h = 1e-5
    s = np.linspace(h, 1 - h, 501)
    q, dq, _, _ = path.evaluate(s)
    qdd = (path.evaluate(s + h)[1] - path.evaluate(s - h)[1]) / (2 * h)
    G = Metric().tensor(robot, q)
    JtH = np.einsum('nki,nk->ni', robot.jacobian12(q), robot.hessian12(q, dq))
    res = np.einsum('nij,nj->ni', G, qdd) + JtH
    assert np.abs(JtH).max() > 1e-3                 # the equation is not trivially satisfied
    assert np.abs(res).max() < 1e-5 * np.abs(JtH).max()
    assert path.residual(np.linspace(0, 1, 1001)).max() < 1e-6


def test_rrpp_constant_metric_speed(rrpp_path):
    robot, path = rrpp_path
    s = np.linspace(0, 1, 1001)
    q, dq, _, _ = path.evaluate(s)
    speed = np.sqrt(np.einsum('ni,nij,nj->n', dq, Metric().tensor(robot, q), dq))
    assert_allclose(speed, speed.mean(), rtol=1e-6)
    assert_allclose(path.length, speed.mean(), rtol=1e-6)


def test_rrpp_energy_is_stationary(rrpp_path):
    """First variation of E = ∫ q'ᵀ G q' ds vanishes on a geodesic (for η with η(0) = η(1) = 0),
    while it does not on the joint-space straight line."""
    robot, path = rrpp_path
    s = np.linspace(0, 1, 4001)
    q, dq, _, _ = path.evaluate(s)
    metric = Metric()

    def energy(qq, vv):
        f = np.einsum('ni,nij,nj->n', vv, metric.tensor(robot, qq), vv)
        return np.sum((f[1:] + f[:-1]) * np.diff(s)) / 2

    rng = np.random.default_rng(41)
    for _ in range(3):
        w = rng.normal(size=4)
        k = rng.integers(1, 3)
        eta, deta = np.sin(k * np.pi * s)[:, None] * w, (k * np.pi * np.cos(k * np.pi * s))[:, None] * w
        eps = 1e-4
        dE = (energy(q + eps * eta, dq + eps * deta) - energy(q - eps * eta, dq - eps * deta)) / (2 * eps)
        q_lin = RRPP_A + s[:, None] * (RRPP_B - RRPP_A)
        v_lin = np.broadcast_to(RRPP_B - RRPP_A, q_lin.shape)
        dE_lin = (energy(q_lin + eps * eta, v_lin + eps * deta)
                  - energy(q_lin - eps * eta, v_lin - eps * deta)) / (2 * eps)
        assert abs(dE) < 1e-4 * abs(dE_lin)
        assert energy(q + 1e-2 * eta, dq + 1e-2 * deta) > energy(q, dq)


def test_rrpp_tool_path_bows_off_the_chord(rrpp_path):
    """docs/maths.md#robots: not the straight line: the tool path leaves the chord by a fraction of a mm."""
    _, path = rrpp_path
    p = path.ee_poses(np.linspace(0, 1, 1001))[:, :3, 3]
    chord = (p[-1] - p[0]) / np.linalg.norm(p[-1] - p[0])
    rel = p - p[0]
    bow = np.linalg.norm(rel - np.outer(rel @ chord, chord), axis=1).max()
    assert 2e-5 < bow < 1e-3, f'bow {bow * 1e3:.4f} mm'


def test_rrpp_from_table5_poses_uses_nearest_reachable_ends():
    req = load_request(os.path.join(ROOT, 'msg_examples', 'paper_rrpp.yaml'))
    path = req.plan()
    assert path.solver.status == 0
    assert_allclose(path.q_start, RRPP_A, atol=1e-3)
    assert_allclose(path.q_goal, RRPP_B, atol=1e-3)
    for ik in (path.ik_start, path.ik_goal):
        assert ik is not None and ik.success and 0 < ik.residual <= 5e-3


# ---------------------------------------------------------------------- failures and edge cases
@pytest.mark.parametrize('name, q_a, q_b', [
    ('rrpp', RRPP_A, np.array([1.5, 1.0, 1.5, 1.5])),
    ('ur5e', np.array([0.0, -1.2, 1.5, -1.9, -1.5, 0.0]), np.array([1.0, -1.6, 2.0, -0.5, -0.5, 1.0])),
])
def test_non_convergence_raises_bvp_error(name, q_a, q_b):
    planner = GeodesicPlanner(load_robot(name), nodes=3, max_nodes=4)
    with pytest.raises(BVPError, match=rf"geodesic solver did not converge for robot '{name}'") as info:
        planner.plan(None, None, start_joints=q_a, goal_joints=q_b, method='collocation')
    assert info.value.status == 1
    assert 'maximum number of mesh nodes' in str(info.value)
    assert info.value.max_residual > planner.tol


def test_zero_length_path_is_constant():
    robot = load_robot('ur5e')
    q = robot.home + 0.1
    path = GeodesicPlanner(robot).plan(None, None, start_joints=q, goal_joints=q)
    qs, dq, ddq, _ = path.evaluate(np.linspace(0, 1, 11))
    assert_allclose(qs, np.broadcast_to(q, qs.shape), atol=1e-15)
    assert_allclose(dq, 0.0, atol=1e-15)
    assert path.length == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize('s, match', [
    ([0.0, 1.5], r's: values must lie in \[0, 1\]'),
    ([-0.1, 0.5], r's: values must lie in \[0, 1\]'),
    ([[0.0, 0.5]], 's: expected a 1-D array'),
    ([0.0, float('nan')], 's: contains NaN'),
])
def test_evaluate_rejects_bad_s(s, match, rrpp_path):
    _, path = rrpp_path
    with pytest.raises(RequestError, match=match):
        path.evaluate(np.array(s))


def test_evaluate_accepts_unsorted_and_scalar_s(rrpp_path):
    _, path = rrpp_path
    s = np.linspace(0, 1, 21)
    perm = np.random.default_rng(3).permutation(21)
    ref = path.evaluate(s)
    got = path.evaluate(s[perm])
    for a, b in zip(got, ref):
        assert_allclose(a, b[perm], atol=0)
    one = path.evaluate(0.5)
    assert all(a.shape == (1, 4) for a in one)
    assert_allclose(one[0][0], path.evaluate(np.array([0.5]))[0][0], atol=0)


@pytest.mark.parametrize('d, axis, angle', [
    ([0.1, 0.05, 0.0], [0, 0, 1], 0.0),                 # pure translation
    ([0.0, 0.0, 0.0], [0.2, 0.3, 1.0], 0.5),            # pure rotation
    ([0.0, 0.0, 0.0], [0, 0, 1], np.radians(150)),      # large rotation about the tool axis
    ([1e-6, 0.0, 0.0], [0, 0, 1], 1e-6),                # tiny move
], ids=['translation', 'rotation', 'rotation_150deg', 'tiny'])
def test_six_joint_special_moves(d, axis, angle):
    robot = load_robot('ur5e')
    q_a = robot.home + np.array([0.3, -0.2, 0.2, 0.1, 0.3, 0.2])
    T_a = U.ur5e_fk_batch(q_a[None])[0]
    T_b = T_a.copy()
    T_b[:3, :3] = T_a[:3, :3] @ U.axis_angle(axis, angle)
    T_b[:3, 3] += d
    path = GeodesicPlanner(robot).plan(None, T_b, start_joints=q_a)
    s = np.linspace(0, 1, 101)
    q = path.evaluate(s)[0]
    q_oracle = U.continuation_ik(U.ur5e_fk_batch, U.line_slerp_oracle(T_a, T_b, s), q_a)
    assert np.abs(q - q_oracle).max() <= JOINT_TOL
    dp, dr = U.tool_deviation(U.ur5e_fk_batch, q, T_a, T_b, s)
    assert dp <= TOOL_TOL and dr <= TOOL_TOL


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
@pytest.mark.parametrize(('s', 'cause'), [
    ([0.5, np.nan], r'^s: contains NaN or inf$'), ([1.5], r'^s: values must lie in \[0, 1\], got \[1\.5, 1\.5\]$'),
    ([[0.5]], r'^s: expected a 1-D array, got shape \(1, 1\)$'), ([-0.1, 0.2], r'must lie in \[0, 1\]')])
def test_regression_bad_s(planar: GeodesicPlanner, s: Any, cause: str) -> None:
    path = planar.plan(None, None, Q3_A, Q3_B)
    expect_error('regression', lambda: path.evaluate(s), RequestError, cause)
    expect_error('regression', lambda: path.ee_poses(s), RequestError, cause)


@pytest.mark.parametrize('s', ['x', [[0.5, 0.6], [0.7]]])
def test_regression_ragged_s(planar: GeodesicPlanner, s: Any) -> None:
    """Found by the fuzzer (was a bare ValueError)."""
    path = planar.plan(None, None, Q3_A, Q3_B)
    for fn in (path.evaluate, path.ee_poses):
        expect_error('regression', lambda: fn(s), RequestError, r'^s: expected a 1-D array of numbers in \[0, 1\] \(')
