"""Via points without stopping: blend zones of ``plan_through(..., blend_radius=r)`` (issue 14 item 2).

Oracles, computed here apart from :mod:`geodesic_planner.core.blend` and its ``BlendZone`` report:

* the tool pose by forward kinematics on a dense grid of s in every zone (distance from the via
  point, distance from the two segments that meet there, rotation from the via orientation), with
  the rotation angle and the segment distance written out in this file;
* the exact geodesic outside the zones: the tool on the straight segment between the via poses and
  its rotation the slerp (``transforms.line_slerp``), linear in s (6-joint ur5e and planar 3R,
  whose pieces are exactly line + slerp), and for every arm the stopping path's own piece at the
  parameter that follows from the zone widths alone;
* derivatives by central finite differences (in s of ``evaluate``, in t of ``Trajectory.at_time``),
  continuity by one-sided evaluations at the zone ends and by bounded steps on dense grids;
* limits on a dense time grid (velocity, acceleration, and jerk with ``max_jerk``).

Arms: ur5e, panda, planar_3r, rrpp; fixed sequences plus random via sequences (hypothesis,
derandomized and short, as in test/core/test_fuzz.py and test/timing).
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import urdf_util as U
from hypothesis import HealthCheck, Phase, assume, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core import blend
from geodesic_planner.core.blend import BlendedPath
from geodesic_planner.core.errors import GeodesicPlannerError, RequestError
from geodesic_planner.core.piecewise import PiecewiseGeodesicPath
from geodesic_planner.core.transforms import line_slerp, so3_exp

ROBOTS = ('ur5e', 'panda', 'planar_3r', 'rrpp')
#: Dense samples per zone for the FK checks (the library checks 201).
ZONE_SAMPLES = 2001
#: Dense time samples of the limit checks.
TIME_SAMPLES = 20001
#: Relative slack on "never above a limit" (round-off only).
LIMIT_RTOL = 1e-6
#: Wall-clock budget of every geodesic solve, s.
SOLVE_TIME_LIMIT = 10.0

HYPOTHESIS = settings(max_examples=4, derandomize=True, deadline=None, database=None, print_blob=True,
                      phases=(Phase.explicit, Phase.reuse, Phase.generate),
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])

_PLANNERS: dict[str, GeodesicPlanner] = {}


def planner(name: str) -> GeodesicPlanner:
    """One planner per preset robot for the whole module (robots are immutable)."""
    if name not in _PLANNERS:
        _PLANNERS[name] = GeodesicPlanner(load_robot(name), time_limit=SOLVE_TIME_LIMIT)
    return _PLANNERS[name]


# ------------------------------------------------------------------------------ independent geometry
def rot_angle(R_a: np.ndarray, R_b: np.ndarray) -> np.ndarray:
    """Angle (rad) of R_aᵀ R_b for (..., 3, 3) rotations, by atan2(|vee|, trace - 1)."""
    E = np.swapaxes(R_a, -1, -2) @ R_b
    vee = np.stack([E[..., 2, 1] - E[..., 1, 2], E[..., 0, 2] - E[..., 2, 0], E[..., 1, 0] - E[..., 0, 1]], -1)
    return np.arctan2(np.linalg.norm(vee, axis=-1), np.trace(E, axis1=-2, axis2=-1) - 1.0)


def seg_dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of points p (N, 3) from the segment a-b."""
    ab = b - a
    den = float(ab @ ab)
    t = np.zeros(len(p)) if den == 0.0 else np.clip((p - a) @ ab / den, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def fk(robot: Any, q: np.ndarray) -> np.ndarray:
    """Tool poses (N, 4, 4); for ur5e and panda the FK written out in test/urdf_util.py."""
    if robot.name == 'ur5e':
        return U.ur5e_fk_batch(q)
    if robot.name == 'panda':
        return U.panda_fk_batch(q)
    return robot.fk(q)


def cartesian_poses(T0: np.ndarray, steps: list[tuple[list[float], list[float]]]) -> list[np.ndarray]:
    """T0 then each pose moved by (dp base frame, m; rotation vector, tool frame, rad)."""
    poses = [T0]
    for dp, w in steps:
        T = poses[-1].copy()
        T[:3, 3] += dp
        T[:3, :3] = T[:3, :3] @ so3_exp(np.array(w, dtype=float))
        poses.append(T)
    return poses


# ------------------------------------------------------------------------------ scenarios
UR5E_Q0 = [0.3, -0.2, 0.2, 0.1, 0.3, 0.2]          # offset from home
UR5E_STEPS = [([0.1, 0.05, -0.05], [0.2, 0.1, 0.0]), ([-0.05, 0.1, 0.05], [0.0, 0.15, 0.1]),
              ([0.08, -0.02, 0.06], [0.1, 0.0, -0.2]), ([0.0, -0.1, -0.04], [-0.1, 0.1, 0.1])]
#: Joint configurations whose tool poses are the via poses (planar 3R, panda, rrpp).
JOINT_SEQUENCES = {
    'planar_3r': [[0.3, 0.9, 0.7], [0.5, 0.6, 0.9], [0.2, 0.8, 1.3], [0.6, 0.4, 0.8]],
    'panda': [[0.0] * 7, [0.2, 0.1, -0.1, 0.2, 0.1, -0.1, 0.2], [0.3, -0.1, 0.0, 0.4, 0.2, 0.1, 0.0],
              [0.1, -0.2, 0.1, 0.2, 0.3, 0.3, -0.1]],
    'rrpp': [[0.0] * 4, [0.2, 0.1, 0.1, -0.1], [0.4, -0.1, 0.2, 0.1], [0.2, -0.3, 0.0, 0.2]],
}
RADIUS = {'ur5e': 0.03, 'panda': 0.04, 'planar_3r': 0.1, 'rrpp': 0.1}


def scenario(name: str) -> tuple[np.ndarray, list[np.ndarray]]:
    """Start joints and via poses (5 on ur5e, 4 elsewhere) of the fixed sequence of ``name``."""
    robot = planner(name).robot
    if name == 'ur5e':
        q0 = robot.home + np.array(UR5E_Q0)
        return q0, cartesian_poses(robot.fk(q0[None])[0], UR5E_STEPS)
    qs = np.array(JOINT_SEQUENCES[name]) + (robot.home if name == 'panda' else 0.0)
    return qs[0], list(robot.fk(qs))


_CACHE: dict[tuple[str, float], tuple[BlendedPath, list[np.ndarray]]] = {}


def blended(name: str) -> tuple[BlendedPath, list[np.ndarray]]:
    """The blended path of the fixed sequence (cached) and its via poses."""
    key = (name, RADIUS[name])
    if key not in _CACHE:
        q0, poses = scenario(name)
        path = planner(name).plan_through(poses, start_joints=q0, blend_radius=RADIUS[name])
        assert isinstance(path, BlendedPath)
        _CACHE[key] = (path, poses)
    return _CACHE[key]


# ------------------------------------------------------------------------------ checks
def junction_poses(path: BlendedPath) -> np.ndarray:
    """Tool pose at every junction of the stopping path (start, kept via points, goal)."""
    return fk(path.robot, path.stopping_path.via_joints)


def check_zones(path: BlendedPath, poses: list[np.ndarray], radii: np.ndarray) -> None:
    """Every zone within its radius (own dense FK), and its BlendZone report agrees."""
    robot = path.robot
    ends = junction_poses(path)
    junctions = len(path.stopping_path.pieces) - 1
    assert len(path.zones) == junctions, f'{junctions} corners, {len(path.zones)} blended'
    for k, z in enumerate(path.zones, start=1):
        r = float(radii[z.via - 1])
        assert z.radius == r
        via = poses[z.via]
        # The junction of the stopping path is the via point named by the zone.
        assert np.linalg.norm(ends[k][:3, 3] - via[:3, 3]) <= 1e-6
        assert rot_angle(ends[k][:3, :3], via[:3, :3]) <= 1e-6
        s = np.linspace(z.s_start, z.s_end, ZONE_SAMPLES)
        T = fk(robot, path.evaluate(s, 0)[0])
        p = T[:, :3, 3]
        dist = np.linalg.norm(p - via[:3, 3], axis=1)
        ang = rot_angle(via[:3, :3], T[:, :3, :3])
        dev = np.minimum(seg_dist(p, ends[k - 1][:3, 3], via[:3, 3]), seg_dist(p, via[:3, 3], ends[k + 1][:3, 3]))
        # the IK reaches the via pose to its tolerance; distances below are measured from the
        # pose asked for, so that residual is allowed on top of round-off
        ik = float(np.linalg.norm(ends[k][:3, 3] - via[:3, 3])) + float(rot_angle(ends[k][:3, :3], via[:3, :3]))
        tiny = 1e-12 + ik
        # within r of the via point everywhere (not only on the library's 201 samples)
        assert dist.max() <= r * (1.0 + 1e-9) + tiny, f'via {z.via}: tool {dist.max()} m from it, r = {r}'
        # the report: ends exact; each maximum never above the dense one (the library's 201
        # samples are among these 2001) and below it by at most half a library step times the
        # Lipschitz constant (distance and deviation: the tool speed |dp/ds|; angle: the angular
        # speed), both measured here
        assert (ZONE_SAMPLES - 1) % (blend.CHECK_SAMPLES - 1) == 0
        assert_allclose(z.entry_distance, max(dist[0], dist[-1]), rtol=1e-9, atol=tiny)
        assert_allclose(z.entry_angle, max(ang[0], ang[-1]), rtol=1e-9, atol=tiny)
        ds = s[1] - s[0]
        speed = np.linalg.norm(np.diff(p, axis=0), axis=1).max() / ds
        turn = rot_angle(T[:-1, :3, :3], T[1:, :3, :3]).max() / ds
        half_step = 0.5 * (z.s_end - z.s_start) / (blend.CHECK_SAMPLES - 1)
        for what, reported, own, lip in (('max_distance', z.max_distance, dist.max(), speed),
                                         ('deviation', z.deviation, dev.max(), speed),
                                         ('max_angle', z.max_angle, ang.max(), turn)):
            assert own - 1.01 * lip * half_step - tiny <= reported <= own + tiny, (z.via, what, reported, own)
        # the corner is cut (the blend leaves the stopping path) but stays near it
        assert 0.0 < dev.max() <= r
        # orientation: never turned further from the via orientation than at the zone's ends
        # (first-order claim; 1 % of the entry angle of slack for second-order terms)
        assert ang.max() <= max(ang[0], ang[-1]) * 1.01 + tiny, (z.via, ang.max(), ang[0], ang[-1])
    # zones in order, none overlapping, inside (0, 1)
    edges = [(z.s_start, z.s_end) for z in path.zones]
    flat = np.array(edges).ravel()
    assert np.all(np.diff(flat) >= 0.0) and flat[0] > 0.0 and flat[-1] < 1.0
    assert all(a < b for a, b in edges)


def check_continuity(path: BlendedPath) -> None:
    """q, q', q'', q''' continuous at every zone end (one-sided evaluation) and derivatives consistent
    with finite differences over the whole path."""
    for z in path.zones:
        width = z.s_end - z.s_start
        # the derivatives' size near the zone (a small zone has large derivatives w.r.t. s)
        near = np.linspace(max(z.s_start - width, 0.0), min(z.s_end + width, 1.0), 2001)
        local = [np.abs(d).max() + 1.0 for d in path.evaluate(near)]
        eps = 1e-7 * width
        for s0 in (z.s_start, z.s_end):
            l1, l2 = path.evaluate(np.array([s0 - eps])), path.evaluate(np.array([s0 - 2 * eps]))
            right = path.evaluate(np.array([s0]))
            for m in range(4):
                # the left limit at s0, to O(eps²): a Taylor step (m < 3) or linear extrapolation
                left = l1[m] + eps * l1[m + 1] if m < 3 else 2.0 * l1[m] - l2[m]
                jump = np.abs(left - right[m]).max()
                assert jump <= 1e-6 * local[m], f'd{m}q/ds{m} jumps by {jump} at s = {s0} (via {z.via})'
    # dense finite differences everywhere (inside zones, across their ends, on exact portions),
    # on a grid that resolves every zone
    h = min([1e-5] + [1e-4 * (z.s_end - z.s_start) for z in path.zones])
    s = np.unique(np.concatenate([np.linspace(0.0, 1.0, 3001)] +
                                 [np.linspace(z.s_start, z.s_end, 401) for z in path.zones]))
    s = np.unique(np.clip(s, 2 * h, 1.0 - 2 * h))
    mid = path.evaluate(s)
    scale = [np.abs(d).max() for d in mid]
    plus, minus = path.evaluate(s + h), path.evaluate(s - h)
    for m in range(3):
        fd = (plus[m] - minus[m]) / (2 * h)
        err = np.abs(fd - mid[m + 1]).max()
        # central differences: O(h² d^(m+3)q) plus round-off, O(h d⁴q) next to a zone end (where
        # d⁴q may jump); a jump of d^(m+1)q inside (s - h, s + h) shows as a fraction of the jump
        assert err <= 1e-3 * (scale[m + 1] + 1.0), f'd{m + 1}q/ds{m + 1} vs finite differences: {err}'
    # no jumps of q'' between dense samples (steps bounded by the largest q''' times the step)
    steps = np.abs(np.diff(mid[2], axis=0)).max(axis=1) / np.diff(s)
    assert steps.max() <= 1.5 * scale[3] + 1e-9


def layout(path: BlendedPath) -> list[tuple[int, float, float, float, float]]:
    """The exact portions expected from the zone widths alone: (piece, s_a, s_b, u_a, u_b).

    Each zone takes ℓ_k of metric length from both neighbouring pieces and is ℓ_k long, and the
    metric speed is the path length everywhere, so zone k is ℓ_k / length wide in s and piece i
    keeps u ∈ [ℓ_i / L_i, 1 − ℓ_(i+1) / L_i] (empty when two zones use it up). Checks that the zones
    and ``exact_intervals()`` sit where this says, and that no zone takes more than half a piece.
    """
    stop = path.stopping_path
    widths = np.array([z.s_end - z.s_start for z in path.zones])
    # total length: the stopping path's length minus one ℓ per zone
    assert_allclose(path.length, stop.length / (1.0 + widths.sum()), rtol=1e-9)
    ell = np.concatenate([[0.0], widths * path.length, [0.0]])
    L = np.diff(stop.breakpoints) * stop.length
    out, s0 = [], 0.0
    for i in range(len(stop.pieces)):
        u0, u1 = ell[i] / L[i], 1.0 - ell[i + 1] / L[i]
        assert ell[i] <= 0.5 * L[i] * (1.0 + 1e-9) and ell[i + 1] <= 0.5 * L[i] * (1.0 + 1e-9)
        e = max(u1 - u0, 0.0) * L[i] / path.length
        if u1 - u0 > 1e-9:
            out.append((i, s0, s0 + e, u0, u1))
        s0 += e
        if i < len(path.zones):
            assert_allclose([path.zones[i].s_start, path.zones[i].s_end], [s0, s0 + widths[i]], atol=1e-9)
            s0 += widths[i]
    assert_allclose(s0, 1.0, atol=1e-9)
    assert_allclose(np.array(path.exact_intervals()), np.array([(a, b) for _, a, b, _, _ in out]), atol=1e-9)
    return out


def check_exact_portions(path: BlendedPath) -> None:
    """Outside the zones the blended path is the stopping path's piece, at the parameter of
    :func:`layout`, linear in s."""
    stop = path.stopping_path
    bp = stop.breakpoints
    for i, a, b, u0, u1 in layout(path):
        s = np.linspace(a, b, 201)
        s_stop = bp[i] + (u0 + (s - a) / (b - a) * (u1 - u0)) * (bp[i + 1] - bp[i])
        q, q1 = path.evaluate(s, 1)
        q_ref, q1_ref = stop.evaluate(np.clip(s_stop, 0.0, 1.0), 1)
        assert_allclose(q, q_ref, atol=1e-9)
        # same curve, traversed at the blended path's own rate: dq/ds scales by stop/blended length
        assert_allclose(q1, q1_ref * path.length / stop.length, atol=1e-7 * (np.abs(q1).max() + 1.0))


def check_line_slerp(path: BlendedPath, poses: list[np.ndarray], tol: float = 1e-8) -> None:
    """On each exact interval the tool follows line + slerp between its via poses, linearly in s
    (the piece's parameter at the interval's ends taken from the tool position there)."""
    robot = path.robot
    for i, a, b, u0, u1 in layout(path):
        A, B = poses[i], poses[i + 1]
        s = np.linspace(a, b, 401)
        T = fk(robot, path.evaluate(s, 0)[0])
        d = B[:3, 3] - A[:3, 3]
        ua, ub = ((T[[0, -1], :3, 3] - A[:3, 3]) @ d) / float(d @ d)
        u = ua + (s - a) / (b - a) * (ub - ua)
        ref = line_slerp(A, B, u)
        dp = np.linalg.norm(T[:, :3, 3] - ref[:, :3, 3], axis=1).max()
        da = rot_angle(T[:, :3, :3], ref[:, :3, :3]).max()
        assert dp <= tol, f'piece {i}: tool {dp} m off line + slerp'
        assert da <= tol, f'piece {i}: tool {da} rad off line + slerp'
        # where on the segment: as the metric lengths say (u is the piece's metric fraction)
        assert_allclose([ua, ub], [u0, u1], atol=1e-7)


def zone_times(traj: Any, z: Any, n: int = 2001) -> np.ndarray:
    """n times whose s lies inside zone z (s(t) increasing), s."""
    t = np.linspace(0.0, traj.duration, TIME_SAMPLES)
    s = traj.s_of_t(t)[0]
    inside = t[(s >= z.s_start) & (s <= z.s_end)]
    assert inside.size >= 3, 'zone not seen on the time grid'
    return np.linspace(inside[0], inside[-1], n)


def check_timed(path: BlendedPath, traj: Any) -> None:
    """Passes through without stopping, within the limits, smooth in time."""
    assert traj.rests == (0.0, 1.0)
    assert traj.rest_times == (0.0, traj.duration)
    t = np.linspace(0.0, traj.duration, TIME_SAMPLES)
    q, dq, ddq = traj.at_time(t)
    vmax = np.broadcast_to(path.robot.max_velocity, (path.dof,))
    amax = np.broadcast_to(path.robot.max_acceleration, (path.dof,))
    assert np.all(np.abs(dq) <= vmax * (1.0 + LIMIT_RTOL)), np.abs(dq).max(axis=0) / vmax
    assert np.all(np.abs(ddq) <= amax * (1.0 + LIMIT_RTOL)), np.abs(ddq).max(axis=0) / amax
    # time derivatives consistent with the positions (central differences), hence continuous: a
    # central difference is the mean of the derivative over [t - dt, t + dt], which differs from
    # its middle value by at most dt/2 times the next derivative's largest magnitude
    dt = t[1] - t[0]
    jerk = np.abs(traj.jerk_at_time(t)).max()
    assert_allclose((q[2:] - q[:-2]) / (2 * dt), dq[1:-1], atol=0.5 * dt * np.abs(ddq).max() * 1.01 + 1e-12)
    assert_allclose((dq[2:] - dq[:-2]) / (2 * dt), ddq[1:-1], atol=0.5 * dt * jerk * 1.01 + 1e-12)
    # acceleration continuous: its steps bounded by the largest jerk times the step
    assert np.abs(np.diff(ddq, axis=0)).max() <= 1.1 * jerk * dt + 1e-12
    # the tool keeps moving through every zone (FK differences and Jacobian x joint rates)
    peak = np.linalg.norm((fk(path.robot, q[1:])[:, :3, 3] - fk(path.robot, q[:-1])[:, :3, 3]), axis=1).max() / dt
    for z in path.zones:
        tz = zone_times(traj, z)
        qz, dqz, _ = traj.at_time(tz)
        h = 1e-6
        p_plus = fk(path.robot, traj.at_time(tz + h)[0])[:, :3, 3]
        p_minus = fk(path.robot, traj.at_time(tz - h)[0])[:, :3, 3]
        v_fd = np.linalg.norm(p_plus - p_minus, axis=1) / (2 * h)
        v_jac = np.linalg.norm(np.einsum('nij,nj->ni', path.robot.jacobian(qz)[:, :3], dqz), axis=1)
        assert_allclose(v_fd, v_jac, atol=1e-5 * peak)
        # no stop: the joints keep moving (a rest is every joint at 0). The tool's linear speed
        # alone may vanish where the via pose nearly reverses the line (the blend turns the tool
        # round within the ball, turning its orientation meanwhile); elsewhere it keeps moving.
        joint_peak = np.linalg.norm(dq, axis=1).max()
        assert np.linalg.norm(dqz, axis=1).min() > 1e-3 * joint_peak, f'via {z.via}: the joints nearly stop'
        k = path._via_index.index(z.via) + 1          # its junction among the kept pieces
        a, v, b = (path.robot.fk(path.stopping_path.via_joints[i])[:3, 3] for i in (k - 1, k, k + 1))
        cos_turn = float((v - a) @ (b - v) / (np.linalg.norm(v - a) * np.linalg.norm(b - v)))
        if cos_turn > -0.9:           # not a near reversal: the tool itself keeps moving
            assert v_fd.min() > 1e-3 * peak, f'via {z.via}: tool nearly stops ({v_fd.min()} m/s, peak {peak})'


# ------------------------------------------------------------------------------ fixed sequences
@pytest.mark.parametrize('name', ROBOTS)
def test_blend_zones_within_radius_and_report_agrees(name: str) -> None:
    path, poses = blended(name)
    check_zones(path, poses, np.full(len(poses) - 2, RADIUS[name]))


@pytest.mark.parametrize('name', ROBOTS)
def test_path_continuous_to_third_derivative(name: str) -> None:
    check_continuity(blended(name)[0])


@pytest.mark.parametrize('name', ROBOTS)
def test_exact_geodesic_pieces_outside_zones(name: str) -> None:
    check_exact_portions(blended(name)[0])


@pytest.mark.parametrize('name', ['ur5e', 'planar_3r'])
def test_tool_on_line_and_slerp_outside_zones(name: str) -> None:
    """6-joint and planar 3R pieces are exactly line + slerp: within 1e-8 m and rad."""
    path, poses = blended(name)
    check_line_slerp(path, poses)


@pytest.mark.parametrize('name', ROBOTS)
def test_timed_passes_through_within_limits(name: str) -> None:
    path, _ = blended(name)
    check_timed(path, path.timed())


@pytest.mark.parametrize('name', ['ur5e', 'planar_3r'])
def test_jerk_limited_law_through_blends(name: str) -> None:
    path, _ = blended(name)
    free = path.timed()
    jmax = 0.5 * np.abs(free.jerk_at_time(np.linspace(0.0, free.duration, TIME_SAMPLES))).max(axis=0)
    traj = path.timed(max_jerk=jmax)
    check_timed(path, traj)
    jerk = np.abs(traj.jerk_at_time(np.linspace(0.0, traj.duration, TIME_SAMPLES)))
    assert np.all(jerk <= jmax * (1.0 + LIMIT_RTOL)), jerk.max(axis=0) / jmax


@pytest.mark.parametrize('name', ROBOTS)
def test_angular_velocity_continuous(name: str) -> None:
    """The orientation changes smoothly: ω(s) = J_ω q' agrees with differences of the FK rotations
    and is continuous at the zone ends."""
    path, _ = blended(name)
    robot = path.robot
    s = np.linspace(1e-3, 1.0 - 1e-3, 2001)
    q, q1 = path.evaluate(s, 1)
    w = np.einsum('nij,nj->ni', robot.jacobian(q)[:, 3:], q1)
    h = 1e-6
    Rp, Rm = fk(robot, path.evaluate(s + h, 0)[0])[:, :3, :3], fk(robot, path.evaluate(s - h, 0)[0])[:, :3, :3]
    E = Rp @ np.swapaxes(Rm, 1, 2)                 # base-frame rotation over 2h
    w_fd = 0.5 * np.stack([E[:, 2, 1] - E[:, 1, 2], E[:, 0, 2] - E[:, 2, 0], E[:, 1, 0] - E[:, 0, 1]], 1) / (2 * h)
    assert_allclose(w_fd, w, atol=1e-5 * (np.abs(w).max() + 1.0))
    for z in path.zones:
        for s0 in (z.s_start, z.s_end):
            (qa, qb), (q1a, q1b) = path.evaluate(np.array([s0 - 1e-10, s0]), 1)
            J = robot.jacobian(np.array([qa, qb]))[:, 3:]
            assert_allclose(J[0] @ q1a, J[1] @ q1b, atol=1e-6 * (np.abs(w).max() + 1.0))


# ------------------------------------------------------------------------------ r = 0, bad input, caps
def test_zero_radius_keeps_exact_stop() -> None:
    q0, poses = scenario('ur5e')
    path = planner('ur5e').plan_through(poses, start_joints=q0, blend_radius=0.0)
    assert type(path) is PiecewiseGeodesicPath
    plain = planner('ur5e').plan_through(poses, start_joints=q0)
    s = np.linspace(0.0, 1.0, 501)
    assert_allclose(path.evaluate(s)[0], plain.evaluate(s)[0], atol=0)
    traj = path.timed()
    assert_allclose(traj.rests, path.breakpoints, atol=1e-12)
    assert len(traj.rests) == len(poses)
    # at rest at every via point, which the tool reaches exactly
    _, dq, _ = traj.at_time(np.asarray(traj.rest_times))
    assert np.abs(dq).max() <= 1e-12
    T = fk(path.robot, path.evaluate(np.asarray(traj.rests), 0)[0])
    for T_k, P_k in zip(T, poses):
        assert np.linalg.norm(T_k[:3, 3] - P_k[:3, 3]) <= 1e-9
    # per-via zero radii too
    again = planner('ur5e').plan_through(poses, start_joints=q0, blend_radius=[0.0] * (len(poses) - 2))
    assert type(again) is PiecewiseGeodesicPath


def test_per_via_radii_and_a_zero_among_them() -> None:
    """One radius per via point; a 0 keeps that corner (the motion rests there only)."""
    q0, poses = scenario('ur5e')
    radii = np.array([0.02, 0.0, 0.04])
    path = planner('ur5e').plan_through(poses, start_joints=q0, blend_radius=radii)
    assert isinstance(path, BlendedPath)
    assert [z.via for z in path.zones] == [1, 3]
    for z in path.zones:
        assert z.radius == radii[z.via - 1]
        s = np.linspace(z.s_start, z.s_end, ZONE_SAMPLES)
        p = fk(path.robot, path.evaluate(s, 0)[0])[:, :3, 3]
        assert np.linalg.norm(p - poses[z.via][:3, 3], axis=1).max() <= z.radius * (1.0 + 1e-9)
    traj = path.timed()
    assert len(traj.rests) == 3
    s_rest = traj.rests[1]
    T = fk(path.robot, path.evaluate(np.array([s_rest]), 0)[0])[0]
    assert np.linalg.norm(T[:3, 3] - poses[2][:3, 3]) <= 1e-9


@pytest.mark.parametrize('radius, match', [
    (-0.01, r'blend_radius: must be finite and >= 0'),
    (float('nan'), r'blend_radius: must be finite and >= 0'),
    (float('inf'), r'blend_radius: must be finite and >= 0'),
    (-float('inf'), r'blend_radius: must be finite and >= 0'),
    ([0.01, -0.01, 0.01], r'blend_radius: must be finite and >= 0.*-0\.01'),
    ([0.01, float('nan'), 0.01], r'blend_radius: must be finite and >= 0.*nan'),
    ([0.01, 0.01], r'blend_radius: expected one value or one per via point \(3\)'),
    ([0.01] * 4, r'blend_radius: expected one value or one per via point \(3\)'),
    ([[0.01, 0.01, 0.01]], r'blend_radius: expected one value or one per via point \(3\)'),
    ('wide', r'blend_radius: expected metres'),
])
def test_bad_radius_is_a_request_error(radius: Any, match: str) -> None:
    q0, poses = scenario('ur5e')
    with pytest.raises(RequestError, match=match):
        planner('ur5e').plan_through(poses, start_joints=q0, blend_radius=radius)


def test_radius_larger_than_segments_is_capped() -> None:
    """r = 10 m: every zone is at most half of each neighbouring piece; zones do not overlap."""
    q0, poses = scenario('ur5e')
    path = planner('ur5e').plan_through(poses, start_joints=q0, blend_radius=10.0)
    assert isinstance(path, BlendedPath)
    assert len(path.zones) == len(poses) - 2
    ends = junction_poses(path)
    for z in path.zones:
        k = z.via
        (T_a, T_b) = fk(path.robot, path.evaluate(np.array([z.s_start, z.s_end]), 0)[0])
        # fraction of the segment into the via point / out of it (pieces are line + slerp)
        d_in, d_out = ends[k][:3, 3] - ends[k - 1][:3, 3], ends[k + 1][:3, 3] - ends[k][:3, 3]
        f_in = (T_a[:3, 3] - ends[k - 1][:3, 3]) @ d_in / (d_in @ d_in)
        f_out = (T_b[:3, 3] - ends[k][:3, 3]) @ d_out / (d_out @ d_out)
        assert f_in >= 0.5 - 1e-9 and f_out <= 0.5 + 1e-9
        assert min(f_in - 0.5, 0.5 - f_out) <= 1e-9        # the cap binds on one side
        assert z.max_distance <= z.radius
    starts = [z.s_start for z in path.zones]
    stops = [z.s_end for z in path.zones]
    assert all(stops[j] <= starts[j + 1] + 1e-15 for j in range(len(starts) - 1))
    check_zones(path, poses, np.full(len(poses) - 2, 10.0))
    check_continuity(path)
    check_exact_portions(path)
    check_timed(path, path.timed())


def test_identical_consecutive_pose_still_blends() -> None:
    q0, poses = scenario('ur5e')
    doubled = poses[:2] + [poses[1].copy()] + poses[2:]
    path = planner('ur5e').plan_through(doubled, start_joints=q0, blend_radius=0.03)
    assert isinstance(path, BlendedPath)
    assert len(path.stopping_path.pieces) == len(poses) - 1        # the empty piece dropped
    assert len(path.zones) == len(poses) - 2
    check_zones(path, doubled, np.full(len(doubled) - 2, 0.03))
    check_continuity(path)
    check_exact_portions(path)
    check_timed(path, path.timed())
    # the same motion as without the repeated pose
    ref, _ = blended('ur5e')
    s = np.linspace(0.0, 1.0, 501)
    assert_allclose(path.evaluate(s, 0)[0], ref.evaluate(s, 0)[0], atol=1e-9)


def test_two_poses_no_via_point() -> None:
    """Start and goal only: nothing to blend, the plain path (radius checked against 0 via points)."""
    q0, poses = scenario('ur5e')
    path = planner('ur5e').plan_through(poses[:2], start_joints=q0, blend_radius=[])
    assert type(path) is PiecewiseGeodesicPath
    with pytest.raises(RequestError, match=r'one per via point \(0\)'):
        planner('ur5e').plan_through(poses[:2], start_joints=q0, blend_radius=[0.01])


# The default law slows down locally around a blend (timing.smoothing, local slow-down and the
# kernel narrowed per speed valley); before that it stretched the whole motion and the blended
# trajectory was longer (2.68 s) than the one that stops at every via point (2.20 s).
def test_blended_faster_than_stopping_at_default_limits() -> None:
    path, _ = blended('ur5e')
    assert len(path.zones) == 3
    blend_t, stop_t = path.timed(), path.stopping_path.timed()
    assert blend_t.duration < stop_t.duration, (blend_t.duration, stop_t.duration)


def test_blended_faster_time_optimal_bound() -> None:
    """What the blend makes possible: the v/a time-optimal duration along the blended path is below
    the stopping path's (the corner's rest is gone and the path is shorter)."""
    path, _ = blended('ur5e')
    assert path.length < path.stopping_path.length
    assert path.timed().topp_duration < path.stopping_path.timed().topp_duration


# Found by test_random_via_sequences[rrpp] with radii down to 2 mm: a zone 1e-3 of s wide (r = 2 mm)
# has a large q'' and the default smoothing law's samples missed its peak: |a| reached 1.00068 x
# the joint-1 limit at s = 0.737 (the law's own check said 0.999). Fixed by giving the time laws
# breakpoints inside every zone (blend.ZONE_NODES), so a short zone is sampled like a piece.
def test_tiny_zone_acceleration_limit() -> None:
    robot = planner('rrpp').robot
    qs = np.array([[-0.75086292, -0.17646485, -0.28639253, -0.668],
                   [-0.7508629246267766, -0.32581688006283116, -0.3669171094146181, -0.5584437243769956],
                   [-0.7508669261225229, -0.7189450450880717, -0.3275013617266087, -0.49456950392221505],
                   [-1.109147797562573, -1.0879152960026546, -0.3246751906746258, -0.4945695055277601],
                   [-0.9091477966863692, -0.8650621647070751, -0.3060614149005613, -0.6010695138110586]])
    path = planner('rrpp').plan_through(list(robot.fk(qs)), start_joints=qs[0],
                                        blend_radius=[0.10224075500243576, 0.28946781090878015, 0.002])
    assert isinstance(path, BlendedPath) and len(path.zones) == 3
    check_timed(path, path.timed())


# ------------------------------------------------------------------------------ random via sequences
@st.composite
def via_sequences(draw: Any, name: str) -> tuple[np.ndarray, list[np.ndarray], Any]:
    """Start joints in the middle of the limits, 2-4 further configurations a random joint step
    apart (one joint at least half a step) (their tool poses are the via poses), and one radius or one per via point."""
    robot = planner(name).robot
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    step = np.where(robot._revolute_mask[:, 0] > 0, 0.4, 0.15)
    dof = robot.dof
    f = np.array(draw(st.lists(st.floats(0.3, 0.7), min_size=dof, max_size=dof)))
    qs = [lo + f * (hi - lo)]
    for _ in range(draw(st.integers(3, 5)) - 1):
        d = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=dof, max_size=dof)))
        d[draw(st.integers(0, dof - 1))] = draw(st.sampled_from([-1.0, 1.0])) * draw(st.floats(0.5, 1.0))
        qs.append(np.clip(qs[-1] + step * d, lo, hi))
    vias = len(qs) - 2
    # Radii from 2 mm: such a zone can be ~1e-3 of s wide (see test_tiny_zone_acceleration_limit).
    radius = st.floats(0.002, 0.3)
    r = draw(st.one_of(radius, st.lists(radius, min_size=vias, max_size=vias)))
    return qs[0], list(robot.fk(np.array(qs))), r


@pytest.mark.parametrize('name', ROBOTS)
def test_random_via_sequences(name: str) -> None:
    @HYPOTHESIS
    @given(via_sequences(name))
    def run(case: tuple[np.ndarray, list[np.ndarray], Any]) -> None:
        q0, poses, r = case
        try:
            path = planner(name).plan_through(poses, start_joints=q0, blend_radius=r)
        except GeodesicPlannerError:
            assume(False)
            raise  # not reached
        assume(len(path.stopping_path.pieces) == len(poses) - 1)    # no piece that does not move
        assert isinstance(path, BlendedPath)
        radii = np.broadcast_to(np.asarray(r, dtype=float), (len(poses) - 2,))
        check_zones(path, poses, radii)
        check_continuity(path)
        check_exact_portions(path)
        if name in ('ur5e', 'planar_3r'):
            check_line_slerp(path, poses)
        check_timed(path, path.timed())

    run()
