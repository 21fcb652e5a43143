"""The long way round (issue 13 #10): core/long_way.py and the IK's choice of turn (core/ik.py).

A revolute joint turned by 2π leaves the tool pose unchanged. A goal *pose* must be reached by the
turn of each joint nearest the start within the limits; when that turn is the far one because
the near one is beyond the joint's limit, the plan is refused (LimitError) unless the planner
allows the long way. Oracles: the goal joints written down by hand (start + the small rotation),
and the joint travel recomputed from the path's own ends.
"""
from __future__ import annotations

import math
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose
from planning_checks import SOLVE_TIME_LIMIT, guarded

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import LimitError
from geodesic_planner.core.ik import nearest_turn, solve_ik
from geodesic_planner.core.kinematics import rot_z, trans
from geodesic_planner.core.long_way import LONG_WAY_EXCESS, long_way_excess, short_way

TAU = 2.0 * math.pi
DATA = os.path.join(os.path.dirname(__file__), '..', '..', 'geodesic_planner', 'data')
ROBOTS = ('planar_3r', 'rrpp', 'ur5e', 'panda', os.path.join(DATA, 'iiwa_like_7r.urdf'),
          os.path.join(DATA, 'kr6_like.urdf'))


@pytest.fixture(scope='module')
def ur5e() -> GeodesicPlanner:
    return GeodesicPlanner(load_robot('ur5e'), time_limit=SOLVE_TIME_LIMIT)


def wrist_start(wrist3: float) -> np.ndarray:
    q = load_robot('ur5e').home.copy()
    q[5] = wrist3
    return q


# ---------------------------------------------------------------------------------------- the case
def test_wrist_near_its_limit_turned_by_half_a_radian_is_refused(ur5e: GeodesicPlanner) -> None:
    """The issue's case: wrist_3 (limits ±2π) at 2π − 1e-3, goal = the same pose turned +0.5 rad
    about the tool axis. The short way (to 2π + 0.499) is beyond the limit; the only goal within
    the limits (0.499) is −5.78 rad away."""
    q0 = wrist_start(TAU - 1e-3)
    T_goal = ur5e.robot.fk(q0) @ rot_z(0.5)
    with pytest.raises(LimitError) as info:
        ur5e.plan(None, T_goal, start_joints=q0)
    msg = str(info.value)
    assert "joint 'wrist_3_joint' would travel -5.783 rad" in msg
    assert 'from 6.28219 to 0.499' in msg
    assert 'the tool needs a rotation of only 0.5 rad and a translation of 0 m' in msg
    assert "the short way (+0.5 rad, to 6.78219) is blocked by the joint's limit 6.28319" in msg
    assert 'long way round' in msg and 'allow_long_way=True' in msg


def test_the_refusal_also_applies_to_via_points(ur5e: GeodesicPlanner) -> None:
    """plan_through: the second piece (a further +0.5 rad past the limit) is refused."""
    q0 = wrist_start(TAU - 0.7)
    T0 = ur5e.robot.fk(q0)
    with pytest.raises(LimitError, match="long way round: joint 'wrist_3_joint'"):
        ur5e.plan_through([T0, T0 @ rot_z(0.5), T0 @ rot_z(1.0)], start_joints=q0)


def test_allow_long_way_plans_it() -> None:
    """With allow_long_way the plan is made: the wrist travels −5.78 rad, the other joints stay,
    and the tool ends at the goal pose."""
    planner = GeodesicPlanner(load_robot('ur5e'), time_limit=SOLVE_TIME_LIMIT, allow_long_way=True)
    q0 = wrist_start(TAU - 1e-3)
    T_goal = planner.robot.fk(q0) @ rot_z(0.5)
    path = planner.plan(None, T_goal, start_joints=q0)
    travel = path.q_goal - path.q_start
    assert_allclose(travel[:5], 0.0, atol=1e-9)
    assert_allclose(travel[5], 0.5 - TAU, atol=1e-9)
    assert_allclose(path.ee_poses(np.array([1.0]))[0], T_goal, atol=1e-9)


def test_explicit_goal_joints_are_taken_as_asked(ur5e: GeodesicPlanner) -> None:
    """A joint goal is what the caller asked for: the same −5.78 rad move is planned."""
    q0 = wrist_start(TAU - 1e-3)
    q1 = q0.copy()
    q1[5] = 0.499
    path = ur5e.plan_joints(q0, q1)
    assert_allclose(path.q_goal, q1, atol=1e-12)


# ---------------------------------------------------------------------------------------- the IK's turn
@pytest.mark.parametrize(('wrist3', 'turn'), [(3.0, 0.5), (3.0, -0.5), (TAU - 1e-3, -0.5), (-3.0, 0.5),
                                              (-3.0, -0.5), (-TAU + 1e-3, 0.5), (1.0, 0.5)])
def test_small_tool_rotation_is_a_small_wrist_move(ur5e: GeodesicPlanner, wrist3: float, turn: float) -> None:
    """Wherever the short way stays within the limits it is taken (before the fix, a wrist at 3.0
    turned by +0.5 went −5.78 rad to 3.5 − 2π: the IK put every ±2π joint in [−π, π))."""
    q0 = wrist_start(wrist3)
    path = ur5e.plan(None, ur5e.robot.fk(q0) @ rot_z(turn), start_joints=q0)
    expected = q0.copy()
    expected[5] += turn
    assert_allclose(path.q_goal, expected, atol=1e-9)


def test_solve_ik_returns_the_turn_nearest_the_seed() -> None:
    robot = load_robot('ur5e')
    q0 = wrist_start(3.0)
    target = q0.copy()
    target[5] = 3.5
    sol = solve_ik(robot, robot.fk(target), q0)
    assert sol.success
    assert_allclose(sol.q, target, atol=1e-9)


def test_nearest_turn_against_hand_values() -> None:
    robot = load_robot('ur5e')                              # every joint within ±2π
    ref = np.array([6.0, -6.0, 3.0, 0.0, 1.0, 6.2])
    q = np.array([-0.2, 0.2, -3.0, 6.0, 1.0 - TAU, 0.5])
    expected = np.array([-0.2 + TAU, 0.2 - TAU, -3.0 + TAU, 6.0 - TAU, 1.0, 0.5])
    # joint 6: 0.5 + 2π = 6.78 is beyond 2π, the next turn 0.5 - 0 stays (the far one).
    assert_allclose(nearest_turn(robot, q, ref), expected, atol=1e-12)
    assert_allclose(nearest_turn(robot, np.stack([q, q]), ref), np.stack([expected, expected]), atol=1e-12)
    rrpp = load_robot('rrpp')                               # prismatic joints never move by 2π
    qp = np.array([0.1, 0.2, 1.9, -1.9])
    assert_allclose(nearest_turn(rrpp, qp, np.array([0.1, 0.2, 1.9 + TAU, -1.9 - TAU])), qp)


def test_short_way_and_excess_against_hand_values() -> None:
    robot = load_robot('rrpp')
    q_a = np.array([3.0, -3.0, -1.5, 0.0])
    q_b = np.array([-3.0, 1.0, 1.5, 0.0])
    # θ1: −6 rad, short way +0.283 (through ±π); θ2: +4 rad, short way −2.283; prismatic: 3 m, no turn.
    assert_allclose(short_way(q_a, q_b)[:2], [TAU - 6.0, 4.0 - TAU], atol=1e-12)
    assert_allclose(long_way_excess(robot, q_a, q_b), [6.0 - (TAU - 6.0), 4.0 - (TAU - 4.0), 0.0, 0.0],
                    atol=1e-12)


# ---------------------------------------------------------------------------------------- properties
def _random_move(robot_name: str, seed: int, scale: float, margin: float = 0.0
                 ) -> tuple[GeodesicPlanner, np.ndarray, np.ndarray]:
    """Start uniform within the limits shrunk by ``margin`` (at most a quarter of each range) at
    both ends, goal joints up to ``scale`` away per joint, clipped into the limits."""
    planner = _planner(robot_name)
    r = planner.robot
    rng = np.random.default_rng(seed)
    lo = np.where(np.isfinite(r.lower), r.lower, -np.pi)
    hi = np.where(np.isfinite(r.upper), r.upper, np.pi)
    m = np.minimum(margin, 0.25 * (hi - lo))
    q_a = rng.uniform(lo + m, hi - m)
    q_b = np.clip(q_a + rng.uniform(-scale, scale, r.dof), lo, hi)
    return planner, q_a, q_b


_PLANNERS: dict[str, GeodesicPlanner] = {}


def _planner(name: str) -> GeodesicPlanner:
    if name not in _PLANNERS:
        _PLANNERS[name] = GeodesicPlanner(load_robot(name), time_limit=SOLVE_TIME_LIMIT)
    return _PLANNERS[name]


@settings(derandomize=True, deadline=None, database=None, max_examples=90,
          suppress_health_check=list(HealthCheck))
@given(robot=st.sampled_from(ROBOTS), seed=st.integers(0, 2**32 - 1), scale=st.sampled_from([0.05, 0.3, 1.0]))
def test_normal_moves_never_refused_as_the_long_way(robot: str, seed: int, scale: float) -> None:
    """Normal moves of every preset and data URDF: from a start at least 1 rad (m) inside every
    limit (a quarter of the range for narrower joints) to the pose of joints at most ``scale``
    rad (m) away per joint: a plan or a documented error, never the long way round, and every
    revolute joint of a plan travels at most π/2 more than its short way.

    (From a start next to a limit, a tool line that crosses the limit can make the goal IK land
    on a joint's far turn: that move is the long way round and is refused, see the next test.)"""
    planner, q_a, q_b = _random_move(robot, seed, scale, margin=1.0)
    out = guarded('long_way_normal', lambda: planner.plan(None, planner.robot.fk(q_b), start_joints=q_a))
    if out.error is not None:
        assert 'long way' not in str(out.error), str(out.error)
        return
    path = out.value
    excess = long_way_excess(planner.robot, path.q_start, path.q_goal)
    assert excess.max() <= LONG_WAY_EXCESS


@settings(derandomize=True, deadline=None, database=None, max_examples=40,
          suppress_health_check=list(HealthCheck))
@given(robot=st.sampled_from(('planar_3r', 'rrpp', 'ur5e')), seed=st.integers(0, 2**32 - 1))
def test_far_moves_refused_only_when_the_short_way_is_blocked(robot: str, seed: int) -> None:
    """Far random moves (up to 6 rad per joint): when the planner refuses the long way, the named
    joint's travel (recomputed from the ends allow_long_way plans) is beyond its short way + π/2,
    and the short way leaves that joint's limits."""
    planner, q_a, q_b = _random_move(robot, seed, 6.0)
    T_goal = planner.robot.fk(q_b)
    out = guarded('long_way_far', lambda: planner.plan(None, T_goal, start_joints=q_a))
    if out.error is None:
        assert long_way_excess(planner.robot, out.value.q_start, out.value.q_goal).max() <= LONG_WAY_EXCESS
        return
    if 'long way' not in str(out.error):
        return
    r = planner.robot
    free = GeodesicPlanner(r, time_limit=SOLVE_TIME_LIMIT, allow_long_way=True)
    q_goal = free.resolve_ends(None, T_goal, start_joints=q_a)[1]
    if long_way_excess(r, q_a, q_goal).max() <= LONG_WAY_EXCESS:
        # The IK's goal is not the long way: the straight line itself winds a joint on its way to the
        # goal pose (issue 36: the line is followed step by step). allow_long_way plans it; the
        # refusal names that plan's joint and travel.
        q_goal = free.plan(None, T_goal, start_joints=q_a).q_goal
        excess = long_way_excess(r, q_a, q_goal)
        i = int(np.argmax(excess))
        assert excess[i] > LONG_WAY_EXCESS
        assert f'joint {r.joint_names[i]!r} would travel {q_goal[i] - q_a[i]:+.4g} rad' in str(out.error)
        return
    excess = long_way_excess(r, q_a, q_goal)
    i = int(np.argmax(excess))
    assert f'joint {r.joint_names[i]!r} would travel {q_goal[i] - q_a[i]:+.4g} rad' in str(out.error)
    assert excess[i] > LONG_WAY_EXCESS
    short_goal = q_a[i] + short_way(q_a, q_goal)[i]
    assert not r.lower[i] <= short_goal <= r.upper[i]


def test_translation_is_reported() -> None:
    """The message gives the translation the move needs: a wrist turn plus a 2 cm tool shift."""
    planner = GeodesicPlanner(load_robot('ur5e'), time_limit=SOLVE_TIME_LIMIT)
    q0 = wrist_start(TAU - 1e-3)
    T_goal = planner.robot.fk(q0) @ rot_z(0.5) @ trans(z=0.02)
    with pytest.raises(LimitError, match=r'rotation of only 0\.5 rad and a translation of 0\.02 m'):
        planner.plan(None, T_goal, start_joints=q0)
