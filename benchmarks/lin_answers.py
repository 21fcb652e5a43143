#!/usr/bin/env python3
"""LIN: every plan or refusal within 100 ms on 6 joints and 200 ms on 7 or more (issue 36, item 4).

Run:  .venv/bin/python benchmarks/lin_answers.py [--moves 30] [--passes 3] [--arms ur5e,panda]

For every arm of the real-arm corpus (test/data/real_arms), ``--moves`` random moves: half as in
test/core/test_real_arm_moves.py (goal = the tool pose of a configuration up to 0.3 rad away on
every joint), half up to 1.0 rad away (more singularities, limits and reach on the way). Each move
is answered ``--passes`` times by the default planner (a fresh call each time, the same planner);
its time is the fastest pass (the machine is shared: the fastest is the move's own cost), wall
clock and the planning thread's CPU time (on a loaded machine the wall clock includes waiting for
a core). Per arm:
the moves planned (by method) and refused (by reason), the median and the slowest answer, and the
worst distance of a planned tool path from the line + slerp (pinocchio's FK at 201 points).
The last lines compare the slowest answer on 6 joints and on 7 or more with the targets. Nothing
is asserted (test/core/test_real_arm_moves.py checks the answers themselves).
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
from test_real_arm_moves import random_move  # noqa: E402
from test_real_arms import ARMS, arm  # noqa: E402

from geodesic_planner import GeodesicPlanner  # noqa: E402
from geodesic_planner.core.errors import GeodesicPlannerError  # noqa: E402

from real_arms import reason  # noqa: E402  (benchmarks/ is the script's directory)
from run import machine  # noqa: E402

#: Targets of issue 36 item 4: the slowest answer, ms.
TARGET_MS = {6: 100.0, 7: 200.0}


def answer(planner: GeodesicPlanner, q_a: np.ndarray, T_b: np.ndarray, passes: int
           ) -> tuple[float, float, object]:
    """(fastest of ``passes`` answers in ms: wall clock and the thread's CPU time, the path or the error)."""
    best, cpu, result = np.inf, np.inf, None
    for _ in range(passes):
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            result = planner.plan(None, T_b, start_joints=q_a)
        except GeodesicPlannerError as err:
            result = err
        best = min(best, (time.perf_counter() - t0) * 1e3)
        cpu = min(cpu, (time.thread_time() - c0) * 1e3)
    return best, cpu, result


def run_arm(key: str, moves: int, passes: int) -> dict[str, object]:
    _, base, tip, _ = ARMS[key]
    _, robot, m = arm(key)
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(3600 + sum(map(ord, key)))
    s = np.linspace(0.0, 1.0, 201)
    times: list[float] = []
    cpus: list[float] = []
    methods: Counter[str] = Counter()
    reasons: Counter[str] = Counter()
    worst_line = 0.0
    slowest = (0.0, '')
    for k in range(moves):
        q_a, q_b = random_move(robot, rng, 0.3 if k % 2 == 0 else 1.0)
        T_a, T_b = robot.fk(np.stack([q_a, q_b]))
        ms, cpu, result = answer(planner, q_a, T_b, passes)
        times.append(ms)
        cpus.append(cpu)
        if isinstance(result, GeodesicPlannerError):
            reasons[reason(result)] += 1
            what = f'refused: {reason(result)}'
        else:
            methods[result.solver.method] += 1  # type: ignore[attr-defined]
            q = result.evaluate(s, order=0)[0]  # type: ignore[attr-defined]
            dp, dr = P.line_errors(m, robot.joint_names, base, tip, q, s, T_a, T_b)
            worst_line = max(worst_line, dp, dr)
            what = f'planned: {result.solver.method}'  # type: ignore[attr-defined]
        if ms > slowest[0]:
            slowest = (ms, what)
    return {'dof': robot.dof, 'times': times, 'cpus': cpus, 'methods': methods, 'reasons': reasons,
            'line': worst_line, 'slowest': slowest}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--moves', type=int, default=30)
    ap.add_argument('--passes', type=int, default=3)
    ap.add_argument('--arms', default=','.join(ARMS), help='comma-separated keys of test_real_arms.ARMS')
    args = ap.parse_args()
    print(f'Machine: {machine()}\n')
    head = ('| arm | DOF | moves | planned (method) | refused (reason) | worst tool error (m, rad) | '
            'median answer (ms) | slowest answer (ms) | slowest CPU (ms) |')
    print(head)
    print('|' + '---|' * (head.count('|') - 1))
    slowest: dict[int, tuple[float, str]] = {}
    slowest_cpu: dict[int, float] = {}
    count: Counter[int] = Counter()
    for key in args.arms.split(','):
        r = run_arm(key, args.moves, args.passes)
        methods = ', '.join(f'{n} {k}' for k, n in r['methods'].most_common()) or '-'  # type: ignore[attr-defined]
        reasons = ', '.join(f'{n} {k}' for k, n in r['reasons'].most_common()) or '-'  # type: ignore[attr-defined]
        times = np.array(r['times'])
        ms, what = r['slowest']  # type: ignore[misc]
        print(f"| {key} | {r['dof']} | {args.moves} | {sum(r['methods'].values())} ({methods}) | "  # type: ignore[attr-defined]
              f"{sum(r['reasons'].values())} ({reasons}) | {r['line']:.1e} | {np.median(times):.1f} | "  # type: ignore[attr-defined]
              f"{ms:.1f} ({what}) | {max(r['cpus']):.1f} |")  # type: ignore[call-overload]
        group = 6 if r['dof'] == 6 else 7  # type: ignore[comparison-overlap]
        count[group] += args.moves
        if ms > slowest.get(group, (0.0, ''))[0]:
            slowest[group] = (ms, f'{key}, {what}')
        slowest_cpu[group] = max(slowest_cpu.get(group, 0.0), *r['cpus'])  # type: ignore[arg-type]
    print()
    for group, (ms, where) in sorted(slowest.items()):
        label = '6 joints' if group == 6 else '7 or more joints'
        print(f'Slowest answer, {label} ({count[group]} moves, fastest of {args.passes} passes each): '
              f'{ms:.1f} ms ({where}); target {TARGET_MS[group]:.0f} ms: ratio {ms / TARGET_MS[group]:.2f}; '
              f'slowest CPU time {slowest_cpu[group]:.1f} ms: ratio {slowest_cpu[group] / TARGET_MS[group]:.2f}')


if __name__ == '__main__':
    main()
