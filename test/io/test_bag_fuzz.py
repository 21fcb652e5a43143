"""``geodesic-bag info`` and ``repair`` never raise on a corrupted bag (issue 25, item 2).

Seeded and bounded: for both storage plugins, bytes flipped in the payloads, in the topic, type
and schema strings (sqlite3: the text columns set to invalid UTF-8; MCAP: inside the Schema and
Channel records), and in metadata.yaml; MCAP truncated at every record boundary; bits flipped in
every table of the SQLite file (page 1's table definitions included, and every text value of
``topics``) and in every record kind of the MCAP file, as a closed bag and as a killed one (issue
37). Each case either reads (exit 0, a message) or prints one ``ERROR:`` line (exit 1); whatever
repair wrote reads afterwards, with rosbags too, and its metadata counts what the storage holds.
"""
from __future__ import annotations

import contextlib
import shutil
import sqlite3
import struct
from pathlib import Path

import numpy as np
import pytest

from bag_util import IN as IN_TOPIC
from bag_util import OUT as OUT_TOPIC
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


# ------------------------------------------------- bytes flipped in every table / record (issue 37)
CUSTOM = {'input_topic': IN_TOPIC, 'output_topic': OUT_TOPIC, 'velocity_scaling': '0.5'}


@pytest.fixture(scope='module')
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Bags as the processor records them (custom data included), one per storage."""
    root = tmp_path_factory.mktemp('fuzz_tables')
    return {s: make_bag(root / s, s, custom_data=CUSTOM) for s in ('sqlite3', 'mcap')}


def sqlite_pages(db: Path) -> dict[str, list[int]]:
    """Pages (0-based) of every table and index of a SQLite file, sqlite_schema (page 0) included."""
    with contextlib.closing(sqlite3.connect(db)) as con:
        rows = con.execute('SELECT name, pageno FROM dbstat').fetchall()
    pages: dict[str, list[int]] = {}
    for name, pageno in rows:
        pages.setdefault(name, []).append(pageno - 1)
    return pages


def flip_case(pristine: Path, dst: Path, spots: list[int], rng: np.random.Generator, *, killed: bool) -> Path:
    """A copy of ``pristine`` with one bit flipped at each spot of its storage file; without
    metadata.yaml when ``killed`` (repair then has to read the storage file)."""
    bag, storage = copy(pristine, dst)
    data = bytearray(storage.read_bytes())
    for at in spots:
        data[at] ^= 1 << int(rng.integers(0, 8))
    storage.write_bytes(bytes(data))
    if killed:
        (bag / 'metadata.yaml').unlink()
    return bag


def test_sqlite_bytes_flipped_in_every_table(recorded, tmp_path) -> None:
    """Bits flipped at seeded places of each table's pages (the table definitions on page 1,
    metadata, topics, message_definitions, messages, the index, the custom data), as a closed
    bag and as a killed one: exit 0 or one ERROR line; what repair wrote reads with rosbags and
    its metadata counts what it holds."""
    db = next(p for p in recorded['sqlite3'].iterdir() if p.suffix == '.db3')
    size = 4096
    assert len(db.read_bytes()) % size == 0
    pages = sqlite_pages(db)
    assert {'sqlite_schema', 'topics', 'messages', 'metadata', 'message_definitions', 'timestamp_idx',
            'geodesic_planner_custom_data'} <= set(pages)
    rng = np.random.default_rng(SEED)
    k = 0
    for _name, where in sorted(pages.items()):
        for case in range(2):  # a killed recording, a closed bag
            page = where[int(rng.integers(0, len(where)))]
            spots = [int(x) for x in page * size + rng.integers(0, size, size=1 + k % 3)]
            check_info_and_repair(flip_case(recorded['sqlite3'], tmp_path / f'bag{k}', spots, rng,
                                            killed=case == 0))
            k += 1


def test_sqlite_bytes_flipped_in_the_text_of_topics(recorded, tmp_path) -> None:
    """A bit flipped inside each text value of a topics row as stored in the file, and in the
    name and type of the others."""
    bag = recorded['sqlite3']
    db = next(p for p in bag.iterdir() if p.suffix == '.db3')
    raw = db.read_bytes()
    with contextlib.closing(sqlite3.connect(db)) as con:
        rows = con.execute('SELECT name, type, serialization_format, offered_qos_profiles, '
                           'type_description_hash FROM topics').fetchall()
    (topics_page,) = sqlite_pages(db)['topics']
    start, end = topics_page * 4096, (topics_page + 1) * 4096
    rng = np.random.default_rng(SEED)
    k = 0
    for i, row in enumerate(rows):
        for value in row if i == 0 else row[:2]:
            at = raw.find(value.encode(), start, end)
            assert at >= 0, value
            spot = at + int(rng.integers(0, len(value)))
            check_info_and_repair(flip_case(bag, tmp_path / f'bag{k}', [spot], rng, killed=k % 3 != 2))
            k += 1
    assert k == 5 + 2 * (len(rows) - 1)


def test_mcap_bytes_flipped_in_every_record_kind(recorded, tmp_path) -> None:
    """Bits flipped inside records of every kind the file holds (header, schemas, channels, the
    custom data, chunks, indexes, statistics, metadata, footer), closed and killed."""
    bag = recorded['mcap']
    data = next(p for p in bag.iterdir() if p.suffix == '.mcap').read_bytes()
    by_kind: dict[int, list[tuple[int, int]]] = {}
    for op, s, e in records(data):
        by_kind.setdefault(op, []).append((s, e))
    assert {SCHEMA, CHANNEL, CHUNK, 0x0C} <= set(by_kind)  # 0x0C: metadata (custom data, rosbag2)
    rng = np.random.default_rng(SEED)
    k = 0
    for _op, spans in sorted(by_kind.items()):
        for case in range(2):  # a killed recording, a closed bag
            s, e = spans[int(rng.integers(0, len(spans)))]
            spots = [int(x) for x in rng.integers(s, e, size=1 + k % 2)]
            check_info_and_repair(flip_case(bag, tmp_path / f'bag{k}', spots, rng, killed=case == 0))
            k += 1
