"""CDR serialisation of message-like objects (io.bags.cdr)."""
from __future__ import annotations

from types import SimpleNamespace as Msg

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from bag_util import example, joint_state, trajectory
from geodesic_planner.core.errors import BagError
from geodesic_planner.io.bags import JOINT_STATE, JOINT_TRAJECTORY, from_cdr, to_cdr


def test_to_cdr_matches_rosbags_serialisation(ts):
    rng = np.random.default_rng(1)
    t, q, dq, _ = example(rng, 4)
    duck = trajectory(t, q, dq, None)
    data = to_cdr(duck, JOINT_TRAJECTORY, ts)
    msg = from_cdr(data, JOINT_TRAJECTORY, ts)
    assert bytes(ts.serialize_cdr(msg, JOINT_TRAJECTORY)) == data  # a fixed point: exact bytes
    assert list(msg.joint_names) == ['j1', 'j2', 'j3']
    assert_array_equal(msg.points[2].velocities, dq[2])
    assert msg.points[2].accelerations.size == 0
    assert to_cdr(msg, JOINT_TRAJECTORY, ts) == data  # rosbags objects work as input too


def test_cdr_errors_are_bag_errors(ts):
    with pytest.raises(BagError, match='unknown message type'):
        to_cdr(joint_state(0), 'nope_msgs/msg/Nope', ts)
    with pytest.raises(BagError, match='cannot serialise'):
        to_cdr(Msg(header=None), JOINT_STATE, ts)
    data = to_cdr(joint_state(0), JOINT_STATE, ts)
    with pytest.raises(BagError, match='invalid sensor_msgs/msg/JointState CDR'):
        from_cdr(data + b'\0' * 16, JOINT_STATE, ts)
