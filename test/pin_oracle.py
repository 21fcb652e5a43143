"""pinocchio as the independent oracle for URDF reading and kinematics (tests only).

pinocchio reads URDF with urdfdom (the parser of robot_state_publisher and MoveIt) and computes
forward kinematics and Jacobians with its own algorithms, so agreeing with it checks our reader
and our kinematics against code that shares nothing with ours. Its model holds every joint of the
file (fingers too); a continuous joint has two coordinates (cos, sin) there, so positions are
mapped by joint name, never by index.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from geodesic_planner.core.kinematics import Chain


def model(xml: str) -> pin.Model:
    """pinocchio's model of a URDF text (mimic joints as independent joints)."""
    return pin.buildModelFromXML(xml)


def accepts(xml: str) -> bool:
    """Whether urdfdom (through pinocchio) loads the text."""
    try:
        pin.buildModelFromXML(xml)
    except ValueError:
        return False
    return True


def configuration(m: pin.Model, names: list[str], q: np.ndarray, rest: dict[str, float] | None = None) -> np.ndarray:
    """pinocchio's q for joint values ``q`` of the joints ``names``; other joints at ``rest`` or neutral."""
    out = pin.neutral(m)
    values = dict(rest or {})
    values.update(zip(names, q))
    for name, value in values.items():
        joint = m.joints[m.getJointId(name)]
        if joint.nq == 2:  # continuous (revolute unbounded): cos, sin
            out[joint.idx_q:joint.idx_q + 2] = np.cos(value), np.sin(value)
        else:
            out[joint.idx_q] = value
    return out


def frame(m: pin.Model, link: str) -> int:
    """The frame id of a link."""
    return m.getFrameId(link, pin.FrameType.BODY)


def fk(m: pin.Model, names: list[str], q: np.ndarray, base: str, tip: str,
       rest: dict[str, float] | None = None) -> np.ndarray:
    """T_base_tip (4x4) at joint values ``q`` (len(names),), by pinocchio."""
    d = m.createData()
    pin.framesForwardKinematics(m, d, configuration(m, names, q, rest))
    return np.linalg.inv(d.oMf[frame(m, base)].homogeneous) @ d.oMf[frame(m, tip)].homogeneous


def jacobian(m: pin.Model, names: list[str], q: np.ndarray, base: str, tip: str) -> np.ndarray:
    """The tip's Jacobian in the base frame, rows [v; w], columns ``names`` (6, len(names)), by pinocchio."""
    d = m.createData()
    qp = configuration(m, names, q)
    pin.computeJointJacobians(m, d, qp)
    pin.framesForwardKinematics(m, d, qp)
    J = pin.getFrameJacobian(m, d, frame(m, tip), pin.LOCAL_WORLD_ALIGNED)
    R = d.oMf[frame(m, base)].rotation
    cols = [m.joints[m.getJointId(n)].idx_v for n in names]
    return np.vstack([R.T @ J[:3, cols], R.T @ J[3:, cols]])


def chain_joints(m: pin.Model, base: str, tip: str) -> list[str]:
    """Names of pinocchio's moving joints between the base and tip links, base first."""
    def support(link: str) -> list[int]:
        return list(m.supports[m.frames[frame(m, link)].parentJoint])
    above_base = set(support(base))
    return [m.names[j] for j in support(tip) if j not in above_base]


def errors(robot: Chain, m: pin.Model, qs: np.ndarray) -> tuple[float, float]:
    """Largest position (m) and rotation (rad) differences between our FK and pinocchio's over ``qs``."""
    T = robot.fk(qs)
    worst_p = worst_r = 0.0
    for q, Tq in zip(qs, T):
        ref = fk(m, robot.joint_names, q, robot.base_link, robot.tip_link)
        worst_p = max(worst_p, float(np.linalg.norm(Tq[:3, 3] - ref[:3, 3])))
        worst_r = max(worst_r, rotation_angle(Tq[:3, :3], ref[:3, :3]))
    return worst_p, worst_r


def rotation_angle(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle of the rotation Raᵀ Rb, rad (accurate near zero: from the skew part)."""
    E = Ra.T @ Rb
    s = 0.5 * np.linalg.norm([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    c = 0.5 * (np.trace(E) - 1.0)
    return float(np.arctan2(s, c))


def line_slerp_pose(T_a: np.ndarray, T_b: np.ndarray, s: float) -> np.ndarray:
    """The pose at ``s`` of the straight line + slerp from T_a to T_b, by pinocchio's SO(3) maps."""
    R = T_a[:3, :3] @ pin.exp3(s * pin.log3(T_a[:3, :3].T @ T_b[:3, :3]))
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = (1.0 - s) * T_a[:3, 3] + s * T_b[:3, 3]
    return T


class Kinematics:
    """pinocchio's FK and Jacobian of one chain, with the model's data kept between calls."""

    def __init__(self, m: pin.Model, names: list[str], base: str, tip: str) -> None:
        self.m, self.d = m, m.createData()
        self.base, self.tip = frame(m, base), frame(m, tip)
        self.names = names
        self.cols = [m.joints[m.getJointId(n)].idx_v for n in names]

    def pose_and_jacobian(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """T_base_tip (4x4) and the tip's Jacobian in the base frame, rows [v; w] (6, n)."""
        m, d = self.m, self.d
        qp = configuration(m, self.names, q)
        pin.computeJointJacobians(m, d, qp)
        pin.updateFramePlacements(m, d)
        B = d.oMf[self.base]
        T = np.linalg.inv(B.homogeneous) @ d.oMf[self.tip].homogeneous
        J = pin.getFrameJacobian(m, d, self.tip, pin.LOCAL_WORLD_ALIGNED)
        R = B.rotation.T
        return T, np.vstack([R @ J[:3, self.cols], R @ J[3:, self.cols]])


def follow(kin: Kinematics, q_a: np.ndarray, T_b: np.ndarray, steps: int = 1000
           ) -> tuple[np.ndarray, float, float]:
    """An independent continuation along the line + slerp from q_a's tool pose to T_b.

    Each of ``steps`` equal steps is solved by Newton iterations on pinocchio's FK and Jacobian
    from the previous configuration (the issue's "IK from the previous sample"). Returns (q at
    every step (steps + 1, n), smallest singular value of the Jacobian met, start included,
    largest joint step); q is NaN from the first step that did not converge to 1e-12.
    """
    T_a, J = kin.pose_and_jacobian(q_a)
    qs = np.full((steps + 1, len(kin.names)), np.nan)
    qs[0] = q = np.array(q_a, dtype=float)
    sigma = float(np.linalg.svd(J, compute_uv=False)[-1])
    for k in range(1, steps + 1):
        target = line_slerp_pose(T_a, T_b, k / steps)
        for _ in range(20):
            T, J = kin.pose_and_jacobian(q)
            err = np.concatenate([target[:3, 3] - T[:3, 3], T[:3, :3] @ pin.log3(T[:3, :3].T @ target[:3, :3])])
            if np.abs(err).max() < 1e-12:
                break
            q = q + np.linalg.lstsq(J, err, rcond=None)[0]
        else:
            return qs, sigma, float(np.nanmax(np.abs(np.diff(qs, axis=0)), initial=0.0))
        sigma = min(sigma, float(np.linalg.svd(J, compute_uv=False)[-1]))
        qs[k] = q
    return qs, sigma, float(np.abs(np.diff(qs, axis=0)).max())


def line_errors(m: pin.Model, names: list[str], base: str, tip: str, qs: np.ndarray, s: np.ndarray,
                T_a: np.ndarray, T_b: np.ndarray) -> tuple[float, float]:
    """Largest distance (m) and angle (rad) of pinocchio's tool poses at joints qs from the line +
    slerp at s."""
    dp = dr = 0.0
    for q, si in zip(qs, s):
        T = fk(m, names, q, base, tip)
        ref = line_slerp_pose(T_a, T_b, float(si))
        dp = max(dp, float(np.linalg.norm(T[:3, 3] - ref[:3, 3])))
        dr = max(dr, rotation_angle(T[:3, :3], ref[:3, :3]))
    return dp, dr
