#!/usr/bin/env python3
"""The time laws' compiled kernels against their numpy fallback, in one process, interleaved.

Run:  .venv/bin/python benchmarks/kernels.py [--repeats 15]

For each case of ``speed.py`` (ur5e, paper 3R, panda: ``timed()``, ``timed(max_jerk)``, and the
plan itself: its kinematics and splines are compiled too) and the blended ur5e sequence under a jerk limit,
the call runs alternately with the kernels and inside ``kernels.numpy_only()``, ``--repeats``
times each after one warm-up of each: both see the same machine load. Prints the medians and
their ratio, the durations both ways (their largest relative difference), and what the kernels
cost: compiling the kernels' C files as setup.py does (cc -O2) and loading the shared object.
Nothing is asserted: test/timing/test_kernels.py checks the results.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import sysconfig
import tempfile
import time

import numpy as np

from geodesic_planner.timing import kernels

from blends import sequences  # benchmarks/ is the script's directory
from run import ROOT, machine
from speed import BLEND_JERK, BLEND_RADIUS, JERK_FACTOR, plan_cases, smooth_peak_jerk


def compile_seconds() -> float:
    """Wall time of compiling the kernels' C files into a shared object as setup.py does (cc -O2)."""
    folder = os.path.join(ROOT, 'geodesic_planner', 'core')
    sources = [os.path.join(folder, name) for name in ('_kernels.c', '_kernels_timing.c')]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        subprocess.run(['cc', '-O2', '-fno-math-errno', '-ffp-contract=off', '-fPIC', '-shared',
                        f'-I{sysconfig.get_paths()["include"]}', *sources, '-o', os.path.join(tmp, 'k.so')],
                       check=True)
        return time.perf_counter() - t0


def load_ms() -> float:
    """Wall time of loading the built shared object with ctypes in a fresh interpreter."""
    import glob
    built = glob.glob(os.path.join(ROOT, 'geodesic_planner', 'core', '_kernels*.so'))[0]
    code = ('import ctypes, sys, time; t0 = time.perf_counter(); ctypes.CDLL(sys.argv[1]); '
            'print((time.perf_counter() - t0) * 1e3)')
    return float(subprocess.run([sys.executable, '-c', code, built], capture_output=True, text=True,
                                check=True).stdout)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=15)
    args = ap.parse_args(argv)
    print(f'Machine: {machine()}; kernels: {kernels.REASON}')
    if not kernels.active():
        print('the compiled kernels are off: nothing to compare')
        return 1
    items = []
    for case in plan_cases():
        path = case.plan()
        jmax = JERK_FACTOR * smooth_peak_jerk(path)
        items += [(case.name, 'timed()', lambda p=path: p.timed()),
                  (case.name, f'timed(max_jerk {JERK_FACTOR:.0%})', lambda p=path, j=jmax: p.timed(max_jerk=j)),
                  (case.name, 'plan', case.plan)]
    name, planner, poses, q0 = sequences()[0]
    seq = planner.plan_through(poses, start_joints=q0, blend_radius=BLEND_RADIUS)
    items.append((f'{name}, r = {BLEND_RADIUS:g} m', f'blended timed(max_jerk {BLEND_JERK:g})',
                  lambda: seq.timed(max_jerk=BLEND_JERK)))
    print(f'\nRepeats: {args.repeats} of each, alternating; medians of wall clock.\n')
    print('| case | call | compiled (ms) | numpy (ms) | numpy / compiled | duration rel. difference |')
    print('|---|---|---:|---:|---:|---:|')
    for case_name, call, fn in items:
        got = fn()
        with kernels.numpy_only():
            want = fn()
        diff = (abs(got.duration / want.duration - 1.0) if hasattr(got, 'duration') and want.duration else 0.0)
        on, off = [], []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            fn()
            on.append(time.perf_counter() - t0)
            with kernels.numpy_only():
                t0 = time.perf_counter()
                fn()
                off.append(time.perf_counter() - t0)
        a, b = float(np.median(on)) * 1e3, float(np.median(off)) * 1e3
        print(f'| {case_name} | {call} | {a:.2f} | {b:.2f} | {b / a:.2f} | {diff:.1e} |', flush=True)
    print(f'\nCost: compiling the kernels {compile_seconds():.2f} s (once, at set-up); '
          f'loading it in a new process {load_ms():.2f} ms.')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
