"""Test helpers: independent DH forward kinematics and URDF text written from DH tables.

Nothing here imports geodesic_planner: these are the oracles the library is checked against.

* :func:`dh_product` multiplies the DH link transforms straightforwardly (standard DH
  ``Rz(θ) Tz(d) Tx(a) Rx(α)`` or modified/Craig ``Rx(α) Tx(a) Rz(θ) Tz(d)``), one 4x4 at a time.
* :func:`dh_to_urdf` writes the same chain as URDF: a base offset as a fixed joint, joint origins
  with general ``xyz``/``rpy`` (optionally a random re-orientation of each joint frame, so the
  joint axes are not z), some link transforms split off into extra fixed joints, prismatic and
  continuous joints, and a fixed tool joint.

Units: m, rad.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


# ---------------------------------------------------------------------- elementary transforms
def rx(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s, 0], [0, 1.0, 0, 0], [-s, 0, c, 0], [0, 0, 0, 1]])


def rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1]])


def tr(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def xyz_rpy(xyz: Sequence[float], rpy: Sequence[float]) -> np.ndarray:
    """URDF origin: translation then fixed-axis roll-pitch-yaw, R = Rz(y) Ry(p) Rx(r)."""
    return tr(*xyz) @ rz(rpy[2]) @ ry(rpy[1]) @ rx(rpy[0])


def rpy_from_matrix(R: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) with R = Rz(yaw) Ry(pitch) Rx(roll); checked by reconstruction."""
    cp = float(np.hypot(R[0, 0], R[1, 0]))
    pitch = float(np.arctan2(-R[2, 0], cp))
    if cp > 1e-9:
        roll = float(np.arctan2(R[2, 1], R[2, 2]))
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    else:  # gimbal lock: only roll - yaw (or roll + yaw) is defined
        yaw = 0.0
        roll = float(np.arctan2(-R[1, 2], R[1, 1]))
    back = xyz_rpy((0, 0, 0), (roll, pitch, yaw))[:3, :3]
    assert np.allclose(back, R, atol=1e-12), 'rpy reconstruction failed'
    return roll, pitch, yaw


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """4x4 transform with a uniformly random rotation (QR of a Gaussian matrix)."""
    Q, Rr = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(Rr)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    T = np.eye(4)
    T[:3, :3] = Q
    return T


# ---------------------------------------------------------------------- DH oracle
def dh_link(row: Sequence[float], kind: str, q: float, modified: bool) -> np.ndarray:
    """One DH link transform with the joint variable q added to θ (revolute) or d (prismatic)."""
    if modified:
        alpha, a, d, theta = row
    else:
        theta, d, a, alpha = row
    if kind == 'revolute':
        theta = theta + q
    else:
        d = d + q
    if modified:
        return rx(alpha) @ tr(x=a) @ rz(theta) @ tr(z=d)
    return rz(theta) @ tr(z=d) @ tr(x=a) @ rx(alpha)


def dh_product(rows: Sequence[Sequence[float]], kinds: Sequence[str], q: Sequence[float], *,
               modified: bool = False, base: np.ndarray | None = None,
               tool: np.ndarray | None = None) -> np.ndarray:
    """base · Π_i DH_i(q_i) · tool for one configuration q (dof,) -> 4x4."""
    T = np.eye(4) if base is None else np.array(base, dtype=float)
    for row, kind, qi in zip(rows, kinds, q):
        T = T @ dh_link(row, kind, float(qi), modified)
    if tool is not None:
        T = T @ tool
    return T


def dh_fk_batch(rows, kinds, qs, **kw) -> np.ndarray:
    """dh_product over qs (N, dof) -> (N, 4, 4)."""
    return np.array([dh_product(rows, kinds, q, **kw) for q in np.atleast_2d(qs)])


def embed12(T: np.ndarray) -> np.ndarray:
    """(p, n, o, a) of a 4x4 (or (..., 4, 4)) transform: position, then the rotation's columns."""
    return np.concatenate([T[..., :3, 3], T[..., :3, 0], T[..., :3, 1], T[..., :3, 2]], axis=-1)


# ---------------------------------------------------------------------- URDF writer
def _fmt(x: float) -> str:
    x = float(x)
    if abs(x) < 1e-14:
        x = 0.0  # no -0.0 or round-off specks in the text
    return f'{x:.16g}'


def origin_xml(T: np.ndarray) -> str:
    r, p, y = rpy_from_matrix(T[:3, :3])
    xyz = ' '.join(_fmt(v) for v in T[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{_fmt(r)} {_fmt(p)} {_fmt(y)}"/>'


def dh_to_urdf(
    name: str,
    rows: Sequence[Sequence[float]],
    kinds: Sequence[str],
    *,
    modified: bool = False,
    base: np.ndarray | None = None,
    tool: np.ndarray | None = None,
    continuous: Sequence[int] = (),
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    velocity: Sequence[float] | None = None,
    split: Sequence[int] = (),
    twist_seed: int | None = None,
    joint_names: Sequence[str] | None = None,
    root_link: str = 'world',
    base_link: str = 'base_link',
    tip_link: str = 'tool0',
    extra: str = '',
    comment: str = '',
) -> str:
    """URDF text of a DH chain.

    Link i's transform ``DH_i(q) = O_i · M(q) · A_i`` (O_i before the joint motion, A_i after it)
    becomes a joint with origin O_i (times an optional random re-orientation Q_i, with the joint
    axis then ``Q_iᵀ z``), and A_i is either folded into the next joint's origin or, for links in
    ``split``, emitted as its own fixed joint.

    Args:
        base: fixed transform root_link -> base_link (a fixed joint), identity if None.
        tool: fixed transform from the last DH frame to tip_link (a fixed joint).
        continuous: indices of revolute joints written as type="continuous" (no position limits).
        split: indices of links whose after-joint transform gets its own fixed joint.
        twist_seed: if set, each joint frame is re-oriented by a random rotation.
        extra: raw XML appended inside <robot> (e.g. a branch, for error tests).
    """
    n = len(rows)
    names = list(joint_names) if joint_names else [f'joint{i + 1}' for i in range(n)]
    lo = list(lower) if lower is not None else [-3.0] * n
    hi = list(upper) if upper is not None else [3.0] * n
    vel = list(velocity) if velocity is not None else [1.5] * n
    rng = np.random.default_rng(twist_seed) if twist_seed is not None else None
    links = [root_link, base_link]
    joints: list[str] = []
    joints.append(
        f'<joint name="{root_link}_to_{base_link}" type="fixed"><parent link="{root_link}"/>'
        f'<child link="{base_link}"/>{origin_xml(np.eye(4) if base is None else base)}</joint>')
    parent = base_link
    pending = np.eye(4)  # fixed transform not yet emitted
    for i, (row, kind) in enumerate(zip(rows, kinds)):
        if modified:
            alpha, a, d, theta = row
            before = rx(alpha) @ tr(x=a) @ rz(theta)
            after = tr(z=d)
            if kind == 'prismatic':
                before, after = before @ after, np.eye(4)
        else:
            theta, d, a, alpha = row
            before = rz(theta) @ tr(z=d)   # Rz(q) commutes with Tz(d); Tz(q) too
            after = tr(x=a) @ rx(alpha)
        Q = random_rotation(rng) if rng is not None else np.eye(4)
        origin = pending @ before @ Q
        axis = Q[:3, :3].T @ np.array([0.0, 0.0, 1.0])
        after = Q.T @ after  # undo the re-orientation after the motion (Q commutes with nothing, so
        # the motion M is expressed in the re-oriented frame: Q M' Qᵀ = M with M' about Qᵀ z)
        child = f'link{i + 1}'
        links.append(child)
        jtype = kind
        limit = f'<limit lower="{_fmt(lo[i])}" upper="{_fmt(hi[i])}" effort="100" velocity="{_fmt(vel[i])}"/>'
        if kind == 'revolute' and i in continuous:
            jtype = 'continuous'
            limit = f'<limit effort="100" velocity="{_fmt(vel[i])}"/>'
        ax = ' '.join(_fmt(v) for v in axis)
        joints.append(
            f'<joint name="{names[i]}" type="{jtype}"><parent link="{parent}"/><child link="{child}"/>'
            f'{origin_xml(origin)}<axis xyz="{ax}"/>{limit}</joint>')
        parent = child
        if i in split:
            mid = f'link{i + 1}_dh'
            links.append(mid)
            joints.append(
                f'<joint name="{names[i]}_dh_fixed" type="fixed"><parent link="{parent}"/>'
                f'<child link="{mid}"/>{origin_xml(after)}</joint>')
            parent = mid
            pending = np.eye(4)
        else:
            pending = after
    last = pending @ (np.eye(4) if tool is None else tool)
    links.append(tip_link)
    joints.append(
        f'<joint name="{tip_link}_fixed" type="fixed"><parent link="{parent}"/><child link="{tip_link}"/>'
        f'{origin_xml(last)}</joint>')
    body = '\n  '.join([f'<link name="{lk}"/>' for lk in links] + joints)
    head = f'<!-- {comment} -->\n' if comment else ''
    return f'<?xml version="1.0"?>\n{head}<robot name="{name}">\n  {body}\n  {extra}\n</robot>\n'


# ---------------------------------------------------------------------- example arms (data files)
PI = np.pi
DEG = PI / 180.0

#: KUKA KR6 R900-like 6R arm, standard DH rows (θ_offset, d, a, α), published main dimensions:
#: base height 0.400, shoulder offset 0.025, upper arm 0.455, elbow offset 0.035, forearm 0.420,
#: flange 0.080 (m). Mounted on a tilted pedestal; tool0 rotated from the flange.
KR6 = {
    'name': 'kr6_like',
    'doc': 'generic 6R industrial arm with KUKA KR6 R900-like dimensions (not an official model).',
    'rows': [(0.0, 0.400, 0.025, -PI / 2), (0.0, 0.0, 0.455, 0.0), (0.0, 0.0, 0.035, -PI / 2),
             (0.0, 0.420, 0.0, PI / 2), (0.0, 0.0, 0.0, -PI / 2), (0.0, 0.080, 0.0, 0.0)],
    'kinds': ['revolute'] * 6,
    'base': xyz_rpy((0.2, -0.1, 0.35), (0.05, -0.03, 0.5)),
    'tool': xyz_rpy((0.0, 0.01, 0.06), (PI, 0.0, PI / 2)),
    'lower': [-170 * DEG, -190 * DEG, -120 * DEG, -185 * DEG, -120 * DEG, -350 * DEG],
    'upper': [170 * DEG, 45 * DEG, 156 * DEG, 185 * DEG, 120 * DEG, 350 * DEG],
    'velocity': [360 * DEG, 300 * DEG, 360 * DEG, 381 * DEG, 388 * DEG, 615 * DEG],
    'joint_names': [f'kr6_a{i}' for i in range(1, 7)],
    'split': (1, 3),
    'root_link': 'world', 'base_link': 'kr6_base_link', 'tip_link': 'kr6_tool0',
}

#: KUKA LBR iiwa 14-like 7R arm, standard DH rows (θ_offset, d, a, α): d1 = 0.36, d3 = 0.42,
#: d5 = 0.40, flange d7 = 0.126 (m). Base offset with a yaw; tool0 offset along the flange axis.
IIWA = {
    'name': 'iiwa_like_7r',
    'doc': 'generic 7R redundant arm with KUKA LBR iiwa 14-like dimensions (not an official model).',
    'rows': [(0.0, 0.36, 0.0, -PI / 2), (0.0, 0.0, 0.0, PI / 2), (0.0, 0.42, 0.0, PI / 2),
             (0.0, 0.0, 0.0, -PI / 2), (0.0, 0.40, 0.0, -PI / 2), (0.0, 0.0, 0.0, PI / 2),
             (0.0, 0.126, 0.0, 0.0)],
    'kinds': ['revolute'] * 7,
    'base': xyz_rpy((-0.3, 0.25, 0.8), (0.0, 0.0, -PI / 3)),
    'tool': xyz_rpy((0.0, 0.0, 0.045), (0.0, 0.0, PI / 4)),
    'lower': [-170 * DEG, -120 * DEG, -170 * DEG, -120 * DEG, -170 * DEG, -120 * DEG, -175 * DEG],
    'upper': [170 * DEG, 120 * DEG, 170 * DEG, 120 * DEG, 170 * DEG, 120 * DEG, 175 * DEG],
    'velocity': [85 * DEG, 85 * DEG, 100 * DEG, 75 * DEG, 130 * DEG, 135 * DEG, 135 * DEG],
    'joint_names': [f'iiwa_joint_{i}' for i in range(1, 8)],
    'split': (0, 2, 4),
    'root_link': 'world', 'base_link': 'iiwa_link_0', 'tip_link': 'iiwa_tool0',
}

EXAMPLE_ARMS = {'kr6_like': KR6, 'iiwa_like_7r': IIWA}


def arm_urdf(spec: dict) -> str:
    """URDF text of one of EXAMPLE_ARMS."""
    keys = ('base', 'tool', 'lower', 'upper', 'velocity', 'joint_names', 'split', 'root_link',
            'base_link', 'tip_link')
    comment = (f'{spec["name"]}: {spec["doc"]} Written from a standard DH table by test/urdf_util.py '
               '(python test/urdf_util.py regenerates it); test/core/test_urdf.py checks its FK against '
               'the DH product.')
    return dh_to_urdf(spec['name'], spec['rows'], spec['kinds'], comment=comment,
                      **{k: spec[k] for k in keys})


def arm_fk(spec: dict, q: Sequence[float]) -> np.ndarray:
    """Oracle FK (root link -> tip link) of one of EXAMPLE_ARMS."""
    return dh_product(spec['rows'], spec['kinds'], q, base=spec['base'], tool=spec['tool'])


if __name__ == '__main__':  # regenerate geodesic_planner/data/*.urdf
    import os
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', 'geodesic_planner', 'data')
    for key, spec in EXAMPLE_ARMS.items():
        with open(os.path.join(out, f'{key}.urdf'), 'w', encoding='utf-8') as fh:
            fh.write(arm_urdf(spec))


def dh_fk_batched(rows: Sequence[Sequence[float]], kinds: Sequence[str], qs: np.ndarray, *,
                  modified: bool = False, base: np.ndarray | None = None,
                  tool: np.ndarray | None = None) -> np.ndarray:
    """Vectorised dh_product: qs (N, dof) -> (N, 4, 4) (same formulas, batched elementary matrices)."""
    qs = np.atleast_2d(np.asarray(qs, dtype=float))
    N = qs.shape[0]

    def brz(t):
        M = np.zeros((N, 4, 4))
        c, s = np.cos(t), np.sin(t)
        M[:, 0, 0], M[:, 0, 1], M[:, 1, 0], M[:, 1, 1] = c, -s, s, c
        M[:, 2, 2] = M[:, 3, 3] = 1.0
        return M

    def btz(d):
        M = np.broadcast_to(np.eye(4), (N, 4, 4)).copy()
        M[:, 2, 3] = d
        return M

    T = np.broadcast_to(np.eye(4) if base is None else base, (N, 4, 4)).copy()
    for i, (row, kind) in enumerate(zip(rows, kinds)):
        if modified:
            alpha, a, d, theta = row
        else:
            theta, d, a, alpha = row
        th = theta + (qs[:, i] if kind == 'revolute' else 0.0)
        dd = d + (qs[:, i] if kind == 'prismatic' else 0.0)
        if modified:
            T = T @ (rx(alpha) @ tr(x=a)) @ brz(np.broadcast_to(th, (N,))) @ btz(np.broadcast_to(dd, (N,)))
        else:
            T = T @ brz(np.broadcast_to(th, (N,))) @ btz(np.broadcast_to(dd, (N,))) @ (tr(x=a) @ rx(alpha))
    if tool is not None:
        T = T @ tool
    return T


# ---------------------------------------------------------------------- IK oracle (Newton, FD Jacobian)
def pose_residual(T: np.ndarray, T_star: np.ndarray) -> np.ndarray:
    """6-vector (p − p*, vee of the skew part of R R*ᵀ) for (..., 4, 4) -> (..., 6); zero iff equal
    (for rotation errors below π/2)."""
    E = T[..., :3, :3] @ np.swapaxes(T_star[..., :3, :3], -1, -2)
    w = 0.5 * np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0],
                        E[..., 1, 0] - E[..., 0, 1]], axis=-1)
    return np.concatenate([T[..., :3, 3] - T_star[..., :3, 3], w], axis=-1)


def newton_ik(fk_batch, T_star: np.ndarray, seed: np.ndarray, *, tol: float = 1e-13,
              max_iter: int = 30, h: float = 1e-7, damping: float = 0.0) -> np.ndarray:
    """Local IK by Newton's method (least squares for dof != 6) with a finite-difference Jacobian
    of an independent FK ``fk_batch(qs (N, dof)) -> (N, 4, 4)``. Converges to the solution nearest
    the seed's basin; raises AssertionError if it does not converge."""
    q = np.array(seed, dtype=float)
    n = q.size
    for _ in range(max_iter):
        Q = np.concatenate([q[None], q + h * np.eye(n), q - h * np.eye(n)])
        T = fk_batch(Q)
        e = pose_residual(T[0], T_star)
        if np.abs(e).max() < tol:
            return q
        J = ((pose_residual(T[1:n + 1], T_star) - pose_residual(T[n + 1:], T_star)) / (2 * h)).T
        if damping:
            dq = -np.linalg.solve(J.T @ J + damping * np.eye(n), J.T @ e)
        else:
            dq = -np.linalg.lstsq(J, e, rcond=None)[0]
        q = q + dq
    e = pose_residual(fk_batch(q[None])[0], T_star)
    assert np.abs(e).max() < 1e3 * tol, f'oracle IK did not converge: residual {np.abs(e).max():.3g}'
    return q


def continuation_ik(fk_batch, targets: np.ndarray, q0: np.ndarray, **kw) -> np.ndarray:
    """IK along a sequence of poses (N, 4, 4), each solve seeded with the previous solution."""
    out = [newton_ik(fk_batch, targets[0], q0, **kw)]
    for T in targets[1:]:
        out.append(newton_ik(fk_batch, T, out[-1], **kw))
    return np.array(out)


def line_slerp_oracle(T_a: np.ndarray, T_b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Straight line + constant-rate rotation (body-frame axis-angle), written independently."""
    Rrel = T_a[:3, :3].T @ T_b[:3, :3]
    axis = np.array([Rrel[2, 1] - Rrel[1, 2], Rrel[0, 2] - Rrel[2, 0], Rrel[1, 0] - Rrel[0, 1]])
    ang = float(np.arctan2(np.linalg.norm(axis) / 2, (np.trace(Rrel) - 1) / 2))
    assert ang < np.pi - 1e-6, 'rotation of pi: slerp axis ambiguous'
    axis = axis / np.linalg.norm(axis) if ang > 1e-15 else np.array([0.0, 0.0, 1.0])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    out = np.zeros((len(s), 4, 4))
    for k, sk in enumerate(s):
        R = np.eye(3) + np.sin(sk * ang) * K + (1 - np.cos(sk * ang)) * K @ K
        out[k, :3, :3] = T_a[:3, :3] @ R
        out[k, :3, 3] = (1 - sk) * T_a[:3, 3] + sk * T_b[:3, 3]
        out[k, 3, 3] = 1.0
    return out


# ---------------------------------------------------------------------- presets written out independently
#: Universal Robots UR5e, published standard DH rows (θ_offset, d, a, α).
UR5E_DH = [(0.0, 0.1625, 0.0, PI / 2), (0.0, 0.0, -0.425, 0.0), (0.0, 0.0, -0.3922, 0.0),
           (0.0, 0.1333, 0.0, PI / 2), (0.0, 0.0997, 0.0, -PI / 2), (0.0, 0.0996, 0.0, 0.0)]


def ur5e_fk_batch(qs: np.ndarray) -> np.ndarray:
    return dh_fk_batched(UR5E_DH, ['revolute'] * 6, qs)


def arm_fk_batch(spec: dict):
    """Batched oracle FK of one of EXAMPLE_ARMS."""
    return lambda qs: dh_fk_batched(spec['rows'], spec['kinds'], qs, base=spec['base'], tool=spec['tool'])


def axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """3x3 rotation by `angle` rad about `axis` (Rodrigues)."""
    u = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def moderate_moves(fk_batch, jacobian_min_sv, home: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                   seed: int, n: int, *, spread: float = 0.4, dist: tuple[float, float] = (0.08, 0.2),
                   angle_deg: tuple[float, float] = (10.0, 30.0), samples: int = 101):
    """Random start configurations near `home` and goal poses a line + rotation away.

    Returns a list of (q_a, T_a, T_b): T_a = FK(q_a); T_b translated by a random vector of length in
    `dist` (m) and rotated (body frame) by a random angle in `angle_deg` about a random axis. Only
    moves whose IK continuation along line + slerp stays inside the limits and away from singular
    configurations (smallest singular value of the Jacobian > 0.05, via `jacobian_min_sv(q)`) are kept.
    """
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(50 * n):
        q_a = np.clip(home + rng.uniform(-spread, spread, home.size), lower, upper)
        T_a = fk_batch(q_a[None])[0]
        d = rng.normal(size=3)
        d *= rng.uniform(*dist) / np.linalg.norm(d)
        T_b = T_a.copy()
        T_b[:3, :3] = T_a[:3, :3] @ axis_angle(rng.normal(size=3), np.deg2rad(rng.uniform(*angle_deg)))
        T_b[:3, 3] += d
        try:
            qs = continuation_ik(fk_batch, line_slerp_oracle(T_a, T_b, np.linspace(0, 1, samples)), q_a)
        except AssertionError:
            continue
        if np.abs(np.diff(qs, axis=0)).max() > 0.1:
            continue
        if not np.all((qs >= lower) & (qs <= upper)):
            continue
        if min(jacobian_min_sv(q) for q in qs) < 0.05:
            continue
        out.append((q_a, T_a, T_b))
        if len(out) == n:
            return out
    raise AssertionError('could not generate enough moderate moves')

#: Franka Panda, published modified DH rows (α_prev, a_prev, d, θ_offset); flange 0.107 m along z.
PANDA_MDH = [(0.0, 0.0, 0.333, 0.0), (-PI / 2, 0.0, 0.0, 0.0), (PI / 2, 0.0, 0.316, 0.0),
             (PI / 2, 0.0825, 0.0, 0.0), (-PI / 2, -0.0825, 0.384, 0.0), (PI / 2, 0.0, 0.0, 0.0),
             (PI / 2, 0.088, 0.0, 0.0)]


def panda_fk_batch(qs: np.ndarray) -> np.ndarray:
    return dh_fk_batched(PANDA_MDH, ['revolute'] * 7, qs, modified=True, tool=tr(z=0.107))


#: UFACTORY xArm 7, modified DH rows (α_prev, a_prev, d, θ_offset) read off the joint origins of
#: xarm_description's default kinematics (xyz + roll only); the flange is the tool. Limits as its URDF.
XARM7_MDH = [(0.0, 0.0, 0.267, 0.0), (-PI / 2, 0.0, 0.0, 0.0), (PI / 2, 0.0, 0.293, 0.0),
             (PI / 2, 0.0525, 0.0, 0.0), (PI / 2, 0.0775, 0.3425, 0.0), (PI / 2, 0.0, 0.0, 0.0),
             (-PI / 2, 0.076, 0.097, 0.0)]
XARM7_LOWER = [-2 * PI, -2.059, -2 * PI, -0.19198, -2 * PI, -1.69297, -2 * PI]
XARM7_UPPER = [2 * PI, 2.0944, 2 * PI, 3.927, 2 * PI, PI, 2 * PI]


def xarm7_fk_batch(qs: np.ndarray) -> np.ndarray:
    return dh_fk_batched(XARM7_MDH, ['revolute'] * 7, qs, modified=True)


def tool_deviation(fk_batch, qs: np.ndarray, T_a: np.ndarray, T_b: np.ndarray, s: np.ndarray):
    """Largest position (m) and rotation (rad) distance of FK(qs) from line + slerp at s."""
    T = fk_batch(qs)
    T_line = line_slerp_oracle(T_a, T_b, s)
    dp = np.linalg.norm(T[:, :3, 3] - T_line[:, :3, 3], axis=1)
    Rrel = np.swapaxes(T[:, :3, :3], 1, 2) @ T_line[:, :3, :3]
    vee = np.stack([Rrel[:, 2, 1] - Rrel[:, 1, 2], Rrel[:, 0, 2] - Rrel[:, 2, 0], Rrel[:, 1, 0] - Rrel[:, 0, 1]], 1)
    ang = np.arctan2(np.linalg.norm(vee, axis=1) / 2, (np.trace(Rrel, axis1=1, axis2=2) - 1) / 2)
    return float(dp.max()), float(ang.max())
