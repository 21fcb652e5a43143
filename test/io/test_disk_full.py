"""Bags on a full disk (issue 13): counts are what the storage file holds, failures are reported.

A tmpfs of 256 KiB is filled up while recording (scripts/test.sh runs the suite as root in a
private mount namespace; without one these tests are skipped with the reason). The oracle is an
independent reading of the bag (rosbags via ``bag_info``, ``metadata.yaml``, ``repair`` of a copy),
never the recorder's own numbers.
"""
from __future__ import annotations

import shutil

import pytest
import yaml

from bag_util import JS, joint_state, tmpfs
from geodesic_planner.core.errors import BagError
from geodesic_planner.io.bags import JOINT_STATE, STORAGES, BagRecorder, bag_info, new_bag_path, repair, to_cdr


def _meta_counts(bag):
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    topics = {x['topic_metadata']['name']: x['message_count'] for x in meta['topics_with_message_count']}
    return meta['message_count'], topics


def _write_until_failing(rec, data, limit=20_000):
    """Write until the storage refuses (raised or reported); returns (attempts, raised)."""
    raised = 0
    for k in range(limit):
        try:
            rec.write(JS, 1_000 + k, data)
            if k % 50 == 49:
                rec.flush()  # at most 50 messages (10 KB) per flush: what is held back stays small
        except BagError:
            raised += 1
        if rec.failures and k % 100 == 99:
            return k + 1, raised
    pytest.fail(f'the {limit} writes never filled the file system')


@pytest.mark.parametrize('storage', STORAGES)
def test_disk_full_then_space_again_counts_what_is_on_disk(tmp_path, ts, storage):
    errors: list[str] = []
    data = to_cdr(joint_state(1), JOINT_STATE, ts)
    with tmpfs(tmp_path / 'fs') as fs:
        filler = fs / 'filler'
        filler.write_bytes(b'\0' * 64 * 1024)  # removed later: space comes back
        rec = BagRecorder(fs / 'bag', storage=storage, topics={JS: JOINT_STATE}, typestore=ts,
                          flush_period=0.01, on_error=errors.append)
        rec.open()
        attempts, raised = _write_until_failing(rec, data)
        assert rec.failures == raised + len(errors)   # every failure raised or reported
        assert rec.failures >= 1
        filler.unlink()
        rec.flush()  # what the flush thread does every half period: the retry now succeeds
        more = 20
        for k in range(more):  # space again: written after the retried flush
            rec.write(JS, 10**9 + k, data)
        rec.close()
        written, lost = rec.counts[JS], rec.lost.get(JS, 0)
        assert written + lost == attempts + more
        # independent readings agree with the recorder's counts
        info = bag_info(fs / 'bag')
        assert {t.name: t.count for t in info.topics} == {JS: written}
        assert _meta_counts(fs / 'bag') == (written, {JS: written})
        assert sum(1 for s in (t.last_ns for t in info.topics) if s is not None and s >= 10**9) == 1


@pytest.mark.parametrize('storage', STORAGES)
def test_disk_still_full_at_close_counts_what_is_on_disk(tmp_path, ts, storage):
    data = to_cdr(joint_state(2), JOINT_STATE, ts)
    with tmpfs(tmp_path / 'fs') as fs:
        rec = BagRecorder(fs / 'bag', storage=storage, topics={JS: JOINT_STATE}, typestore=ts,
                          flush_period=0.01, on_error=lambda _: None)
        rec.open()
        attempts, _ = _write_until_failing(rec, data)
        try:
            rec.close()  # SQLite may still find room for its metadata once the rows were rolled back
        except BagError as err:
            assert 'cannot finish bag' in str(err) and 'geodesic-bag repair' in str(err)
        written = rec.counts[JS]
        assert written + rec.lost.get(JS, 0) == attempts
        assert written > 0
        copy = tmp_path / 'copy'
        shutil.copytree(fs / 'bag', copy)
    report = repair(copy)
    assert report.messages == {JS: written}


def test_empty_mount_point_as_bag_path(tmp_path, ts):
    with tmpfs(tmp_path / 'mnt') as mnt:
        with pytest.raises(BagError, match=r'cannot record into the empty directory .*mnt: it is a mount point'):
            BagRecorder(mnt, topics={JS: JOINT_STATE}).open()
        path = new_bag_path(mnt, prefix='proc')  # what the processor does: a new bag inside it
        assert path.parent == mnt and path.name.startswith('proc_')
        with BagRecorder(path, topics={JS: JOINT_STATE}, typestore=ts) as rec:
            rec.write(JS, 5, to_cdr(joint_state(0), JOINT_STATE, ts))
        assert bag_info(path).message_count == 1
