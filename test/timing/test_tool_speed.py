"""Tool speed limits of the timing layer (max_tool_speed, max_tool_angular_speed).

The tool's speed is computed independently of the library's tool rows (which use ``fk``,
``jacobian12`` and ``hessian12``): from the geometric Jacobian ``robot.jacobian(q) dq`` with the
trajectory's own joint velocities, and from finite differences of the tool poses ``fk(q(t))`` on a
dense time grid. A chord speed |p(t+h) - p(t)| / h is an average over the step, never above the
largest speed on it, so it is a lower bound of the true peak that needs no tolerance of its own.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st
from timing_paths import PolyPath, check_limits, curved

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import GeodesicPlannerError, LimitError
from geodesic_planner.core.kinematics import REVOLUTE, chain_from_dh
from geodesic_planner.core.transforms import make_transform, so3_exp
from geodesic_planner.timing import time_parameterize

ROBOTS = ('planar_3r', 'ur5e', 'panda', 'rrpp')
#: Relative slack on "never above the limit". The law keeps every sample of its dense check within
#: 1 - CHECK_MARGIN (0.1 %) of each limit and re-checks the samples nearest a limit exactly; a
#: peak between two check samples exceeds the checked value by O((dt sdot)^2 c'') relative, orders
#: of magnitude below 0.1 %. So no real excess is allowed, only floating-point round-off.
RTOL = 1e-9
#: "The limit binds": the peak is within this fraction of the limit (TOPP runs 0.1 % below it; on
#: a collocation path the tool speed per unit s varies, and the law reaches the cap at its maximum).
#: Where the smooth law had to be stretched uniformly for another row (``time_scale`` > 1, e.g. a
#: joint's acceleration at a sharp feature of a collocation path), the peak is the cap divided by
#: that stretch.
BIND = 0.02
#: Dense time samples for the independent check.
SAMPLES = 20001
#: Each example plans a path (collocation on panda and rrpp), so no shrinking (minutes per failure):
#: a failure reports the example as generated.
HYPOTHESIS = settings(max_examples=4, derandomize=True, deadline=None, database=None,
                      phases=(Phase.explicit, Phase.reuse, Phase.generate),
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])

_PLANNERS: dict[str, GeodesicPlanner] = {}


def planner(name: str) -> GeodesicPlanner:
    """One planner per preset robot for the whole module (robots are immutable)."""
    if name not in _PLANNERS:
        _PLANNERS[name] = GeodesicPlanner(load_robot(name), time_limit=20.0)
    return _PLANNERS[name]


def moves(name: str) -> st.SearchStrategy[tuple[np.ndarray, np.ndarray]]:
    """Random start joints inside the middle of the limits and a goal up to 0.6 rad (0.3 m) away."""
    robot = planner(name).robot
    lo = np.maximum(robot.lower, -np.pi)
    hi = np.minimum(robot.upper, np.pi)
    step = np.where(robot._revolute_mask[:, 0] > 0, 0.6, 0.3)
    dof = robot.dof
    frac = st.lists(st.floats(0.25, 0.75), min_size=dof, max_size=dof)
    direction = st.lists(st.floats(-1.0, 1.0), min_size=dof, max_size=dof)

    def build(f: list[float], d: list[float]) -> tuple[np.ndarray, np.ndarray]:
        q_a = lo + np.array(f) * (hi - lo)
        return q_a, np.clip(q_a + step * np.array(d), lo, hi)

    return st.builds(build, frac, direction)


def plan(name: str, q_a: np.ndarray, q_b: np.ndarray):
    """The planner's path between two joint configurations (random moves that fail are skipped)."""
    assume(float(np.max(np.abs(q_b - q_a))) > 0.05)
    try:
        return planner(name).plan_joints(q_a, q_b)
    except GeodesicPlannerError:
        assume(False)
        raise  # not reached


def tool_speeds(robot, traj, samples: int = SAMPLES) -> dict[str, float]:
    """Peak linear (m/s) and angular (rad/s) tool speed of ``traj``, computed two ways."""
    t = np.linspace(0.0, traj.duration, samples)
    q, dq, _ = traj.at_time(t)
    twist = np.einsum('nij,nj->ni', robot.jacobian(q), dq)     # base frame, rows [v; ω]
    T = robot.fk(q)
    dt = np.diff(t)
    chord = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1) / dt
    # Rotation angle of each step, R_k^T R_{k+1} = exp(θ u^): atan2(sin θ, cos θ), accurate for
    # the small angles of a step (arccos of the trace alone loses half the digits there).
    rel = np.einsum('nji,njk->nik', T[:-1, :3, :3], T[1:, :3, :3])
    sin = 0.5 * np.linalg.norm(np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0],
                                         rel[:, 1, 0] - rel[:, 0, 1]], axis=1), axis=1)
    cos = 0.5 * (np.trace(rel, axis1=1, axis2=2) - 1.0)
    turn = np.arctan2(sin, cos) / dt
    # The trajectory's velocities agree with its positions: J dq at the middle of each step against
    # the chord (second order in dt, which is <= 1e-4 of the duration here), plus 1e-9 m/s for the
    # round-off of fk differences (1e-16 m over steps of >= 1e-5 s) when the tool origin hardly moves.
    mid_v = 0.5 * (np.linalg.norm(twist[1:, :3], axis=1) + np.linalg.norm(twist[:-1, :3], axis=1))
    assert np.max(np.abs(mid_v - chord)) <= 1e-3 * float(mid_v.max()) + 1e-9, \
        'J dq disagrees with fk differences'
    return {'v': float(np.linalg.norm(twist[:, :3], axis=1).max()),
            'w': float(np.linalg.norm(twist[:, 3:], axis=1).max()),
            'v_chord': float(chord.max()), 'w_chord': float(turn.max())}


def check_unchanged_path(path, traj) -> None:
    """The time law leaves the path alone: q(t) = path(s(t)) with s monotone, and on a pull-back
    geodesic the tool stays on the straight line between its end positions."""
    t = np.linspace(0.0, traj.duration, 2001)
    s = traj.s_of_t(t)[0]
    assert np.all(np.diff(s) >= 0.0) and s[0] == 0.0 and s[-1] == 1.0
    q = traj.at_time(t)[0]
    np.testing.assert_allclose(q, path.evaluate(s)[0], atol=1e-12)
    if path.solver.method == 'pullback':
        p = path.robot.fk(q)[:, :3, 3]
        a, b = p[0], p[-1]
        u = (b - a) / np.linalg.norm(b - a)
        off = (p - a) - np.outer((p - a) @ u, u)
        assert float(np.linalg.norm(off, axis=1).max()) <= 1e-6


def check_tool_limit(path, key: str, arg: str) -> bool:
    """A limit at 40 % of the free law's peak: never exceeded, binds, slower, joints within limits.

    Returns False (nothing checked) when the free law's peak is below 1e-3 (m/s or rad/s): the
    move hardly translates or turns the tool.
    """
    robot = path.robot
    free = path.timed()
    peak = tool_speeds(robot, free)[key]
    if peak <= 1e-3:
        return False
    limit = 0.4 * peak
    traj = path.timed(**{arg: limit})
    got = tool_speeds(robot, traj)
    assert got[key] <= limit * (1.0 + RTOL), f'{arg}: peak {got[key]:.9g} above the limit {limit:.9g}'
    assert got[f'{key}_chord'] <= limit * (1.0 + RTOL)
    assert got[key] * traj.time_scale >= limit * (1.0 - BIND), \
        f'{arg}: peak {got[key]:.6g} (stretched by {traj.time_scale:.6g}) does not reach {limit:.6g}'
    assert traj.duration > free.duration
    check_limits(traj)
    check_unchanged_path(path, traj)
    assert getattr(traj, arg) == limit
    return True


@pytest.mark.parametrize('name', ROBOTS)
def test_tool_speed_limit_holds_and_binds(name: str) -> None:
    @HYPOTHESIS
    @given(moves(name))
    def run(move: tuple[np.ndarray, np.ndarray]) -> None:
        assume(check_tool_limit(plan(name, *move), 'v', 'max_tool_speed'))

    run()


@pytest.mark.parametrize('name', ROBOTS)
def test_tool_angular_speed_limit_holds_and_binds(name: str) -> None:
    @HYPOTHESIS
    @given(moves(name))
    def run(move: tuple[np.ndarray, np.ndarray]) -> None:
        assume(check_tool_limit(plan(name, *move), 'w', 'max_tool_angular_speed'))

    run()


@pytest.mark.parametrize('move', [
    # A collocation path with a sharp feature near s = 0.85: the smooth law is stretched by 1.14
    # for a joint's acceleration there, so the tool cruises at 87.5 % of its limit.
    ([0.0, 0.0, 0.0, -0.8203, 1.44865, 1.56204633, 0.0], [0.0, 0.6, 0.0, -0.2203, 1.44865, 1.56204633, 0.0]),
    # Only joint 7 turns: the tool origin does not move (the angular row is the one that binds).
    ([0.0, 0.0, 0.0, -1.5708, 0.0, 1.56204633, 0.0], [0.0, 0.0, 0.0, -1.5708, 0.0, 1.56204633, 0.6]),
])
def test_panda_moves_found_by_hypothesis(move: tuple[list[float], list[float]]) -> None:
    # the collocation geodesic of G + εI these moves were found on (since issue 36 a LIN between
    # joints on other branches is refused; the time law is what is tested here)
    path = planner('panda').plan_joints(*move, method='collocation')
    checked = [check_tool_limit(path, key, arg)
               for key, arg in (('v', 'max_tool_speed'), ('w', 'max_tool_angular_speed'))]
    assert checked[1]


def test_both_limits_on_a_position_metric_path() -> None:
    """A geodesic of the position metric (collocation; its tool path is no line): both rows at once.

    The dp^2 metric is regular only on a spatial arm of 3 joints: an elbow arm.
    """
    robot = chain_from_dh('elbow_3r', [(0.0, 0.4, 0.0, np.pi / 2), (0.0, 0.0, 0.4, 0.0),
                                       (0.0, 0.0, 0.35, 0.0)], [REVOLUTE] * 3)
    path = GeodesicPlanner(robot, 'position').plan_joints([0.2, 0.5, -1.0], [0.9, 0.2, -0.4])
    assert path.solver.method == 'collocation'
    free = tool_speeds(robot, path.timed())
    v_lim, w_lim = 0.5 * free['v'], 0.5 * free['w']
    traj = path.timed(max_tool_speed=v_lim, max_tool_angular_speed=w_lim)
    got = tool_speeds(robot, traj)
    assert got['v'] <= v_lim * (1.0 + RTOL) and got['w'] <= w_lim * (1.0 + RTOL)
    # One of the two binds (the tighter one along this path).
    assert max(got['v'] / v_lim, got['w'] / w_lim) >= 1.0 - BIND
    check_limits(traj)
    check_unchanged_path(path, traj)


def test_tool_speed_limit_on_a_piecewise_path_through_via_points() -> None:
    """Via points: the rows hold on every piece; the motion still rests at the corners."""
    robot = load_robot('ur5e')
    q0 = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2])
    T0 = robot.fk(q0)
    poses = [T0] + [make_transform(T0[:3, 3] + np.array([0.06 * k, 0.04 * np.sin(k), 0.03 * k * (-1) ** k]),
                                   T0[:3, :3] @ so3_exp(np.array([0.0, 0.0, 0.1 * k]))) for k in range(1, 4)]
    path = GeodesicPlanner(robot).plan_through(poses, start_joints=q0)
    free = path.timed()
    limit = 0.4 * tool_speeds(robot, free)['v']
    traj = path.timed(max_tool_speed=limit)
    got = tool_speeds(robot, traj)
    assert got['v'] <= limit * (1.0 + RTOL) and got['v_chord'] <= limit * (1.0 + RTOL)
    assert got['v'] >= limit * (1.0 - BIND)
    assert traj.duration > free.duration
    assert len(traj.rest_times) == len(free.rest_times)
    check_limits(traj)
    _, sd, _ = traj.s_of_t(np.array(traj.rest_times))
    np.testing.assert_array_equal(sd, 0.0)


@pytest.mark.parametrize('name', ['planar_3r', 'ur5e'])
@pytest.mark.parametrize('seed', range(4))
def test_smoothing_overshoot_of_the_tool_rows_is_caught(name: str, seed: int) -> None:
    """Random quartic joint paths (no geodesics): the tool's speed per unit s varies along them, so
    the time-optimal law, capped at the nodes, goes over the tool limit once smoothed (by up to
    3 % on these paths); the dense check of the smooth law must see the tool rows and stretch."""
    robot = load_robot(name)
    rng = np.random.default_rng(seed)
    coeffs = 0.8 * rng.normal(size=(5, robot.dof))
    coeffs[0] = robot.home
    path = PolyPath(coeffs)
    path.robot = robot
    free = time_parameterize(path, 50.0, 100.0)  # joint limits far away: the tool rows bind
    peaks = tool_speeds(robot, free)
    for key, arg in (('v', 'max_tool_speed'), ('w', 'max_tool_angular_speed')):
        limit = 0.3 * peaks[key]
        traj = time_parameterize(path, 50.0, 100.0, **{arg: limit})
        got = tool_speeds(robot, traj, samples=40001)
        assert got[key] <= limit * (1.0 + RTOL), f'{arg}: peak / limit = {got[key] / limit:.6f}'
        assert got[f'{key}_chord'] <= limit * (1.0 + RTOL)
        assert got[key] >= limit * (1.0 - BIND)


@pytest.mark.parametrize('name', ROBOTS)
def test_a_loose_tool_limit_changes_nothing(name: str) -> None:
    robot = planner(name).robot
    rng = np.random.default_rng(7)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    for _ in range(20):  # the first random move the planner solves
        q_a = lo + rng.uniform(0.3, 0.7, robot.dof) * (hi - lo)
        q_b = q_a + 0.3 * rng.uniform(-1.0, 1.0, robot.dof)
        try:
            path = planner(name).plan_joints(q_a, q_b)
            break
        except GeodesicPlannerError:
            continue
    else:
        pytest.fail(f'no random move planned on {name}')
    free = path.timed()
    peaks = tool_speeds(robot, free)
    traj = path.timed(max_tool_speed=10.0 * peaks['v'], max_tool_angular_speed=10.0 * peaks['w'] + 1e-9)
    assert traj.duration == free.duration
    t = np.linspace(0.0, free.duration, 101)
    np.testing.assert_array_equal(traj.at_time(t)[1], free.at_time(t)[1])


@pytest.mark.parametrize('arg', ['max_tool_speed', 'max_tool_angular_speed'])
@pytest.mark.parametrize('value', [0.0, -1.0, float('nan'), float('inf'), -float('inf'), 'fast', True, [0.1]])
def test_invalid_tool_limits_are_named(arg: str, value: object) -> None:
    path = planner('planar_3r').plan_joints([0.2, 0.4, -0.3], [0.6, 0.1, 0.2])
    with pytest.raises(LimitError, match=rf'^{arg} must be '):
        path.timed(**{arg: value})
    with pytest.raises(LimitError, match=rf'^{arg} must be '):
        time_parameterize(path, **{arg: value})


def test_a_tool_limit_needs_a_robot_with_kinematics() -> None:
    # curved(): a polynomial path whose robot carries joint limits only.
    with pytest.raises(LimitError, match=r"^max_tool_speed needs the robot's kinematics.*has no fk"):
        time_parameterize(curved(), max_tool_speed=0.1)
    path = curved()
    bare = SimpleNamespace(dof=path.dof, joint_names=path.joint_names, evaluate=path.evaluate)
    with pytest.raises(LimitError, match=r'^max_tool_angular_speed needs the robot of the path'):
        time_parameterize(bare, 1.0, 2.0, max_tool_angular_speed=0.1)
    # Without a tool limit nothing is asked of the robot.
    assert time_parameterize(bare, 1.0, 2.0).duration > 0.0
