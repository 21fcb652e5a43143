"""rosbag2 bags with rosbags (no rclpy, no rosbag2 needed).

* :mod:`.cdr`: typestore, CDR serialisation of any object with a message's fields, QoS profiles;
* :mod:`.storage`: MCAP and SQLite storage files that can be flushed while recording;
* :mod:`.recorder`: :class:`BagRecorder`, crash-tolerant recording of raw CDR messages;
* :mod:`.reader`: :func:`read_trajectories` (JointTrajectory messages as arrays) and :func:`bag_info`;
* :mod:`.salvage`: what a damaged or interrupted storage file still holds (SQLite);
* :mod:`.repair`: :func:`repair` of a recording killed before ``close()``.
"""
from __future__ import annotations

from .cdr import JOINT_STATE, JOINT_TRAJECTORY, from_cdr, make_typestore, qos_profile, to_cdr
from .reader import (
    BagInfo,
    TopicSummary,
    TrajectoryRecord,
    TrajectorySummary,
    UndecodableRecord,
    bag_info,
    read_custom_data,
    read_trajectories,
    summarize_trajectory,
)
from .recorder import STORAGES, BagRecorder, new_bag_path
from .repair import RepairReport, repair

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
    'UndecodableRecord',
    'bag_info',
    'from_cdr',
    'make_typestore',
    'new_bag_path',
    'qos_profile',
    'read_custom_data',
    'read_trajectories',
    'repair',
    'summarize_trajectory',
    'to_cdr',
]
