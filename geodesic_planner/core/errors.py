"""Exception types of geodesic_planner.

Every error the library raises on purpose derives from :class:`GeodesicPlannerError`, so a node or
a CLI catches one family and reports ``str(err)``, which always names the cause.
"""
from __future__ import annotations


class GeodesicPlannerError(Exception):
    """Root of all geodesic_planner errors."""


class RequestError(GeodesicPlannerError, ValueError):
    """A request is malformed: NaN/inf, wrong shape or joint count, bad quaternion, unknown name."""


class TrajectoryError(RequestError):
    """A joint trajectory breaks joint_trajectory_controller's rules (the message lists them)."""


class KinematicsError(GeodesicPlannerError):
    """A robot model cannot be built (bad DH table, URDF not a serial chain, unsupported joint)."""


class SingularMetricError(GeodesicPlannerError):
    """The metric tensor G(q) is singular (or numerically so) at a configuration."""


class IKError(GeodesicPlannerError):
    """Inverse kinematics failed: pose unreachable beyond tolerance or no convergence.

    Attributes:
        residual: remaining pose error in the metric's embedding (m-equivalent), or nan.
        iterations: iterations used.
    """

    def __init__(self, message: str, *, residual: float = float('nan'), iterations: int = 0) -> None:
        super().__init__(message)
        self.residual = residual
        self.iterations = iterations


class BVPError(GeodesicPlannerError):
    """The geodesic boundary-value problem did not converge.

    Attributes:
        status: scipy ``solve_bvp`` status (1: max nodes, 2: singular Jacobian, 3: tolerance).
        max_residual: largest relative collocation residual reached.
    """

    def __init__(self, message: str, *, status: int = -1, max_residual: float = float('nan')) -> None:
        super().__init__(message)
        self.status = status
        self.max_residual = max_residual


class LimitError(GeodesicPlannerError):
    """Joint limits (position, velocity, acceleration) are invalid or cannot be met."""


class BagError(GeodesicPlannerError):
    """A bag cannot be read or written."""


__all__ = [
    'BVPError',
    'BagError',
    'GeodesicPlannerError',
    'IKError',
    'KinematicsError',
    'LimitError',
    'RequestError',
    'SingularMetricError',
    'TrajectoryError',
]
