"""IK branches of a start pose, and the first collision-free one.

A pose has several joint solutions: a 6-joint arm's branches (shoulder left or right, elbow up or
down, wrist flipped or not), a 7-joint arm's self-motion. The planner takes one by default (the
IK seeded from the current joint state or the home pose). Where that plan collides and the start
was given as a pose, :func:`first_clear` plans from the other branches and keeps the first whose
motion is free. An explicit start state (start joints, the current state) is never changed.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .cancel import checkpoint
from .collision import CollisionModel, MotionClearance
from .errors import CollisionError, GeodesicPlannerError
from .ik import nearest_turn

if TYPE_CHECKING:
    from .planner import GeodesicPlanner

#: Most branches tried (the default included).
MAX_BRANCHES = 8
#: Seeds tried when looking for branches (fixed: the same request finds the same branches).
BRANCH_SEEDS = 24
#: Two solutions closer than this (every joint, rad or m, after 2π turns) are one branch.
SAME_BRANCH = 1e-3


def start_branches(planner: GeodesicPlanner, T_start: np.ndarray, default: np.ndarray,
                   tolerance: float | None = None) -> list[np.ndarray]:
    """Distinct exact IK solutions of ``T_start`` other than ``default``, nearest first.

    Args:
        planner: the planner (its robot, metric weights and IK tolerance).
        T_start: 4x4 base->tool pose.
        default: the default solution (dof,), rad or m.
        tolerance: as in :meth:`GeodesicPlanner.plan`.
    Returns:
        up to ``MAX_BRANCHES - 1`` joint vectors (dof,).
    """
    robot = planner.robot
    rng = np.random.default_rng(0)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    seeds: list[np.ndarray] = []
    if robot.closed_form_ik is not None:
        cand = robot.closed_form_ik(np.asarray(T_start, dtype=float)[None])[:, 0]
        seeds.extend(c for c in cand if np.all(np.isfinite(c)))
    seeds.extend(rng.uniform(lo, hi, size=(BRANCH_SEEDS, robot.dof)))
    found: list[np.ndarray] = [np.asarray(default, dtype=float)]
    for seed in seeds:
        checkpoint()
        sol = planner._ik(T_start, seed, tolerance, restarts=0, raise_on_failure=False)
        if not sol.success or not robot.within_limits(sol.q):
            continue
        q = nearest_turn(robot, sol.q, default)
        if not robot.within_limits(q):
            q = sol.q
        if all(np.abs(q - f).max() > SAME_BRANCH for f in found):
            found.append(q)
        if len(found) >= MAX_BRANCHES:
            break
    others = found[1:]
    others.sort(key=lambda q: float(np.abs(q - found[0]).sum()))
    return others


def first_clear(attempt: Callable[[np.ndarray | None], tuple[Any, Any]], model: CollisionModel,
                branches: Callable[[Any], list[np.ndarray]] | None = None, refine: bool = True
                ) -> tuple[Any, Any, MotionClearance, str]:
    """Plan and time with the default start, check the motion, and try other start branches on a
    collision.

    Args:
        attempt: start joints (None: the request's own start) -> (path, trajectory); the
            trajectory has ``duration``, ``max_velocity`` and ``s_of_t``, its ``path`` evaluates q(s).
        model: the collision model.
        branches: the first path -> other start joints to try (None: the start is fixed).
        refine: as :meth:`CollisionModel.check_motion`'s.
    Returns:
        (path, trajectory, clearance, branch): branch is ``'default'``, or ``'k of n'`` (k >= 2)
        for the k-th of n branches tried.
    Raises:
        CollisionError: every branch collides (the default's error, the count tried added).
        GeodesicPlannerError: the default branch fails otherwise.
    """
    path, trajectory = attempt(None)
    try:
        return path, trajectory, check_trajectory(model, trajectory, refine), 'default'
    except CollisionError as err:
        if branches is None:
            raise
        first = err
    others = branches(path)
    reasons: list[str] = []
    for k, q in enumerate(others, start=2):
        try:
            path, trajectory = attempt(q)
            return path, trajectory, check_trajectory(model, trajectory, refine), f'{k} of {len(others) + 1}'
        except GeodesicPlannerError as err:
            reasons.append(f'branch {k}: {err}')
    shown = '; '.join(r[:200] for r in reasons[:3])
    first.args = (f'{first.args[0]}; no other IK branch of the start pose is free '
                  f'({len(others)} more tried{": " + shown if shown else ""})',)
    raise first


def check_trajectory(model: CollisionModel, trajectory: Any, refine: bool = True  # noqa: ANN401
                     ) -> MotionClearance:
    """:meth:`CollisionModel.check_path` of a timed trajectory's path (``refine``: as there), the
    places also given as the trajectory's times: the answer is the path's, whatever its time law."""
    return model.check_path(trajectory.path, refine, s_of_t=lambda t: trajectory.s_of_t(t)[0],
                            duration=float(trajectory.duration))
