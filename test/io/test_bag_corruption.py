"""Bag tools against undecodable records and corrupt storage files (issue 13, item 7).

``geodesic-bag info/plot/repair`` report and skip records that do not decode, and never let an
exception out on a damaged bag: either they read what is there (exit 0) or they print one line
``ERROR: ...`` (exit 1). A property test corrupts bag files at random (hypothesis).
"""
from __future__ import annotations

import atexit
import contextlib
import io
import shutil
import sqlite3
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rosbags.rosbag2 import Reader

from bag_util import IN, OUT, JS, example, joint_state, trajectory
from geodesic_planner.cli import bag as bag_cli
from geodesic_planner.io.bags import (JOINT_STATE, JOINT_TRAJECTORY, STORAGES, BagRecorder, UndecodableRecord,
                                      bag_info, make_typestore, read_trajectories, to_cdr)

GARBAGE = b'\x00\x01\x00\x00\xff\xff\xff\x7fnot a trajectory'


def make_bag(path: Path, storage: str, *, garbage: bool = True, custom_data: dict[str, str] | None = None) -> Path:
    """A bag: input, garbage on the input topic (optional), output, a joint state."""
    ts = make_typestore()
    t, q, dq, ddq = example(np.random.default_rng(3), 4)
    with BagRecorder(path, storage=storage, typestore=ts, custom_data=custom_data,
                     topics={IN: JOINT_TRAJECTORY, OUT: JOINT_TRAJECTORY, JS: JOINT_STATE}) as rec:
        rec.write(IN, 100, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        if garbage:
            rec.write(IN, 150, GARBAGE)
        rec.write(OUT, 200, to_cdr(trajectory(t * 2, q, dq / 2, ddq / 4), JOINT_TRAJECTORY, ts))
        rec.write(JS, 250, to_cdr(joint_state(1), JOINT_STATE, ts))
    return path


def run_cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = bag_cli.main(list(args))
    return rc, out.getvalue(), err.getvalue()


def assert_one_error_line(rc: int, err: str) -> None:
    if rc == 1:
        assert err.startswith('ERROR: ') and err.count('\n') == 1, err
    assert 'Traceback' not in err


def assert_counts_as_stored(bag: Path) -> dict[str, int]:
    """rosbags reads the bag, and metadata.yaml's counts are the messages the storage holds."""
    with Reader(bag) as reader:
        stored = Counter(conn.id for conn, _, _ in reader.messages())
        for conn in reader.connections:
            assert conn.msgcount == stored[conn.id], (conn.topic, conn.msgcount, stored[conn.id])
        assert reader.message_count == sum(stored.values())
        return {c.topic: c.msgcount for c in reader.connections}


def check_info_and_repair(bag: Path) -> None:
    """info and repair: exit 0 with a message, or one ERROR line (exit 1); a bag that repair wrote
    (exit 0, or 1 naming what the damage cost) reads afterwards, with rosbags too, and its
    metadata counts what the storage file holds."""
    rc, _, err = run_cli('info', str(bag))
    assert rc in (0, 1), err
    assert_one_error_line(rc, err)
    rc, out, err = run_cli('repair', str(bag))
    assert rc in (0, 1), err
    assert_one_error_line(rc, err)
    assert out if rc == 0 else err
    if rc == 0 or out.startswith('repaired'):
        rc, _, err = run_cli('info', str(bag))
        assert rc == 0, (out, err)
        assert_counts_as_stored(bag)


@pytest.mark.parametrize('storage', STORAGES)
def test_undecodable_record_reported_and_skipped(tmp_path, storage):
    bag = make_bag(tmp_path / 'bag', storage)
    info = bag_info(bag)
    assert {t.name: t.count for t in info.topics} == {IN: 2, OUT: 1, JS: 1}  # the record is there
    assert [(s.topic, s.points) for s in info.trajectories] == [(IN, 4), (OUT, 4)]
    (bad,) = info.undecodable
    assert isinstance(bad, UndecodableRecord)
    assert (bad.topic, bad.msgtype, bad.stamp_ns, bad.size) == (IN, JOINT_TRAJECTORY, 150, len(GARBAGE))
    skipped: list[UndecodableRecord] = []
    assert [r.stamp_ns for r in read_trajectories(bag, skipped=skipped)] == [100, 200]
    assert skipped == [bad]
    assert [r.stamp_ns for r in read_trajectories(bag)] == [100, 200]  # skipped without a list too

    rc, out, err = run_cli('info', str(bag))
    assert rc == 0, err
    assert 'undecodable records: 1 (skipped)' in out and f'{IN} at 150 ns ({len(GARBAGE)} bytes' in out
    rc, out, err = run_cli('plot', str(bag), '-o', str(tmp_path / 'png'))
    assert rc == 0, err
    assert out.split() == [str(tmp_path / 'png' / 'trajectory_00.png')]   # the good pair
    assert err.startswith('skipped 1 undecodable record(s):') and f'{IN} at 150 ns' in err
    rc, out, err = run_cli('repair', str(bag))
    assert (rc, err) == (0, '') and out.startswith('unchanged')


def test_plot_with_only_undecodable_trajectories_says_so(tmp_path):
    ts = make_typestore()
    with BagRecorder(tmp_path / 'bag', typestore=ts, topics={IN: JOINT_TRAJECTORY}) as rec:
        rec.write(IN, 1, GARBAGE)
    rc, _, err = run_cli('plot', str(tmp_path / 'bag'), '-o', str(tmp_path / 'png'))
    assert rc == 1
    assert err == (f'ERROR: no trajectory_msgs/msg/JointTrajectory messages in {tmp_path / "bag"} '
                   '(1 undecodable record(s) skipped)\n')


def _truncate(db: Path) -> None:
    data = db.read_bytes()
    db.write_bytes(data[:len(data) // 2])


def _garbage(db: Path) -> None:
    db.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, db.stat().st_size, dtype=np.uint8)))


def _header_only(db: Path) -> None:
    db.write_bytes(db.read_bytes()[:100])


def _drop(table: str):
    def corrupt(db: Path) -> None:
        with contextlib.closing(sqlite3.connect(db)) as conn:
            conn.execute(f'DROP TABLE {table}')
            conn.commit()
    return corrupt


def _bad_values(db: Path) -> None:
    with contextlib.closing(sqlite3.connect(db)) as conn:
        conn.execute("UPDATE messages SET data = 'text', timestamp = -5 WHERE id = 1")
        conn.execute("UPDATE topics SET type = 'nope_msgs/msg/Nope' WHERE name = ?", (JS,))
        conn.execute('DELETE FROM message_definitions')
        conn.commit()


@pytest.mark.parametrize('corrupt, rc_expected, message', [
    (_truncate, None, None),
    (_garbage, 1, 'file is not a database'),
    (_header_only, 1, 'cannot read SQLite storage'),
    (_drop('messages'), 1, 'no such table: messages'),
    (_drop('topics'), 1, 'no such table: topics'),
    (_drop('message_definitions'), 0, None),
    (_bad_values, 1, 'was damaged (what could be read was written)'),
])
def test_repair_of_corrupt_sqlite_bag_never_raises(tmp_path, corrupt, rc_expected, message):
    bag = make_bag(tmp_path / 'bag', 'sqlite3', garbage=False)
    (bag / 'metadata.yaml').unlink()   # as after a kill: repair has to read the database
    corrupt(bag / 'bag.db3')
    rc, out, err = run_cli('repair', str(bag))
    assert_one_error_line(rc, err)
    assert rc in (0, 1)
    if rc_expected is not None:
        assert rc == rc_expected, (out, err)
    if message is not None:
        assert message in err
    if out.startswith('repaired'):  # exit 0, or 1 naming what the damage cost
        rc_info, _, err_info = run_cli('info', str(bag))
        assert rc_info == 0, err_info
    if corrupt is _bad_values:  # the row with a text blob and the topic without a definition left out
        assert 'left out for want of a usable message definition: /joint_states' in out
        assert {t.name: t.count for t in bag_info(bag).topics} == {IN: 0, OUT: 1}  # row 1 was the input


# --------------------------------------------------------------------------- property test
_BASE: dict[str, Path] = {}


def _base_bag(storage: str) -> Path:
    """One pristine bag per storage for the whole session (copied before each corruption)."""
    if storage not in _BASE:
        tmp = tempfile.mkdtemp(prefix='gp_corrupt_')
        atexit.register(shutil.rmtree, tmp, True)
        _BASE[storage] = make_bag(Path(tmp) / 'bag', storage)
    return _BASE[storage]


corruptions = st.fixed_dictionaries({
    'storage': st.sampled_from(STORAGES),
    'writes': st.lists(st.tuples(st.floats(0.0, 1.0), st.binary(min_size=1, max_size=16)), max_size=6),
    'truncate': st.one_of(st.none(), st.floats(0.0, 1.0)),
    'append': st.binary(max_size=64),
    'metadata': st.sampled_from(['keep', 'delete', 'garble']),
})


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(corruptions)
def test_fuzz_corrupt_bags_never_raise(case):
    """Random byte overwrites, truncation, appended garbage, a missing or garbled metadata.yaml:
    info, plot and repair exit 0 or print one ERROR line (exit 1); a repaired bag reads."""
    with tempfile.TemporaryDirectory(prefix='gp_fuzz_') as tmp:
        bag = Path(tmp) / 'bag'
        shutil.copytree(_base_bag(case['storage']), bag)
        (storage_file,) = [p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3')]
        data = bytearray(storage_file.read_bytes())
        for where, chunk in case['writes']:
            at = int(where * (len(data) - 1))
            data[at:at + len(chunk)] = chunk
        if case['truncate'] is not None:
            del data[int(case['truncate'] * len(data)):]
        data += case['append']
        storage_file.write_bytes(bytes(data))
        if case['metadata'] == 'delete':
            (bag / 'metadata.yaml').unlink()
        elif case['metadata'] == 'garble':
            (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [1, {')
        rc, _, err = run_cli('plot', str(bag), '-o', str(Path(tmp) / 'png'))
        assert rc in (0, 1) and 'Traceback' not in err, err
        check_info_and_repair(bag)


# ------------------------------------------------------------- a damaged recording (issue 37)
REPRO = Path(__file__).parent.parent / 'data' / 'bags' / 'flipped_topics_table.db3'


def _table_cells(raw: bytes, page: int, size: int = 4096) -> int:
    """Rows of the SQLite table b-tree rooted at ``page`` (1-based), read from the file format."""
    p = raw[(page - 1) * size:page * size]
    cells = int.from_bytes(p[3:5], 'big')
    if p[0] == 0x0D:  # table leaf
        return cells
    assert p[0] == 0x05  # table interior: cells of (left child u32, rowid varint), right-most child
    kids = [int.from_bytes(p[8:12], 'big')]
    for k in range(cells):
        at = int.from_bytes(p[12 + 2 * k:14 + 2 * k], 'big')
        kids.append(int.from_bytes(p[at:at + 4], 'big'))
    return sum(_table_cells(raw, kid, size) for kid in kids)


def test_repair_of_flipped_table_definitions(tmp_path):
    """A killed SQLite recording with bytes flipped on page 1 (the CREATE TABLE statements of
    metadata, topics, message_definitions and messages, and a cell pointer) and in the topic's
    name: SQLite refuses every query (its error message is not even UTF-8). repair rebuilds the
    definitions, writes the messages, names the damage, exits 1."""
    bag = tmp_path / 'bag'
    bag.mkdir()
    shutil.copyfile(REPRO, bag / REPRO.name)
    raw = REPRO.read_bytes()
    rc, out, err = run_cli('repair', str(bag))
    assert rc == 1, (out, err)
    assert_one_error_line(rc, err)
    assert 'the table definitions (page 1) were damaged (malformed database schema (metadata)' in err
    assert "topic 1: name '/g\\x16odesic_planner/joint_trajectory' is damaged" in err
    assert out.startswith(f'repaired: {bag} (sqlite3)')
    assert assert_counts_as_stored(bag) == {'/g\x16odesic_planner/joint_trajectory': 4}
    # independently of SQLite: the messages table's b-tree (root page 6, as sqlite_master's row 5
    # in the file says) holds 4 rows, and each recovered payload is in the file
    assert _table_cells(raw, 6) == 4
    with Reader(bag) as reader:
        payloads = [(stamp, data) for _, stamp, data in reader.messages()]
    assert [s for s, _ in payloads] == sorted(s for s, _ in payloads)
    assert all(len(d) > 100 and bytes(d) in raw for _, d in payloads)
    assert (bag / f'{REPRO.name}.damaged').read_bytes() == raw  # the original kept as it was
    rc, out, _ = run_cli('info', str(bag))
    assert rc == 0 and '4 msgs' in out
