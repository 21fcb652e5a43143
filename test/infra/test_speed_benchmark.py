"""benchmarks/speed.py's pure helpers: met / missed, row cells, and the parser of node_latency.py's
table (on a literal sample of its output). No timing, no ROS."""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / 'benchmarks'
# The script imports run, blends and markdown_block from its own directory: on sys.path only for the import.
# Loaded from its file (benchmarks/ is not a package, and not a dependency to declare).
sys.path.insert(0, str(BENCHMARKS))
try:
    _spec = importlib.util.spec_from_file_location('benchmark_speed', BENCHMARKS / 'speed.py')
    assert _spec is not None and _spec.loader is not None
    speed = importlib.util.module_from_spec(_spec)
    sys.modules['benchmark_speed'] = speed          # its dataclasses look their module up
    _spec.loader.exec_module(speed)
finally:
    sys.path.remove(str(BENCHMARKS))
Timing = speed.Timing

# node_latency.py's output, in the format of its main() (two robots; the second table is ignored).
NODE_OUTPUT = '\n'.join([
    '# planner node latency (x86_64, 2 cores, Python 3.11.7, load average 1.2 / 1.0; 40 sequential '
    'requests after 5 warm-up; /joint_states at 0 Hz)',
    '| robot | points | request->trajectory p50 / p90 / max (ms) | of which node compute p50 '
    '| ROS overhead p50 / p90 (ms) | request->response p50 / p90 (ms) '
    '| 4 clients: plans/s (requests, failures) | CPU per plan under load: node / benchmark (ms) |',
    '|---|---|---|---|---|---|---|---|',
    '| planar_3r | 41 | 6.2 / 7.9 / 11.0 | 3.1 | 3.0 / 4.2 | 5.9 / 7.5 | 131.4 (100, 0) | 9.8 / 4.1 |',
    '| ur5e | 66 | 16.7 / 21.3 / 30.2 | 10.0 | 6.4 / 9.9 | 15.8 / 20.1 | 72.7 (100, 0) | 13.3 / 4.4 |',
    '(node compute: plan + timing + trajectory message as the node logs them; ROS overhead: '
    'request->trajectory minus that, per request)',
    '',
    '# where the time goes: node compute_plan in-process (median ms, no ROS transport)',
    '| robot | plan | timing | trajectory | total |',
    '|---|---|---|---|---|',
    '| ur5e | 3.1 | 5.0 | 0.8 | 9.9 |',
])


def test_verdict():
    assert speed.verdict(0.5, '<=', 0.5) == 'met'
    assert speed.verdict(0.51, '<=', 0.5) == 'missed'
    assert speed.verdict(100.0, '>=', 100.0) == 'met'
    assert speed.verdict(99.9, '>=', 100.0) == 'missed'
    assert speed.verdict(10.0, '<', 10.0) == 'missed'
    assert speed.verdict(9.99, '<', 10.0) == 'met'
    assert speed.verdict(None, '<=', 1.0) == 'n/a'
    assert speed.verdict(float('nan'), '<=', 1.0) == 'n/a'


def test_ratio_row_cells():
    plan, timed = Timing(2.0, 2.5, 1.9), Timing(0.8, 1.1, 0.8)
    row = speed.ratio_row('1', 'timed() <= 0.5x plan', 'ur5e', plan, timed, 0.5)
    assert row.ratio == pytest.approx(0.4)
    assert row.cells() == ('1', 'timed() <= 0.5x plan', 'ur5e', '2.00 / 2.50', '0.80 / 1.10 ms', '0.40',
                           '<= 0.5x', 'met')
    slow = speed.ratio_row('2', 'jerk', 'ur5e', plan, Timing(4.2, 5.0, 4.0), 2.0)
    assert slow.cells()[5:] == ('2.10', '<= 2x', 'missed')


def test_absolute_row_and_summary():
    row = speed.Row('3', 'blended', 'ur5e', 'plan_through 10.00 / 12.00', '25.00 / 30.00 ms', 2.5, 25.0,
                    '<=', 20.0, 'ms')
    assert row.cells()[5:] == ('2.50', '<= 20 ms', 'missed')
    rows = [row, speed.ratio_row('4', 'panda', 'p/u', Timing(1.0, 1.0, 1.0), Timing(1.5, 1.6, 1.5), 2.0),
            *speed.node_rows(None, None, missing='not run (--node)')]
    assert [r.cells()[-1] for r in rows] == ['missed', 'met', 'n/a', 'n/a', 'n/a']
    assert rows[2].cells()[4] == 'not run (--node)'
    assert speed.summary(rows) == '1 of 2 measured targets met (1 missed, 3 not measured).'


def test_markdown_table():
    text = speed.markdown_table(('a', 'bb'), [('xyz', '1')])
    assert text.splitlines() == ['| a   | bb |', '|-----|----|', '| xyz | 1  |']


def test_first_number():
    assert speed.first_number('16.7 / 21.3 / 30.2') == 16.7
    assert speed.first_number('72.7 (100, 0)') == 72.7
    with pytest.raises(ValueError, match='no number'):
        speed.first_number('-')


def test_parse_node_table():
    parsed = speed.parse_node_table(NODE_OUTPUT)
    assert parsed == {'planar_3r': {'p50_ms': 6.2, 'plans_per_s': 131.4},
                      'ur5e': {'p50_ms': 16.7, 'plans_per_s': 72.7}}


def test_parse_node_table_failures():
    with pytest.raises(ValueError, match='no request->trajectory table'):
        speed.parse_node_table('Traceback (most recent call last):\n  ...\n')
    header_only = '\n'.join(NODE_OUTPUT.splitlines()[:3])
    with pytest.raises(ValueError, match='no rows'):
        speed.parse_node_table(header_only)
    short = NODE_OUTPUT.replace('| 13.3 / 4.4 |', '|')
    with pytest.raises(ValueError, match='cells'):
        speed.parse_node_table(short)


def test_node_rows():
    base = {'p50_ms': 7.5, 'plans_per_s': 120.0}
    states = {'p50_ms': 8.4, 'plans_per_s': 110.0}
    a, b, c = speed.node_rows(base, states)
    assert a.cells()[4:] == ('7.5 ms', '', '<= 8 ms', 'met')
    assert b.cells()[4:] == ('120.0 plans/s', '', '>= 100 plans/s', 'met')
    # (8.4 / 7.5 - 1) = 12 %: missed
    assert c.value == pytest.approx(12.0)
    assert c.cells()[3:] == ('p50 7.5', 'p50 8.4 ms (+12.0 %)', '1.12', '< 10 %', 'missed')
