"""``geodesic-bag info`` and ``repair`` never raise on a corrupted bag (issue 25, item 2).

Seeded and bounded: for both storage plugins, bytes flipped in the payloads, in the topic, type
and schema strings (sqlite3: the text columns set to invalid UTF-8; MCAP: inside the Schema and
Channel records), and in metadata.yaml; MCAP truncated at every record boundary. Each case either
reads (exit 0) or prints one ``ERROR:`` line (exit 1); after a repair that succeeded, info reads.
"""
from __future__ import annotations

import shutil
import sqlite3
import struct
from pathlib import Path

import numpy as np
import pytest

from test_bag_corruption import check_info_and_repair, make_bag

SEED = 25
#: MCAP opcodes of the records whose strings are flipped (Schema, Channel) and of Chunk (the messages).
SCHEMA, CHANNEL, CHUNK = 0x03, 0x04, 0x06
MAGIC = b'\x89MCAP0\r\n'


@pytest.fixture(scope='module')
def pristine(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp('fuzz_base')
    return {s: make_bag(root / s, s) for s in ('sqlite3', 'mcap')}


def copy(src: Path, dst: Path) -> tuple[Path, Path]:
    shutil.copytree(src, dst)
    (storage,) = [p for p in dst.iterdir() if p.suffix in ('.mcap', '.db3')]
    return dst, storage


# ------------------------------------------------------------------------------------- sqlite3
SQLITE_TEXT = [('topics', c) for c in ('name', 'type', 'serialization_format', 'offered_qos_profiles',
                                      'type_description_hash')] + [
    ('message_definitions', c) for c in ('topic_type', 'encoding', 'encoded_message_definition')] + [
    ('schema', 'ros_distro'), ('metadata', 'metadata')]


@pytest.mark.parametrize('table,column', SQLITE_TEXT)
def test_sqlite_text_with_invalid_utf8(pristine, tmp_path, table, column) -> None:
    bag, db = copy(pristine['sqlite3'], tmp_path / 'bag')
    con = sqlite3.connect(db)
    with con:                 # invalid UTF-8 (a lone continuation byte, a truncated sequence) as TEXT
        con.execute(f"UPDATE {table} SET {column} = CAST(x'2f80ff74c3' AS TEXT)")
    con.close()
    check_info_and_repair(bag)


def test_sqlite_payload_bytes_flipped(pristine, tmp_path) -> None:
    rng = np.random.default_rng(SEED)
    for k in range(6):
        bag, db = copy(pristine['sqlite3'], tmp_path / f'bag{k}')
        con = sqlite3.connect(db)
        rows = con.execute('SELECT id, data FROM messages').fetchall()
        with con:
            for rid, data in rows:
                data = bytearray(data)
                for at in rng.integers(0, len(data), size=3):
                    data[at] ^= 1 << int(rng.integers(0, 8))
                con.execute('UPDATE messages SET data = ? WHERE id = ?', (bytes(data), rid))
        con.close()
        check_info_and_repair(bag)


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_metadata_bytes_flipped(pristine, tmp_path, storage) -> None:
    rng = np.random.default_rng(SEED)
    for k in range(8):
        bag, _ = copy(pristine[storage], tmp_path / f'bag{k}')
        meta = bytearray((bag / 'metadata.yaml').read_bytes())
        for at in rng.integers(0, len(meta), size=1 + k):
            meta[at] ^= 0x80 | (1 << int(rng.integers(0, 7)))
        (bag / 'metadata.yaml').write_bytes(bytes(meta))
        check_info_and_repair(bag)


# ---------------------------------------------------------------------------------------- MCAP
def records(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, end) of every record after the leading magic (MCAP: opcode u8, length u64)."""
    assert data[:8] == MAGIC
    out, at = [], 8
    while at + 9 <= len(data):
        op, length = data[at], struct.unpack_from('<Q', data, at + 1)[0]
        end = at + 9 + length
        if end > len(data):
            break
        out.append((op, at, end))
        at = end
    return out


def test_mcap_truncated_at_every_record_boundary(pristine, tmp_path) -> None:
    data = next(p for p in pristine['mcap'].iterdir() if p.suffix == '.mcap').read_bytes()
    bounds = sorted({start for _, start, _ in records(data)} | {len(data) - 8, 8})
    assert len(bounds) > 10
    for k, cut in enumerate(bounds):
        bag, storage = copy(pristine['mcap'], tmp_path / f'bag{k}')
        storage.write_bytes(data[:cut])
        check_info_and_repair(bag)


@pytest.mark.parametrize('opcode', [SCHEMA, CHANNEL, CHUNK])
def test_mcap_bytes_flipped_in_records(pristine, tmp_path, opcode) -> None:
    data = next(p for p in pristine['mcap'].iterdir() if p.suffix == '.mcap').read_bytes()
    rng = np.random.default_rng(SEED + opcode)
    spans = [(s, e) for op, s, e in records(data) if op == opcode]
    assert spans
    for k in range(8):
        start, end = spans[k % len(spans)]
        corrupt = bytearray(data)
        for at in rng.integers(start + 9, end, size=2):     # inside the record's content
            corrupt[at] ^= 0x80 | (1 << int(rng.integers(0, 7)))
        bag, storage = copy(pristine['mcap'], tmp_path / f'bag{k}')
        storage.write_bytes(bytes(corrupt))
        check_info_and_repair(bag)


@pytest.mark.parametrize('storage', ['sqlite3', 'mcap'])
def test_storage_file_bytes_flipped_anywhere(pristine, tmp_path, storage) -> None:
    """Single bits flipped at seeded places of the raw storage file (pages, strings, payloads)."""
    data = next(p for p in pristine[storage].iterdir() if p.suffix in ('.mcap', '.db3')).read_bytes()
    rng = np.random.default_rng(SEED)
    for k in range(40):
        corrupt = bytearray(data)
        for at in rng.integers(0, len(data), size=1 + k % 3):
            corrupt[at] ^= 1 << int(rng.integers(0, 8))
        bag, file = copy(pristine[storage], tmp_path / f'bag{k}')
        file.write_bytes(bytes(corrupt))
        check_info_and_repair(bag)
