"""The batch job's parts that need no Ray: reading requests, one request -> one row, the shards,
the manifest, the CLI's argument bounds and its progress line."""
from __future__ import annotations

import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

pa = pytest.importorskip('pyarrow')
pq = pytest.importorskip('pyarrow.parquet')

from geodesic_planner.cli import batch as cli  # noqa: E402
from geodesic_planner.core.errors import RequestError  # noqa: E402
from geodesic_planner.io.batch_input import MAX_LINE_BYTES, count_records, read_records  # noqa: E402
from geodesic_planner.io.batch_output import read_rows, write_manifest, write_shard  # noqa: E402
from geodesic_planner.io.batch_plan import BatchContext, plan_row  # noqa: E402
from geodesic_planner.io.requests import parse_request  # noqa: E402

Q0 = [0.3, -1.2, 1.4, -1.5, -1.4, 0.2]
Q1 = [0.2, -1.1, 1.3, -1.4, -1.3, 0.1]


def test_json_lines_numbered_by_line_malformed_ones_named(tmp_path: Path) -> None:
    path = tmp_path / 'r.jsonl'
    long_line = '{"id": "' + 'x' * MAX_LINE_BYTES + '"}'
    path.write_bytes(b'\n'.join([b'{"id": "a"}', b'', b'   ', b'[1, 2]', b'{"id": ', long_line.encode(),
                                 b'\xff\xfe', b'{"id": "b"}\r']) + b'\n')
    recs = list(read_records(str(path), 'jsonl'))
    assert [(r.index, r.problem) for r in recs] == [
        (1, ''), (4, 'expected a JSON object, got list'), (5, 'malformed JSON at column 8: Expecting value'),
        (6, f'longer than {MAX_LINE_BYTES} bytes'), (7, 'not UTF-8 (byte 1)'), (8, '')]
    assert recs[0].data == {'id': 'a'} and recs[-1].data == {'id': 'b'} and recs[1].where == 'line 4'
    assert count_records(str(path), 'jsonl') == 6
    with pytest.raises(RequestError, match=r'^line 4: expected a JSON object, got list \(--strict'):
        count_records(str(path), 'jsonl', strict=True)
    assert [r.index for r in read_records(str(path), 'jsonl', skip=lambda i: i < 6)] == [6, 7, 8]


def test_parquet_rows_numbered_nulls_are_absent_keys(tmp_path: Path) -> None:
    rows = [{'id': 'a', 'start_joints': Q0}, {'id': 'b', 'goal_joints': Q1}, {'id': 'c'}]
    pq.write_table(pa.Table.from_struct_array(pa.array(rows)), tmp_path / 'r.parquet', row_group_size=2)
    recs = list(read_records(str(tmp_path / 'r.parquet'), 'parquet'))
    assert [(r.index, r.data, r.where) for r in recs] == [(1, rows[0], 'row 1'), (2, rows[1], 'row 2'),
                                                          (3, rows[2], 'row 3')]
    assert count_records(str(tmp_path / 'r.parquet'), 'parquet') == 3
    (tmp_path / 'bad.parquet').write_bytes(b'not parquet')
    with pytest.raises(RequestError, match='cannot read Parquet file'):
        count_records(str(tmp_path / 'bad.parquet'), 'parquet')


@pytest.mark.parametrize('request_, code, words', [
    ({'start_joints': Q0, 'goal_joints': Q1, 'velocity_scaling': 0.0}, -101, 'velocity_scaling must be in (0, 1]'),
    ({'start_joints': Q0, 'goal_joints': Q1, 'time_limit': -1}, -101, 'time_limit must be in (0, 3600] s'),
    ({'start_joints': Q0, 'goal_joints': Q1, 'motion': 'PTP', 'sequence': []}, -101, 'give motion or sequence'),
    ({'start_joints': Q0, 'goal_joints': Q1, 'scene': 'x'}, -101, "no scene named 'x'"),
    ({'start_joints': Q0, 'goal_joints': Q1, 'robot': 'no_such_robot'}, -101, "unknown robot 'no_such_robot'"),
    ({'start_joints': Q0, 'goal_joints': [9.0, 0, 0, 0, 0, 0]}, -103, 'limit'),   # JOINT_LIMITS_VIOLATED
    ('not a mapping', -101, 'expected a mapping, got str'),
])
def test_failed_requests_are_rows_with_their_code(request_: object, code: int, words: str) -> None:
    ctx = BatchContext('ur5e')
    row = plan_row(request_, ctx, 7)
    assert (row['index'], row['id'], row['status']) == (7, '7', code), row['message']
    assert words in row['message'] and np.isnan(row['duration']) and row['times'].size == 0


def test_a_row_does_not_depend_on_what_was_planned_before() -> None:
    req = {'id': 17, 'motion': 'PTP', 'start_joints': Q0, 'goal_joints': Q1, 'ptp': 'joint_line'}
    first = plan_row(req, BatchContext('ur5e'), 1)
    ctx = BatchContext('ur5e')
    for other in ([0.0] * 6, [0.5, -1.0, 1.0, -1.0, -1.0, 0.5]):
        plan_row({'start_joints': Q0, 'goal_joints': other}, ctx, 2)
    again = plan_row(req, ctx, 1)
    assert first['id'] == again['id'] == '17'
    for key in ('duration', 'times', 'positions', 'velocities', 'accelerations'):
        np.testing.assert_array_equal(first[key], again[key])
    direct = parse_request({'robot': 'ur5e', 'start_joints': Q0,
                            'sequence': [{'motion': 'PTP', 'goal_joints': Q1, 'ptp': 'joint_line'}]}).plan().timed()
    t, q, _, _ = direct.sample(0.01, check=True)
    np.testing.assert_array_equal(first['times'], t)
    np.testing.assert_array_equal(first['positions'], q)


def test_shards_round_trip_and_the_manifest_guards_a_resume(tmp_path: Path) -> None:
    ctx = BatchContext('ur5e')
    rows = [plan_row({'start_joints': Q0, 'goal_joints': Q1}, ctx, 3), plan_row('x', ctx, 2)]
    write_shard(rows, str(tmp_path / 'part-000000.parquet'))
    table = pq.read_table(tmp_path / 'part-000000.parquet').to_pydict()
    assert table['index'] == [2, 3] and table['status'] == [-101, 1]
    assert table['positions'][1] == rows[0]['positions'].tolist() and table['times'][0] == []
    back = list(read_rows(str(tmp_path)))
    np.testing.assert_array_equal(back[1]['accelerations'], rows[0]['accelerations'])
    job = {'input': 'a', 'shard_size': 10}
    with pytest.raises(RequestError, match='holds the results of a job'):
        write_manifest(str(tmp_path), job, resume=False)
    with pytest.raises(RequestError, match=r'has shards but no job\.json'):
        write_manifest(str(tmp_path), job, resume=True)
    (tmp_path / 'part-000000.parquet').unlink()
    write_manifest(str(tmp_path), job, resume=False)
    write_manifest(str(tmp_path), job, resume=True)
    with pytest.raises(RequestError, match=r"another job .*shard_size: was 10, now 20"):
        write_manifest(str(tmp_path), {**job, 'shard_size': 20}, resume=True)
    assert json.loads((tmp_path / 'job.json').read_text()) == job


@pytest.mark.parametrize('args, words', [
    (['--workers', '0'], '--workers: must be 1 to 1024'), (['--workers', '2000'], '--workers: must be 1 to 1024'),
    (['--shard-size', '0'], '--shard-size: must be 1 to 100000'),
    (['--sample-period', '0'], '--sample-period: must be 0.0001 to 1 s'),
    (['--time-limit', 'nan'], '--time-limit: must be 0.001 to 3600 s'), (['--workers', 'two'], 'expected an integer'),
    (['--scene', 'a=x', '--scene', 'a=y'], "scene 'a' given twice"),
])
def test_every_numeric_option_is_bounded(args: list[str], words: str, tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main([str(tmp_path / 'r.jsonl'), '-o', str(tmp_path / 'o'), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith('ERROR: ') and words in err and err.count('\n') == 1, err


def test_bad_input_is_one_error_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main([str(tmp_path / 'missing.jsonl'), '-o', str(tmp_path / 'o')]) == 1
    from geodesic_planner.core.errors import quoted
    # the path as every message quotes a user's string (cut at 80 characters: pytest's tmp_path is long on CI)
    assert capsys.readouterr().err == f"ERROR: cannot read {quoted(tmp_path / 'missing.jsonl')}: no such file\n"
    (tmp_path / 'r.txt').write_text('{}\n')
    assert cli.main([str(tmp_path / 'r.txt'), '-o', str(tmp_path / 'o')]) == 1
    assert 'give --format jsonl or parquet' in capsys.readouterr().err


def test_progress_plain_lines_when_not_a_terminal() -> None:
    out = io.StringIO()
    progress = cli.Progress(out, tty=False)
    progress(10, 100, 10)           # printed (the first), then at most every PLAIN_EVERY s
    progress(60, 100, 60)
    assert out.getvalue() == 'batch: 10/100 (10 %), 0.0 requests/s, ETA ?\n'
    assert re.fullmatch(r'batch: 60/100 \(60 %\), [0-9.]+ requests/s, ETA \d+s', progress.line())
    tty = io.StringIO()
    bar = cli.Progress(tty, tty=True)
    bar(5, 10, 5)
    assert tty.getvalue().startswith('\r[###############...............] 5/10 (50 %)')
