"""core/codes.py: the numbers are the interface package's PlanErrorCode.msg constants (read from
the .msg file here, no ROS import), and each error class takes its code along its MRO."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from geodesic_planner.core import errors as E
from geodesic_planner.core.codes import ERROR_CODES, PlanCode, error_code

MSG = Path(__file__).resolve().parents[2] / 'geodesic_planner_interfaces' / 'msg' / 'PlanErrorCode.msg'


def _msg_constants() -> dict[str, int]:
    found = re.findall(r'^int32\s+([A-Z_]+)\s*=\s*(-?\d+)\s*$', MSG.read_text(), flags=re.MULTILINE)
    return {name: int(value) for name, value in found}


def test_the_codes_are_the_message_constants() -> None:
    constants = _msg_constants()
    assert len(constants) >= 11
    assert {c.name: int(c) for c in PlanCode} == constants


# The codes written out by number (moveit_msgs/MoveItErrorCodes where MoveIt has one, ours below -100).
@pytest.mark.parametrize('cls,code', [
    (E.GeodesicPlannerError, -1), (E.RequestError, -101), (E.FrameError, -21), (E.StartStateError, -102),
    (E.TrajectoryError, -1), (E.KinematicsError, -1), (E.BVPError, -1), (E.IKError, -31), (E.LimitError, -103),
    (E.ConfigError, -1), (E.PlanTimeoutError, -6),
], ids=lambda v: getattr(v, '__name__', str(v)))
def test_codes_by_number(cls: type[Exception], code: int) -> None:
    assert error_code(cls('x')) == code


def test_two_base_classes_and_collisions() -> None:
    assert error_code(E.LineLimitError('x', fraction=0.5)) == -103
    assert error_code(E.LineUnreachableError('x', fraction=0.5)) == -31
    assert error_code(E.PathFollowError('x', fraction=0.5)) == -1
    where = {'pair': ('a', 'b'), 'fraction': 0.5, 'time': 0.1, 'clearance': 0.0}
    assert error_code(E.StartInCollisionError('x', **where)) == -10
    assert error_code(E.GoalInCollisionError('x', **where)) == -12
    assert error_code(E.PathInCollisionError('x', **where)) == -2
    assert error_code(E.CollisionError('x', **where)) == -1
    assert error_code(RuntimeError('x')) == -1
    assert all(isinstance(code, int) for code in ERROR_CODES.values())
