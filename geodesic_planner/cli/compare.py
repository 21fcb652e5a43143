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
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import GeodesicPlannerError, RequestError

if TYPE_CHECKING:
    from ..core.kinematics import Chain
    from ..core.path import JointPath
    from ..io.requests import PlanRequest

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
    rate = np.maximum.reduce([np.ones(s.size), np.abs(dq).max(axis=1), np.sqrt(np.abs(ddq).max(axis=1)),
                              np.cbrt(np.abs(dddq).max(axis=1))])
    delta = 0.05 / rate                                                   # (M,)
    h = delta[:, None] * _OFFSETS[None, :]                                # (M, 9)
    qj = (q[:, None] + h[..., None] * dq[:, None] + (h**2 / 2.0)[..., None] * ddq[:, None]
          + (h**3 / 6.0)[..., None] * dddq[:, None])                      # (M, 9, dof)
    T = np.asarray(robot.fk(qj))                                          # (M, 9, 4, 4)
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
    return {'s': s, 'q': q, 'dq': dq, 'ddq': ddq, 'dddq': dddq,
            'p': p[0], 'dp': p[1], 'ddp': p[2], 'dddp': p[3],
            'R': R[0], 'dR': R[1], 'ddR': R[2], 'dddR': R[3],
            'w': w, 'dw': dw, 'ddw': ddw}


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


def compare_request(request: PlanRequest, samples: int = 1001,
                    n_via: int = 11) -> tuple[dict[str, Any], dict[str, Any]]:
    """Plan a parsed request with both methods.

    Args:
        request: :class:`geodesic_planner.io.requests.PlanRequest`.
        samples: number of s samples in [0, 1].
        n_via: via points of the polynomial method (paper: 11).
    Returns:
        (JSON-ready summary dict, {'geodesic': profile, 'polynomial': profile, ...} for plotting).
    Raises:
        GeodesicPlannerError: planning, IK or request errors.
    """
    from ..core.baselines import polynomial_path
    if getattr(request, 'via', None):
        raise RequestError('geodesic-compare compares single straight-line moves; remove "via"')
    robot = request.robot
    path = request.plan()
    q_a, q_b = np.asarray(path.q_start), np.asarray(path.q_goal)
    T_a, T_b = robot.fk(q_a), robot.fk(q_b)
    poly = polynomial_path(robot, T_a, T_b, q_a, n_via=n_via, q_goal=q_b)
    s = np.linspace(0.0, 1.0, int(samples))
    profiles = {'geodesic': ee_profile(robot, path, s), 'polynomial': ee_profile(robot, poly, s)}
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
    for name, p, extra in (('geodesic', path, {'solver': path.solver.as_dict() if hasattr(path, 'solver') else {},
                                                'metric_length': float(getattr(path, 'length', float('nan')))}),
                           ('polynomial', poly, {'n_via': int(n_via), 'end_velocity': poly.end_velocity})):
        block = summarize(profiles[name])
        block['line'] = line_errors(profiles[name], T_a, T_b)
        block['timing_at_robot_limits'] = _timing(p)
        block.update(extra)
        result[name] = block
    return result, profiles


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
    parser.add_argument('--samples', type=int, default=1001, help='samples of s in [0, 1] (default 1001)')
    parser.add_argument('--n-via', type=int, default=11, help='via points of the polynomial method (default 11)')
    parser.add_argument('--no-plots', action='store_true', help='write only comparison.json')
    try:
        args = parser.parse_args(argv)
    except _ArgError as err:
        print(f'ERROR: {err}', file=sys.stderr)
        return 1
    if args.samples < 2:
        print('ERROR: --samples must be at least 2', file=sys.stderr)
        return 1
    try:
        from ..io.requests import load_request
        req = load_request(args.request)
        result, profiles = compare_request(req, args.samples, args.n_via)
        os.makedirs(args.output, exist_ok=True)
        figures: list[str] = []
        if not args.no_plots:
            from ..io.plotting import plot_comparison
            figures = plot_comparison(profiles, args.output, title=f'{req.robot.name}: geodesic vs polynomial')
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
    return 0


if __name__ == '__main__':
    sys.exit(main())
