"""Time parameterization of a geometric path under joint velocity and acceleration limits.

The paper (Lemma 2) notes that a geodesic's speed is set by rescaling its parameter; this is the
entry point that turns a path ``q(s)``, s in [0, 1], into a trajectory ``q(t) = q(s(t))``. It
validates the limits and the duration, then hands the path to a time law (:mod:`.law`); the
default is the smooth rest-to-rest law of :mod:`.smoothing`, or with ``max_jerk`` the
jerk-limited law of :mod:`.jerk`. The path never changes:
``dq/dt = q' sdot`` and ``d2q/dt2 = q' sddot + q'' sdot^2`` are evaluated exactly from it.
"""
from __future__ import annotations

import numpy.typing as npt

from ..core.errors import LimitError
from .jerk import JerkLimited
from .law import TimeLaw, check_duration, joint_limits
from .types import PathLike
from .sampling import CORNER_TOLERANCE
from .smoothing import SmoothRestToRest
from .tuning import CHECK_MARGIN, TOPP_MARGIN
from .trajectory import Trajectory


#: The default jerk-limited law (immutable: shared by every call with the default options).
_JERK_LIMITED = JerkLimited()


def time_parameterize(path: PathLike, max_velocity: npt.ArrayLike | None = None,
                      max_acceleration: npt.ArrayLike | None = None,
                      duration: float | None = None, *, law: TimeLaw | None = None,
                      grid_points: int = 100, refine: int = 2, smoothing: float = 0.05,
                      check_samples: int | None = None, max_tool_speed: float | None = None,
                      max_tool_angular_speed: float | None = None,
                      max_jerk: npt.ArrayLike | None = None) -> Trajectory:
    """Time law along ``path`` within joint limits; by default the fastest smooth rest-to-rest one.

    Tool speed limits (Cartesian, as Pilz's planners honour them) are velocity rows like the
    joints': the tool's twist along the path is ``J(q(s)) q'(s) sdot`` (:mod:`.tool`).

    Args:
        path: a :class:`~.law.PathLike`: ``evaluate(s, order)`` (each (len(s), dof), w.r.t. s in
            [0, 1]), ``dof``, ``joint_names``; optional ``breakpoints`` (the motion rests where q'
            jumps) and ``robot`` (``robot.max_velocity`` and ``robot.max_acceleration`` (dof,) are
            the default limits).
        max_velocity: per-joint limit (dof,) or scalar, rad/s (m/s for prismatic); None: robot's.
        max_acceleration: per-joint limit (dof,) or scalar, rad/s^2 (m/s^2); None: robot's.
        duration: if given, the law is stretched uniformly to exactly this duration, s.
        law: the time law; None: ``SmoothRestToRest(grid_points, refine, smoothing,
            check_samples)``, or with ``max_jerk`` ``JerkLimited(grid_points, refine,
            check_samples)`` (those options only configure these defaults). Another law, e.g.
            :class:`~.constant_speed.ConstantSpeed` (constant metric speed, the paper's Lemma 2).
        grid_points: number of uniform s intervals at which the path is evaluated.
        refine: the time-optimal pass runs on ``refine`` times finer steps.
        smoothing: acceleration-ramp time as a fraction of the time-optimal duration, in (0, 1].
        check_samples: time samples of the dense limit check (default max(4000, 20 nodes)).
        max_tool_speed: limit on the linear speed of the tool frame origin (base frame), m/s,
            positive and finite; None: no limit. Needs ``path.robot`` with kinematics (``fk``,
            ``jacobian12``, ``hessian12``).
        max_tool_angular_speed: limit on the norm of the tool's angular velocity, rad/s, positive
            and finite; None: no limit. Needs ``path.robot`` likewise.
        max_jerk: per-joint jerk limit (dof,) or scalar, rad/s^3 (m/s^3), positive and finite;
            None: no jerk limit (the default law's jerk is bounded but not limited). A given
            ``law`` must honour it (``honours_jerk``).
    Returns:
        A :class:`Trajectory`; for the default law, zero velocity and acceleration at both ends
        (and at corners), within the limits.
    Raises:
        LimitError: invalid limits (the message names the joint, or the tool limit's
            argument) or options, ``max_jerk`` with a law that does not honour it, a tool limit
            on a path without a robot, duration shorter than the minimum (the message gives
            it), or a path that cannot be traversed.
    """
    if law is None and max_jerk is not None:
        law = (_JERK_LIMITED if (grid_points, refine, check_samples) == (100, 2, None) else
               JerkLimited(grid_points=int(grid_points), refine=refine, check_samples=check_samples))
    elif law is None:
        law = SmoothRestToRest(grid_points=int(grid_points), refine=refine, smoothing=smoothing,
                               check_samples=check_samples)
    elif max_jerk is not None and not getattr(law, 'honours_jerk', False):
        raise LimitError(f'max_jerk: the time law {type(law).__name__} does not honour a jerk limit')
    duration = check_duration(duration)
    limits = joint_limits(path, max_velocity, max_acceleration, max_tool_speed=max_tool_speed,
                          max_tool_angular_speed=max_tool_angular_speed, max_jerk=max_jerk)
    return law(path, limits, duration)


__all__ = ['CHECK_MARGIN', 'CORNER_TOLERANCE', 'TOPP_MARGIN', 'Trajectory', 'time_parameterize']
