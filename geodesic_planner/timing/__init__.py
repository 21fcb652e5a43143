"""Time laws: timing of a joint path under per-joint limits, the Trajectory type and its validator.

Layers inside: sampling -> topp -> smoothing (the rest-to-rest law), jerk (the jerk-limited law) and
constant_speed (Lemma 2) behind the law protocol;
``trajectory`` is what every law returns; ``validate`` holds joint_trajectory_controller's rules.
"""
from __future__ import annotations

from .constant_speed import ConstantSpeed
from .jerk import JerkLimited
from .law import TimeLaw
from .types import JointLimits, PathLike, TimeScaling
from .parameterize import time_parameterize
from .smoothing import SmoothRestToRest
from .trajectory import Trajectory
from .validate import check_trajectory, trajectory_problems

__all__ = [
    'ConstantSpeed',
    'JerkLimited',
    'JointLimits',
    'PathLike',
    'SmoothRestToRest',
    'TimeLaw',
    'TimeScaling',
    'Trajectory',
    'check_trajectory',
    'time_parameterize',
    'trajectory_problems',
]
