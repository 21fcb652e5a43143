"""Crash safety: flushed data survives a kill and repair (io.bags.repair) recovers it."""
from __future__ import annotations

import os
import sqlite3
from contextlib import closing
import signal
import subprocess
import sys
import textwrap
import time
from types import SimpleNamespace

import numpy as np
import pytest
from rosbags.highlevel import AnyReader, AnyReaderError

from bag_util import IN, JS, copy_as_killed, joint_state, trajectory
from geodesic_planner.io.bags import (
    JOINT_STATE,
    JOINT_TRAJECTORY,
    STORAGES,
    BagRecorder,
    bag_info,
    read_trajectories,
    repair,
    to_cdr,
)


@pytest.mark.parametrize('storage', STORAGES)
def test_flushed_messages_survive_a_kill(tmp_path, ts, storage):
    rec = BagRecorder(tmp_path / 'live', storage=storage, topics={JS: JOINT_STATE, IN: JOINT_TRAJECTORY},
                      flush_period=None)
    rec.open()
    for i in range(30):
        rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    rec.write(IN, 2000, to_cdr(trajectory([0.0, 1.0], np.zeros((2, 3))), JOINT_TRAJECTORY, ts))
    rec.flush()
    for i in range(30, 35):  # written but never flushed: lost in a kill
        rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    copy_as_killed(rec.path, tmp_path / 'killed')
    rec.close()

    report = repair(tmp_path / 'killed')
    assert report.repaired
    assert report.messages == {JS: 30, IN: 1}
    assert report.damaged_file is not None and report.damaged_file.exists()
    with AnyReader([tmp_path / 'killed']) as reader:
        got = [reader.deserialize(d, c.msgtype) for c, _, d in reader.messages()
               if c.topic == JS]
        assert [m.position[0] for m in got] == pytest.approx([0.1 * i for i in range(30)])
        qos = {c.topic: c.ext.offered_qos_profiles for c in reader.connections}
        assert qos[JS][0].reliability.name == 'RELIABLE'  # QoS metadata recovered
    assert len(read_trajectories(tmp_path / 'killed')) == 1
    # the live bag was closed normally: all 35 + 1 messages, and repair leaves it alone
    assert bag_info(tmp_path / 'live').message_count == 36
    again = repair(tmp_path / 'live')
    assert not again.repaired
    assert again.messages == {JS: 35, IN: 1}


CHILD = textwrap.dedent('''
    import sys, time
    from types import SimpleNamespace as NS
    from geodesic_planner.io.bags import BagRecorder, JOINT_STATE, make_typestore, to_cdr
    ts = make_typestore()
    with BagRecorder(sys.argv[1], storage=sys.argv[2], topics={'/joint_states': JOINT_STATE},
                     flush_period=0.5) as rec:
        i = 0
        while True:
            now = time.time_ns()
            msg = NS(header=NS(stamp=NS(sec=0, nanosec=0), frame_id=str(i)), name=['a'],
                     position=[float(i)], velocity=[], effort=[])
            rec.write('/joint_states', now, to_cdr(msg, JOINT_STATE, ts))
            print(i, now, flush=True)
            i += 1
            time.sleep(0.002)
''')


@pytest.mark.parametrize('storage', STORAGES)
def test_sigkill_loses_at_most_the_last_second(tmp_path, storage):
    """A recorder process killed with SIGKILL: repair recovers every message older than 1 s."""
    script = tmp_path / 'child.py'
    script.write_text(CHILD)
    bag = tmp_path / 'bag'
    proc = subprocess.Popen([sys.executable, str(script), str(bag), storage], stdout=subprocess.PIPE, text=True)
    written: list[tuple[int, int]] = []
    deadline = time.monotonic() + 60
    try:
        assert proc.stdout is not None
        for line in proc.stdout:  # wait until 1.5 s of messages were written
            i, stamp = map(int, line.split())
            written.append((i, stamp))
            if stamp - written[0][1] > 1.5e9 or time.monotonic() > deadline:
                break
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    assert written[-1][1] - written[0][1] > 1.5e9
    assert not (bag / 'metadata.yaml').exists()
    report = repair(bag)
    assert report.repaired
    with AnyReader([bag]) as reader:
        got = [(int(reader.deserialize(d, c.msgtype).header.frame_id), s) for c, s, d in reader.messages()]
    indices = [i for i, _ in got]
    assert indices == list(range(len(got)))  # a prefix, in order, nothing corrupted
    must_have = [i for i, s in written if s <= written[-1][1] - 1_000_000_000]
    assert len(got) > max(must_have)
    # what was recovered is exactly what the writer wrote (stamps of the reported messages)
    reported = dict(written)
    assert all(reported[i] == s for i, s in got if i in reported)


def test_independent_mcap_reader_accepts_recorded_and_repaired_bags(tmp_path, ts):
    """The reference MCAP library (what Foxglove implements) reads our files, CRCs checked."""
    mcap_reader = pytest.importorskip('mcap.reader')
    with BagRecorder(tmp_path / 'ok', topics={JS: JOINT_STATE}) as rec:
        for i in range(5):
            rec.write(JS, 100 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    live = BagRecorder(tmp_path / 'live', topics={JS: JOINT_STATE}, flush_period=None).open()
    for i in range(5):
        live.write(JS, 100 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    live.flush()
    copy_as_killed(live.path, tmp_path / 'killed')
    live.close()
    repair(tmp_path / 'killed')
    for bag in ('ok', 'killed'):
        (path,) = (tmp_path / bag).glob('*.mcap')
        with path.open('rb') as fh:
            reader = mcap_reader.make_reader(fh, validate_crcs=True)
            assert reader.get_header().profile == 'ros2'
            summary = reader.get_summary()
            assert summary.statistics.message_count == 5
            (channel,) = summary.channels.values()
            assert channel.topic == JS and 'offered_qos_profiles' in channel.metadata
            assert summary.schemas[channel.schema_id].name == JOINT_STATE
            assert [m.log_time for _, _, m in reader.iter_messages()] == [100, 101, 102, 103, 104]


def _chunked_killed_bag(tmp_path, ts, n=200, every=20):
    """A killed MCAP recording of n JointStates, flushed (one chunk) every `every` messages."""
    rec = BagRecorder(tmp_path / 'live', topics={JS: JOINT_STATE}, flush_period=None).open()
    for i in range(n):
        rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
        if i % every == every - 1:
            rec.flush()
    copy_as_killed(rec.path, tmp_path / 'killed')
    rec.close()
    (mcap_file,) = (tmp_path / 'killed').glob('*.mcap')
    return mcap_file


def _recovered_indices(bag):
    with AnyReader([bag]) as reader:
        return [round(reader.deserialize(d, c.msgtype).position[0] * 10) for c, _, d in reader.messages()]


def test_truncated_mcap_recovers_every_complete_chunk(tmp_path, ts):
    """Cut anywhere: repair keeps exactly the messages of the chunks that are complete."""
    full = _chunked_killed_bag(tmp_path, ts).read_bytes()
    rng = np.random.default_rng(3)
    for k, cut in enumerate(sorted(rng.integers(200, len(full), 12))):
        bag = tmp_path / f'cut{k}'
        bag.mkdir()
        (bag / 'cut.mcap').write_bytes(full[:cut])
        report = repair(bag)
        got = _recovered_indices(bag) if report.messages.get(JS) else []
        assert got == list(range(len(got)))  # a clean prefix
        assert len(got) % 20 == 0  # whole chunks only
        assert report.messages.get(JS, 0) == len(got)


def test_garbage_and_corrupt_chunks_never_raise(tmp_path, ts):
    mcap_file = _chunked_killed_bag(tmp_path, ts)
    data = bytearray(mcap_file.read_bytes())
    mid = len(data) // 2
    data[mid:mid + 40] = b'\xff' * 40  # inside one chunk: its CRC fails, the others survive
    mcap_file.write_bytes(bytes(data))
    report = repair(tmp_path / 'killed')
    assert report.repaired and 'corrupt chunks skipped' in report.note
    assert 0 < report.messages[JS] < 200 and report.messages[JS] % 20 == 0

    garbage = tmp_path / 'garbage'
    garbage.mkdir()
    (garbage / 'garbage.mcap').write_bytes(b'\x89MCAP0\r\n' + os.urandom(50_000))
    assert repair(garbage).messages == {}


# ------------------------------------------------------------------ what the metadata held
#: custom data as the trajectory processor writes it (ros/recording.py: BagRecording.open)
PROCESSOR_CUSTOM_DATA = {'recorded_by': 'trajectory_processor', 'input_topic': IN,
                         'output_topic': '/trajectory_processor/joint_trajectory',
                         'sample_period': '0.01', 'velocity_scaling': '0.5'}


def _metadata(bag):
    """metadata.yaml's fields (PyYAML), and the metadata and connections as rosbags reads them."""
    import yaml
    from rosbags.rosbag2 import Reader
    fields = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    with Reader(bag) as reader:
        conns = [(c.topic, c.msgtype, c.msgcount, c.digest, c.ext.offered_qos_profiles) for c in reader.connections]
        seen = SimpleNamespace(duration=reader.duration, start_time=reader.start_time, end_time=reader.end_time,
                               message_count=reader.message_count, ros_distro=reader.ros_distro,
                               custom=reader.storage.metadata.custom)
        return fields, seen, conns


@pytest.mark.parametrize('storage', STORAGES)
def test_repair_keeps_everything_the_metadata_held(tmp_path, ts, storage):
    """A killed recording, repaired: metadata.yaml equal field by field to that of the same
    recording closed normally (custom data, file name, counts, times, topics, QoS, hashes)."""
    rec = BagRecorder(tmp_path / 'live', storage=storage, topics={JS: JOINT_STATE, IN: JOINT_TRAJECTORY},
                      custom_data=PROCESSOR_CUSTOM_DATA, flush_period=None)
    rec.open()
    for i in range(10):
        rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    rec.write(IN, 2000, to_cdr(trajectory([0.0, 1.0], np.zeros((2, 3))), JOINT_TRAJECTORY, ts))
    rec.flush()
    copy_as_killed(rec.path, tmp_path / 'killed')
    rec.close()

    report = repair(tmp_path / 'killed')
    assert report.repaired
    (before, meta_before, conns_before), (after, meta_after, conns_after) = (
        _metadata(tmp_path / 'live'), _metadata(tmp_path / 'killed'))
    assert after['custom_data'] == PROCESSOR_CUSTOM_DATA
    assert set(after) == set(before)
    for key, value in before.items():
        assert after[key] == value, key
    assert meta_after == meta_before and meta_after.custom == PROCESSOR_CUSTOM_DATA
    assert conns_after == conns_before
    assert report.damage == ()  # an interrupted recording is not a damaged one
    assert bag_info(tmp_path / 'killed').custom_data == PROCESSOR_CUSTOM_DATA


def test_repair_keeps_custom_data_and_distro_of_an_old_metadata_file(tmp_path, ts):
    """A closed bag whose storage file lost its end later: its metadata.yaml still says it all."""
    import yaml
    with BagRecorder(tmp_path / 'bag', topics={JS: JOINT_STATE}) as rec:
        for i in range(5):
            rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    meta_path = tmp_path / 'bag' / 'metadata.yaml'
    meta = yaml.safe_load(meta_path.read_text())
    meta['rosbag2_bagfile_information'].update(custom_data={'operator': 'ann', 'cell': '3'}, ros_distro='jazzy')
    meta_path.write_text(yaml.safe_dump(meta))
    mcap = tmp_path / 'bag' / 'bag.mcap'
    mcap.write_bytes(mcap.read_bytes()[:-30])  # footer cut: rosbags cannot read it, repair has work to do
    with pytest.raises(AnyReaderError, match='end magic'), AnyReader([tmp_path / 'bag']) as reader:
        list(reader.messages())
    report = repair(tmp_path / 'bag')
    assert report.repaired
    after, meta, _ = _metadata(tmp_path / 'bag')
    assert after['custom_data'] == meta.custom == {'operator': 'ann', 'cell': '3'}
    assert after['ros_distro'] == meta.ros_distro == 'jazzy'
    assert after['message_count'] == meta.message_count == 5


def test_sqlite_repair_reads_past_a_damaged_messages_page(tmp_path, ts):
    """A killed SQLite recording with one leaf page of the messages table zeroed: the rows of the
    other pages are recovered, those after the damaged page too, and the damage is named."""
    rec = BagRecorder(tmp_path / 'live', storage='sqlite3', topics={JS: JOINT_STATE}, flush_period=None).open()
    for i in range(300):
        rec.write(JS, 1000 + i, to_cdr(joint_state(i), JOINT_STATE, ts))
    rec.flush()
    copy_as_killed(rec.path, tmp_path / 'killed')
    rec.close()
    (db,) = (tmp_path / 'killed').glob('*.db3')
    with closing(sqlite3.connect(db)) as con:
        size = con.execute('PRAGMA page_size').fetchone()[0]
        leaves = [p for (p,) in con.execute("SELECT pageno FROM dbstat WHERE name = 'messages' AND pagetype = 'leaf' "
                                            'ORDER BY pageno')]
    assert len(leaves) >= 4
    data = bytearray(db.read_bytes())
    page = leaves[len(leaves) // 2]
    cells = int.from_bytes(data[(page - 1) * size + 3:(page - 1) * size + 5], 'big')  # read from the format
    data[(page - 1) * size:page * size] = bytes(size)
    db.write_bytes(bytes(data))

    report = repair(tmp_path / 'killed')
    assert any(d.startswith('messages table damaged') for d in report.damage), report.damage
    got = _recovered_indices(tmp_path / 'killed')
    assert len(got) == 300 - cells, str(sorted(set(range(300)) - set(got)))
    assert got == sorted(set(got)) and set(got) <= set(range(300))
    assert got[-1] == 299  # the pages after the damaged one were read
