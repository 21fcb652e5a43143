"""Tool speed rows: limits on the tool's Cartesian speed as velocity rows of a time law.

Along a path q(s) the tool's twist (base frame, rows [v; ω]: v the velocity of the tool frame
origin, ω the angular velocity) is ``V(s) sdot`` with ``V(s) = J(q(s)) q'(s)``, the twist per unit
s. A limit ``|v| <= max_tool_speed`` is then one more velocity row, ``|V_v(s)| sdot <=
max_tool_speed``, exactly like a joint's ``|q_i'(s)| sdot <= vmax_i``; likewise ``|ω| <=
max_tool_angular_speed`` with ``|V_ω(s)|``. (On a pull-back geodesic ``|V_v|`` is the length of the
tool's line and ``|V_ω|`` its rotation angle, both constant in s; nothing here assumes it.)

V and its s-derivative V' come from the robot's derivatives of the paper's embedding
f = (p, n, o, a) (``jacobian12``, ``hessian12``) and the tool pose (``fk``): ``p' = J12_p q'``,
``p'' = J12_p q'' + H12_p(q, q')``; with ``R' = J12_R q'`` and ``R'' = J12_R q'' + H12_R(q, q')``,
``ω^ = R' R^T`` and ``(ω')^ = skew(R'' R^T)`` (``R' R'^T`` is symmetric). At the path's nodes they
are the :class:`~.sampling.PathSamples` of a six-row "path" (rows [v; ω]), interpolated between
the nodes as the joints' derivatives are.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from ..core.errors import LimitError
from .sampling import PathSamples

if TYPE_CHECKING:
    from .types import JointLimits, PathLike

#: What a tool limit needs of ``path.robot``.
KINEMATICS = ('fk', 'jacobian12', 'hessian12')


class ToolKinematics(Protocol):
    """The robot's kinematics as the tool rows read them (:class:`~..core.kinematics.Chain`)."""

    def fk(self, q: np.ndarray) -> np.ndarray:
        """Base->tool transforms (..., 4, 4) at joint positions (..., dof)."""

    def jacobian12(self, q: np.ndarray) -> np.ndarray:
        """Jacobian of f = (p, n, o, a), (..., 12, dof)."""

    def hessian12(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Second directional derivative of f along v, (..., 12)."""


def check_tool_limit(value: object, what: str) -> float | None:
    """None, or ``value`` as a positive finite float; LimitError naming ``what`` otherwise."""
    if value is None:
        return None
    unit = 'rad/s' if 'angular' in what else 'm/s'
    if isinstance(value, bool):
        raise LimitError(f'{what} must be a number ({unit}), got {value!r}')
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as err:
        raise LimitError(f'{what} must be a number ({unit}), got {value!r}') from err
    if not (math.isfinite(number) and number > 0.0):
        raise LimitError(f'{what} must be positive and finite ({unit}), got {value!r}')
    return number


def tool_kinematics(path: PathLike, what: str) -> ToolKinematics:
    """``path.robot`` if it has the kinematics a tool limit needs; LimitError naming ``what`` otherwise."""
    robot = getattr(path, 'robot', None)
    if robot is None:
        raise LimitError(f'{what} needs the robot of the path (its kinematics), and the path has none')
    missing = [name for name in KINEMATICS if not callable(getattr(robot, name, None))]
    if missing:
        raise LimitError(f"{what} needs the robot's kinematics, and the path's robot has no "
                         f"{', '.join(missing)}")
    return robot


def _omega(m9: np.ndarray, R: np.ndarray) -> np.ndarray:
    """vee of the skew part of ``M R^T``: M (N, 3, 3) with columns m9 (N, 9) = (n, o, a) parts."""
    W = m9.reshape(-1, 3, 3).transpose(0, 2, 1) @ R.transpose(0, 2, 1)
    return 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]],
                          axis=1)


def tool_twist(robot: ToolKinematics, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray | None]:
    """The tool's twist per unit s, ``V = J(q) q'``, and (if ``ddq``) its s-derivative ``V'``.

    Args:
        robot: the kinematics.
        q, dq, ddq: q(s), q'(s), q''(s), each (N, dof); rad (m) and per unit s.
    Returns:
        (V, V'): each (N, 6), base frame, rows [v; ω] (v of the tool frame origin); m and rad per
        unit s (per unit s^2); V' is None without ``ddq``.
    """
    q = np.asarray(q, dtype=float)
    dq = np.asarray(dq, dtype=float)
    R = np.asarray(robot.fk(q))[:, :3, :3]
    J = np.asarray(robot.jacobian12(q))
    f1 = np.einsum('nij,nj->ni', J, dq)
    V = np.concatenate([f1[:, :3], _omega(f1[:, 3:], R)], axis=1)
    if ddq is None:
        return V, None
    f2 = np.einsum('nij,nj->ni', J, np.asarray(ddq, dtype=float)) + np.asarray(robot.hessian12(q, dq))
    return V, np.concatenate([f2[:, :3], _omega(f2[:, 3:], R)], axis=1)


def tool_speeds(V_t: np.ndarray) -> np.ndarray:
    """Linear and angular tool speed per unit s, ``|V_v|`` and ``|V_ω|``: twists (6, M) -> (2, M)."""
    sq = V_t * V_t
    return np.sqrt(np.stack([sq[:3].sum(axis=0), sq[3:].sum(axis=0)]))


@dataclass(frozen=True, eq=False)
class ToolRows:
    """The tool speed rows of a time law on one path: ``speeds(s) * sdot <= limits``.

    Attributes:
        robot: the path's kinematics.
        limits: (2,) [max_tool_speed m/s, max_tool_angular_speed rad/s]; inf where not limited.
        samples: the tool twist per unit s (rows [v; ω], base frame) and its s-derivative at the
            nodes of the path's samples (one-sided at breakpoints); third derivatives zero.
    """

    robot: ToolKinematics
    limits: np.ndarray
    samples: PathSamples

    def speed_cap(self, refine: int = 1, margin: float = 0.0) -> np.ndarray:
        """Largest sdot^2 the rows allow at each node of ``samples.refined(refine)``, (n+1,), 1/s^2.

        ``min_j (limits_j (1 - margin) / c_j)^2`` with ``c_j`` the larger one-sided tool speed per
        unit s at the node; inf where the tool does not move.
        """
        ts = self.samples.refined(refine)
        c = np.maximum(tool_speeds(ts.aL.T), tool_speeds(ts.aR.T))
        with np.errstate(divide='ignore'):
            cap = (self.limits * (1.0 - margin))[:, None] / c
        return (cap * cap).min(axis=0)

    def ratios(self, s: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """Largest tool speed / limit at path parameters ``s`` (M,) with path speeds ``sd`` (M,).

        The twist is interpolated between the nodes (cubic Hermite, exact V' as slopes).
        """
        V, _ = self.samples.interpolate_t(s)
        return self.ratios_of(V, sd)

    def ratios_of(self, V_t: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """Largest tool speed / limit for twists per unit s ``V_t`` (6, M) at path speeds ``sd`` (M,)."""
        r = tool_speeds(V_t)
        r *= np.abs(sd)
        r /= self.limits[:, None]
        return r.max(axis=0)

    def exact_ratios(self, q: np.ndarray, dq: np.ndarray, sd: np.ndarray) -> np.ndarray:
        """As :meth:`ratios`, with the exact twist at q(s), q'(s) (each (M, dof))."""
        V, _ = tool_twist(self.robot, q, dq)
        return self.ratios_of(V.T, sd)


def tool_rows(path: PathLike, limits: JointLimits, ps: PathSamples) -> ToolRows | None:
    """The tool rows of ``limits`` on ``path``, sampled at the nodes of ``ps``; None if unlimited.

    Evaluates q at the nodes once more (``order=0``) and the robot's kinematics there.
    """
    if limits.max_tool_speed is None and limits.max_tool_angular_speed is None:
        return None
    robot = tool_kinematics(path, 'max_tool_speed' if limits.max_tool_speed is not None
                            else 'max_tool_angular_speed')
    lim = np.array([math.inf if v is None else float(v)
                    for v in (limits.max_tool_speed, limits.max_tool_angular_speed)])
    q = np.asarray(path.evaluate(ps.s, order=0)[0], dtype=float)
    VR, dVR = tool_twist(robot, q, ps.aR, ps.bR)
    assert dVR is not None
    VL, dVL = VR.copy(), dVR.copy()
    sided = np.flatnonzero((ps.aL != ps.aR).any(axis=1) | (ps.bL != ps.bR).any(axis=1))
    if sided.size:
        VL[sided], dVL_s = tool_twist(robot, q[sided], ps.aL[sided], ps.bL[sided])
        assert dVL_s is not None
        dVL[sided] = dVL_s
    zeros = np.zeros_like(VR)
    return ToolRows(robot, lim, PathSamples(ps.s, VL, VR, dVL, dVR, zeros, zeros, ps.stop))


__all__ = ['KINEMATICS', 'ToolKinematics', 'ToolRows', 'check_tool_limit', 'tool_kinematics', 'tool_rows',
           'tool_speeds', 'tool_twist']
