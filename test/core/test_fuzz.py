"""Property-based fuzzing of the core library.

Every call of the public planning API with random or hostile input must either

* return a valid path: boundary conditions met (q(0), q(1) are the given or IK joints), every
  output of ``evaluate`` finite, inside the joint limits, a geodesic (equation residual small,
  checked independently of the library by finite differences of the forward kinematics; metric
  speed nearly constant), and ``timed()`` respects the limits and starts and ends at rest; or
* raise a subclass of :class:`~geodesic_planner.core.errors.GeodesicPlannerError` whose message names
  the cause;

never a bare numpy/scipy/Python error, never a hang (every call is timed; the planners run with a
wall-clock ``time_limit``).

Robots: the presets ``planar_3r``, ``rrpp``, ``ur5e``, ``panda`` and random standard or modified DH
chains of 2-7 joints, revolute and prismatic, with random link lengths and twists.

The default run is deterministic (``derandomize=True``) and short; the ``slow`` variants run many
more examples (``--run-slow``). Set ``GP_FUZZ_REPORT=path.json`` to write the figures (examples
per category, exceptions by type, time per call) used in docs/reliability.md.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from planning_checks import (
    FAST_EXAMPLES,
    HOSTILE_POSES,
    PRESET_NAMES,
    QUICK_PHASES,
    SLOW_FACTOR,
    SOLVE_TIME_LIMIT,
    Outcome,
    check_path,
    check_trajectory,
    embed,
    expect_error,
    guarded,
    sample_path,
)

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import (
    IKError,
    KinematicsError,
    LimitError,
    PathFollowError,
    RequestError,
    SingularMetricError,
)
from geodesic_planner.core.kinematics import Chain, chain_from_dh
from geodesic_planner.core.transforms import check_quaternion, pose_to_transform, quat_to_matrix, so3_exp

# ---------------------------------------------------------------------------------------- strategies
PI = math.pi


@st.composite
def dh_chains(draw: Any, min_dof: int = 2, max_dof: int = 7) -> Chain:
    """Random standard or modified DH chains, revolute and prismatic, random lengths and twists."""
    n = draw(st.integers(min_dof, max_dof))
    modified = draw(st.booleans())
    kinds = draw(st.lists(st.sampled_from(['revolute', 'revolute', 'prismatic']), min_size=n, max_size=n))
    # Mostly the twists of real arms; all-zero twists make planar chains, whose metric is singular
    # beyond 3 joints (fine, but they would crowd out the rest).
    twist = st.one_of(st.sampled_from([PI / 2, -PI / 2, PI / 2, 0.0, PI]), st.floats(-PI, PI))
    rows, lower, upper = [], [], []
    for kind in kinds:
        theta = draw(st.one_of(st.just(0.0), st.floats(-PI, PI)))
        d = draw(st.one_of(st.just(0.0), st.floats(-1.0, 1.0)))
        a = draw(st.one_of(st.just(0.0), st.floats(0.0, 1.5)))
        alpha = draw(twist)
        rows.append((alpha, a, d, theta) if modified else (theta, d, a, alpha))
        if kind == 'revolute':
            lo, hi = draw(st.sampled_from([(-PI, PI), (-2 * PI, 2 * PI), (-2.0, 1.0), (-math.inf, math.inf)]))
        else:
            lo, hi = draw(st.sampled_from([(-1.0, 1.0), (0.0, 1.5), (-0.2, 0.3)]))
        lower.append(lo)
        upper.append(hi)
    tool = None
    if draw(st.booleans()):
        tool = np.eye(4)
        tool[2, 3] = draw(st.floats(0.0, 0.3))
    vmax = draw(st.floats(0.2, 3.0))
    amax = draw(st.floats(0.5, 10.0))
    return chain_from_dh(f'dh{n}{"m" if modified else "s"}', rows, kinds, modified=modified, tool=tool,
                         lower=lower, upper=upper, max_velocity=vmax, max_acceleration=amax)


def robots() -> Any:
    """Presets (as often as random chains) and random DH chains."""
    return st.one_of(st.sampled_from(PRESET_NAMES).map(load_robot), dh_chains())


def box(robot: Chain) -> tuple[np.ndarray, np.ndarray]:
    """Finite sampling box of the joints: the limits, or ±π (rad) / ±1 (m) where infinite."""
    span = np.where(np.array(robot.joint_types) == 'revolute', PI, 1.0)
    return (np.where(np.isfinite(robot.lower), robot.lower, -span),
            np.where(np.isfinite(robot.upper), robot.upper, span))


def joints_in(draw: Any, robot: Chain) -> np.ndarray:
    """A configuration inside the limits: mostly generic, sometimes exactly on a limit."""
    lo, hi = box(robot)
    u = np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=robot.dof, max_size=robot.dof)))
    if draw(st.integers(0, 4)):  # hypothesis likes 0, 0.5 and 1: map them off the limits
        u = 0.0731 + 0.8537 * u
    return lo + u * (hi - lo)


def joints_near(draw: Any, robot: Chain, q: np.ndarray, scale: float) -> np.ndarray:
    """A configuration near q (steps up to ``scale`` of the box), clipped into the limits."""
    lo, hi = box(robot)
    step = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=robot.dof, max_size=robot.dof)))
    return np.clip(q + scale * step * np.minimum(hi - lo, 2.0), robot.lower, robot.upper)


def goal_joints(draw: Any, robot: Chain, q_a: np.ndarray) -> np.ndarray:
    """Goal joints: mostly a local move, sometimes anywhere, sometimes equal to the start."""
    mode = draw(st.sampled_from(['local', 'local', 'local', 'tiny', 'far', 'same']))
    if mode == 'same':
        return q_a.copy()
    if mode == 'far':
        return joints_in(draw, robot)
    return joints_near(draw, robot, q_a, 0.3 if mode == 'local' else 1e-6)


def planner_for(draw: Any, robot: Chain) -> GeodesicPlanner:
    """A planner with a (mostly) default metric, sometimes other weights or the position metric."""
    kind = draw(st.sampled_from(['paper', 'paper', 'paper', 'position']))
    wp = draw(st.sampled_from([1.0, 1.0, 0.3, 3.0]))
    wo = draw(st.sampled_from([1.0, 1.0, 0.2, 2.0]))
    eps = draw(st.sampled_from([None, None, None, 1e-3]))
    return GeodesicPlanner(robot, metric=kind, position_weight=wp, orientation_weight=wo, epsilon=eps,
                           time_limit=SOLVE_TIME_LIMIT)


def random_rotation(draw: Any) -> np.ndarray:
    quat = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4)))
    assume(np.linalg.norm(quat) > 1e-3)
    return quat_to_matrix(quat / np.linalg.norm(quat))


def fuzz(fast: int, **given_kwargs: Any) -> Callable[[Callable[..., None]], tuple[Any, Any]]:
    """A deterministic short hypothesis test and a ``slow`` variant with SLOW_FACTOR x more examples."""
    def deco(body: Callable[..., None]) -> tuple[Any, Any]:
        common = {'deadline': None, 'derandomize': True, 'database': None, 'print_blob': True,
                  'suppress_health_check': [HealthCheck.too_slow, HealthCheck.filter_too_much,
                                            HealthCheck.data_too_large]}
        # The quick run does not shrink (a failure in CI must not cost minutes); the slow one does.
        quick = settings(max_examples=FAST_EXAMPLES or fast, phases=QUICK_PHASES, **common)(
            given(**given_kwargs)(body))
        slow = settings(max_examples=fast * SLOW_FACTOR, **common)(given(**given_kwargs)(body))
        return quick, pytest.mark.slow(slow)
    return deco


def plan_and_check(category: str, planner: GeodesicPlanner, start: Any, goal: Any,
                   q_a: Any = None, q_b: Any = None, tolerance: float | None = None,
                   timed: bool = True) -> Outcome:
    """Plan (guarded); if a path comes back, validate it and its time parameterization."""
    out = guarded(category, lambda: planner.plan(start, goal, q_a, q_b, tolerance=tolerance))
    if out.value is None:
        return out
    path = out.value
    check_path(planner, path, None if q_a is None else np.asarray(q_a, float),
               None if q_b is None else np.asarray(q_b, float), start, goal, tolerance)
    if timed:
        robot = planner.robot
        tr = guarded(category + '.timed', path.timed)
        if tr.value is not None:
            check_trajectory(path, tr.value, robot.max_velocity, robot.max_acceleration, planner.tol)
    return out


# ---------------------------------------------------------------------------------------- fuzz tests
@fuzz(60, robot=robots(), data=st.data())
def _plan_joints(robot: Chain, data: Any) -> None:
    """Random robots, random joint boundary conditions inside the limits."""
    planner = planner_for(data.draw, robot)
    q_a = joints_in(data.draw, robot)
    q_b = goal_joints(data.draw, robot, q_a)
    plan_and_check('plan.joints', planner, None, None, q_a, q_b)


test_fuzz_plan_joints, test_fuzz_plan_joints_slow = _plan_joints


@fuzz(50, robot=robots(), data=st.data())
def _plan_poses(robot: Chain, data: Any) -> None:
    """Goal poses: reachable (fk of random joints), perturbed a little or a lot, or far away; the
    start as a pose or as joints (the planner node's usual request)."""
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    draw = data.draw
    q_a = joints_in(draw, robot)
    q_b = goal_joints(draw, robot, q_a)
    T_a, T_b = robot.fk(np.stack([q_a, q_b]))
    T_b = T_b.copy()
    mode = draw(st.sampled_from(['exact', 'exact', 'nudged', 'moved', 'far']))
    if mode == 'nudged':   # inside the IK tolerance for some robots, not for the under-actuated ones
        T_b[:3, 3] += np.array(draw(st.lists(st.floats(-1e-4, 1e-4), min_size=3, max_size=3)))
    elif mode == 'moved':  # a pose nearby: unreachable for arms with fewer than 6 joints
        T_b[:3, :3] = T_b[:3, :3] @ so3_exp(np.array(draw(st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3))))
        T_b[:3, 3] += np.array(draw(st.lists(st.floats(-0.2, 0.2), min_size=3, max_size=3)))
    elif mode == 'far':    # certainly outside the workspace of every robot here
        T_b[:3, :3] = random_rotation(draw)
        T_b[:3, 3] = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3))) + [20.0, 0, 0]
    tolerance = draw(st.sampled_from([None, None, 1e-6, 1e-2, 0.5]))
    if draw(st.booleans()):  # the node's usual request: current joints to a goal pose
        out = plan_and_check('plan.poses', planner, None, T_b, q_a=q_a, tolerance=tolerance)
    else:
        out = plan_and_check('plan.poses', planner, T_a, T_b, tolerance=tolerance)
    if mode == 'far':
        assert isinstance(out.error, IKError), f'a pose 20 m away was planned: {out.value or out.error!r}'
        assert re.search(r'nearest reachable pose is [0-9.e+]+ away', str(out.error)), str(out.error)


test_fuzz_plan_poses, test_fuzz_plan_poses_slow = _plan_poses


#: Hostile joint vectors: (name, builder(robot, q) -> value, expected type, cause regex).
HOSTILE_JOINTS: list[tuple[str, Callable[[Chain, np.ndarray], Any], type, str]] = [
    ('nan', lambda r, q: np.where(np.arange(r.dof) == r.dof - 1, np.nan, q), RequestError, r'NaN or inf'),
    ('inf', lambda r, q: np.where(np.arange(r.dof) == 0, np.inf, q), RequestError, r'NaN or inf'),
    ('-inf', lambda r, q: np.where(np.arange(r.dof) == 0, -np.inf, q), RequestError, r'NaN or inf'),
    ('too few', lambda r, q: q[:-1], RequestError, r'has \d+ joints.*got \d+ values'),
    ('too many', lambda r, q: np.append(q, 0.0), RequestError, r'has \d+ joints.*got \d+ values'),
    ('empty', lambda r, q: [], RequestError, r'has \d+ joints.*got 0 values'),
    ('scalar', lambda r, q: 0.5, RequestError, r'has \d+ joints.*got 1 values'),
    ('text', lambda r, q: ['a'] * r.dof, RequestError, r'not a numeric joint vector'),
    ('ragged', lambda r, q: [[0.0], [0.0, 1.0]], RequestError, r'not a numeric joint vector'),
]


@fuzz(40, robot=robots(), data=st.data())
def _hostile_joints(robot: Chain, data: Any) -> None:
    """NaN/inf, wrong joint counts, non-numbers, and values beyond the limits, at either end."""
    draw = data.draw
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    q_a = joints_in(draw, robot)
    q_b = joints_near(draw, robot, q_a, 0.2)
    end = draw(st.sampled_from(['start', 'goal']))
    finite = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    choices = list(range(len(HOSTILE_JOINTS))) + (['beyond'] if finite.any() else [])
    pick = draw(st.sampled_from(choices))
    if pick == 'beyond':
        i = int(draw(st.sampled_from(np.flatnonzero(finite).tolist())))
        excess = draw(st.sampled_from([1e-6, 1e-3, 0.5, 100.0]))
        side = draw(st.booleans())
        bad = q_a.copy() if end == 'start' else q_b.copy()
        bad[i] = robot.upper[i] + excess if side else robot.lower[i] - excess
        kind, cause = LimitError, rf"{end} joints: joint '{re.escape(robot.joint_names[i])}' = .* is outside its limits"
        # The first offending joint is named; make it the only one.
    else:
        name, build, kind, cause = HOSTILE_JOINTS[pick]
        bad = build(robot, q_a if end == 'start' else q_b)
        cause = rf'{end}_joints: .*' + cause
    args = (bad, q_b) if end == 'start' else (q_a, bad)
    expect_error('hostile.joints', lambda: planner.plan(None, None, *args), kind, cause)


test_fuzz_hostile_joints, test_fuzz_hostile_joints_slow = _hostile_joints




@fuzz(40, robot=robots(), data=st.data())
def _hostile_poses(robot: Chain, data: Any) -> None:
    """NaN/inf, non-rotation matrices (scaled, reflected, sheared), wrong shapes, at either end."""
    draw = data.draw
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    q = joints_in(draw, robot)
    T = robot.fk(q)
    name, build, cause = draw(st.sampled_from(HOSTILE_POSES))
    x = draw(st.floats(1e-4, 10.0))
    bad = build(T, x)
    end = draw(st.sampled_from(['start', 'goal']))
    args = (bad, T) if end == 'start' else (T, bad)
    expect_error('hostile.poses', lambda: planner.plan(*args), RequestError, rf'{end} pose: .*' + cause)


test_fuzz_hostile_poses, test_fuzz_hostile_poses_slow = _hostile_poses


QUAT_PART = st.one_of(st.floats(-2.0, 2.0), st.sampled_from([0.0, -0.0, 1.0, np.nan, np.inf, -np.inf, 1e-300, 1e300]),
                      st.floats(allow_nan=True, allow_infinity=True))


@fuzz(100, quat=st.one_of(st.lists(st.floats(-1.0, 1.0), min_size=4, max_size=4),
                         st.lists(QUAT_PART, min_size=4, max_size=4)),
      position=st.one_of(st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
                         st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3),
                         st.lists(st.one_of(st.floats(-3.0, 3.0), st.sampled_from([np.nan, np.inf])),
                                  min_size=3, max_size=3)),
      scale=st.one_of(st.just(1.0), st.sampled_from([None, 1.0 + 5e-4, 1.0 - 5e-4, 1.002, 0.5, 0.0])),
      robot_name=st.sampled_from(PRESET_NAMES))
def _quaternions(quat: list[float], position: list[float], scale: float | None, robot_name: str) -> None:
    """pose_to_transform/check_quaternion on any four floats: zero, unnormalised, NaN/inf, huge, tiny.

    Oracle: the quaternion is accepted iff it and the position are finite and |‖q‖ − 1| ≤ 1e-3; an
    accepted one gives an exact rotation. A valid pose then goes to the planner as a goal.
    """
    q = np.array(quat, dtype=float)
    if scale is not None:  # often exactly normalised, or just inside / outside the tolerance
        with np.errstate(all='ignore'):
            nrm = np.linalg.norm(q)
            if np.isfinite(nrm) and nrm > 1e-150:
                q = q / nrm * scale
    with np.errstate(all='ignore'):
        nrm = float(np.linalg.norm(q))
    finite_q, finite_p = bool(np.all(np.isfinite(q))), bool(np.all(np.isfinite(position)))
    out = guarded('quaternion', lambda: pose_to_transform(position, q, 'goal'))
    if not finite_p:
        assert out.error is not None and re.search(r'position contains NaN or inf', str(out.error)), out.error
        return
    if not finite_q:
        assert out.error is not None and re.search(r'quaternion contains NaN or inf', str(out.error)), out.error
        return
    if not abs(nrm - 1.0) <= 1e-3:
        assert isinstance(out.error, RequestError), f'quaternion of norm {nrm} accepted'
        assert re.search(r'not normalised \(norm', str(out.error)), out.error
        return
    assert out.error is None, f'a quaternion of norm {nrm} was rejected: {out.error}'
    T = out.value
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) > 0
    np.testing.assert_allclose(check_quaternion(q), q / nrm, rtol=0, atol=1e-15)
    robot = load_robot(robot_name)
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    T_home = robot.fk(robot.home)
    T = T.copy()
    T[:3, 3] = T_home[:3, 3] + 0.05 * T[:3, 3]   # near the home position: often reachable
    plan_and_check('quaternion.plan', planner, T_home, T, timed=False)


test_fuzz_quaternions, test_fuzz_quaternions_slow = _quaternions


#: Singular configurations: (name, robot, builder(delta, rng-like draws) -> q). At delta = 0 the
#: Jacobian of the pose is rank-deficient (geometry, not the library): the metric is singular.
def _planar_stretched(d: float, x: np.ndarray) -> np.ndarray:
    return np.array([x[0], d, x[1]])            # θ2 = 0: links 1 and 2 aligned (det J = sin θ2)


def _planar_folded(d: float, x: np.ndarray) -> np.ndarray:
    return np.array([x[0], PI - d, x[1]])       # θ2 = π: folded back


def _ur5e_elbow(d: float, x: np.ndarray) -> np.ndarray:
    return np.array([x[0], x[1], d, x[2], x[3], x[4]])   # elbow stretched


def _ur5e_wrist(d: float, x: np.ndarray) -> np.ndarray:
    return np.array([x[0], x[1], x[2], x[3], d, x[4]])   # θ5 = 0: wrist axes 4 and 6 aligned


SINGULAR = [('planar_3r', _planar_stretched), ('planar_3r', _planar_folded),
            ('ur5e', _ur5e_elbow), ('ur5e', _ur5e_wrist)]


@fuzz(40, case=st.sampled_from(SINGULAR), data=st.data())
def _singular(case: tuple[str, Callable[[float, np.ndarray], np.ndarray]], data: Any) -> None:
    """Starts (or goals) at and near singular configurations: a stretched or folded planar arm, the
    UR5e elbow and wrist singularities; goals given as joints or as poses."""
    draw = data.draw
    name, build = case
    robot = load_robot(name)
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    delta = draw(st.sampled_from([0.0, 0.0, 1e-12, 1e-9, 1e-6, 1e-4, 1e-2, -1e-6]))
    x = np.array(draw(st.lists(st.floats(-2.5, 2.5), min_size=5, max_size=5)))
    q_s = build(delta, x)
    q_other = joints_near(draw, robot, q_s, draw(st.sampled_from([1e-6, 0.05, 0.3])))
    singular_end = draw(st.sampled_from(['start', 'goal']))
    q_a, q_b = (q_s, q_other) if singular_end == 'start' else (q_other, q_s)
    by_pose = draw(st.booleans())
    if by_pose:
        T_a, T_b = robot.fk(np.stack([q_a, q_b]))
        out = plan_and_check('singular.poses', planner, T_a, T_b)
    else:
        out = plan_and_check('singular.joints', planner, None, None, q_a, q_b)
        if delta == 0.0 and name == 'planar_3r':  # exactly singular joints: the planner must say so and where
            assert isinstance(out.error, SingularMetricError), \
                f'singular {singular_end} {q_s.tolist()} gave {out.value or out.error!r}'
            # The other end may be numerically singular too (a tiny move): then the start is named.
            assert re.search(rf"singular for robot '{name}' at the (start|goal)", str(out.error)), str(out.error)
        elif delta == 0.0 and out.error is not None:   # 6 joints, the line: planned exactly (checked), or
            assert isinstance(out.error, PathFollowError), out.error      # refused naming the singularity
            assert re.search(r'singularit', str(out.error)), str(out.error)


test_fuzz_singular, test_fuzz_singular_slow = _singular


@fuzz(25, robot=robots(), data=st.data())
def _plan_through(robot: Chain, data: Any) -> None:
    """Piecewise geodesics through 2-5 poses (repeated via points included; sometimes a NaN one)."""
    draw = data.draw
    planner = GeodesicPlanner(robot, time_limit=SOLVE_TIME_LIMIT)
    qs = [joints_in(draw, robot)]
    for _ in range(draw(st.integers(1, 3))):
        qs.append(qs[-1].copy() if draw(st.integers(0, 4)) == 0 else joints_near(draw, robot, qs[-1], 0.15))
    poses = list(robot.fk(np.array(qs)))
    with_joints = draw(st.booleans())
    bad = draw(st.sampled_from([None, None, None, 'nan']))
    if bad:
        k = draw(st.integers(1, len(poses) - 1))
        poses[k] = poses[k].copy()
        poses[k][1, 3] = np.nan
        expect_error('plan_through', lambda: planner.plan_through(poses, qs[0] if with_joints else None),
                     RequestError, rf'^via point {k}: transform contains NaN or inf$')
        return
    out = guarded('plan_through', lambda: planner.plan_through(poses, qs[0] if with_joints else None))
    if out.value is None:
        return
    path = out.value
    check_path(planner, path, qs[0] if with_joints else None, None, None if with_joints else poses[0], poses[-1])
    bp = path.breakpoints
    assert bp[0] == 0.0 and bp[-1] == 1.0 and np.all(np.diff(bp) > 0), f'breakpoints {bp}'
    tr = guarded('plan_through.timed', path.timed)
    if tr.value is not None:
        check_trajectory(path, tr.value, robot.max_velocity, robot.max_acceleration, planner.tol)


test_fuzz_plan_through, test_fuzz_plan_through_slow = _plan_through






LIMIT_VALUE = st.one_of(st.floats(1e-3, 1e3), st.sampled_from([1e-9, 1e9]))
HOSTILE_LIMIT = st.sampled_from([0.0, -1.0, np.nan, np.inf, -np.inf])


@fuzz(40, which=st.sampled_from(['planar_3r', 'rrpp', 'ur5e', 'ur5e.piecewise', 'planar_3r.still']),
      data=st.data())
def _timed(which: str, data: Any) -> None:
    """timed() with random, extreme and hostile limits and durations.

    Oracle: hostile limits (<= 0, NaN, inf, wrong count) give LimitError naming the limit and the
    joint; a duration below the minimum gives LimitError with the minimum; otherwise the
    trajectory is within the limits it was given, at rest at both ends, of the asked duration.
    """
    draw = data.draw
    path = sample_path(which)
    dof = path.dof
    cause = None

    def limit(what: str) -> Any:
        nonlocal cause
        form = draw(st.sampled_from(['none', 'scalar', 'vector', 'vector', 'hostile', 'count']))
        if form == 'none':
            return None
        if form == 'scalar':
            return draw(LIMIT_VALUE)
        vec = draw(st.lists(LIMIT_VALUE, min_size=dof, max_size=dof))
        if form == 'hostile':
            i = draw(st.integers(0, dof - 1))
            vec[i] = draw(HOSTILE_LIMIT)
            cause = cause or rf"{what} for joint '{re.escape(path.joint_names[i])}' must be positive and finite"
        elif form == 'count':
            vec = vec + [1.0] if draw(st.booleans()) else vec[:-1]
            cause = cause or rf'{what}: expected 1 or {dof} values \(one per joint\), got {len(vec)}'
        return vec

    vmax_in = limit('max_velocity')
    amax_in = limit('max_acceleration')
    if cause is not None:
        expect_error('timed.hostile', lambda: path.timed(vmax_in, amax_in), LimitError, cause)
        return
    robot = path.robot
    vmax = robot.max_velocity if vmax_in is None else np.broadcast_to(np.asarray(vmax_in, float), (dof,))
    amax = robot.max_acceleration if amax_in is None else np.broadcast_to(np.asarray(amax_in, float), (dof,))
    out = guarded('timed', lambda: path.timed(vmax_in, amax_in))
    if out.value is None:
        return
    traj = out.value
    check_trajectory(path, traj, vmax, amax)
    mode = draw(st.sampled_from(['longer', 'shorter', 'nan', 'negative', 'inf']))
    if mode == 'longer':
        want = traj.duration * draw(st.floats(1.0, 10.0))
        tr2 = guarded('timed.duration', lambda: path.timed(vmax_in, amax_in, duration=want))
        if tr2.value is not None:
            assert tr2.value.duration == pytest.approx(want, rel=1e-12, abs=1e-12)
            check_trajectory(path, tr2.value, vmax, amax)
    elif mode == 'shorter' and traj.duration > 0:
        want = traj.duration * draw(st.floats(0.0, 0.999))
        expect_error('timed.duration', lambda: path.timed(vmax_in, amax_in, duration=want), LimitError,
                     r'shorter than the minimum')
    elif mode in ('nan', 'negative', 'inf'):
        want = {'nan': np.nan, 'negative': -1.0, 'inf': np.inf}[mode]
        expect_error('timed.duration', lambda: path.timed(vmax_in, amax_in, duration=want), LimitError,
                     r'duration must be finite and >= 0')


test_fuzz_timed, test_fuzz_timed_slow = _timed


@fuzz(40, which=st.sampled_from(['planar_3r', 'rrpp', 'ur5e.piecewise']),
      s=st.one_of(st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=6),
                  st.lists(st.floats(-1e-11, 1.0 + 1e-11), max_size=6),
                  st.lists(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=2), min_size=1, max_size=2)))
def _evaluate(which: str, s: list[Any]) -> None:
    """evaluate() and ee_poses() on any numbers: NaN/inf, outside [0, 1], round-off, 2-D, empty.

    Oracle: RequestError iff s is not 1-D, not finite, or outside [0, 1] by more than 1e-12.
    """
    path = sample_path(which)
    arr = np.asarray(s, dtype=float) if not (s and isinstance(s[0], list) and len({len(x) for x in s}) > 1) \
        else None
    if arr is None:  # ragged
        for fn in (path.evaluate, path.ee_poses):
            expect_error('evaluate', lambda: fn(s), RequestError, r'^s: expected a 1-D array of numbers')
        return
    out = guarded('evaluate', lambda: path.evaluate(s))
    pout = guarded('evaluate', lambda: path.ee_poses(s))
    if arr.ndim != 1:
        assert isinstance(out.error, RequestError) and re.search(r'1-D|not', str(out.error)), out.error
    elif not np.all(np.isfinite(arr)):
        assert isinstance(out.error, RequestError) and 'NaN or inf' in str(out.error), out.error
    elif arr.size and (arr.min() < -1e-12 or arr.max() > 1 + 1e-12):
        assert isinstance(out.error, RequestError) and 'must lie in [0, 1]' in str(out.error), out.error
    else:
        assert out.error is None, out.error
        for a in out.value:
            assert a.shape == (arr.size, path.dof) and np.all(np.isfinite(a))
        assert pout.value.shape == (arr.size, 4, 4) and np.all(np.isfinite(pout.value))
        return
    assert isinstance(pout.error, RequestError), pout.error


test_fuzz_evaluate, test_fuzz_evaluate_slow = _evaluate


#: Hostile values per planner option and the words the RequestError must use for it.
BAD_OPTIONS: dict[str, tuple[list[Any], str]] = {
    'metric': (['PAPER', '', 'dp2', 'traditional'], r"^metric: unknown metric"),
    'position_weight': ([-1.0, np.nan, np.inf, -1e-12], r'^metric: position_weight must be finite and >= 0'),
    'orientation_weight': ([-1.0, np.nan, np.inf], r'^metric: orientation_weight must be finite and >= 0'),
    'epsilon': ([-1.0, np.nan, np.inf], r'^metric: epsilon must be finite and >= 0'),
    'nodes': ([-2, 0, 2, 10**6, 5.5], r'^nodes must be in \[3, max_nodes\]'),
    'max_nodes': ([0, 2, -5, 100.5], r'^max_nodes must be an integer >= 3|^nodes must be in \[3, max_nodes\]'),
    'tol': ([0.0, -1e-6, 1.0, 5.0, np.nan, np.inf], r'^tol \(collocation tolerance\) must be a number in \(0, 1\)'),
    'time_limit': ([0.0, -1.0, np.nan], r'^time_limit must be > 0 s or None'),
}


@fuzz(60, robot_name=st.sampled_from(PRESET_NAMES), data=st.data())
def _planner_options(robot_name: str, data: Any) -> None:
    """GeodesicPlanner options: a valid set (random weights, ε, mesh sizes, tolerances, time limits)
    that must plan a short move, or the same with one option broken, which must give RequestError
    naming that option."""
    draw = data.draw
    robot = load_robot(robot_name)
    opts: dict[str, Any] = {
        'metric': draw(st.sampled_from(['paper', 'paper', 'position'])),
        'position_weight': draw(st.one_of(st.floats(0.1, 5.0), st.just(1.0))),
        'orientation_weight': draw(st.one_of(st.floats(0.1, 5.0), st.just(1.0), st.just(0.0))),
        'epsilon': draw(st.one_of(st.none(), st.floats(0.0, 1e-2))),
        'nodes': draw(st.integers(3, 40)),
        'max_nodes': draw(st.sampled_from([2000, 2000, 500, 100])),
        'tol': draw(st.one_of(st.floats(1e-8, 1e-3), st.just(1e-5))),
        'time_limit': draw(st.sampled_from([None, SOLVE_TIME_LIMIT, 0.5])),
    }
    opts['max_nodes'] = max(opts['max_nodes'], opts['nodes'])
    broken = draw(st.sampled_from([None, None, None] + sorted(BAD_OPTIONS)))
    if broken is not None:
        values, cause = BAD_OPTIONS[broken]
        opts[broken] = draw(st.sampled_from(values))
        if broken == 'orientation_weight' and opts['metric'] == 'position':
            opts['metric'] = 'paper'   # the position metric ignores the orientation weight
        expect_error('options', lambda: GeodesicPlanner(robot, **opts), RequestError, cause)
        return
    mk = guarded('options', lambda: GeodesicPlanner(robot, **opts))
    if opts['position_weight'] == 0 and (opts['orientation_weight'] == 0 or opts['metric'] == 'position'):
        assert isinstance(mk.error, RequestError) and 'weights are both 0' in str(mk.error), mk.error
        return
    assert mk.error is None, f'valid options {opts} rejected: {mk.error}'
    planner = mk.value
    q_a = robot.home if robot_name != 'planar_3r' else np.array([0.258, 0.583, -0.317])
    q_b = np.clip(q_a + 0.1, robot.lower, robot.upper)
    plan_and_check('options.plan', planner, None, None, q_a, q_b, timed=False)


test_fuzz_planner_options, test_fuzz_planner_options_slow = _planner_options


@fuzz(40, robot=robots(), data=st.data())
def _solve_ik(robot: Chain, data: Any) -> None:
    """solve_ik on reachable, nudged and far targets with valid, hostile and missing seeds."""
    from geodesic_planner.core.ik import solve_ik
    draw = data.draw
    q_t = joints_in(draw, robot)
    T = robot.fk(q_t).copy()
    mode = draw(st.sampled_from(['exact', 'exact', 'moved', 'far']))
    if mode == 'moved':
        T[:3, 3] += np.array(draw(st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3)))
    elif mode == 'far':
        T[:3, 3] += [0.0, 0.0, 25.0]
    seed_kind = draw(st.sampled_from(['none', 'near', 'random', 'nan', 'count']))
    seed = {'none': None, 'near': joints_near(draw, robot, q_t, 0.05), 'random': joints_in(draw, robot),
            'nan': np.full(robot.dof, np.nan), 'count': np.zeros(robot.dof + 1)}[seed_kind]
    tol = draw(st.sampled_from([None, 1e-6, 1e-3, 0.1]))
    if seed_kind in ('nan', 'count'):
        expect_error('ik', lambda: solve_ik(robot, T, seed, tolerance=tol), RequestError,
                     r'IK seed: .*(NaN or inf|got \d+ values)')
        return
    out = guarded('ik', lambda: solve_ik(robot, T, seed, tolerance=tol))
    if mode == 'far':
        assert isinstance(out.error, IKError), out.value
    if out.value is None:
        assert isinstance(out.error, IKError), out.error
        assert math.isfinite(out.error.residual) and out.error.residual > 0
        return
    sol = out.value
    assert sol.success and sol.reason == ''
    dist = float(np.linalg.norm(embed(robot.fk(sol.q)) - embed(T)))
    assert dist <= (tol or 1e-3) * (1 + 1e-9), f'IK success but {dist:.3g} from the target'
    assert dist == pytest.approx(sol.residual, rel=1e-6, abs=1e-12)
    assert bool(robot.within_limits(sol.q, 1e-9)), 'IK solution outside the limits'


test_fuzz_solve_ik, test_fuzz_solve_ik_slow = _solve_ik


@fuzz(40, data=st.data())
def _robot_models(data: Any) -> None:
    """chain_from_dh with broken tables and limits, load_robot with arbitrary names: KinematicsError
    / RequestError naming the problem, or a usable chain (fk finite)."""
    draw = data.draw
    n = draw(st.integers(0, 4))
    rows = [list(draw(st.lists(st.floats(-2.0, 2.0), min_size=4, max_size=4))) for _ in range(n)]
    kinds = [draw(st.sampled_from(['revolute', 'prismatic'])) for _ in range(n)]
    kw: dict[str, Any] = {}
    defect = draw(st.sampled_from(['none', 'nan', 'inf', 'kind', 'row', 'limits', 'nan limit', 'speed',
                                   'home', 'kinds count']))
    cause = None
    if n == 0:
        cause = r'at least one actuated joint|0 DH rows'
    elif defect in ('nan', 'inf'):
        rows[draw(st.integers(0, n - 1))][draw(st.integers(0, 3))] = np.nan if defect == 'nan' else np.inf
        cause = r'DH row \d contains NaN or inf'
    elif defect == 'kind':
        kinds[0] = draw(st.sampled_from(['continuous', 'floating', 'ball', '']))
        cause = r'unsupported type'
    elif defect == 'row':
        rows[0] = rows[0][:draw(st.integers(0, 3))]
        cause = r'DH row 0 needs 4 numbers'
    elif defect in ('limits', 'nan limit'):
        kw['lower'] = [1.0] * n
        kw['upper'] = [0.5 if defect == 'limits' else np.nan] * n
        cause = r'lower limit > upper limit|limit'
    elif defect == 'speed':
        kw['max_velocity'] = draw(st.sampled_from([0.0, -1.0, np.nan]))
        cause = r'positive velocity and acceleration limits'
    elif defect == 'home':
        kw['home'] = [0.0] * (n + 1)
        cause = rf'home needs {n} values'
    elif defect == 'kinds count':
        kinds = kinds[:-1]
        cause = r'DH rows but \d+ joint kinds'
    modified = draw(st.booleans())
    out = guarded('robot models', lambda: chain_from_dh('fuzz', rows, kinds, modified=modified, **kw))
    if cause is not None:
        assert isinstance(out.error, KinematicsError), f'{defect}: {out.value or out.error!r}'
        assert re.search(cause, str(out.error)), f'{defect}: {out.error}'
    else:
        assert out.error is None, out.error
        T = out.value.fk(np.zeros(n))
        assert np.all(np.isfinite(T))
    name = draw(st.one_of(st.text(max_size=12).filter(lambda t: '\x00' not in t), st.sampled_from(PRESET_NAMES)))
    res = guarded('robot models', lambda: load_robot(name))
    if name in PRESET_NAMES:
        assert res.value is not None and res.value.name == name
    else:
        assert isinstance(res.error, RequestError), res.value
        assert re.search(r'unknown robot|cannot read URDF|expected a preset', str(res.error)), res.error


test_fuzz_robot_models, test_fuzz_robot_models_slow = _robot_models
