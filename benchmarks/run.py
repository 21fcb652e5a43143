#!/usr/bin/env python3
"""Benchmark of GeodesicPlanner.plan against baselines measured in the same run.

Run:  .venv/bin/python benchmarks/run.py [--repeats 30] [--quick] [--markdown docs/benchmarks.md]

Per case it prints plan time (median and p90 over repeated runs after warm-up, wall clock and this
thread's CPU time), solver iterations, mesh size and accuracy: the tool-path error against the
exact oracle (line + slerp at the same s, docs/maths.md#oracles) where one exists, else the geodesic ODE
residual. Baselines timed beside it: a plain numpy prototype of the same BVP (solve_bvp with a
finite-difference Jacobian, 30 nodes, tol 1e-6, joint-space linear guess), the naive eq. (4)
version (Christoffel symbols from finite differences of G, per-node loop), and Cartesian
line + IK at 100 samples (baselines.cartesian_ik_path). Then scaling with joints, via points and
path length. Nothing here is asserted: tests check correctness, this prints figures.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy
from scipy.integrate import solve_bvp

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.baselines import cartesian_ik_path
from geodesic_planner.core.geodesic import GeodesicEquations
from geodesic_planner.core.kinematics import REVOLUTE, chain_from_dh
from geodesic_planner.io.requests import load_request
from geodesic_planner.core.urdf import regular_home
from geodesic_planner.core.transforms import line_slerp, make_transform, pose_error, so3_exp

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


@dataclass
class Timing:
    median_ms: float
    p90_ms: float
    cpu_median_ms: float


#: Each measurement first runs its function for at least this long (s): the host's cores reach
#: full speed only after a busy spell (docs/benchmarks.md), and the first calls fill caches.
WARMUP_SECONDS = 0.3


def measure(fn: Callable[[], object], repeats: int, warmup: int = 3) -> Timing:
    """Median / p90 wall time and median thread CPU time of fn() in ms (after ``warmup`` calls
    and at least WARMUP_SECONDS of calls)."""
    end = time.perf_counter() + WARMUP_SECONDS
    for k in range(1_000_000):
        fn()
        if k + 1 >= warmup and time.perf_counter() >= end:
            break
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.thread_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    w = np.array(wall) * 1e3
    return Timing(float(np.median(w)), float(np.percentile(w, 90)), float(np.median(cpu) * 1e3))


def tool_error(path, T_a, T_b, samples: int = 1001) -> tuple[float, float]:
    """Max position (m) and orientation (rad) error of the tool path against line + slerp at the same s."""
    s = np.linspace(0.0, 1.0, samples)
    dp, dr = pose_error(path.ee_poses(s), line_slerp(T_a, T_b, s))
    return float(dp.max()), float(dr.max())


def piecewise_tool_error(path, poses, samples: int = 2001) -> tuple[float, float]:
    """Tool error of a piecewise path against line + slerp on every piece (local parameter)."""
    s = np.linspace(0.0, 1.0, samples)
    bp = path.breakpoints
    idx = np.clip(np.searchsorted(bp, s, side='right') - 1, 0, len(bp) - 2)
    T = path.ee_poses(s)
    worst = [0.0, 0.0]
    for i in np.unique(idx):
        sel = idx == i
        u = (s[sel] - bp[i]) / (bp[i + 1] - bp[i])
        dp, dr = pose_error(T[sel], line_slerp(poses[i], poses[i + 1], u))
        worst = [max(worst[0], float(dp.max())), max(worst[1], float(dr.max()))]
    return worst[0], worst[1]


def ode_residual(path, samples: int = 1001) -> float:
    """Max relative geodesic residual ‖G q'' + Jᵀ Ω H‖ / ‖Jᵀ Ω H‖ along the path (spline q'')."""
    s = np.linspace(0.0, 1.0, samples)
    res = path.residual(s)
    q, _dq, a, _ = path.evaluate(s)
    G = path.metric.tensor(path.robot, q)
    scale = np.linalg.norm(np.einsum('nij,nj->ni', G, a), axis=-1).max()
    return float(res.max() / max(scale, 1e-300))


# ---------------------------------------------------------------------------------- baselines
def _bvp_setup(q_a, q_b, nodes: int):
    """Boundary conditions and the joint-space linear initial guess shared by the baselines."""
    n = q_a.size

    def bc(ya, yb):
        return np.concatenate([ya[:n] - q_a, yb[:n] - q_b])

    s = np.linspace(0.0, 1.0, nodes)
    y0 = np.vstack([(q_a + s[:, None] * (q_b - q_a)).T, np.repeat((q_b - q_a)[:, None], nodes, 1)])
    return bc, s, y0


def prototype_plan(robot, q_a, q_b, nodes: int = 30, tol: float = 1e-6):
    """Plain numpy prototype: same equations, solve_bvp's finite-difference Jacobian, linear guess."""
    eq = GeodesicEquations(robot, GeodesicPlanner(robot).metric)
    n = robot.dof

    def fun(_s, y):
        return np.vstack([y[n:], eq.evaluate(y[:n].T, y[n:].T, jacobians=False)[0].T])

    bc, s, y0 = _bvp_setup(q_a, q_b, nodes)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        return solve_bvp(fun, bc, s, y0, tol=tol, max_nodes=5000)


def naive_plan(robot, q_a, q_b, nodes: int = 30, tol: float = 1e-6, max_nodes: int = 300,
               budget_s: float = 20.0):
    """Paper eq. (4) done naively: Christoffel symbols from finite differences of G, node by node."""
    metric = GeodesicPlanner(robot).metric
    n = robot.dof
    h = 1e-6
    deadline = time.perf_counter() + budget_s

    def christoffel_acc(q, v):
        G = metric.tensor(robot, q)
        dG = np.empty((n, n, n))
        for k in range(n):
            e = np.zeros(n)
            e[k] = h
            dG[:, :, k] = (metric.tensor(robot, q + e) - metric.tensor(robot, q - e)) / (2 * h)
        # Γ_m,kj = ½ (∂_j g_mk + ∂_k g_mj − ∂_m g_kj)
        low = 0.5 * (dG.transpose(0, 1, 2) + dG.transpose(0, 2, 1) - dG.transpose(2, 0, 1))
        return -np.linalg.solve(G, np.einsum('mkj,k,j->m', low, v, v))

    def fun(_s, y):
        if time.perf_counter() > deadline:
            raise TimeoutError
        return np.vstack([y[n:], np.array([christoffel_acc(y[:n, i], y[n:, i]) for i in range(y.shape[1])]).T])

    bc, s, y0 = _bvp_setup(q_a, q_b, nodes)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        try:
            return solve_bvp(fun, bc, s, y0, tol=tol, max_nodes=max_nodes)
        except TimeoutError:
            return None


# ---------------------------------------------------------------------------------- cases
def yaw_pose(x, y, yaw):
    T = np.eye(4)
    T[:3, :3] = so3_exp(np.array([0.0, 0.0, yaw]))
    T[:3, 3] = (x, y, 0.0)
    return T


def moved(T, dp, rotvec):
    """T translated by dp (m, base frame) and rotated by so3_exp(rotvec) (rad, tool frame)."""
    return make_transform(T[:3, 3] + np.asarray(dp, dtype=float),
                          T[:3, :3] @ so3_exp(np.asarray(rotvec, dtype=float)))


def ur5e_case():
    robot = load_robot('ur5e')
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T_a = robot.fk(q0)
    T_b = moved(T_a, [0.2, -0.1, 0.15], [0.0, 0.0, np.pi / 6])   # line + 30° rotation
    return robot, T_a, T_b, q0


def random_dh_arm(n: int, seed: int):
    """A random revolute DH arm with n joints (for scaling)."""
    rng = np.random.default_rng(seed)
    rows = [(0.0, rng.uniform(0.05, 0.3), rng.uniform(0.1, 0.4), rng.uniform(-np.pi / 2, np.pi / 2))
            for _ in range(n)]
    return chain_from_dh(f'random_{n}r', rows, [REVOLUTE] * n)


def row(name, timing, path, acc, note=''):
    rep = path.solver
    method = rep.method if hasattr(rep, 'method') else 'piecewise'
    if method in ('pullback', 'redundant'):
        acc = f'{acc}; est. {rep.path_error:.1e} m'
    return (name, f'{timing.median_ms:8.2f}', f'{timing.p90_ms:8.2f}', f'{timing.cpu_median_ms:8.2f}',
            method, str(rep.iterations), str(rep.mesh_size), acc, note)


def print_table(title, header, rows, out):
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    line = '| ' + ' | '.join(str(h).ljust(w) for h, w in zip(header, widths)) + ' |'
    sep = '|' + '|'.join('-' * (w + 2) for w in widths) + '|'
    text = [f'\n### {title}\n', line, sep]
    text += ['| ' + ' | '.join(str(c).ljust(w) for c, w in zip(r, widths)) + ' |' for r in rows]
    block = '\n'.join(text)
    print(block)
    out.append(block)


def machine() -> str:
    cpu = platform.processor() or 'unknown'
    try:
        with open('/proc/cpuinfo', encoding='utf-8') as fh:
            for line in fh:
                if line.startswith('model name'):
                    cpu = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    return (f'{platform.system()} {platform.machine()}, {cpu}, {os.cpu_count()} cores; '
            f'Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}; '
            f'load average {os.getloadavg()[0]:.2f}')


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=30)
    ap.add_argument('--quick', action='store_true', help='fewer repeats, skip the slow naive baseline on 6 joints')
    ap.add_argument('--markdown', help='also write the tables to this Markdown file')
    args = ap.parse_args(argv)
    R = 5 if args.quick else args.repeats
    out: list[str] = [f'Machine: {machine()}\n', f'Repeats per timing: {R} (after at least 3 warm-up runs and {WARMUP_SECONDS} s); times in ms.']
    print(out[0], out[1])

    hdr = ('case', 'median', 'p90', 'cpu med', 'method', 'Newton it', 'mesh', 'accuracy', 'target')
    rows = []
    ratios = []

    # Paper planar 3R (poses)
    req = load_request(os.path.join(ROOT, 'msg_examples', 'paper_3r.yaml'))
    pl3 = GeodesicPlanner(req.robot)
    p3 = pl3.plan(req.start, req.goal)
    e3 = tool_error(p3, req.start, req.goal)
    t3 = measure(lambda: pl3.plan(req.start, req.goal), R)
    rows.append(row('paper 3R (poses)', t3, p3,
                    f'tool {e3[0]:.1e} m, {e3[1]:.1e} rad', '<= 1.5 ms, <= 1e-8 m'))

    # RRPP (Table 5 poses)
    reqr = load_request(os.path.join(ROOT, 'msg_examples', 'paper_rrpp.yaml'))
    plr = reqr.planner()
    pr = reqr.plan(plr)
    tr = measure(lambda: reqr.plan(plr), R)
    sp = pr.metric_speed(np.linspace(0, 1, 201))
    rows.append(row('RRPP (Table 5 poses)', tr, pr,
                    f'ODE residual {ode_residual(pr):.1e} (rel), speed var {np.ptp(sp) / sp.mean():.1e}', ''))

    # ur5e line + 30° rotation
    u, T_a, T_b, q0 = ur5e_case()
    plu = GeodesicPlanner(u)
    pu = plu.plan(T_a, T_b, start_joints=q0)
    eu = tool_error(pu, T_a, T_b)
    tu = measure(lambda: plu.plan(T_a, T_b, start_joints=q0), R)
    rows.append(row('ur5e line + 30° (start joints)', tu, pu,
                    f'tool {eu[0]:.1e} m, {eu[1]:.1e} rad', '<= 3 ms, <= 1e-8 m'))
    tu2 = measure(lambda: plu.plan(T_a, T_b), R)
    pu2 = plu.plan(T_a, T_b)
    eu2 = tool_error(pu2, T_a, T_b)
    rows.append(row('ur5e line + 30° (both poses: 2 IK)', tu2, pu2,
                    f'tool {eu2[0]:.1e} m, {eu2[1]:.1e} rad', ''))

    # Held-out-style 6-joint URDF arm
    kr = load_robot(os.path.join(ROOT, 'geodesic_planner', 'data', 'kr6_like.urdf'))
    qk = np.array([0.2, -0.6, 0.9, 0.3, 0.8, -0.2])
    Tk_a = kr.fk(qk)
    Tk_b = moved(Tk_a, [0.1, 0.12, -0.08], [0.2, -0.1, 0.3])
    plk = GeodesicPlanner(kr)
    pk = plk.plan(Tk_a, Tk_b, start_joints=qk)
    ek = tool_error(pk, Tk_a, Tk_b)
    tk = measure(lambda: plk.plan(Tk_a, Tk_b, start_joints=qk), R)
    rows.append(row('kr6_like.urdf line + rotation', tk, pk,
                    f'tool {ek[0]:.1e} m, {ek[1]:.1e} rad', ''))

    # panda (7 joints): the least-motion path, exactly on line + slerp (docs/maths.md#redundant-arms)
    pa = load_robot('panda')
    qp = pa.home + np.array([0.1, 0.1, -0.1, 0.2, 0.1, -0.1, 0.1])
    Tp_a = pa.fk(qp)
    Tp_b = moved(Tp_a, [0.1, -0.1, 0.1], [0.0, 0.2, 0.2])
    plp = GeodesicPlanner(pa)
    pp = plp.plan(Tp_a, Tp_b, start_joints=qp)
    ep = tool_error(pp, Tp_a, Tp_b)
    tp = measure(lambda: plp.plan(Tp_a, Tp_b, start_joints=qp), R)
    rows.append(row('panda 7 joints (least motion)', tp, pp, f'tool {ep[0]:.1e} m, {ep[1]:.1e} rad',
                    '<= 1e-8 m, <= 2x ur5e'))

    # 5 via points on ur5e (6 poses: start, 4 via, goal ... the path has 5 pieces)
    poses = [T_a]
    for k in range(1, 6):
        poses.append(moved(T_a, [0.05 * k, 0.04 * np.sin(k), 0.03 * k * (-1) ** k], [0.0, 0.0, 0.08 * k]))
    pv = plu.plan_through(poses, start_joints=q0)
    ev = piecewise_tool_error(pv, poses)
    tv = measure(lambda: plu.plan_through(poses, start_joints=q0), R)
    rows.append(row('ur5e through 5 via points', tv, pv,
                    f'tool {ev[0]:.1e} m, {ev[1]:.1e} rad', ''))
    print_table('Plan time per case', hdr, rows, out)

    # ---- baselines in the same run
    brow = []
    for name, robot, planner, T_x, T_y, qs, ours in (
            ('paper 3R', req.robot, pl3, req.start, req.goal, None, t3),
            ('ur5e line + 30°', u, plu, T_a, T_b, q0, tu),
            ('kr6_like.urdf', kr, plk, Tk_a, Tk_b, qk, tk)):
        q_a, q_b = planner.resolve_ends(T_x, T_y, qs)[:2]
        sol = prototype_plan(robot, q_a, q_b)
        tproto = measure(lambda: prototype_plan(robot, q_a, q_b), max(3, R // 5), warmup=1)
        ours_j = measure(lambda: planner.plan(None, None, q_a, q_b), R)
        brow.append((f'{name}: geodesic_planner (joint ends)', f'{ours_j.median_ms:.2f}', '1.0', f'CPU {ours_j.cpu_median_ms:.2f} ms'))
        brow.append((f'{name}: plain prototype (FD Jacobian, 30 nodes, tol 1e-6)', f'{tproto.median_ms:.2f}',
                     f'{tproto.cpu_median_ms / ours_j.cpu_median_ms:.1f}x slower (CPU)',
                     f'status {sol.status}, {sol.niter} it, {sol.x.size} nodes; CPU {tproto.cpu_median_ms:.2f} ms'))
        ratios.append((name, 'prototype', tproto.cpu_median_ms / ours_j.cpu_median_ms))
        if qs is not None:   # the table above planned from start joints: also both ends as poses
            ours_p = measure(lambda: planner.plan(T_x, T_y), R)
            brow.append((f'{name}: geodesic_planner (both ends as poses: 2 IK)', f'{ours_p.median_ms:.2f}',
                         f'prototype {tproto.cpu_median_ms / ours_p.cpu_median_ms:.1f}x slower (CPU)',
                         f'CPU {ours_p.cpu_median_ms:.2f} ms'))
            ratios.append((f'{name} (poses, 2 IK)', 'prototype', tproto.cpu_median_ms / ours_p.cpu_median_ms))
        tcart = measure(lambda: cartesian_ik_path(robot, T_x, T_y, q_start=q_a, samples=100), max(3, R // 5), warmup=1)
        brow.append((f'{name}: Cartesian line + IK, 100 samples', f'{tcart.median_ms:.2f}',
                     f'{tcart.cpu_median_ms / ours.cpu_median_ms:.1f}x slower (CPU) than plan() as in the table above', ''))
        ratios.append((name, 'cartesian+IK', tcart.cpu_median_ms / ours.cpu_median_ms))
        if name == 'paper 3R' or not args.quick:
            t0 = time.perf_counter()
            nsol = naive_plan(robot, q_a, q_b)
            tn = (time.perf_counter() - t0) * 1e3
            status = 'timed out (20 s budget)' if nsol is None else f'status {nsol.status}, {nsol.niter} it, {nsol.x.size} nodes'
            brow.append((f'{name}: naive eq. (4), FD Christoffel (1 run)', f'{tn:.0f}',
                         f'{tn / ours_j.median_ms:.0f}x slower', status))
            ratios.append((name, 'naive', tn / ours_j.median_ms))
    print_table('Baselines measured in the same run', ('what', 'median ms', 'ratio', 'note'), brow, out)

    # ---- held-out style: other 6-joint arms (DH tables of common arms, URDF-like default seed)
    PI = np.pi
    arms = {
        'UR10-like': ([(0, 0.1273, 0, PI / 2), (0, 0, -0.612, 0), (0, 0, -0.5723, 0),
                       (0, 0.1639, 0, PI / 2), (0, 0.1157, 0, -PI / 2), (0, 0.0922, 0, 0)],
                      [0.3, -1.3, 1.5, -1.6, -1.5, 0.3]),
        'IRB120-like': ([(0, 0.29, 0, -PI / 2), (-PI / 2, 0, 0.27, 0), (0, 0, 0.07, -PI / 2),
                         (0, 0.302, 0, PI / 2), (0, 0, 0, -PI / 2), (PI, 0.072, 0, 0)],
                        [0.2, 0.3, 0.2, 0.4, 0.7, 0.1]),
        'PUMA-like': ([(0, 0.67, 0, PI / 2), (0, 0, 0.4318, 0), (0, 0.15, 0.0203, -PI / 2),
                       (0, 0.4318, 0, PI / 2), (0, 0, 0, -PI / 2), (0, 0.0563, 0, 0)],
                      [0.1, 0.5, -0.4, 0.3, 0.6, 0.2]),
    }
    arow = []
    rng = np.random.default_rng(0)
    for arm_name, (dh, q_start) in arms.items():
        arm = chain_from_dh(arm_name, dh, [REVOLUTE] * 6, lower=[-3.0] * 6, upper=[3.0] * 6)
        arm = chain_from_dh(arm_name, dh, [REVOLUTE] * 6, lower=[-3.0] * 6, upper=[3.0] * 6,
                            home=regular_home(arm))   # the seed load_robot gives a URDF arm
        qs0 = np.array(q_start)
        for move in range(3):
            T_x = arm.fk(qs0)
            T_y = moved(T_x, rng.uniform(-0.15, 0.15, 3), rng.uniform(-0.4, 0.4, 3))
            pla = GeodesicPlanner(arm)
            try:
                pa_ = pla.plan(T_x, T_y, start_joints=qs0)
            except Exception as err:  # noqa: BLE001 - a benchmark row, not library code
                arow.append((f'{arm_name} move {move}', 'failed', '', '', '', '', str(err)[:60]))
                continue
            ea = tool_error(pa_, T_x, T_y)
            tj = measure(lambda: pla.plan(T_x, T_y, start_joints=qs0), R)
            tpo = measure(lambda: pla.plan(T_x, T_y), R)
            tpr = measure(lambda: prototype_plan(arm, qs0, pa_.q_goal), max(3, R // 5), warmup=1)
            arow.append((f'{arm_name} move {move}', f'{tj.cpu_median_ms:.2f}', f'{tpo.cpu_median_ms:.2f}',
                         f'{tpr.cpu_median_ms:.2f}', f'{tpr.cpu_median_ms / tj.cpu_median_ms:.1f}x / '
                         f'{tpr.cpu_median_ms / tpo.cpu_median_ms:.1f}x',
                         f'{pa_.solver.method}, {pa_.solver.mesh_size} nodes', f'{ea[0]:.1e} m, {ea[1]:.1e} rad'))
    print_table('Other 6-joint arms: plan vs plain prototype (CPU ms)',
                ('move', 'from joints', 'from poses', 'prototype', 'ratio (joints / poses)', 'method', 'tool error'),
                arow, out)

    # ---- scaling
    srows = []
    for n in range(3, 8):
        arm = random_dh_arm(n, seed=n)
        pln = GeodesicPlanner(arm)
        rng = np.random.default_rng(100 + n)
        k = min(n, 6)
        for _ in range(1000):   # a well-conditioned move: sigma_k / sigma_1 of the pose Jacobian > 0.05
            qa = rng.uniform(-1, 1, n)
            qb = qa + rng.uniform(-0.3, 0.3, n)
            sv = np.linalg.svd(arm.jacobian12(np.stack([qa, qb])), compute_uv=False)
            if np.all(sv[:, k - 1] / sv[:, 0] > 0.05):
                break
        try:
            pn = pln.plan(None, None, qa, qb)
            tn_ = measure(lambda: pln.plan(None, None, qa, qb), R)
            srows.append((f'{n} joints (random DH, joint ends)', f'{tn_.median_ms:.2f}', pn.solver.method, pn.solver.iterations, pn.solver.mesh_size))
        except Exception as err:  # noqa: BLE001 - a benchmark row, not library code
            srows.append((f'{n} joints (random DH)', 'failed', '', str(err)[:60], ''))
    for k in (1, 2, 5, 10, 20, 50):
        arc = [T_a]
        for i in range(1, k + 1):
            ang = 0.6 * i / k
            arc.append(moved(T_a, 0.2 * np.array([np.sin(ang), 1 - np.cos(ang), 0.0]), [0.0, 0.0, ang / 2]))
        pvk = plu.plan_through(arc, start_joints=q0)
        tvk = measure(lambda: plu.plan_through(arc, start_joints=q0), max(3, R // 5), warmup=1)
        srows.append((f'ur5e arc through {k} via point(s)', f'{tvk.median_ms:.2f}', pvk.solver.method, pvk.solver.iterations, pvk.solver.mesh_size))
    for L in (0.05, 0.1, 0.2, 0.4):
        T = T_a.copy()
        T[:3, 3] += L * np.array([0.6, -0.48, 0.64])
        pl_ = plu.plan(T_a, T, start_joints=q0)
        tl = measure(lambda: plu.plan(T_a, T, start_joints=q0), R)
        srows.append((f'ur5e line of {L:.2f} m', f'{tl.median_ms:.2f}', pl_.solver.method, pl_.solver.iterations, pl_.solver.mesh_size))
    print_table('Scaling', ('case', 'median ms', 'method', 'Newton it', 'mesh'), srows, out)

    summary = ['\n### Ratios (baseline time / geodesic_planner time; thread CPU time except the one-run naive column)\n']
    summary += [f'- {case}: {what} {r:.1f}x' for case, what, r in ratios]
    print('\n'.join(summary))
    out.append('\n'.join(summary))
    if args.markdown:
        with open(args.markdown, 'w', encoding='utf-8') as fh:
            fh.write('# Benchmarks\n\nGenerated by `.venv/bin/python benchmarks/run.py --markdown docs/benchmarks.md`.\n\n')
            fh.write('\n'.join(out) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
