"""``geodesic-compare REQUEST.yaml --output DIR [--samples N]``: geodesic vs the paper's polynomial method.

Plans the request (same YAML as ``geodesic-plan``) with the geodesic planner and with the paper's
cubic-polynomial baseline (:func:`geodesic_planner.core.baselines.polynomial_path`, 11 via points on
the line between the same two joint configurations), then writes ``DIR/comparison.json`` and PNG
figures in the style of the paper's Fig. 5/6 (planar arms) or Fig. 8-10 (spatial arms).

All derivatives are w.r.t. the path parameter s over s in [0, 1] (the paper's convention):

* joints: each method's own analytic derivatives from ``evaluate(s)`` (q', q'', q''').
* end effector: the k-th derivative of ``fk(q(s))`` depends only on q', ..., q^(k) at s, so it is
  computed from the method's own joint derivatives: ``phi(h) = fk(q + h q' + h^2/2 q'' + h^3/6 q''')``
  is evaluated at 13 points ``h = j * delta`` (j = -6..6) and differentiated with a 13-point
  central finite-difference stencil (error O(delta^10); ``delta = 0.05 / r`` with r the largest of
  |q'|, |q''|^(1/2), |q'''|^(1/3) and 1, so the stencil spans a small fraction of the joint motion). This
  high-order numerical differentiation lives in this comparison code ONLY; the planner never uses it.
  The polynomial's one-sided derivatives at a knot are those of the segment on its right.
* ``ee_position``: Euclidean norm of p', p'', p''' (m per unit s^k).
* ``ee_orientation``: norm of the angular velocity w (base frame, ``R' = [w] R``) and of its s-derivatives
  w', w'' (rad per unit s^k) — "orientation jerk" = |w''|. Zero for an exact line + slerp.
* ``ee_orientation_matrix``: Frobenius norm of R', R'', R''' (= the paper's (n, o, a) measure; its
  Fig. 5(d) shows |R'|_F = sqrt(2) |dphi| for the 3R). For a constant-rate rotation |R'''|_F =
  sqrt(2) |w|^3 is not zero.

In time (the ``timed`` block of each method, and the ``timed_*.png`` figures): every method —
geodesic, cubic polynomial, and Cartesian line + IK at every sample as MoveIt's Pilz LIN does
(:func:`geodesic_planner.core.baselines.cartesian_ik_path`) — is timed with its own ``.timed()``
under the same joint limits (the robot's, or ``--max-velocity`` / ``--max-acceleration``):

* joints: ``dq/dt``, ``d2q/dt2`` from ``Trajectory.at_time`` and ``d3q/dt3`` from
  ``Trajectory.jerk_at_time`` (exact chain rule of the path's s-derivatives and s(t)), rad/s^k.
* tool: the same 13-point jet stencil as above, applied to the *time* jet (q, dq/dt, d2q/dt2,
  d3q/dt3) at each time sample, gives dp/dt, d2p/dt2, d3p/dt3 (m/s^k) analytically up to the
  stencil's round-off (no finite differences in time).
* peaks are maxima over ``--time-samples`` uniform times (default 4001, both ends included); the
  step is reported (``time_step_s``), and so is the relative change of each peak when the grid
  is halved (``peak_change_vs_half_grid``): a peak between samples, e.g. at a jump of the jerk,
  can be missed by at most that much as far as the grid can tell.
* ``at_common_duration``: every method stretched uniformly to the slowest one's duration, so
  that jerks compare paths at the same pace.
* deviation from the line: distance of the tool to the chord A-B (m) over the s samples (timing
  does not move the tool off the path); the Cartesian path also gives it at its IK samples.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..core.chunks import in_chunks
from ..core.errors import GeodesicPlannerError, RequestError
from ..core.request import MAX_VIA_POSES
from ..timing.resample import MAX_POINTS

if TYPE_CHECKING:
    from ..core.kinematics import Chain
    from ..core.path import JointPath
    from ..core.request import PlanRequest
    from ..timing.trajectory import Trajectory

#: Most IK samples of the Cartesian line + IK method (each is an IK solve and a knot of the timed
#: path: about 5 ms each on the 2-core machine, so 1000 add about 5 s).
MAX_CARTESIAN_SAMPLES = 1000

#: 13-point central stencil offsets used for end-effector derivatives.
_OFFSETS = np.arange(-6, 7, dtype=float)
_CENTER = 6


def _stencil_weights() -> np.ndarray:
    """Weights w[m, j] with sum_j w[m, j] f(j delta) = f^(m)(0) delta^m + O(delta^(m + 10)), m = 0..3."""
    k = np.arange(_OFFSETS.size)
    V = _OFFSETS[None, :] ** k[:, None] / np.array([math.factorial(int(i)) for i in k])[:, None]
    W = np.linalg.solve(V, np.eye(_OFFSETS.size)[:, :4]).T
    return W


_W = _stencil_weights()


def _vee(S: np.ndarray) -> np.ndarray:
    A = 0.5 * (S - np.swapaxes(S, -1, -2))
    return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1)


def ee_profile(robot: Chain, path: JointPath, s: np.ndarray) -> dict[str, np.ndarray]:
    """Joint and end-effector positions and s-derivatives (up to third) along a path.

    Args:
        robot: chain with ``fk`` ((..., dof) -> (..., 4, 4)).
        path: object with ``evaluate(s) -> (q, q', q'', q''')``.
        s: path parameters (M,) in [0, 1].
    Returns:
        dict with ``s`` (M,), ``q``, ``dq``, ``ddq``, ``dddq`` (M, dof); ``p``, ``dp``, ``ddp``, ``dddp``
        (M, 3) in m per unit s^k; ``R``, ``dR``, ``ddR``, ``dddR`` (M, 3, 3); ``w``, ``dw``, ``ddw``
        (M, 3) angular velocity (base frame) and its derivatives, rad per unit s^k.
    """
    s = np.asarray(s, dtype=float)
    q, dq, ddq, dddq = (np.asarray(a, dtype=float) for a in path.evaluate(s))
    p, dp, ddp, dddp, R, dR, ddR, dddR, w, dw, ddw = in_chunks(
        lambda *jet: _tool_jet(robot, *jet), q, dq, ddq, dddq)
    return {'s': s, 'q': q, 'dq': dq, 'ddq': ddq, 'dddq': dddq,
            'p': p, 'dp': dp, 'ddp': ddp, 'dddp': dddp,
            'R': R, 'dR': dR, 'ddR': ddR, 'dddR': dddR,
            'w': w, 'dw': dw, 'ddw': ddw}


def _tool_jet(robot: Chain, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, dddq: np.ndarray
              ) -> tuple[np.ndarray, ...]:
    """The tool's position, rotation and angular velocity and their derivatives at rows of a joint
    jet (:func:`ee_profile`; its memory grows with the rows: called on blocks of rows)."""
    rate = np.maximum.reduce([np.ones(q.shape[0]), np.abs(dq).max(axis=1), np.sqrt(np.abs(ddq).max(axis=1)),
                              np.cbrt(np.abs(dddq).max(axis=1))])
    delta = 0.05 / rate                                                   # (M,)
    h = delta[:, None] * _OFFSETS[None, :]                                # (M, 13)
    qj = (q[:, None] + h[..., None] * dq[:, None] + (h**2 / 2.0)[..., None] * ddq[:, None]
          + (h**3 / 6.0)[..., None] * dddq[:, None])                      # (M, 13, dof)
    T = np.asarray(robot.fk(qj))                                          # (M, 13, 4, 4)
    D = np.einsum('mj,njab->mnab', _W, T)                                 # (4, M, 4, 4)
    scale = delta[None, :, None, None] ** np.arange(4)[:, None, None, None]
    D = D / scale
    D[0] = T[:, _CENTER]                                                  # exact value at h = 0
    p = D[:, :, :3, 3]
    R = D[:, :, :3, :3]
    Rt = np.swapaxes(R[0], -1, -2)
    w = _vee(R[1] @ Rt)
    dw = _vee(R[2] @ Rt + R[1] @ np.swapaxes(R[1], -1, -2))
    ddw = _vee(R[3] @ Rt + 2.0 * R[2] @ np.swapaxes(R[1], -1, -2) + R[1] @ np.swapaxes(R[2], -1, -2))
    return p[0], p[1], p[2], p[3], R[0], R[1], R[2], R[3], w, dw, ddw


def summarize(profile: dict[str, np.ndarray]) -> dict[str, Any]:
    """Max-abs velocity / acceleration / jerk (w.r.t. s) of joints and end effector."""
    out: dict[str, Any] = {}
    for key, (jq, jp, jw, jR) in {
            'max_abs_velocity': ('dq', 'dp', 'w', 'dR'),
            'max_abs_acceleration': ('ddq', 'ddp', 'dw', 'ddR'),
            'max_abs_jerk': ('dddq', 'dddp', 'ddw', 'dddR')}.items():
        out[key] = {
            'joints': np.abs(profile[jq]).max(axis=0).tolist(),
            'ee_position': float(np.linalg.norm(profile[jp], axis=-1).max()),
            'ee_orientation': float(np.linalg.norm(profile[jw], axis=-1).max()),
            'ee_orientation_matrix': float(np.linalg.norm(profile[jR], axis=(-2, -1)).max()),
        }
    return out


def line_errors(profile: dict[str, np.ndarray], T_a: np.ndarray, T_b: np.ndarray) -> dict[str, float]:
    """How far the tool path is from the straight line A->B (and from line + slerp at the same s)."""
    from ..core.transforms import line_slerp, pose_error, segment_distance
    p = profile['p']
    dist = segment_distance(p, T_a[:3, 3], T_b[:3, 3])
    ref = line_slerp(T_a, T_b, profile['s'])
    T = np.zeros((p.shape[0], 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = profile['R'], p, 1.0
    dp, dr = pose_error(T, ref)
    return {'max_distance_to_line_m': float(dist.max()),
            'max_position_error_vs_line_slerp_m': float(dp.max()),
            'max_orientation_error_vs_line_slerp_rad': float(dr.max())}


def _timing(path: JointPath) -> dict[str, float]:
    traj = path.timed()
    return {'duration_s': traj.duration, 'topp_duration_s': traj.topp_duration,
            'optimality_ratio': traj.optimality_ratio}


class _TimeJet:
    """A timed trajectory seen as a "path" over t: ``evaluate(t) -> (q, dq/dt, d2q/dt2, d3q/dt3)``."""

    def __init__(self, traj: Trajectory) -> None:
        self.traj = traj

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        q, dq, ddq = self.traj.at_time(t)
        return q, dq, ddq, self.traj.jerk_at_time(t)


def timed_profile(robot: Chain, traj: Trajectory, samples: int = 4001) -> dict[str, np.ndarray]:
    """Joint and tool motion in time along a timed trajectory, at ``samples`` uniform times.

    Args:
        robot: the chain (``fk``).
        traj: a :class:`geodesic_planner.timing.trajectory.Trajectory`.
        samples: number of uniform times in [0, duration], both ends included (>= 2).
    Returns:
        dict with ``t`` (M,) s; ``q``, ``dq``, ``ddq``, ``dddq`` (M, dof) in rad (m) per s^k;
        ``p``, ``dp``, ``ddp``, ``dddp`` (M, 3) tool position (base frame) and its time
        derivatives, m/s^k (same jet stencil as :func:`ee_profile`, on the time jet).
    """
    t = np.linspace(0.0, float(traj.duration), max(int(samples), 2))
    prof = ee_profile(robot, _TimeJet(traj), t)  # type: ignore[arg-type]
    prof['t'] = prof.pop('s')
    return prof


def _timed_peaks(prof: dict[str, np.ndarray]) -> dict[str, Any]:
    return {'joint_velocity': np.abs(prof['dq']).max(axis=0).tolist(),
            'joint_acceleration': np.abs(prof['ddq']).max(axis=0).tolist(),
            'joint_jerk': np.abs(prof['dddq']).max(axis=0).tolist(),
            'tool_speed': float(np.linalg.norm(prof['dp'], axis=-1).max()),
            'tool_acceleration': float(np.linalg.norm(prof['ddp'], axis=-1).max()),
            'tool_jerk': float(np.linalg.norm(prof['dddp'], axis=-1).max())}


def timed_block(robot: Chain, traj: Trajectory, samples: int = 4001
                ) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The ``timed`` block of one method (JSON-ready) and its time profile (for the figures).

    Peaks are maxima over ``samples`` uniform times; ``peak_change_vs_half_grid`` is the relative
    change of each peak when every other sample is dropped (how much the grid resolves it).
    """
    prof = timed_profile(robot, traj, samples)
    peaks = _timed_peaks(prof)
    half = _timed_peaks({k: v[::2] for k, v in prof.items()})

    def change(full: float | list[float], coarse: float | list[float]) -> float:
        a, b = np.atleast_1d(full), np.atleast_1d(coarse)
        return float(np.max(np.abs(a - b) / np.maximum(np.abs(a), 1e-300)))

    block: dict[str, Any] = {
        'duration_s': float(traj.duration),
        'topp_duration_s': float(traj.topp_duration),
        'max_velocity': np.asarray(traj.max_velocity, dtype=float).tolist(),
        'max_acceleration': np.asarray(traj.max_acceleration, dtype=float).tolist(),
        'time_samples': int(prof['t'].size),
        'time_step_s': float(prof['t'][1] - prof['t'][0]) if prof['t'].size > 1 else 0.0,
        'peak_joint_jerk': float(np.max(peaks['joint_jerk'])),
        'peak_tool_jerk': peaks['tool_jerk'],
        'peaks': peaks,
        'peak_change_vs_half_grid': {'joint_jerk': change(peaks['joint_jerk'], half['joint_jerk']),
                                     'tool_jerk': change(peaks['tool_jerk'], half['tool_jerk'])},
        'limit_ratios': {
            'velocity': float(np.max(np.abs(prof['dq']) / np.asarray(traj.max_velocity))),
            'acceleration': float(np.max(np.abs(prof['ddq']) / np.asarray(traj.max_acceleration)))},
    }
    return block, prof


def compare_request(request: PlanRequest, samples: int = 1001, n_via: int = 11, *,
                    max_velocity: npt.ArrayLike | None = None,
                    max_acceleration: npt.ArrayLike | None = None,
                    cartesian_samples: int = 100, time_samples: int = 4001) -> Comparison:
    """Plan a parsed request with the geodesic, the paper's polynomial and Cartesian line + IK.

    Args:
        request: :class:`geodesic_planner.io.requests.PlanRequest`.
        samples: number of s samples in [0, 1].
        n_via: via points of the polynomial method (paper: 11).
        max_velocity, max_acceleration: joint limits of the timing of every method, (dof,) or
            scalar, rad/s (m/s) and rad/s^2 (m/s^2); None: the robot's.
        cartesian_samples: IK samples of the Cartesian line + IK path (Pilz LIN style).
        time_samples: uniform time samples of each timed trajectory (peaks in time).
    Returns:
        :class:`Comparison` (JSON-ready ``result``, s ``profiles`` of the geodesic and the
        polynomial for the paper's figures, time ``timed_profiles`` and ``trajectories`` of all
        three methods).
    Raises:
        GeodesicPlannerError: planning, IK, limit or request errors.
    """
    from ..core.baselines import cartesian_ik_path, polynomial_path
    from ..core.transforms import segment_distance
    if getattr(request, 'via', None):
        raise RequestError('geodesic-compare compares single straight-line moves; remove "via"')
    robot = request.robot
    path = request.plan()
    q_a, q_b = np.asarray(path.q_start), np.asarray(path.q_goal)
    T_a, T_b = robot.fk(q_a), robot.fk(q_b)
    poly = polynomial_path(robot, T_a, T_b, q_a, n_via=n_via, q_goal=q_b)
    cart = cartesian_ik_path(robot, T_a, T_b, q_a, samples=cartesian_samples, q_goal=q_b)
    s = np.linspace(0.0, 1.0, int(samples))
    profiles = {'geodesic': ee_profile(robot, path, s), 'polynomial': ee_profile(robot, poly, s)}
    cart_profile = ee_profile(robot, cart, s)
    result: dict[str, Any] = {
        'robot': robot.name,
        'joint_names': list(robot.joint_names),
        'samples': int(samples),
        'q_start': q_a.tolist(),
        'q_goal': q_b.tolist(),
        'ee_start': {'position': T_a[:3, 3].tolist(), 'rotation': T_a[:3, :3].tolist()},
        'ee_goal': {'position': T_b[:3, 3].tolist(), 'rotation': T_b[:3, :3].tolist()},
        'definitions': {
            'derivatives': 'w.r.t. the path parameter s in [0, 1]',
            'joints': "each method's own analytic derivatives (evaluate(s))",
            'ee_position': '|d^k p / ds^k|, m; from the joint derivatives (13-point stencil on the jet)',
            'ee_orientation': '|w|, |dw/ds|, |d2w/ds2|; w = angular velocity (base frame), rad',
            'ee_orientation_matrix': '|d^k R / ds^k|_F = |d^k (n, o, a) / ds^k| (paper Table 3 measure)',
        },
    }
    at_samples = robot.fk(cart.q_samples)[:, :3, 3]
    cart_extra = {'ik_samples': int(cartesian_samples),
                  'max_distance_to_line_at_ik_samples_m':
                      float(segment_distance(at_samples, T_a[:3, 3], T_b[:3, 3]).max())}
    s_profiles = dict(profiles, cartesian_ik=cart_profile)
    trajectories: dict[str, Trajectory] = {}
    timed_profiles: dict[str, dict[str, np.ndarray]] = {}
    for name, p, extra in (('geodesic', path, {'solver': path.solver.as_dict() if hasattr(path, 'solver') else {},
                                                'metric_length': float(getattr(path, 'length', float('nan')))}),
                           ('polynomial', poly, {'n_via': int(n_via), 'end_velocity': poly.end_velocity}),
                           ('cartesian_ik', cart, cart_extra)):
        block = summarize(s_profiles[name])
        block['line'] = line_errors(s_profiles[name], T_a, T_b)
        block['timing_at_robot_limits'] = _timing(p)
        traj = p.timed(max_velocity, max_acceleration)
        block['timed'], timed_profiles[name] = timed_block(robot, traj, time_samples)
        block['timed']['max_distance_to_line_m'] = block['line']['max_distance_to_line_m']
        trajectories[name] = traj
        block.update(extra)
        result[name] = block
    common = max(traj.duration for traj in trajectories.values())
    for name, p in (('geodesic', path), ('polynomial', poly), ('cartesian_ik', cart)):
        same, _ = timed_block(robot, p.timed(max_velocity, max_acceleration, duration=common), time_samples)
        result[name]['timed']['at_common_duration'] = {
            k: same[k] for k in ('duration_s', 'peak_joint_jerk', 'peak_tool_jerk', 'peaks')}
    result['definitions']['timed'] = (
        'each method timed by its own .timed() under the same joint limits (max_velocity, '
        'max_acceleration); peaks over time_samples uniform times: joint jerk from '
        'Trajectory.jerk_at_time (rad/s^3 or m/s^3), tool jerk |d3p/dt3| (m/s^3) from the time jet '
        '(q, dq/dt, d2q/dt2, d3q/dt3) by the 13-point stencil; max_distance_to_line_m over the s samples; '
        'at_common_duration: every method stretched to the slowest duration (same time law)')
    return Comparison(result, profiles, timed_profiles, trajectories, s_profiles)


@dataclass
class Comparison:
    """What :func:`compare_request` computed.

    Attributes:
        result: the JSON-ready summary (``comparison.json``).
        profiles: s profiles (:func:`ee_profile`) of 'geodesic' and 'polynomial' (the paper's figures).
        timed_profiles: time profiles (:func:`timed_profile`) of every method.
        trajectories: the timed trajectory of every method.
        s_profiles: s profiles of every method (with 'cartesian_ik').
    """

    result: dict[str, Any]
    profiles: dict[str, dict[str, np.ndarray]]
    timed_profiles: dict[str, dict[str, np.ndarray]]
    trajectories: dict[str, Trajectory]
    s_profiles: dict[str, dict[str, np.ndarray]]


def _limits_arg(text: str) -> list[float] | float:
    """``'1.5'`` or ``'1,2,0.5'`` -> float or list of floats (argparse type)."""
    try:
        vals = [float(v) for v in text.split(',')]
    except ValueError as err:
        raise argparse.ArgumentTypeError(f'expected a number or comma-separated numbers, got {text!r}') from err
    return vals[0] if len(vals) == 1 else vals


class _ArgError(Exception):
    pass


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise _ArgError(message)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``geodesic-compare``; returns the exit code (0 ok, 1 error)."""
    import yaml
    parser = _Parser(prog='geodesic-compare',
                     description='Compare the geodesic with the paper\'s cubic-polynomial method '
                                 '(JSON + Fig. 5/6-style PNGs).')
    parser.add_argument('request', help='YAML request (as for geodesic-plan)')
    parser.add_argument('--output', required=True, help='output directory (created if missing)')
    parser.add_argument('--samples', type=int, default=1001,
                        help=f'samples of s in [0, 1], 2 to {MAX_POINTS} (default 1001)')
    parser.add_argument('--n-via', type=int, default=11,
                        help=f'via points of the polynomial method, 2 to {MAX_VIA_POSES} (default 11)')
    parser.add_argument('--max-velocity', type=_limits_arg, default=None,
                        help='joint velocity limit(s) for timing every method: V or V1,V2,... '
                             '(rad/s, m/s); default: the robot\'s')
    parser.add_argument('--max-acceleration', type=_limits_arg, default=None,
                        help='joint acceleration limit(s): A or A1,A2,... (rad/s^2, m/s^2); default: the robot\'s')
    parser.add_argument('--cartesian-samples', type=int, default=100,
                        help=f'IK samples of the Cartesian line + IK method, 2 to {MAX_CARTESIAN_SAMPLES} '
                             '(default 100)')
    parser.add_argument('--time-samples', type=int, default=4001,
                        help=f'uniform time samples for the peaks in time, 2 to {MAX_POINTS} (default 4001)')
    parser.add_argument('--no-plots', action='store_true', help='write only comparison.json')
    try:
        args = parser.parse_args(argv)
    except _ArgError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    for opt, most, unit in (('samples', MAX_POINTS, 'points'), ('time_samples', MAX_POINTS, 'points'),
                            ('cartesian_samples', MAX_CARTESIAN_SAMPLES, 'points'),
                            ('n_via', MAX_VIA_POSES, 'via points')):
        flag, value = f"--{opt.replace('_', '-')}", getattr(args, opt)
        if value < 2:
            print(f'ERROR: {flag} must be at least 2', file=sys.stderr)
            return 1
        if value > most:
            print(f'ERROR: {flag}: {value} {unit}, more than {most}', file=sys.stderr)
            return 1
    try:
        from ..io.requests import load_request
        req = load_request(args.request)
        cmp = compare_request(req, args.samples, args.n_via, max_velocity=args.max_velocity,
                              max_acceleration=args.max_acceleration,
                              cartesian_samples=args.cartesian_samples, time_samples=args.time_samples)
        result = cmp.result
        os.makedirs(args.output, exist_ok=True)
        figures: list[str] = []
        if not args.no_plots:
            from ..io.plotting import plot_comparison, plot_timed_comparison
            figures = plot_comparison(cmp.profiles, args.output,
                                      joint_types=getattr(req.robot, 'joint_types', None))
            figures += plot_timed_comparison(cmp.timed_profiles, args.output, joint_names=req.robot.joint_names,
                                             joint_types=getattr(req.robot, 'joint_types', None))
        result['figures'] = [os.path.basename(f) for f in figures]
        out = os.path.join(args.output, 'comparison.json')
        with open(out, 'w', encoding='utf-8') as fh:
            json.dump(result, fh, indent=1)
            fh.write('\n')
    except (GeodesicPlannerError, OSError, yaml.YAMLError) as err:
        msg = str(err).splitlines()[0] if str(err) else type(err).__name__
        print(f'ERROR: {msg}', file=sys.stderr)
        return 1
    g, p = result['geodesic']['max_abs_jerk'], result['polynomial']['max_abs_jerk']
    print(f"{result['robot']}: max |ee jerk| position geodesic {g['ee_position']:.4g} vs polynomial "
          f"{p['ee_position']:.4g}; orientation {g['ee_orientation']:.4g} vs {p['ee_orientation']:.4g} "
          f"-> {out}", file=sys.stderr)
    timed = {m: result[m]['timed'] for m in ('geodesic', 'polynomial', 'cartesian_ik')}
    print('timed: ' + '; '.join(
        f"{m} {b['duration_s']:.3f} s, peak joint jerk {b['peak_joint_jerk']:.4g}, "
        f"tool jerk {b['peak_tool_jerk']:.4g} m/s^3" for m, b in timed.items()), file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
