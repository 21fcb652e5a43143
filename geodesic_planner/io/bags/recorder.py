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

Write failures (a full disk). A message is counted once the storage holds it and it was not
lost since: ``counts`` never include a message SQLite rolled back or one refused while the
storage could not be written, so after ``close()`` the counts, the closing summary and
``metadata.yaml`` are what the storage file holds. When a flush fails, what the storage could
keep (MCAP bytes in memory, an open SQLite transaction) is retried every half flush period and
new messages are refused (:class:`BagError`, counted in :attr:`BagRecorder.lost`) until a flush
succeeds again; what SQLite rolled back is counted as lost at once. Every failure is either
raised to the caller (``write``) or, when no caller is there (background flush), passed to the
``on_error`` callback; :attr:`BagRecorder.failures` counts both.
"""
from __future__ import annotations

import math
import os
import sqlite3
import threading
import time
from collections.abc import Callable, Mapping
from datetime import datetime, UTC
from pathlib import Path
from typing import TYPE_CHECKING

from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, WriterError

from ...core.errors import BagError
from ..storages import STORAGE_SUFFIX, STORAGES
from .cdr import make_typestore, qos_profile
from .storage import FlushableWriter

if TYPE_CHECKING:
    from types import TracebackType

    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}

__all__ = ['STORAGES', 'STORAGE_SUFFIX', 'BagRecorder', 'new_bag_path']


def new_bag_path(path: str | os.PathLike[str], *, prefix: str = 'bag', now: datetime | None = None) -> Path:
    """Where a new recording should go, never an existing bag or file.

    * ``path`` does not exist, or is an empty directory: ``path`` itself;
    * ``path`` is a bag (has ``metadata.yaml`` or a storage file): a sibling
      ``<path>_<UTC timestamp>``;
    * ``path`` is another non-empty directory, or a mount point (empty or not: it cannot be
      replaced by a new directory): ``<path>/<prefix>_<UTC timestamp>``.
    A numeric suffix ``_2``, ``_3``... makes the name unique.

    Raises:
        BagError: ``path`` is a file, or a directory that cannot be listed.
    """
    base = Path(path)
    if not base.exists():
        return base
    if not base.is_dir():
        msg = f'bag path is an existing file, not a directory: {base}'
        raise BagError(msg)
    if not os.path.ismount(base) and _is_empty_dir(base):
        return base
    stamp = (now or datetime.now(UTC)).strftime('%Y%m%dT%H%M%SZ')
    candidate = base.parent / f'{base.name}_{stamp}' if _looks_like_bag(base) else base / f'{prefix}_{stamp}'
    unique, k = candidate, 2
    while unique.exists():
        unique = candidate.with_name(f'{candidate.name}_{k}')
        k += 1
    return unique


def _is_empty_dir(path: Path) -> bool:
    try:
        return not any(path.iterdir())
    except OSError as err:
        msg = f'cannot use {path} as bag path: {err.strerror or err}'
        raise BagError(msg) from err


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
        on_error: called with a one-line reason for every failure no caller sees (a background
            flush that failed), possibly from the flush thread.

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
        on_error: Callable[[str], None] | None = None,
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
        self._counts: dict[str, int] = {}  # in the storage file (flushed)
        self._pending: dict[str, int] = {}  # handed to the storage since the last flush
        self._lost: dict[str, int] = {}  # never reached the file
        self._failures = 0
        self._last_error: str | None = None
        self._failing = False  # a flush failed and the storage still holds its data
        self._on_error = on_error
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
        """Messages written per topic and not lost (after ``close()``: what the file holds)."""
        with self._lock:
            return {t: n + self._pending[t] for t, n in self._counts.items()}

    @property
    def flushed_counts(self) -> dict[str, int]:
        """Messages per topic already in the storage file (what survives a kill)."""
        with self._lock:
            return dict(self._counts)

    @property
    def lost(self) -> dict[str, int]:
        """Messages per topic given to :meth:`write` that never reached the file (write failures)."""
        with self._lock:
            return {t: n for t, n in self._lost.items() if n}

    @property
    def failures(self) -> int:
        """Failed writes and flushes so far."""
        with self._lock:
            return self._failures

    @property
    def last_error(self) -> str | None:
        """Reason of the last failure (None: none)."""
        with self._lock:
            return self._last_error

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
                if self._path.is_dir() and _is_empty_dir(self._path):
                    self._replace_empty_dir()
                else:
                    msg = f'bag directory exists: {self._path} (a recording never overwrites; choose a new path)'
                    raise BagError(msg)
            if self._typestore is None:
                self._typestore = make_typestore()
            writer = FlushableWriter(self._path, version=9, storage_plugin=PLUGINS[self._storage])
            for key, value in self._custom_data.items():
                writer.set_custom_data(key, value)
            try:
                writer.open()  # custom data stored at once: a killed recording keeps it
            except (WriterError, OSError, sqlite3.Error) as err:
                msg = f'cannot create bag {self._path}: {err}'
                raise BagError(msg) from err
            self._writer = writer
            try:
                for topic, msgtype in self._initial_topics.items():
                    self.add_topic(topic, msgtype)
                self._flush_locked(writer)
            except BaseException:
                self._abort_locked()
                raise
        if self._flush_period is not None:
            self._thread = threading.Thread(target=self._flusher, name='bag-flusher', daemon=True)
            self._thread.start()
        return self

    def _replace_empty_dir(self) -> None:
        """Remove the empty bag directory (rosbags creates it anew), or explain why it cannot be."""
        try:
            self._path.rmdir()
        except OSError as err:
            why = 'it is a mount point' if os.path.ismount(self._path) else (err.strerror or str(err))
            msg = (f'cannot record into the empty directory {self._path}: {why} (a bag is created as a '
                   f'new directory; give a path inside it, e.g. {self._path / "bag"})')
            raise BagError(msg) from err

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
            except (WriterError, OSError, sqlite3.Error) as err:
                msg = f'cannot add topic {topic} to {self._path}: {err}'
                raise BagError(msg) from err
            self._connections[topic] = conn
            self._counts[topic] = 0
            self._pending[topic] = 0
            self._lost[topic] = 0
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
            BagError: recorder not open, topic not registered, negative stamp; or the message
                was not written (storage failure, or an earlier flush still failing): it is
                counted in :attr:`lost`.
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
            if self._failing and time.monotonic() - self._last_flush >= self._retry_period():
                self._try_flush_locked()  # an earlier flush failed: retry before refusing
            if self._failing:
                self._lost[topic] += 1
                self._failures += 1
                msg = (f'cannot write to {self._path}: message on {topic} dropped, the storage still '
                       f'cannot be written ({self._last_error})')
                raise BagError(msg)
            try:
                writer.write(conn, stamp, bytes(data))
            except (WriterError, OSError, sqlite3.Error) as err:
                self._lost[topic] += 1
                self._failed_locked(writer, err)
                msg = f'cannot write to {self._path}: message on {topic} dropped: {err}'
                raise BagError(msg) from err
            self._pending[topic] += 1
            self._dirty = True
            if self._flush_period is not None and time.monotonic() - self._last_flush >= self._flush_period:
                self._try_flush_locked()

    def flush(self) -> None:
        """Push everything written so far to the storage file (no-op when closed).

        Raises:
            BagError: the storage file could not be written (see the module docstring).
        """
        with self._lock:
            if self._writer is not None:
                self._flush_locked(self._writer)

    def _retry_period(self) -> float:
        return self._flush_period / 2.0 if self._flush_period is not None else 0.25

    def _failed_locked(self, writer: FlushableWriter, err: BaseException) -> str:
        """Account for a failed storage operation; returns what happened to the pending messages."""
        self._failures += 1
        self._last_error = str(err) or type(err).__name__
        waiting = sum(self._pending.values())
        if writer.has_pending():
            self._failing = waiting > 0 or self._failing
            return f'{waiting} message(s) kept for the next attempt' if waiting else 'no message lost'
        for topic, n in self._pending.items():  # rolled back (SQLite) or dropped
            self._lost[topic] += n
            self._pending[topic] = 0
        self._failing = False
        return f'{waiting} message(s) lost' if waiting else 'no message lost'

    def _flush_locked(self, writer: FlushableWriter) -> None:
        if self._dirty or self._failing:
            try:
                writer.flush()
            except (OSError, sqlite3.Error, WriterError) as err:
                self._last_flush = time.monotonic()
                outcome = self._failed_locked(writer, err)
                msg = f'cannot write to {self._path}: {err} ({outcome})'
                raise BagError(msg) from err
            for topic, n in self._pending.items():
                self._counts[topic] += n
                self._pending[topic] = 0
            self._dirty = False
            self._failing = False
        self._last_flush = time.monotonic()

    def _try_flush_locked(self) -> None:
        """Flush where no caller sees a failure: it goes to ``on_error``."""
        assert self._writer is not None
        try:
            self._flush_locked(self._writer)
        except BagError as err:
            if self._on_error is not None:
                self._on_error(str(err))

    def _flusher(self) -> None:
        period = self._flush_period
        assert period is not None
        while not self._stop.wait(period / 2.0):
            with self._lock:
                if self._writer is None:
                    return
                if (self._dirty or self._failing) and time.monotonic() - self._last_flush >= period / 2.0:
                    self._try_flush_locked()

    def close(self) -> None:
        """Finish the bag: storage index/summary and ``metadata.yaml``. Idempotent.

        The messages still pending are flushed first; ``metadata.yaml`` then gets the counts of
        what the storage file holds (:attr:`counts`), also after write failures.

        Raises:
            BagError: the storage could not be finalised (the bag can still be repaired; what
                the file holds is in :attr:`counts`, what never reached it in :attr:`lost`).
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
            repair_hint = f'run `geodesic-bag repair {self._path}`'
            try:
                self._flush_locked(writer)
            except BagError as err:
                for topic, n in self._pending.items():  # what the last flush could not write is lost
                    self._lost[topic] += n
                    self._pending[topic] = 0
                writer.abort()
                msg = f'cannot finish bag {self._path}: {err}; {repair_hint}'
                raise BagError(msg) from err
            for topic, conn in self._connections.items():
                writer.counts[conn.id] = self._counts[topic]  # metadata.yaml: what the file holds
            try:
                writer.close()
            except (WriterError, OSError, sqlite3.Error) as err:
                self._failures += 1
                self._last_error = str(err)
                if writer.storage is not None:
                    writer.abort()
                msg = f'cannot finish bag {self._path}: {err}; {repair_hint}'
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
