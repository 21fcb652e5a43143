"""Kinematics: forward kinematics of every preset against hand-derived values and an independent DH
product; the geometric Jacobian, the 12 x n Jacobian of f = (p, n, o, a) and its second directional
derivative H(q, v) against central finite differences (here only: the library is analytic)."""
from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest
import urdf_util as U
from numpy.testing import assert_allclose
from planning_checks import expect_error

from geodesic_planner import load_robot
from geodesic_planner.core.errors import KinematicsError, RequestError
from geodesic_planner.core.kinematics import Chain, Joint, chain_from_dh
from geodesic_planner.core.urdf import chain_from_urdf

DATA = os.path.abspath(os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data'))
PI = np.pi

# Published UR5e standard DH (Universal Robots), written out here independently of robots.py.
UR5E_DH = [(0.0, 0.1625, 0.0, PI / 2), (0.0, 0.0, -0.425, 0.0), (0.0, 0.0, -0.3922, 0.0),
           (0.0, 0.1333, 0.0, PI / 2), (0.0, 0.0997, 0.0, -PI / 2), (0.0, 0.0996, 0.0, 0.0)]
# Franka Panda modified DH (Craig) rows (alpha_prev, a_prev, d, theta), flange 0.107 m along z.
PANDA_MDH = [(0.0, 0.0, 0.333, 0.0), (-PI / 2, 0.0, 0.0, 0.0), (PI / 2, 0.0, 0.316, 0.0),
             (PI / 2, 0.0825, 0.0, 0.0), (-PI / 2, -0.0825, 0.384, 0.0), (PI / 2, 0.0, 0.0, 0.0),
             (PI / 2, 0.088, 0.0, 0.0)]
# RRPP (docs/maths.md#robots), modified DH rows; tool row (π, 0, d5, −π/2).
A1 = A3 = D5 = 1.0
RRPP_MDH = [(0.0, 0.0, 0.0, 0.0), (np.arccos(1 / np.sqrt(3)), A1, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0),
            (-PI / 2, A3, 0.0, PI)]
RRPP_TOOL = U.rx(PI) @ U.tr() @ U.rz(-PI / 2) @ U.tr(z=D5)
# Stanford-arm-like standard DH with a prismatic third joint (a mixed chain for chain_from_dh).
STANFORD_DH = [(0.0, 0.412, 0.0, -PI / 2), (0.0, 0.154, 0.0, PI / 2), (-PI / 2, 0.1, 0.0, 0.0),
               (0.0, 0.0, 0.0, -PI / 2), (0.0, 0.0, 0.0, PI / 2), (0.0, 0.263, 0.0, 0.0)]
STANFORD_KINDS = ['revolute', 'revolute', 'prismatic', 'revolute', 'revolute', 'revolute']


def mixed_urdf_robot() -> Chain:
    """A URDF chain with a prismatic and a continuous joint and randomly re-oriented joint frames."""
    xml = U.dh_to_urdf('mixed', STANFORD_DH, STANFORD_KINDS, continuous=(5,), split=(0, 3),
                       twist_seed=7, base=U.xyz_rpy((0.1, 0.2, 0.3), (0.3, -0.2, 1.0)),
                       tool=U.xyz_rpy((0.01, 0.0, 0.1), (0.0, 0.5, 0.0)))
    return chain_from_urdf(xml)


ROBOTS = {
    'planar_3r': lambda: load_robot('planar_3r'),
    'rrpp': lambda: load_robot('rrpp'),
    'ur5e': lambda: load_robot('ur5e'),
    'panda': lambda: load_robot('panda'),
    'kr6_like_urdf': lambda: load_robot(os.path.join(DATA, 'kr6_like.urdf')),
    'iiwa_like_7r_urdf': lambda: load_robot(os.path.join(DATA, 'iiwa_like_7r.urdf')),
    'mixed_urdf': mixed_urdf_robot,
}


def random_q(robot: Chain, rng: np.random.Generator, n: int) -> np.ndarray:
    lo = np.where(np.isfinite(robot.lower), robot.lower, -PI)
    hi = np.where(np.isfinite(robot.upper), robot.upper, PI)
    lo = np.where(np.array(robot.joint_types) == 'prismatic', np.maximum(lo, -1.0), lo)
    hi = np.where(np.array(robot.joint_types) == 'prismatic', np.minimum(hi, 1.0), hi)
    return rng.uniform(lo, hi, size=(n, robot.dof))


# ---------------------------------------------------------------------- forward kinematics
def test_planar_3r_fk_closed_form():
    """docs/maths.md#robots: p = (c1 + c12 + c123, s1 + s12 + s123, 0), n = (c123, s123, 0), a = z."""
    robot = load_robot('planar_3r')
    qs = random_q(robot, np.random.default_rng(1), 40)
    T = robot.fk(qs)
    t1, t12, t123 = qs[:, 0], qs[:, 0] + qs[:, 1], qs.sum(axis=1)
    p = np.stack([np.cos(t1) + np.cos(t12) + np.cos(t123), np.sin(t1) + np.sin(t12) + np.sin(t123),
                  np.zeros(40)], axis=1)
    n = np.stack([np.cos(t123), np.sin(t123), np.zeros(40)], axis=1)
    o = np.stack([-np.sin(t123), np.cos(t123), np.zeros(40)], axis=1)
    assert_allclose(T[:, :3, 3], p, atol=1e-14)
    assert_allclose(T[:, :3, 0], n, atol=1e-15)
    assert_allclose(T[:, :3, 1], o, atol=1e-15)
    assert_allclose(T[:, :3, 2], np.broadcast_to([0, 0, 1.0], (40, 3)), atol=1e-15)
    assert_allclose(T[:, 3], np.broadcast_to([0, 0, 0, 1.0], (40, 4)), atol=0)
    assert robot.joint_types == ('revolute',) * 3


@pytest.mark.parametrize('q, p, n, o, a', [
    ((0.123, -1.539, 0.276, -0.640), (-0.501, -0.901, -0.699), (0.100, -0.810, 0.577),
     (-0.102, 0.569, 0.816), (-0.990, -0.141, -0.026)),
    ((0.129, -1.629, 0.239, -0.643), (-0.600, -0.800, -0.599), (0.105, -0.810, 0.577),
     (-0.016, 0.579, 0.815), (-0.994, -0.095, 0.047)),
])
def test_rrpp_table6_joints_give_table5_poses(q, p, n, o, a):
    """Paper Tables 5/6 (signs restored in docs/maths.md#robots): FK reproduces the printed 3 decimals."""
    robot = load_robot('rrpp')
    assert robot.joint_types == ('revolute', 'revolute', 'prismatic', 'prismatic')
    T = robot.fk(np.array(q))
    got = np.stack([T[:3, 3], T[:3, 0], T[:3, 1], T[:3, 2]])
    assert_allclose(np.round(got, 3), np.array([p, n, o, a]), atol=1e-12)


def test_rrpp_fk_matches_modified_dh_product():
    robot = load_robot('rrpp')
    kinds = ['revolute', 'revolute', 'prismatic', 'prismatic']
    for q in random_q(robot, np.random.default_rng(2), 10):
        assert_allclose(robot.fk(q), U.dh_product(RRPP_MDH, kinds, q, modified=True, tool=RRPP_TOOL),
                        atol=1e-14)


def test_ur5e_zero_configuration_by_hand():
    """At q = 0 the UR5e tool sits at (a2 + a3, −(d4 + d6), d1 − d5) with R = Rx(π/2)."""
    T = load_robot('ur5e').fk(np.zeros(6))
    assert_allclose(T[:3, 3], [-0.425 - 0.3922, -(0.1333 + 0.0996), 0.1625 - 0.0997], atol=1e-15)
    assert_allclose(T[:3, :3], [[1, 0, 0], [0, 0, -1], [0, 1, 0]], atol=1e-15)


def test_ur5e_fk_matches_dh_product():
    robot = load_robot('ur5e')
    qs = np.concatenate([[[0.0, -PI / 2, PI / 2, -PI / 2, -PI / 2, 0.0],
                          [0.3, -1.2, 1.9, -2.3, -1.5, 0.4],
                          [-2.0, 0.5, -1.0, 3.0, 1.0, -5.0]],
                         random_q(robot, np.random.default_rng(3), 10)])
    for q in qs:
        assert_allclose(robot.fk(q), U.dh_product(UR5E_DH, ['revolute'] * 6, q), atol=1e-14)
    assert robot.joint_names == ['shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint',
                                 'wrist_1_joint', 'wrist_2_joint', 'wrist_3_joint']


def test_panda_zero_configuration_by_hand_and_dh_product():
    robot = load_robot('panda')
    T0 = robot.fk(np.zeros(7))
    # flange at (a7, 0, d1 + d3 + d5 - d_flange), z axis pointing down
    assert_allclose(T0[:3, 3], [0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107], atol=1e-15)
    assert_allclose(T0[:3, :3], np.diag([1.0, -1.0, -1.0]), atol=1e-15)
    for q in random_q(robot, np.random.default_rng(4), 10):
        assert_allclose(robot.fk(q), U.dh_product(PANDA_MDH, ['revolute'] * 7, q, modified=True,
                                                  tool=U.tr(z=0.107)), atol=1e-14)
    assert robot.dof == 7


def test_chain_from_dh_standard_with_prismatic_joint():
    tool = U.xyz_rpy((0.0, 0.02, 0.05), (0.1, 0.2, 0.3))
    robot = chain_from_dh('stanford', STANFORD_DH, STANFORD_KINDS, tool=tool)
    for q in np.random.default_rng(5).uniform(-2, 2, size=(10, 6)):
        assert_allclose(robot.fk(q), U.dh_product(STANFORD_DH, STANFORD_KINDS, q, tool=tool), atol=1e-14)


def test_fk_batched_shapes():
    robot = load_robot('ur5e')
    qs = random_q(robot, np.random.default_rng(6), 6).reshape(2, 3, 6)
    T = robot.fk(qs)
    assert T.shape == (2, 3, 4, 4)
    J = robot.jacobian(qs)
    assert J.shape == (2, 3, 6, 6)
    assert robot.jacobian12(qs).shape == (2, 3, 12, 6)
    assert robot.hessian12(qs, np.ones(6)).shape == (2, 3, 12)
    for i in range(2):
        for j in range(3):
            assert_allclose(T[i, j], robot.fk(qs[i, j]), atol=0)
            assert_allclose(J[i, j], robot.jacobian(qs[i, j]), atol=0)


# ---------------------------------------------------------------------- derivatives vs finite differences
def fd_geometric_jacobian(robot: Chain, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    J = np.zeros((6, robot.dof))
    R = robot.fk(q)[:3, :3]
    for k in range(robot.dof):
        e = np.zeros(robot.dof)
        e[k] = h
        Tp, Tm = robot.fk(q + e), robot.fk(q - e)
        J[:3, k] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
        W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ R.T          # ω^ = Ṙ Rᵀ
        J[3:, k] = 0.5 * np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]])
    return J


@pytest.mark.parametrize('name', list(ROBOTS))
def test_jacobian_matches_finite_differences(name):
    robot = ROBOTS[name]()
    for q in random_q(robot, np.random.default_rng(10), 6):
        assert_allclose(robot.jacobian(q), fd_geometric_jacobian(robot, q), atol=2e-9, rtol=0)


@pytest.mark.parametrize('name', list(ROBOTS))
def test_jacobian12_matches_finite_differences(name):
    robot = ROBOTS[name]()
    h = 1e-6
    for q in random_q(robot, np.random.default_rng(11), 6):
        fd = np.zeros((12, robot.dof))
        for k in range(robot.dof):
            e = np.zeros(robot.dof)
            e[k] = h
            fd[:, k] = (U.embed12(robot.fk(q + e)) - U.embed12(robot.fk(q - e))) / (2 * h)
        assert_allclose(robot.jacobian12(q), fd, atol=2e-9, rtol=0)


@pytest.mark.parametrize('name', list(ROBOTS))
def test_hessian12_matches_finite_differences(name):
    """H(q, v) = d²/dt² f(q + t v) at t = 0: against a second difference of FK and a first
    difference of the (separately checked) Jacobian along v."""
    robot = ROBOTS[name]()
    rng = np.random.default_rng(12)
    for q in random_q(robot, rng, 6):
        v = rng.normal(size=robot.dof)
        H = robot.hessian12(q, v)
        h2 = 1e-4
        fd2 = (U.embed12(robot.fk(q + h2 * v)) - 2 * U.embed12(robot.fk(q))
               + U.embed12(robot.fk(q - h2 * v))) / h2**2
        assert_allclose(H, fd2, atol=2e-6 * max(1.0, v @ v), rtol=0)
        h1 = 1e-6
        fd1 = (robot.jacobian12(q + h1 * v) - robot.jacobian12(q - h1 * v)) / (2 * h1) @ v
        assert_allclose(H, fd1, atol=1e-8 * max(1.0, v @ v), rtol=0)


def test_hessian12_batched_matches_single():
    robot = load_robot('panda')
    rng = np.random.default_rng(13)
    qs = random_q(robot, rng, 5)
    vs = rng.normal(size=(5, 7))
    H = robot.hessian12(qs, vs)
    for k in range(5):
        assert_allclose(H[k], robot.hessian12(qs[k], vs[k]), atol=1e-15)


# ---------------------------------------------------------------------- validation and errors
def test_check_joints_errors_name_the_cause():
    robot = load_robot('ur5e')
    with pytest.raises(RequestError, match=r"start_joints: robot 'ur5e' has 6 joints .* got 5 values"):
        robot.check_joints([0.0] * 5, 'start_joints')
    with pytest.raises(RequestError, match='NaN or inf'):
        robot.check_joints([0.0, float('nan'), 0, 0, 0, 0])
    with pytest.raises(RequestError, match='NaN or inf'):
        robot.check_joints([0.0, float('inf'), 0, 0, 0, 0])
    with pytest.raises(RequestError, match='not a numeric joint vector'):
        robot.check_joints(['a'] * 6)
    with pytest.raises(RequestError, match='got 1 values'):
        robot.check_joints(0.5)
    assert_allclose(robot.check_joints([1, 2, 3, 4, 5, 6]), np.arange(1.0, 7.0), atol=0)


def test_within_limits_and_with_limits():
    robot = load_robot('panda')
    assert bool(robot.within_limits(robot.home))
    q = robot.home.copy()
    q[3] = 0.0  # above panda_joint4's upper limit −0.0698
    assert not bool(robot.within_limits(q))
    r2 = robot.with_limits(max_velocity=0.5, max_acceleration=[1, 2, 3, 4, 5, 6, 7])
    assert_allclose(r2.max_velocity, np.full(7, 0.5), atol=0)
    assert_allclose(r2.max_acceleration, np.arange(1.0, 8.0), atol=0)
    assert_allclose(r2.fk(q), robot.fk(q), atol=0)
    with pytest.raises(KinematicsError, match='3 joint names for 7 joints'):
        robot.with_limits(joint_names=['a', 'b', 'c'])


@pytest.mark.parametrize('make, match', [
    (lambda: Chain('x', [], [np.eye(4)]), 'at least one actuated joint'),
    (lambda: Chain('x', [Joint('j', 'revolute')], [np.eye(4)]), '1 joints need 2 fixed transforms'),
    (lambda: Chain('x', [Joint('j', 'spherical')], [np.eye(4)] * 2), "unsupported type 'spherical'"),
    (lambda: Chain('x', [Joint('j', 'revolute', np.zeros(3))], [np.eye(4)] * 2), 'invalid axis'),
    (lambda: Chain('x', [Joint('j', 'revolute', lower=1.0, upper=0.0)], [np.eye(4)] * 2),
     'lower limit > upper limit'),
    (lambda: Chain('x', [Joint('j', 'revolute', max_velocity=0.0)], [np.eye(4)] * 2),
     'positive velocity'),
    (lambda: Chain('x', [Joint('j', 'revolute'), Joint('j', 'revolute')], [np.eye(4)] * 3),
     'duplicate joint names'),
    (lambda: Chain('x', [Joint('j', 'revolute')], [np.eye(4), np.full((4, 4), np.nan)]),
     'finite 4x4'),
    (lambda: chain_from_dh('x', [(0.0, 0.0, 1.0)], ['revolute']), 'DH row 0 needs 4 numbers'),
    (lambda: chain_from_dh('x', [(0.0, 0.0, 1.0, 0.0)], ['revolute', 'revolute']),
     '1 DH rows but 2 joint kinds'),
])
def test_chain_construction_errors(make, match):
    with pytest.raises(KinematicsError, match=match):
        make()


def test_load_robot_unknown_name_lists_presets():
    with pytest.raises(RequestError, match=r"unknown robot 'kr16'.*planar_3r"):
        load_robot('kr16')
    with pytest.raises(RequestError, match='cannot read URDF'):
        load_robot('/nonexistent/dir/robot.urdf')


# Deterministic regressions found by the fuzzer (test_fuzz.py): exception type and cause.
@pytest.mark.parametrize(('kwargs', 'cause'), [
    ({'joint_names': ['a']}, r"^robot 'bad': 1 joint names for 2 joints$"),
    ({'tool': np.eye(3)}, r"^robot 'bad': tool.*4x4.*got shape \(3, 3\)$"),
    ({'rows': [(0.0, 0.0, 'x', 0.0), (0.0, 0.0, 1.0, 0.0)]}, r"^robot 'bad': DH row 0 must hold 4 numbers"),
    ({'lower': [0.0], 'upper': [1.0, 1.0]}, r"^robot 'bad': lower limits need one number or 2 numbers, got 1$"),
    ({'max_velocity': [1.0, 1.0, 1.0]}, r"^robot 'bad': velocity limits need one number or 2 numbers, got 3$")])
def test_regression_chain_from_dh_bad_arguments(kwargs: dict[str, Any], cause: str) -> None:
    """Found by the fuzzer (bare IndexError / ValueError)."""
    args = {'rows': [(0.0, 0.0, 1.0, 0.0)] * 2, 'kinds': ['revolute'] * 2, **kwargs}
    rows, kinds = args.pop('rows'), args.pop('kinds')
    expect_error('regression', lambda: chain_from_dh('bad', rows, kinds, **args), KinematicsError, cause)
