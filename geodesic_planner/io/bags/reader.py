"""Reading rosbag2 bags: every JointTrajectory as arrays, and a summary of a bag.

:func:`read_trajectories` returns each ``trajectory_msgs/msg/JointTrajectory`` as a
:class:`TrajectoryRecord` whose ``problems`` come from the one trajectory validator
(:func:`geodesic_planner.timing.validate.trajectory_problems`); :func:`bag_info` counts topics and
summarises each trajectory. Readers use a fresh Jazzy typestore for bags without definitions.

A record whose bytes do not decode as its type (a corrupt or hostile recording) never fails the
whole bag: it is skipped and reported as an :class:`UndecodableRecord` (``bag_info(...).undecodable``,
``read_trajectories(..., skipped=[])``). rosbags' decoders raise whatever the malformed bytes
lead to (``struct.error``, ``IndexError``, ``UnicodeDecodeError``, ...), so any exception out of
decoding one record means "undecodable"; the same holds for reading a corrupt storage file, which
becomes a :class:`BagError` naming the bag.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.typesys import TypesysError

from ...core.errors import BagError
from ...timing.validate import trajectory_problems
from .cdr import JOINT_TRAJECTORY, load_yaml, make_typestore

if TYPE_CHECKING:
    from rosbags.interfaces import Connection

__all__ = [
    'BagInfo',
    'OpenBag',
    'TopicSummary',
    'TrajectoryRecord',
    'TrajectorySummary',
    'UndecodableRecord',
    'bag_info',
    'read_custom_data',
    'read_trajectories',
    'summarize_trajectory',
    'trajectory_record',
]


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


@dataclass(frozen=True)
class UndecodableRecord:
    """A recorded message that could not be decoded as its type (skipped by the readers).

    Attributes:
        topic: topic name.
        msgtype: the topic's message type.
        stamp_ns: bag (receive) time, ns since the epoch.
        size: bytes of the record.
        reason: the decoder's error.
    """

    topic: str
    msgtype: str
    stamp_ns: int
    size: int
    reason: str

    def __str__(self) -> str:
        """One line: where and why."""
        return f'{self.topic} at {self.stamp_ns} ns ({self.size} bytes, {self.msgtype}): {self.reason}'


def _rows(points: list[Any], name: str, dof: int) -> tuple[list[list[float]], np.ndarray | None]:
    """A per-point float64[] field as ragged rows and, when every row has dof values, as (N, dof).

    Positions always get an array (NaN rows where a point has the wrong count).
    """
    rows = [[float(x) for x in getattr(p, name)] for p in points]
    full = [len(r) == dof for r in rows]
    if name != 'positions' and not (rows and all(full)):
        return rows, None
    out = np.full((len(rows), dof), np.nan)
    for i, r in enumerate(rows):
        if full[i]:
            out[i] = r
    return rows, out


def trajectory_record(topic: str, stamp_ns: int, msg: Any) -> TrajectoryRecord:  # noqa: ANN401 duck-typed rosbags or rclpy message
    """Arrays and validity of one decoded JointTrajectory (rosbags or rclpy message object).

    Args:
        topic: topic name.
        stamp_ns: bag (receive) time, ns since the epoch.
        msg: the message (attributes as in the .msg definition).
    """
    names = [str(n) for n in msg.joint_names]
    dof = len(names)
    points = list(msg.points)
    t = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in points], dtype=float)
    pos_rows, pos = _rows(points, 'positions', dof)
    vel_rows, vel = _rows(points, 'velocities', dof)
    acc_rows, acc = _rows(points, 'accelerations', dof)
    # A recording holds planner inputs as well as outputs: only the controller's rules apply here,
    # not the processor's own demand that a trajectory ends at rest.
    problems = trajectory_problems(names, t, pos_rows, vel_rows, acc_rows, require_rest_at_end=False)
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


class OpenBag:
    """Context manager opening a bag directory with AnyReader; errors become :class:`BagError`.

    Raises:
        BagError: missing path, not a bag, interrupted recording (no ``metadata.yaml``).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = _resolve_bag_dir(path)
        self.reader: AnyReader | None = None

    def __enter__(self) -> AnyReader:
        try:
            reader = AnyReader([self.path], default_typestore=make_typestore())
            reader.open()
        except Exception as err:  # a corrupt file makes rosbags raise anything (re-raised as BagError)
            msg = f'cannot read bag {self.path}: {_reason(err)}'
            raise BagError(msg) from err
        self.reader = reader
        return reader

    def __exit__(self, *exc: object) -> None:
        if self.reader is not None:
            self.reader.close()


def _reason(err: BaseException) -> str:
    if isinstance(err, (AnyReaderError, ReaderError, TypesysError)):
        return str(err)
    return f'{type(err).__name__}: {err}'


def decode(reader: AnyReader, conn: Connection, stamp: int, data: bytes) -> Any | UndecodableRecord:  # noqa: ANN401 any message type
    """The message of one record, or what went wrong when its bytes do not decode."""
    try:
        return reader.deserialize(data, conn.msgtype)
    except Exception as err:  # noqa: BLE001 - malformed bytes make rosbags raise anything
        return UndecodableRecord(conn.topic, conn.msgtype, int(stamp), len(data), _reason(err))


def messages(reader: AnyReader, connections: list[Connection], path: Path) -> Iterator[tuple[Connection, int, bytes]]:
    """Messages (connection, log time in ns, CDR bytes) of the given connections; none for [].

    Raises:
        BagError: unreadable storage.
    """
    if not connections:  # AnyReader reads every connection when given none
        return
    try:
        yield from reader.messages(connections=connections)
    except Exception as err:  # a corrupt storage file makes rosbags raise anything (re-raised)
        msg = f'cannot read messages of bag {path}: {_reason(err)}; try `geodesic-bag repair {path}`'
        raise BagError(msg) from err


def read_trajectories(bag_path: str | os.PathLike[str], topic: str | None = None, *,
                      skipped: list[UndecodableRecord] | None = None) -> list[TrajectoryRecord]:
    """Every JointTrajectory in a bag, in bag-time order, as arrays.

    Args:
        bag_path: rosbag2 directory (or its storage file).
        topic: only this topic (default: every JointTrajectory topic).
        skipped: records that could not be decoded are appended here (they are skipped either way).

    Returns:
        Records sorted by ``stamp_ns``; invalid messages are included with ``problems`` set.

    Raises:
        BagError: missing or unreadable bag, topic absent or not a JointTrajectory topic.
    """
    src = OpenBag(bag_path)
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
        for conn, stamp, data in messages(reader, conns, src.path):
            rec = _trajectory_or_undecodable(reader, conn, stamp, data)
            if isinstance(rec, UndecodableRecord):
                if skipped is not None:
                    skipped.append(rec)
                continue
            records.append(rec)
    return records


def _trajectory_or_undecodable(reader: AnyReader, conn: Connection, stamp: int,
                               data: bytes) -> TrajectoryRecord | UndecodableRecord:
    msg_obj = decode(reader, conn, stamp, data)
    if isinstance(msg_obj, UndecodableRecord):
        return msg_obj
    try:
        return trajectory_record(conn.topic, stamp, msg_obj)
    except (TypeError, ValueError, OverflowError) as err:  # decoded, but fields of the wrong kind
        return UndecodableRecord(conn.topic, conn.msgtype, int(stamp), len(data), _reason(err))


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
    undecodable: list[UndecodableRecord] = field(default_factory=list)

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


def _read_metadata(bag: Path) -> tuple[str, dict[str, str]]:
    """(storage identifier, custom data) of a bag directory's ``metadata.yaml``.

    Raises:
        BagError: the file cannot be read or is not YAML.
    """
    try:
        meta = load_yaml((bag / 'metadata.yaml').read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
        msg = f'cannot read {bag / "metadata.yaml"}: {err}'
        raise BagError(msg) from err
    meta = meta if isinstance(meta, dict) else {}
    bagfile = meta.get('rosbag2_bagfile_information')
    bagfile = bagfile if isinstance(bagfile, dict) else {}
    custom_raw = bagfile.get('custom_data')
    custom = {str(k): str(v) for k, v in custom_raw.items()} if isinstance(custom_raw, dict) else {}
    return str(bagfile.get('storage_identifier', '?')), custom


def read_custom_data(path: str | os.PathLike[str]) -> dict[str, str]:
    """The ``custom_data`` of a bag's ``metadata.yaml`` ({} when it has none).

    The trajectory processor's recordings say there which topics were its input and output
    (``input_topic``, ``output_topic``) and its ``sample_period`` and ``velocity_scaling``.

    Raises:
        BagError: missing or unreadable bag directory or ``metadata.yaml``.
    """
    return _read_metadata(_resolve_bag_dir(path))[1]


def bag_info(path: str | os.PathLike[str]) -> BagInfo:
    """Topics, counts, times and a summary of every JointTrajectory of a bag.

    Undecodable JointTrajectory records are counted with their topic and listed in
    ``undecodable`` (not summarised).

    Raises:
        BagError: missing or unreadable bag.
    """
    src = OpenBag(path)
    storage, custom = _read_metadata(src.path)
    undecodable: list[UndecodableRecord] = []
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
        for conn, stamp, data in messages(reader, list(reader.connections), src.path):
            counts[conn.topic] += 1
            first.setdefault(conn.topic, stamp)
            last[conn.topic] = max(stamp, last.get(conn.topic, stamp))
            first[conn.topic] = min(stamp, first[conn.topic])
            if conn.msgtype == JOINT_TRAJECTORY:
                rec = _trajectory_or_undecodable(reader, conn, stamp, data)
                if isinstance(rec, UndecodableRecord):
                    undecodable.append(rec)
                    continue
                k = per_topic_index.get(conn.topic, 0)
                per_topic_index[conn.topic] = k + 1
                trajectories.append(summarize_trajectory(rec, k))
    topics = [TopicSummary(name, types[name], counts[name], first.get(name), last.get(name))
              for name in sorted(types)]
    total = sum(counts.values())
    return BagInfo(
        path=src.path, storage=storage, message_count=total,
        start_ns=min(first.values()) if first else None, end_ns=max(last.values()) if last else None,
        topics=topics, trajectories=trajectories, custom_data=custom, undecodable=undecodable,
    )
