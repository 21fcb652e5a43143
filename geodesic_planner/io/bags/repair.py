"""Repair of an interrupted recording (SIGKILL, crash before ``close()``).

The storage file is scanned for every complete record and rewritten with a full index and
``metadata.yaml``: MCAP with the ``mcap`` package's stream reader (schemas, channels, messages of
every intact chunk; a truncated record ends the scan, a corrupt chunk is skipped), SQLite through
its committed rows (read in order up to the first unreadable page; rows with values of the
wrong kind skipped).

A storage file that is not a bag at all (garbage bytes, a truncated SQLite header, a missing
table) gives a :class:`BagError` naming the cause, never another exception; topics whose
message definition is unusable are left out with their messages, and the report says so.
"""
from __future__ import annotations

import os
import shutil
import sqlite3
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, BinaryIO, cast

import lz4.frame
import zstandard
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, McapRecord, Message, Schema
from mcap.stream_reader import StreamReader
from rosbags.interfaces import Qos
from rosbags.rosbag2 import Writer, WriterError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from ...core.errors import BagError
from .cdr import make_typestore, parse_qos_text
from .reader import OpenBag, bag_info
from .reader import messages as messages_of
from .recorder import PLUGINS

if TYPE_CHECKING:
    from rosbags.interfaces import Connection

__all__ = ['RepairReport', 'repair']

_MCAP_MAGIC = b'\x89MCAP0\r\n'


# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RepairReport:
    """Outcome of :func:`repair`.

    Attributes:
        path: bag directory.
        repaired: False when the bag was already readable (nothing changed).
        storage: 'mcap' or 'sqlite3'.
        messages: messages in the repaired bag, per topic.
        damaged_file: where the original storage file was kept (None if untouched).
        note: what was found.
    """

    path: Path
    repaired: bool
    storage: str
    messages: dict[str, int]
    damaged_file: Path | None
    note: str


@dataclass
class _Recovered:
    topic: str
    msgtype: str
    msgdef: str
    msgdef_format: str  # 'ros2msg' | 'ros2idl' | ''
    qos: list[Qos]
    digest: str = ''


class _ExactReader:
    """Binary stream whose ``read(n)`` returns n bytes or raises: a truncated record never passes.

    (mcap's stream reader accepts a short final read as a whole field.)
    """

    def __init__(self, stream: BinaryIO) -> None:
        self._stream = stream

    def read(self, n: int = -1) -> bytes:
        data = self._stream.read(n)
        if n >= 0 and len(data) != n:
            raise EndOfFile
        return data


def _exact_reader(stream: BinaryIO) -> IO[bytes]:
    """``stream`` behind an :class:`_ExactReader`, typed as the stream StreamReader accepts.

    StreamReader only calls ``read(n)``; the reader is deliberately not a RawIOBase, which
    StreamReader would wrap in a BufferedReader (whose reads may return fewer bytes).
    """
    return cast('IO[bytes]', _ExactReader(stream))


def _decompress(chunk: Chunk) -> bytes | None:
    """Uncompressed records of a chunk; None when it is corrupt or its compression unknown."""
    try:
        if chunk.compression == '':
            data = bytes(chunk.data)
        elif chunk.compression == 'zstd':
            data = zstandard.ZstdDecompressor().decompress(chunk.data, max_output_size=chunk.uncompressed_size)
        elif chunk.compression == 'lz4':
            data = bytes(lz4.frame.decompress(chunk.data))
        else:
            return None
    except (zstandard.ZstdError, RuntimeError):  # lz4 reports corrupt frames as RuntimeError
        return None
    if len(data) != chunk.uncompressed_size:
        return None
    if chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc:
        return None
    return data


# What a damaged file can make mcap's record parsers raise: a truncated or garbled record ends
# the scan, everything complete before it is kept.
_DAMAGE = (McapError, struct.error, UnicodeDecodeError, ValueError, KeyError, OverflowError, MemoryError)


def _scan_records(records: Iterator[McapRecord], found: _Found, *, nested: bool) -> None:
    try:
        for record in records:
            if isinstance(record, Schema):
                found.schemas[record.id] = (record.name, record.encoding, record.data.decode('utf-8'))
            elif isinstance(record, Channel):
                name, enc, text = found.schemas.get(record.schema_id, ('', '', ''))
                found.channels[record.id] = _Recovered(
                    record.topic, name, text, enc, parse_qos_text(record.metadata.get('offered_qos_profiles')),
                    record.metadata.get('topic_type_hash', ''))
            elif isinstance(record, Message):
                found.messages.append((record.channel_id, record.log_time, bytes(record.data)))
            elif isinstance(record, Chunk) and not nested:
                inner = _decompress(record)
                if inner is None:
                    found.skipped += 1
                    continue
                reader = StreamReader(_exact_reader(BytesIO(inner)), skip_magic=True,
                                      record_size_limit=len(inner))
                _scan_records(_until_end(reader.records), found, nested=True)
            elif isinstance(record, (Footer, DataEnd)) and not nested:
                return
    except _DAMAGE:
        return


def _until_end(records: Iterator[McapRecord]) -> Iterator[McapRecord]:
    """A chunk's records: the chunk ends where the stream does (no footer inside a chunk)."""
    try:
        yield from records
    except EndOfFile:
        return


@dataclass
class _Found:
    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    channels: dict[int, _Recovered] = field(default_factory=dict)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    skipped: int = 0


def _scan_mcap(path: Path) -> tuple[dict[int, _Recovered], list[tuple[int, int, bytes]], int]:
    """Tolerant MCAP scan with mcap's stream reader: channels, messages, corrupt chunks skipped."""
    found = _Found()
    with path.open('rb') as fh:
        if fh.read(8) != _MCAP_MAGIC:
            msg = f'not an MCAP file: {path}'
            raise BagError(msg)
        reader = StreamReader(_exact_reader(fh), skip_magic=True, emit_chunks=True,
                              record_size_limit=path.stat().st_size)
        _scan_records(reader.records, found, nested=False)
    return found.channels, found.messages, found.skipped


_UINT64 = 1 << 64


def _sqlite_rows(conn: sqlite3.Connection, query: str) -> tuple[list[Any], bool]:
    """Rows of ``query`` read one by one up to the first error; (rows, True if it stopped early)."""
    rows: list[Any] = []
    try:
        for row in conn.execute(query):
            rows.append(row)
    except sqlite3.Error:
        return rows, True
    return rows, False


def _text(value: object) -> str:
    if isinstance(value, bytes):
        return value.decode('utf-8', 'replace')
    return '' if value is None else str(value)


def _scan_sqlite(path: Path) -> tuple[dict[int, _Recovered], list[tuple[int, int, bytes]], int]:
    """Committed topics, definitions and messages of a SQLite storage file.

    Returns:
        (channels by topic id, messages (topic id, ns, bytes), rows skipped or unread).

    Raises:
        BagError: not a SQLite database, or no readable ``topics`` / ``messages`` table.
    """
    try:
        conn = sqlite3.connect(f'file:{path}', uri=True)  # rolls back an interrupted transaction
    except sqlite3.Error as err:
        msg = f'cannot read SQLite storage {path}: {err}'
        raise BagError(msg) from err
    try:
        try:
            cur = conn.execute('SELECT id, name, type, offered_qos_profiles FROM topics')
            topics = cur.fetchall()
            hashes = dict(_sqlite_rows(conn, 'SELECT id, type_description_hash FROM topics')[0])
            conn.execute('SELECT topic_id, timestamp, data FROM messages LIMIT 0').fetchall()
        except sqlite3.Error as err:
            msg = f'cannot read SQLite storage {path}: {err} (not a rosbag2 database, or damaged)'
            raise BagError(msg) from err
        def_rows, _ = _sqlite_rows(
            conn, 'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions')
        rows, stopped = _sqlite_rows(conn, 'SELECT topic_id, timestamp, data FROM messages ORDER BY id')
        if stopped and not rows:  # the ordered scan needs pages the plain one may not
            rows, stopped = _sqlite_rows(conn, 'SELECT topic_id, timestamp, data FROM messages')
    finally:
        conn.close()
    defs = {_text(ttype): (_text(enc), _text(text)) for ttype, enc, text in def_rows}
    channels = {}
    for tid, name, ttype, qos in topics:
        if not isinstance(tid, int) or not name or not ttype:
            continue
        enc, text = defs.get(_text(ttype), ('', ''))
        channels[tid] = _Recovered(_text(name), _text(ttype), text, enc, parse_qos_text(_text(qos)),
                                   _text(hashes.get(tid)))
    messages = [(a, b, bytes(c)) for a, b, c in rows
                if isinstance(a, int) and isinstance(b, int) and 0 <= b < _UINT64 and isinstance(c, bytes)]
    return channels, messages, len(rows) - len(messages) + int(stopped)


def _bag_is_readable(path: Path) -> bool:
    try:
        with OpenBag(path) as reader:
            for _ in messages_of(reader, list(reader.connections), path):
                pass
    except BagError:
        return False
    return True


def repair(path: str | os.PathLike[str]) -> RepairReport:
    """Make an interrupted recording readable again (SIGKILL, crash before ``close()``).

    The storage file is scanned for every complete record (MCAP: schemas, channels and whole
    chunks up to the first truncated record; SQLite: committed rows), a new storage file with a
    full index is written next to it with ``metadata.yaml``, and the damaged original is kept as
    ``<name>.damaged``. A bag that already reads fine is left untouched.

    Raises:
        BagError: not a bag directory, no storage file, a storage file that cannot be read at
            all (not MCAP / SQLite, no topics table), the new bag cannot be written.
    """
    bag = Path(path)
    if not bag.is_dir():
        msg = f'no such bag directory: {bag}'
        raise BagError(msg)
    files = sorted(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3') and p.is_file())
    if not files:
        msg = f'not a bag: {bag} has no .mcap or .db3 file'
        raise BagError(msg)
    if len(files) > 1:
        msg = f'cannot repair {bag}: several storage files ({", ".join(p.name for p in files)})'
        raise BagError(msg)
    src = files[0]
    storage = 'mcap' if src.suffix == '.mcap' else 'sqlite3'
    if (bag / 'metadata.yaml').exists() and _bag_is_readable(bag):
        info = bag_info(bag)
        return RepairReport(bag, False, storage, {t.name: t.count for t in info.topics}, None,
                            'bag is readable: nothing to repair')

    channels, messages, skipped = _scan_mcap(src) if storage == 'mcap' else _scan_sqlite(src)
    tmp_parent = bag.parent / f'.{bag.name}.repair-{os.getpid()}'
    if tmp_parent.exists():
        shutil.rmtree(tmp_parent)
    tmp_bag = tmp_parent / bag.name
    counts: dict[str, int] = {}
    try:
        tmp_parent.mkdir()
        writer = Writer(tmp_bag, version=9, storage_plugin=PLUGINS[storage])
        writer.open()
        conns: dict[int, Connection] = {}
        store = make_typestore()
        left_out: list[str] = []
        for cid, ch in channels.items():
            conn = _add_connection(writer, ch, store)
            if conn is None:
                left_out.append(f'{ch.topic} ({ch.msgtype})')
                continue
            conns[cid] = conn
            counts.setdefault(ch.topic, 0)
        lost = 0
        for cid, stamp, data in messages:
            conn = conns.get(cid)
            if conn is None:
                lost += 1
                continue
            writer.write(conn, stamp, data)
            counts[conn.topic] += 1
        writer.close()
        new_file = next(p for p in tmp_bag.iterdir() if p.suffix == src.suffix)
        damaged = src.with_name(src.name + '.damaged')
        k = 2
        while damaged.exists():
            damaged = src.with_name(f'{src.name}.damaged{k}')
            k += 1
        src.replace(damaged)
        if (bag / 'metadata.yaml').exists():
            (bag / 'metadata.yaml').replace(bag / 'metadata.yaml.damaged')
        new_file.replace(bag / new_file.name)
        (tmp_bag / 'metadata.yaml').replace(bag / 'metadata.yaml')
    except (WriterError, OSError, sqlite3.Error, struct.error) as err:
        msg = f'cannot repair {bag}: {err}'
        raise BagError(msg) from err
    finally:
        shutil.rmtree(tmp_parent, ignore_errors=True)
    note = f'recovered {sum(counts.values())} messages on {len(counts)} topics'
    if skipped:
        what = 'corrupt chunks' if storage == 'mcap' else 'unreadable rows'
        note += f'; {skipped} {what} skipped'
    if left_out:
        note += f'; left out for want of a usable message definition: {", ".join(left_out)}'
    if lost:
        note += f'; {lost} messages without a usable channel dropped'
    return RepairReport(bag, True, storage, counts, damaged, note)


def _add_connection(writer: Writer, ch: _Recovered, store: Any) -> Connection | None:  # noqa: ANN401 rosbags Typestore
    """The repaired bag's connection for a recovered channel; None when its type is unusable."""
    kwargs: dict[str, Any] = {}
    if ch.msgdef and ch.msgdef_format in ('ros2msg', ''):
        ts = get_typestore(Stores.EMPTY)
        try:
            ts.register(get_types_from_msg(ch.msgdef, ch.msgtype))
            # the hash of the definition itself: a recorded digest may be damaged (a flipped byte
            # in one topic's copy makes the repaired bag's connections disagree)
            kwargs = {'msgdef': ch.msgdef, 'rihs01': ts.hash_rihs01(ch.msgtype)}
        except Exception:  # noqa: BLE001 - a damaged definition makes the parser raise anything: unusable
            kwargs = {}
    if not kwargs:
        if ch.msgtype not in store.fielddefs:
            return None
        kwargs = {'typestore': store}
    try:
        return writer.add_connection(ch.topic, ch.msgtype, offered_qos_profiles=ch.qos, **kwargs)
    except (WriterError, TypesysError, KeyError, ValueError):
        return None
