"""One trajectory validator: the reasons joint_trajectory_controller (JTC) rejects a trajectory.

JTC (ros2_controllers, ``validate_trajectory_msg``) refuses a trajectory whose joint names are
empty or repeated, that has no points, whose points' positions are not one per joint, whose
velocities or accelerations are neither empty nor one per joint, whose ``time_from_start`` is
not strictly increasing, or (unless ``allow_nonzero_velocity_at_trajectory_end``) whose last
point moves. Times are compared as ROS durations, i.e. rounded to integer ns. The planner, the
processor and the bag tools all use this one list of rules.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import numpy as np
import numpy.typing as npt

from ..core.errors import TrajectoryError, quoted

#: At most this many problems are spelled out; the rest are counted.
MAX_PROBLEMS = 20


class _Problems:
    """Problems found so far: the first MAX_PROBLEMS as text, all of them counted."""

    def __init__(self) -> None:
        self.text: list[str] = []
        self.count = 0

    def add(self, message: str) -> None:
        self.count += 1
        if len(self.text) < MAX_PROBLEMS:
            self.text.append(message)

    def add_each(self, indices: np.ndarray, message: Callable[[int], str]) -> None:
        """One problem per index; only as many messages are built as can still be shown."""
        room = max(0, MAX_PROBLEMS - len(self.text))
        self.text.extend(message(int(i)) for i in indices[:room])
        self.count += int(indices.size)

    def result(self) -> list[str]:
        if self.count > len(self.text):
            return self.text + [f'... and {self.count - len(self.text)} more']
        return self.text


def _rows(values: Iterable[npt.ArrayLike], what: str, problems: _Problems) -> tuple[np.ndarray, np.ndarray] | None:
    """Row sizes (P,) and all values flattened, of a (P, dof) array or P ragged rows; None if unreadable."""
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        arr = None  # ragged rows, or not numbers
    if arr is not None and arr.ndim == 2:
        return np.full(arr.shape[0], arr.shape[1]), arr.reshape(-1)
    if arr is not None and arr.ndim == 1 and arr.size == 0:
        return np.zeros(0, dtype=int), arr
    try:
        rows = [np.asarray(row, dtype=float).reshape(-1) for row in values]
    except (TypeError, ValueError):
        problems.add(f'{what}: expected one row of numbers per point')
        return None
    sizes = np.array([row.size for row in rows], dtype=int)
    return sizes, (np.concatenate(rows) if rows else np.zeros(0))


def _check_field(values: Iterable[npt.ArrayLike], what: str, names: list[str], n_points: int, allow_empty: bool,
                 problems: _Problems) -> np.ndarray | None:
    """Sizes and finiteness of one per-point field; the last point's values when dof long."""
    parsed = _rows(values, what, problems)
    if parsed is None:
        return None
    sizes, flat = parsed
    dof = len(names)
    if sizes.size != n_points:
        problems.add(f'{what}: {sizes.size} rows for {n_points} points')
        return None
    ok = (sizes == dof) | ((sizes == 0) & allow_empty)
    expected = f'{dof} (one per joint)' + (' or 0' if allow_empty else '')
    problems.add_each(np.flatnonzero(~ok),
                      lambda i: f'point {i}: {sizes[i]} {what}, expected {expected}')
    bad = np.flatnonzero(~np.isfinite(flat))
    if bad.size:
        point = np.searchsorted(np.cumsum(sizes), bad, side='right')
        points = np.unique(point)
        problems.add_each(points, lambda i: f'point {i}: {what} contain NaN or inf')
    if n_points and sizes[-1] == dof:
        return flat[flat.size - dof:]
    return None


def trajectory_problems(joint_names: Sequence[str], times: npt.ArrayLike, positions: Iterable[npt.ArrayLike],
                        velocities: Iterable[npt.ArrayLike] | None = None,
                        accelerations: Iterable[npt.ArrayLike] | None = None, *,
                        require_rest_at_end: bool = True) -> list[str]:
    """The reasons JTC would reject a joint trajectory; empty if it would accept it.

    Args:
        joint_names: one name per joint (non-empty, distinct).
        times: ``time_from_start`` of each point, shape (N,), s.
        positions: per-point rows (ragged allowed) or an (N, dof) array; rad or m.
        velocities: None (not given), or per-point rows, each empty or dof long; rad/s or m/s.
        accelerations: None, or per-point rows, each empty or dof long; rad/s^2 or m/s^2.
        require_rest_at_end: velocities at the last point must be zero (JTC's default, unless
            ``allow_nonzero_velocity_at_trajectory_end``).
    Returns:
        Short messages naming the point index; at most MAX_PROBLEMS of them, then
        ``'... and K more'``.
    """
    problems = _Problems()
    names = [str(n) for n in joint_names]
    if not names:
        problems.add('no joint names')  # nothing to size the points against
        return problems.result()
    empty = [i for i, n in enumerate(names) if not n]
    if empty:
        problems.add(f'empty joint name at index {empty[0]}')
    unique, counts = np.unique(np.asarray([n for n in names if n], dtype=str), return_counts=True)
    if np.any(counts > 1):
        dups = unique[counts > 1].tolist()
        shown = ', '.join(quoted(d, 40) for d in dups[:10]) + (f', ... ({len(dups)})' if len(dups) > 10 else '')
        problems.add(f'duplicate joint names: [{shown}]')
    try:
        t = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        problems.add('times: not numbers')
        return problems.result()
    if t.ndim != 1:
        problems.add(f'times: expected shape (N,), got {t.shape}')
        return problems.result()
    n = t.size
    if n == 0:
        problems.add('no points')
        return problems.result()
    finite = np.isfinite(t)
    problems.add_each(np.flatnonzero(~finite), lambda i: f'point {i}: time_from_start {float(t[i])} is not finite')
    ns = np.round(np.where(finite, t, 0.0) * 1e9)
    problems.add_each(np.flatnonzero(finite & (ns < 0)),
                      lambda i: f'point {i}: time_from_start {t[i]:.9g} s is negative')
    step_ok = (np.diff(ns) > 0) | ~(finite[1:] & finite[:-1])
    problems.add_each(np.flatnonzero(~step_ok) + 1,
                      lambda i: f'point {i}: time_from_start {t[i]:.9g} s is not after point {i - 1} '
                                f'({t[i - 1]:.9g} s)')
    _check_field(positions, 'positions', names, n, False, problems)
    v_end = None
    if velocities is not None:
        v_end = _check_field(velocities, 'velocities', names, n, True, problems)
    if accelerations is not None:
        _check_field(accelerations, 'accelerations', names, n, True, problems)
    if require_rest_at_end and v_end is not None:
        moving = np.flatnonzero(v_end != 0.0)
        problems.add_each(moving, lambda j: f'point {n - 1}: final velocity of joint {quoted(names[j], 40)} is '
                                            f'{v_end[j]:.6g}, not 0')
    return problems.result()


def check_trajectory(joint_names: Sequence[str], times: npt.ArrayLike, positions: Iterable[npt.ArrayLike],
                     velocities: Iterable[npt.ArrayLike] | None = None,
                     accelerations: Iterable[npt.ArrayLike] | None = None, *,
                     require_rest_at_end: bool = True) -> None:
    """Raise if JTC would reject the trajectory (arguments as :func:`trajectory_problems`).

    Raises:
        TrajectoryError: the problems, joined by '; '.
    """
    problems = trajectory_problems(joint_names, times, positions, velocities, accelerations,
                                   require_rest_at_end=require_rest_at_end)
    if problems:
        raise TrajectoryError('trajectory would be rejected: ' + '; '.join(problems))


__all__ = ['MAX_PROBLEMS', 'check_trajectory', 'trajectory_problems']
