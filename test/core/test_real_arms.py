"""Real arms: manufacturers' URDFs (test/data/real_arms, copied from PyPI wheels) load through our
reader with the chain ends a user would pick, and our FK, Jacobian and limits match pinocchio's
(urdfdom's reading, an independent kinematics library) at random configurations within limits."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pin_oracle as P
import pytest
from numpy.testing import assert_allclose

from geodesic_planner import load_robot
from geodesic_planner.core.errors import KinematicsError

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
#: Agreement with pinocchio: m, rad, and Jacobian entries (m/rad or 1).
TOL = 1e-12
#: arm -> (file under DATA, base link, tip link, joint names base to tip)
ARMS = {
    'ur3': ('example-robot-data/ur3_robot.urdf', 'base_link', 'tool0', 'ur'),
    'ur5': ('example-robot-data/ur5_robot.urdf', 'base_link', 'tool0', 'ur'),
    'ur10': ('example-robot-data/ur10_robot.urdf', 'base_link', 'tool0', 'ur'),
    'ur3e': ('airo-models/ur3e.urdf', 'base_link', 'tool0', 'ur'),
    'ur5e': ('airo-models/ur5e.urdf', 'base_link', 'tool0', 'ur'),
    'panda': ('example-robot-data/panda.urdf', 'panda_link0', 'panda_hand_tcp',
              [f'panda_joint{i}' for i in range(1, 8)]),
    'kinova_jaco': ('example-robot-data/kinova.urdf', 'base', 'j2s6s200_end_effector',
                    [f'j2s6s200_joint_{i}' for i in range(1, 7)]),
    'xarm7': ('example-robot-data/xarm7.urdf', 'link_base', 'link_eef', [f'joint{i}' for i in range(1, 8)]),
    'unitree_z1': ('example-robot-data/z1.urdf', 'link00', 'gripperStator', [f'joint{i}' for i in range(1, 7)]),
    'kuka_iiwa14': ('pybullet/kuka_iiwa_model.urdf', 'lbr_iiwa_link_0', 'lbr_iiwa_link_7',
                    [f'lbr_iiwa_joint_{i}' for i in range(1, 8)]),
}
UR_JOINTS = ['shoulder_pan_joint', 'shoulder_lift_joint', 'elbow_joint', 'wrist_1_joint', 'wrist_2_joint',
             'wrist_3_joint']
N_CONFIGS = 40


def arm(key: str):
    """(URDF text, our chain, pinocchio's model) of a corpus arm."""
    path, base, tip, _ = ARMS[key]
    text = (DATA / path).read_text()
    return text, load_robot(str(DATA / path), base_link=base, tip_link=tip), P.model(text)


def random_configurations(robot, rng: np.random.Generator, n: int = N_CONFIGS) -> np.ndarray:
    """Uniform within the position limits; continuous joints over two full turns."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, -2 * np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, 2 * np.pi)
    return rng.uniform(lo, hi, size=(n, robot.dof))


@pytest.mark.parametrize('key', list(ARMS))
def test_real_arm_loads_with_the_joints_pinocchio_finds(key):
    _, base, tip, names = ARMS[key]
    text, robot, m = arm(key)
    expected = UR_JOINTS if names == 'ur' else names
    assert robot.joint_names == expected
    assert robot.joint_names == P.chain_joints(m, base, tip)     # urdfdom's tree, walked by pinocchio
    assert (robot.base_link, robot.tip_link) == (base, tip)
    assert robot.within_limits(robot.home)


@pytest.mark.parametrize('key', list(ARMS))
def test_real_arm_fk_matches_pinocchio(key):
    _, robot, m = arm(key)
    qs = random_configurations(robot, np.random.default_rng(sum(map(ord, key))))
    worst_p, worst_r = P.errors(robot, m, qs)
    assert worst_p <= TOL and worst_r <= TOL, (worst_p, worst_r)
    # the comparison is not vacuous: the tool really moves between these configurations
    spread = np.ptp(robot.fk(qs)[:, :3, 3], axis=0)
    assert spread.max() > 0.1


@pytest.mark.parametrize('key', list(ARMS))
def test_real_arm_jacobian_matches_pinocchio(key):
    _, robot, m = arm(key)
    qs = random_configurations(robot, np.random.default_rng(7 + sum(map(ord, key))), n=10)
    J = robot.jacobian(qs)
    for q, Jq in zip(qs, J):
        assert_allclose(Jq, P.jacobian(m, robot.joint_names, q, robot.base_link, robot.tip_link), atol=TOL, rtol=0)


@pytest.mark.parametrize('key', list(ARMS))
def test_real_arm_limits_match_pinocchio(key):
    """Position and velocity limits as urdfdom reads them (continuous joints: unbounded)."""
    _, robot, m = arm(key)
    for i, name in enumerate(robot.joint_names):
        joint = m.joints[m.getJointId(name)]
        if joint.nq == 2:                                    # continuous
            assert (robot.lower[i], robot.upper[i]) == (-np.inf, np.inf)
        else:
            assert robot.lower[i] == m.lowerPositionLimit[joint.idx_q], name
            assert robot.upper[i] == m.upperPositionLimit[joint.idx_q], name
        assert robot.max_velocity[i] == m.velocityLimit[joint.idx_v], name


def test_corpus_has_the_cases_the_reader_must_handle():
    """The files really carry what the tests above claim to cover (each check fails on a wrong corpus)."""
    texts = {key: (DATA / ARMS[key][0]).read_text() for key in ARMS}
    for key in ('ur3e', 'ur5e'):                 # an attribute prefix that is never declared
        assert 'drake:acceleration=' in texts[key] and 'xmlns:drake' not in texts[key]
        with pytest.raises(ET.ParseError, match='unbound prefix'):
            ET.fromstring(texts[key])            # what a namespace-aware parser (our old one) says
    assert '<gazebo' in texts['ur5'] and '<transmission' in texts['ur5']
    assert '<ros2_control' in texts['xarm7']
    assert '<mimic joint="panda_finger_joint1"/>' in texts['panda']   # a finger off the arm's chain
    assert texts['kinova_jaco'].count('type="continuous"') == 3
    assert len({ARMS[k][0] for k in ARMS}) == len(ARMS) == 10


def test_mimic_joints_of_a_real_gripper():
    """Robotiq 2F-85: the inner finger joints mimic finger_joint. A chain through one is refused
    with the reason; the chain to the outer finger (finger_joint, then fixed joints) matches pinocchio."""
    path = DATA / 'airo-models' / 'robotiq_2f_85.urdf'
    with pytest.raises(KinematicsError, match=r"joint 'left_inner_finger_joint' is a mimic joint on the chain .* "
                                              r"moves with joint 'finger_joint' \(on the chain\) as -1 \* q \+ 0"):
        load_robot(str(path), tip_link='left_inner_finger_pad')
    with pytest.raises(KinematicsError, match=r"'right_outer_knuckle_joint' is a mimic joint .* 'finger_joint' "
                                              r"\(not on the chain\)"):
        load_robot(str(path), tip_link='right_outer_finger')
    robot = load_robot(str(path), tip_link='left_outer_finger')
    assert robot.joint_names == ['finger_joint']
    qs = random_configurations(robot, np.random.default_rng(3))
    worst_p, worst_r = P.errors(robot, P.model(path.read_text()), qs)
    assert worst_p <= TOL and worst_r <= TOL
