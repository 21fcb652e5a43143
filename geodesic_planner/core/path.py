"""Joint paths q(s), s ∈ [0, 1]: the common interface and the quintic Hermite spline behind them.

Every path (geodesic, piecewise geodesic, baselines) offers ``evaluate(s) -> (q, dq, ddq, dddq)``
with derivatives w.r.t. s, ``ee_poses(s)`` and ``timed(...)`` (time parameterization).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt

from .errors import RequestError
from .kinematics import Chain
from .transforms import segment_distance



def check_order(order: int) -> int:
    """Validate a derivative order for evaluate(): 0, 1, 2 or 3."""
    if order not in (0, 1, 2, 3):
        raise RequestError(f'order must be 0, 1, 2 or 3, got {order!r}')
    return int(order)


def check_s(s: object) -> np.ndarray:
    """Validate a path-parameter array: 1-D, finite, inside [0, 1] (tiny round-off clipped).

    Raises:
        RequestError: otherwise.
    """
    try:
        arr = np.atleast_1d(np.asarray(s, dtype=float))
    except (TypeError, ValueError) as err:
        raise RequestError(f's: expected a 1-D array of numbers in [0, 1] ({err})') from err
    if arr.ndim != 1:
        raise RequestError(f's: expected a 1-D array, got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise RequestError('s: contains NaN or inf')
    if arr.size and (arr.min() < -1e-12 or arr.max() > 1 + 1e-12):
        raise RequestError(f's: values must lie in [0, 1], got [{arr.min():.6g}, {arr.max():.6g}]')
    return np.clip(arr, 0.0, 1.0)


def by_segment(edges: np.ndarray, s: np.ndarray) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Split ``s`` (1-D in [0, 1]) over the segments between sorted ``edges`` (n + 1,).

    Yields, for every segment j that holds some of s: (j, boolean mask of those s, their local
    parameter in [0, 1] along segment j).
    """
    idx = np.clip(np.searchsorted(edges, s, side='right') - 1, 0, edges.size - 2)
    for j in np.unique(idx).tolist():
        sel = idx == j
        yield j, sel, np.clip((s[sel] - edges[j]) / (edges[j + 1] - edges[j]), 0.0, 1.0)


class JointPath(ABC):
    """A joint path over s ∈ [0, 1] for a robot."""

    robot: Chain

    @abstractmethod
    def evaluate(self, s: np.ndarray, order: int = 3) -> tuple[np.ndarray, ...]:
        """q, dq/ds, d²q/ds², d³q/ds³ at s (1-D in [0, 1]); each (len(s), dof); rad or m.

        ``order`` < 3 returns only the first ``order + 1`` of them (cheaper for geodesics, whose
        third derivative needs the Jacobians of the geodesic equations).
        """

    def interpolate(self, s: np.ndarray) -> tuple[np.ndarray, ...]:
        """q and its first three s-derivatives at s, for sampling a time law and for the
        trajectory's motion: from the path's own interpolant where it has one (a solver's spline:
        q and dq/ds are the path's, and the second and third derivatives are theirs, within the
        solver's tolerance of :meth:`evaluate`'s, at a fraction of the cost), else :meth:`evaluate`.
        Each (len(s), dof); rad or m."""
        return self.evaluate(s, 3)

    @property
    def joint_names(self) -> list[str]:
        """Joint names in the robot's order."""
        return list(self.robot.joint_names)

    @property
    def dof(self) -> int:
        """Number of joints."""
        return self.robot.dof

    @property
    def q_start(self) -> np.ndarray:
        """Joint positions at s = 0."""
        return self.evaluate(np.array([0.0]))[0][0]

    @property
    def q_goal(self) -> np.ndarray:
        """Joint positions at s = 1."""
        return self.evaluate(np.array([1.0]))[0][0]

    def ee_poses(self, s: np.ndarray) -> np.ndarray:
        """Tool poses (len(s), 4, 4) along the path, base frame."""
        return self.robot.fk(self.evaluate(check_s(s), 0)[0])

    def deviation(self, s: np.ndarray) -> np.ndarray:
        """Distance (m) of the tool from the path's own geometry at s (N,): here the straight
        segment between the path's end positions (LIN); an arc's circle, nothing for PTP."""
        p = self.ee_poses(np.concatenate([[0.0, 1.0], check_s(s)]))[:, :3, 3]    # the ends, then s
        return segment_distance(p[2:], p[0], p[1])

    def line_deviation(self, samples: int = 101) -> float:
        """Largest :meth:`deviation` (m) on ``samples`` uniform values of s (piecewise paths:
        per piece): for a LIN, the distance from the straight segment."""
        return float(self.deviation(np.linspace(0.0, 1.0, int(samples))).max())

    def timed(self, max_velocity: npt.ArrayLike | None = None, max_acceleration: npt.ArrayLike | None = None,
              duration: float | None = None, *, max_tool_speed: float | None = None,
              max_tool_angular_speed: float | None = None, law: Any = None,  # noqa: ANN401
              max_jerk: npt.ArrayLike | None = None) -> Any:  # noqa: ANN401
        """Time parameterization under per-joint limits (see timing.parameterize).

        The one call from core up into the timing layer: a function-local import, so that core
        never imports timing at module level (timing reads paths only through its PathLike
        protocol).

        Args:
            max_velocity, max_acceleration: per-joint limits (scalars broadcast); the robot's
                limits when None; rad/s (m/s), rad/s² (m/s²).
            duration: stretch to exactly this duration, s (must not be shorter than feasible).
            max_tool_speed: limit on the linear speed of the tool frame origin (base frame), m/s;
                None: no limit.
            max_tool_angular_speed: limit on the norm of the tool's angular velocity, rad/s;
                None: no limit.
            law: the time law (``timing.TimeLaw``); None: the smooth rest-to-rest law, or the
                jerk-limited one when ``max_jerk`` is given. ``timing.ConstantSpeed(ramp=...)``
                keeps the metric speed constant (Lemma 2).
            max_jerk: per-joint jerk limit (scalars broadcast), rad/s³ (m/s³); None: no jerk
                limit. With it the jerk-limited law (timing.jerk) is used.
        Raises:
            LimitError: an invalid limit (the message names it) or a duration below the minimum.
        """
        from ..timing.parameterize import time_parameterize
        return time_parameterize(self, max_velocity=max_velocity, max_acceleration=max_acceleration,
                                 duration=duration, law=law, max_tool_speed=max_tool_speed,
                                 max_tool_angular_speed=max_tool_angular_speed, max_jerk=max_jerk)
