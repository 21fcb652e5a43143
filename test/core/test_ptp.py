"""PTP: the joint line, and the kinetic-energy geodesic of the URDF's inertias.

Oracles: with a constant mass matrix the kinetic-energy metric is flat, so its geodesic is the
joint line itself; on a real arm (the UR5 of example-robot-data) the geodesic's metric speed
q'^T M(q) q' is constant (the geodesic property, M computed here through pinocchio independently
of the solver's right-hand side), and its action is at most the joint line's.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from geodesic_planner import load_robot
from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.ptp import (ConstantMass, JointLinePath, UrdfMass, action,
                                       kinetic_energy_path)

UR5 = Path(__file__).resolve().parents[1] / 'data' / 'real_arms' / 'example-robot-data' / 'ur5_robot.urdf'
Q_A = np.array([0.0, -1.0, 1.2, -1.5, -1.4, 0.2])
Q_B = Q_A + np.array([1.5, 0.6, -0.9, 0.5, 1.0, -1.0])


@pytest.fixture(scope='module')
def ur5():
    return load_robot(str(UR5), tip_link='tool0')


def test_joint_line_path_is_the_straight_line(ur5) -> None:
    path = JointLinePath(ur5, Q_A, Q_B)
    s = np.linspace(0.0, 1.0, 11)
    q, dq, ddq, dddq = path.evaluate(s)
    assert_allclose(q, Q_A + s[:, None] * (Q_B - Q_A), atol=1e-15)
    assert_allclose(dq, np.broadcast_to(Q_B - Q_A, dq.shape))
    assert not ddq.any() and not dddq.any()


def test_constant_mass_matrix_gives_the_joint_line(ur5) -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6))
    mass = ConstantMass(A @ A.T + 6.0 * np.eye(6))
    path = kinetic_energy_path(ur5, mass, Q_A, Q_B)
    s = np.linspace(0.0, 1.0, 501)
    assert_allclose(path.evaluate(s, 0)[0], Q_A + s[:, None] * (Q_B - Q_A), atol=1e-8)


def test_real_arm_kinetic_energy_geodesic_beats_the_joint_line(ur5) -> None:
    import pinocchio as pin

    mass = UrdfMass(ur5, UR5.read_text())
    path = kinetic_energy_path(ur5, mass, Q_A, Q_B)
    s = np.linspace(0.0, 1.0, 201)
    q, v = path.evaluate(s, 1)
    assert_allclose(q[[0, -1]], [Q_A, Q_B], atol=1e-10)
    # M independently: pinocchio's crba on the full model (the UR5's joints are its only ones)
    model = pin.buildModelFromUrdf(str(UR5))
    data = model.createData()
    assert list(model.names)[1:] == ur5.joint_names

    def M(qk: np.ndarray) -> np.ndarray:
        m = pin.crba(model, data, qk)
        return np.triu(m) + np.triu(m, 1).T
    speed2 = np.array([vk @ M(qk) @ vk for qk, vk in zip(q, v)])
    assert np.ptp(speed2) < 1e-5 * speed2.mean()                  # constant metric speed: a geodesic
    line = JointLinePath(ur5, Q_A, Q_B)
    e_geo, e_line = action(path, mass), action(line, mass)
    assert e_geo == pytest.approx(speed2.mean(), rel=1e-5)
    assert e_geo <= e_line * (1.0 + 1e-6), (e_geo, e_line)
    assert e_geo < 0.95 * e_line                                   # and clearly so on this move


def test_a_link_without_mass_is_named(ur5) -> None:
    text = UR5.read_text()
    # wrist_3_link's mass to 0
    start = text.index('<link name="wrist_3_link">')
    end = text.index('</link>', start)
    link = re.sub(r'<mass value="[^"]*"', '<mass value="0"', text[start:end])
    with pytest.raises(RequestError, match=r"wrist_3_joint.*no <inertial> mass"):
        UrdfMass(ur5, text[:start] + link + text[end:])
