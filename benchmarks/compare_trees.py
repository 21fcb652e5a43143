#!/usr/bin/env python3
"""Before / after: the calls of speed.py timed on two source trees, in alternating rounds.

Run:  .venv/bin/python benchmarks/compare_trees.py BEFORE_TREE AFTER_TREE [--rounds 3]

A tree is a checkout of the repository (``git worktree add /tmp/before <commit>``). Each round
starts one child process per tree (PYTHONPATH = the tree, the same venv), one after the other, so
both see the same machine load; each child times the plans, ``timed()`` and ``timed(max_jerk)`` of
the ur5e, paper 3R and panda cases and the blended ur5e sequence under a jerk limit (the rows of
speed.py; median of 8-15 calls after a warm-up). Prints the median over the rounds per call and
tree, and before / after. A tree whose compiled kernels are not built (a fresh worktree) gets
them compiled first, as setup.py does. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import subprocess
import sys
import sysconfig

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
FLAGS = ['-O2', '-fno-math-errno', '-ffp-contract=off', '-fPIC', '-shared']

CHILD = r'''
import json, sys, time
import numpy as np
from speed import BLEND_JERK, BLEND_RADIUS, JERK_FACTOR, plan_cases, smooth_peak_jerk
from blends import sequences
try:
    from geodesic_planner.core.compiled import REASON
except ImportError:          # a tree from before the compiled kernels
    REASON = 'none in this tree'

def median_ms(fn, repeats):
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)) * 1e3

out = {'kernels': REASON}
for case in plan_cases():
    path = case.plan()
    jmax = JERK_FACTOR * smooth_peak_jerk(path)
    out[f'{case.name} | plan'] = median_ms(case.plan, 15)
    out[f'{case.name} | timed()'] = median_ms(path.timed, 15)
    out[f'{case.name} | timed(max_jerk)'] = median_ms(lambda: path.timed(max_jerk=jmax), 10)
name, planner, poses, q0 = sequences()[0]
seq = planner.plan_through(poses, start_joints=q0, blend_radius=BLEND_RADIUS)
out[f'{name}, r = {BLEND_RADIUS:g} m | blended timed(max_jerk {BLEND_JERK:g})'] = median_ms(
    lambda: seq.timed(max_jerk=BLEND_JERK), 8)
print(json.dumps(out))
'''


def build_kernels(tree: str) -> None:
    """Compile the tree's kernels next to their source when no built copy is there."""
    for main in glob.glob(os.path.join(tree, 'geodesic_planner', '**', '_kernels.c'), recursive=True):
        folder = os.path.dirname(main)
        if not glob.glob(os.path.join(folder, '_kernels*.so')):
            sources = sorted(glob.glob(os.path.join(folder, '_kernels*.c')))
            suffix = sysconfig.get_config_var('EXT_SUFFIX')
            subprocess.run(['cc', *FLAGS, f'-I{sysconfig.get_paths()["include"]}', *sources, '-o',
                            os.path.join(folder, '_kernels' + suffix)], check=True)


def run_child(tree: str) -> dict[str, float | str]:
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join([os.path.abspath(tree), HERE])}
    res = subprocess.run([sys.executable, '-c', CHILD], env=env, capture_output=True, text=True, cwd=HERE,
                         check=False)
    if res.returncode != 0:
        raise RuntimeError(f'{tree}: {res.stderr[-3000:]}')
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('before')
    ap.add_argument('after')
    ap.add_argument('--rounds', type=int, default=3)
    args = ap.parse_args(argv)
    trees = [args.before, args.after]
    for tree in trees:
        build_kernels(tree)
    runs: dict[str, list[dict[str, float | str]]] = {t: [] for t in trees}
    for _ in range(args.rounds):
        for tree in trees:
            runs[tree].append(run_child(tree))
    print(f'kernels: before {runs[trees[0]][0]["kernels"]}, after {runs[trees[1]][0]["kernels"]}; '
          f'{args.rounds} rounds; medians over the rounds, ms\n')
    print('| case | call | before | after | before / after |')
    print('|---|---|---:|---:|---:|')
    for key in runs[trees[0]][0]:
        if key == 'kernels':
            continue
        before, after = (float(np.median([float(r[key]) for r in runs[t]])) for t in trees)
        case, call = key.split(' | ')
        print(f'| {case} | {call} | {before:.2f} | {after:.2f} | {before / after:.2f} |')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
