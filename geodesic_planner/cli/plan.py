"""``geodesic-plan REQUEST.yaml [--samples N] [-o FILE.json] [--method auto|collocation]
[--sample-period DT] [--scene SCENE.yaml [--no-ptp-around] [--ptp-planning-timeout T]]``: plan a
geodesic from a YAML request, time it, and check it against a collision scene as the planner node
does (a sequence's blocked PTP items go around the obstacles unless ``--no-ptp-around``).

Every size a user gives is bounded as the nodes bound it: ``--samples`` and the timed trajectory's
points by :data:`~geodesic_planner.timing.resample.MAX_POINTS` (the planner node's cap on one
trajectory, with its message), the request's via poses and sequence items by
:data:`~geodesic_planner.core.request.MAX_VIA_POSES` and :data:`~geodesic_planner.core.request.MAX_ITEMS`,
the request and scene files by :data:`~geodesic_planner.io.requests.MAX_YAML_BYTES`.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import GeodesicPlannerError, RequestError, quoted
from ..core.path import JointPath
from ..core.planner import check_method
from ..core.transforms import matrix_to_quat
from ..timing.resample import MAX_POINTS, sample_count

if TYPE_CHECKING:
    from ..core.collision import CollisionModel, MotionClearance
    from ..core.request import PlanRequest
    from ..timing.trajectory import Trajectory

#: Time between the written trajectory's points, s (the nodes' ``sample_period`` default).
DEFAULT_SAMPLE_PERIOD = 0.01


def path_to_dict(path: JointPath, samples: int) -> dict[str, object]:
    """JSON-friendly samples of a path: joints and their s-derivatives, tool poses, solver block."""
    s = np.linspace(0.0, 1.0, samples)
    q, dq, ddq, dddq = path.evaluate(s)
    T = path.robot.fk(q)
    solver = path.solver.as_dict() if hasattr(path, 'solver') else {}
    out: dict[str, object] = {
        'robot': path.robot.name,
        'joint_names': path.joint_names,
        's': s.tolist(),
        'positions': q.tolist(),
        'velocities': dq.tolist(),
        'accelerations': ddq.tolist(),
        'jerks': dddq.tolist(),
        'ee_positions': T[:, :3, 3].tolist(),
        'ee_orientations': matrix_to_quat(T[:, :3, :3]).tolist(),
        'solver': solver,
        'length': float(getattr(path, 'length', float('nan'))),
    }
    notes = getattr(path, 'notes', None)
    if notes:                  # a sequence: what was planned otherwise than asked
        out['notes'] = list(notes)
    zones = getattr(path, 'zones', None)
    if zones is not None:      # a blended via sequence: what each blend did to the tool
        out['blend_zones'] = [dataclasses.asdict(z) for z in zones]
    for end in ('ik_start', 'ik_goal'):
        ik = getattr(path, end, None)
        if ik is not None:
            out[end] = {'q': ik.q.tolist(), 'residual': ik.residual, 'position_error': ik.position_error,
                        'orientation_error': ik.orientation_error, 'iterations': ik.iterations}
    return out


def check_point_count(duration: float, sample_period: float) -> None:
    """Refuse a trajectory of more than :data:`MAX_POINTS` points, as the planner node does, before
    anything is sampled.

    Raises:
        RequestError: the node's message, with the option to change.
    """
    points = sample_count(duration, sample_period)
    if points > MAX_POINTS:
        raise RequestError(
            f'the trajectory would have {points:.0f} points ({duration:.3g} s every {sample_period:g} s), '
            f'more than {MAX_POINTS}: increase --sample-period')


def trajectory_to_dict(trajectory: Trajectory, sample_period: float) -> dict[str, object]:
    """The timed trajectory as the node publishes it: points every ``sample_period`` s (the last at
    the duration), positions, velocities and accelerations, checked by the one validator.

    Raises:
        RequestError: more than :data:`MAX_POINTS` points; TrajectoryError: samples the
            controller would refuse.
    """
    duration = float(trajectory.duration)
    check_point_count(duration, sample_period)
    t, q, dq, ddq = trajectory.sample(sample_period, check=True)
    return {'sample_period': sample_period, 'duration': duration, 'times': t.tolist(),
            'positions': q.tolist(), 'velocities': dq.tolist(), 'accelerations': ddq.tolist(),
            'max_velocity': np.asarray(trajectory.max_velocity, dtype=float).tolist(),
            'max_acceleration': np.asarray(trajectory.max_acceleration, dtype=float).tolist()}


def plan_in_scene(req: PlanRequest, model: CollisionModel | None
                  ) -> tuple[Any, Trajectory, MotionClearance | None, str]:
    """Plan and time the request; with a collision model, check the motion as the planner node
    does (another IK branch of a start pose where the default one collides) and bound its
    clearance over the whole motion.

    Returns:
        (path, trajectory, clearance or None, branch: 'default', 'k of n', or '' for a start
        given by joints or without a model).
    Raises:
        GeodesicPlannerError: the plan fails or every branch collides (CollisionError, its reason).
    """
    planner = req.planner()

    def attempt(q_start: np.ndarray | None) -> tuple[Any, Trajectory]:
        r = req if q_start is None else dataclasses.replace(req, start=None, start_joints=q_start)
        path = r.plan(planner)
        return path, path.timed()

    if model is None:
        path, trajectory = attempt(None)
        return path, trajectory, None, ''
    from ..core.branches import first_clear, start_branches
    T_start = req.start
    pose_start = T_start is not None and req.start_joints is None

    def branches(first: JointPath) -> list[np.ndarray]:
        assert T_start is not None
        return start_branches(planner, T_start, first.q_start, req.tolerance)

    path, trajectory, found, branch = first_clear(attempt, model, branches if pose_start else None)
    return path, trajectory, found, branch if pose_start else ''


def scene_model(req: PlanRequest, scene: str) -> CollisionModel:
    """The collision model of the request's robot (its URDF's geometry, else capsules) in the scene
    of a YAML file, with the nodes' default padding and link radius.

    Raises:
        GeodesicPlannerError: a file that cannot be read, a bad scene.
    """
    from ..core.collision import DEFAULT_LINK_RADIUS, DEFAULT_PADDING
    from ..core.robots import urdf_text
    from ..io.collision_setup import collision_model
    urdf = urdf_text(req.robot_source) if req.robot_source else None
    return collision_model(req.robot, urdf, padding=DEFAULT_PADDING, link_radius=DEFAULT_LINK_RADIUS,
                           scene=scene)


def check_output(path: str) -> None:
    """Refuse an output path that cannot be written, before any planning.

    Raises:
        RequestError: a directory, a missing or non-directory parent, no write permission.
    """
    shown = quoted(path)
    if os.path.isdir(path):
        raise RequestError(f'cannot write {shown}: it is a directory')
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        why = 'not a directory' if os.path.exists(parent) else 'no such directory'
        raise RequestError(f'cannot write {shown}: {quoted(parent)}: {why}')
    if not os.access(path if os.path.exists(path) else parent, os.W_OK):
        raise RequestError(f'cannot write {shown}: permission denied')


class _ArgError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    """Argument errors as one ``ERROR:`` line (exit 2), not argparse's usage and exit."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise _ArgError(message)


def _period(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number of seconds, got {text!r}') from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f'must be finite and > 0 s, got {text!r}')
    return value


def _parser() -> _Parser:
    parser = _Parser(
        prog='geodesic-plan', description='Plan a geodesic joint path between two poses (Chen, Li & Tang 2016), '
                                          'time it, and optionally check it against a collision scene.')
    parser.add_argument('request', help='YAML request (robot, start/goal poses or joints)')
    parser.add_argument('--samples', type=int, default=101,
                        help=f'samples of s in [0, 1], 2 to {MAX_POINTS} (default 101)')
    parser.add_argument('-o', '--output', help='write the JSON here (default: stdout)')
    parser.add_argument('--method', help="'auto' (default: the request's, else the pull-back where it "
                        "applies) or 'collocation' (the paper's route: IK only at the two ends)")
    parser.add_argument('--sample-period', type=_period, default=DEFAULT_SAMPLE_PERIOD,
                        help=f'time between the timed trajectory\'s points, s (default {DEFAULT_SAMPLE_PERIOD:g}, '
                             f'as the nodes); at most {MAX_POINTS} points')
    parser.add_argument('--scene', help='collision scene YAML (as the node\'s scene parameter): refuse a motion '
                                        'that collides, else report its min_clearance; a sequence\'s blocked PTP '
                                        'items go around the obstacles')
    parser.add_argument('--no-ptp-around', action='store_true',
                        help='with --scene: refuse a blocked PTP item instead of planning around the obstacles')
    parser.add_argument('--ptp-planning-timeout', type=_period, default=1.0,
                        help='with --scene: the search\'s budget around obstacles per PTP item, s (default 1)')
    return parser


def plan_main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``geodesic-plan``; returns the exit code (0 ok, 1 error, 2 bad arguments).
    ``geodesic-plan batch ...`` is :func:`geodesic_planner.cli.batch.main`."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ['batch']:
        from .batch import main as batch_main
        return batch_main(argv[1:])
    from ..io.requests import load_request
    try:
        args = _parser().parse_args(argv)
    except _ArgError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 2
    if args.samples < 2:
        print('ERROR: --samples must be at least 2', file=sys.stderr)
        return 2
    if args.samples > MAX_POINTS:
        print(f'ERROR: --samples: {args.samples} points, more than {MAX_POINTS}', file=sys.stderr)
        return 2
    try:
        if args.output:
            check_output(args.output)
        req = load_request(args.request)
        if args.method is not None:
            req.method = check_method(args.method)
        model = scene_model(req, args.scene) if args.scene else None
        if model is not None and not args.no_ptp_around:
            from ..core.around import AroundOptions
            req.around = AroundOptions(model, args.ptp_planning_timeout)
        path, trajectory, found, branch = plan_in_scene(req, model)
        data = path_to_dict(path, args.samples)
        data['trajectory'] = trajectory_to_dict(trajectory, args.sample_period)
        summary = ''
        if found is not None:
            clearance = found.min_clearance if math.isfinite(found.min_clearance) else None  # None: nothing checked
            data['collision'] = {'scene': args.scene, 'min_clearance': clearance,
                                 'pair': list(found.pair), 'time': found.time, 'fraction': found.fraction,
                                 'padding': model.padding if model is not None else math.nan,
                                 'branch': branch}
            summary = f', min_clearance {found.min_clearance:.4g} m ({found.pair[0]} - {found.pair[1]})'
        if args.output:
            _write(args.output, data)
            sol = path.solver
            print(f'{req.robot.name}: {sol.method}, {sol.iterations} iterations, {sol.mesh_size} nodes, max residual '
                  f'{sol.max_residual:.2g}, {sol.time_ms:.1f} ms, {trajectory.duration:.3f} s{summary} '
                  f'-> {args.output}', file=sys.stderr)
        else:
            json.dump(data, sys.stdout, indent=1)
            sys.stdout.write('\n')
    except (GeodesicPlannerError, OSError) as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    return 0


def _write(path: str, data: dict[str, object]) -> None:
    """Write the JSON (streamed, not built as one string).

    Raises:
        RequestError: the file cannot be written (the reason).
    """
    try:
        with open(path, 'w', encoding='utf-8') as fh:
            json.dump(data, fh, indent=1)
            fh.write('\n')
    except OSError as err:
        raise RequestError(f'cannot write {quoted(path)}: {err.strerror or err}') from err


if __name__ == '__main__':
    sys.exit(plan_main())
