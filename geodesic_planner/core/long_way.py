"""The long way round: a revolute joint turned far beyond what the tool motion needs.

A revolute joint shifted by 2π leaves the tool pose unchanged, so a goal pose is reached by every
*turn* q_b,i + 2πk of each revolute joint; the planner's goal IK takes the turn nearest the start
that lies within the limits (``ik.nearest_turn``). When that turn is the far one because the near
one is outside the joint's limits, a small tool motion (a wrist at 2π − 1e-3 rad turned by
+0.5 rad) becomes a joint move of almost a full turn (−5.78 rad), which a user asking for a pose
does not expect.

Criterion (docs/maths.md#the-long-way-round): with Δ = q_b − q_a and the short way
δ = Δ − 2π round(Δ / 2π) (the travel to the goal's nearest turn, ignoring limits, |δ| <= π), a
plan to a goal *pose* goes the long way round when a revolute joint travels more than
:data:`LONG_WAY_EXCESS` beyond its short way: |Δ_i| − |δ_i| > π/2, i.e. |Δ_i| > 5π/4 (3.93 rad)
for a single extra turn. It depends on the ends only, so it is checked before the solve and
costs a few vector operations. Explicit goal joints are taken as asked (never checked).

Why not compare the tool's travelled rotation with the slerp angle: on random UR5e moves the
geodesic often turns the tool the other way round the slerp (2π − θ instead of θ, up to 2.8 rad
more) with every joint moving less than π; those are ordinary plans, and a tool-based threshold
loose enough to pass them would miss a wrist turned by 4 rad.
"""
from __future__ import annotations

import numpy as np

from .errors import LimitError
from .kinematics import Chain
from .transforms import so3_log

#: A revolute joint may travel this much more than its short way (same tool pose, limits
#: ignored) before a plan to a goal pose is refused as the long way round, rad.
LONG_WAY_EXCESS = np.pi / 2


def short_way(q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """Per joint, the travel δ to the turn of q_b nearest q_a: Δ − 2π round(Δ/2π), |δ| <= π, rad."""
    delta = q_b - q_a
    return delta - 2.0 * np.pi * np.round(delta / (2.0 * np.pi))


def long_way_excess(robot: Chain, q_a: np.ndarray, q_b: np.ndarray) -> np.ndarray:
    """Per joint, |Δ| − |δ|: how much farther each revolute joint travels from q_a to q_b than
    to the nearest turn of q_b (0 for prismatic joints), rad, shape (dof,)."""
    excess = np.abs(q_b - q_a) - np.abs(short_way(q_a, q_b))
    return np.where(robot.revolute, excess, 0.0)


def check_long_way(robot: Chain, q_a: np.ndarray, q_b: np.ndarray, what: str = 'the goal') -> None:
    """Refuse a plan from joints q_a to the IK solution q_b of a goal pose that goes the long way
    round (see the module docstring).

    Args:
        robot: the chain.
        q_a, q_b: start and goal joints, shape (dof,), rad or m.
        what: the end named in the message.
    Raises:
        LimitError: naming the joint, its travel, the tool rotation and translation the move
            needs and the limit that blocks the short way.
    """
    if np.abs(q_b - q_a).max() <= np.pi + LONG_WAY_EXCESS / 2:       # no joint beyond 5π/4: the hot path
        return
    excess = long_way_excess(robot, q_a, q_b)
    i = int(np.argmax(excess))
    if not excess[i] > LONG_WAY_EXCESS:
        return
    name = robot.joint_names[i]
    delta = float(q_b[i] - q_a[i])
    short = float(short_way(q_a[i:i + 1], q_b[i:i + 1])[0])
    target = float(q_a[i]) + short
    lo, hi = float(robot.lower[i]), float(robot.upper[i])
    T_a, T_b = robot.fk(np.stack([q_a, q_b]))
    rotation = round(float(np.linalg.norm(so3_log(T_a[:3, :3].T @ T_b[:3, :3]))), 9)
    translation = round(float(np.linalg.norm(T_b[:3, 3] - T_a[:3, 3])), 9)
    if target < lo or target > hi:
        why = (f'the short way ({short:+.4g} rad, to {target:.6g}) is blocked by the joint\'s limit '
               f'{lo if target < lo else hi:.6g} (limits [{lo:.6g}, {hi:.6g}])')
    else:
        why = f'the short way ({short:+.4g} rad, to {target:.6g}) lies within the limits [{lo:.6g}, {hi:.6g}]'
    raise LimitError(
        f'{what} is reached the long way round: joint {name!r} would travel {delta:+.4g} rad '
        f'(from {q_a[i]:.6g} to {q_b[i]:.6g}) while the tool needs a rotation of only {rotation:.4g} rad '
        f'and a translation of {translation:.4g} m; {why}. GeodesicPlanner(allow_long_way=True) '
        'plans such moves anyway')


__all__ = ['LONG_WAY_EXCESS', 'check_long_way', 'long_way_excess', 'short_way']
