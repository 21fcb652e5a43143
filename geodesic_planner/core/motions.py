"""The motion types (LIN, CIRC, PTP) and sequences of them with blends, as Pilz's
``MotionSequenceRequest`` has them.

Each item moves from where the previous one ended (the first from the start) to its goal: LIN the
paper's geodesic (tool on the line, orientation by slerp), CIRC the arc (:mod:`.circ`), PTP a
joint-space geodesic (:mod:`.ptp`: ``kinetic_energy`` with a mass model, else ``joint_line``).
Consecutive items join at their goals; ``blend_radius`` > 0 on an item replaces the corner at its
goal by a blend zone (:mod:`.blend`) within that distance of it, whatever the two items' types;
outside the zones every item keeps its exact geometry. Pilz's rules: the last item's radius is 0,
and the zones of neighbouring goals must not overlap (``r_k + r_{k+1}`` at most the distance
between goals k and k + 1). A bad item fails the whole sequence, the message naming its index.
"""
from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .circ import ArcPath, arc_about, arc_through, plan_arc
from .errors import GeodesicPlannerError, RequestError
from .geodesic import SolverReport
from .path import JointPath
from .piecewise import PiecewiseGeodesicPath
from .planner import GeodesicPlanner, snap_same
from .around import AroundOptions, around_ptp
from .branches import start_branches
from .ptp import PTP_OPTIONS, ConstantMass, JointLinePath, MassModel, kinetic_energy_path
from .transforms import check_transform

__all__ = ['MOTION_TYPES', 'MotionItem', 'plan_item', 'plan_sequence']

#: Motion types, as Pilz names them.
MOTION_TYPES = ('LIN', 'CIRC', 'PTP')
#: Samples of the metric-length quadrature of a piece that is not the paper's geodesic.
LENGTH_SAMPLES = 201


@dataclass(frozen=True)
class MotionItem:
    """One motion of a sequence.

    Attributes:
        motion: 'LIN', 'CIRC' or 'PTP'.
        goal: the goal pose, 4x4 base frame (or None with ``goal_joints``: PTP and LIN).
        goal_joints: the goal configuration (dof,), rad or m.
        interim: CIRC: a point the tool passes (3,), m, base frame; or
        centre: CIRC: the circle's centre (3,), m.
        ptp: PTP's metric: 'kinetic_energy' (needs a mass model; without one the joint line, and
            the plan says so) or 'joint_line'.
        blend_radius: m, the blend around this item's goal (0: stop there; the last item's is 0).
    """

    motion: str
    goal: np.ndarray | None = None
    goal_joints: np.ndarray | None = None
    interim: np.ndarray | None = None
    centre: np.ndarray | None = None
    ptp: str = 'kinetic_energy'
    blend_radius: float = 0.0


def _check(item: MotionItem) -> None:
    if item.motion not in MOTION_TYPES:
        raise RequestError(f'motion must be one of {", ".join(MOTION_TYPES)}, got {item.motion!r}')
    if item.goal is None and item.goal_joints is None:
        raise RequestError('give a goal pose or goal_joints')
    if item.motion == 'CIRC':
        if item.goal is None:
            raise RequestError('CIRC needs a goal pose')
        if (item.interim is None) == (item.centre is None):
            raise RequestError('CIRC needs exactly one of interim and centre')
    if item.motion == 'PTP' and item.ptp not in PTP_OPTIONS:
        raise RequestError(f'ptp must be one of {", ".join(PTP_OPTIONS)}, got {item.ptp!r}')
    r = float(item.blend_radius)
    if not (np.isfinite(r) and r >= 0.0):
        raise RequestError(f'blend_radius must be a finite number >= 0, got {item.blend_radius!r}')


def _finish(path: JointPath, planner: GeodesicPlanner, method: str, t0: float) -> JointPath:
    """Give a CIRC or PTP piece what a piecewise path needs of it: its paper-metric length, the
    metric and a solver report."""
    s = np.linspace(0.0, 1.0, LENGTH_SAMPLES)
    q, dq = path.evaluate(s, 1)
    speed = planner.metric.speed(planner.robot, q, dq)
    path.length = float(np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(s)))  # type: ignore[attr-defined]
    path.metric = planner.metric  # type: ignore[attr-defined]
    nodes = getattr(path, 's_nodes', s)
    path.solver = SolverReport(0, method, 0, 0.0, int(nodes.size),  # type: ignore[attr-defined]
                               (time.perf_counter() - t0) * 1e3, 0.0, method, 0.0)
    return path


def plan_item(planner: GeodesicPlanner, item: MotionItem, q_start: np.ndarray,
              mass: MassModel | None = None, tolerance: float | None = None,
              around: AroundOptions | None = None) -> JointPath:
    """One item's path from joints q_start (dof,); with ``around``, a PTP whose path collides goes
    around the obstacles (:func:`.around.around_ptp`; a pose goal tries its IK branches), LIN and
    CIRC never do.

    Raises:
        RequestError: an invalid item; IKError: an unreachable goal; PathFollowError: a line or
            arc the arm cannot follow (LineLimitError past a joint limit, LineUnreachableError out
            of the branch's reach); BVPError: a geodesic that does not converge.
    """
    _check(item)
    t0 = time.perf_counter()
    robot = planner.robot
    goal = None if item.goal is None else check_transform(item.goal, 'goal pose')
    if item.motion == 'LIN':
        return planner.plan(None, goal, start_joints=q_start, goal_joints=item.goal_joints, tolerance=tolerance)
    if item.motion == 'CIRC':
        assert goal is not None
        p_a = robot.fk(q_start)[:3, 3]
        arc = (arc_through(p_a, np.asarray(item.interim, dtype=float), goal[:3, 3]) if item.interim is not None
               else arc_about(p_a, np.asarray(item.centre, dtype=float), goal[:3, 3]))
        path: ArcPath | JointPath = plan_arc(robot, q_start, goal, arc, weights=(
            planner.metric.position_weight, planner.metric.effective_orientation_weight or 1.0),
            tolerance=planner.ik_tolerance if tolerance is None else tolerance)
        return _finish(path, planner, 'circ', t0)
    if item.goal_joints is not None:
        q_goal = robot.check_joints(item.goal_joints, 'goal_joints')
    else:
        assert goal is not None
        q_goal = planner._goal_ik(goal, q_start, tolerance).q
    q_goal = snap_same(q_start, q_goal)
    use_mass = item.ptp == 'kinetic_energy' and mass is not None

    def direct(q_b: np.ndarray) -> JointPath:
        if use_mass:
            assert mass is not None
            return kinetic_energy_path(robot, mass, q_start, q_b)
        return JointLinePath(robot, q_start, q_b)

    if around is None:
        path = direct(q_goal)
    else:
        terms = mass.terms if use_mass else ConstantMass(np.eye(robot.dof)).terms  # type: ignore[union-attr]
        others = None if goal is None else (lambda: start_branches(planner, goal, q_goal, tolerance))
        path = around_ptp(around, direct, terms, q_start, q_goal, others,
                          'mass' if use_mass else 'joint (Euclidean)')
    method = 'around' if getattr(path, 'note', '').startswith('PTP went around') else (
        'kinetic_energy' if use_mass else 'joint_line')
    out = _finish(path, planner, method, t0)
    if item.ptp == 'kinetic_energy' and mass is None:      # said in the plan's notes (the reply's message)
        note = 'PTP kinetic_energy: no mass model (no <inertial> masses), planned as the joint line'
        out.note = '; '.join(n for n in (getattr(out, 'note', ''), note) if n)  # type: ignore[attr-defined]
    return out


def _check_radii(items: Sequence[MotionItem], ends: np.ndarray) -> np.ndarray:
    """Pilz's rules on the radii, with the tool positions ``ends`` (n + 1, 3) at the start and
    every goal."""
    radii = np.array([float(it.blend_radius) for it in items])
    if radii[-1] != 0.0:
        raise RequestError(f'sequence item {len(items) - 1}: the last item\'s blend_radius must be 0, '
                           f'got {radii[-1]:g}')
    for k in range(len(items) - 1):
        gap = float(np.linalg.norm(ends[k + 2] - ends[k + 1]))
        before = float(np.linalg.norm(ends[k + 1] - ends[k]))
        if radii[k] > 0.0 and radii[k] + radii[k + 1] > gap:
            raise RequestError(f'sequence item {k}: blend_radius {radii[k]:g} m and the next item\'s '
                               f'{radii[k + 1]:g} m overlap (their goals are {gap:.4g} m apart)')
        if radii[k] > before:
            raise RequestError(f'sequence item {k}: blend_radius {radii[k]:g} m exceeds the item\'s own '
                               f'length {before:.4g} m')
    return radii


def plan_sequence(planner: GeodesicPlanner, items: Sequence[MotionItem], *, start: np.ndarray | None = None,
                  start_joints: object = None, tolerance: float | None = None, start_seed: object = None,
                  mass: MassModel | None = None, around: AroundOptions | None = None) -> JointPath:
    """Plan the items one after the other from the start; blend where an item has a radius.

    ``around``: PTP items whose path collides go around the obstacles (None: they are planned
    directly and a collision is found, and refused, by the caller's check).

    Returns:
        a :class:`~.piecewise.PiecewiseGeodesicPath` (rests at every goal) or, with blends, a
        :class:`~.blend.BlendedPath` (its ``zones`` report each blend); ``notes``: what was
        planned otherwise than asked (a PTP without a mass model).
    Raises:
        The first failing item's error, of its own class, the message starting with
        ``sequence item i:``; RequestError for an empty sequence or radii against Pilz's rules.
    """
    from .blend import BlendedPath

    items = list(items)
    if not items:
        raise RequestError('the sequence has no items')
    t0 = time.perf_counter()
    if start_joints is not None:
        q = planner.robot.check_joints(start_joints, 'start_joints')
    elif start is not None:
        seed = None if start_seed is None else planner.robot.check_joints(start_seed, 'start_seed')
        q = planner._ik(check_transform(start, 'start pose'), seed, tolerance).q
    else:
        raise RequestError('give a start pose or start_joints')
    pieces, ends = [], [planner.robot.fk(q)[:3, 3]]
    for i, item in enumerate(items):
        try:
            piece = plan_item(planner, item, q, mass, tolerance, around)
        except GeodesicPlannerError as err:
            err.args = (f'sequence item {i} ({item.motion}): {err.args[0] if err.args else err}',) + err.args[1:]
            err.item = i          # type: ignore[attr-defined]   # the service's failed_item
            raise
        pieces.append(piece)
        q = piece.q_goal
        ends.append(planner.robot.fk(q)[:3, 3])
    radii = _check_radii(items, np.array(ends))
    path = PiecewiseGeodesicPath(pieces, (time.perf_counter() - t0) * 1e3)  # type: ignore[arg-type]
    notes = [f'sequence item {i}: {note}' for i, p in enumerate(pieces) if (note := getattr(p, 'note', ''))]
    out: JointPath = path
    if np.any(radii[:-1] > 0.0) and len(path.pieces) >= 2:
        kept = path.kept[1:]
        out = BlendedPath(path, radii[kept - 1], via_index=kept.tolist())
    out.notes = notes  # type: ignore[attr-defined]
    return out
