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

Refusals (:class:`~.errors.RequestError`): an interim point closer than :data:`MIN_CHORD_OFFSET`
(0.1 mm) to the straight line through start and goal (the three points are nearly collinear: no
unique circle); start and goal at radii from the centre differing by more than
:data:`RADIUS_TOLERANCE`; start and goal at the same place (a full circle); a centre closer than
:data:`MIN_CHORD_OFFSET` to that line (start and goal nearly opposite about it: the plane of the
arc is undefined). Where the arm cannot follow the arc, the one reason, as a LIN gives it: a goal
pose out of reach (:class:`~.errors.IKError`, the nearest reachable distance), a joint limit on
the way (:class:`~.errors.LineLimitError`: the joint, the fraction of the arc, the tool's place), a
singularity (:class:`~.errors.PathFollowError`: the fraction, the tool's place) or the arc leaving
what the start's branch reaches (:class:`~.errors.LineUnreachableError`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .cancel import checkpoint
from .continuation import LineFollow, follow_line
from .errors import IKError, PathFollowError, RequestError
from .ik import DEFAULT_IK_TOLERANCE, IKSolution, gauss_newton_batch, solve_ik
from .kinematics import Chain
from .limits import BETWEEN, LIMIT_SLACK, line_limit_error
from .path import JointPath, check_order, check_s
from .polynomials import QuinticHermite
from .transforms import so3_exp, so3_log

__all__ = ['ARC_TOLERANCE', 'MIN_CHORD_OFFSET', 'RADIUS_TOLERANCE', 'Arc', 'ArcPath', 'arc_about', 'arc_through',
           'plan_arc']

#: The tool stays this close to the arc (position, m) and the slerp (orientation, rad).
ARC_TOLERANCE = 1e-8
#: With a centre, start and goal must be at radii within this of each other, m.
RADIUS_TOLERANCE = 1e-4
#: The interim point (or the centre) must lie at least this far from the straight line through
#: start and goal, m. Closer, the three points are (nearly) collinear and the circle is set by the
#: input's rounding: an interim point on the chord's midpoint rounded to 1e-6 m gives a radius of
#: kilometres and a plane at random (a centre: start and goal nearly opposite about it, the plane
#: of the arc undefined). Pilz bounds the same triangle by its doubled area, |(I - A) x (B - A)|
#: >= 1e-5 m^2 (1e-4 m from a 0.1 m chord); a distance states it whatever the chord's length.
MIN_CHORD_OFFSET = 1e-4
#: Start and goal closer than this are the same place (a full circle), m.
SAME_POINT = 1e-9
#: Largest arc swept between two mesh nodes at first, rad; the mesh is refined where needed.
NODE_ANGLE = math.pi / 16
#: Mesh refinement rounds and largest number of nodes.
MAX_ROUNDS = 12
MAX_NODES = 4000
#: IK residual (weighted embedding) at a node that counts as on the arc.
NODE_RESIDUAL = 1e-12
#: The arc, as the refusals name it.
ARC = 'CIRC: the arc'


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


def _chord_offset(p_a: np.ndarray, p: np.ndarray, p_b: np.ndarray) -> float:
    """Distance (m) of p from the straight line through p_a and p_b (each (3,), m; p_a != p_b)."""
    e = (p_b - p_a) / np.linalg.norm(p_b - p_a)
    return float(np.linalg.norm(np.cross(p - p_a, e)))


def arc_through(p_a: np.ndarray, p_i: np.ndarray, p_b: np.ndarray) -> Arc:
    """The arc from p_a through the interim point p_i to p_b (each (3,), m): its centre is the
    circumcentre of the three points; the arc may exceed 180 degrees.

    Raises:
        RequestError: start and goal at the same place; the interim point closer than
            :data:`MIN_CHORD_OFFSET` to the straight line through them (nearly collinear).
    """
    p_a, p_i, p_b = (np.asarray(p, dtype=float).reshape(3) for p in (p_a, p_i, p_b))
    _check_ends(p_a, p_b)
    offset = _chord_offset(p_a, p_i, p_b)
    if not offset >= MIN_CHORD_OFFSET:
        raise RequestError(f'CIRC: the interim point is {offset:.2g} m from the straight line through start '
                           f'and goal (at least {MIN_CHORD_OFFSET:g} m needed): the three points are (nearly) '
                           'collinear, no unique circle passes through them')
    d1, d2 = p_i - p_a, p_b - p_a
    n = np.cross(d1, d2)
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
            tolerance; the centre closer than :data:`MIN_CHORD_OFFSET` to the straight line
            through start and goal (they are nearly opposite about it: the plane is undefined).
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
    offset = _chord_offset(p_a, centre, p_b)
    if not offset >= MIN_CHORD_OFFSET:
        raise RequestError(f'CIRC: the centre is {offset:.2g} m from the straight line through start and '
                           f'goal (at least {MIN_CHORD_OFFSET:g} m needed): start and goal are (nearly) '
                           'opposite about it, the plane of the arc is undefined (give an interim point instead)')
    n = np.cross(p_a - centre, p_b - centre)
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
    """Joints on the arc at s (N,), each solved from its seed within the limits; PathFollowError
    where a node is not reached (:func:`plan_arc` then finds the reason by continuation)."""
    q, res, _, _ = gauss_newton_batch(robot, _targets(arc, R_a, w_body, s), seeds, position_weight=weights[0],
                                      orientation_weight=weights[1], max_iterations=10,
                                      residual_tol=0.1 * NODE_RESIDUAL)
    bad = np.flatnonzero(~(res < NODE_RESIDUAL) | ~robot.within_limits(q))
    if bad.size:
        k = int(bad[0])
        raise PathFollowError(f'{ARC}: its node at {100.0 * s[k]:.3g} % of the way is not reached from the '
                              'neighbouring nodes on the start\'s branch', fraction=float(s[k]))
    return q


def _first_mesh(robot: Chain, arc: Arc, R_a: np.ndarray, w_body: np.ndarray, q_a: np.ndarray,
                weights: tuple[float, float], guide: LineFollow | None) -> tuple[np.ndarray, ...]:
    """s, q, q', q'' at the first mesh's nodes (at most NODE_ANGLE apart, 8 intervals at least):
    solved one after the other from the start, each seeded by the previous node's Taylor step,
    or all at once from the continuation's samples ``guide``."""
    omega = R_a @ w_body                           # constant angular velocity, base frame
    m = max(8, math.ceil(arc.angle / NODE_ANGLE))
    s = np.linspace(0.0, 1.0, m + 1)
    if guide is not None:
        q = _follow(robot, arc, R_a, w_body, s, guide.seeds(s), weights)
        q[0] = q_a
        dq, ddq, _ = _rates(robot, arc, omega, s, q)
        return s, q, dq, ddq
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
            raise PathFollowError(f'{ARC}: the tool velocity is not reachable at its node at '
                                  f'{100.0 * s[k]:.3g} % of the way', fraction=float(s[k]))
    return s, q, dq, ddq


def _pull_back(robot: Chain, arc: Arc, R_a: np.ndarray, w_body: np.ndarray, q_a: np.ndarray,
               weights: tuple[float, float], guide: LineFollow | None) -> ArcPath:
    """The first mesh, refined until the spline's tool is within ARC_TOLERANCE of the arc and the
    slerp at every interval's midpoint."""
    omega = R_a @ w_body
    s, q, dq, ddq = _first_mesh(robot, arc, R_a, w_body, q_a, weights, guide)
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


def _outside_limits(robot: Chain, path: ArcPath) -> tuple[float, int, float] | None:
    """(s, joint, bound) of the first place where the path's joints leave their position limits
    (checked at the nodes and BETWEEN points between each two), or None."""
    nodes = path.s_nodes
    between = nodes[:-1, None] + np.diff(nodes)[:, None] * (np.arange(1, BETWEEN + 1) / (BETWEEN + 1))
    s = np.sort(np.concatenate([nodes, between.ravel()]))
    q = path.evaluate(s, 0)[0]
    out = (q < robot.lower - LIMIT_SLACK) | (q > robot.upper + LIMIT_SLACK)
    if not np.any(out):
        return None
    k = int(np.argmax(np.any(out, axis=1)))
    j = int(np.argmax(out[k]))
    return float(s[k]), j, float(robot.upper[j] if q[k, j] > robot.upper[j] else robot.lower[j])


def _goal_error(robot: Chain, T_b: np.ndarray, goal: IKSolution, tolerance: float | None) -> IKError:
    """The refusal of a CIRC whose goal pose no configuration reaches (``goal``: the nearest)."""
    x, y, z = T_b[:3, 3]
    where = f'CIRC: the goal pose (tool at {x:.4f}, {y:.4f}, {z:.4f} m)'
    if not robot.within_limits(goal.q, 1e-9):
        why = f'is reached by robot {robot.name!r} only outside its joint limits'
    else:
        tol = DEFAULT_IK_TOLERANCE if tolerance is None else tolerance
        why = (f'is out of reach of robot {robot.name!r}: the nearest reachable pose is '
               f'{goal.position_error:.4g} m and {goal.orientation_error:.4g} rad away (weighted distance '
               f'{goal.residual:.4g}, tolerance {tol:.3g})')
    return IKError(f'{where} {why}', residual=goal.residual, iterations=goal.iterations)


def _reason(robot: Chain, q_a: np.ndarray, T_b: np.ndarray, arc: Arc, w_body: np.ndarray,
            weights: tuple[float, float], tolerance: float | None) -> LineFollow:
    """Why the mesh failed, raised as the one reason, as a LIN gives it; or the continuation's
    samples along the whole arc (the mesh's steps jumped), to seed the mesh again.

    Raises:
        IKError: the goal pose is out of reach (checked first: the reason whatever the way).
        LineLimitError, PathFollowError, LineUnreachableError: a joint limit, a singularity, or
            the arc leaving what the start's branch reaches, where the continuation
            (:func:`~.continuation.follow_line` on the arc's poses) stops: the fraction of the
            arc and the tool's place.
    """
    goal = solve_ik(robot, T_b, q_a, position_weight=weights[0], orientation_weight=weights[1],
                    tolerance=tolerance, raise_on_failure=False)
    if not goal.success:
        raise _goal_error(robot, T_b, goal, tolerance)
    T_a = robot.fk(q_a)
    follow = follow_line(robot, q_a, T_a, np.asarray(T_b, dtype=float), w_body, position_weight=weights[0],
                         orientation_weight=weights[1], name=ARC,
                         task=lambda s: (_targets(arc, T_a[:3, :3], w_body, s), arc.derivatives(s)[1]))
    if follow.error is not None:
        raise follow.error
    return follow


def plan_arc(robot: Chain, q_a: np.ndarray, T_b: np.ndarray, arc: Arc, *,
             weights: tuple[float, float] = (1.0, 1.0), tolerance: float | None = None) -> ArcPath:
    """The CIRC path from joints q_a (dof,) along ``arc`` to the goal pose T_b (4x4, base frame).

    The orientation follows the slerp from FK(q_a) to T_b; the arc must start at FK(q_a)'s
    position and end at T_b's (within ARC_TOLERANCE). Nodes are solved one after the other from
    the start (each seeded by the previous node's Taylor step), then the mesh is refined until the
    spline's tool is within ARC_TOLERANCE of the arc and the slerp at every interval's midpoint,
    and the joints are checked against their limits. Where that fails, the goal pose's IK and the
    continuation along the arc tell why and where (or seed the mesh, where the arc is followable).

    Args:
        weights: the metric's position and orientation weights (the IK's).
        tolerance: the goal IK's tolerance for telling a goal out of reach (as a LIN's goal pose;
            default :data:`~.ik.DEFAULT_IK_TOLERANCE`).
    Raises:
        RequestError: the arc does not start or end at the poses.
        IKError: the goal pose is out of reach (the nearest reachable distance).
        LineLimitError: a joint limit on the way (the joint, the fraction of the arc, the place).
        PathFollowError: a singularity on the way; LineUnreachableError: the arc leaves what the
            start's branch reaches (each with the fraction and the tool's place).
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
    path: ArcPath | None
    try:
        path = _pull_back(robot, arc, R_a, w_body, q_a, weights, None)
        place = _outside_limits(robot, path)
        if place is None:
            return path
    except PathFollowError:
        path, place = None, None
    follow = _reason(robot, q_a, T_b, arc, w_body, weights, tolerance)
    if path is None:              # followable: the mesh's steps jumped; seeded from the samples
        path = _pull_back(robot, arc, R_a, w_body, q_a, weights, follow)
        place = _outside_limits(robot, path)
    if place is not None:         # between two continuation samples: the spline's place
        s_k, j, bound = place
        raise line_limit_error(robot, j, bound, s_k, arc.derivatives(np.array([s_k]))[0][0], ARC)
    return path
