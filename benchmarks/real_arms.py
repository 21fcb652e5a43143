#!/usr/bin/env python3
"""Real arms: random moves on manufacturers' URDFs, checked by an independent library (issue 21).

Run:  .venv/bin/python benchmarks/real_arms.py [--moves 36] [--arms ur5e,panda] [--markdown FILE]

For every arm of the corpus (test/data/real_arms, read by our URDF reader), ``--moves`` random
moves as in test/core/test_real_arm_moves.py (start random within limits, goal = tool pose of
a configuration up to 0.3 rad away on every joint). Each move is planned with the default
planner, and its tool path checked with pinocchio's FK at 101 points against the line + slerp.
Each move is also judged followable or not by the independent continuation of the test
(pinocchio, 1000 Newton steps along the line). The table gives per arm: DOF, moves, followable
moves, moves planned, refusals by reason, followable moves refused (the target is 0), the worst
line and slerp errors of the plans, and the median plan time (ms, wall clock, shared machine).
Nothing is asserted.
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / 'test'), str(ROOT / 'test' / 'core')]

import pin_oracle as P  # noqa: E402  (test tooling, after the path set-up)
from test_real_arm_moves import followable, random_move  # noqa: E402
from test_real_arms import ARMS, arm  # noqa: E402

from geodesic_planner import GeodesicPlanner  # noqa: E402
from geodesic_planner.core.errors import GeodesicPlannerError  # noqa: E402

from run import machine  # noqa: E402  (benchmarks/ is the script's directory)


def reason(err: GeodesicPlannerError) -> str:
    """A short name of a refusal's cause."""
    text = str(err)
    for key, words in (('singularity on the line', 'passes through a singularity'),
                       ('joint limit on the line', 'would pass its limit'),
                       ('line out of reach', 'cannot be followed by robot'),
                       ('singular end', 'is singular for robot'),
                       ('long way round', 'long way'),
                       ('path leaves the limits', 'leaves the joint limits')):
        if words in text:
            return key
    return type(err).__name__


def run_arm(key: str, moves: int) -> dict[str, object]:
    _, base, tip, _ = ARMS[key]
    _, robot, m = arm(key)
    kin = P.Kinematics(m, robot.joint_names, base, tip)
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(1000 + sum(map(ord, key)))
    s = np.linspace(0.0, 1.0, 101)
    out: dict[str, object] = {'dof': robot.dof, 'followable': 0, 'planned': 0, 'bad_refusals': 0,
                              'line': 0.0, 'slerp': 0.0, 'times': [], 'reasons': Counter(),
                              'methods': Counter()}
    for _ in range(moves):
        q_a, q_b = random_move(robot, rng)
        T_a, T_b = kin.pose_and_jacobian(q_a)[0], kin.pose_and_jacobian(q_b)[0]
        ok = followable(robot, kin, q_a, T_b)
        out['followable'] += ok  # type: ignore[operator]
        t0 = time.perf_counter()
        try:
            path = planner.plan(None, T_b, start_joints=q_a)
        except GeodesicPlannerError as err:
            out['reasons'][reason(err)] += 1  # type: ignore[index]
            out['bad_refusals'] += ok  # type: ignore[operator]
            continue
        out['times'].append((time.perf_counter() - t0) * 1e3)  # type: ignore[attr-defined]
        out['planned'] += 1  # type: ignore[operator]
        out['methods'][path.solver.method] += 1  # type: ignore[index]
        dp, dr = P.line_errors(m, robot.joint_names, base, tip, path.evaluate(s, order=0)[0], s, T_a, T_b)
        out['line'] = max(out['line'], dp)  # type: ignore[call-overload]
        out['slerp'] = max(out['slerp'], dr)  # type: ignore[call-overload]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--moves', type=int, default=36)
    ap.add_argument('--arms', default=','.join(ARMS), help='comma-separated keys of test_real_arms.ARMS')
    args = ap.parse_args()
    print(f'Machine: {machine()}\n')
    head = ('| arm | DOF | moves | followable | planned (method) | refused: reasons | followable refused | '
            'worst line error (m) | worst slerp error (rad) | median plan (ms) |')
    print(head)
    print('|' + '---|' * (head.count('|') - 1))
    total = Counter()
    for key in args.arms.split(','):
        r = run_arm(key, args.moves)
        reasons = ', '.join(f'{n} {k}' for k, n in r['reasons'].most_common()) or '-'  # type: ignore[attr-defined]
        methods = ', '.join(f'{n} {k}' for k, n in r['methods'].most_common())  # type: ignore[attr-defined]
        times = r['times']
        print(f"| {key} | {r['dof']} | {args.moves} | {r['followable']} | {r['planned']} ({methods}) | "
              f"{args.moves - r['planned']}: {reasons} | {r['bad_refusals']} | {r['line']:.1e} | "  # type: ignore[operator]
              f"{r['slerp']:.1e} | {np.median(times) if times else float('nan'):.1f} |")
        total.update(moves=args.moves, followable=r['followable'], planned=r['planned'],
                     bad=r['bad_refusals'])
    print(f"\nTotal: {total['moves']} moves, {total['followable']} followable, {total['planned']} planned, "
          f"{total['bad']} followable moves refused.")


if __name__ == '__main__':
    main()
