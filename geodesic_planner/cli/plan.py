"""``geodesic-plan REQUEST.yaml [--samples N] [--output FILE.json] [--method auto|collocation]``: plan a
geodesic from a YAML request."""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence

import numpy as np

from ..core.errors import GeodesicPlannerError
from ..core.planner import check_method
from ..core.path import JointPath
from ..core.transforms import matrix_to_quat


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


def plan_main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``geodesic-plan``; returns the exit code (0 ok, 1 error)."""
    from ..io.requests import load_request
    parser = argparse.ArgumentParser(
        prog='geodesic-plan', description='Plan a geodesic joint path between two poses (Chen, Li & Tang 2016).')
    parser.add_argument('request', help='YAML request (robot, start/goal poses or joints)')
    parser.add_argument('--samples', type=int, default=101, help='samples of s in [0, 1] (default 101)')
    parser.add_argument('--output', help='write JSON here (default: stdout)')
    parser.add_argument('--method', help="'auto' (default: the request's, else the pull-back where it "
                        "applies) or 'collocation' (the paper's route: IK only at the two ends)")
    args = parser.parse_args(argv)
    if args.samples < 2:
        print('ERROR: --samples must be at least 2', file=sys.stderr)
        return 1
    try:
        req = load_request(args.request)
        if args.method is not None:
            req.method = check_method(args.method)
        path = req.plan()
        data = path_to_dict(path, args.samples)
        text = json.dumps(data, indent=1)
        if args.output:
            with open(args.output, 'w', encoding='utf-8') as fh:
                fh.write(text + '\n')
            sol = path.solver
            print(f'{req.robot.name}: {sol.method}, {sol.iterations} iterations, {sol.mesh_size} nodes, max residual '
                  f'{sol.max_residual:.2g}, {sol.time_ms:.1f} ms -> {args.output}', file=sys.stderr)
        else:
            print(text)
    except (GeodesicPlannerError, OSError) as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(plan_main())
