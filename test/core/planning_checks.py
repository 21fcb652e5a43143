"""Shared checks of the core tests: guarded calls, expected errors and the geodesic oracles.

Every guarded call is timed and recorded in :data:`STATS` (the fuzz report of docs/reliability.md);
only values and :class:`~geodesic_planner.core.errors.GeodesicPlannerError` subclasses whose message
names the cause may come out of the library.
"""
from __future__ import annotations

import json
import math
import os
import re
import time
from collections import Counter, defaultdict
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from hypothesis import Phase

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.errors import (
    BVPError,
    GeodesicPlannerError,
    IKError,
    PathFollowError,
    KinematicsError,
    LimitError,
    RequestError,
    SingularMetricError,
)
from geodesic_planner.core.kinematics import Chain

# ---------------------------------------------------------------------------------------- budget
#: Wall-clock budget given to every fuzzed planner's geodesic solve, s.
SOLVE_TIME_LIMIT = 4.0
#: Any single library call must return (or raise) within this bound, s: no hangs.
CALL_BOUND = 15.0
FAST_EXAMPLES = int(os.environ.get('GP_FUZZ_EXAMPLES', '0')) or None
SLOW_FACTOR = 20
QUICK_PHASES = (Phase.explicit, Phase.reuse, Phase.generate)

PRESET_NAMES = ('planar_3r', 'rrpp', 'ur5e', 'panda')

#: What a message must mention for each exception type (the cause, in words).
CAUSES: dict[type, str] = {
    # first: its subclasses are also LimitError / IKError, with a message of the line's own
    PathFollowError: r'(passes through a singularity|would pass its limit|cannot be followed).*'
                     r'% of the way.*followable fraction',
    RequestError: r'NaN|inf|expected|got|normalis|quaternion|rotation|shape|joints|last row|must|'
                  r'unknown|give|values|both 0|metric|nodes|time_limit|tolerance|not a numeric|cannot read|tol',
    IKError: r'IK failed.*(nearest reachable pose|outside joint limits)',
    SingularMetricError: r'singular',
    BVPError: r'did not converge|diverged|time limit|solver failed',
    LimitError: r'limit|duration|traversed|positive|NaN|expected \d+ or \d+ values|velocity|acceleration',
    KinematicsError: r'robot|joint|DH|axis|limit|tool',
}

# ---------------------------------------------------------------------------------------- figures
STATS: dict[str, Any] = {'calls': Counter(), 'outcomes': defaultdict(Counter), 'times': defaultdict(list)}


@pytest.fixture(scope='module', autouse=True)
def _fuzz_report():
    """Write the collected figures to $GP_FUZZ_REPORT (JSON) after the module, if set."""
    yield
    path = os.environ.get('GP_FUZZ_REPORT')
    if not path:
        return
    out: dict[str, Any] = {}
    for cat, n in sorted(STATS['calls'].items()):
        t = np.array(STATS['times'][cat]) * 1e3
        out[cat] = {'calls': n, 'outcomes': dict(STATS['outcomes'][cat]),
                    'time_ms_median': float(np.median(t)), 'time_ms_p90': float(np.percentile(t, 90)),
                    'time_ms_max': float(t.max())}
    with open(path, 'w', encoding='utf-8') as fh:
        json.dump(out, fh, indent=1, sort_keys=True)


class Outcome:
    """Result of one guarded call: ``value`` or ``error`` (a GeodesicPlannerError)."""

    def __init__(self, value: Any = None, error: GeodesicPlannerError | None = None,
                 seconds: float = 0.0) -> None:
        self.value, self.error, self.seconds = value, error, seconds


def guarded(category: str, fn: Callable[[], Any]) -> Outcome:
    """Run ``fn`` once; only values and documented errors naming their cause may come out, in time.

    Raises:
        AssertionError: a foreign exception (bare numpy/scipy/Python error), an empty or
            cause-less message, or a call slower than CALL_BOUND.
    """
    t0 = time.perf_counter()
    try:
        value = fn()
    except GeodesicPlannerError as err:
        dt = time.perf_counter() - t0
        _record(category, type(err).__name__, dt)
        msg = str(err)
        assert msg.strip(), f'{type(err).__name__} with an empty message'
        pattern = next((p for k, p in CAUSES.items() if isinstance(err, k)), None)
        assert pattern is not None, f'undocumented error type {type(err).__name__}: {msg}'
        assert re.search(pattern, msg), f'{type(err).__name__} message does not name a cause: {msg!r}'
        assert dt < CALL_BOUND, f'{category}: took {dt:.1f} s before raising {type(err).__name__}'
        return Outcome(error=err, seconds=dt)
    except Exception as err:  # the property under test: nothing else may escape
        raise AssertionError(f'{category}: bare {type(err).__module__}.{type(err).__name__} escaped '
                             f'the library: {err}') from err
    dt = time.perf_counter() - t0
    _record(category, 'ok', dt)
    assert dt < CALL_BOUND, f'{category}: call took {dt:.1f} s (bound {CALL_BOUND} s)'
    return Outcome(value=value, seconds=dt)


def _record(category: str, outcome: str, seconds: float) -> None:
    STATS['calls'][category] += 1
    STATS['outcomes'][category][outcome] += 1
    STATS['times'][category].append(seconds)


def expect_error(category: str, fn: Callable[[], Any], kind: type, cause: str) -> GeodesicPlannerError:
    """Guarded call that must raise ``kind`` with a message matching ``cause`` (regex, case-insensitive)."""
    out = guarded(category, fn)
    assert out.error is not None, f'{category}: expected {kind.__name__} ({cause}), got a result'
    assert isinstance(out.error, kind), f'{category}: expected {kind.__name__}, got {out.error!r}'
    assert re.search(cause, str(out.error), re.IGNORECASE), \
        f'{category}: message does not name {cause!r}: {out.error}'
    return out.error


# ---------------------------------------------------------------------------------------- oracles
S_CHECK = np.linspace(0.0, 1.0, 81)
#: Tolerance on the boundary joints, rad or m.
BC_TOL = 1e-7
#: Relative variation of the metric speed allowed along a solved geodesic.
SPEED_TOL = 2e-3
#: Relative geodesic-equation residual allowed (independent finite-difference check).
GEODESIC_TOL = 5e-3
#: Relative residual of the library's own path.residual (beyond the solver's absolute tolerance,
#: relative to |G| (|q'|^2 + |q''|)).
LIB_RESIDUAL_TOL = 1e-3


def weights12(planner: GeodesicPlanner) -> np.ndarray:
    """Ω as a 12-vector of squared weights on f = (p, n, o, a)."""
    m = planner.metric
    return np.concatenate([np.full(3, m.position_weight**2), np.full(9, m.effective_orientation_weight**2)])


def embed(T: np.ndarray) -> np.ndarray:
    """f = (p, n, o, a) of transforms (..., 4, 4) -> (..., 12), written here (not the library's)."""
    return np.concatenate([T[..., :3, 3], T[..., :3, 0], T[..., :3, 1], T[..., :3, 2]], axis=-1)


def fd_jacobian12(robot: Chain, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """∂f/∂q by central differences of fk: (N, dof) -> (N, 12, dof)."""
    cols = []
    for k in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[k] = h
        cols.append((embed(robot.fk(q + dq)) - embed(robot.fk(q - dq))) / (2 * h))
    return np.stack(cols, axis=-1)


def geodesic_defect(planner: GeodesicPlanner, path: Any, s: np.ndarray, h: float = 1e-3) -> float:
    """Largest relative residual of the geodesic equation  Jᵀ Ω f''(s) + ε q''(s) = 0.

    For the pull-back metric G = Jᵀ Ω J + ε I the geodesic equation G q'' + Jᵀ Ω H = 0 is exactly
    this, with f(s) = embed(fk(q(s))) the tool curve. f'' comes from second differences of fk along
    the path and J from central differences: independent of the library's derivatives. The scale is
    |J| |Ω| (|f''| + |f'|² / r) + ε |q''| with r = 1 m: the size of the terms that must cancel.
    """
    robot = path.robot
    inner = s[(s > 2 * h) & (s < 1 - 2 * h)]
    q_m = path.evaluate(inner - h)[0]
    q_0, dq_0, ddq_0, _ = path.evaluate(inner)
    q_p = path.evaluate(inner + h)[0]
    f_m, f_0, f_p = (embed(robot.fk(q)) for q in (q_m, q_0, q_p))
    f2 = (f_p - 2 * f_0 + f_m) / h**2
    f1 = (f_p - f_m) / (2 * h)
    w = weights12(planner)
    J = fd_jacobian12(robot, q_0)
    eps = planner.metric.epsilon
    r = np.einsum('nki,nk->ni', J, w * f2) + eps * ddq_0
    Jn = np.linalg.norm(J, axis=(1, 2))
    # The terms that must cancel set the scale; two absolute floors are subtracted first: the
    # solver's tolerance (solve_bvp bounds the error of q'' by tol (1 + |q''|): an absolute error,
    # which dominates on very short paths) and the round-off of the second differences (4 u |f| / h²).
    scale = Jn * w.max() * (np.linalg.norm(f2, axis=1) + np.sum(f1 * f1, axis=1)) \
        + eps * np.linalg.norm(ddq_0, axis=1) + 1e-300
    floor = (Jn**2 * w.max() + eps) * planner.tol * (1.0 + np.linalg.norm(ddq_0, axis=1)) \
        + Jn * w.max() * 4.5e-16 * np.maximum(1.0, np.abs(f_0).max(axis=1)) / h**2
    excess = np.maximum(np.linalg.norm(r, axis=1) - floor, 0.0)
    return float(np.max(excess / scale)) if inner.size else 0.0


#: Relative residuals allowed on a least-motion piece of a redundant arm (finite differences).
LEAST_MOTION_TOL = 1e-4


def least_motion_defect(path: Any, s: np.ndarray, h: float = 1e-4) -> tuple[float, float]:
    """Largest relative residuals of a least-motion piece (method 'redundant', docs/maths.md#redundant-arms),
    from finite differences of the path's positions and of fk (not the library's derivatives).

    Returns:
        (Euler-Lagrange: the null-space part of q'' (q'' must be orthogonal to the null space of J)
        against |q''| + |q'|²; the tool's twist (dp/ds, ω with ω^ = R' Rᵀ, base frame) against its
        mean: it is constant along line + slerp).
    """
    robot = path.robot
    inner = s[(s > 2 * h) & (s < 1 - 2 * h)]
    q_m, q_0, q_p = (path.evaluate(inner + d, order=0)[0] for d in (-h, 0.0, h))
    q1 = (q_p - q_m) / (2 * h)
    q2 = (q_p - 2 * q_0 + q_m) / h**2
    null = np.linalg.svd(fd_jacobian12(robot, q_0))[2][:, 6:, :]      # J₁₂ has the geometric J's null space
    # Less the round-off of the second differences (4 u |q| / h²), against |q''| + |q'|².
    floor = 4.5e-16 * np.maximum(1.0, np.abs(q_0).max(axis=1)) / h**2
    el = np.maximum(np.linalg.norm(np.einsum('nri,ni->nr', null, q2), axis=1) - floor, 0.0) / (
        np.linalg.norm(q2, axis=1) + np.sum(q1 * q1, axis=1) + 1e-300)
    T_m, T_0, T_p = (robot.fk(q) for q in (q_m, q_0, q_p))
    W = (T_p[:, :3, :3] - T_m[:, :3, :3]) / (2 * h) @ np.swapaxes(T_0[:, :3, :3], 1, 2)
    w = 0.5 * np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]], axis=1)
    V = np.concatenate([(T_p[:, :3, 3] - T_m[:, :3, 3]) / (2 * h), w], axis=1)
    mean = V.mean(axis=0)
    twist = max(np.abs(V - mean).max() - 4.5e-16 * max(1.0, np.abs(T_0).max()) / h, 0.0) / max(
        float(np.linalg.norm(mean)), 1e-300)
    return float(el.max(initial=0.0)), float(twist)


def check_geodesic_piece(planner: GeodesicPlanner, path: Any, what: str) -> None:
    """Metric speed constant and both residuals small on one geodesic (a GeodesicPath); on a
    least-motion piece of a redundant arm, the residuals of least_motion_defect instead."""
    robot = path.robot
    if getattr(path.solver, 'method', '') == 'redundant':
        speed = path.metric_speed(S_CHECK)
        if path.length > 1e-6:
            var = float(np.max(np.abs(speed - path.length)) / path.length)
            assert var < 1e-6, f'{what}: the paper metric\'s speed varies by {var:.3g} of its mean'
            el, twist = least_motion_defect(path, S_CHECK)
            assert el < LEAST_MOTION_TOL, f'{what}: Euler-Lagrange residual (finite differences) {el:.3g}'
            assert twist < LEAST_MOTION_TOL, f'{what}: the tool\'s twist varies by {twist:.3g} of its mean'
        return
    if getattr(path.solver, 'method', '') == 'trace':
        # the line traced step by step (core/trace.py): the tool's twist is the line's, constant
        # (by finite differences of the FK), whatever the joints do near a singular end
        if path.length > 1e-6:
            twist = least_motion_defect(path, S_CHECK)[1]
            assert twist < LEAST_MOTION_TOL, f'{what}: the tool\'s twist varies by {twist:.3g} of its mean'
        return
    q, dq, ddq, _ = path.evaluate(S_CHECK)
    speed = planner.metric.speed(robot, q, dq)
    L = path.length
    if L > 1e-6:
        var = float(np.max(np.abs(speed - L)) / L)
        assert var < SPEED_TOL, f'{what}: metric speed varies by {var:.3g} of its mean {L:.4g}'
        res = path.residual(S_CHECK)
        Gn = np.linalg.norm(planner.metric.tensor(robot, q), axis=(1, 2))
        # Scale |G| (|q'|² + |q''|); floor: the solver's absolute tolerance |G| tol (1 + |q''|).
        excess = np.maximum(res - Gn * planner.tol * (1.0 + np.linalg.norm(ddq, axis=1)), 0.0)
        rel = float(np.max(excess / (Gn * (np.sum(dq * dq, axis=1) + np.linalg.norm(ddq, axis=1)))))
        assert rel < LIB_RESIDUAL_TOL, f'{what}: path.residual beyond tol / (|G| (|q\'|² + |q\'\'|)) = {rel:.3g}'
        d = geodesic_defect(planner, path, S_CHECK)
        assert d < GEODESIC_TOL, f'{what}: geodesic equation residual (finite differences) {d:.3g}'
    else:
        assert float(np.max(speed)) < 1e-5, f'{what}: zero-length path moves (speed {speed.max():.3g})'


def check_path(planner: GeodesicPlanner, path: Any, q_a: np.ndarray | None, q_b: np.ndarray | None,
               T_a: np.ndarray | None = None, T_b: np.ndarray | None = None,
               tolerance: float | None = None) -> None:
    """Assert that a returned path is valid (see the module docstring)."""
    robot = planner.robot
    n = robot.dof
    q, dq, ddq, dddq = path.evaluate(S_CHECK)
    for name, arr in (('q', q), ("q'", dq), ("q''", ddq), ("q'''", dddq)):
        assert arr.shape == (S_CHECK.size, n), f'evaluate: {name} has shape {arr.shape}'
        assert np.all(np.isfinite(arr)), f'evaluate: {name} has NaN or inf'
    # Boundary conditions: the given joints, or the IK solutions reported with the path (whose
    # poses are checked against the request below).
    for end, ik_name, k in (('start', 'ik_start', 0), ('goal', 'ik_goal', -1)):
        ik = getattr(path, ik_name, None) or getattr(getattr(path, 'pieces', [None])[k], ik_name, None)
        given = q_a if end == 'start' else q_b
        if given is None:
            assert (T_a if end == 'start' else T_b) is not None, f'{end}: neither joints nor a pose'
            q_ik = ik.q if ik is not None else (path.q_start if end == 'start' else path.q_goal)
            if end == 'start':
                q_a = q_ik
            else:
                q_b = q_ik
        if ik is not None:
            assert ik.success and not ik.reason, f'{end}: path returned with a failed IK ({ik.reason})'
    np.testing.assert_allclose(q[0], q_a, atol=BC_TOL, rtol=0, err_msg='q(0) != start joints')
    np.testing.assert_allclose(q[-1], q_b, atol=BC_TOL, rtol=0, err_msg='q(1) != goal joints')
    np.testing.assert_allclose(path.q_start, q_a, atol=BC_TOL, rtol=0)
    np.testing.assert_allclose(path.q_goal, q_b, atol=BC_TOL, rtol=0)
    # Requested poses are met within the IK tolerance (weighted embedding distance).
    tol = 1e-3 if tolerance is None or not tolerance > 0 else tolerance
    w = np.sqrt(weights12(planner))
    for T, qe, end in ((T_a, q_a, 'start'), (T_b, q_b, 'goal')):
        if T is not None:
            dist = float(np.linalg.norm(w * (embed(robot.fk(qe)) - embed(T))))
            assert dist <= tol * (1 + 1e-6) + 1e-12, f'{end} pose missed by {dist:.3g} (tolerance {tol:g})'
    if planner.check_limits:
        q_dense = path.evaluate(np.linspace(0.0, 1.0, 2001))[0]
        out = float(np.max(np.maximum(robot.lower - q_dense, q_dense - robot.upper)))
        assert out <= 1e-9, f'path leaves the joint limits by {out:.3g} between mesh nodes'
    poses = path.ee_poses(S_CHECK)
    assert np.all(np.isfinite(poses))
    if planner.tol > 1e-4:  # the user asked for a coarse solve: only the above is promised
        return
    pieces = getattr(path, 'pieces', [path])
    for i, piece in enumerate(pieces):
        check_geodesic_piece(planner, piece, f'piece {i}')
    if len(pieces) > 1:  # eq. 10: the same metric speed on every piece of the global parameter
        speed = planner.metric.speed(robot, q, dq)
        if path.length > 1e-6:
            var = float(np.max(np.abs(speed - path.length)) / path.length)
            assert var < SPEED_TOL * 2, f'piecewise: global metric speed varies by {var:.3g}'


def check_trajectory(path: Any, traj: Any, vmax: np.ndarray, amax: np.ndarray, tol: float = 1e-5) -> None:
    """A timed trajectory: finite, within limits, at rest at both ends, at the path's ends, and
    dq, ddq the time derivatives of q, dq (up to the path's solver tolerance ``tol``)."""
    T = traj.duration
    assert math.isfinite(T) and T >= 0.0, f'duration {T}'
    t = np.linspace(0.0, T, 1501)
    q, dq, ddq = traj.at_time(t)
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.all(np.isfinite(ddq))
    rv = float(np.max(np.abs(dq) / vmax))
    assert rv <= 1 + 1e-6, f'velocity limit exceeded: max ratio {rv:.6g}'
    ra = float(np.max(np.abs(ddq) / amax))
    assert ra <= 1 + 1e-6, f'acceleration limit exceeded: max ratio {ra:.6g}'
    for k in (0, -1):
        np.testing.assert_allclose(dq[k], 0.0, atol=1e-9, err_msg='not at rest (velocity)')
        np.testing.assert_allclose(ddq[k], 0.0, atol=1e-9, err_msg='not at rest (acceleration)')
    np.testing.assert_allclose(q[0], path.q_start, atol=1e-9, rtol=0)
    np.testing.assert_allclose(q[-1], path.q_goal, atol=1e-9, rtol=0)
    if T > 0:
        # Velocities and accelerations are the time derivatives of what at_time returns (central
        # differences at interior times; h small against every ramp of the time law).
        tc = t[5:-5:15]
        h = 1e-7 * T
        qp, dqp, _ = traj.at_time(tc + h)
        qm, dqm, _ = traj.at_time(tc - h)
        _, dq_c, ddq_c = traj.at_time(tc)
        # Allowed: a small fraction of the limit plus the round-off of the differences, plus for ddq
        # the solver's tolerance: a GeodesicPath's q'' is the geodesic equations' value, its q' the
        # spline's derivative; they agree to tol (1 + |q''|) (absolute), times sdot².
        _, sd_c, _ = traj.s_of_t(tc)
        q2 = np.abs(path.evaluate(traj.s_of_t(tc)[0])[2])
        noise_v = 4e-16 * (np.abs(q).max() + 1.0) / (2 * h) / vmax
        noise_a = 4e-16 * (np.abs(dq).max() + 1.0) / (2 * h) / amax + tol * (1.0 + q2) * (sd_c**2)[:, None] / amax
        err_v = np.abs((qp - qm) / (2 * h) - dq_c) / vmax - noise_v
        err_a = np.abs((dqp - dqm) / (2 * h) - ddq_c) / amax - noise_a
        assert err_v.max() < 1e-4, f'dq is not the derivative of q (error {err_v.max():.3g} of the limit)'
        assert err_a.max() < 1e-3, f'ddq is not the derivative of dq (error {err_a.max():.3g} of the limit)'


# ---------------------------------------------------------------------------------------- hostile input
_CELL = np.arange(16).reshape(4, 4)   # index of each entry of a 4x4 matrix


def _skew(T: np.ndarray, k: float) -> np.ndarray:
    T = T.copy()
    T[0, 1] += k
    return T


#: Hostile 4x4 transforms: (name, builder(T, x) -> value, cause regex); all RequestError.
HOSTILE_POSES: list[tuple[str, Callable[[np.ndarray, float], Any], str]] = [
    ('nan', lambda T, x: np.where(_CELL == 5, np.nan, T), r'NaN or inf'),
    ('inf position', lambda T, x: np.where(_CELL == 3, np.inf, T), r'NaN or inf'),
    ('scaled rotation', lambda T, x: np.diag([1 + x, 1 + x, 1 + x, 1.0]) @ T, r'not a proper rotation'),
    ('reflection', lambda T, x: np.diag([1.0, 1.0, -1.0, 1.0]) @ T, r'not a proper rotation'),
    ('shear', _skew, r'not a proper rotation'),
    ('zero rotation', lambda T, x: np.where((_CELL % 4 < 3) & (_CELL < 12), 0.0, T), r'not a proper rotation'),
    ('bad last row', lambda T, x: T + np.outer([0, 0, 0, 1.0], [x, 0, 0, 0]), r'last row'),
    ('3x3', lambda T, x: T[:3, :3], r'expected a 4x4.*shape \(3, 3\)'),
    ('flat', lambda T, x: T.reshape(-1), r'expected a 4x4.*shape \(16,\)'),
    ('text', lambda T, x: [['a'] * 4] * 4, r'not a numeric 4x4'),
]


#: Paper Table 2 (planar 3R), rad.
Q3_A, Q3_B = [0.258, 0.583, -0.317], [0.969, 0.380, -0.574]   # paper Table 2 (planar 3R)
#: A panda configuration with several joints at their limits, rad.
PANDA_AT_LIMITS = [-2.8973, -1.7628, 0.1811, -2.978, -2.8973, 0.4538, -1.4486]

_PATHS: dict[str, Any] = {}


def sample_path(name: str) -> Any:
    """A few solved paths, planned once per session (timing is fuzzed on them)."""
    if name not in _PATHS:
        if name == 'planar_3r':
            r = load_robot('planar_3r')
            _PATHS[name] = GeodesicPlanner(r).plan(None, None, [0.258, 0.583, -0.317], [0.969, 0.380, -0.574])
        elif name == 'rrpp':
            r = load_robot('rrpp')
            _PATHS[name] = GeodesicPlanner(r).plan(None, None, [0.123, -1.539, 0.276, -0.640],
                                                   [0.129, -1.629, 0.239, -0.643])
        elif name == 'ur5e':
            r = load_robot('ur5e')
            _PATHS[name] = GeodesicPlanner(r).plan(None, None, r.home, r.home + [0.4, -0.3, 0.2, 0.5, -0.2, 1.0])
        elif name == 'ur5e.piecewise':
            r = load_robot('ur5e')
            qs = r.home + np.array([[0, 0, 0, 0, 0, 0], [0.3, 0.1, 0, 0, 0, 0], [0.3, 0.1, 0.2, 0, 0.3, 0]])
            _PATHS[name] = GeodesicPlanner(r).plan_through(list(r.fk(qs)), qs[0])
        elif name == 'planar_3r.still':
            r = load_robot('planar_3r')
            _PATHS[name] = GeodesicPlanner(r).plan(None, None, [0.3, 0.5, 0.1], [0.3, 0.5, 0.1])
    return _PATHS[name]
