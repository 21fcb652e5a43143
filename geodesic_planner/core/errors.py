"""Exception types of geodesic_planner.

Every error the library raises on purpose derives from :class:`GeodesicPlannerError`, so a node or
a CLI catches one family and reports ``str(err)``, which always names the cause.
"""
from __future__ import annotations

#: Longest user-given string quoted in an error message, characters (a 1 MB frame_id must not be
#: echoed into every log line and reply).
QUOTE_LIMIT = 80


def quoted(text: object, limit: int = QUOTE_LIMIT) -> str:
    """``repr`` of a user-given string for a message, cut to ``limit`` characters with its length."""
    s = str(text)
    if len(s) <= limit:
        return repr(s)
    return f'{s[:limit]!r}... ({len(s)} characters)'


class GeodesicPlannerError(Exception):
    """Root of all geodesic_planner errors."""


class RequestError(GeodesicPlannerError, ValueError):
    """A request is malformed: NaN/inf, wrong shape or joint count, bad quaternion, unknown name."""


class FrameError(RequestError):
    """A pose is given in a frame the planner cannot transform (only the robot's base frame is known)."""


class StartStateError(RequestError):
    """A plan's first point is not where the robot is (beyond the allowed start tolerance)."""


class ConfigError(GeodesicPlannerError, ValueError):
    """A node's parameter value is invalid (the message names the parameter and the reason)."""


class PlanningFailedError(GeodesicPlannerError):
    """A valid request gave no plan a node can deliver (e.g. too many trajectory points)."""


class PlanTimeoutError(GeodesicPlannerError):
    """A plan took longer than the node's ``plan_timeout``."""


class JointStateError(RequestError):
    """A joint state (a message, or joints given in a request) is unusable.

    Attributes:
        kind: what is wrong, one of :data:`JOINT_STATE_PROBLEMS`: 'length' (names and values
            disagree), 'duplicate' (a name twice), 'none of' (no robot joint), 'missing' (some
            robot joints), 'non-finite' (NaN/inf positions).
    """

    def __init__(self, message: str, *, kind: str) -> None:
        super().__init__(message)
        self.kind = kind


#: The kinds of :class:`JointStateError`.
JOINT_STATE_PROBLEMS = ('length', 'duplicate', 'none of', 'missing', 'non-finite')


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


class PathFollowError(GeodesicPlannerError):
    """The tool's line + slerp cannot be followed on one branch: the message says why and where.

    Raised for a singularity on the way (the joints would have to flip); the subclasses below
    for a joint limit and for a pose out of reach.

    Attributes:
        fraction: the part of the line that can be followed from the start, in [0, 1] (as
            MoveIt's GetCartesianPath reports it).
    """

    def __init__(self, message: str, *, fraction: float) -> None:
        super().__init__(message)
        self.fraction = fraction


class LineLimitError(PathFollowError, LimitError):
    """The line's branch crosses a joint's position limit (names the joint and the place)."""


class LineUnreachableError(PathFollowError, IKError):
    """The line leaves what the start's branch can reach (names the place)."""


class CollisionError(GeodesicPlannerError):
    """Two bodies (robot links, scene or attached objects) come closer than the collision padding.

    Attributes:
        pair: the two bodies' names.
        fraction: where, as the path parameter s in [0, 1] (0 at the start, 1 at the goal).
        time: where, s from the trajectory's start.
        clearance: their distance there, m (0 or negative: in contact).
    """

    def __init__(self, message: str, *, pair: tuple[str, str], fraction: float, time: float,
                 clearance: float) -> None:
        super().__init__(message)
        self.pair = pair
        self.fraction = fraction
        self.time = time
        self.clearance = clearance


class StartInCollisionError(CollisionError):
    """The start state is in collision (MoveIt's START_STATE_IN_COLLISION)."""


class GoalInCollisionError(CollisionError):
    """The goal state is in collision (MoveIt's GOAL_IN_COLLISION)."""


class PathInCollisionError(CollisionError):
    """A collision on the way between start and goal (MoveIt's INVALID_MOTION_PLAN)."""


class BagError(GeodesicPlannerError):
    """A bag cannot be read or written."""


__all__ = [
    'JOINT_STATE_PROBLEMS',
    'QUOTE_LIMIT',
    'BVPError',
    'BagError',
    'CollisionError',
    'ConfigError',
    'FrameError',
    'GeodesicPlannerError',
    'GoalInCollisionError',
    'IKError',
    'JointStateError',
    'KinematicsError',
    'LimitError',
    'PathInCollisionError',
    'PlanTimeoutError',
    'PlanningFailedError',
    'RequestError',
    'SingularMetricError',
    'StartInCollisionError',
    'StartStateError',
    'TrajectoryError',
    'quoted',
]
