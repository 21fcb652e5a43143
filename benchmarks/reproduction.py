#!/usr/bin/env python3
"""Every table of docs/paper-reproduction.md that ``geodesic-compare`` does not print by itself.

Run:  .venv/bin/python benchmarks/reproduction.py [--section NAME ...] [--repeats 20]

Sections (all by default; about 10 s on a shared 2-core machine):

* ``table2``: IK at the ends of the planar 3R (paper Table 2).
* ``table3``: maximum absolute jerks w.r.t. s of the 3R (paper Table 3): geodesic over [0, 1] and
  over [0, 0.99], polynomial; the exact geodesic jerk at s = 98/99 against the paper; which
  uniform grid, with its last points lost, reproduces the paper's geodesic row best.
* ``variants``: the polynomial-method variants tried against the paper's polynomial row.
* ``ranges``: the figure ranges (3R Figs. 5-6, RRPP Figs. 8-9), signed minima and maxima over
  1001 values of s, and the RRPP's Table 3-style maxima.
* ``table6``: IK at the ends of the RRPP (paper Table 6) with the IK residuals.
* ``time``: durations of ``path.timed()`` against the time-optimal duration of an independent
  linear program on 1000 steps (the oracle of the timing tests), and the median time of
  ``path.timed()``.
* ``seconds``: the "Comparison in seconds" table (from :func:`compare_request`, as
  ``geodesic-compare`` writes it into ``comparison.json``).

Everything except the millisecond column is deterministic. Nothing is asserted.
"""
from __future__ import annotations

import argparse
import os
import sys
from types import SimpleNamespace
from typing import Any

import numpy as np
from scipy.interpolate import CubicSpline

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.cli.compare import compare_request, ee_profile, summarize
from geodesic_planner.core.baselines import PolynomialPath, polynomial_path
from geodesic_planner.core.transforms import so3_exp
from geodesic_planner.io.requests import load_request
from geodesic_planner.timing.sampling import refine_adaptively, sample_path

from run import ROOT, machine, measure  # benchmarks/ is the script's directory

#: The paper's Table 3 (planar 3R), geodesic and polynomial rows.
PAPER_GEODESIC = np.array([106.901, 214.241, 107.347])
PAPER_POLYNOMIAL = np.array([105.428, 126.839, 126.789])
SECTIONS = ('table2', 'table3', 'variants', 'ranges', 'table6', 'time', 'seconds')


def _request(name: str) -> Any:
    return load_request(os.path.join(ROOT, 'msg_examples', f'{name}.yaml'))


class _Cache:
    """The comparisons of the two paper requests, computed once."""

    def __init__(self) -> None:
        self._cmp: dict[str, Any] = {}

    def compare(self, name: str) -> Any:
        if name not in self._cmp:
            self._cmp[name] = compare_request(_request(name), 1001)
        return self._cmp[name]


def table2(cache: _Cache) -> None:
    r = cache.compare('paper_3r').result
    print('\n### Table 2 (3R IK at the ends, rad)\n')
    print('| | θ1 | θ2 | θ3 |\n|---|---|---|---|')
    for end, q in (('A', r['q_start']), ('B', r['q_goal'])):
        print(f'| {end}, ours | ' + ' | '.join(f'{v:.4f}' for v in q) + ' |')
    print(f"\nθ1 + θ2 + θ3 at A: {sum(r['q_start']):.4f} rad; pose errors at the ends: "
          f"{np.abs(np.subtract(r['ee_start']['position'], [2.5, 1.5, 0.0])).max():.1e} m, "
          f"{np.abs(np.subtract(r['ee_goal']['position'], [1.5, 2.5, 0.0])).max():.1e} m")


def _row(summary: dict[str, Any]) -> str:
    j = summary['max_abs_jerk']
    return (' | '.join(f'{v:.3f}' for v in j['joints']) + f" | {j['ee_position']:.1e} | "
            f"‖R‴‖_F = {j['ee_orientation_matrix']:.4f}; |ω″| = {j['ee_orientation']:.0e}")


def table3(cache: _Cache) -> None:
    cmp = cache.compare('paper_3r')
    req = _request('paper_3r')
    robot = req.robot
    path = req.plan()
    print('\n### Table 3 (3R max |jerk| w.r.t. s)\n')
    print('| | joint 1 | joint 2 | joint 3 | EE position | EE orientation |\n|---|---|---|---|---|---|')
    print(f"| paper geodesic | {' | '.join(f'{v:.3f}' for v in PAPER_GEODESIC)} | 0.042 | 0.022 |")
    print(f'| geodesic, s ∈ [0, 1] | {_row(cmp.result["geodesic"])} |')
    s = np.linspace(0.0, 1.0, 1001)
    short = summarize(ee_profile(robot, path, s[s <= 0.99 + 1e-12]))
    print(f'| geodesic, s ∈ [0, 0.99] | {_row(short)} |')
    print(f"| paper polynomial | {' | '.join(f'{v:.3f}' for v in PAPER_POLYNOMIAL)} | 41.901 | 139.229 |")
    print(f'| polynomial | {_row(cmp.result["polynomial"])} |')

    jerk_099 = np.abs(path.evaluate(np.array([0.99]))[3][0])
    jerk_9899 = np.abs(path.evaluate(np.array([98.0 / 99.0]))[3][0])
    for label, j in (('s = 0.99', jerk_099), ('s = 98/99', jerk_9899)):
        rel = (j / PAPER_GEODESIC - 1.0) * 100.0
        print(f"\nexact geodesic jerk at {label}: {' / '.join(f'{v:.3f}' for v in j)}; vs paper "
              + ', '.join(f'{v:+.3f} %' for v in rel) + f' (largest |.| {np.abs(rel).max():.3f} %)')
    s_end = np.array([0.5])
    print('jerk ratio joint 2 / joint 1, joint 3 / joint 1 at s = 98/99: '
          f'{jerk_9899[1] / jerk_9899[0]:.3f}, {jerk_9899[2] / jerk_9899[0]:.3f} '
          f'(paper {PAPER_GEODESIC[1] / PAPER_GEODESIC[0]:.3f}, {PAPER_GEODESIC[2] / PAPER_GEODESIC[0]:.3f}); '
          f'peak at s = 1: {np.argmax(np.abs(path.evaluate(np.linspace(0, 1, 1001))[3][:, 1])) == 1000}, '
          f'|jerk| at s = 0.5: {np.abs(path.evaluate(s_end)[3][0]).round(3).tolist()}')

    # Which uniform grid s = k / (N - 1), N = 11..1001, with its last m = 1..3 points lost (so its
    # maximum, the jerk growing towards s = 1, sits at s = (N - 1 - m) / (N - 1)), fits the paper best?
    cands = [(n, m, (n - 1 - m) / (n - 1)) for n in range(11, 1002) for m in (1, 2, 3)]
    jerk = np.abs(path.evaluate(np.array([c[2] for c in cands]))[3])
    err = np.abs(jerk / PAPER_GEODESIC - 1.0).max(axis=1) * 100.0
    order = np.argsort(err)
    print('\nbest uniform grids (N points s = k/(N-1), last m lost; largest relative error vs the paper):')
    for i in order[:5]:
        n, m, sv = cands[i]
        print(f'  N = {n}, m = {m}: maximum at s = {n - 1 - m}/{n - 1} = {sv:.5f}, error {err[i]:.3f} %')
    i101 = next(i for i, c in enumerate(cands) if c[0] == 101 and c[1] == 1)
    i100 = next(i for i, c in enumerate(cands) if c[0] == 100 and c[1] == 1)
    print(f'  N = 101, m = 1 (s = 0:0.01:0.99): error {err[i101]:.3f} % = {err[i101] / err[i100]:.1f} '
          f'times that of N = 100, m = 1 ({err[i100]:.3f} %)')


class _Spline:
    """A path given by one scipy spline per joint (for the spline variants)."""

    def __init__(self, sp: CubicSpline) -> None:
        self.sp = sp

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        return tuple(self.sp(s, k) for k in range(order + 1))


def variants(cache: _Cache) -> None:
    req = _request('paper_3r')
    robot = req.robot
    r = cache.compare('paper_3r').result
    q_a, q_b = np.array(r['q_start']), np.array(r['q_goal'])
    T_a, T_b = robot.fk(q_a), robot.fk(q_b)
    poly = polynomial_path(robot, T_a, T_b, q_a, q_goal=q_b)
    J = np.asarray(robot.jacobian(poly.q_via))
    dq_pos = np.linalg.pinv(J[:, :3, :]) @ poly.twist[:3]
    cases = [
        ('as described, constant end velocity (default)', poly),
        ('zero joint velocity at both ends', polynomial_path(robot, T_a, T_b, q_a, q_goal=q_b, end_velocity='zero')),
        ('position-only pseudo-inverse Jacobian',
         PolynomialPath(robot, poly.s_via, poly.q_via, dq_pos, poly.twist, 'constant')),
        ('natural cubic spline through the via points',
         _Spline(CubicSpline(poly.s_via, poly.q_via, axis=0, bc_type='natural'))),
        ('not-a-knot cubic spline', _Spline(CubicSpline(poly.s_via, poly.q_via, axis=0, bc_type='not-a-knot'))),
        ('clamped spline with zero end velocities',
         _Spline(CubicSpline(poly.s_via, poly.q_via, axis=0, bc_type='clamped'))),
    ]
    s = np.linspace(0.0, 1.0, 1001)
    print('\n### Polynomial variants (3R, max |jerk| w.r.t. s)\n')
    print('| variant (ours) | joint jerks | EE position | |ω″| | ‖R‴‖_F |\n|---|---|---|---|---|')
    for name, p in cases:
        j = summarize(ee_profile(robot, p, s))['max_abs_jerk']  # type: ignore[arg-type]
        print(f"| {name} | {' / '.join(f'{v:.3g}' for v in j['joints'])} | {j['ee_position']:.3g} | "
              f"{j['ee_orientation']:.3g} | {j['ee_orientation_matrix']:.3g} |")


def _span(x: np.ndarray, fmt: str) -> str:
    return f'{format(float(np.min(x)), fmt)} – {format(float(np.max(x)), fmt)}'


def ranges(cache: _Cache) -> None:
    for name in ('paper_3r', 'paper_rrpp'):
        cmp = cache.compare(name)
        print(f'\n### Figure ranges, {name} (over 1001 values of s)\n')
        print('| quantity | geodesic | polynomial |\n|---|---|---|')
        rows = [('|p′| (m)', lambda p: np.linalg.norm(p['dp'], axis=1), '.5f'),
                ('|p″|', lambda p: np.linalg.norm(p['ddp'], axis=1), '.3g'),
                ('|p‴|', lambda p: np.linalg.norm(p['dddp'], axis=1), '.3g'),
                ('‖R′‖_F', lambda p: np.linalg.norm(p['dR'], axis=(1, 2)), '.5f'),
                ('‖R″‖_F', lambda p: np.linalg.norm(p['ddR'], axis=(1, 2)), '.4g'),
                ('‖R‴‖_F', lambda p: np.linalg.norm(p['dddR'], axis=(1, 2)), '.4g'),
                ('joint positions', lambda p: p['q'], '.4f'),
                ('joint velocities', lambda p: p['dq'], '.4g'),
                ('joint accelerations', lambda p: p['ddq'], '.4g'),
                ('joint jerks', lambda p: p['dddq'], '.4g')]
        for label, f, fmt in rows:
            print(f"| {label} | {_span(f(cmp.profiles['geodesic']), fmt)} | "
                  f"{_span(f(cmp.profiles['polynomial']), fmt)} |")
        geo = cmp.profiles['geodesic']
        keep = geo['s'] <= 0.99 + 1e-12
        print(f"| joint jerks, s ≤ 0.99 | {_span(geo['dddq'][keep], '.4g')} | |")
        res = cmp.result
        print('| max distance of the tool from the chord (mm) | '
              + ' | '.join(f"{res[m]['line']['max_distance_to_line_m'] * 1e3:.3g}"
                           for m in ('geodesic', 'polynomial')) + ' |')
        for m in ('geodesic', 'polynomial'):
            j = res[m]['max_abs_jerk']
            print(f"\n{m} max |jerk|: joints {' / '.join(f'{v:.2g}' for v in j['joints'])}, position "
                  f"{j['ee_position']:.3g}, |ω″| {j['ee_orientation']:.3g} (‖R‴‖_F {j['ee_orientation_matrix']:.3g})")
        ratio = res['polynomial']['max_abs_jerk']['ee_position'] / res['geodesic']['max_abs_jerk']['ee_position']
        print(f"\npolynomial / geodesic end-effector position jerk: {ratio:.3g}; geodesic solver: "
              f"{res['geodesic']['solver']['method']}, max residual {res['geodesic']['solver']['max_residual']:.2g}, "
              f"path error {res['geodesic']['solver']['path_error']:.2g} m")


def table6(cache: _Cache) -> None:
    req = _request('paper_rrpp')
    path = req.plan()
    r = cache.compare('paper_rrpp').result
    print('\n### Table 6 (RRPP IK at the ends; rad, rad, m, m)\n')
    print('| | θ1 | θ2 | d3 | d4 |\n|---|---|---|---|---|')
    for end, q in (('A', r['q_start']), ('B', r['q_goal'])):
        print(f'| {end}, ours | ' + ' | '.join(f'{v:.4f}' for v in q) + ' |')
    for end, ik in (('A', path.ik_start), ('B', path.ik_goal)):
        print(f'\nIK at {end}: residual {ik.residual:.2g}, position error {ik.position_error * 1e3:.3f} mm, '
              f'orientation error {ik.orientation_error * 1e3:.3f} mrad')


def _move(robot: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The move of the time table: from home + 0.1 rad, 0.19 m and 0.37 rad (tool frame)."""
    q_a = np.asarray(robot.home, dtype=float) + 0.1
    T_a = robot.fk(q_a)
    T_b = T_a.copy()
    T_b[:3, 3] += [0.1, -0.15, 0.05]
    T_b[:3, :3] = T_a[:3, :3] @ so3_exp(np.array([0.3, 0.2, -0.1]))
    return q_a, T_a, T_b


def lp_topp_duration(path: Any, vmax: np.ndarray, amax: np.ndarray, n: int = 1000) -> float:
    """Time-optimal duration by a linear program in (x = sdot^2, u = sddot) on an n-interval grid.

    A copy of the oracle of test/timing/timing_paths.py (independent of the package's TOPP):
    maximises sum(x) subject to x_{k+1} = x_k + 2 h u_k, |q' u + q'' x| <= amax and
    |q'|^2 x <= vmax^2 at the grid points, x_0 = x_n = 0.
    """
    from scipy.optimize import linprog
    from scipy.sparse import coo_matrix

    h = 1.0 / n
    s = np.linspace(0.0, 1.0, n + 1)
    _, a, b, _ = path.evaluate(s)
    dof = a.shape[1]
    nx = n + 1
    k = np.arange(n)
    rows = np.concatenate([k, k, k, [n, n + 1]])
    cols = np.concatenate([k + 1, k, nx + k, [0, n]])
    vals = np.concatenate([np.ones(n), -np.ones(n), np.full(n, -2.0 * h), [1.0, 1.0]])
    A_eq = coo_matrix((vals, (rows, cols)), shape=(n + 2, nx + n)).tocsr()
    # rows (k, i, sign): sign * (a[k, i] u_k + b[k, i] x_k) <= amax[i]
    kk, ii, sg = np.meshgrid(k, np.arange(dof), [1.0, -1.0], indexing='ij')
    kk, ii, sg = kk.ravel(), ii.ravel(), sg.ravel()
    r = np.arange(kk.size)
    A_ub = coo_matrix((np.concatenate([sg * a[kk, ii], sg * b[kk, ii]]),
                       (np.concatenate([r, r]), np.concatenate([nx + kk, kk]))), shape=(r.size, nx + n)).tocsr()
    b_ub = np.asarray(amax, dtype=float)[ii]
    with np.errstate(divide='ignore'):
        xv = np.min(np.where(np.abs(a) > 0, (vmax / np.abs(a)) ** 2, np.inf), axis=1)
    bounds = [(0.0, float(min(v, 1e9))) for v in xv] + [(None, None)] * n
    c = np.concatenate([-np.ones(nx), np.zeros(n)])
    res = linprog(c, A_ub=A_ub, b_ub=b_ub, A_eq=A_eq, b_eq=np.zeros(n + 2), bounds=bounds, method='highs')
    if res.status != 0:
        raise RuntimeError(f'LP failed: {res.message}')
    x = np.maximum(res.x[:nx], 0.0)
    return float(np.sum(2.0 * h / (np.sqrt(x[:-1]) + np.sqrt(x[1:]))))


def time_table(cache: _Cache, repeats: int) -> None:
    paths: list[tuple[str, Any]] = []
    for name, label in (('paper_3r', '3R'), ('paper_rrpp', 'RRPP')):
        req = _request(name)
        geo = req.plan()
        r = cache.compare(name).result
        q_a, q_b = np.array(r['q_start']), np.array(r['q_goal'])
        poly = polynomial_path(req.robot, req.robot.fk(q_a), req.robot.fk(q_b), q_a, q_goal=q_b)
        paths += [(f'{label} geodesic', geo), (f'{label} polynomial', poly)]
    for preset, label in (('ur5e', 'UR5e geodesic (0.19 m + 0.37 rad)'), ('panda', 'Panda geodesic (same move)')):
        robot = load_robot(preset)
        q_a, T_a, T_b = _move(robot)
        paths.append((label, GeodesicPlanner(robot).plan(T_a, T_b, start_joints=q_a)))
    print(f'\n### Time (robot default limits; LP on 1000 steps; `timed()` median of {repeats} calls)\n')
    print(f'Machine: {machine()}\n')
    print('| path | TOPP (ours) | LP optimum | smooth duration | ratio to optimum | `timed()` | s samples |')
    print('|---|---|---|---|---|---|---|')
    for label, path in paths:
        traj = path.timed()
        lp = lp_topp_duration(path, traj.max_velocity, traj.max_acceleration)
        ms = measure(lambda p=path: p.timed(), repeats).median_ms
        n_s = refine_adaptively(path, sample_path(path, 100)).s.size
        print(f'| {label} | {traj.topp_duration:.4f} s | {lp:.4f} s | {traj.duration:.4f} s | '
              f'{traj.duration / lp:.3f} | {ms:.1f} ms | {n_s} |')
    durations = {label: path.timed().duration for label, path in paths[:4]}
    for label in ('3R', 'RRPP'):
        g, p = durations[f'{label} geodesic'], durations[f'{label} polynomial']
        print(f'\n{label}: geodesic {100.0 * (1.0 - g / p):.1f} % shorter than the polynomial '
              f'(polynomial {100.0 * (p / g - 1.0):.1f} % longer)')


def seconds(cache: _Cache) -> None:
    print('\n### Comparison in seconds (robot default limits, peaks over 4001 times)\n')
    print('| | duration | peak joint jerk | peak tool jerk | at common duration: joint / tool jerk | '
          'max distance to chord | peak change on half grid |')
    print('|---|---|---|---|---|---|---|')
    names = {'geodesic': 'geodesic', 'polynomial': 'polynomial', 'cartesian_ik': 'Cartesian + IK'}
    for name, label in (('paper_3r', '3R'), ('paper_rrpp', 'RRPP')):
        res = cache.compare(name).result
        for m, mlabel in names.items():
            t = res[m]['timed']
            c = t['at_common_duration']
            ch = t['peak_change_vs_half_grid']
            print(f"| {label} {mlabel} | {t['duration_s']:.3f} s | {t['peak_joint_jerk']:.1f} | "
                  f"{t['peak_tool_jerk']:.1f} m/s³ | {c['peak_joint_jerk']:.1f} / {c['peak_tool_jerk']:.1f} | "
                  f"{t['max_distance_to_line_m']:.3g} m | {100 * max(ch.values()):.2f} % |")
        g, p = res['geodesic']['timed'], res['polynomial']['timed']
        print(f"\n{label}: polynomial peak joint jerk {100 * (1 - p['peak_joint_jerk'] / g['peak_joint_jerk']):.1f} % "
              f"lower at the limits, {100 * (1 - p['at_common_duration']['peak_joint_jerk'] / g['at_common_duration']['peak_joint_jerk']):.1f} % "
              f"at the common duration; time step {1e3 * g['time_step_s']:.3f} ms\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or '').split('\n')[0])
    ap.add_argument('--section', action='append', choices=SECTIONS, help='print only this table (repeatable)')
    ap.add_argument('--repeats', type=int, default=20, help='calls of timed() per median (time table)')
    args = ap.parse_args(argv)
    cache = _Cache()
    chosen = args.section or list(SECTIONS)
    funcs = SimpleNamespace(table2=table2, table3=table3, variants=variants, ranges=ranges, table6=table6,
                            seconds=seconds)
    for name in SECTIONS:
        if name not in chosen:
            continue
        if name == 'time':
            time_table(cache, args.repeats)
        else:
            getattr(funcs, name)(cache)
        sys.stdout.flush()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
