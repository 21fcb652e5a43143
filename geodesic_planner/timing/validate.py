"""TEMPORARY stand-in for the trajectory validator another branch adds (dropped at merge).

Only the signature and the rules the bag reader relies on: names, points, row sizes, finite
values, strictly increasing times, optionally zero final velocity.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ['trajectory_problems']


def trajectory_problems(
    joint_names: Sequence[str],
    times: Sequence[float],
    positions: Sequence[Sequence[float]],
    velocities: Sequence[Sequence[float]] | None = None,
    accelerations: Sequence[Sequence[float]] | None = None,
    *,
    require_rest_at_end: bool = True,
) -> list[str]:
    """Why joint_trajectory_controller would reject this trajectory (empty list: valid).

    Args:
        joint_names: dof names.
        times: time_from_start per point, s.
        positions: per-point rows (may be ragged), rad or m.
        velocities: per-point rows, each empty or dof long; None when absent.
        accelerations: as velocities.
        require_rest_at_end: the last point's velocities must be zero.
    """
    names = list(joint_names)
    dof = len(names)
    problems: list[str] = []
    if dof == 0:
        problems.append('empty joint_names')
    if len(set(names)) != dof:
        problems.append('duplicate joint names')
    if len(times) == 0:
        problems.append('no points')
    for field, rows, optional in (('positions', positions, False), ('velocities', velocities, True),
                                  ('accelerations', accelerations, True)):
        if rows is None:
            continue
        nonfinite = None
        for i, row in enumerate(rows):
            n = len(row)
            if n != dof and not (optional and n == 0):
                problems.append(f'point {i}: {n} {field} for {dof} joints')
            elif nonfinite is None and not all(math.isfinite(float(x)) for x in row):
                nonfinite = i
        if nonfinite is not None:
            problems.append(f'point {nonfinite}: non-finite {field}')
    for i in range(1, len(times)):
        if not float(times[i]) > float(times[i - 1]):
            problems.append(f'point {i}: time_from_start {float(times[i]):.9f} s not after {float(times[i - 1]):.9f} s')
            break
    if require_rest_at_end and velocities is not None and len(velocities) and len(velocities[-1]):
        if any(float(v) != 0.0 for v in velocities[-1]):
            problems.append(f'point {len(velocities) - 1}: final velocities not zero')
    return problems
