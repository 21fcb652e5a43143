"""rosbag2 recording and reading with rosbags (no rclpy, no rosbag2 needed).

* :class:`BagRecorder` writes raw CDR bytes (exactly as received from a ``raw=True``
  subscription) into a new rosbag2 directory (``mcap`` or ``sqlite3`` storage, metadata
  version 9) with the message types, their definitions and type hashes (RIHS01) and offered QoS
  profiles, so ``ros2 bag info``/``ros2 bag play`` and Foxglove read it.
* :func:`read_trajectories` returns every ``trajectory_msgs/msg/JointTrajectory`` of a bag as
  numpy arrays (:class:`TrajectoryRecord`); :func:`bag_info` summarises a bag.
* :func:`repair` makes a bag readable again after the recording process was killed (SIGKILL,
  power cut of the process) by rebuilding the storage index and ``metadata.yaml`` from what the
  storage file holds.

Crash behaviour (issue 7). rosbags' writers keep data in memory until ``close()``: the MCAP
writer buffers whole 1 MiB chunks, the SQLite writer keeps one transaction open. The recorder
therefore *flushes* at least every ``flush_period`` seconds (default 0.5 s) from a background
thread and after any write that finds the last flush older than that: the pending MCAP chunk is
closed and written to the file (``flush()`` of the file object; the OS keeps it across a process
kill), the SQLite transaction is committed. After a SIGKILL, at most the messages of the last
``flush_period`` seconds are missing; the bag lacks its index and ``metadata.yaml`` and
:func:`repair` (``geodesic-bag repair BAG``) restores both. SIGINT/SIGTERM handled by the
caller's ``close()`` lose nothing.

A typestore (``Stores.ROS2_JAZZY``) is created per recorder/reader, never shared module-wide.
"""
from __future__ import annotations

import math
import os
import shutil
import sqlite3
import struct
import threading
import time
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.interfaces import (
    Nodetype,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import ReaderError, StoragePlugin, Writer, WriterError
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, TypesysError, get_types_from_msg, get_typestore

from ..core.errors import BagError

if TYPE_CHECKING:
    from types import TracebackType

    from rosbags.interfaces import Connection
    from rosbags.typesys.store import Typestore

JOINT_TRAJECTORY = 'trajectory_msgs/msg/JointTrajectory'
JOINT_STATE = 'sensor_msgs/msg/JointState'
STORAGES = ('mcap', 'sqlite3')
STORAGE_SUFFIX = {'mcap': '.mcap', 'sqlite3': '.db3'}
_PLUGINS = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
_MCAP_MAGIC = b'\x89MCAP0\r\n'

__all__ = [
    'JOINT_STATE',
    'JOINT_TRAJECTORY',
    'STORAGES',
    'BagInfo',
    'BagRecorder',
    'RepairReport',
    'TopicSummary',
    'TrajectoryRecord',
    'TrajectorySummary',
    'bag_info',
    'from_cdr',
    'make_typestore',
    'new_bag_path',
    'qos_profile',
    'read_trajectories',
    'repair',
    'summarize_trajectory',
    'to_cdr',
]


# ----------------------------------------------------------------------------------------------
# Types, QoS, serialisation
# ----------------------------------------------------------------------------------------------
def make_typestore() -> Typestore:
    """A fresh ROS 2 Jazzy typestore (create one per use; do not share globally)."""
    return get_typestore(Stores.ROS2_JAZZY)


def qos_profile(
    *,
    reliability: str = 'reliable',
    durability: str = 'volatile',
    history: str = 'keep_last',
    depth: int = 10,
    liveliness: str = 'automatic',
) -> Qos:
    """An offered QoS profile for the bag metadata (what ``ros2 bag play`` will offer).

    Args:
        reliability: 'reliable' | 'best_effort' | 'system_default'.
        durability: 'volatile' | 'transient_local' | 'system_default'.
        history: 'keep_last' | 'keep_all' | 'system_default'.
        depth: history depth (>= 0).
        liveliness: 'automatic' | 'manual_by_topic' | 'system_default'.

    Deadline, lifespan and liveliness lease are 0 (= unspecified: the rmw default, infinite).

    Raises:
        BagError: unknown policy name or negative depth.
    """
    try:
        rel = QosReliability[reliability.upper()]
        dur = QosDurability[durability.upper()]
        his = QosHistory[history.upper()]
        liv = QosLiveliness[liveliness.upper()]
    except KeyError as err:
        msg = f'unknown QoS policy value {err.args[0]!r}'
        raise BagError(msg) from None
    if int(depth) < 0:
        msg = f'QoS depth must be >= 0, got {depth}'
        raise BagError(msg)
    zero = QosTime(0, 0)
    return Qos(his, int(depth), rel, dur, zero, zero, liv, zero, False)


def _qos_from_dict(item: Mapping[str, Any]) -> Qos:
    """rosbags Qos from one entry of rosbag2 ``offered_qos_profiles`` (v8 ints or v9 names)."""

    def enum(cls: Any, key: str) -> Any:  # noqa: ANN401
        value = item.get(key, 0)
        try:
            return cls(value) if isinstance(value, int) else cls[str(value).upper()]
        except (KeyError, ValueError):
            return cls.UNKNOWN

    def qtime(key: str) -> QosTime:
        value = item.get(key) or {}
        return QosTime(int(value.get('sec', 0)), int(value.get('nsec', 0)))

    return Qos(
        enum(QosHistory, 'history'), int(item.get('depth', 0)), enum(QosReliability, 'reliability'),
        enum(QosDurability, 'durability'), qtime('deadline'), qtime('lifespan'),
        enum(QosLiveliness, 'liveliness'), qtime('liveliness_lease_duration'),
        bool(item.get('avoid_ros_namespace_conventions', False)),
    )


def _parse_qos_text(text: str | bytes | None) -> list[Qos]:
    if not text:
        return []
    try:
        items = yaml.safe_load(text)
    except yaml.YAMLError:
        return []
    if not isinstance(items, list):
        return []
    return [_qos_from_dict(x) for x in items if isinstance(x, Mapping)]


_NUMPY_TYPES = {
    'bool': np.bool_, 'byte': np.uint8, 'char': np.uint8, 'octet': np.uint8,
    'int8': np.int8, 'uint8': np.uint8, 'int16': np.int16, 'uint16': np.uint16,
    'int32': np.int32, 'uint32': np.uint32, 'int64': np.int64, 'uint64': np.uint64,
    'float32': np.float32, 'float64': np.float64,
}


def _to_rosbags(obj: Any, msgtype: str, typestore: Typestore) -> object:  # noqa: ANN401
    """Convert an object with the message's attributes (e.g. an rclpy message) to rosbags'."""
    _, fields = typestore.fielddefs[msgtype]
    kwargs: dict[str, Any] = {}
    for name, (ntype, detail) in fields:
        value = getattr(obj, name)
        if ntype == Nodetype.BASE:
            base = detail[0]
            if base in ('string', 'wstring'):
                kwargs[name] = str(value)
            elif base in _NUMPY_TYPES:
                if isinstance(value, bytes):  # rclpy byte/char fields
                    value = ord(value)
                kwargs[name] = _NUMPY_TYPES[base](value).item()
            else:
                kwargs[name] = value
        elif ntype == Nodetype.NAME:
            kwargs[name] = _to_rosbags(value, detail, typestore)
        else:  # ARRAY or SEQUENCE
            (sub_type, sub_detail), _ = detail
            if sub_type == Nodetype.BASE and sub_detail[0] in _NUMPY_TYPES:
                dtype = _NUMPY_TYPES[sub_detail[0]]
                if isinstance(value, (bytes, bytearray)):
                    kwargs[name] = np.frombuffer(bytes(value), dtype=np.uint8).astype(dtype)
                elif len(value) and isinstance(value[0], bytes):  # rclpy byte[]: list of bytes
                    kwargs[name] = np.array([ord(v) for v in value], dtype=dtype)
                else:  # array.array, list, numpy: one buffer copy
                    kwargs[name] = np.array(value, dtype=dtype)
            elif sub_type == Nodetype.BASE:
                kwargs[name] = [str(v) for v in value]
            else:
                kwargs[name] = [_to_rosbags(v, sub_detail, typestore) for v in value]
    return typestore.types[msgtype](**kwargs)


def to_cdr(message: object, msgtype: str, typestore: Typestore | None = None) -> bytes:
    """Exact CDR bytes of a message given as any object with the message's fields.

    Use this for messages built with rclpy: ``rclpy.serialization.serialize_message`` returns the
    rmw's size estimate (4 junk bytes per empty ``float64[]``), which rosbags rejects on reading.

    Args:
        message: rclpy or rosbags message (attributes named as in the .msg definition).
        msgtype: e.g. ``'trajectory_msgs/msg/JointTrajectory'``.
        typestore: rosbags typestore (default: a fresh Jazzy store).

    Raises:
        BagError: unknown type or fields that do not match the definition.
    """
    store = typestore or make_typestore()
    if msgtype not in store.fielddefs:
        msg = f'unknown message type {msgtype!r}'
        raise BagError(msg)
    try:
        return bytes(store.serialize_cdr(_to_rosbags(message, msgtype, store), msgtype))
    except (AttributeError, TypeError, ValueError, SerdeError) as err:
        msg = f'cannot serialise {type(message).__name__} as {msgtype}: {err}'
        raise BagError(msg) from err


def from_cdr(data: bytes, msgtype: str, typestore: Typestore | None = None) -> object:
    """Decode CDR bytes into a rosbags message object.

    Raises:
        BagError: unknown type or bytes that are not a valid message of that type.
    """
    store = typestore or make_typestore()
    if msgtype not in store.fielddefs:
        msg = f'unknown message type {msgtype!r}'
        raise BagError(msg)
    try:
        return store.deserialize_cdr(bytes(data), msgtype)
    except SerdeError as err:
        msg = f'invalid {msgtype} CDR data ({len(data)} bytes): {err}'
        raise BagError(msg) from err


# ----------------------------------------------------------------------------------------------
# Recording
# ----------------------------------------------------------------------------------------------
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
    stamp = (now or datetime.now(timezone.utc)).strftime('%Y%m%dT%H%M%SZ')
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
        self._writer: Writer | None = None
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
            writer = Writer(self._path, version=9, storage_plugin=_PLUGINS[self._storage])
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
                msg = f'topic {topic} is not recorded in {self._path} (recorded: {", ".join(self._connections) or "none"})'
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
        # Reaches into rosbags 0.11 storage writers (pinned): there is no public flush.
        writer = self._writer
        assert writer is not None
        storage = writer.storage
        if self._dirty and storage is not None:
            try:
                if self._storage == 'mcap':
                    if storage.chunk.msgs:  # type: ignore[attr-defined]
                        storage.close_chunk()  # type: ignore[attr-defined]
                    storage.bio.flush()  # type: ignore[attr-defined]
                else:
                    storage.conn.commit()  # type: ignore[attr-defined]
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

    def _require_open(self) -> Writer:
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
# ----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TrajectoryRecord:
    """One recorded JointTrajectory as arrays.

    Attributes:
        topic: topic name.
        stamp_ns: bag (receive) time, ns since the epoch.
        joint_names: dof names.
        t: time_from_start, shape (N,), s.
        positions: shape (N, dof), rad or m (NaN where a point had the wrong number of values).
        velocities: shape (N, dof) when every point has dof velocities, else None.
        accelerations: shape (N, dof) when every point has dof accelerations, else None.
        header_stamp_ns: header.stamp, ns.
        frame_id: header.frame_id.
        problems: why joint_trajectory_controller would reject the message (empty: valid).
    """

    topic: str
    stamp_ns: int
    joint_names: list[str]
    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    header_stamp_ns: int = 0
    frame_id: str = ''
    problems: tuple[str, ...] = ()

    @property
    def duration(self) -> float:
        """time_from_start of the last point minus the first, s (0 for < 2 points)."""
        return float(self.t[-1] - self.t[0]) if self.t.size > 1 else 0.0


def _rows(points: list[Any], name: str, dof: int) -> tuple[np.ndarray | None, list[str]]:
    """Stack a per-point float64[] field into (N, dof).

    Positions are always returned (NaN rows where a point has the wrong count); velocities and
    accelerations only when every point has dof values (else None). Problems are listed like
    ``validate_joint_trajectory`` does (optional fields may be empty per point).
    """
    optional = name != 'positions'
    problems: list[str] = []
    out = np.full((len(points), dof), np.nan)
    full = np.zeros(len(points), dtype=bool)
    for i, p in enumerate(points):
        values = getattr(p, name)
        n = len(values)
        if n == dof:
            out[i] = np.asarray(values, dtype=float)
            full[i] = True
        elif not (optional and n == 0):
            problems.append(f'point {i}: {n} {name} for {dof} joints')
    nonfinite = np.flatnonzero(full & ~np.all(np.isfinite(out), axis=1))
    if nonfinite.size:
        problems.append(f'point {int(nonfinite[0])}: non-finite {name}')
    if optional and not (points and full.all()):
        return None, problems
    return out, problems


def _trajectory_record(topic: str, stamp_ns: int, msg: Any) -> TrajectoryRecord:  # noqa: ANN401
    names = [str(n) for n in msg.joint_names]
    dof = len(names)
    points = list(msg.points)
    t = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in points], dtype=float)
    problems: list[str] = []
    if dof == 0:
        problems.append('empty joint_names')
    if len(set(names)) != dof:
        problems.append('duplicate joint names')
    if not points:
        problems.append('no points')
    pos, p1 = _rows(points, 'positions', dof)
    vel, p2 = _rows(points, 'velocities', dof)
    acc, p3 = _rows(points, 'accelerations', dof)
    problems += p1 + p2 + p3
    bad_t = np.flatnonzero(np.diff(t) <= 0)
    if bad_t.size:
        i = int(bad_t[0]) + 1
        problems.append(f'point {i}: time_from_start {t[i]:.9f} s not after {t[i - 1]:.9f} s')
    assert pos is not None
    stamp = msg.header.stamp
    return TrajectoryRecord(
        topic=topic, stamp_ns=int(stamp_ns), joint_names=names, t=t, positions=pos,
        velocities=vel, accelerations=acc,
        header_stamp_ns=int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec),
        frame_id=str(msg.header.frame_id), problems=tuple(problems),
    )


def _resolve_bag_dir(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    if not p.exists():
        msg = f'no such bag: {p}'
        raise BagError(msg)
    if p.is_file():
        if p.suffix in ('.mcap', '.db3') and (p.parent / 'metadata.yaml').exists():
            return p.parent
        msg = f'not a bag: {p} is a file (give the rosbag2 directory)'
        raise BagError(msg)
    if not (p / 'metadata.yaml').exists():
        if any(x.suffix in ('.mcap', '.db3') for x in p.iterdir()):
            msg = (f'bag {p} has no metadata.yaml: the recording was interrupted; '
                   f'run `geodesic-bag repair {p}`')
        else:
            msg = f'not a bag: {p} has no metadata.yaml and no .mcap/.db3 file'
        raise BagError(msg)
    return p


class _OpenBag:
    """AnyReader with errors converted to BagError."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = _resolve_bag_dir(path)
        self.reader: AnyReader | None = None

    def __enter__(self) -> AnyReader:
        try:
            reader = AnyReader([self.path], default_typestore=make_typestore())
            reader.open()
        except (AnyReaderError, ReaderError, TypesysError, OSError, KeyError, ValueError) as err:
            msg = f'cannot read bag {self.path}: {err}'
            raise BagError(msg) from err
        self.reader = reader
        return reader

    def __exit__(self, *exc: object) -> None:
        if self.reader is not None:
            self.reader.close()


def _messages(reader: AnyReader, connections: list[Connection], path: Path) -> Iterator[tuple[Connection, int, bytes]]:
    if not connections:  # AnyReader reads every connection when given none
        return
    try:
        yield from reader.messages(connections=connections)
    except (AnyReaderError, ReaderError, OSError) as err:
        msg = f'cannot read messages of bag {path}: {err}'
        raise BagError(msg) from err


def read_trajectories(bag_path: str | os.PathLike[str], topic: str | None = None) -> list[TrajectoryRecord]:
    """Every JointTrajectory in a bag, in bag-time order, as arrays.

    Args:
        bag_path: rosbag2 directory (or its storage file).
        topic: only this topic (default: every JointTrajectory topic).

    Returns:
        Records sorted by ``stamp_ns``; invalid messages are included with ``problems`` set.

    Raises:
        BagError: missing or unreadable bag, topic absent or not a JointTrajectory topic.
    """
    src = _OpenBag(bag_path)
    with src as reader:
        conns = [c for c in reader.connections if c.msgtype == JOINT_TRAJECTORY]
        if topic is not None:
            if not any(c.topic == topic for c in reader.connections):
                have = ', '.join(sorted({c.topic for c in reader.connections})) or 'none'
                msg = f'topic {topic} not in bag {src.path} (topics: {have})'
                raise BagError(msg)
            conns = [c for c in conns if c.topic == topic]
            if not conns:
                msg = f'topic {topic} in bag {src.path} is not a {JOINT_TRAJECTORY} topic'
                raise BagError(msg)
        records = []
        for conn, stamp, data in _messages(reader, conns, src.path):
            try:
                msg_obj = reader.deserialize(data, conn.msgtype)
            except AnyReaderError as err:
                msg = f'bag {src.path}: undecodable {conn.msgtype} on {conn.topic} at {stamp} ns: {err}'
                raise BagError(msg) from err
            records.append(_trajectory_record(conn.topic, stamp, msg_obj))
    return records


@dataclass(frozen=True)
class TopicSummary:
    """Per-topic counts and times (ns since the epoch; None without messages)."""

    name: str
    msgtype: str
    count: int
    first_ns: int | None
    last_ns: int | None

    @property
    def duration(self) -> float:
        """last - first message time, s."""
        if self.first_ns is None or self.last_ns is None:
            return 0.0
        return (self.last_ns - self.first_ns) * 1e-9


@dataclass(frozen=True)
class TrajectorySummary:
    """Summary of one recorded trajectory: points, duration (s), peak |v|, peak |a| (nan if absent)."""

    topic: str
    index: int
    stamp_ns: int
    points: int
    dof: int
    duration: float
    peak_velocity: float
    peak_acceleration: float
    problems: tuple[str, ...] = ()


@dataclass(frozen=True)
class BagInfo:
    """What ``geodesic-bag info`` prints."""

    path: Path
    storage: str
    message_count: int
    start_ns: int | None
    end_ns: int | None
    topics: list[TopicSummary] = field(default_factory=list)
    trajectories: list[TrajectorySummary] = field(default_factory=list)
    custom_data: dict[str, str] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Bag duration (first to last message), s."""
        if self.start_ns is None or self.end_ns is None:
            return 0.0
        return (self.end_ns - self.start_ns) * 1e-9


def _peak(x: np.ndarray | None) -> float:
    if x is None or x.size == 0:
        return float('nan')
    return float(np.nanmax(np.abs(x)))


def summarize_trajectory(rec: TrajectoryRecord, index: int) -> TrajectorySummary:
    """Summary numbers of a record (peaks over all joints and points)."""
    return TrajectorySummary(
        topic=rec.topic, index=index, stamp_ns=rec.stamp_ns, points=int(rec.t.size),
        dof=len(rec.joint_names), duration=rec.duration, peak_velocity=_peak(rec.velocities),
        peak_acceleration=_peak(rec.accelerations), problems=rec.problems,
    )


def bag_info(path: str | os.PathLike[str]) -> BagInfo:
    """Topics, counts, times and a summary of every JointTrajectory of a bag.

    Raises:
        BagError: missing or unreadable bag.
    """
    src = _OpenBag(path)
    meta = yaml.safe_load((src.path / 'metadata.yaml').read_text()) or {}
    bagfile = meta.get('rosbag2_bagfile_information') or {}
    storage = str(bagfile.get('storage_identifier', '?'))
    custom = {str(k): str(v) for k, v in (bagfile.get('custom_data') or {}).items()}
    with src as reader:
        first: dict[str, int] = {}
        last: dict[str, int] = {}
        counts: dict[str, int] = {}
        types: dict[str, str] = {}
        for c in reader.connections:
            types.setdefault(c.topic, c.msgtype)
            counts.setdefault(c.topic, 0)
        trajectories: list[TrajectorySummary] = []
        per_topic_index: dict[str, int] = {}
        for conn, stamp, data in _messages(reader, list(reader.connections), src.path):
            counts[conn.topic] += 1
            first.setdefault(conn.topic, stamp)
            last[conn.topic] = max(stamp, last.get(conn.topic, stamp))
            first[conn.topic] = min(stamp, first[conn.topic])
            if conn.msgtype == JOINT_TRAJECTORY:
                try:
                    rec = _trajectory_record(conn.topic, stamp, reader.deserialize(data, conn.msgtype))
                except AnyReaderError as err:
                    msg = f'bag {src.path}: undecodable message on {conn.topic} at {stamp} ns: {err}'
                    raise BagError(msg) from err
                k = per_topic_index.get(conn.topic, 0)
                per_topic_index[conn.topic] = k + 1
                trajectories.append(summarize_trajectory(rec, k))
    topics = [TopicSummary(name, types[name], counts[name], first.get(name), last.get(name))
              for name in sorted(types)]
    total = sum(counts.values())
    return BagInfo(
        path=src.path, storage=storage, message_count=total,
        start_ns=min(first.values()) if first else None, end_ns=max(last.values()) if last else None,
        topics=topics, trajectories=trajectories, custom_data=custom,
    )


# ----------------------------------------------------------------------------------------------
# Repair
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


def _records(buf: bytes | memoryview, start: int) -> Iterator[tuple[int, memoryview]]:
    """MCAP records (opcode, body) from ``start`` up to the first truncated or invalid one."""
    view = memoryview(buf)
    pos, end = start, len(view)
    while pos + 9 <= end:
        op = view[pos]
        (length,) = struct.unpack_from('<Q', view, pos + 1)
        if op == 0 or pos + 9 + length > end:
            return
        yield op, view[pos + 9:pos + 9 + length]
        pos += 9 + length


def _mcap_string(body: memoryview, pos: int) -> tuple[str, int]:
    (n,) = struct.unpack_from('<I', body, pos)
    return bytes(body[pos + 4:pos + 4 + n]).decode('utf-8'), pos + 4 + n


def _decompress(data: memoryview, compression: str, size: int) -> bytes | None:
    if compression == '':
        return bytes(data)
    if compression == 'zstd':
        try:
            from compression import zstd  # type: ignore[import-not-found]  # Python >= 3.14
        except ImportError:
            from backports import zstd  # type: ignore[no-redef]
        try:
            return zstd.decompress(bytes(data))
        except Exception:  # noqa: BLE001  (corrupt chunk: skip it, keep the rest)
            return None
    if compression == 'lz4':
        try:
            import lz4.frame  # type: ignore[import-not-found]
        except ImportError:
            return None
        try:
            return bytes(lz4.frame.decompress(bytes(data)))
        except Exception:  # noqa: BLE001
            return None
    _ = size
    return None


def _scan_mcap(path: Path) -> tuple[dict[int, _Recovered], list[tuple[int, int, bytes]], int]:
    """Tolerant MCAP scan: channels, messages (channel, log_time, data), chunks skipped."""
    data = path.read_bytes()
    if data[:8] != _MCAP_MAGIC:
        msg = f'not an MCAP file: {path}'
        raise BagError(msg)
    schemas: dict[int, tuple[str, str, str]] = {}
    channels: dict[int, _Recovered] = {}
    messages: list[tuple[int, int, bytes]] = []
    skipped = 0

    def handle(op: int, body: memoryview) -> None:
        if op == 0x03:  # schema
            (sid,) = struct.unpack_from('<H', body, 0)
            name, pos = _mcap_string(body, 2)
            enc, pos = _mcap_string(body, pos)
            (n,) = struct.unpack_from('<I', body, pos)
            schemas[sid] = (name, enc, bytes(body[pos + 4:pos + 4 + n]).decode('utf-8'))
        elif op == 0x04:  # channel
            cid, sid = struct.unpack_from('<HH', body, 0)
            topic, pos = _mcap_string(body, 4)
            _, pos = _mcap_string(body, pos)  # message encoding (cdr)
            (mlen,) = struct.unpack_from('<I', body, pos)
            pos += 4
            meta: dict[str, str] = {}
            mend = pos + mlen
            while pos < mend:
                key, pos = _mcap_string(body, pos)
                value, pos = _mcap_string(body, pos)
                meta[key] = value
            name, enc, text = schemas.get(sid, ('', '', ''))
            channels[cid] = _Recovered(topic, name, text, enc, _parse_qos_text(meta.get('offered_qos_profiles')))
        elif op == 0x05:  # message
            (cid,) = struct.unpack_from('<H', body, 0)
            (log_time,) = struct.unpack_from('<Q', body, 6)
            messages.append((cid, log_time, bytes(body[22:])))

    for op, body in _records(data, 8):
        if op == 0x02:  # footer
            break
        if op == 0x06:  # chunk
            try:
                _, _, usize, crc = struct.unpack_from('<QQQI', body, 0)
                compression, pos = _mcap_string(body, 28)
                (csize,) = struct.unpack_from('<Q', body, pos)
                inner = _decompress(body[pos + 8:pos + 8 + csize], compression, usize)
            except (struct.error, UnicodeDecodeError):
                inner = None
            if inner is None or (crc and zlib.crc32(inner) != crc):
                skipped += 1
                continue
            for op2, body2 in _records(inner, 0):
                try:
                    handle(op2, body2)
                except (struct.error, UnicodeDecodeError):
                    break
        else:
            try:
                handle(op, body)
            except (struct.error, UnicodeDecodeError):
                break
    return channels, messages, skipped


def _scan_sqlite(path: Path) -> tuple[dict[int, _Recovered], list[tuple[int, int, bytes]], int]:
    try:
        conn = sqlite3.connect(f'file:{path}', uri=True)  # rolls back an interrupted transaction
        try:
            cur = conn.execute('SELECT * FROM topics')
            cols = [d[0] for d in cur.description]
            topics = [dict(zip(cols, row)) for row in cur.fetchall()]
            defs: dict[str, tuple[str, str]] = {}
            try:
                for ttype, enc, text in conn.execute(
                        'SELECT topic_type, encoding, encoded_message_definition FROM message_definitions'):
                    defs[ttype] = (enc, text)
            except sqlite3.Error:
                pass
            rows = conn.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY id').fetchall()
        finally:
            conn.close()
    except sqlite3.Error as err:
        msg = f'cannot read SQLite storage {path}: {err}'
        raise BagError(msg) from err
    channels = {}
    for t in topics:
        enc, text = defs.get(t['type'], ('', ''))
        channels[int(t['id'])] = _Recovered(
            t['name'], t['type'], text, enc, _parse_qos_text(t.get('offered_qos_profiles')),
            str(t.get('type_description_hash') or ''))
    return channels, [(int(a), int(b), bytes(c)) for a, b, c in rows], 0


def _bag_is_readable(path: Path) -> bool:
    try:
        with _OpenBag(path) as reader:
            for _ in reader.messages():
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
        BagError: not a bag directory, no storage file, unknown message definitions.
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
        writer = Writer(tmp_bag, version=9, storage_plugin=_PLUGINS[storage])
        writer.open()
        conns: dict[int, Connection] = {}
        store = make_typestore()
        for cid, ch in channels.items():
            kwargs: dict[str, Any] = {}
            if ch.msgdef and ch.msgdef_format in ('ros2msg', ''):
                ts = get_typestore(Stores.EMPTY)
                try:
                    ts.register(get_types_from_msg(ch.msgdef, ch.msgtype))
                    kwargs = {'msgdef': ch.msgdef, 'rihs01': ch.digest or ts.hash_rihs01(ch.msgtype)}
                except (TypesysError, KeyError, ValueError):
                    kwargs = {}
            if not kwargs:
                if ch.msgtype not in store.fielddefs:
                    writer.abort()
                    msg = f'cannot repair {bag}: no usable definition of {ch.msgtype} (topic {ch.topic})'
                    raise BagError(msg)
                kwargs = {'typestore': store}
            conns[cid] = writer.add_connection(ch.topic, ch.msgtype, offered_qos_profiles=ch.qos, **kwargs)
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
    except (WriterError, OSError) as err:
        msg = f'cannot repair {bag}: {err}'
        raise BagError(msg) from err
    finally:
        shutil.rmtree(tmp_parent, ignore_errors=True)
    note = f'recovered {sum(counts.values())} messages on {len(counts)} topics'
    if skipped:
        note += f'; {skipped} corrupt chunks skipped'
    if lost:
        note += f'; {lost} messages without a channel dropped'
    return RepairReport(bag, True, storage, counts, damaged, note)

