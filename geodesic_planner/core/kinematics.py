"""Serial-chain kinematics: batched forward kinematics and analytic derivatives of the pose.

A chain is ``T(q) = F0 · M1(q1) · F1 · M2(q2) · … · Mn(qn) · Fn`` where ``Fi`` are fixed 4x4
transforms and ``Mi`` is a rotation about (revolute) or translation along (prismatic) a unit axis
given in the joint's own frame. Standard DH, modified DH (Craig) and URDF all map onto this form.

Derivatives use the spatial generators ``X_k`` (4x4 twist matrices of joint k in the base frame at
configuration q): ``∂T/∂q_k = X_k T``, ``∂²T/∂q_j∂q_k = X_min X_max T`` and
``∂³T/∂q_i∂q_j∂q_k = X_a X_b X_c T`` (indices sorted). The pose embedding of the paper,
``f(q) = (p, n, o, a) ∈ R^12``, is the top 3x4 block of T, so every derivative of f is exact and
needs only products of 4x4 matrices (no finite differences).

Units: lengths in m, angles in rad. Arrays are batched over leading axes: ``q`` has shape (..., dof).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from . import compiled
from .chunks import in_chunks
from .errors import KinematicsError, RequestError
from .transforms import check_transform, hat

REVOLUTE = 'revolute'
PRISMATIC = 'prismatic'

#: Default joint acceleration limit when the model gives none, rad/s^2 (m/s^2).
DEFAULT_MAX_ACCELERATION = 5.0
#: Default joint velocity limit when the model gives none, rad/s (m/s).
DEFAULT_MAX_VELOCITY = 1.0


def rot_x(a: float) -> np.ndarray:
    """4x4 rotation about x by ``a`` rad."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def rot_z(a: float) -> np.ndarray:
    """4x4 rotation about z by ``a`` rad."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def trans(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    """4x4 translation by (x, y, z) m."""
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


@dataclass(frozen=True)
class Joint:
    """One actuated joint.

    Attributes:
        name: joint name.
        kind: ``'revolute'`` or ``'prismatic'``.
        axis: unit axis (3,) in the joint frame (the frame after the preceding fixed transform).
        lower, upper: position limits, rad or m (may be infinite).
        max_velocity: velocity limit, rad/s or m/s.
        max_acceleration: acceleration limit, rad/s^2 or m/s^2.
    """

    name: str
    kind: str
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    lower: float = -np.inf
    upper: float = np.inf
    max_velocity: float = DEFAULT_MAX_VELOCITY
    max_acceleration: float = DEFAULT_MAX_ACCELERATION


class Chain:
    """An immutable serial chain of revolute and prismatic joints (the robot model).

    Args:
        name: model name.
        joints: the actuated joints, base to tip.
        fixed: ``len(joints) + 1`` fixed 4x4 transforms F0..Fn interleaved with the joints.
        base_link, tip_link: frame names (informational).
        home: default IK seed (dof,); zeros (clipped into the limits) when omitted.

    Raises:
        KinematicsError: inconsistent sizes, bad axes or limits.
    """

    def __init__(
        self,
        name: str,
        joints: Sequence[Joint],
        fixed: Sequence[np.ndarray],
        *,
        base_link: str = 'base_link',
        tip_link: str = 'tool0',
        home: Sequence[float] | np.ndarray | None = None,
    ) -> None:
        if len(joints) == 0:
            raise KinematicsError(f'robot {name!r}: a chain needs at least one actuated joint')
        if len(fixed) != len(joints) + 1:
            raise KinematicsError(
                f'robot {name!r}: {len(joints)} joints need {len(joints) + 1} fixed transforms, '
                f'got {len(fixed)}')
        self.name = name
        #: Optional closed-form IK: targets (N, 4, 4) -> candidate solutions (B, N, dof), NaN rows
        #: where a branch has no solution. Used for the path ends and the mesh nodes when set.
        self.closed_form_ik: Callable[[np.ndarray], np.ndarray] | None = None
        self.joints: tuple[Joint, ...] = tuple(joints)
        self.base_link = base_link
        self.tip_link = tip_link
        self._fixed = np.array([np.asarray(F, dtype=float) for F in fixed])
        self._fixed_given = self._fixed.copy()
        if self._fixed.shape[1:] != (4, 4) or not np.all(np.isfinite(self._fixed)):
            raise KinematicsError(f'robot {name!r}: fixed transforms must be finite 4x4 matrices')
        axes = []
        for j in self.joints:
            if j.kind not in (REVOLUTE, PRISMATIC):
                raise KinematicsError(f'robot {name!r}: joint {j.name!r} has unsupported type {j.kind!r}')
            a = np.asarray(j.axis, dtype=float)
            nrm = np.linalg.norm(a)
            if a.shape != (3,) or not np.isfinite(nrm) or nrm < 1e-9:
                raise KinematicsError(f'robot {name!r}: joint {j.name!r} has an invalid axis {a.tolist()}')
            axes.append(a / nrm)
            if not j.lower <= j.upper:
                raise KinematicsError(f'robot {name!r}: joint {j.name!r} has lower limit > upper limit')
            if not (j.max_velocity > 0 and j.max_acceleration > 0):
                raise KinematicsError(f'robot {name!r}: joint {j.name!r} needs positive velocity and '
                                      'acceleration limits')
        # Fold every joint axis u into the fixed transforms: M(q) about/along u equals
        # C Rz(q) Cᵀ (C Tz(q) Cᵀ) with C e_z = u, so the hot path only handles z axes.
        fixed_z = [F.copy() for F in self._fixed]
        for i, u in enumerate(axes):
            if np.allclose(u, [0.0, 0.0, 1.0]):
                continue
            C = np.eye(4)
            C[:3, :3] = rotation_z_to(u)
            fixed_z[i] = fixed_z[i] @ C
            fixed_z[i + 1] = C.T @ fixed_z[i + 1]
        self._fixed = np.array(fixed_z)
        self._joint_axes = np.array(axes)
        self._prismatic = np.array([j.kind == PRISMATIC for j in self.joints])
        self._revolute_mask = (~self._prismatic).astype(float)[:, None]
        self._all_revolute = not bool(self._prismatic.any())
        self._kernel_chain = compiled.Pinned(self._fixed, self._prismatic)   # for the compiled kinematics
        self.joint_names: list[str] = [j.name for j in self.joints]
        if len(set(self.joint_names)) != len(self.joint_names):
            raise KinematicsError(f'robot {name!r}: duplicate joint names {self.joint_names}')
        self.joint_types: tuple[str, ...] = tuple(j.kind for j in self.joints)
        #: True for the revolute joints, shape (dof,) (a 2π turn of them leaves the pose unchanged).
        self.revolute: np.ndarray = ~self._prismatic
        self.revolute.setflags(write=False)
        self.lower = np.array([j.lower for j in self.joints], dtype=float)
        self.upper = np.array([j.upper for j in self.joints], dtype=float)
        self.max_velocity = np.array([j.max_velocity for j in self.joints], dtype=float)
        self.max_acceleration = np.array([j.max_acceleration for j in self.joints], dtype=float)
        if home is None:
            h = np.clip(np.zeros(self.dof), self.lower, self.upper)
        else:
            h = np.asarray(home, dtype=float)
            if h.shape != (self.dof,):
                raise KinematicsError(f'robot {name!r}: home needs {self.dof} values')
        self.home = h
        for arr in (self.lower, self.upper, self.max_velocity, self.max_acceleration, self.home):
            arr.setflags(write=False)

    def __repr__(self) -> str:
        return f'Chain({self.name!r}, dof={self.dof}, joints={self.joint_names})'

    @property
    def dof(self) -> int:
        """Number of actuated joints."""
        return len(self.joints)

    def with_limits(
        self,
        *,
        max_velocity: Sequence[float] | float | None = None,
        max_acceleration: Sequence[float] | float | None = None,
        joint_names: Sequence[str] | None = None,
    ) -> Chain:
        """A copy with other velocity/acceleration limits or joint names (scalars broadcast)."""
        mv = self.max_velocity if max_velocity is None else np.broadcast_to(
            np.asarray(max_velocity, dtype=float), (self.dof,))
        ma = self.max_acceleration if max_acceleration is None else np.broadcast_to(
            np.asarray(max_acceleration, dtype=float), (self.dof,))
        names = self.joint_names if joint_names is None else list(joint_names)
        if len(names) != self.dof:
            raise KinematicsError(f'robot {self.name!r}: {len(names)} joint names for {self.dof} joints')
        joints = [
            Joint(n, j.kind, j.axis, j.lower, j.upper, float(v), float(a))
            for n, j, v, a in zip(names, self.joints, mv, ma)
        ]
        return Chain(self.name, joints, list(self._fixed_given), base_link=self.base_link,
                     tip_link=self.tip_link, home=self.home)

    # ------------------------------------------------------------------ input checks
    def check_joints(self, q: object, what: str = 'joints') -> np.ndarray:
        """Validate a joint vector: shape (..., dof), finite. Returns a float array.

        Raises:
            RequestError: wrong joint count or NaN/inf (the message names which).
        """
        try:
            arr = np.asarray(q, dtype=float)
        except (TypeError, ValueError) as err:
            raise RequestError(f'{what}: not a numeric joint vector ({err})') from err
        if arr.ndim == 0 or arr.shape[-1] != self.dof:
            got = 1 if arr.ndim == 0 else arr.shape[-1]
            raise RequestError(f'{what}: robot {self.name!r} has {self.dof} joints '
                               f'{self.joint_names}, got {got} values')
        if not np.all(np.isfinite(arr)):
            raise RequestError(f'{what}: joint values contain NaN or inf: {arr.tolist()}')
        return arr

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Boolean (...,): every joint inside [lower, upper] (with tolerance)."""
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)

    # ------------------------------------------------------------------ kinematics
    def frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Joint frames and tool pose.

        Args:
            q: joint positions, shape (N, dof).
        Returns:
            (Tj, T): Tj (N, dof, 4, 4) base->joint-frame transforms (the frame in which joint i's
            axis is given, before its motion), T (N, 4, 4) base->tool.
        """
        return in_chunks(self._frames, q)

    def _frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if compiled.active():
            return compiled.frames(self._kernel_chain, q)
        N = q.shape[0]
        F = self._fixed[1:]                      # (dof, 4, 4): F_{i+1}
        # M_i F_{i+1}, M_i a rotation about / translation along z: row operations on F_{i+1},
        # for all joints at once.
        MF = np.empty((N, self.dof, 4, 4))
        MF[:] = F
        c = np.cos(q)[..., None]
        s_ = np.sin(q)[..., None]
        rot0 = c * F[:, 0] - s_ * F[:, 1]
        rot1 = s_ * F[:, 0] + c * F[:, 1]
        if self._all_revolute:
            MF[:, :, 0] = rot0
            MF[:, :, 1] = rot1
        else:
            rev = ~self._prismatic[:, None]
            MF[:, :, 0] = np.where(rev, rot0, F[:, 0])
            MF[:, :, 1] = np.where(rev, rot1, F[:, 1])
            MF[:, :, 2] += np.where(rev, 0.0, q[..., None] * F[:, 3])
        Tj = np.empty((N, self.dof, 4, 4))
        T = self._fixed[0]                       # (4, 4): broadcasts in the first product
        for i in range(self.dof):
            Tj[:, i] = T
            T = T @ MF[:, i]
        return Tj, T

    def segment_frames(self, q: np.ndarray) -> np.ndarray:
        """Frames of the rigid segments: the base and the body moved by each joint.

        Args:
            q: joint positions, shape (N, dof).
        Returns:
            (N, dof + 1, 4, 4) base->segment transforms: index 0 is the base (identity), index k
            the frame moved by joint k (its joint frame after the joint's motion; every link between
            joint k and joint k + 1 is rigidly attached to it).
        """
        Tj, _ = self.frames(q)
        N = q.shape[0]
        S = np.empty((N, self.dof + 1, 4, 4))
        S[:, 0] = np.eye(4)
        S[:, 1:] = Tj
        c = np.cos(q)[..., None]
        s_ = np.sin(q)[..., None]
        col0, col1 = Tj[..., :, 0], Tj[..., :, 1]
        rev = ~self._prismatic[:, None]
        S[:, 1:, :, 0] = np.where(rev, c * col0 + s_ * col1, col0)
        S[:, 1:, :, 1] = np.where(rev, c * col1 - s_ * col0, col1)
        S[:, 1:, :, 3] += np.where(rev, 0.0, q[..., None] * Tj[..., :, 2])
        return S

    def segment_ends(self) -> np.ndarray:
        """(dof + 1, 3): where each segment ends in its own frame (m): the next joint's origin, the
        tool's for the last segment (a segment's length is this point's norm)."""
        return self._fixed[:, :3, 3].copy()

    def tool_offset(self) -> np.ndarray:
        """4x4: the last segment's frame -> the tool frame (fixed)."""
        return self._fixed[-1].copy()

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Forward kinematics: joint positions (..., dof) -> base->tool transforms (..., 4, 4)."""
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, self.dof)
        return self.frames(flat)[1].reshape(q.shape[:-1] + (4, 4))

    def generators(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spatial twist matrices X_k (base frame) and tool pose.

        Args:
            q: joint positions (N, dof).
        Returns:
            (X, T): X (N, dof, 4, 4) with ``∂T/∂q_k = X_k T``; T (N, 4, 4).
        """
        return in_chunks(self._generators, q)

    def _generators(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if compiled.active():
            return compiled.generators(self._kernel_chain, q)
        Tj, T = self._frames(q)
        u = Tj[..., :3, 2]  # joint axes in the base frame (all axes were folded onto z)
        p = Tj[..., :3, 3]
        X = np.zeros(Tj.shape)
        w = u * self._revolute_mask
        X[..., :3, :3] = hat(w)
        # v = p × ω for revolute joints, the axis for prismatic ones
        X[..., :3, 3] = np.einsum('...ij,...j->...i', hat(p), w)
        if not self._all_revolute:
            X[..., :3, 3] += u * (1.0 - self._revolute_mask)
        return X, T

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Geometric Jacobian in the base frame, rows [v; ω]: (..., dof) -> (..., 6, dof).

        v is the velocity of the tool origin (m/s per unit joint rate), ω the angular velocity.
        """
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, self.dof)
        X, T = self.generators(flat)
        w = _vee3(X[..., :3, :3])  # (N, dof, 3)
        v = np.einsum('nkab,nb->nka', X[..., :3, :3], T[:, :3, 3]) + X[..., :3, 3]
        J = np.concatenate([v, w], axis=-1).transpose(0, 2, 1)
        return J.reshape(q.shape[:-1] + (6, self.dof))

    def jacobian12(self, q: np.ndarray) -> np.ndarray:
        """Jacobian of the paper's embedding f = (p, n, o, a) ∈ R^12: (..., dof) -> (..., 12, dof)."""
        q = np.asarray(q, dtype=float)
        flat = q.reshape(-1, self.dof)
        X, T = self.generators(flat)
        Y = X @ T[:, None]
        J = embed12(Y).transpose(0, 2, 1)
        return J.reshape(q.shape[:-1] + (12, self.dof))

    def hessian12(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Second directional derivative H(q, v) = Σ_jk ∂²f/∂q_j∂q_k v_j v_k of f = (p, n, o, a).

        Args:
            q, v: joint positions and a direction, (..., dof).
        Returns:
            (..., 12).
        """
        q = np.asarray(q, dtype=float)
        v = np.broadcast_to(np.asarray(v, dtype=float), q.shape)
        flat, vf = q.reshape(-1, self.dof), v.reshape(-1, self.dof)
        X, T = self.generators(flat)
        W = X * vf[..., None, None]
        C = np.cumsum(W, axis=1)
        P = C - W
        S = np.sum((W + 2.0 * P) @ W, axis=1)
        return embed12(S @ T).reshape(q.shape[:-1] + (12,))


def taylor3(W: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Taylor coefficients c1, c2, c3 of the product e^{W_1 t} ... e^{W_n t} at t = 0.

    W: (N, n, 4, 4), the joints' generators times their rates (``X * v``). The d-th derivative
    of the pose along the motion is d! c_d T. Returns three (N, 4, 4) arrays.
    """
    c1 = np.zeros(W.shape[:1] + W.shape[2:])
    c2 = np.zeros_like(c1)
    c3 = np.zeros_like(c1)
    for k in range(W.shape[1]):
        Wk = W[:, k]
        Wk2 = Wk @ Wk
        c3 = c3 + c2 @ Wk + c1 @ Wk2 / 2.0 + Wk2 @ Wk / 6.0
        c2 = c2 + c1 @ Wk + Wk2 / 2.0
        c1 = c1 + Wk
    return c1, c2, c3


def embed12(M: np.ndarray) -> np.ndarray:
    """The 12-vector (p, n, o, a) of 4x4 matrices (..., 4, 4): columns 3, 0, 1, 2 of the top 3 rows."""
    return np.concatenate([M[..., :3, 3], M[..., :3, 0], M[..., :3, 1], M[..., :3, 2]], axis=-1)


def rotation_z_to(u: np.ndarray) -> np.ndarray:
    """A rotation matrix C with C @ e_z = u (u a unit vector)."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, u))
    if c > 1 - 1e-15:
        return np.eye(3)
    if c < -1 + 1e-15:
        return np.diag([1.0, -1.0, -1.0])
    k = np.cross(z, u)
    K = hat(k)
    return np.eye(3) + K + K @ K / (1.0 + c)


def _vee3(K: np.ndarray) -> np.ndarray:
    return np.stack([K[..., 2, 1], K[..., 0, 2], K[..., 1, 0]], axis=-1)


# ---------------------------------------------------------------------- DH builders
def chain_from_dh(
    name: str,
    rows: Sequence[Sequence[float]],
    kinds: Sequence[str],
    *,
    modified: bool = False,
    tool: np.ndarray | None = None,
    joint_names: Sequence[str] | None = None,
    lower: Sequence[float] | None = None,
    upper: Sequence[float] | None = None,
    max_velocity: Sequence[float] | float = DEFAULT_MAX_VELOCITY,
    max_acceleration: Sequence[float] | float = DEFAULT_MAX_ACCELERATION,
    home: Sequence[float] | None = None,
    base_link: str = 'base_link',
    tip_link: str = 'tool0',
) -> Chain:
    """Build a chain from a DH table.

    Args:
        rows: standard DH rows ``(theta_offset, d, a, alpha)`` with
            ``T_i = Rz(θ) Tz(d) Tx(a) Rx(α)``; or, with ``modified=True`` (Craig),
            ``(alpha_prev, a_prev, d, theta_offset)`` with ``T_i = Rx(α) Tx(a) Rz(θ) Tz(d)``.
            For a prismatic joint the joint variable adds to d; for a revolute one to θ.
            Lengths m, angles rad.
        kinds: ``'revolute'``/``'prismatic'`` per row.
        tool: fixed 4x4 tool transform after the last joint (identity if omitted).

    Raises:
        KinematicsError: malformed table.
    """
    n = len(rows)
    if len(kinds) != n:
        raise KinematicsError(f'robot {name!r}: {n} DH rows but {len(kinds)} joint kinds')
    names = list(joint_names) if joint_names is not None else [f'joint{i + 1}' for i in range(n)]
    if len(names) != n:
        raise KinematicsError(f'robot {name!r}: {len(names)} joint names for {n} joints')

    def per_joint(value: object, what: str, default: float) -> np.ndarray:
        try:
            arr = np.asarray(default if value is None else value, dtype=float)
        except (TypeError, ValueError) as err:
            raise KinematicsError(f'robot {name!r}: {what} need one number or {n} numbers, '
                                  f'got {value!r}') from err
        if arr.ndim == 0:
            return np.full(n, float(arr))
        if arr.shape != (n,):
            raise KinematicsError(f'robot {name!r}: {what} need one number or {n} numbers, '
                                  f'got {arr.size}')
        return arr.copy()

    lo = per_joint(lower, 'lower limits', -np.inf)
    hi = per_joint(upper, 'upper limits', np.inf)
    mv = per_joint(max_velocity, 'velocity limits', DEFAULT_MAX_VELOCITY)
    ma = per_joint(max_acceleration, 'acceleration limits', DEFAULT_MAX_ACCELERATION)
    fixed = [np.eye(4)]
    joints = []
    for i, (row, kind) in enumerate(zip(rows, kinds)):
        try:
            vals = [float(x) for x in row]
        except (TypeError, ValueError) as err:
            raise KinematicsError(f'robot {name!r}: DH row {i} must hold 4 numbers, got {row!r}') from err
        if len(vals) != 4:
            raise KinematicsError(f'robot {name!r}: DH row {i} needs 4 numbers, got {len(vals)}')
        if not np.all(np.isfinite(vals)):
            raise KinematicsError(f'robot {name!r}: DH row {i} contains NaN or inf: {row!r}')
        if modified:
            alpha, a, d, theta = vals
            before = rot_x(alpha) @ trans(x=a) @ rot_z(theta)
            after = trans(z=d)
        else:
            theta, d, a, alpha = vals
            before = rot_z(theta)
            after = trans(z=d) @ trans(x=a) @ rot_x(alpha)
        if kind == PRISMATIC:
            # Tz(d + q) = Tz(d) Tz(q): move the constant part before the joint (Tz commutes with Rz).
            if modified:
                before, after = before @ after, np.eye(4)
            else:
                before, after = before @ trans(z=d), trans(x=a) @ rot_x(alpha)
        fixed[-1] = fixed[-1] @ before
        fixed.append(after)
        joints.append(Joint(names[i], kind, np.array([0.0, 0.0, 1.0]), float(lo[i]), float(hi[i]),
                            float(mv[i]), float(ma[i])))
    if tool is not None:
        try:
            tool_T = check_transform(tool, f'robot {name!r}: tool')
        except RequestError as err:
            raise KinematicsError(str(err)) from err
        fixed[-1] = fixed[-1] @ tool_T
    return Chain(name, joints, fixed, base_link=base_link, tip_link=tip_link, home=home)
