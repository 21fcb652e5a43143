"""PTP: joint-space motions for free space, as geodesics of two metrics (docs/maths.md, "PTP").

- ``joint_line``: the Euclidean metric on the joints; its geodesic is the straight line
  ``q(s) = q_a + s (q_b - q_a)`` (Pilz PTP's path).
- ``kinetic_energy``: the mass-matrix metric ``<u, v> = u^T M(q) v`` of the URDF's ``<inertial>``
  elements; the path of least action ``int_0^1 q'^T M(q) q' ds`` (twice the kinetic energy
  integral at unit duration; the paper's "minimum kinetic energy" paths, Introduction and
  section 2) between the two configurations, inside the joint limits. It is found by direct
  minimisation of the discretised action from several starts (:mod:`.least_energy`): a local
  minimum, never a saddle of the geodesic equation ``M q'' + C(q, q') q' = 0``. M and its
  derivative come from pinocchio (``crba``, ``computeCoriolisMatrix``), gravity left out.

:func:`action` gives a path's integral of ``q'^T M(q) q'`` over s in [0, 1].
"""
from __future__ import annotations

from typing import Protocol

import numpy as np

from .errors import RequestError
from .kinematics import Chain
from .least_energy import LeastEnergyPath, least_energy_path
from .path import JointPath, check_order, check_s

__all__ = ['PTP_OPTIONS', 'ConstantMass', 'JointLinePath', 'KineticEnergyPath', 'MassModel', 'UrdfMass',
           'action', 'kinetic_energy_path', 'mass_from_urdf']

#: The ``ptp`` options: the geodesic's metric.
PTP_OPTIONS = ('kinetic_energy', 'joint_line')


class MassModel(Protocol):
    """What the kinetic-energy metric needs: M(q) and the velocity terms C(q, v) v, chain order."""

    def matrix(self, q: np.ndarray) -> np.ndarray:
        """M(q): (dof,) -> (dof, dof), kg m^2 (kg for prismatic joints)."""
        ...

    def velocity_terms(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """C(q, v) v: (dof,), (dof,) -> (dof,)."""
        ...

    def terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """At m points (m, dof) each: M(q) (m, dof, dof) and the derivative of v^T M(q) v in q
        (m, dof), which is 2 C(q, v)^T v."""
        ...


class ConstantMass:
    """A constant mass matrix (tests, and arms whose inertia does not depend on q)."""

    def __init__(self, M: np.ndarray) -> None:
        self.M = np.asarray(M, dtype=float)

    def matrix(self, q: np.ndarray) -> np.ndarray:
        return self.M

    def velocity_terms(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.zeros_like(np.asarray(v, dtype=float))

    def terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.broadcast_to(self.M, (len(q),) + self.M.shape), np.zeros_like(np.asarray(v, dtype=float))


class UrdfMass:
    """M(q) and C(q, v) v of a URDF's ``<inertial>`` elements, through pinocchio, for the joints of
    ``robot`` (other joints of the URDF, e.g. gripper fingers, locked at their neutral value).

    Raises:
        RequestError: the URDF cannot be read, lacks one of the chain's joints, or a moving link of
            the chain has no mass (its message says which: the kinetic-energy metric needs them).
    """

    def __init__(self, robot: Chain, urdf: str) -> None:
        import pinocchio as pin

        try:
            full = pin.buildModelFromXML(urdf)
        except (RuntimeError, ValueError) as err:
            raise RequestError(f'kinetic_energy: the URDF cannot be read by pinocchio: {err}') from None
        names = list(full.names)
        missing = [n for n in robot.joint_names if n not in names]
        if missing:
            raise RequestError(f'kinetic_energy: the URDF has no joint {missing[0]!r}')
        lock = [i for i, n in enumerate(names) if i > 0 and n not in robot.joint_names]
        model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
        model.gravity.setZero()
        ids = [model.getJointId(n) for n in robot.joint_names]
        if any(model.joints[i].nq != 1 for i in ids):
            raise RequestError('kinetic_energy: only revolute and prismatic joints (one coordinate each)')
        massless = [model.names[i] for i in ids if model.inertias[i].mass <= 0.0]
        if massless:
            raise RequestError(f'kinetic_energy: the link moved by joint {massless[0]!r} has no '
                               '<inertial> mass in the URDF')
        self._pin, self._model, self._data = pin, model, model.createData()
        self._iq = np.array([model.joints[i].idx_q for i in ids])
        self._iv = np.array([model.joints[i].idx_v for i in ids])
        self._q0 = pin.neutral(model)

    def _q(self, q: np.ndarray) -> np.ndarray:
        full = self._q0.copy()
        full[self._iq] = q
        return full

    def matrix(self, q: np.ndarray) -> np.ndarray:
        M = self._pin.crba(self._model, self._data, self._q(q))
        M = np.triu(M) + np.triu(M, 1).T
        return M[np.ix_(self._iv, self._iv)]

    def velocity_terms(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        nv = self._model.nv
        vf, zero = np.zeros(nv), np.zeros(nv)
        vf[self._iv] = v
        return np.asarray(self._pin.rnea(self._model, self._data, self._q(q), vf, zero))[self._iv]

    def terms(self, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pin, model, data = self._pin, self._model, self._data
        crba, coriolis = pin.crba, pin.computeCoriolisMatrix
        m, nv = len(q), model.nv
        M, C = np.empty((m, nv, nv)), np.empty((m, nv, nv))
        qf, vf = np.empty((m, self._q0.size)), np.zeros((m, nv))
        qf[:] = self._q0
        qf[:, self._iq], vf[:, self._iv] = q, v
        for k in range(m):                # pinocchio has no batched call: ~5 us a point
            M[k] = crba(model, data, qf[k])
            C[k] = coriolis(model, data, qf[k], vf[k])
        upper = np.triu(np.ones((nv, nv), dtype=bool))
        M = np.where(upper, M, np.transpose(M, (0, 2, 1)))       # crba fills the upper triangle
        grad = 2.0 * np.einsum('pji,pj->pi', C, vf)
        if nv == len(self._iv):
            return M, grad
        return M[:, self._iv][:, :, self._iv], grad[:, self._iv]


class JointLinePath(JointPath):
    """The straight line in joint space between q_a and q_b (dof,)."""

    def __init__(self, robot: Chain, q_a: np.ndarray, q_b: np.ndarray) -> None:
        self.robot = robot
        self._q_a = robot.check_joints(q_a, 'start joints')
        self._dq = robot.check_joints(q_b, 'goal joints') - self._q_a

    @property
    def joint_line(self) -> tuple[np.ndarray, np.ndarray]:
        """``(q_a, q_b - q_a)``, each (dof,), rad or m: the path is ``q_a + s (q_b - q_a)``.

        The jerk-limited time law reads it to time the line in closed form (timing.line_profile).
        """
        return self._q_a.copy(), self._dq.copy()

    def deviation(self, s: np.ndarray) -> np.ndarray:
        """Zeros: a PTP has no tool geometry to keep."""
        return np.zeros(check_s(s).size)

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        s = check_s(s)
        order = check_order(order)
        q = self._q_a + s[:, None] * self._dq
        rest = [np.broadcast_to(self._dq, q.shape).copy(), np.zeros_like(q), np.zeros_like(q)]
        return tuple([q] + rest[:order])


#: The kinetic-energy PTP's path (a polynomial per joint, :mod:`.least_energy`).
KineticEnergyPath = LeastEnergyPath


def kinetic_energy_path(robot: Chain, mass: MassModel, q_a: np.ndarray, q_b: np.ndarray) -> KineticEnergyPath:
    """The path of least action of the mass-matrix metric from q_a to q_b (dof,), inside the joint
    limits (:func:`.least_energy.least_energy_path`).

    Raises:
        BVPError: the descent diverged (NaN from the mass model).
    """
    q_a = robot.check_joints(q_a, 'start joints')
    q_b = robot.check_joints(q_b, 'goal joints')
    return least_energy_path(robot, mass.terms, q_a, q_b)


def action(path: JointPath, mass: MassModel, samples: int = 2001) -> float:
    """``int_0^1 q'^T M(q) q' ds`` of ``path`` (Simpson's rule on ``samples`` (odd) values of s)."""
    k = int(samples) | 1
    s = np.linspace(0.0, 1.0, k)
    q, v = path.evaluate(s, 1)
    f = np.array([vk @ mass.matrix(qk) @ vk for qk, vk in zip(q, v)])
    h = 1.0 / (k - 1)
    return float(h / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum()))


def mass_from_urdf(robot: Chain, urdf: str | None) -> tuple[UrdfMass | None, str]:
    """The URDF's mass model for ``robot``, or (None, why not): no URDF (a DH preset), or a link
    without ``<inertial>`` mass; PTP ``kinetic_energy`` then plans the joint line and says so."""
    if not urdf:
        return None, f'robot {robot.name!r} has no URDF (no <inertial> elements)'
    try:
        return UrdfMass(robot, urdf), ''
    except RequestError as err:
        return None, str(err)
