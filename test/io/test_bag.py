"""Bag recording, reading, info, repair and the geodesic-bag CLI (rosbags only, no rclpy)."""
from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from datetime import datetime, timezone
from pathlib import Path
from types import SimpleNamespace as NS

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader

from geodesic_planner.cli import bag as bag_cli
from geodesic_planner.io.bags import (
    JOINT_STATE,
    JOINT_TRAJECTORY,
    STORAGES,
    BagRecorder,
    bag_info,
    from_cdr,
    make_typestore,
    new_bag_path,
    qos_profile,
    read_trajectories,
    repair,
    to_cdr,
)
from geodesic_planner.core.errors import BagError

IN, OUT, JS = '/geodesic_planner/joint_trajectory', '/trajectory_processor/joint_trajectory', '/joint_states'


def _duration(t: float) -> NS:
    ns = int(round(t * 1e9))
    return NS(sec=ns // 10**9, nanosec=ns % 10**9)


def trajectory(t, q, dq=None, ddq=None, names=('j1', 'j2', 'j3'), frame_id='base', stamp=(0, 0)):
    """A JointTrajectory as a plain object with the message's attributes (like an rclpy message)."""
    points = [NS(positions=list(q[i]), velocities=[] if dq is None else list(dq[i]),
                 accelerations=[] if ddq is None else list(ddq[i]), effort=[],
                 time_from_start=_duration(ti)) for i, ti in enumerate(t)]
    return NS(header=NS(stamp=NS(sec=stamp[0], nanosec=stamp[1]), frame_id=frame_id),
              joint_names=list(names), points=points)


def joint_state(i: int) -> NS:
    return NS(header=NS(stamp=NS(sec=i, nanosec=0), frame_id=''), name=['j1', 'j2', 'j3'],
              position=[0.1 * i, 0.2, 0.3], velocity=[], effort=[])


def _example(rng: np.random.Generator, n: int):
    t = np.cumsum(rng.uniform(0.1, 0.5, n)) - 0.1
    t[0] = 0.0
    return t, rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3))


@pytest.fixture
def ts():
    return make_typestore()


@pytest.mark.parametrize('storage', STORAGES)
def test_roundtrip_arrays_types_and_qos(tmp_path, ts, storage):
    rng = np.random.default_rng(0)
    examples = [_example(rng, n) for n in (3, 7)]
    path = tmp_path / 'bag'
    qos = qos_profile(reliability='reliable', durability='transient_local', depth=5)
    with BagRecorder(path, storage=storage, topics={IN: JOINT_TRAJECTORY, JS: JOINT_STATE},
                     qos={IN: qos}) as rec:
        for k, (t, q, dq, ddq) in enumerate(examples):
            rec.write(IN, 1_000 + k, to_cdr(trajectory(t, q, dq, ddq, stamp=(5, 7)), JOINT_TRAJECTORY, ts))
            rec.write(JS, 1_500 + k, to_cdr(joint_state(k), JOINT_STATE, ts))
        assert rec.counts == {IN: 2, JS: 2}

    records = read_trajectories(path)
    assert [r.stamp_ns for r in records] == [1_000, 1_001]
    for rec_, (t, q, dq, ddq) in zip(records, examples):
        assert rec_.topic == IN
        assert rec_.joint_names == ['j1', 'j2', 'j3']
        assert_allclose(rec_.t, t, atol=1e-9)  # time_from_start is stored in ns
        assert_array_equal(rec_.positions, q)
        assert_array_equal(rec_.velocities, dq)
        assert_array_equal(rec_.accelerations, ddq)
        assert rec_.header_stamp_ns == 5 * 10**9 + 7
        assert rec_.frame_id == 'base'
        assert rec_.problems == ()

    # plain rosbags reads the bag; types carry the Jazzy type hashes; QoS metadata as given
    with Reader(path) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert conns[IN].msgtype == JOINT_TRAJECTORY
        assert conns[JS].msgtype == JOINT_STATE
        assert conns[IN].digest == ts.hash_rihs01(JOINT_TRAJECTORY)
        assert conns[IN].ext.offered_qos_profiles[0].depth == 5
        assert conns[IN].ext.offered_qos_profiles[0].durability.name == 'TRANSIENT_LOCAL'
        assert conns[JS].ext.offered_qos_profiles[0].reliability.name == 'RELIABLE'
        assert reader.message_count == 4
    meta = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['storage_identifier'] == storage
    assert meta['version'] == 9
    counts = {x['topic_metadata']['name']: x['message_count'] for x in meta['topics_with_message_count']}
    assert counts == {IN: 2, JS: 2}


def test_to_cdr_matches_rosbags_serialisation(ts):
    rng = np.random.default_rng(1)
    t, q, dq, _ = _example(rng, 4)
    duck = trajectory(t, q, dq, None)
    data = to_cdr(duck, JOINT_TRAJECTORY, ts)
    msg = from_cdr(data, JOINT_TRAJECTORY, ts)
    assert bytes(ts.serialize_cdr(msg, JOINT_TRAJECTORY)) == data  # a fixed point: exact bytes
    assert list(msg.joint_names) == ['j1', 'j2', 'j3']
    assert_array_equal(msg.points[2].velocities, dq[2])
    assert msg.points[2].accelerations.size == 0
    assert to_cdr(msg, JOINT_TRAJECTORY, ts) == data  # rosbags objects work as input too


def test_cdr_errors_are_bag_errors(ts):
    with pytest.raises(BagError, match='unknown message type'):
        to_cdr(joint_state(0), 'nope_msgs/msg/Nope', ts)
    with pytest.raises(BagError, match='cannot serialise'):
        to_cdr(NS(header=None), JOINT_STATE, ts)
    data = to_cdr(joint_state(0), JOINT_STATE, ts)
    with pytest.raises(BagError, match='invalid sensor_msgs/msg/JointState CDR'):
        from_cdr(data + b'\0' * 16, JOINT_STATE, ts)


def test_invalid_trajectory_recorded_with_problems(tmp_path, ts):
    t = np.array([0.0, 1.0, 1.0])
    q = np.zeros((3, 3))
    bad = trajectory(t, q)
    bad.points[1].positions = [0.0, 1.0]
    bad.points[2].positions = [0.0, float('nan'), 0.0]
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY}) as rec:
        rec.write(IN, 1, to_cdr(bad, JOINT_TRAJECTORY, ts))
    (r,) = read_trajectories(tmp_path / 'b')
    assert 'point 1: 2 positions for 3 joints' in r.problems
    assert 'point 2: non-finite positions' in r.problems
    assert any('not after' in p for p in r.problems)
    assert np.isnan(r.positions[1]).all()
    assert r.velocities is None


def test_recorder_errors(tmp_path, ts):
    with pytest.raises(BagError, match='unknown storage'):
        BagRecorder(tmp_path / 'x', storage='rosbag1')
    with pytest.raises(BagError, match='flush_period'):
        BagRecorder(tmp_path / 'x', flush_period=0.0)
    occupied = tmp_path / 'occupied'
    occupied.mkdir()
    (occupied / 'keep.txt').write_text('data')
    with pytest.raises(BagError, match='bag directory exists'):
        BagRecorder(occupied).open()
    assert (occupied / 'keep.txt').read_text() == 'data'
    with pytest.raises(BagError, match="unknown message type 'foo/msg/Bar' for topic /x"):
        BagRecorder(tmp_path / 'y', topics={'/x': 'foo/msg/Bar'}).open()

    rec = BagRecorder(tmp_path / 'z', topics={JS: JOINT_STATE})
    with pytest.raises(BagError, match='is not open'):
        rec.write(JS, 1, b'')
    rec.open()
    with pytest.raises(BagError, match=r'topic /other is not recorded .*recorded: /joint_states'):
        rec.write('/other', 1, b'')
    with pytest.raises(BagError, match='negative timestamp'):
        rec.write(JS, -1, to_cdr(joint_state(0), JOINT_STATE, ts))
    with pytest.raises(BagError, match='already recorded as'):
        rec.add_topic(JS, JOINT_TRAJECTORY)
    rec.close()
    rec.close()  # idempotent
    with pytest.raises(BagError, match='is closed'):
        rec.write(JS, 1, b'')
    with pytest.raises(BagError, match='already opened'):
        rec.open()
    assert (tmp_path / 'z' / 'metadata.yaml').exists()


def test_custom_data_in_metadata(tmp_path, ts):
    with BagRecorder(tmp_path / 'b', topics={JS: JOINT_STATE}, custom_data={'velocity_scaling': '0.5'}):
        pass
    info = bag_info(tmp_path / 'b')
    assert info.custom_data == {'velocity_scaling': '0.5'}
    assert 'custom data: velocity_scaling=0.5' in bag_cli.format_info(info)
    with pytest.raises(BagError, match='custom_data'):
        BagRecorder(tmp_path / 'c', custom_data={'x': 0.5})


def test_empty_directory_is_used_and_exception_still_closes(tmp_path, ts):
    empty = tmp_path / 'empty'
    empty.mkdir()
    with pytest.raises(RuntimeError), BagRecorder(empty, topics={JS: JOINT_STATE}) as rec:
        rec.write(JS, 10, to_cdr(joint_state(1), JOINT_STATE, ts))
        raise RuntimeError('boom')
    info = bag_info(empty)
    assert info.message_count == 1
    assert info.topics[0].count == 1


def test_new_bag_path(tmp_path):
    now = datetime(2026, 1, 2, 3, 4, 5, tzinfo=timezone.utc)
    assert new_bag_path(tmp_path / 'new', now=now) == tmp_path / 'new'
    (tmp_path / 'empty').mkdir()
    assert new_bag_path(tmp_path / 'empty', now=now) == tmp_path / 'empty'
    with BagRecorder(tmp_path / 'bag'):
        pass
    assert new_bag_path(tmp_path / 'bag', now=now) == tmp_path / 'bag_20260102T030405Z'
    (tmp_path / 'bag_20260102T030405Z').mkdir()
    assert new_bag_path(tmp_path / 'bag', now=now) == tmp_path / 'bag_20260102T030405Z_2'
    (tmp_path / 'runs').mkdir()
    (tmp_path / 'runs' / 'notes.txt').write_text('x')
    assert new_bag_path(tmp_path / 'runs', prefix='proc', now=now) == tmp_path / 'runs' / 'proc_20260102T030405Z'
    with pytest.raises(BagError, match='existing file'):
        new_bag_path(tmp_path / 'runs' / 'notes.txt')


def test_read_errors(tmp_path, ts):
    with pytest.raises(BagError, match='no such bag'):
        read_trajectories(tmp_path / 'missing')
    (tmp_path / 'plain').mkdir()
    with pytest.raises(BagError, match='not a bag'):
        bag_info(tmp_path / 'plain')
    with BagRecorder(tmp_path / 'b', topics={JS: JOINT_STATE}) as rec:
        rec.write(JS, 1, to_cdr(joint_state(0), JOINT_STATE, ts))
    with pytest.raises(BagError, match='topic /nope not in bag'):
        read_trajectories(tmp_path / 'b', topic='/nope')
    with pytest.raises(BagError, match='not a trajectory_msgs/msg/JointTrajectory topic'):
        read_trajectories(tmp_path / 'b', topic=JS)
    assert read_trajectories(tmp_path / 'b') == []
    (tmp_path / 'b' / 'metadata.yaml').unlink()
    with pytest.raises(BagError, match='interrupted; run `geodesic-bag repair'):
        read_trajectories(tmp_path / 'b')


def test_bag_info_summary(tmp_path, ts):
    rng = np.random.default_rng(5)
    t, q, dq, ddq = _example(rng, 6)
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY, JS: JOINT_STATE}) as rec:
        for i in range(4):
            rec.write(JS, 2_000_000_000 + i * 100_000_000, to_cdr(joint_state(i), JOINT_STATE, ts))
        rec.write(IN, 2_050_000_000, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        rec.write(IN, 2_060_000_000, to_cdr(trajectory(t, q), JOINT_TRAJECTORY, ts))
    info = bag_info(tmp_path / 'b')
    assert info.storage == 'mcap'
    assert info.message_count == 6
    assert info.duration == pytest.approx(0.3)
    topics = {x.name: x for x in info.topics}
    assert topics[JS].count == 4
    assert topics[JS].duration == pytest.approx(0.3)
    assert topics[IN].count == 2
    s0, s1 = info.trajectories
    assert (s0.points, s0.dof, s0.index, s1.index) == (6, 3, 0, 1)
    assert s0.duration == pytest.approx(t[-1] - t[0], abs=1e-9)
    assert s0.peak_velocity == np.abs(dq).max()
    assert s0.peak_acceleration == np.abs(ddq).max()
    assert np.isnan(s1.peak_velocity)
    text = bag_cli.format_info(info)
    assert f'{IN} #0 at +0.050 s: 6 points, 3 joints' in text
    assert f'peak |v| {np.abs(dq).max():.4g}' in text


# ---------------------------------------------------------------------------------- crash safety
def _copy_as_killed(src: Path, dst: Path) -> None:
    """What a SIGKILL leaves: the files as they are now, no close(), no metadata.yaml."""
    shutil.copytree(src, dst)
    assert not (dst / 'metadata.yaml').exists()


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
    _copy_as_killed(rec.path, tmp_path / 'killed')
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


# ---------------------------------------------------------------------------------- CLI
def test_cli_info_plot_repair(tmp_path, ts, capsys):
    rng = np.random.default_rng(2)
    t, q, dq, ddq = _example(rng, 5)
    with BagRecorder(tmp_path / 'b', topics={IN: JOINT_TRAJECTORY, OUT: JOINT_TRAJECTORY}) as rec:
        rec.write(IN, 100, to_cdr(trajectory(t, q, dq, ddq), JOINT_TRAJECTORY, ts))
        rec.write(OUT, 200, to_cdr(trajectory(t * 2, q, dq / 2, ddq / 4), JOINT_TRAJECTORY, ts))
        rec.write(IN, 300, to_cdr(trajectory(t, q[:, :2], names=('a', 'a')), JOINT_TRAJECTORY, ts))
    assert bag_cli.main(['info', str(tmp_path / 'b')]) == 0
    out = capsys.readouterr().out
    assert re.search(rf'{IN}\s+trajectory_msgs/msg/JointTrajectory\s+2 msgs', out)
    assert 'INVALID: duplicate joint names' in out
    assert bag_cli.main(['plot', str(tmp_path / 'b'), '--output', str(tmp_path / 'png')]) == 0
    files = sorted((tmp_path / 'png').glob('*.png'))
    assert [f.name for f in files] == ['trajectory_00.png', 'trajectory_01.png']  # (in, out) + lone invalid in
    assert all(f.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n' for f in files)
    assert bag_cli.main(['repair', str(tmp_path / 'b')]) == 0
    assert 'unchanged' in capsys.readouterr().out


@pytest.mark.parametrize('args, message', [
    (['info', '/nonexistent/bag'], 'ERROR: no such bag: /nonexistent/bag'),
    (['plot', '/nonexistent/bag', '-o', '/tmp/x'], 'ERROR: no such bag'),
    (['repair', '/nonexistent/bag'], 'ERROR: no such bag directory'),
])
def test_cli_errors_one_line(args, message, capsys):
    assert bag_cli.main(args) == 1
    err = capsys.readouterr().err
    assert err.startswith(message)
    assert err.count('\n') == 1 and 'Traceback' not in err


def test_cli_plot_without_trajectories(tmp_path, ts, capsys):
    with BagRecorder(tmp_path / 'b', topics={JS: JOINT_STATE}) as rec:
        rec.write(JS, 1, to_cdr(joint_state(0), JOINT_STATE, ts))
    assert bag_cli.main(['plot', str(tmp_path / 'b'), '-o', str(tmp_path / 'png')]) == 1
    assert 'ERROR: no trajectory_msgs/msg/JointTrajectory messages' in capsys.readouterr().err


def test_pair_trajectories_matches_latest_earlier_input():
    def rec(topic, stamp):
        return NS(topic=topic, stamp_ns=stamp)
    ins = [rec(IN, 10), rec(IN, 20), rec(IN, 30)]  # the one at 20 was rejected (no output)
    outs = [rec(OUT, 15), rec(OUT, 35)]
    pairs = bag_cli.pair_trajectories(ins, outs)
    assert [(a.stamp_ns if a else None, b.stamp_ns if b else None) for a, b in pairs] == [
        (10, 15), (20, None), (30, 35)]


# ---------------------------------------------------------------------------------- msg_examples
EXAMPLES = Path(__file__).resolve().parents[2] / 'msg_examples'


def _yaml_trajectory(path: Path):
    data = yaml.safe_load(path.read_text())
    pts = data['points']
    t = np.array([p['time_from_start']['sec'] + p['time_from_start']['nanosec'] * 1e-9 for p in pts])
    arrays = [np.array([p[k] for p in pts], dtype=float) for k in ('positions', 'velocities', 'accelerations')]
    return data['joint_names'], t, *arrays


def _fk_3r(q):
    c = np.cumsum(q, axis=1)
    return np.stack([np.cos(c).sum(1), np.sin(c).sum(1), c[:, 2]], axis=1)


def test_yaml_examples_are_the_paper_trajectory_before_and_after_scaling():
    names, t, q, dq, ddq = _yaml_trajectory(EXAMPLES / 'joint_trajectory.yaml')
    names2, t2, q2, dq2, ddq2 = _yaml_trajectory(EXAMPLES / 'joint_trajectory_processed.yaml')
    assert names == names2 == ['joint1', 'joint2', 'joint3']
    assert np.all(np.diff(t) > 0) and t[0] == 0.0
    assert_allclose(dq[[0, -1]], 0.0, atol=1e-9)
    assert_allclose(ddq[[0, -1]], 0.0, atol=1e-9)
    # paper example: tool on the straight line A -> B with phi linear along it (exact oracle)
    a, b = np.array([2.5, 1.5, np.radians(30)]), np.array([1.5, 2.5, np.arctan2(0.7, 0.714)])
    xyphi = _fk_3r(q)
    lam = (xyphi[:, :2] - a[:2]) @ (b - a)[:2] / np.sum((b - a)[:2] ** 2)
    assert_allclose(xyphi, a + lam[:, None] * (b - a), atol=1e-5)
    assert_allclose(lam[[0, -1]], [0.0, 1.0], atol=1e-5)
    # processed at f = 0.5: twice as long, point k at 0.5 k s is the original at 0.25 k s
    assert t2[-1] == pytest.approx(2 * t[-1], abs=2e-9)
    n = min(len(t), len(t2)) - 1
    assert_allclose(t2[:n], 2 * t[:n], atol=1e-9)
    assert_allclose(q2[:n], q[:n], atol=2e-9)
    assert_allclose(dq2[:n], 0.5 * dq[:n], atol=2e-9)
    assert_allclose(ddq2[:n], 0.25 * ddq[:n], atol=2e-9)


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
    _copy_as_killed(live.path, tmp_path / 'killed')
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
