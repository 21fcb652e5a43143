"""The seam between paths and time laws: what a time law takes and what it returns.

A time law maps a path ``q(s)``, s in [0, 1], and per-joint limits to a :class:`Trajectory`
``q(t) = q(s(t))``. The path is only used through :class:`PathLike`, so this layer never imports
the path module; the law's ``s(t)`` is handed to the trajectory through :class:`TimeScaling`.
The rest-to-rest smoothing law (:class:`~geodesic_planner.timing.smoothing.SmoothRestToRest`) is
the first implementation; a jerk-limited or constant-speed law is another module with the same
call.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import numpy.typing as npt

from ..core.errors import LimitError
from .tool import check_tool_limit, tool_kinematics
from .types import JointLimits, PathLike, TimeScaling

if TYPE_CHECKING:
    from .trajectory import Trajectory


class TimeLaw(Protocol):
    """A time law: path and limits in, :class:`Trajectory` out, within the limits.

    Within all of them: the joint rows and, when set, the tool speed rows
    (:func:`~.tool.tool_rows`, or :func:`~.tool.tool_twist` for a law that does not sample the
    path at nodes). A law that also honours ``limits.max_jerk`` says so with a class attribute
    ``honours_jerk = True`` (:mod:`.jerk`); the others are never given a jerk limit.
    """

    def __call__(self, path: PathLike, limits: JointLimits, duration: float | None) -> Trajectory:
        """Time ``path`` within ``limits``.

        Args:
            path: the geometric path.
            limits: validated limits (see :func:`joint_limits`).
            duration: if given, the trajectory lasts exactly this long, s (finite, >= 0).
        Raises:
            LimitError: the duration is shorter than the law's minimum, or the path cannot be
                traversed.
        """


def _limit(value: npt.ArrayLike | None, default: npt.ArrayLike | None, dof: int, joint_names: list[str],
           what: str) -> np.ndarray:
    """Validate a per-joint limit (scalar broadcast); LimitError names the joint."""
    source = 'robot default' if value is None else 'requested'
    if value is None:
        value = default
    if value is None:
        raise LimitError(f'{what}: no limit given and the robot has no default')
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise LimitError(f'{what}: not a number or list of numbers ({err})') from err
    if arr.ndim == 0:
        arr = np.full(dof, float(arr))
    arr = arr.reshape(-1)
    if arr.shape != (dof,):
        raise LimitError(f'{what}: expected 1 or {dof} values (one per joint), got {arr.size}')
    if all(0.0 < x < math.inf for x in arr.tolist()):     # the usual case, a few µs less
        return arr
    bad = np.flatnonzero(~(np.isfinite(arr) & (arr > 0.0)))
    if bad.size:
        i = int(bad[0])
        raise LimitError(
            f"{what} for joint '{joint_names[i]}' must be positive and finite, got {arr[i]!r} ({source})")
    return arr


def joint_limits(path: PathLike, max_velocity: npt.ArrayLike | None = None,
                 max_acceleration: npt.ArrayLike | None = None, *,
                 max_tool_speed: float | None = None,
                 max_tool_angular_speed: float | None = None,
                 max_jerk: npt.ArrayLike | None = None) -> JointLimits:
    """The path's joint names and validated limits (the robot's where None).

    Args:
        path: the path (``dof``, ``joint_names``, optional ``robot``).
        max_velocity: scalar or (dof,), rad/s (m/s); None: ``path.robot.max_velocity``.
        max_acceleration: scalar or (dof,), rad/s^2 (m/s^2); None: ``path.robot.max_acceleration``.
        max_tool_speed: limit on the linear speed of the tool frame origin (base frame), m/s;
            None: no limit.
        max_tool_angular_speed: limit on the norm of the tool's angular velocity, rad/s; None: no
            limit.
        max_jerk: scalar or (dof,), rad/s^3 (m/s^3); None: no jerk limit (never the robot's).
    Raises:
        LimitError: a limit is missing, not a number, of the wrong size, or not positive and
            finite (the message names the joint, or the tool limit's argument); a tool limit on a
            path without a robot with kinematics (``robot.fk``, ``jacobian12``, ``hessian12``).
    """
    dof = int(path.dof)
    joint_names = [str(n) for n in getattr(path, 'joint_names', [])]
    if len(joint_names) != dof:
        joint_names = joint_names or [f'joint{i + 1}' for i in range(dof)]
        if len(joint_names) != dof:
            raise LimitError(f'path has {len(joint_names)} joint names but {dof} joints')
    robot = getattr(path, 'robot', None)
    vmax = _limit(max_velocity, getattr(robot, 'max_velocity', None), dof, joint_names, 'max_velocity')
    amax = _limit(max_acceleration, getattr(robot, 'max_acceleration', None), dof, joint_names,
                  'max_acceleration')
    tool_speed = check_tool_limit(max_tool_speed, 'max_tool_speed')
    tool_angular = check_tool_limit(max_tool_angular_speed, 'max_tool_angular_speed')
    if tool_speed is not None or tool_angular is not None:
        tool_kinematics(path, 'max_tool_speed' if tool_speed is not None else 'max_tool_angular_speed')
    jmax = None if max_jerk is None else _limit(max_jerk, None, dof, joint_names, 'max_jerk')
    return JointLimits(joint_names, vmax, amax, tool_speed, tool_angular, jmax)


def check_duration(duration: float | None) -> float | None:
    """None, or ``duration`` as a finite float >= 0, s; LimitError otherwise."""
    if duration is None:
        return None
    try:
        value = float(duration)
    except (TypeError, ValueError) as err:
        raise LimitError(f'duration must be a number, got {duration!r}') from err
    if not (math.isfinite(value) and value >= 0.0):
        raise LimitError(f'duration must be finite and >= 0, got {duration!r}')
    return value


def final_duration(duration: float | None, t_min: float) -> float:
    """The trajectory's duration, s: ``t_min`` when ``duration`` is None, else ``duration``.

    Raises:
        LimitError: ``duration`` shorter than ``t_min`` (the message gives the minimum).
    """
    if duration is None:
        return t_min
    if duration < t_min * (1.0 - 1e-12):
        raise LimitError(
            f'duration {duration:.6g} s is shorter than the minimum {t_min:.6g} s for these limits')
    return duration


__all__ = ['JointLimits', 'PathLike', 'TimeLaw', 'TimeScaling', 'check_duration', 'final_duration',
           'joint_limits', 'scaled_limits']


def scaled_limits(max_velocity: np.ndarray, max_acceleration: np.ndarray, time_scaling: float,
                  velocity_factor: float = 1.0, acceleration_factor: float = 1.0, *,
                  max_jerk: np.ndarray | None = None, max_tool_speed: float | None = None,
                  max_tool_angular_speed: float | None = None) -> dict[str, Any]:
    """The limits a scaled motion is timed under, as ``path.timed`` keyword arguments.

    A time scaling ``f`` (joint_trajectory_controller's: durations / f, velocities * f,
    accelerations * f**2, jerks * f**3, same path) and a request's velocity and acceleration
    factors (MoveIt's): velocities * f * velocity_factor (the tool speeds too), accelerations
    * f**2 * acceleration_factor, jerks * f**3. With factors 1 the result is exactly the time
    scaling of the unscaled motion. Units as given (rad or m, per s, s^2, s^3).
    """
    fv = time_scaling * velocity_factor
    out: dict[str, Any] = {'max_velocity': np.asarray(max_velocity, dtype=float) * fv,
                           'max_acceleration': np.asarray(max_acceleration, dtype=float)
                           * time_scaling ** 2 * acceleration_factor}
    if max_tool_speed is not None:
        out['max_tool_speed'] = max_tool_speed * fv
    if max_tool_angular_speed is not None:
        out['max_tool_angular_speed'] = max_tool_angular_speed * fv
    if max_jerk is not None:
        out['max_jerk'] = np.asarray(max_jerk, dtype=float) * time_scaling ** 3
    return out
