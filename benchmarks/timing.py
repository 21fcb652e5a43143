#!/usr/bin/env python3
"""Benchmark of the timing layer: ``path.timed()`` on the planner cases of ``run.py``.

Run:  .venv/bin/python benchmarks/timing.py [--repeats 40] [--tool] [--jerk]

Per case it prints the time of ``path.timed()`` with the robot's joint limits (median and p90 wall
clock, median thread CPU time, ms) and the trajectory's duration. ``--tool`` adds rows timed with
a tool speed limit (half the tool's peak linear speed of the unlimited law) and an angular one
(half its peak angular speed); an older checkout without those arguments runs without
``--tool``. ``--jerk`` adds a table of jerk-limited timings (``max_jerk`` at 100 %, 30 % and
10 % of the smooth law's peak jerk per joint): duration against the v/a time-optimal duration
(``optimality_ratio``) and against the per-joint 7-segment lower bound (test/timing/jerk_bound.py), the
peak jerk / limit on a dense grid, and the time of ``path.timed(max_jerk=...)``. The paths are
planned once; only the timing is measured. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.io.requests import load_request

from run import ROOT, machine, measure, moved, ur5e_case  # benchmarks/ is the script's directory


def cases() -> list[tuple[str, object]]:
    """(name, path) of the cases of run.py's plan table."""
    req = load_request(os.path.join(ROOT, 'msg_examples', 'paper_3r.yaml'))
    out: list[tuple[str, object]] = [('paper 3R (poses)', GeodesicPlanner(req.robot).plan(req.start, req.goal))]
    reqr = load_request(os.path.join(ROOT, 'msg_examples', 'paper_rrpp.yaml'))
    out.append(('RRPP (Table 5 poses)', reqr.plan(reqr.planner())))
    u, T_a, T_b, q0 = ur5e_case()
    plu = GeodesicPlanner(u)
    out.append(('ur5e line + 30°', plu.plan(T_a, T_b, start_joints=q0)))
    pa = load_robot('panda')
    qp = pa.home + np.array([0.1, 0.1, -0.1, 0.2, 0.1, -0.1, 0.1])
    Tp_a = pa.fk(qp)
    Tp_b = moved(Tp_a, [0.1, -0.1, 0.1], [0.0, 0.2, 0.2])
    out.append(('panda 7 joints', GeodesicPlanner(pa).plan(Tp_a, Tp_b, start_joints=qp)))
    poses = [T_a]
    for k in range(1, 6):
        poses.append(moved(T_a, [0.05 * k, 0.04 * np.sin(k), 0.03 * k * (-1) ** k], [0.0, 0.0, 0.08 * k]))
    out.append(('ur5e through 5 via points', plu.plan_through(poses, start_joints=q0)))
    return out


def peak_tool_speeds(path, traj, samples: int = 4001) -> tuple[float, float]:
    """Largest linear (m/s) and angular (rad/s) tool speed of ``traj``, from J(q) dq."""
    q, dq, _ = traj.at_time(np.linspace(0.0, traj.duration, samples))
    twist = np.einsum('nij,nj->ni', path.robot.jacobian(q), dq)
    return (float(np.linalg.norm(twist[:, :3], axis=1).max()),
            float(np.linalg.norm(twist[:, 3:], axis=1).max()))


JERK_FACTORS = (1.0, 0.3, 0.1)


def jerk_table(repeats: int) -> None:
    """Jerk-limited timing on every case: durations against the v/a optimum and the 7-segment bound."""
    sys.path.insert(0, os.path.join(ROOT, 'test', 'timing'))      # test tooling: the 7-segment bound
    from jerk_bound import rest_to_rest_lower_bound

    print('\n| case | max_jerk | duration (s) | / v/a optimum | / 7-segment bound | peak jerk / limit '
          '| median ms |')
    print('|---|---|---:|---:|---:|---:|---:|')
    for name, path in cases():
        free = path.timed()
        t = np.linspace(0.0, free.duration, 20001)
        peak = np.abs(free.jerk_at_time(t)).max(axis=0)
        for f in JERK_FACTORS:
            jmax = f * peak
            traj = path.timed(max_jerk=jmax)
            tt = np.linspace(0.0, traj.duration, 20001)
            ratio = float((np.abs(traj.jerk_at_time(tt)) / jmax).max())
            q_r = path.evaluate(np.asarray(traj.rests, dtype=float), 0)[0]
            bound = rest_to_rest_lower_bound(q_r, traj.max_velocity, traj.max_acceleration, jmax)
            ms = measure(lambda p=path, j=jmax: p.timed(max_jerk=j), repeats)
            print(f'| {name} | {f:.0%} of smooth peak | {traj.duration:.3f} | {traj.optimality_ratio:.3f} | '
                  f'{traj.duration / bound:.3f} | {ratio:.4f} | {ms.median_ms:.1f} |')
        print(f'| {name} | none (smooth law) | {free.duration:.3f} | {free.optimality_ratio:.3f} | | | |')


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=40)
    ap.add_argument('--tool', action='store_true', help='also time with tool speed limits')
    ap.add_argument('--jerk', action='store_true', help='also a table of jerk-limited timings')
    args = ap.parse_args(argv)
    print(f'Machine: {machine()}')
    print(f'Repeats per timing: {args.repeats}; times in ms.\n')
    print('| case | limits | median | p90 | cpu med | duration (s) |')
    print('|---|---|---:|---:|---:|---:|')
    for name, path in cases():
        traj = path.timed()
        t = measure(lambda p=path: p.timed(), args.repeats)
        print(f'| {name} | joints | {t.median_ms:.2f} | {t.p90_ms:.2f} | {t.cpu_median_ms:.2f} | '
              f'{traj.duration:.3f} |')
        if args.tool:
            v, w = peak_tool_speeds(path, traj)
            for label, kw in ((f'+ tool {0.5 * v:.3g} m/s', {'max_tool_speed': 0.5 * v}),
                              (f'+ tool {0.5 * w:.3g} rad/s', {'max_tool_angular_speed': 0.5 * w})):
                if kw[next(iter(kw))] <= 0.0:
                    continue
                tt = path.timed(**kw)
                t = measure(lambda p=path, k=kw: p.timed(**k), args.repeats)
                print(f'| {name} | {label} | {t.median_ms:.2f} | {t.p90_ms:.2f} | {t.cpu_median_ms:.2f} | '
                      f'{tt.duration:.3f} |')
    if args.jerk:
        jerk_table(max(1, args.repeats // 4))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
