"""Recording (io.bags.recorder and its flushable storages): round trip, metadata, errors, paths."""
from __future__ import annotations

from datetime import datetime, UTC

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose, assert_array_equal
from rosbags.rosbag2 import Reader

from bag_util import IN, JS, example, joint_state, trajectory
from geodesic_planner.cli import bag as bag_cli
from geodesic_planner.core.errors import BagError
from geodesic_planner.io.bags import (
    JOINT_STATE,
    JOINT_TRAJECTORY,
    STORAGES,
    BagRecorder,
    bag_info,
    new_bag_path,
    qos_profile,
    read_trajectories,
    to_cdr,
)


@pytest.mark.parametrize('storage', STORAGES)
def test_roundtrip_arrays_types_and_qos(tmp_path, ts, storage):
    rng = np.random.default_rng(0)
    examples = [example(rng, n) for n in (3, 7)]
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
    now = datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC)
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
