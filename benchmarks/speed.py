#!/usr/bin/env python3
"""Speed targets of issue 23 in one table, each measured in the same run with its ratio.

Run:  .venv/bin/python benchmarks/speed.py [--repeats 20] [--node] [--markdown docs/benchmarks.md]

Every time is the median (and p90) wall clock of ``--repeats`` calls after one warm-up call;
"plan" is ``GeodesicPlanner(robot).plan(...)`` on the same case, measured just before the call it
is compared with, so that both see the same machine load. Each call is measured once per request,
on ``--repeats`` requests never planned before (``measure_fresh``: the case with its goal moved
by i x 0.1 mm), plans and timings alike, as a node plans and times each request once: the
geodesic equations remember their last evaluations, and planning or timing the same request again
would skip part of the work (ur5e plan 1.04 ms repeated, 1.35 ms fresh). Each row gives the
absolute times (median / p90, ms), the ratio of the medians, the target and "met" / "missed".
Nothing is asserted: benchmarks print, tests assert.

Rows:

1. ``timed()``: the default timing ``path.timed()`` at most 0.5x the plan's time, on the ur5e
   (``run.ur5e_case()``: line + 30°, from start joints), the paper's planar 3R
   (msg_examples/paper_3r.yaml, poses) and the panda (7 joints, as in ``timing.cases()``);
2. ``timed(max_jerk)``: the jerk-limited timing at most 2x the plan's time, same cases, with
   ``max_jerk`` = 50 % of (issue 40: "binding at half the free peak"; 30 % before) the smooth law's peak jerk per joint (peak of ``|jerk_at_time|`` on
   20001 samples, as ``timing.jerk_table`` computes it);
3. blended sequence: the ur5e 5-point sequence of ``blends.sequences()`` planned by
   ``plan_through(..., blend_radius=0.02)`` and timed with ``max_jerk`` = 50 rad/s³ on every
   joint: at most 20 ms absolute; the ratio to the ``plan_through`` time is printed beside it;
4. 7 joints: the panda's plan time at most 2x the ur5e's (the two plan medians of rows 1);
5. with ``--node`` (starts ROS nodes, in the loopback network namespace via scripts/netns.sh):
   ``benchmarks/node_latency.py --robots ur5e --requests 40 --per-client 100`` run twice, without and with
   ``--joint-states-hz 250``: ur5e request->trajectory p50 <= 8 ms and plans/s with 4 clients
   >= 100 (both from the first run), and the extra p50 with /joint_states at 250 Hz < 10 %.
   Without ``--node`` these rows say "not run (--node)"; when node_latency.py fails, or its table
   cannot be parsed, they say so ("n/a") and its error or raw output is printed under the table.

``--markdown FILE`` also writes the table into FILE between ``<!-- begin speed -->`` and
``<!-- end speed -->`` (benchmarks/markdown_block.py).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.io.requests import load_request

from blends import sequences  # benchmarks/ is the script's directory
from markdown_block import replace_block
from run import ROOT, Timing, machine, moved, ur5e_case

#: Jerk limit of rows 2: this fraction of the smooth law's peak jerk per joint (timing.py --jerk).
JERK_FACTOR = 0.5
#: Samples of the smooth law on which its peak jerk is taken (timing.jerk_table).
JERK_SAMPLES = 20001
#: Blended sequence of row 3: blend radius (m) and jerk limit (rad/s³, every joint; blends.py --jerk).
BLEND_RADIUS = 0.02
BLEND_JERK = 50.0
#: node_latency.py runs of rows 5: sequential requests, and requests per client under load (400
#: in all: about 4 s of load, so that the rate is not one second's sample of a drifting host).
NODE_REQUESTS = 40
NODE_PER_CLIENT = 100
JOINT_STATES_HZ = 250.0

HEADER = ('#', 'target', 'case', 'reference (ms, median / p90)', 'measured (median / p90)', 'ratio',
          'target', 'result')


# ---------------------------------------------------------------------------------- pure helpers
_OPS: dict[str, Callable[[float, float], bool]] = {
    '<=': lambda v, lim: v <= lim,
    '>=': lambda v, lim: v >= lim,
    '<': lambda v, lim: v < lim,
    '>': lambda v, lim: v > lim,
}


def verdict(value: float | None, op: str, limit: float) -> str:
    """'met' when ``value op limit`` holds, 'missed' when not, 'n/a' without a (finite) value."""
    if value is None or not np.isfinite(value):
        return 'n/a'
    return 'met' if _OPS[op](value, limit) else 'missed'


def ms(t: Timing | None) -> str:
    """'median / p90' of a timing in ms ('' for none)."""
    return '' if t is None else f'{t.median_ms:.2f} / {t.p90_ms:.2f}'


@dataclass
class Row:
    """One target: ``value op limit`` decides met / missed; the other fields are shown."""
    number: str
    target: str
    case: str
    reference: str       # what the ratio divides by (absolute, ms), '' if none
    measured: str        # the measured quantity (absolute, with its unit)
    ratio: float | None  # measured / reference, if there is a reference
    value: float | None  # the number compared with the limit
    op: str
    limit: float
    unit: str = ''       # unit of the limit ('' for a ratio)

    def cells(self) -> tuple[str, ...]:
        ratio = '' if self.ratio is None or not np.isfinite(self.ratio) else f'{self.ratio:.2f}'
        limit = f'{self.op} {self.limit:g}{" " + self.unit if self.unit else "x"}'
        return (self.number, self.target, self.case, self.reference, self.measured, ratio, limit,
                verdict(self.value, self.op, self.limit))


def ratio_row(number: str, target: str, case: str, ref: Timing, meas: Timing, limit: float) -> Row:
    """A row whose target is ``meas / ref <= limit`` (ratio of the medians)."""
    r = meas.median_ms / ref.median_ms
    return Row(number, target, case, ms(ref), f'{ms(meas)} ms', r, r, '<=', limit)


def summary(rows: list[Row]) -> str:
    """'k of n measured targets met (m missed, u not measured).'"""
    results = [verdict(r.value, r.op, r.limit) for r in rows]
    met, missed = results.count('met'), results.count('missed')
    return (f'{met} of {met + missed} measured targets met ({missed} missed, '
            f'{results.count("n/a")} not measured).')


def markdown_table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    """A Markdown table with padded columns (as run.print_table)."""
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]

    def line(cells: tuple[str, ...]) -> str:
        return '| ' + ' | '.join(str(c).ljust(w) for c, w in zip(cells, widths)) + ' |'

    return '\n'.join([line(header), '|' + '|'.join('-' * (w + 2) for w in widths) + '|',
                      *(line(r) for r in rows)])


_NUMBER = re.compile(r'[-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?')


def first_number(cell: str) -> float:
    """The first number in a table cell ('12.3 / 15.0 / 20.1' -> 12.3); ValueError if none."""
    m = _NUMBER.search(cell)
    if m is None:
        raise ValueError(f'no number in {cell!r}')
    return float(m.group())


def parse_node_table(text: str) -> dict[str, dict[str, float]]:
    """Per robot, from node_latency.py's output: ``p50_ms`` (request->trajectory) and
    ``plans_per_s`` (4 clients). Columns are found by their header, not their position.
    ValueError when the table or a column is missing."""
    lines = [ln.strip() for ln in text.splitlines()]
    try:
        h = next(i for i, ln in enumerate(lines) if ln.startswith('|') and 'request->trajectory' in ln)
    except StopIteration:
        raise ValueError('no request->trajectory table in the output') from None

    def cells(ln: str) -> list[str]:
        return [c.strip() for c in ln.strip('|').split('|')]

    head = [c.lower() for c in cells(lines[h])]

    def column(*words: str) -> int:
        for i, c in enumerate(head):
            if all(w in c for w in words):
                return i
        raise ValueError(f'no column with {words} in {head}')

    c_robot, c_p50, c_rate = column('robot'), column('request->trajectory', 'p50'), column('plans/s')
    out: dict[str, dict[str, float]] = {}
    for ln in lines[h + 1:]:
        if not ln.startswith('|'):
            break
        row = cells(ln)
        if set(''.join(row)) <= set('-: '):
            continue   # the separator row
        if len(row) != len(head):
            raise ValueError(f'row has {len(row)} cells, header {len(head)}: {ln!r}')
        out[row[c_robot]] = {'p50_ms': first_number(row[c_p50]), 'plans_per_s': first_number(row[c_rate])}
    if not out:
        raise ValueError('the node table has no rows')
    return out


def node_rows(base: dict[str, float] | None, with_states: dict[str, float] | None, robot: str = 'ur5e',
              missing: str = 'not measured') -> list[Row]:
    """Rows 5 from the two node_latency.py runs of one robot (without / with /joint_states); with
    ``base`` None, the same rows saying ``missing`` and 'n/a'."""
    rows = [Row('5a', 'node: request->trajectory p50', robot, '', missing, None, None, '<=', 8.0, 'ms'),
            Row('5b', 'node: plans/s, 4 clients', robot, '', missing, None, None, '>=', 100.0, 'plans/s'),
            Row('5c', f'node: extra p50 with /joint_states at {JOINT_STATES_HZ:g} Hz', robot, '', missing,
                None, None, '<', 10.0, '%')]
    if base is None or with_states is None:
        return rows
    p50, rate, p50_js = base['p50_ms'], base['plans_per_s'], with_states['p50_ms']
    extra = 100.0 * (p50_js / p50 - 1.0)
    rows[0].measured, rows[0].value = f'{p50:.1f} ms', p50
    rows[1].measured, rows[1].value = f'{rate:.1f} plans/s', rate
    rows[2].reference, rows[2].measured = f'p50 {p50:.1f}', f'p50 {p50_js:.1f} ms ({extra:+.1f} %)'
    rows[2].ratio, rows[2].value = p50_js / p50, extra
    return rows


# ---------------------------------------------------------------------------------- measurements
@dataclass
class Case:
    name: str
    plan: Callable[[], object]           # plans the case (returns the path)
    variant: Callable[[int], object]     # plans it with the goal moved by i x 0.1 mm (i != 0): a new path


#: Goal offset of the i-th variant of a case (m, along x): a path never timed before, with the same
#: work (the geodesic equations remember their last evaluations, so timing one path again would
#: skip the exact re-check of the samples nearest a limit: 0.2-0.4 ms of a ur5e timing).
VARIANT_STEP = 1e-4


def measure_fresh(paths: list[object], fn: Callable[[object], object]) -> Timing:
    """Median / p90 wall time and median thread CPU time (ms) of ``fn(path)`` once per path,
    after one warm-up call on the first path (not counted)."""
    fn(paths[0])
    wall, cpu = [], []
    for path in paths[1:]:
        t0, c0 = time.perf_counter(), time.thread_time()
        fn(path)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    w = np.array(wall) * 1e3
    return Timing(float(np.median(w)), float(np.percentile(w, 90)), float(np.median(cpu) * 1e3))


def plan_cases() -> list[Case]:
    """ur5e, paper 3R and panda as run.py / timing.cases() build them (here with their planners:
    timing.cases() returns only the paths, and the plan itself is timed)."""
    u, T_a, T_b, q0 = ur5e_case()
    plu = GeodesicPlanner(u)
    req = load_request(os.path.join(ROOT, 'msg_examples', 'paper_3r.yaml'))
    pl3 = GeodesicPlanner(req.robot)
    pa = load_robot('panda')
    qp = pa.home + np.array([0.1, 0.1, -0.1, 0.2, 0.1, -0.1, 0.1])
    Tp_a = pa.fk(qp)
    Tp_b = moved(Tp_a, [0.1, -0.1, 0.1], [0.0, 0.2, 0.2])
    plp = GeodesicPlanner(pa)

    def shifted(T: np.ndarray, i: int) -> np.ndarray:
        return moved(T, [VARIANT_STEP * i, 0.0, 0.0], [0.0, 0.0, 0.0])

    return [Case('ur5e line + 30°', lambda: plu.plan(T_a, T_b, start_joints=q0),
                 lambda i: plu.plan(T_a, shifted(T_b, i), start_joints=q0)),
            Case('paper 3R (poses)', lambda: pl3.plan(req.start, req.goal),
                 lambda i: pl3.plan(req.start, shifted(req.goal, i))),
            Case('panda 7 joints', lambda: plp.plan(Tp_a, Tp_b, start_joints=qp),
                 lambda i: plp.plan(Tp_a, shifted(Tp_b, i), start_joints=qp))]


def smooth_peak_jerk(path: object) -> np.ndarray:
    """Peak |jerk| per joint of the smooth (default) law on a dense grid."""
    free = path.timed()
    t = np.linspace(0.0, free.duration, JERK_SAMPLES)
    return np.abs(free.jerk_at_time(t)).max(axis=0)


def fresh_plans(plan: Callable[[int], object], count: int, step: int = 1) -> tuple[Timing, list[object]]:
    """``plan(i)`` for i = step, 2 step, ..., count step, timed by :func:`measure_fresh` (the first
    not counted), and the paths."""
    paths: list[object] = []
    timing = measure_fresh([step * k for k in range(1, count + 1)], lambda i: paths.append(plan(i)))
    return timing, paths


def planner_rows(repeats: int) -> list[Row]:
    rows_1, rows_2, plans = [], [], {}
    for case in plan_cases():
        jmax = JERK_FACTOR * smooth_peak_jerk(case.plan())
        # plans and timings on requests never seen before (the variants), one set per timing
        t_plan, paths = fresh_plans(case.variant, repeats + 1)
        t_timed = measure_fresh(paths, lambda p: p.timed())
        _, paths = fresh_plans(case.variant, repeats + 1, step=-1)     # goals moved the other way
        t_jerk = measure_fresh(paths, lambda p, j=jmax: p.timed(max_jerk=j))
        plans[case.name] = t_plan
        rows_1.append(ratio_row('1', 'timed() <= 0.5x plan', case.name, t_plan, t_timed, 0.5))
        rows_2.append(ratio_row('2', f'timed(max_jerk {JERK_FACTOR:.0%} of smooth peak) <= 2x plan',
                                case.name, t_plan, t_jerk, 2.0))

    name, planner, poses, q0 = sequences()[0]   # ur5e, 5 points

    def plan_seq(i: int) -> object:
        goal = moved(poses[-1], [VARIANT_STEP * i, 0.0, 0.0], [0.0, 0.0, 0.0])
        return planner.plan_through(poses[:-1] + [goal], start_joints=q0, blend_radius=BLEND_RADIUS)

    t_seq, paths = fresh_plans(plan_seq, repeats + 1)
    t_seq_jerk = measure_fresh(paths, lambda p: p.timed(max_jerk=BLEND_JERK))
    row_3 = Row('3', f'blended timed(max_jerk {BLEND_JERK:g}) <= 20 ms', f'{name}, r = {BLEND_RADIUS:g} m',
                f'plan_through {ms(t_seq)}', f'{ms(t_seq_jerk)} ms', t_seq_jerk.median_ms / t_seq.median_ms,
                t_seq_jerk.median_ms, '<=', 20.0, 'ms')

    ur, panda = plans['ur5e line + 30°'], plans['panda 7 joints']
    row_4 = ratio_row('4', '7 joints: panda plan <= 2x ur5e plan', 'panda / ur5e (rows 1)', ur, panda, 2.0)
    row_4.reference = f'ur5e {ms(ur)}'
    return [*rows_1, *rows_2, row_3, row_4]


def run_node_latency(extra: list[str]) -> str:
    """stdout of node_latency.py for ur5e inside the network namespace; RuntimeError on failure."""
    cmd = ['bash', 'scripts/netns.sh', sys.executable, 'benchmarks/node_latency.py', '--robots', 'ur5e',
           '--requests', str(NODE_REQUESTS), '--per-client', str(NODE_PER_CLIENT), *extra]
    print(f'running: {" ".join(cmd)}', flush=True)
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900, check=False)
    if res.returncode != 0:
        raise RuntimeError(f'node_latency.py exited with {res.returncode}:\n{res.stdout}\n{res.stderr[-3000:]}')
    return res.stdout


def node_part() -> tuple[list[Row], list[str]]:
    """Rows 5, and notes to print under the table (raw output when it could not be parsed)."""
    outputs = []
    try:
        outputs.append(run_node_latency([]))
        outputs.append(run_node_latency(['--joint-states-hz', f'{JOINT_STATES_HZ:g}']))
    except (RuntimeError, OSError, subprocess.TimeoutExpired) as err:
        return node_rows(None, None, missing='failed (below)'), [f'node rows not measured: {err}']
    try:
        base, with_states = (parse_node_table(o)['ur5e'] for o in outputs)
    except (ValueError, KeyError) as err:
        raw = '\n\n'.join(outputs)
        return (node_rows(None, None, missing='unparsed (below)'),
                [f'node rows: could not parse node_latency.py output ({err!r}); raw output:\n{raw}'])
    return node_rows(base, with_states), []


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--repeats', type=int, default=20, help='timed calls per measurement (median), after warm-up')
    ap.add_argument('--node', action='store_true', help='also the node rows (starts ROS nodes in scripts/netns.sh)')
    ap.add_argument('--markdown', help='also write the table into this Markdown file (block "speed")')
    args = ap.parse_args(argv)
    load = os.getloadavg()
    head = [f'Machine: {machine()}',
            f'Load average (1 / 5 / 15 min): {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}',
            f'Repeats per timing: {args.repeats} (measure_fresh: once per request never planned before, after one '
            'warm-up call; median and p90 wall clock); '
            'ratio = measured median / reference median.']
    print('\n'.join(head), flush=True)
    rows = planner_rows(args.repeats)
    notes: list[str] = []
    if args.node:
        node, notes = node_part()
        rows += node
    else:
        rows += node_rows(None, None, missing='not run (--node)')
    table = markdown_table(HEADER, [r.cells() for r in rows])
    print('\n' + table + '\n\n' + summary(rows))
    for note in notes:
        print('\n' + note)
    if args.markdown:
        replace_block(args.markdown, 'speed', '\n'.join([*head, '', table, '', summary(rows), *notes]))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
