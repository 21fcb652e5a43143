#!/usr/bin/env python3
"""geodesic-plan batch: throughput on 1 and 2 workers, overhead against the library in a loop (issue 42).

Run (Ray only inside the loopback namespace):
    bash scripts/netns.sh .venv/bin/python benchmarks/batch.py --requests 1000
    bash scripts/netns.sh .venv/bin/python benchmarks/batch.py --requests 10000    # the issue's full run

Cases: N ur5e LIN requests (seeded: start joints within 0.1 rad of a nominal pose, goal 5 cm or
less from the start's tool pose, same orientation), as JSON Lines. Measured:

* the library in a loop in this process (``plan_row`` on one ``BatchContext``: the work a worker
  does, without Ray): wall time per request;
* ``run_job`` on 1 and on 2 workers of a local Ray instance: the planning wall time (Ray's
  start-up apart, printed separately), requests/s, and the driver's CPU time per request (reading,
  handing out, gathering rows, writing the Parquet shards);
* overhead per request = (1-worker time - loop time) / loop time; speed-up = 1-worker / 2-worker.

Projection to a cluster: a worker plans ``1 / loop time`` requests/s; the driver, one process,
can hand out and write ``1 / driver CPU per request`` requests/s; so W workers give about
``min(W / loop time, 1 / driver CPU)`` requests/s. Nothing is asserted (a shared machine).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))

from geodesic_planner.core.robots import load_robot
from geodesic_planner.core.transforms import matrix_to_quat
from geodesic_planner.io.batch_job import JobSpec, run_job
from geodesic_planner.io.batch_output import read_rows
from geodesic_planner.io.batch_plan import BatchContext, plan_row

Q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])


def write_requests(path: str, n: int) -> list[dict[str, object]]:
    robot, rng = load_robot('ur5e'), np.random.default_rng(42)
    out = []
    with open(path, 'w', encoding='utf-8') as fh:
        for i in range(n):
            q = Q0 + rng.uniform(-0.1, 0.1, 6)
            T = robot.fk(q[None])[0]
            x, y, z, w = (float(v) for v in matrix_to_quat(T[None, :3, :3])[0])
            p = T[:3, 3] + rng.uniform(-0.05, 0.05, 3)
            req = {'id': f'lin{i}', 'motion': 'LIN', 'start_joints': q.tolist(),
                   'goal': {'position': dict(zip('xyz', p.tolist())), 'orientation': {'x': x, 'y': y, 'z': z, 'w': w}}}
            out.append(req)
            fh.write(json.dumps(req) + '\n')
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--requests', type=int, default=1000)
    ap.add_argument('--shard-size', type=int, default=1000)
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix='gp_batch_bench')
    try:
        path = os.path.join(tmp, 'lin.jsonl')
        requests = write_requests(path, args.requests)
        print(f'Machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} / {os.getloadavg()[1]:.1f}; '
              f'{args.requests} ur5e LIN requests, shards of {args.shard_size}\n')
        ctx = BatchContext('ur5e', base_dir=tmp)
        ctx.load()
        t0, c0 = time.perf_counter(), time.process_time()
        ok = sum(plan_row(req, ctx, i + 1)['status'] == 1 for i, req in enumerate(requests))
        loop, loop_cpu = time.perf_counter() - t0, time.process_time() - c0
        print(f'library in a loop: {loop:.2f} s, {1e3 * loop / args.requests:.2f} ms per request, '
              f'{args.requests / loop:.1f} requests/s ({ok} planned); CPU {1e3 * loop_cpu / args.requests:.2f} ms '
              'per request')
        results, cpu = {}, {}
        for workers in (1, 2):
            out = os.path.join(tmp, f'out{workers}')
            w0 = time.perf_counter()
            report = run_job(JobSpec(path, out, 'ur5e', shard_size=args.shard_size), workers=workers)
            wall = time.perf_counter() - w0
            busy = sum(r['planning_time'] for r in read_rows(out))
            results[workers] = report.seconds
            cpu[workers] = report.driver_cpu + report.worker_cpu
            print(f'batch, {workers} worker(s): {report.seconds:.2f} s planning ({wall - report.seconds:.1f} s '
                  f'Ray start-up and stop), {report.planned / report.seconds:.1f} requests/s, '
                  f'{report.failed} failed; driver CPU {1e3 * report.driver_cpu / args.requests:.3f} ms per request; '
                  f'workers busy {1e3 * busy / args.requests:.2f}, CPU {1e3 * report.worker_cpu / args.requests:.2f} '
                  'ms per request')
        overhead = (results[1] - loop) / loop
        print(f'\noverhead per request, wall (1 worker vs the loop): {100 * overhead:+.1f} % '
              f'({1e3 * (results[1] - loop) / args.requests:+.3f} ms)')
        for workers in (1, 2):
            print(f'overhead per request, CPU (driver + {workers} worker(s) vs the loop): '
                  f'{100 * (cpu[workers] - loop_cpu) / loop_cpu:+.1f} % '
                  f'({1e3 * (cpu[workers] - loop_cpu) / args.requests:+.3f} ms)')
        print(f'speed-up 2 workers / 1 worker: {results[1] / results[2]:.2f}x')
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == '__main__':
    main()
