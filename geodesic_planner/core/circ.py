"""CIRC: the tool on a circular arc, its orientation on the slerp at the same s (docs/maths.md,
"Arcs").

The arc is a geodesic of a metric suited to it: in cylindrical coordinates (rho, theta, z) about
the circle's axis, the flat metric ``d rho^2 + d theta^2 + d z^2`` (times SO(3) with the paper's
weights, whose geodesics are the slerp). Between two points at the same rho and z its geodesic
keeps rho and z and turns theta at a constant rate: the arc, at constant tool speed. As LIN's
line, it is pulled back to joint space at the nodes of a mesh in s (IK on the branch followed from
the start; q' and q'' from the task's velocity and acceleration through the Jacobian), with a
quintic Hermite spline between the nodes; the mesh is refined until the spline's tool stays within
:data:`ARC_TOLERANCE` of the arc.

Refusals (:class:`~.errors.RequestError`): start, interim and goal collinear (no circle through
them); start and goal at radii from the centre differing by more than :data:`RADIUS_TOLERANCE`;
start and goal at the same place (a full circle); a centre with start and goal on opposite sides
(the plane of the shorter arc is undefined). :class:`~.errors.PathFollowError` where the arm
cannot follow the arc (a singularity, a joint limit, a branch switch), with the fraction.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .errors import IKError, PathFollowError, RequestError
from .ik import gauss_newton_batch
from .kinematics import Chain
from .path import JointPath, check_order, check_s
from .polynomials import QuinticHermite
from .transforms import so3_exp, so3_log

__all__ = ['ARC_TOLERANCE', 'RADIUS_TOLERANCE', 'Arc', 'ArcPath', 'arc_about', 'arc_through', 'plan_arc']

#: The tool stays this close to the arc (position, m) and the slerp (orientation, rad).
ARC_TOLERANCE = 1e-8
#: With a centre, start and goal must be at radii within this of each other, m.
RADIUS_TOLERANCE = 1e-4
#: Three points are collinear (no circle) when twice the triangle's area is below this times the
#: product of two of its sides (the sine of the angle at the start).
COLLINEAR_SINE = 1e-9
#: Start and goal closer than this are the same place (a full circle), m.
SAME_POINT = 1e-9
#: Largest arc swept between two mesh nodes at first, rad; the mesh is refined where needed.
NODE_ANGLE = math.pi / 16
#: Mesh refinement rounds and largest number of nodes.
MAX_ROUNDS = 12
MAX_NODES = 4000
#: IK residual (weighted embedding) at a node that counts as on the arc.
NODE_RESIDUAL = 1e-12


@dataclass(frozen=True)
class Arc:
    """A circular arc in the base frame: ``p(s) = centre + radius (cos(angle s) u + sin(angle s) w)``.

    Attributes:
        centre: (3,), m. radius: m. u: unit vector from the centre to the start. w: unit vector
        in the circle's plane, perpendicular to u, in the direction of motion. angle: swept
        angle, rad, in (0, 2 pi).
    """

    centre: np.ndarray
    radius: float
    u: np.ndarray
    w: np.ndarray
    angle: float

    @property
    def normal(self) -> np.ndarray:
        """The axis (3,) about which the arc turns positively."""
        return np.cross(self.u, self.w)

    def derivatives(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """p, p', p'' (each (N, 3), m) at s (N,), derivatives w.r.t. s."""
        th = self.angle * np.asarray(s, dtype=float)[:, None]
        c, sn = np.cos(th), np.sin(th)
        r, a = self.radius, self.angle
        p = self.centre + r * (c * self.u + sn * self.w)
        dp = r * a * (-sn * self.u + c * self.w)
        ddp = -r * a * a * (c * self.u + sn * self.w)
        return p, dp, ddp

    def distance(self, points: np.ndarray) -> np.ndarray:
        """Distance (m) of points (N, 3) from the circle (not only the arc)."""
        rel = np.asarray(points, dtype=float) - self.centre
        n = self.normal
        z = rel @ n
        rho = np.linalg.norm(rel - z[:, None] * n, axis=1)
        return np.hypot(rho - self.radius, z)


def _arc(centre: np.ndarray, p_a: np.ndarray, axis: np.ndarray, angle: float) -> Arc:
    r = float(np.linalg.norm(p_a - centre))
    u = (p_a - centre) / r
    w = np.cross(axis, u)
    return Arc(centre, r, u, w / np.linalg.norm(w), float(angle))


def _check_ends(p_a: np.ndarray, p_b: np.ndarray) -> None:
    if np.linalg.norm(p_b - p_a) <= SAME_POINT:
        raise RequestError('CIRC: start and goal are at the same place: the arc would be a full circle '
                           '(give a goal elsewhere on the circle)')


def arc_through(p_a: np.ndarray, p_i: np.ndarray, p_b: np.ndarray) -> Arc:
    """The arc from p_a through the interim point p_i to p_b (each (3,), m): its centre is the
    circumcentre of the three points; the arc may exceed 180 degrees.

    Raises:
        RequestError: start and goal at the same place; the three points collinear.
    """
    p_a, p_i, p_b = (np.asarray(p, dtype=float).reshape(3) for p in (p_a, p_i, p_b))
    _check_ends(p_a, p_b)
    d1, d2 = p_i - p_a, p_b - p_a
    n = np.cross(d1, d2)
    if np.linalg.norm(n) <= COLLINEAR_SINE * np.linalg.norm(d1) * np.linalg.norm(d2) or min(
            np.linalg.norm(d1), np.linalg.norm(p_b - p_i)) <= SAME_POINT:
        raise RequestError('CIRC: start, interim and goal are collinear (or two of them coincide): '
                           'no circle passes through them')
    # (c - a) . d1 = |d1|^2 / 2, (c - a) . d2 = |d2|^2 / 2, (c - a) . n = 0
    centre = p_a + np.linalg.solve(np.stack([d1, d2, n]), np.array([d1 @ d1 / 2, d2 @ d2 / 2, 0.0]))
    axis = n / np.linalg.norm(n)
    u, v = p_a - centre, np.cross(axis, p_a - centre)

    def theta(p: np.ndarray) -> float:
        rel = p - centre
        return math.atan2(float(rel @ v), float(rel @ u)) % (2.0 * math.pi)
    # n = d1 x d2 turns from the start towards the interim point first: theta(i) < theta(b)
    return _arc(centre, p_a, axis, theta(p_b))


def arc_about(p_a: np.ndarray, centre: np.ndarray, p_b: np.ndarray) -> Arc:
    """The shorter arc from p_a to p_b about ``centre`` (each (3,), m).

    The radii |p_a - centre| and |p_b - centre| must agree within :data:`RADIUS_TOLERANCE`; the
    centre is then moved onto the bisecting plane of start and goal (by at most about half their
    difference, for goals not much closer to the start than the radius), so that the arc meets
    both exactly.

    Raises:
        RequestError: start and goal at the same place; radii differing by more than the
            tolerance; start and goal opposite about the centre (the plane is undefined).
    """
    p_a, centre, p_b = (np.asarray(p, dtype=float).reshape(3) for p in (p_a, centre, p_b))
    _check_ends(p_a, p_b)
    r_a, r_b = float(np.linalg.norm(p_a - centre)), float(np.linalg.norm(p_b - centre))
    if abs(r_a - r_b) > RADIUS_TOLERANCE:
        raise RequestError(f'CIRC: start and goal are at different distances from the centre '
                           f'({r_a:.6g} m and {r_b:.6g} m; they must agree within {RADIUS_TOLERANCE:g} m)')
    if min(r_a, r_b) <= SAME_POINT:
        raise RequestError('CIRC: the centre is at the start or the goal (radius 0)')
    e = (p_b - p_a) / np.linalg.norm(p_b - p_a)
    centre = centre - ((centre - 0.5 * (p_a + p_b)) @ e) * e
    n = np.cross(p_a - centre, p_b - centre)
    if np.linalg.norm(n) <= COLLINEAR_SINE * r_a * r_b:
        raise RequestError('CIRC: start and goal are opposite about the centre: the plane of the arc '
                           'is undefined (give an interim point instead)')
    axis = n / np.linalg.norm(n)
    cos_t = float((p_a - centre) @ (p_b - centre)) / float(np.linalg.norm(p_a - centre) ** 2)
    return _arc(centre, p_a, axis, math.acos(max(-1.0, min(1.0, cos_t))))


class ArcPath(JointPath):
    """The joint path of a CIRC motion: the arc and the slerp pulled back (see the module's doc).

    Attributes:
        robot, arc: the model and the arc. R_a: the start orientation (3, 3); w_body: the slerp's
        rotation vector (start frame, rad). s_nodes, q_nodes, v_nodes, a_nodes: the mesh.
    """

    def __init__(self, robot: Chain, arc: Arc, R_a: np.ndarray, w_body: np.ndarray, s_nodes: np.ndarray,
                 q_nodes: np.ndarray, v_nodes: np.ndarray, a_nodes: np.ndarray) -> None:
        self.robot, self.arc, self.R_a, self.w_body = robot, arc, R_a, w_body
        self.s_nodes, self.q_nodes, self.v_nodes, self.a_nodes = s_nodes, q_nodes, v_nodes, a_nodes
        self._spline = QuinticHermite(s_nodes, q_nodes, v_nodes, a_nodes)

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q and its first three s-derivatives (the spline's) at s; each (len(s), dof)."""
        return tuple(self._spline(check_s(s), order=check_order(order)))

    def targets(self, s: np.ndarray) -> np.ndarray:
        """The task poses (N, 4, 4) on the arc and the slerp at s."""
        return _targets(self.arc, self.R_a, self.w_body, np.asarray(s, dtype=float))

    def deviation(self, s: np.ndarray) -> np.ndarray:
        """Distance (m) of the tool from the arc's point at the same s (N,)."""
        s = check_s(s)
        return np.linalg.norm(self.ee_poses(s)[:, :3, 3] - self.arc.derivatives(s)[0], axis=1)

    def arc_deviation(self, samples: int = 2001) -> float:
        """Largest distance (m) of the tool from the arc's point at the same s, on ``samples``
        uniform values of s."""
        s = np.linspace(0.0, 1.0, int(samples))
        return float(np.linalg.norm(self.ee_poses(s)[:, :3, 3] - self.arc.derivatives(s)[0], axis=1).max())


def _targets(arc: Arc, R_a: np.ndarray, w_body: np.ndarray, s: np.ndarray) -> np.ndarray:
    T = np.zeros((s.size, 4, 4))
    T[:, :3, :3] = R_a @ so3_exp(s[:, None] * w_body)
    T[:, :3, 3] = arc.derivatives(s)[0]
    T[:, 3, 3] = 1.0
    return T


def _rates(robot: Chain, arc: Arc, omega: np.ndarray, s: np.ndarray, q: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, float]:
    """q' and q'' (N, dof) at nodes s (N,) with joints q (N, dof): least squares of
    ``J q' = (p', omega)`` and ``J q'' = (p'', 0) - Jdot q'``; and the largest residual (m)."""
    _, dp, ddp = arc.derivatives(s)
    J = robot.jacobian(q)
    twist = np.concatenate([dp, np.broadcast_to(omega, dp.shape)], axis=1)
    dq = np.stack([np.linalg.lstsq(Jk, tk, rcond=None)[0] for Jk, tk in zip(J, twist)])
    h = 1e-6 / np.maximum(np.abs(dq).max(axis=1, keepdims=True), 1e-12)
    Jd = (robot.jacobian(q + h * dq) - robot.jacobian(q - h * dq)) / (2.0 * h[:, :, None])
    acc = np.concatenate([ddp, np.zeros_like(ddp)], axis=1) - np.einsum('nij,nj->ni', Jd, dq)
    ddq = np.stack([np.linalg.lstsq(Jk, ak, rcond=None)[0] for Jk, ak in zip(J, acc)])
    residual = float(np.abs(np.einsum('nij,nj->ni', J, dq) - twist).max())
    return dq, ddq, residual


def _follow(robot: Chain, arc: Arc, R_a: np.ndarray, w_body: np.ndarray, s: np.ndarray,
            seeds: np.ndarray, weights: tuple[float, float]) -> np.ndarray:
    """Joints on the arc at s (N,), each solved from its seed; PathFollowError where not reached."""
    q, res, _, _ = gauss_newton_batch(robot, _targets(arc, R_a, w_body, s), seeds, position_weight=weights[0],
                                      orientation_weight=weights[1], max_iterations=10,
                                      residual_tol=0.1 * NODE_RESIDUAL)
    bad = np.flatnonzero(~(res < NODE_RESIDUAL) | ~robot.within_limits(q))
    if bad.size:
        k = int(bad[0])
        raise PathFollowError(f'CIRC: the arm cannot follow the arc at {100.0 * s[k]:.1f} % of the way '
                              '(a joint limit, a singularity or out of reach)', fraction=float(s[k]))
    return q


def plan_arc(robot: Chain, q_a: np.ndarray, T_b: np.ndarray, arc: Arc, *,
             weights: tuple[float, float] = (1.0, 1.0)) -> ArcPath:
    """The CIRC path from joints q_a (dof,) along ``arc`` to the goal pose T_b (4x4, base frame).

    The orientation follows the slerp from FK(q_a) to T_b; the arc must start at FK(q_a)'s
    position and end at T_b's (within ARC_TOLERANCE). Nodes are solved one after the other from
    the start (each seeded by the previous node's Taylor step), then the mesh is refined until the
    spline's tool is within ARC_TOLERANCE of the arc and the slerp at every interval's midpoint.

    Raises:
        RequestError: the arc does not start or end at the poses.
        PathFollowError: the arm cannot follow the arc (the fraction where).
    """
    q_a = robot.check_joints(q_a, 'start joints')
    T_a = robot.fk(q_a)
    for name, p, want in (('start', arc.derivatives(np.zeros(1))[0][0], T_a[:3, 3]),
                          ('goal', arc.derivatives(np.ones(1))[0][0], np.asarray(T_b)[:3, 3])):
        if np.linalg.norm(p - want) > 1e3 * ARC_TOLERANCE:
            raise RequestError(f'CIRC: the arc does not pass the {name} position (off by '
                               f'{np.linalg.norm(p - want):.3g} m)')
    R_a = T_a[:3, :3]
    w_body = so3_log(R_a.T @ np.asarray(T_b)[:3, :3])
    omega = R_a @ w_body                           # constant angular velocity, base frame
    m = max(8, math.ceil(arc.angle / NODE_ANGLE))
    s = np.linspace(0.0, 1.0, m + 1)
    q = np.empty((s.size, robot.dof))
    q[0] = q_a
    dq = np.zeros_like(q)
    ddq = np.zeros_like(q)
    dq[:1], ddq[:1], _ = _rates(robot, arc, omega, s[:1], q[:1])
    for k in range(1, s.size):                    # continuation from the start, on its branch
        checkpoint()
        h = s[k] - s[k - 1]
        seed = q[k - 1] + h * dq[k - 1] + 0.5 * h * h * ddq[k - 1]
        q[k] = _follow(robot, arc, R_a, w_body, s[k:k + 1], seed[None], weights)[0]
        dq[k:k + 1], ddq[k:k + 1], residual = _rates(robot, arc, omega, s[k:k + 1], q[k:k + 1])
        if residual > 1e-6 * max(1.0, arc.radius * arc.angle):
            raise PathFollowError(f'CIRC: the arm cannot move the tool along the arc at '
                                  f'{100.0 * s[k]:.1f} % of the way (a singularity: the tool velocity '
                                  'is not reachable)', fraction=float(s[k]))
    for _ in range(MAX_ROUNDS):
        checkpoint()
        path = ArcPath(robot, arc, R_a, w_body, s, q, dq, ddq)
        mid = 0.5 * (s[:-1] + s[1:])
        got = robot.fk(path.evaluate(mid, 0)[0])
        want = path.targets(mid)
        err = np.maximum(np.linalg.norm(got[:, :3, 3] - want[:, :3, 3], axis=1),
                         np.linalg.norm(got[:, :3, :3] - want[:, :3, :3], axis=(1, 2)))
        bad = np.flatnonzero(err > 0.1 * ARC_TOLERANCE)
        if not bad.size:
            return path
        if s.size + bad.size > MAX_NODES:
            break
        s_new = mid[bad]
        q_new = _follow(robot, arc, R_a, w_body, s_new, path.evaluate(s_new, 0)[0], weights)
        dq_new, ddq_new, _ = _rates(robot, arc, omega, s_new, q_new)
        order = np.argsort(np.concatenate([s, s_new]), kind='stable')
        s = np.concatenate([s, s_new])[order]
        q, dq, ddq = (np.concatenate([u, v])[order] for u, v in ((q, q_new), (dq, dq_new), (ddq, ddq_new)))
    raise IKError(f'CIRC: the spline between {s.size} nodes does not stay within {ARC_TOLERANCE:g} m '
                  'of the arc (the joint path is too sharp there)')
