"""CDR serialisation, the ROS 2 Jazzy typestore and rosbag2 QoS profiles (rosbags, no rclpy).

A typestore (``Stores.ROS2_JAZZY``) is created per use, never shared module-wide.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml
from rosbags.interfaces import Nodetype, Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_typestore

from ...core.errors import BagError

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

JOINT_TRAJECTORY = 'trajectory_msgs/msg/JointTrajectory'
JOINT_STATE = 'sensor_msgs/msg/JointState'

__all__ = ['JOINT_STATE', 'JOINT_TRAJECTORY', 'from_cdr', 'load_yaml', 'make_typestore', 'parse_qos_text',
           'qos_profile', 'to_cdr']

#: PyYAML's safe loader, through libyaml where PyYAML was built with it (its wheels are): a bag's
#: metadata and QoS strings are read 5-10x faster, with the same results and the same errors.
_SAFE_LOADER: Any = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


def load_yaml(text: str | bytes) -> Any:  # noqa: ANN401
    """``yaml.safe_load(text)`` with libyaml when available; raises yaml.YAMLError likewise."""
    return yaml.load(text, Loader=_SAFE_LOADER)


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

    def enum(cls: Any, key: str) -> Any:  # noqa: ANN401 any rosbags Qos enum class
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


def parse_qos_text(text: str | bytes | None) -> list[Qos]:
    """Offered QoS profiles from rosbag2 metadata text (YAML list); [] when absent or unreadable."""
    if not text:
        return []
    try:
        items = load_yaml(text)
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


def _to_rosbags(obj: Any, msgtype: str, typestore: Typestore) -> object:  # noqa: ANN401 duck-typed message objects
    """Convert an object with the message's attributes (e.g. an rclpy message) to rosbags'."""
    _, fields = typestore.fielddefs[msgtype]
    kwargs: dict[str, Any] = {}
    for name, desc in fields:
        value = getattr(obj, name)
        if desc[0] == Nodetype.BASE:
            base = desc[1][0]
            if base in ('string', 'wstring'):
                kwargs[name] = str(value)
            elif base in _NUMPY_TYPES:
                if isinstance(value, bytes):  # rclpy byte/char fields
                    value = ord(value)
                kwargs[name] = _NUMPY_TYPES[base](value).item()
            else:
                kwargs[name] = value
        elif desc[0] == Nodetype.NAME:
            kwargs[name] = _to_rosbags(value, desc[1], typestore)
        else:  # ARRAY or SEQUENCE
            sub_desc, _ = desc[1]
            if sub_desc[0] == Nodetype.BASE and sub_desc[1][0] in _NUMPY_TYPES:
                dtype = _NUMPY_TYPES[sub_desc[1][0]]
                if isinstance(value, (bytes, bytearray)):
                    kwargs[name] = np.frombuffer(bytes(value), dtype=np.uint8).astype(dtype)
                elif len(value) and isinstance(value[0], bytes):  # rclpy byte[]: list of bytes
                    kwargs[name] = np.array([ord(v) for v in value], dtype=dtype)
                else:  # array.array, list, numpy: one buffer copy
                    kwargs[name] = np.array(value, dtype=dtype)
            elif sub_desc[0] == Nodetype.BASE:
                kwargs[name] = [str(v) for v in value]
            else:
                kwargs[name] = [_to_rosbags(v, sub_desc[1], typestore) for v in value]
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
