"""Recording raw CDR messages into a new rosbag2 directory (``mcap`` or ``sqlite3``, metadata v9).

:class:`BagRecorder` stores the message types, their definitions and type hashes (RIHS01) and the
offered QoS profiles, so ``ros2 bag info``/``ros2 bag play`` and Foxglove read the bag.

Crash behaviour. The storage is flushed at least every ``flush_period`` seconds (default 0.5 s),
from a background thread and after any write that finds the last flush older than that: the
pending MCAP chunk is written and the file flushed (the OS keeps it across a process kill), the
SQLite transaction is committed (see :mod:`.storage`). After a SIGKILL, at most the messages of
the last ``flush_period`` seconds are missing; the bag lacks its index and ``metadata.yaml`` and
:func:`~geodesic_planner.io.bags.repair.repair` (``geodesic-bag repair BAG``) restores both.
SIGINT/SIGTERM handled by the caller's ``close()`` lose nothing.
"""
from __future__ import annotations

import math
import sqlite3
import threading
import time
from collections.abc import Mapping
from datetime import datetime, UTC
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, WriterError

from ...core.errors import BagError
from .cdr import make_typestore, qos_profile
from .storage import FlushableWriter

if TYPE_CHECKING:
    import os
    from types import TracebackType

    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

STORAGES = ('mcap', 'sqlite3')
STORAGE_SUFFIX = {'mcap': '.mcap', 'sqlite3': '.db3'}
PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}

__all__ = ['STORAGES', 'STORAGE_SUFFIX', 'BagRecorder', 'new_bag_path']


def new_bag_path(path: str | os.PathLike[str], *, prefix: str = 'bag', now: datetime | None = None) -> Path:
    """Where a new recording should go, never an existing bag or file.

    * ``path`` does not exist, or is an empty directory: ``path`` itself;
    * ``path`` is a bag (has ``metadata.yaml`` or a storage file): a sibling
      ``<path>_<UTC timestamp>``;
    * ``path`` is another non-empty directory: ``<path>/<prefix>_<UTC timestamp>``.
    A numeric suffix ``_2``, ``_3``... makes the name unique.

    Raises:
        BagError: ``path`` is a file.
    """
    base = Path(path)
    if not base.exists():
        return base
    if not base.is_dir():
        msg = f'bag path is an existing file, not a directory: {base}'
        raise BagError(msg)
    if not any(base.iterdir()):
        return base
    stamp = (now or datetime.now(UTC)).strftime('%Y%m%dT%H%M%SZ')
    candidate = base.parent / f'{base.name}_{stamp}' if _looks_like_bag(base) else base / f'{prefix}_{stamp}'
    unique, k = candidate, 2
    while unique.exists():
        unique = candidate.with_name(f'{candidate.name}_{k}')
        k += 1
    return unique


def _looks_like_bag(path: Path) -> bool:
    return (path / 'metadata.yaml').exists() or any(
        p.suffix in ('.mcap', '.db3') for p in path.iterdir())


class BagRecorder:
    """Context-managed rosbag2 recorder of raw CDR messages.

    Example::

        with BagRecorder(path, storage='mcap', topics={'/chatter': 'std_msgs/msg/String'}) as rec:
            rec.write('/chatter', stamp_ns, cdr_bytes)

    Args:
        path: new bag directory (must not exist, or be an empty directory).
        storage: 'mcap' (default, as rosbag2 in Jazzy) or 'sqlite3'.
        topics: topic -> message type (e.g. ``'trajectory_msgs/msg/JointTrajectory'``) to
            register at open; more with :meth:`add_topic`.
        qos: offered QoS written to the metadata: one profile for all topics, a mapping
            topic -> profile (missing topics get the default), or None for
            ``qos_profile()`` (reliable, volatile, keep_last 10).
        flush_period: longest time (s) data may sit in memory; None disables flushing (data
            reaches the file only at ``close()``).
        typestore: rosbags typestore (default: a fresh ROS 2 Jazzy store).
        custom_data: string key/values stored in ``metadata.yaml`` (``custom_data``), e.g. the
            recording node's parameters.

    Raises:
        BagError: unknown storage, non-positive flush period, non-string custom data.

    Thread-safe: ``write``/``flush``/``close`` may be called from different threads.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        storage: str = 'mcap',
        topics: Mapping[str, str] | None = None,
        qos: Qos | Mapping[str, Qos] | None = None,
        flush_period: float | None = 0.5,
        typestore: Typestore | None = None,
        custom_data: Mapping[str, str] | None = None,
    ) -> None:
        if storage not in STORAGES:
            msg = f'unknown storage {storage!r}; expected one of {", ".join(STORAGES)}'
            raise BagError(msg)
        if flush_period is not None and not (math.isfinite(flush_period) and flush_period > 0):
            msg = f'flush_period must be > 0 s or None, got {flush_period!r}'
            raise BagError(msg)
        if custom_data is not None and not all(isinstance(k, str) and isinstance(v, str)
                                               for k, v in custom_data.items()):
            msg = 'custom_data keys and values must be strings'
            raise BagError(msg)
        self._custom_data = dict(custom_data or {})
        self._path = Path(path)
        self._storage = storage
        self._initial_topics = dict(topics or {})
        self._qos = qos
        self._flush_period = flush_period
        self._typestore = typestore
        self._writer: FlushableWriter | None = None
        self._connections: dict[str, Connection] = {}
        self._counts: dict[str, int] = {}
        self._closed = False
        self._lock = threading.RLock()
        self._dirty = False
        self._last_flush = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- properties
    @property
    def path(self) -> Path:
        """Bag directory."""
        return self._path

    @property
    def storage(self) -> str:
        """'mcap' or 'sqlite3'."""
        return self._storage

    @property
    def counts(self) -> dict[str, int]:
        """Messages written per topic so far."""
        with self._lock:
            return dict(self._counts)

    @property
    def is_open(self) -> bool:
        """True between open() and close()."""
        return self._writer is not None

    @property
    def topics(self) -> dict[str, str]:
        """Registered topic -> message type."""
        with self._lock:
            return {t: c.msgtype for t, c in self._connections.items()}

    # -- lifecycle
    def open(self) -> BagRecorder:
        """Create the bag directory and storage file and register the initial topics.

        Raises:
            BagError: already opened/closed, bag directory exists (and is not empty), cannot create.
        """
        with self._lock:
            if self._writer is not None or self._closed:
                msg = f'recorder for {self._path} was already opened'
                raise BagError(msg)
            if self._path.exists():
                if self._path.is_dir() and not any(self._path.iterdir()):
                    self._path.rmdir()  # empty directory: use it (rosbags creates it anew)
                else:
                    msg = f'bag directory exists: {self._path} (a recording never overwrites; choose a new path)'
                    raise BagError(msg)
            if self._typestore is None:
                self._typestore = make_typestore()
            writer = FlushableWriter(self._path, version=9, storage_plugin=PLUGINS[self._storage])
            for key, value in self._custom_data.items():
                writer.set_custom_data(key, value)
            try:
                writer.open()
            except (WriterError, OSError) as err:
                msg = f'cannot create bag {self._path}: {err}'
                raise BagError(msg) from err
            self._writer = writer
            try:
                for topic, msgtype in self._initial_topics.items():
                    self.add_topic(topic, msgtype)
                self._flush_locked()
            except BaseException:
                self._abort_locked()
                raise
        if self._flush_period is not None:
            self._thread = threading.Thread(target=self._flusher, name='bag-flusher', daemon=True)
            self._thread.start()
        return self

    def add_topic(self, topic: str, msgtype: str, qos: Qos | None = None) -> None:
        """Register a topic (its type definition, hash and offered QoS go into the bag).

        Raises:
            BagError: not open, unknown type, topic already registered with another type.
        """
        with self._lock:
            writer = self._require_open()
            assert self._typestore is not None
            if topic in self._connections:
                if self._connections[topic].msgtype != msgtype:
                    msg = (f'topic {topic} already recorded as {self._connections[topic].msgtype}, '
                           f'not {msgtype}')
                    raise BagError(msg)
                return
            if msgtype not in self._typestore.fielddefs:
                msg = f'unknown message type {msgtype!r} for topic {topic}'
                raise BagError(msg)
            profile = qos if qos is not None else self._default_qos(topic)
            try:
                conn = writer.add_connection(topic, msgtype, typestore=self._typestore,
                                             offered_qos_profiles=[profile])
            except WriterError as err:
                msg = f'cannot add topic {topic} to {self._path}: {err}'
                raise BagError(msg) from err
            self._connections[topic] = conn
            self._counts[topic] = 0
            self._dirty = True

    def _default_qos(self, topic: str) -> Qos:
        if isinstance(self._qos, Qos):
            return self._qos
        if isinstance(self._qos, Mapping) and topic in self._qos:
            return self._qos[topic]
        return qos_profile()

    def write(self, topic: str, stamp_ns: int, data: bytes | bytearray | memoryview) -> None:
        """Append one serialized message.

        Args:
            topic: a registered topic.
            stamp_ns: receive time, ns since the epoch (rosbag2's log time).
            data: CDR bytes exactly as on the wire (``raw=True`` subscription or :func:`to_cdr`).

        Raises:
            BagError: recorder not open, topic not registered, negative stamp.
        """
        with self._lock:
            writer = self._require_open()
            conn = self._connections.get(topic)
            if conn is None:
                recorded = ', '.join(self._connections) or 'none'
                msg = f'topic {topic} is not recorded in {self._path} (recorded: {recorded})'
                raise BagError(msg)
            stamp = int(stamp_ns)
            if stamp < 0:
                msg = f'negative timestamp {stamp} ns'
                raise BagError(msg)
            try:
                writer.write(conn, stamp, bytes(data))
            except (WriterError, OSError) as err:
                msg = f'cannot write to {self._path}: {err}'
                raise BagError(msg) from err
            self._counts[topic] += 1
            self._dirty = True
            if self._flush_period is not None and time.monotonic() - self._last_flush >= self._flush_period:
                self._flush_locked()

    def flush(self) -> None:
        """Push everything written so far to the storage file (no-op when closed)."""
        with self._lock:
            if self._writer is not None:
                self._flush_locked()

    def _flush_locked(self) -> None:
        writer = self._writer
        assert writer is not None
        if self._dirty:
            try:
                writer.flush()
            except (OSError, sqlite3.Error) as err:
                msg = f'cannot flush {self._path}: {err}'
                raise BagError(msg) from err
            self._dirty = False
        self._last_flush = time.monotonic()

    def _flusher(self) -> None:
        period = self._flush_period
        assert period is not None
        while not self._stop.wait(period / 2.0):
            with self._lock:
                if self._writer is None:
                    return
                if self._dirty and time.monotonic() - self._last_flush >= period / 2.0:
                    try:
                        self._flush_locked()
                    except BagError:
                        return

    def close(self) -> None:
        """Finish the bag: storage index/summary and ``metadata.yaml``. Idempotent.

        Raises:
            BagError: the storage could not be finalised (the bag can still be repaired).
        """
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=5.0)
        with self._lock:
            writer, self._writer = self._writer, None
            self._closed = True
            if writer is None:
                return
            try:
                writer.close()
            except (WriterError, OSError, sqlite3.Error) as err:
                msg = f'cannot finish bag {self._path}: {err}; run `geodesic-bag repair {self._path}`'
                raise BagError(msg) from err

    def _abort_locked(self) -> None:
        writer, self._writer = self._writer, None
        self._closed = True
        if writer is not None:
            writer.abort()

    def _require_open(self) -> FlushableWriter:
        if self._writer is None:
            state = 'closed' if self._closed else 'not open'
            msg = f'bag recorder for {self._path} is {state}'
            raise BagError(msg)
        return self._writer

    def __enter__(self) -> BagRecorder:
        """Open (see :meth:`open`)."""
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """Close, also after an exception: what was written stays readable."""
        self.close()


# ----------------------------------------------------------------------------------------------
# Reading
