#!/usr/bin/env python3
"""Via points with and without stopping: blended against stopping sequences (issue 14, item 2).

Run:  .venv/bin/python benchmarks/blends.py [--repeats 5] [--jerk]

Cases: ur5e through a 5-point sequence (start, 3 via points, goal: 10-20 cm moves with 10-20°
turns, the benchmark's "ur5e through via points" family) and panda through a 5-point square.
Per blend radius r (0 = rest at every via point) it prints the duration of ``path.timed()`` at the
robot's limits, the time saved against r = 0, the largest tool distance from the via point and
from the stopping path inside the zones (the :class:`BlendZone` report, checked by FK), the
largest distance from the exact line outside the zones, and the median wall time of
``plan_through`` and of ``timed()`` (ms, shared machine). ``--jerk`` adds the jerk-limited law
(``max_jerk`` = 50 rad/s³ on every joint). Nothing is asserted.
"""
from __future__ import annotations

import argparse

import numpy as np

from geodesic_planner import GeodesicPlanner, load_robot

from run import machine, measure, moved  # benchmarks/ is the script's directory

RADII = (0.0, 0.005, 0.01, 0.02, 0.03, 0.05)


def sequences() -> list[tuple[str, GeodesicPlanner, list[np.ndarray], np.ndarray]]:
    """(name, planner, poses, start joints) of the cases."""
    u = load_robot('ur5e')
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T0 = u.fk(q0)
    ur = [T0, moved(T0, [0.15, 0.0, 0.0], [0.0, 0.0, 0.2]), moved(T0, [0.15, -0.15, 0.05], [0.0, 0.0, 0.3]),
          moved(T0, [0.0, -0.15, 0.1], [0.0, 0.2, 0.1]), moved(T0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])]
    pa = load_robot('panda')
    qp = pa.home + np.array([0.1, 0.1, -0.1, 0.2, 0.1, -0.1, 0.1])
    Tp = pa.fk(qp)
    square = [Tp, moved(Tp, [0.1, 0.0, 0.0], [0.0, 0.0, 0.0]), moved(Tp, [0.1, 0.1, 0.0], [0.0, 0.0, 0.0]),
              moved(Tp, [0.0, 0.1, 0.0], [0.0, 0.0, 0.0]), moved(Tp, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])]
    return [('ur5e, 5 points', GeodesicPlanner(u), ur, q0),
            ('panda, 5-point square', GeodesicPlanner(pa), square, qp)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=5)
    ap.add_argument('--jerk', action='store_true', help='also the jerk-limited law (50 rad/s^3)')
    args = ap.parse_args()
    print(f'Machine: {machine()}')
    print(f'Repeats per timing: {args.repeats}; times in ms (median wall clock).\n')
    head = '| case | r (m) | duration (s) | saved | max dist. from via (mm) | corner cut (mm) | ' \
           'line error outside (m) | plan_through | timed() |'
    if args.jerk:
        head += ' duration, jerk 50 (s) | saved |'
    print(head)
    print('|' + '---|' * (head.count('|') - 1))
    for name, planner, poses, q0 in sequences():
        base = base_j = None
        for r in RADII:
            path = planner.plan_through(poses, start_joints=q0, blend_radius=r)
            traj = path.timed()
            base = traj.duration if base is None else base
            zones = getattr(path, 'zones', [])
            dist = max((z.max_distance for z in zones), default=0.0) * 1e3
            cut = max((z.deviation for z in zones), default=0.0) * 1e3
            t_plan = measure(lambda: planner.plan_through(poses, start_joints=q0, blend_radius=r), args.repeats, 1)
            t_time = measure(path.timed, args.repeats, 1)
            row = (f'| {name} | {r:g} | {traj.duration:.3f} | {100 * (1 - traj.duration / base):.1f} % | '
                   f'{dist:.2f} | {cut:.2f} | {path.line_deviation():.1e} | {t_plan.median_ms:.1f} | '
                   f'{t_time.median_ms:.1f} |')
            if args.jerk:
                dj = path.timed(max_jerk=50.0).duration
                base_j = dj if base_j is None else base_j
                row += f' {dj:.3f} | {100 * (1 - dj / base_j):.1f} % |'
            print(row, flush=True)


if __name__ == '__main__':
    main()
