#!/usr/bin/env python3
"""The time laws against the field's libraries, side by side, on the same inputs (issue 40).

Run:  .venv/bin/python benchmarks/peers.py [--rounds 20] [--quick]

The peers are optional benchmark dependencies, never installed by this script (requirements/bench.txt:
``pip install ruckig==0.19.4 toppra==0.6.10``, e.g. into a directory put on PYTHONPATH); a
missing peer's rows say so. pinocchio (``pin``) is in the lock file already (the tests' oracle).

Tables (ratios: ours / peer; compute times are medians of ``--rounds`` interleaved pairs, each
pair the two calls back to back on the same input, thread CPU time):

1. **Jerk-limited PTP along the joint line vs ruckig** (``Synchronization.Phase``, zero end
   velocity and acceleration, the same v/a/j limits): ur5e short (<= 0.05 rad) and long moves at
   j = 10 and 50 rad/s^3. ``path.timed(max_jerk=j)`` of a :class:`JointLinePath` against ruckig's
   whole call from the same arrays (``InputParameter``, ``Ruckig``, ``calculate``). Where ruckig
   leaves the line (it falls back to timing each joint on its own when the Phase profile of the
   slowest joint would break another joint's limit), its duration is not a line's: the table
   says so and also gives ruckig run on s (1 degree of freedom, the line's bounds on s).
2. **Jerk-limited LIN vs an s-ruckig reference**: 10 ur5e LINs at j = 15 and 50 rad/s^3 on
   every joint. Reference: ruckig on s in [0, 1] with constant bounds ``V = min_j vmax_j /
   max_s |q'_j|`` (A, J likewise), then the smallest uniform stretch that keeps every joint's
   velocity, acceleration and jerk (exact path derivatives, 4001 times) 0.1 % below its limit,
   as the project's laws keep them. Lower bound: max(the v/a time-optimal duration (the
   project's TOPP on 800 intervals, full limits), each joint's own 7-segment minimum time for its
   displacement, and the path-coupled bound: every joint's speed |q'_j(s)| sdot within the fastest
   ramp from rest since the start and until the end, sdot within the v/a optimum
   (test/timing/jerk_bound.py, ``coupled_lower_bound``)); the column "binding" names the largest.
   Compute: ``timed(max_jerk=j)`` / ``plan``.
3. **TOPP under v/a limits vs toppra** (seidel, ``ParametrizeConstAccel``; the same paths and
   limits): our fastest (bang-bang) duration and ``timed()`` against toppra's; compute of
   ``timed()`` against toppra's whole call; toppra's largest acceleration / limit by exact
   derivatives of its output (a ConstAccel output is piecewise quadratic).
4. **Whole LIN pipeline vs pinocchio + damped least squares IK + toppra**: the ur5e URDF of
   test/data/real_arms, line + slerp at 100 samples, each sample's IK by pinocchio (damped least
   squares from the previous sample), toppra on the joint waypoints; against
   ``GeodesicPlanner.plan`` + ``timed()`` on the same URDF. Tool error: the largest distance of
   the tool from the line at 1001 samples.

Nothing is asserted: benchmarks print, tests assert.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Callable

import numpy as np

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.ptp import JointLinePath
from geodesic_planner.timing.sampling import sample_path
from geodesic_planner.timing.topp import topp

from run import ROOT, machine, moved, ur5e_case  # benchmarks/ is the script's directory

sys.path.insert(0, os.path.join(ROOT, 'test', 'timing'))      # test tooling: the 7-segment bound
from jerk_bound import coupled_lower_bound, min_rest_to_rest_time

try:
    import ruckig
except ImportError:         # optional: requirements/bench.txt
    ruckig = None
try:
    import toppra
    import toppra.algorithm
    import toppra.constraint
except ImportError:
    toppra = None

#: Check margin of the project's laws (tuning.CHECK_MARGIN), applied to the s-ruckig reference too.
MARGIN = 1e-3


def pair_times(ours: Callable[[], object], peer: Callable[[], object], rounds: int) -> tuple[float, float]:
    """Median thread CPU time (ms) of each of two calls, measured in interleaved pairs."""
    a, b = [], []
    for _ in range(2):      # warm-up
        ours()
        peer()
    for _ in range(rounds):
        t0 = time.thread_time()
        ours()
        t1 = time.thread_time()
        peer()
        t2 = time.thread_time()
        a.append(t1 - t0)
        b.append(t2 - t1)
    return float(np.median(a)) * 1e3, float(np.median(b)) * 1e3


def ruckig_call(q_a: np.ndarray, q_b: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray):
    """ruckig's time-optimal Phase-synchronised rest-to-rest trajectory, from the arrays."""
    n = len(q_a)
    inp = ruckig.InputParameter(n)
    inp.current_position = q_a
    inp.target_position = q_b
    inp.max_velocity = v
    inp.max_acceleration = a
    inp.max_jerk = j
    inp.synchronization = ruckig.Synchronization.Phase
    traj = ruckig.Trajectory(n)
    ruckig.Ruckig(n).calculate(inp, traj)
    return traj


def ruckig_1d(V: float, A: float, J: float):
    """ruckig on s from 0 to 1 under |sdot| <= V, |sddot| <= A, |sdddot| <= J."""
    return ruckig_call(np.zeros(1), np.ones(1), np.array([V]), np.array([A]), np.array([J]))


def off_line(traj, q_a: np.ndarray, dq: np.ndarray, samples: int = 201) -> float:
    """Largest distance (rad) of ruckig's positions from the joint line through q_a along dq."""
    u = dq / np.linalg.norm(dq)
    worst = 0.0
    for t in np.linspace(0.0, traj.duration, samples):
        d = np.asarray(traj.at_time(t)[0]) - q_a
        worst = max(worst, float(np.linalg.norm(d - (d @ u) * u)))
    return worst


def ptp_table(rounds: int) -> None:
    print('\n### 1. Jerk-limited PTP along the joint line vs ruckig 0.19.4 (Phase)\n')
    if ruckig is None:
        print('ruckig not installed (requirements/bench.txt): skipped')
        return
    robot = load_robot('ur5e')
    rng = np.random.default_rng(40)
    print('| move | max_jerk | ours (s) | ruckig (s) | ours / ruckig | ruckig off the line (rad) '
          '| ruckig on s (s) | ours / ruckig on s | compute ours / ruckig (ms) |')
    print('|---|---:|---:|---:|---:|---:|---:|---:|---:|')
    worst, worst_c = 0.0, 0.0
    for k in range(8):
        size = 0.05 if k < 4 else 1.5
        q_a = robot.home + rng.uniform(-0.4, 0.4, 6)
        q_b = q_a + rng.uniform(-1.0, 1.0, 6) * size
        path = JointLinePath(robot, q_a, q_b)
        for j in (10.0, 50.0):
            jv = np.full(6, j)
            ours = path.timed(max_jerk=j)
            peer = ruckig_call(q_a, q_b, robot.max_velocity, robot.max_acceleration, jv)
            dq = q_b - q_a
            d = np.abs(dq)
            s_peer = ruckig_1d(float(np.min(robot.max_velocity / d)), float(np.min(robot.max_acceleration / d)),
                               float(np.min(jv / d)))
            off = off_line(peer, q_a, dq)
            t_o, t_p = pair_times(lambda p=path, j=j: p.timed(max_jerk=j),
                                  lambda: ruckig_call(q_a, q_b, robot.max_velocity, robot.max_acceleration, jv),
                                  rounds)
            r = ours.duration / peer.duration
            if off < 1e-9:
                worst = max(worst, r)
            worst_c = max(worst_c, t_o / t_p)
            print(f'| {"short" if size < 1 else "long"} {k} | {j:g} | {ours.duration:.4f} | {peer.duration:.4f} | '
                  f'{r:.5f} | {off:.1e} | {s_peer.duration:.4f} | {ours.duration / s_peer.duration:.6f} | '
                  f'{t_o / t_p:.2f} ({t_o:.3f} / {t_p:.3f}) |')
    print(f'\nWorst where ruckig keeps to the line: duration {worst:.5f}x; compute {worst_c:.2f}x.')


def lin_paths(count: int = 10) -> tuple[object, list[object], Callable[[int], object]]:
    """The ur5e and ``count`` LIN paths from run.ur5e_case's start (seeded goals), and a replanner."""
    robot, T_a, _, q0 = ur5e_case()
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(40)
    goals = []
    while len(goals) < count:
        T_b = moved(T_a, rng.uniform(-0.25, 0.25, 3), [0.0, 0.0, rng.uniform(-0.6, 0.6)])
        try:
            planner.plan(T_a, T_b, start_joints=q0)
        except Exception:       # noqa: BLE001 - an unreachable goal: the next one
            continue
        goals.append(T_b)
    paths = [planner.plan(T_a, T_b, start_joints=q0) for T_b in goals]
    return robot, paths, lambda i: planner.plan(T_a, goals[i], start_joints=q0)


def s_ruckig_reference(path, robot, j: float, samples: int = 4001) -> float:
    """Table 2's reference duration (s): ruckig on s under constant bounds, stretched into the limits."""
    q1 = np.abs(path.evaluate(np.linspace(0.0, 1.0, 1001), 1)[1]).max(axis=0)
    v, a = robot.max_velocity, robot.max_acceleration
    traj = ruckig_1d(float(np.min(v / q1)), float(np.min(a / q1)), float(np.min(j / q1)))
    t = np.linspace(0.0, traj.duration, samples)
    st = np.array([[x[0] for x in traj.at_time(ti)] for ti in t])
    s, sd, sdd = np.clip(st[:, 0], 0.0, 1.0), st[:, 1], st[:, 2]
    sddd = np.gradient(sdd, t)          # piecewise-constant jerk: exact between its switches
    _, d1, d2, d3 = path.evaluate(s)
    rv = np.max(np.abs(d1 * sd[:, None]) / v)
    ra = np.max(np.abs(d1 * sdd[:, None] + d2 * sd[:, None] ** 2) / a)
    rj = np.max(np.abs(d1 * sddd[:, None] + 3.0 * d2 * (sd * sdd)[:, None] + d3 * sd[:, None] ** 3) / j)
    k = 1.0 - MARGIN
    return traj.duration * max(rv / k, math.sqrt(ra / k), math.cbrt(rj / k))


def topp_profile(path, robot, intervals: int = 800) -> tuple[np.ndarray, np.ndarray]:
    """The v/a time-optimal sdot^2 (1/s^2) under the full limits at ``intervals + 1`` uniform s (the
    project's TOPP on that grid), and the path's q' there."""
    fine = sample_path(path, intervals)
    return topp(fine, robot.max_velocity, robot.max_acceleration), path.evaluate(fine.s, 1)[1]


def topp_duration(path, robot, intervals: int = 800) -> float:
    """The v/a time-optimal duration (s) under the full limits, the project's TOPP on a fine grid."""
    x, _ = topp_profile(path, robot, intervals)
    ds = 1.0 / intervals
    return float(np.sum(2.0 * ds / (np.sqrt(x[1:]) + np.sqrt(x[:-1]))))


def lin_table(rounds: int, count: int) -> None:
    print('\n### 2. Jerk-limited LIN vs ruckig on s (constant bounds, stretched into the limits)\n')
    robot, paths, replan = lin_paths(count)
    print('| move | max_jerk | ours (s) | s-ruckig (s) | ours / s-ruckig | lower bound (s) | binding | ours / bound '
          '| compute timed(max_jerk) / plan (ms) |')
    print('|---|---:|---:|---:|---:|---:|---|---:|---:|')
    for j in (15.0, 50.0):
        worst_ref, worst_lb, ratios = 0.0, 0.0, []
        for i, path in enumerate(paths):
            ours = path.timed(max_jerk=j)
            ref = s_ruckig_reference(path, robot, j) if ruckig is not None else float('nan')
            q_ends = path.evaluate(np.array([0.0, 1.0]), 0)[0]
            own = float(min_rest_to_rest_time(np.abs(q_ends[1] - q_ends[0]), robot.max_velocity,
                                              robot.max_acceleration, j).max())
            x_star, dq = topp_profile(path, robot)
            t_va = float(np.sum(2.0 / 800 / (np.sqrt(x_star[1:]) + np.sqrt(x_star[:-1]))))
            coupled = coupled_lower_bound(dq, x_star, robot.max_velocity, robot.max_acceleration, j,
                                          0.5 * max(t_va, own), ours.duration)
            bounds = {'v/a': t_va, 'joint': own, 'coupled': coupled}
            binding = max(bounds, key=bounds.__getitem__)
            bound = bounds[binding]
            t_o, t_p = pair_times(lambda p=path, j=j: p.timed(max_jerk=j), lambda i=i: replan(i), rounds)
            ratios.append(t_o / t_p)
            worst_ref = max(worst_ref, ours.duration / ref)
            worst_lb = max(worst_lb, ours.duration / bound)
            print(f'| {i} | {j:g} | {ours.duration:.4f} | {ref:.4f} | {ours.duration / ref:.4f} | {bound:.4f} | '
                  f'{binding} | {ours.duration / bound:.3f} | {t_o / t_p:.2f} ({t_o:.2f} / {t_p:.2f}) |')
        print(f'| all | {j:g} | | | worst {worst_ref:.4f} | | | worst {worst_lb:.3f} | '
              f'median {float(np.median(ratios)):.2f} |')


def toppra_call(path, robot, gridpoints: int = 101):
    """toppra 0.6.10's seidel TOPP with ParametrizeConstAccel on the path's joint waypoints."""
    s = np.linspace(0.0, 1.0, gridpoints)
    spline = toppra.SplineInterpolator(s, path.evaluate(s, 0)[0])
    vlim = np.stack([-robot.max_velocity, robot.max_velocity], axis=1)
    alim = np.stack([-robot.max_acceleration, robot.max_acceleration], axis=1)
    algo = toppra.algorithm.TOPPRA([toppra.constraint.JointVelocityConstraint(vlim),
                                    toppra.constraint.JointAccelerationConstraint(alim)],
                                   spline, solver_wrapper='seidel', parametrizer='ParametrizeConstAccel',
                                   gridpoints=np.linspace(0.0, 1.0, gridpoints))
    return algo.compute_trajectory()


def topp_table(rounds: int, count: int) -> None:
    print('\n### 3. TOPP under velocity + acceleration limits vs toppra 0.6.10 (seidel, ConstAccel)\n')
    if toppra is None:
        print('toppra not installed (requirements/bench.txt): skipped')
        return
    toppra.setup_logging('WARNING')
    robot, paths, _ = lin_paths(count)
    print('| move | toppra (s) | ours, fastest (s) | / toppra | ours, timed() (s) | / toppra '
          '| toppra a / limit | compute timed() / toppra (ms) |')
    print('|---|---:|---:|---:|---:|---:|---:|---:|')
    for i, path in enumerate(paths):
        peer = toppra_call(path, robot)
        ours = path.timed()
        t = np.linspace(0.0, peer.duration, 4001)
        ra = float(np.max(np.abs(peer(t, 2)) / robot.max_acceleration))
        t_o, t_p = pair_times(lambda p=path: p.timed(), lambda p=path: toppra_call(p, robot), rounds)
        print(f'| {i} | {peer.duration:.4f} | {ours.topp_duration:.4f} | {ours.topp_duration / peer.duration:.4f} '
              f'| {ours.duration:.4f} | {ours.duration / peer.duration:.3f} | {ra:.4f} | '
              f'{t_o / t_p:.2f} ({t_o:.2f} / {t_p:.2f}) |')


def pipeline_table(rounds: int) -> None:
    print('\n### 4. Whole LIN pipeline vs pinocchio + damped least squares IK + toppra\n')
    if toppra is None:
        print('toppra not installed (requirements/bench.txt): skipped')
        return
    import pinocchio as pin

    urdf = os.path.join(ROOT, 'test', 'data', 'real_arms', 'airo-models', 'ur5e.urdf')
    robot = load_robot(urdf, base_link='base_link', tip_link='tool0')
    model = pin.buildModelFromUrdf(urdf)
    data = model.createData()
    tip = model.getFrameId('tool0')
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T_a = robot.fk(q0)
    T_b = moved(T_a, [0.1, -0.1, 0.1], [0.0, 0.0, np.pi / 12])
    planner = GeodesicPlanner(robot)
    M_a, M_b = pin.SE3(T_a[:3, :3], T_a[:3, 3]), pin.SE3(T_b[:3, :3], T_b[:3, 3])
    w_ab = pin.log3(T_a[:3, :3].T @ T_b[:3, :3])      # line + slerp (SE3.Interpolate is a screw)

    def pipeline():
        qs = [q0.copy()]
        for s in np.linspace(0.0, 1.0, 100)[1:]:
            target = pin.SE3(M_a.rotation @ pin.exp3(s * w_ab), M_a.translation + s * (M_b.translation - M_a.translation))
            q = qs[-1].copy()
            for _ in range(50):
                pin.framesForwardKinematics(model, data, q)
                err = pin.log6(data.oMf[tip].actInv(target)).vector
                if np.linalg.norm(err) < 1e-10:
                    break
                Jm = pin.computeFrameJacobian(model, data, q, tip, pin.LOCAL)
                q = q + Jm.T @ np.linalg.solve(Jm @ Jm.T + 1e-10 * np.eye(6), err)
            qs.append(q)
        qs = np.array(qs)
        s = np.linspace(0.0, 1.0, qs.shape[0])
        spline = toppra.SplineInterpolator(s, qs)
        vlim = np.stack([-robot.max_velocity, robot.max_velocity], axis=1)
        alim = np.stack([-robot.max_acceleration, robot.max_acceleration], axis=1)
        algo = toppra.algorithm.TOPPRA([toppra.constraint.JointVelocityConstraint(vlim),
                                        toppra.constraint.JointAccelerationConstraint(alim)], spline,
                                       solver_wrapper='seidel', parametrizer='ParametrizeConstAccel')
        return spline, algo.compute_trajectory()

    def ours():
        return planner.plan(T_a, T_b, start_joints=q0).timed()

    def line_error(q_of_s) -> float:
        s = np.linspace(0.0, 1.0, 1001)
        p = np.array([robot.fk(q)[:3, 3] for q in q_of_s(s)])
        return float(np.max(np.abs(p - (T_a[:3, 3] + s[:, None] * (T_b[:3, 3] - T_a[:3, 3])))))

    spline, traj = pipeline()
    mine = ours()
    t_o, t_p = pair_times(ours, pipeline, rounds)
    print('| pipeline | duration (s) | tool off the line (m) | compute (ms) |')
    print('|---|---:|---:|---:|')
    print(f'| pinocchio DLS IK (100 samples) + toppra | {traj.duration:.4f} | '
          f'{line_error(spline):.1e} | {t_p:.2f} |')
    print(f'| geodesic_planner plan + timed() | {mine.duration:.4f} | '
          f'{line_error(lambda s: mine.path.evaluate(s, 0)[0]):.1e} | {t_o:.2f} |')
    print(f'\nCompute: pipeline / ours {t_p / t_o:.2f}x.')


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--rounds', type=int, default=20, help='interleaved pairs per compute ratio')
    ap.add_argument('--quick', action='store_true', help='5 LIN moves, 5 rounds')
    args = ap.parse_args(argv)
    rounds, count = (5, 5) if args.quick else (args.rounds, 10)
    print(f'Machine: {machine()}')
    print(f'ruckig: {getattr(ruckig, "__file__", "not installed")}; toppra: '
          f'{getattr(toppra, "__file__", "not installed")}')
    ptp_table(rounds)
    if ruckig is not None:
        lin_table(rounds, count)
    topp_table(rounds, count)
    pipeline_table(rounds)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
