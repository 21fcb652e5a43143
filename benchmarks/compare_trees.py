#!/usr/bin/env python3
"""Before / after: the calls of speed.py timed on two source trees, in alternating rounds.

Run:  .venv/bin/python benchmarks/compare_trees.py BEFORE_TREE AFTER_TREE [--rounds 3]

A tree is a checkout of the repository (``git worktree add /tmp/before <commit>``). Each round
starts one child process per tree (PYTHONPATH = the tree, the same venv), one after the other, so
both see the same machine load; each child times the plans, ``timed()`` and ``timed(max_jerk)`` of
the ur5e, paper 3R and panda cases and the blended ur5e sequence under a jerk limit (the rows of
speed.py, measured as it does: once per request on requests never planned before; medians of
8-15). Prints the median over the rounds per call and
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
import json
from speed import (BLEND_JERK, BLEND_RADIUS, JERK_FACTOR, VARIANT_STEP, fresh_plans, measure_fresh, moved,
                   plan_cases, smooth_peak_jerk)
from blends import sequences
try:
    from geodesic_planner.core.compiled import REASON
except ImportError:          # a tree from before the compiled kernels
    REASON = 'none in this tree'

out = {'kernels': REASON}
for case in plan_cases():
    jmax = JERK_FACTOR * smooth_peak_jerk(case.plan())
    timing, paths = fresh_plans(case.variant, 16)
    out[f'{case.name} | plan'] = timing.median_ms
    out[f'{case.name} | timed()'] = measure_fresh(paths, lambda p: p.timed()).median_ms
    _, paths = fresh_plans(case.variant, 11, step=-1)
    out[f'{case.name} | timed(max_jerk)'] = measure_fresh(paths, lambda p: p.timed(max_jerk=jmax)).median_ms
name, planner, poses, q0 = sequences()[0]

def plan_seq(i):
    goal = moved(poses[-1], [VARIANT_STEP * i, 0.0, 0.0], [0.0, 0.0, 0.0])
    return planner.plan_through(poses[:-1] + [goal], start_joints=q0, blend_radius=BLEND_RADIUS)

_, paths = fresh_plans(plan_seq, 9)
out[f'{name}, r = {BLEND_RADIUS:g} m | blended timed(max_jerk {BLEND_JERK:g})'] = measure_fresh(
    paths, lambda p: p.timed(max_jerk=BLEND_JERK)).median_ms
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
