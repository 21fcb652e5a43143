#!/usr/bin/env python3
"""7-joint arms against the 6-joint ur5e: line and slerp errors and plan times, in one run.

Run:  .venv/bin/python benchmarks/redundant.py [--moves 12] [--repeats 9] [--markdown FILE ...]

Per arm, random moves as issue 21 drew them: a start configuration drawn within the joint limits
(10 % margin) away from singularities (smallest singular value of the geometric Jacobian >= 0.05
there), and a goal pose = forward kinematics of a nearby configuration (every joint moved by up to
0.25 rad). Each move is planned from the start joints to the goal pose:

- ``after``: ``GeodesicPlanner(robot)`` (7 joints: the least-motion path with the tool exactly on
  line + slerp, method 'redundant'; ur5e: the pull-back);
- ``before``: ``GeodesicPlanner(robot, epsilon=1e-4)``, the 7-joint default until issue 21 (the
  geodesic of ``G + εI`` by collocation); not run on ur5e, where nothing changed.

Line and slerp errors: the tool path at 2001 samples of s against line + slerp at the same s.
Plan time: each (arm, move, planner) once per round, rounds repeated, so that a change of the
machine's load touches every row alike; per arm the median over moves of each move's median.
The ratio divides by ur5e's median from the same run. Nothing here is asserted.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

from geodesic_planner import GeodesicPlanner, GeodesicPlannerError, load_robot
from geodesic_planner.core.kinematics import REVOLUTE, chain_from_dh
from geodesic_planner.core.transforms import line_slerp, pose_error
from markdown_block import replace_block

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PI = np.pi


def machine() -> str:
    cpu = platform.machine()
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as fh:
            cpu = next((line.split(':', 1)[1].strip() for line in fh if line.startswith('model name')), cpu)
    except OSError:
        pass
    return f'{cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}'


def xarm7_like():
    """UFACTORY xArm 7 from its published kinematics (xarm_description's default kinematics yaml:
    joint origins as modified DH rows (α, a, d, θ)), flange as the tool; limits of its URDF."""
    rows = [(0.0, 0.0, 0.267, 0.0), (-PI / 2, 0.0, 0.0, 0.0), (PI / 2, 0.0, 0.293, 0.0),
            (PI / 2, 0.0525, 0.0, 0.0), (PI / 2, 0.0775, 0.3425, 0.0), (PI / 2, 0.0, 0.0, 0.0),
            (-PI / 2, 0.076, 0.097, 0.0)]
    return chain_from_dh('xarm7_like', rows, [REVOLUTE] * 7, modified=True,
                         lower=[-2 * PI, -2.059, -2 * PI, -0.19198, -2 * PI, -1.69297, -2 * PI],
                         upper=[2 * PI, 2.0944, 2 * PI, 3.927, 2 * PI, PI, 2 * PI], max_velocity=PI)


def arms():
    return {
        'ur5e': load_robot('ur5e'),
        'panda': load_robot('panda'),
        'iiwa_like_7r.urdf': load_robot(os.path.join(ROOT, 'geodesic_planner', 'data', 'iiwa_like_7r.urdf')),
        'xarm7_like': xarm7_like(),
    }


def random_moves(robot, count: int, seed: int):
    """(q_a, T_a, T_b): start joints, its pose, and the pose of a configuration nearby."""
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -PI)
    hi = np.where(np.isfinite(robot.upper), robot.upper, PI)
    lo, hi = np.maximum(lo, -PI), np.minimum(hi, PI)
    margin = 0.1 * (hi - lo)
    moves = []
    while len(moves) < count:
        q_a = rng.uniform(lo + margin, hi - margin)
        q_b = np.clip(q_a + rng.uniform(-0.25, 0.25, robot.dof), lo + margin, hi - margin)
        sv = np.linalg.svd(robot.jacobian(np.stack([q_a, q_b])), compute_uv=False)[:, -1]
        if sv.min() < 0.05:
            continue
        moves.append((q_a, robot.fk(q_a), robot.fk(q_b)))
    return moves


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--moves', type=int, default=12)
    ap.add_argument('--repeats', type=int, default=9)
    ap.add_argument('--seed', type=int, default=21)
    ap.add_argument('--markdown', action='append', help='also write the table into this Markdown file '
                    '(between its markers; may be repeated)')
    args = ap.parse_args(argv)
    robots = arms()
    s = np.linspace(0.0, 1.0, 2001)
    planners = {}
    for name, robot in robots.items():
        planners[name, 'after'] = GeodesicPlanner(robot)
        if robot.dof > 6:
            planners[name, 'before'] = GeodesicPlanner(robot, epsilon=1e-4)
    moves = {name: random_moves(robot, args.moves, args.seed + k) for k, (name, robot) in enumerate(robots.items())}
    rows = {}
    ok = {}
    for (name, which), planner in planners.items():
        robot = robots[name]
        errs, methods, fails, ok[name, which] = [], set(), [], []
        for i, (q_a, T_a, T_b) in enumerate(moves[name]):
            try:
                path = planner.plan(None, T_b, start_joints=q_a)
            except GeodesicPlannerError as err:
                fails.append(f'{type(err).__name__}: {str(err)[:80]}')
                continue
            dp, dr = pose_error(robot.fk(path.evaluate(s, order=0)[0]), line_slerp(T_a, T_b, s))
            errs.append((float(dp.max()), float(dr.max())))
            methods.add(path.solver.method)
            ok[name, which].append(i)
        rows[name, which] = (errs, methods, fails)
    times = {key: {i: [] for i in ok[key]} for key in planners}
    for _ in range(max(1, args.repeats)):
        for key, planner in planners.items():
            for i in ok[key]:
                q_a, _, T_b = moves[key[0]][i]
                t0 = time.perf_counter()
                planner.plan(None, T_b, start_joints=q_a)
                times[key][i].append((time.perf_counter() - t0) * 1e3)
    med = {key: float(np.median([np.median(v) for v in t.values()])) if t else float('nan') for key, t in times.items()}
    ref = med['ur5e', 'after']
    lines = ['| arm | planner | planned | method | worst line error (m) | worst slerp error (rad) | '
             'median plan time (ms) | ratio to ur5e |', '|---|---|---|---|---|---|---|---|']
    for key in planners:
        errs, methods, fails = rows[key]
        dp = max((e[0] for e in errs), default=float('nan'))
        dr = max((e[1] for e in errs), default=float('nan'))
        label = {'after': 'default', 'before': 'epsilon=1e-4 (before)'}[key[1]]
        lines.append(f'| {key[0]} ({robots[key[0]].dof}) | {label} | {len(errs)}/{len(moves[key[0]])} | '
                     f'{", ".join(sorted(methods))} | {dp:.1e} | {dr:.1e} | {med[key]:.2f} | {med[key] / ref:.2f} |')
        for f in fails:
            print(f'  {key[0]} {label}: {f}', file=sys.stderr)
    table = '\n'.join(lines)
    head = (f'`.venv/bin/python benchmarks/redundant.py --moves {args.moves} --repeats {args.repeats}`: '
            f'{args.moves} moves per arm, {args.repeats} rounds, {machine()}.')
    print(head + '\n')
    print(table)
    if args.markdown:
        for path in args.markdown:
            replace_block(path, 'benchmarks/redundant.py', f'{head}\n\n{table}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
