"""rosbag2 storage files that can be flushed while recording (MCAP and SQLite 3).

rosbags' :class:`~rosbags.rosbag2.Writer` keeps data in memory until ``close()`` (whole MCAP
chunks of 1 MiB; one open SQLite transaction) and offers no flush. Its storage backends are
chosen through the public class attribute ``Writer.STORAGE_PLUGINS`` and talk to the writer
through its ``StorageWriter`` protocol (``path``, ``add_msgtype``, ``add_connection``,
``write``, ``close``, ``abort``). :class:`FlushableWriter` plugs in the two storages below, which
implement that protocol plus :meth:`flush`, so the recorder uses only public API:

* :class:`McapStorage` writes through the ``mcap`` package's :class:`mcap.writer.Writer`
  (``flush()`` closes the pending chunk and writes it to the file);
* :class:`Sqlite3Storage` writes the rosbag2 SQLite schema (version 4) and commits on ``flush()``.

rosbags still builds the connections, type hashes and ``metadata.yaml``.

Custom data survives a kill. ``metadata.yaml`` and the storage's own copy of the metadata are
written at ``close()``; :class:`FlushableWriter` also stores the bag's ``custom_data`` when it opens
(MCAP: a metadata record named :data:`CUSTOM_DATA_RECORD`; SQLite: the table of the same name,
``key``/``value`` rows), so that :func:`~geodesic_planner.io.bags.repair.repair` gives it back to
a recording that never closed. rosbag2 and rosbags ignore both.

Write failures (a full disk). Both storages touch the file only in ``flush()`` and ``close()``
(SQLite also when its page cache spills during an insert). A failed flush raises and keeps what
it could not write when it can: the MCAP bytes stay in memory and the file is cut back to its last
complete flush (:class:`_FileSink`), the SQLite transaction stays open unless SQLite rolled it
back. :meth:`has_pending` tells the recorder which of the two happened, so that it counts only
what is in the file.
"""
from __future__ import annotations

import os
import sqlite3
from importlib.metadata import version
from typing import IO, TYPE_CHECKING, Any, ClassVar, cast

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from rosbags.interfaces import MessageDefinitionFormat
from rosbags.rosbag2 import CompressionMode, StoragePlugin, Writer, WriterError

if TYPE_CHECKING:
    from collections.abc import Mapping
    from pathlib import Path

    from rosbags.interfaces import Connection

__all__ = ['CUSTOM_DATA_RECORD', 'FlushableWriter', 'McapStorage', 'Sqlite3Storage']

#: MCAP metadata record / SQLite table holding the bag's custom data from the start of a recording.
CUSTOM_DATA_RECORD = 'geodesic_planner_custom_data'


def _schema_encoding(connection: Connection) -> str:
    return 'ros2msg' if connection.msgdef.format == MessageDefinitionFormat.MSG else 'ros2idl'


def _serialization_format(connection: Connection) -> str:
    return str(getattr(connection.ext, 'serialization_format', 'cdr'))


class _FileSink:
    """Append-only binary stream for the mcap writer that never leaves half a flush in the file.

    ``write`` only buffers; :meth:`flush` appends the buffer to the file. When that fails (no space
    left), the file is cut back to the end of the last complete flush and the bytes are kept for
    the next attempt, so the file always holds whole records and ``tell()`` stays the offset the
    next record will have.
    """

    def __init__(self, path: Path) -> None:
        self._file = path.open('xb', buffering=0)
        self._size = 0  # bytes in the file (whole flushes)
        self._buf = bytearray()

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Buffer ``data``; returns its length."""
        self._buf += data
        return len(data)

    def tell(self) -> int:
        """Offset of the next byte written (file and buffer)."""
        return self._size + len(self._buf)

    @property
    def pending(self) -> int:
        """Bytes not yet in the file."""
        return len(self._buf)

    def flush(self) -> None:
        """Append the buffer to the file.

        Raises:
            OSError: the write failed; the file is back at its previous size, the bytes kept.
        """
        if not self._buf:
            return
        done = 0
        try:
            with memoryview(self._buf) as view:
                while done < len(view):
                    n = self._file.write(view[done:])
                    if not n:
                        raise OSError(f'short write to {self._file.name}')
                    done += n
        except OSError:
            if done:
                try:
                    os.ftruncate(self._file.fileno(), self._size)
                    self._file.seek(self._size)
                except OSError:
                    pass
            raise
        self._size += len(self._buf)
        self._buf = bytearray()

    def close(self) -> None:
        """Close the file (unflushed bytes are dropped)."""
        self._file.close()


class McapStorage:
    """MCAP storage file ``<bag>/<bag name>.mcap`` (ROS 2 profile, uncompressed chunks of 1 MiB)."""

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        """Create the file; ``path`` is the bag directory (already created by the writer).

        Raises:
            WriterError: compression requested (not supported by this recorder).
        """
        if compression != CompressionMode.NONE:
            msg = 'the flushable MCAP storage writes uncompressed chunks only'
            raise WriterError(msg)
        self.path = path / f'{path.name}.mcap'
        self._file = _FileSink(self.path)
        self._mcap = McapWriter(cast('IO[Any]', self._file), compression=CompressionType.NONE)
        self._mcap.start(profile='ros2', library=f'geodesic_planner (mcap {version("mcap")})')
        self._schemas: dict[str, int] = {}
        self._channels: dict[int, int] = {}

    def add_msgtype(self, connection: Connection) -> None:
        """Register the message definition of ``connection.msgtype`` as an MCAP schema."""
        self._schemas[connection.msgtype] = self._mcap.register_schema(
            connection.msgtype, _schema_encoding(connection), connection.msgdef.data.encode())

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Register a topic as an MCAP channel with its offered QoS (rosbag2 metadata text)."""
        self._channels[connection.id] = self._mcap.register_channel(
            connection.topic, _serialization_format(connection), self._schemas[connection.msgtype],
            {'offered_qos_profiles': offered_qos_profiles, 'topic_type_hash': connection.digest})

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Append one message; ``timestamp`` is the log time, ns since the epoch."""
        self._mcap.add_message(self._channels[connection.id], log_time=timestamp, data=bytes(data),
                               publish_time=timestamp)

    def write_custom_data(self, custom_data: Mapping[str, str]) -> None:
        """Store the bag's custom data now (a metadata record, in the file at the next flush)."""
        self._mcap.add_metadata(CUSTOM_DATA_RECORD, dict(custom_data))

    def flush(self) -> None:
        """Close the pending chunk (if it holds messages) and write everything to the file.

        Raises:
            OSError: the file could not be written; see :meth:`has_pending`.
        """
        self._mcap.flush()  # ends with the sink's flush (also a retry of an earlier failed one)

    def has_pending(self) -> bool:
        """True when bytes of a failed flush wait in memory for the next one."""
        return self._file.pending > 0

    def close(self, version: int, metadata: str) -> None:
        """Write the rosbag2 metadata record, the summary and the footer; close the file."""
        _ = version
        try:
            self._mcap.add_metadata('rosbag2', {'serialized_metadata': metadata})
            self._mcap.finish()
            self._file.flush()
        finally:
            self._file.close()

    def abort(self) -> None:
        """Close the file without summary (what was flushed stays for repair)."""
        self._file.close()


class Sqlite3Storage:
    """SQLite storage file ``<bag>/<bag name>.db3`` (rosbag2 schema version 4)."""

    _SCHEMA = """
    CREATE TABLE schema(schema_version INTEGER PRIMARY KEY, ros_distro TEXT NOT NULL);
    CREATE TABLE metadata(id INTEGER PRIMARY KEY, metadata_version INTEGER NOT NULL,
                          metadata TEXT NOT NULL);
    CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL,
                        serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL,
                        type_description_hash TEXT NOT NULL);
    CREATE TABLE message_definitions(id INTEGER PRIMARY KEY, topic_type TEXT NOT NULL,
                                     encoding TEXT NOT NULL,
                                     encoded_message_definition TEXT NOT NULL,
                                     type_description_hash TEXT NOT NULL);
    CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL,
                          timestamp INTEGER NOT NULL, data BLOB NOT NULL);
    CREATE INDEX timestamp_idx ON messages (timestamp ASC);
    INSERT INTO schema(schema_version, ros_distro) VALUES (4, 'jazzy');
    """

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        """Create the database; ``path`` is the bag directory.

        Raises:
            WriterError: storage compression requested (SQLite bags have none).
        """
        if compression == CompressionMode.STORAGE:
            msg = 'SQLite 3 storage does not support storage compression'
            raise WriterError(msg)
        self.path = path / f'{path.name}.db3'
        self._db = sqlite3.connect(f'file:{self.path}?mode=rwc', uri=True, check_same_thread=False)
        self._db.executescript(self._SCHEMA)

    def add_msgtype(self, connection: Connection) -> None:
        """Store the message definition of ``connection.msgtype``."""
        self._db.execute(
            'INSERT INTO message_definitions (topic_type, encoding, encoded_message_definition, '
            'type_description_hash) VALUES (?, ?, ?, ?)',
            (connection.msgtype, _schema_encoding(connection), connection.msgdef.data, connection.digest))

    def add_connection(self, connection: Connection, offered_qos_profiles: str) -> None:
        """Store a topic with its offered QoS (rosbag2 metadata text)."""
        self._db.execute(
            'INSERT INTO topics VALUES (?, ?, ?, ?, ?, ?)',
            (connection.id, connection.topic, connection.msgtype, _serialization_format(connection),
             offered_qos_profiles, connection.digest))

    def write(self, connection: Connection, timestamp: int, data: bytes | memoryview) -> None:
        """Insert one message; ``timestamp`` is the log time, ns since the epoch."""
        self._db.execute('INSERT INTO messages (topic_id, timestamp, data) VALUES (?, ?, ?)',
                         (connection.id, timestamp, bytes(data)))

    def write_custom_data(self, custom_data: Mapping[str, str]) -> None:
        """Store the bag's custom data now (table ``CUSTOM_DATA_RECORD``, committed at the next flush)."""
        self._db.execute(f'CREATE TABLE {CUSTOM_DATA_RECORD}(key TEXT PRIMARY KEY, value TEXT NOT NULL)')
        self._db.executemany(f'INSERT INTO {CUSTOM_DATA_RECORD} VALUES (?, ?)', list(custom_data.items()))

    def flush(self) -> None:
        """Commit the open transaction (committed rows survive a process kill).

        Raises:
            sqlite3.Error: the commit failed; see :meth:`has_pending`.
        """
        self._db.commit()

    def has_pending(self) -> bool:
        """True while a transaction is open (rows written, not committed, not rolled back)."""
        return self._db.in_transaction

    def close(self, version: int, metadata: str) -> None:
        """Store the rosbag2 metadata, commit and close."""
        try:
            self._db.execute('INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)',
                             (version, metadata))
            self._db.commit()
        finally:
            self._db.close()

    def abort(self) -> None:
        """Close; rows not yet committed are rolled back."""
        self._db.close()


class FlushableWriter(Writer):
    """rosbags :class:`~rosbags.rosbag2.Writer` whose storages have a :meth:`flush`."""

    STORAGE_PLUGINS: ClassVar[Mapping[StoragePlugin, type]] = {  # type: ignore[misc]
        StoragePlugin.MCAP: McapStorage,
        StoragePlugin.SQLITE3: Sqlite3Storage,
    }

    def open(self) -> None:
        """Open for writing (see rosbags' ``Writer.open``); the custom data set so far is stored at once.

        Raises:
            WriterError: the bag directory exists.
            OSError, sqlite3.Error: the storage file cannot be written.
        """
        super().open()
        storage = self.storage
        if self.custom_data and isinstance(storage, (McapStorage, Sqlite3Storage)):
            storage.write_custom_data(self.custom_data)
            storage.flush()

    def flush(self) -> None:
        """Push everything written so far to the storage file (no-op before open / after close)."""
        storage = self.storage
        if isinstance(storage, (McapStorage, Sqlite3Storage)):
            storage.flush()

    def has_pending(self) -> bool:
        """True when data written but not yet in the file is still held (retried by :meth:`flush`)."""
        storage = self.storage
        return isinstance(storage, (McapStorage, Sqlite3Storage)) and storage.has_pending()
