"""Repair of an interrupted recording (SIGKILL, crash before ``close()``).

The storage file is scanned for every complete record and rewritten with a full index and
``metadata.yaml``: MCAP with the ``mcap`` package's stream reader (schemas, channels, messages of
every intact chunk; a truncated record ends the scan, a corrupt chunk is skipped), SQLite through
its committed rows (:mod:`.salvage`: damaged pages skipped, damaged table definitions rebuilt).

What the metadata held is kept: the repaired bag gets the custom data of the old
``metadata.yaml`` when there is one, else of the storage file's own copy of the metadata, else
of the copy the recorder stored when it opened (see :mod:`.storage`), and the old ``ros_distro``;
the storage file keeps its name. Everything else in ``metadata.yaml`` describes the messages and
is computed anew from them.

A storage file that is not a bag at all (garbage bytes, a truncated SQLite header, a missing
table) gives a :class:`BagError` naming the cause, never another exception. Damage that cost
data (corrupt chunks, unreadable rows or pages, topics left out for want of a usable message
definition, damaged names) is listed in :attr:`RepairReport.damage`; what could be read is
written all the same.
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
import yaml
import zstandard
from mcap.exceptions import EndOfFile, McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, McapRecord, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from rosbags.rosbag2 import Writer, WriterError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from ...core.errors import BagError
from .cdr import load_yaml, make_typestore, parse_qos_text
from .reader import OpenBag, bag_info
from .reader import messages as messages_of
from .recorder import PLUGINS
from .salvage import Recovered, Salvage, metadata_fields, scan_sqlite
from .storage import CUSTOM_DATA_RECORD

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
        damage: what was damaged in the storage file and what that cost, one line each (empty: a
            recording that was only interrupted, nothing lost but what never reached the file).
        custom_data: the repaired bag's custom data.
    """

    path: Path
    repaired: bool
    storage: str
    messages: dict[str, int]
    damaged_file: Path | None
    note: str
    damage: tuple[str, ...] = ()
    custom_data: dict[str, str] = field(default_factory=dict)


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
            if isinstance(record, Metadata):
                _scan_metadata(record, found)
            elif isinstance(record, Schema):
                found.schemas[record.id] = (record.name, record.encoding, record.data.decode('utf-8'))
            elif isinstance(record, Channel):
                name, enc, text = found.schemas.get(record.schema_id, ('', '', ''))
                found.channels[record.id] = Recovered(
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


def _scan_metadata(record: Metadata, found: _Found) -> None:
    """The recorder's early custom data, or rosbag2's metadata record (written at close: it wins)."""
    if record.name == CUSTOM_DATA_RECORD:
        found.early_custom_data.update({str(k): str(v) for k, v in record.metadata.items()})
    elif record.name == 'rosbag2':
        try:
            custom, distro = metadata_fields(load_yaml(record.metadata.get('serialized_metadata', '')))
        except yaml.YAMLError:
            return
        found.custom_data.update(custom)
        found.ros_distro = distro


@dataclass
class _Found(Salvage):
    schemas: dict[int, tuple[str, str, str]] = field(default_factory=dict)
    early_custom_data: dict[str, str] = field(default_factory=dict)


def _scan_mcap(path: Path) -> Salvage:
    """Tolerant MCAP scan with mcap's stream reader: channels, messages, corrupt chunks skipped."""
    found = _Found()
    with path.open('rb') as fh:
        if fh.read(8) != _MCAP_MAGIC:
            msg = f'not an MCAP file: {path}'
            raise BagError(msg)
        reader = StreamReader(_exact_reader(fh), skip_magic=True, emit_chunks=True,
                              record_size_limit=path.stat().st_size)
        _scan_records(reader.records, found, nested=False)
    if found.skipped:
        found.damage.append(f'{found.skipped} corrupt chunk(s) skipped with their messages')
    found.custom_data = {**found.early_custom_data, **found.custom_data}
    return found


def _why_unreadable(path: Path) -> str | None:
    """None when rosbags reads every message ``metadata.yaml`` counts, else why not.

    (rosbags silently skips a SQLite topic row that no longer matches ``metadata.yaml``.)
    """
    counts: dict[int, int] = {}
    try:
        with OpenBag(path) as reader:
            for conn, _, _ in messages_of(reader, list(reader.connections), path):
                counts[conn.id] = counts.get(conn.id, 0) + 1
            wrong = [f'{c.topic}: {counts.get(c.id, 0)} of {c.msgcount}' for c in reader.connections
                     if counts.get(c.id, 0) != c.msgcount]
    except BagError as err:
        return str(err)
    if wrong:
        return f'metadata.yaml counts messages the storage file does not give ({", ".join(wrong)})'
    return None


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
    why = _why_unreadable(bag) if (bag / 'metadata.yaml').exists() else 'no metadata.yaml'
    if why is None:
        info = bag_info(bag)
        return RepairReport(bag, False, storage, {t.name: t.count for t in info.topics}, None,
                            'bag is readable: nothing to repair', custom_data=info.custom_data)

    old_meta = _old_metadata(bag / 'metadata.yaml')
    tmp_parent = bag.parent / f'.{bag.name}.repair-{os.getpid()}'
    if tmp_parent.exists():
        shutil.rmtree(tmp_parent)
    tmp_bag = tmp_parent / src.stem  # the writer names the storage file after the directory
    counts: dict[str, int] = {}
    try:
        tmp_parent.mkdir()
        found = _scan_mcap(src) if storage == 'mcap' else scan_sqlite(src, tmp_parent)
        custom, distro = metadata_fields(old_meta)
        custom = {**found.custom_data, **custom}
        distro = distro or found.ros_distro
        writer = Writer(tmp_bag, version=9, storage_plugin=PLUGINS[storage])
        for key, value in custom.items():
            writer.set_custom_data(key, value)
        writer.open()
        conns: dict[int, Connection] = {}
        store = make_typestore()
        left_out: list[str] = []
        for cid, ch in found.channels.items():
            conn = _add_connection(writer, ch, store)
            if conn is None:
                left_out.append(f'{ch.topic} ({ch.msgtype})')
                continue
            conns[cid] = conn
            counts.setdefault(ch.topic, 0)
        lost = 0
        for cid, stamp, data in found.messages:
            conn = conns.get(cid)
            if conn is None:
                lost += 1
                continue
            writer.write(conn, stamp, data)
            counts[conn.topic] += 1
        writer.close()
        if distro and distro != 'rosbags':
            _set_ros_distro(tmp_bag / 'metadata.yaml', distro)
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
    except (WriterError, OSError, sqlite3.Error, struct.error, yaml.YAMLError) as err:
        msg = f'cannot repair {bag}: {err}'
        raise BagError(msg) from err
    finally:
        shutil.rmtree(tmp_parent, ignore_errors=True)
    damage = list(found.damage)
    if left_out:
        damage.append(f'left out for want of a usable message definition: {", ".join(left_out)}')
    if lost:
        damage.append(f'{lost} messages without a usable channel dropped')
    note = f'recovered {sum(counts.values())} messages on {len(counts)} topics'
    if why.startswith('metadata.yaml counts'):
        note += f'; {why}'
    if found.skipped:
        what = 'corrupt chunks' if storage == 'mcap' else 'unreadable rows'
        note += f'; {found.skipped} {what} skipped'
    if left_out:
        note += f'; left out for want of a usable message definition: {", ".join(left_out)}'
    if lost:
        note += f'; {lost} messages without a usable channel dropped'
    return RepairReport(bag, True, storage, counts, damaged, note, tuple(damage), custom)


def _old_metadata(path: Path) -> object:
    """The parsed ``metadata.yaml`` of the bag being repaired; None when absent or unreadable."""
    try:
        return load_yaml(path.read_bytes())
    except (OSError, yaml.YAMLError):
        return None


def _set_ros_distro(path: Path, distro: str) -> None:
    """Put the old bag's ``ros_distro`` into the repaired bag's ``metadata.yaml``."""
    meta = load_yaml(path.read_text())
    meta['rosbag2_bagfile_information']['ros_distro'] = distro
    path.write_text(yaml.safe_dump(meta, default_flow_style=False, sort_keys=False))


def _add_connection(writer: Writer, ch: Recovered, store: Any) -> Connection | None:  # noqa: ANN401 rosbags Typestore
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
