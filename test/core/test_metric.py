"""The metric: G = J_vᵀJ_v + 2 J_ωᵀJ_ω (docs/maths.md#metric) = J12ᵀJ12 from finite differences, the planar 3R
closed form, the RRPP printed entries (docs/maths.md#robots), weights and ε, the singular traditional metric."""
from __future__ import annotations

import os

import numpy as np
import pytest
import urdf_util as U
from numpy.testing import assert_allclose
from planning_checks import Q3_A, Q3_B, expect_error

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import RequestError, SingularMetricError
from geodesic_planner.core.metric import Metric

DATA = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data'))
ROBOTS = ['planar_3r', 'rrpp', 'ur5e', 'panda', os.path.join(DATA, 'kr6_like.urdf'),
          os.path.join(DATA, 'iiwa_like_7r.urdf')]


def random_q(robot, rng, n):
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    return rng.uniform(np.maximum(lo, -2.0), np.minimum(hi, 2.0), size=(n, robot.dof))


def fd_jacobian12(robot, q, h=1e-6):
    J = np.zeros((12, robot.dof))
    for k in range(robot.dof):
        e = np.zeros(robot.dof)
        e[k] = h
        J[:, k] = (U.embed12(robot.fk(q + e)) - U.embed12(robot.fk(q - e))) / (2 * h)
    return J


@pytest.mark.parametrize('name', ROBOTS, ids=os.path.basename)
def test_paper_metric_is_pullback_and_geometric_identity(name):
    """G = J12ᵀ J12 (eq. 7) and the identity dn² + do² + da² = 2‖ω‖²: G = J_vᵀJ_v + 2 J_ωᵀJ_ω."""
    robot = load_robot(name)
    metric = Metric('paper')
    for q in random_q(robot, np.random.default_rng(1), 5):
        G = metric.tensor(robot, q)
        J12 = fd_jacobian12(robot, q)
        assert_allclose(G, J12.T @ J12, atol=1e-8, rtol=0)
        J = robot.jacobian(q)
        Jv, Jw = J[:3], J[3:]
        assert_allclose(G, Jv.T @ Jv + 2.0 * Jw.T @ Jw, atol=1e-12, rtol=0)
        assert_allclose(G, G.T, atol=0)


def test_planar_3r_metric_closed_form():
    """g = dx² + dy² + 2 dφ², φ = θ1 + θ2 + θ3 (docs/maths.md#robots)."""
    robot = load_robot('planar_3r')
    for q in random_q(robot, np.random.default_rng(2), 10):
        t1, t12, t123 = q[0], q[0] + q[1], q.sum()
        Jx = -np.array([np.sin(t1) + np.sin(t12) + np.sin(t123), np.sin(t12) + np.sin(t123), np.sin(t123)])
        Jy = np.array([np.cos(t1) + np.cos(t12) + np.cos(t123), np.cos(t12) + np.cos(t123), np.cos(t123)])
        Jphi = np.ones(3)
        G = np.outer(Jx, Jx) + np.outer(Jy, Jy) + 2.0 * np.outer(Jphi, Jphi)
        assert_allclose(Metric().tensor(robot, q), G, atol=1e-13)
        # traditional metric: the (x, y) part only, rank 2 (paper eq. 15-16: |D| = 0)
        G1 = Metric('position').tensor(robot, q)
        assert_allclose(G1, np.outer(Jx, Jx) + np.outer(Jy, Jy), atol=1e-13)
        assert abs(np.linalg.det(G1)) < 1e-12


@pytest.mark.parametrize('q', [(0.123, -1.539, 0.276, -0.640), (0.129, -1.629, 0.239, -0.643),
                               (0.5, 0.3, -0.2, 0.7), (-1.0, 2.0, 1.5, -1.2)])
def test_rrpp_printed_metric_entries(q):
    """Paper: g22 = 2 + a3² + (d4 + d5)², g24 = a3, g33 = g44 = 1, g23 = g34 = 0 (1-based indices
    over (θ1, θ2, d3, d4)). With Table 6 printed as d4 = 0.640 (the sign restored in docs/maths.md is
    negative: our d4 = −0.640 points the other way), the printed g22 is 2 + a3² + (d5 − d4)² in our
    convention; at Table 6, (0.640 + 1)² = 2.6896."""
    a3 = d5 = 1.0
    robot = load_robot('rrpp')
    G = Metric().tensor(robot, np.array(q))
    d4 = q[3]
    assert_allclose(G[1, 1], 2.0 + a3**2 + (d5 - d4) ** 2, atol=1e-12)
    assert_allclose([G[1, 3], G[3, 1]], [a3, a3], atol=1e-12)
    assert_allclose([G[2, 2], G[3, 3]], [1.0, 1.0], atol=1e-12)
    assert_allclose([G[1, 2], G[2, 1], G[2, 3], G[3, 2]], 0.0, atol=1e-12)
    if q[0] == 0.123:  # Table 6 A with the printed magnitude of d4
        assert_allclose(G[1, 1], 2.0 + a3**2 + (0.640 + d5) ** 2, atol=1e-12)


def test_weights_and_epsilon():
    robot = load_robot('ur5e')
    rng = np.random.default_rng(3)
    for q in random_q(robot, rng, 4):
        J = robot.jacobian(q)
        JvJv, JwJw = J[:3].T @ J[:3], J[3:].T @ J[3:]
        for wp, wo in [(1.0, 1.0), (2.0, 0.5), (0.3, 3.0), (0.0, 1.0)]:
            G = Metric('paper', position_weight=wp, orientation_weight=wo).tensor(robot, q)
            assert_allclose(G, wp**2 * JvJv + 2 * wo**2 * JwJw, atol=1e-12)
        # the traditional metric ignores the orientation weight
        assert_allclose(Metric('position', position_weight=2.0, orientation_weight=5.0).tensor(robot, q),
                        4.0 * JvJv, atol=1e-12)
        assert_allclose(Metric('paper', epsilon=0.25).tensor(robot, q), JvJv + 2 * JwJw + 0.25 * np.eye(6),
                        atol=1e-12)


def test_metric_speed():
    robot = load_robot('panda')
    rng = np.random.default_rng(4)
    qs = random_q(robot, rng, 5)
    vs = rng.normal(size=(5, 7))
    m = Metric(epsilon=1e-3)
    sp = m.speed(robot, qs, vs)
    assert sp.shape == (5,)
    for k in range(5):
        G = m.tensor(robot, qs[k])
        assert_allclose(sp[k], np.sqrt(vs[k] @ G @ vs[k]), rtol=1e-13)


@pytest.mark.parametrize('kwargs, match', [
    ({'kind': 'riemann'}, r"unknown metric 'riemann'"),
    ({'position_weight': -1.0}, 'position_weight must be finite and >= 0'),
    ({'orientation_weight': float('nan')}, 'orientation_weight must be finite'),
    ({'epsilon': float('inf')}, 'epsilon must be finite'),
    ({'position_weight': 0.0, 'orientation_weight': 0.0}, 'both 0'),
    ({'kind': 'position', 'position_weight': 0.0}, 'both 0'),
])
def test_invalid_metric_options(kwargs, match):
    with pytest.raises(RequestError, match=match):
        Metric(**kwargs)
    with pytest.raises(RequestError, match=match):
        GeodesicPlanner(load_robot('planar_3r'), kwargs.pop('kind', 'paper'), **kwargs)


# ---------------------------------------------------------------------- singular metrics
def test_traditional_metric_on_planar_3r_is_singular():
    """Paper eq. 15-16: the dp² metric of the planar 3R has |D| = 0; the error says so, names the
    metric and the configuration."""
    robot = load_robot('planar_3r')
    q = np.array([0.3, 0.5, -0.2])
    with pytest.raises(SingularMetricError) as info:
        Metric('position').check_regular(robot, q)
    msg = str(info.value)
    assert 'singular' in msg
    assert 'position' in msg
    assert "'planar_3r'" in msg
    assert 'q=[0.3, 0.5, -0.2]' in msg
    Metric('paper').check_regular(robot, q)  # the improved metric is fine there


def test_planner_with_traditional_metric_on_planar_3r_raises():
    planner = GeodesicPlanner(load_robot('planar_3r'), metric='position')
    with pytest.raises(SingularMetricError, match=r'position.*singular.*q=\[0\.258, 0\.583, -0\.317\]'):
        planner.plan(None, None, start_joints=[0.258, 0.583, -0.317], goal_joints=[0.969, 0.380, -0.574])


def test_paper_metric_of_planar_3r_is_singular_when_stretched():
    """G = J_xyφᵀ diag(1, 1, 2) J_xyφ and det J_xyφ = l1 l2 sin θ2: singular at θ2 = 0 too."""
    with pytest.raises(SingularMetricError, match=r'singular.*q=\[0.4, 0.0, 0.1\]'):
        Metric().check_regular(load_robot('planar_3r'), np.array([0.4, 0.0, 0.1]))


def test_traditional_metric_singular_beyond_three_joints():
    with pytest.raises(SingularMetricError, match="singular for robot 'ur5e'"):
        Metric('position').check_regular(load_robot('ur5e'), np.array([0.1, -1.0, 1.2, -0.5, 0.9, 0.3]))


def test_seven_joints_need_epsilon():
    robot = load_robot('panda')
    q = robot.home
    with pytest.raises(SingularMetricError, match='more than 6 joints: use epsilon > 0'):
        Metric().check_regular(robot, q)
    Metric(epsilon=1e-3).check_regular(robot, q)
    # epsilon = 0 leaves the collocation route singular; 'auto' plans the exact line instead.
    planner = GeodesicPlanner(robot, epsilon=0.0)
    with pytest.raises(SingularMetricError, match='singular'):
        planner.plan(None, None, start_joints=q, goal_joints=q + 0.1, method='collocation')
    assert planner.plan(None, None, start_joints=q, goal_joints=q + 0.1).solver.method == 'redundant'


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
def test_regression_position_metric_is_singular() -> None:
    planner = GeodesicPlanner(load_robot('planar_3r'), metric='position')
    expect_error('regression', lambda: planner.plan(None, None, Q3_A, Q3_B), SingularMetricError,
                 r'singular .* at the start .*traditional dp² metric has rank <= 3')
