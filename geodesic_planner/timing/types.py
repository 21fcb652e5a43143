"""The types the time laws share: the path as they read it, the law's s(t), the limits.

A leaf of the timing layer (it imports nothing of it), so that the modules that use these types
(sampling, tool, the laws, the trajectory) never import each other for them.
"""
from __future__ import annotations

from typing import NamedTuple, Protocol

import numpy as np

__all__ = ['JointLimits', 'PathLike', 'TimeScaling']


class PathLike(Protocol):
    """A joint path q(s), s in [0, 1], as the time laws read it.

    Optional attributes, read with ``getattr``: ``breakpoints`` (values of s where derivatives
    may jump; the law rests where q' jumps), ``robot`` (its ``max_velocity`` and
    ``max_acceleration``, shape (dof,), are the default limits) and ``joint_line`` (``(q_a, dq)``
    when the path is the straight joint line ``q_a + s dq``: the jerk-limited law times it in
    closed form, :mod:`.line_profile`).
    """

    @property
    def dof(self) -> int:
        """Number of joints."""

    @property
    def joint_names(self) -> list[str]:
        """Joint names, length dof."""

    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q, dq/ds, ..., up to the ``order``-th derivative at ``s`` (N,); each (N, dof); rad or m."""


class TimeScaling(Protocol):
    """A law's path parameter as a function of time, ``s(t)``, on [0, duration]."""

    @property
    def duration(self) -> float:
        """Duration of the law, s."""

    def evaluate(self, t: np.ndarray, jerk: bool = True
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """s, sdot, sddot and (if ``jerk``) sdddot at sorted or unsorted times ``t`` (M,), s.

        Times outside [0, duration] are clipped. Units 1, 1/s, 1/s^2, 1/s^3.
        """


class JointLimits(NamedTuple):
    """Validated limits: per joint, and optionally on the tool's Cartesian speed.

    A law honours every limit it is given: the tool limits are velocity rows like the joints'
    (:mod:`.tool` computes them from the path's robot).

    Attributes:
        joint_names: joint names, length dof.
        max_velocity: shape (dof,), rad/s (m/s), positive and finite.
        max_acceleration: shape (dof,), rad/s^2 (m/s^2), positive and finite.
        max_tool_speed: linear speed of the tool frame origin, base frame, m/s (positive and
            finite), or None (no limit); set only when the path's robot has kinematics.
        max_tool_angular_speed: norm of the tool's angular velocity, rad/s (positive and
            finite), or None (no limit).
        max_jerk: shape (dof,), rad/s^3 (m/s^3), positive and finite, or None (no jerk limit;
            only laws with ``honours_jerk = True`` accept one, see :class:`TimeLaw`).
    """

    joint_names: list[str]
    max_velocity: np.ndarray
    max_acceleration: np.ndarray
    max_tool_speed: float | None = None
    max_tool_angular_speed: float | None = None
    max_jerk: np.ndarray | None = None
