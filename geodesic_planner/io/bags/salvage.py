"""What a damaged or interrupted rosbag2 storage file still holds (the reading half of repair).

:class:`Salvage` is what :func:`~geodesic_planner.io.bags.repair.repair` writes into the new bag:
the channels (topic, type, definition, QoS), the messages, the bag's custom data, and a list of
the damage found (what was lost, and why). :func:`scan_sqlite` reads a SQLite storage file:

* every text value is read as bytes and decoded here (a flipped byte in a topic name or a type
  makes SQLite's rows, and even its error messages, invalid UTF-8);
* the rows of each table are read up to the first unreadable page; a damaged ``messages`` page
  is skipped by seeking past it (rowids are ascending), a damaged ``topics`` page by looking the
  missing topic ids up one by one;
* when the table definitions themselves are damaged (``sqlite_master`` on page 1: a flipped byte
  in a ``CREATE TABLE`` statement or a cell pointer makes SQLite refuse every query), a copy of the
  file gets a new page 1 holding the rosbag2 schema with the tables' root pages as the damaged
  page still names them (:func:`rebuild_schema`); the tables' own pages are read from the copy.

The MCAP scan is in :mod:`.repair`.
"""
from __future__ import annotations

import difflib
import re
import sqlite3
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import yaml

from ...core.errors import BagError
from .cdr import load_yaml, parse_qos_text
from .storage import CUSTOM_DATA_RECORD

if TYPE_CHECKING:
    from pathlib import Path

    from rosbags.interfaces import Qos

__all__ = ['ROSBAG2_TABLES', 'Recovered', 'Salvage', 'metadata_fields', 'rebuild_schema', 'scan_sqlite']

#: rosbag2's SQLite tables (schema version 4) in the order rosbag2 and rosbags create them; the
#: root page of the k-th is k + 2 in a file written that way.
ROSBAG2_TABLES = {
    'schema': 'CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL)',
    'metadata': ('CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL, '
                 'metadata TEXT NOT NULL)'),
    'topics': ('CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, '
               'serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL, '
               'type_description_hash TEXT NOT NULL)'),
    'message_definitions': ('CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL, '
                            'encoding TEXT NOT NULL, encoded_message_definition TEXT NOT NULL, '
                            'type_description_hash TEXT NOT NULL)'),
    'messages': ('CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, '
                 'timestamp INTEGER NOT NULL, data BLOB NOT NULL)'),
}

_UINT64 = 1 << 64
#: A ROS 2 topic name (fully qualified, as recorded) and a message type name.
_TOPIC_NAME = re.compile(r'/[A-Za-z_~{][A-Za-z0-9_/{}~]*\Z')
_TYPE_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*/(msg/|srv/|action/)?[A-Za-z][A-Za-z0-9_]*\Z')


@dataclass
class Recovered:
    """One recovered channel: topic, type, definition (text and format), offered QoS, type hash."""

    topic: str
    msgtype: str
    msgdef: str
    msgdef_format: str  # 'ros2msg' | 'ros2idl' | ''
    qos: list[Qos]
    digest: str = ''


@dataclass
class Salvage:
    """What a storage file still holds.

    Attributes:
        channels: by storage id (SQLite topic id, MCAP channel id).
        messages: (channel id, log time in ns, CDR bytes) in storage order.
        skipped: rows or chunks that could not be read (or had values of the wrong kind).
        damage: one line per damaged part of the file and what it cost.
        custom_data: the bag's custom data as the file still holds it.
        ros_distro: ``ros_distro`` of the file's own copy of the metadata ('' when absent).
    """

    channels: dict[int, Recovered] = field(default_factory=dict)
    messages: list[tuple[int, int, bytes]] = field(default_factory=list)
    skipped: int = 0
    damage: list[str] = field(default_factory=list)
    custom_data: dict[str, str] = field(default_factory=dict)
    ros_distro: str = ''


def metadata_fields(meta: object) -> tuple[dict[str, str], str]:
    """(custom_data, ros_distro) of rosbag2 metadata (``metadata.yaml`` or the storage's copy).

    ``meta`` is the parsed YAML: either the whole file (``rosbag2_bagfile_information: ...``) or
    the mapping inside it; anything else gives ({}, '').
    """
    if isinstance(meta, dict) and isinstance(meta.get('rosbag2_bagfile_information'), dict):
        meta = meta['rosbag2_bagfile_information']
    if not isinstance(meta, dict):
        return {}, ''
    raw = meta.get('custom_data')
    custom = {str(k): str(v) for k, v in raw.items()} if isinstance(raw, dict) else {}
    distro = meta.get('ros_distro')
    return custom, distro if isinstance(distro, str) else ''


def _text(value: object) -> str:
    if isinstance(value, bytes):
        return value.decode('utf-8', 'replace')
    return '' if value is None else str(value)


def _reason(err: BaseException) -> str:
    """An error's text; SQLite's own message may quote damaged bytes that are not UTF-8."""
    if isinstance(err, UnicodeDecodeError):
        return bytes(err.object).decode('utf-8', 'replace')
    return str(err) or type(err).__name__


def _rows(conn: sqlite3.Connection, query: str, args: tuple[Any, ...] = ()) -> tuple[list[Any], str]:
    """Rows of ``query`` read one by one up to the first error; (rows, '' or why it stopped)."""
    rows: list[Any] = []
    try:
        for row in conn.execute(query, args):
            rows.append(row)
    except (sqlite3.Error, UnicodeDecodeError) as err:
        return rows, _reason(err)
    return rows, ''


class _SchemaDamagedError(Exception):
    """SQLite cannot read the table definitions of the file."""


def _connect(path: Path) -> sqlite3.Connection:
    conn = sqlite3.connect(f'file:{path}', uri=True)  # rolls back an interrupted transaction
    conn.text_factory = bytes
    return conn


def scan_sqlite(path: Path, workdir: Path) -> Salvage:
    """Committed topics, definitions, messages and custom data of a SQLite storage file.

    Args:
        path: the ``.db3`` file (not modified).
        workdir: an existing directory for a copy with rebuilt table definitions, if needed.

    Raises:
        BagError: not a SQLite database, or no ``topics`` / ``messages`` table to be found.
    """
    try:
        return _scan(path, Salvage())
    except _SchemaDamagedError as err:
        first = str(err)
    copy = workdir / path.name
    found = Salvage()
    try:
        tables = rebuild_schema(path, copy)
    except (OSError, sqlite3.Error, ValueError) as err:
        msg = f'cannot read SQLite storage {path}: {first} (not a rosbag2 database, or damaged: {err})'
        raise BagError(msg) from err
    found.damage.append(f'the table definitions (page 1) were damaged ({first}); rebuilt from the rosbag2 '
                        f'schema with the root pages {tables}')
    try:
        return _scan(copy, found)
    except _SchemaDamagedError as err:
        msg = f'cannot read SQLite storage {path}: {first} (not a rosbag2 database, or damaged: {err})'
        raise BagError(msg) from err


def _scan(path: Path, found: Salvage) -> Salvage:
    try:
        conn = _connect(path)
    except sqlite3.Error as err:
        raise _SchemaDamagedError(_reason(err)) from err
    try:
        try:
            conn.execute('SELECT id, name, type, offered_qos_profiles FROM topics LIMIT 0').fetchall()
            conn.execute('SELECT topic_id, timestamp, data FROM messages LIMIT 0').fetchall()
        except (sqlite3.Error, UnicodeDecodeError) as err:
            reason = _reason(err)
            if reason.startswith('no such table'):  # the definitions were read: the table is not there
                msg = f'cannot read SQLite storage {path}: {reason} (not a rosbag2 database, or damaged)'
                raise BagError(msg) from err
            raise _SchemaDamagedError(reason) from err
        _read_metadata(conn, found)
        messages = _read_messages(conn, found)
        topics = _read_topics(conn, found, {tid for tid, _, _ in messages})
        def_rows, why = _rows(conn, 'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions')
        if why and not why.startswith('no such table'):
            found.damage.append(f'message_definitions table: read stopped after {len(def_rows)} rows ({why})')
    finally:
        conn.close()
    defs = {_text(ttype): (_text(enc), _text(text)) for ttype, enc, text in def_rows}
    for tid, (name, ttype, qos, digest) in topics.items():
        enc, text = defs.get(ttype, ('', ''))
        found.channels[tid] = Recovered(name, ttype, text, enc, parse_qos_text(qos), digest)
    found.messages = [(a, b, bytes(c)) for a, b, c in messages
                      if isinstance(a, int) and isinstance(b, int) and 0 <= b < _UINT64 and isinstance(c, bytes)]
    bad_values = len(messages) - len(found.messages)
    found.skipped += bad_values
    if bad_values:
        found.damage.append(f'messages table: {bad_values} rows with values of the wrong kind skipped')
    return found


def _read_metadata(conn: sqlite3.Connection, found: Salvage) -> None:
    """Custom data: the recorder's early copy, then the storage's metadata (written at close)."""
    rows, _ = _rows(conn, f'SELECT key, value FROM {CUSTOM_DATA_RECORD}')
    found.custom_data.update({_text(k): _text(v) for k, v in rows})
    meta_rows, _ = _rows(conn, 'SELECT metadata FROM metadata ORDER BY id')
    for (text,) in meta_rows[-1:]:
        try:
            custom, distro = metadata_fields(load_yaml(_text(text)))
        except yaml.YAMLError:
            continue
        found.custom_data.update(custom)
        found.ros_distro = distro


def _read_messages(conn: sqlite3.Connection, found: Salvage) -> list[Any]:
    """Every readable row of ``messages`` (id order), seeking past damaged pages."""
    query = 'SELECT id, topic_id, timestamp, data FROM messages WHERE id >= ? ORDER BY id'  # SeekGE
    rows, why = _rows(conn, query, (-(1 << 63),))
    if why and not rows:  # the ordered scan needs pages a plain one may not
        rows, why = _rows(conn, 'SELECT id, topic_id, timestamp, data FROM messages')
        if not why:
            return [r[1:] for r in rows]
    first_why, stretches = why, 0
    pos = max((r[0] for r in rows if isinstance(r[0], int)), default=-(1 << 63)) + 1  # next rowid to try
    while why:
        while True:  # one row at a time: a scan reads a row ahead and fails before returning it
            got, why = _rows(conn, query + ' LIMIT 1', (pos,))
            if not got:
                break
            rows += got
            pos = got[0][0] + 1
        start = _seek_past(conn, pos - 1) if why else None
        if start is None:
            break
        more, why = _rows(conn, query, (start,))
        stretches += 1
        rows += more
        pos = more[-1][0] + 1 if more else start  # the row at start reads alone (it was probed)
    if first_why:
        found.skipped += 1
        lost = ('the rest unread' if why else
                f'the damaged pages skipped ({stretches} readable stretch(es) after them)')
        found.damage.append(f'messages table damaged ({first_why}): {len(rows)} rows read, {lost}')
    return [r[1:] for r in rows]


def _seek_past(conn: sqlite3.Connection, last: int) -> int | None:
    """The smallest s > ``last`` from which ``id >= s`` can be read again; None: nothing to find.

    Steps of doubling length find a start past the damage (at most 63 of them), a bisection then
    the first one (rows between ``last`` and it were on the damaged pages). ``>=`` seeks to the
    row itself; ``id > s`` would seek to s and step on, through the damaged page that holds s.
    """
    probe = 'SELECT id FROM messages WHERE id >= ? ORDER BY id LIMIT 1'

    def readable(start: int) -> bool | None:  # None: readable, and no row after start
        got, why = _rows(conn, probe, (start,))
        return True if got else (None if not why else False)

    lo, step = last, 1  # readable(last) is False: the scan stopped after it
    while True:
        hi = last + step
        ok = readable(hi)
        if ok is None:
            return None
        if ok:
            break
        lo, step = hi, step * 2
        if step > 1 << 62:
            return None
    while hi - lo > 1:  # readable(lo) is False, readable(hi) True
        mid = (lo + hi) // 2
        if readable(mid):
            hi = mid
        else:
            lo = mid
    return hi


def _read_topics(conn: sqlite3.Connection, found: Salvage,
                 used: set[int]) -> dict[int, tuple[str, str, str, str]]:
    """Topic id -> (name, type, offered QoS text, type hash); damaged rows reported."""
    rows, why = _rows(conn, 'SELECT id, name, type, offered_qos_profiles FROM topics ORDER BY id')
    if why:
        have = {r[0] for r in rows}
        for tid in sorted(t for t in used if isinstance(t, int) and t not in have):  # one by one
            rows += _rows(conn, 'SELECT id, name, type, offered_qos_profiles FROM topics WHERE id = ?', (tid,))[0]
        found.damage.append(f'topics table damaged ({why}): {len(rows)} topic rows read')
    hashes = dict(_rows(conn, 'SELECT id, type_description_hash FROM topics')[0])
    topics = {}
    for tid, name, ttype, qos in rows:
        if not isinstance(tid, int) or not name or not ttype:
            found.skipped += 1
            found.damage.append(f'topic row {tid!r}: id, name or type missing (its messages are dropped)')
            continue
        topic, msgtype = _text(name), _text(ttype)
        if not _TOPIC_NAME.match(topic):
            found.damage.append(f'topic {tid}: name {topic!r} is damaged (kept as it is)')
        if not _TYPE_NAME.match(msgtype):
            found.damage.append(f'topic {tid} ({topic}): type {msgtype!r} is damaged')
        topics[tid] = (topic, msgtype, _text(qos), _text(hashes.get(tid)))
    return topics


# --------------------------------------------------------------------------------- page 1
def _page_size(data: bytes) -> int:
    size = int.from_bytes(data[16:18], 'big')
    size = 65536 if size == 1 else size
    if 512 <= size <= 65536 and size & (size - 1) == 0 and len(data) % size == 0 and len(data) >= 2 * size:
        return size
    if len(data) % 4096 == 0 and len(data) >= 2 * 4096:  # rosbag2's and SQLite's default page size
        return 4096
    msg = f'{len(data)} bytes: not a whole number of SQLite pages'
    raise ValueError(msg)


def _root_pages(path: Path, pages: int) -> dict[str, int]:
    """Root page of each rosbag2 table as the damaged ``sqlite_master`` rows still say."""
    roots: dict[str, int] = {}
    try:
        conn = sqlite3.connect(f'file:{path}?mode=ro', uri=True)
    except sqlite3.Error:
        return roots
    conn.text_factory = bytes
    try:
        _rows(conn, 'PRAGMA writable_schema = ON')  # ignore the definitions that do not parse
        for rowid in range(1, 4 * len(ROSBAG2_TABLES)):
            got, _ = _rows(conn, 'SELECT type, name, tbl_name, rootpage FROM sqlite_master WHERE rowid = ?', (rowid,))
            for kind, name, tbl_name, root in got:
                names = difflib.get_close_matches(_text(name), list(ROSBAG2_TABLES), n=1, cutoff=0.8) or \
                    difflib.get_close_matches(_text(tbl_name), list(ROSBAG2_TABLES), n=1, cutoff=0.8)
                if kind == b'table' and names and isinstance(root, int) and 2 <= root <= pages:
                    roots.setdefault(names[0], root)
    finally:
        conn.close()
    return roots


def rebuild_schema(src: Path, dst: Path) -> dict[str, int]:
    """Copy ``src`` to ``dst`` with a new page 1: the rosbag2 tables on their old root pages.

    The root pages are read from the damaged definitions where SQLite still can (one row at a
    time, with ``writable_schema``); a table whose row is unreadable gets the page rosbag2's
    creation order gives it, unless another table holds that page. The index and the free-page
    list are dropped (not needed to read).

    Returns:
        table -> root page used.

    Raises:
        ValueError: the file is not a whole number of pages.
        OSError, sqlite3.Error: the copy cannot be written.
    """
    data = src.read_bytes()
    size = _page_size(data)
    pages = len(data) // size
    roots = _root_pages(src, pages)
    for k, name in enumerate(ROSBAG2_TABLES):
        if name not in roots and k + 2 <= pages and k + 2 not in roots.values():
            roots[name] = k + 2
    fresh = dst.with_name(dst.name + '.schema')
    fresh.unlink(missing_ok=True)
    conn = sqlite3.connect(fresh)
    try:
        conn.execute(f'PRAGMA page_size = {size}')
        conn.executescript(';\n'.join(ROSBAG2_TABLES[n] for n in roots) + ';')
        conn.execute('PRAGMA writable_schema = ON')
        for name, root in roots.items():
            conn.execute('UPDATE sqlite_master SET rootpage = ? WHERE name = ?', (root, name))
        conn.commit()
    finally:
        conn.close()
    page1 = fresh.read_bytes()[:size]
    fresh.unlink()
    out = bytearray(data)
    out[:size] = page1
    out[28:32] = pages.to_bytes(4, 'big')  # database size in pages
    out[32:40] = bytes(8)  # no free-page list
    out[92:96] = out[24:28]  # the size above is valid for this change counter
    dst.write_bytes(bytes(out))
    return roots
