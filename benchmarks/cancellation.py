#!/usr/bin/env python3
"""How long an abandoned plan takes to stop once cancelled (issue 26, item 1).

Run:  .venv/bin/python benchmarks/cancellation.py [--delays 12]

Each case is a long computation run in a worker thread under a
:class:`~geodesic_planner.core.cancel.CancelToken`; the token is cancelled after a delay drawn
evenly over the computation's own undisturbed duration, and the time from ``cancel()`` to the
worker's end is measured. The largest of these is the bound the planner node's next request
waits at most (``CANCEL_WAIT`` = 2 s is its hard limit). Cases:

* the node's pipeline (:func:`~geodesic_planner.ros.planning.compute_plan`, plan only) on the
  planar 3R with a velocity scaling factor of 0.0017: close to the 100 000-point cap (sampling,
  validation, message and tool path building);
* the jerk-limited law on a blended 5-pose ur5e sequence (``path.timed(max_jerk=50)``);
* the paper's collocation route on the Panda (7 joints, ``method='collocation'``).

Nothing is asserted; the table goes to docs/testing.md.
"""
from __future__ import annotations

import argparse
import math
import threading
import time
from collections.abc import Callable

import numpy as np
from geodesic_planner_interfaces.srv import PlanTrajectory
from geometry_msgs.msg import PoseStamped

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.cancel import Cancelled, CancelToken, cancellable
from geodesic_planner.ros import params
from geodesic_planner.ros.planning import build_config, compute_plan
from geodesic_planner.ros.service_requests import plan_trajectory_request

from blends import sequences  # benchmarks/ is the script's directory
from run import machine


def _pose_3r(x: float, y: float, psi: float) -> PoseStamped:
    msg = PoseStamped()
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(psi / 2), math.cos(psi / 2)
    return msg


def node_pipeline() -> Callable[[], object]:
    values = params.defaults(params.PLANNER_PARAMETERS)
    values['robot'] = 'planar_3r'
    config = build_config(values)
    f = 0.0017
    msg = PlanTrajectory.Request(start=_pose_3r(2.5, 1.5, math.radians(30.0)),
                                 goal=_pose_3r(1.5, 2.5, math.atan2(0.7, 0.714)),
                                 velocity_scaling_factor=f, acceleration_scaling_factor=f * f)
    request, fv, fa = plan_trajectory_request(config, msg)
    return lambda: compute_plan(config, request, None, velocity_factor=fv, acceleration_factor=fa)


def jerk_blends() -> Callable[[], object]:
    _, planner, poses, q0 = sequences()[0]
    path = planner.plan_through(poses, start_joints=q0, blend_radius=0.02)
    return lambda: path.timed(max_jerk=50.0)


def collocation_7r() -> Callable[[], object]:
    robot = load_robot('panda')
    planner = GeodesicPlanner(robot)
    q_a = robot.home + 0.2
    q_b = robot.home - 0.2
    return lambda: planner.plan(None, robot.fk(q_b), start_joints=q_a, method='collocation')


def stop_times(work: Callable[[], object], delays: int) -> tuple[float, list[float], int]:
    """(undisturbed duration s, stop times ms, runs that finished before the cancel)."""
    t0 = time.perf_counter()
    work()
    full = time.perf_counter() - t0
    out: list[float] = []
    finished = 0
    for delay in np.linspace(0.0, 0.95 * full, delays):
        token = CancelToken()
        end: dict[str, object] = {}

        def run() -> None:
            try:
                with cancellable(token):
                    work()
                end['how'] = 'finished'
            except Cancelled:
                end['how'] = 'cancelled'
            end['t'] = time.monotonic()

        worker = threading.Thread(target=run)
        worker.start()
        time.sleep(float(delay))
        token.cancel()
        worker.join()
        if end['how'] == 'cancelled':
            assert token.cancelled_at is not None
            out.append((float(end['t']) - token.cancelled_at) * 1e3)  # type: ignore[arg-type]
        else:
            finished += 1
    return full, out, finished


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--delays', type=int, default=12, help='cancellation instants per case')
    args = ap.parse_args()
    print(f'Machine: {machine()}\n')
    print('| computation | undisturbed (ms) | cancelled runs | stop time median (ms) | max (ms) |')
    print('|---|---:|---:|---:|---:|')
    cases = [('node pipeline, planar 3R, ~99 000 points', node_pipeline),
             ('jerk-limited law, ur5e 5-pose blended sequence', jerk_blends),
             ('collocation, panda (7 joints)', collocation_7r)]
    for name, make in cases:
        full, ms, finished = stop_times(make(), args.delays)
        med = f'{np.median(ms):.1f}' if ms else '-'
        top = f'{max(ms):.1f}' if ms else '-'
        print(f'| {name} | {full * 1e3:.0f} | {len(ms)} (+{finished} finished first) | {med} | {top} |')


if __name__ == '__main__':
    main()
