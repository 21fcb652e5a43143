"""A batch job's trajectories as a rosbag2 (MCAP) for replay: ``geodesic-plan batch --bag``.

One ``trajectory_msgs/msg/JointTrajectory`` on :data:`TOPIC` per successful row, in the rows'
order, stamped one second apart from :data:`FIRST_STAMP_NS` (a replay plays them one after the
other); the header's ``frame_id`` is the row's ``id``, so each message names its request. Written
with :class:`~.bags.BagRecorder` (``metadata.yaml`` on close), one shard in memory at a time.
"""
from __future__ import annotations

import os
from types import SimpleNamespace as Msg

import numpy as np

from ..core.codes import PlanCode
from ..core.errors import BagError, quoted
from .batch_output import read_rows

__all__ = ['FIRST_STAMP_NS', 'TOPIC', 'check_bag_path', 'write_bag']

TOPIC = '/geodesic_planner/batch/joint_trajectory'
#: Log time of the first message, ns since the epoch.
FIRST_STAMP_NS = 1_000_000_000
#: Time between two messages' log times, ns.
STAMP_STEP_NS = 1_000_000_000


def check_bag_path(path: str) -> None:
    """Refuse a bag path that exists (a new bag never replaces anything) before the job runs.

    Raises:
        BagError: ``path`` exists, or its parent is not a directory.
    """
    if os.path.exists(path):
        raise BagError(f'bag {quoted(path)} exists: give a new directory')
    parent = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(parent):
        raise BagError(f'bag {quoted(path)}: {quoted(parent)} is not a directory')


def _time(t: float) -> Msg:
    ns = round(t * 1e9)
    return Msg(sec=ns // 10**9, nanosec=ns % 10**9)


def write_bag(results: str, path: str) -> int:
    """Write the successful rows of the job in ``results`` to a new MCAP bag at ``path``.

    Returns:
        The number of trajectories written.
    Raises:
        BagError: the bag cannot be written; RequestError: a shard cannot be read.
    """
    from .bags.cdr import JOINT_TRAJECTORY, make_typestore, to_cdr
    from .bags.recorder import BagRecorder
    check_bag_path(path)
    store = make_typestore()
    written = 0
    with BagRecorder(path, storage='mcap', topics={TOPIC: JOINT_TRAJECTORY}, typestore=store,
                     custom_data={'geodesic_planner.batch': os.path.abspath(results)}) as rec:
        for row in read_rows(results):
            if row['status'] != PlanCode.SUCCESS:
                continue
            q, dq, ddq = (np.asarray(row[k], dtype=float) for k in ('positions', 'velocities', 'accelerations'))
            points = [Msg(positions=q[i].tolist(), velocities=dq[i].tolist(), accelerations=ddq[i].tolist(),
                          effort=[], time_from_start=_time(t)) for i, t in enumerate(row['times'])]
            msg = Msg(header=Msg(stamp=Msg(sec=0, nanosec=0), frame_id=str(row['id'])),
                      joint_names=list(row['joint_names']), points=points)
            rec.write(TOPIC, FIRST_STAMP_NS + written * STAMP_STEP_NS, to_cdr(msg, JOINT_TRAJECTORY, store))
            written += 1
    return written
