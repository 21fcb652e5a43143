"""The LIN's promise: the tool on the straight line + slerp exactly, or a refusal that says why and where.

The planner (core/planner.py) takes this route wherever the geodesic between two poses is the line
+ slerp (the paper's metric with ε = 0 on 6 joints; beyond 6 joints with ε None or 0, the line of
least joint motion): the fast route first (the pull-back at a mesh, verified against the geodesic
equations; beyond 6 joints the least-motion solve, core/redundant_solve.py), else the line traced
step by step (core/trace.py), which follows it or names the singularity, joint limit or reach
where it stops, with the fraction and the tool's place. Never a path off the line: the general
collocation runs only when asked (``method='collocation'``). Both ends reach their poses within
END_POSITION_TOLERANCE and END_ORIENTATION_TOLERANCE, or the plan is refused.
"""
from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable

import numpy as np

from .continuation import LineFollow
from .errors import IKError, LimitError, PathFollowError
from .geodesic import GeodesicPath
from .ik import IKSolution
from .kinematics import Chain
from .limits import check_path_limits
from .long_way import check_long_way
from .metric import Metric
from .redundant import LineTask, RedundantEquations
from .redundant_solve import plan_redundant
from .trace import line_curve, trace
from .transforms import check_transform, pose_error

#: A LIN's ends reach the requested poses within these (m, rad), or the plan is refused (issue 36).
END_POSITION_TOLERANCE = 1e-8
END_ORIENTATION_TOLERANCE = 1e-6


def check_exact_end(robot: Chain, ik: IKSolution, end: str) -> None:
    """Refuse an end pose that the IK reached only within the IK tolerance (a LIN ends exactly)."""
    if exact_end(ik):
        return
    raise IKError(f'IK failed for robot {robot.name!r}: the {end} pose is not reachable exactly within the '
                  f'joint limits: nearest reachable pose is {ik.position_error:.3g} m and '
                  f'{ik.orientation_error:.3g} rad away (a LIN reaches its poses within '
                  f'{END_POSITION_TOLERANCE:g} m and {END_ORIENTATION_TOLERANCE:g} rad, or is refused)',
                  residual=ik.residual)


def exact_end(ik: IKSolution) -> bool:
    """Whether an IK solution reaches its pose within a LIN's end tolerances."""
    return ik.position_error <= END_POSITION_TOLERANCE and ik.orientation_error <= END_ORIENTATION_TOLERANCE


def other_configuration(robot: Chain, q_end: np.ndarray, q_b: np.ndarray) -> PathFollowError:
    """The refusal of a LIN to goal joints that the line + slerp from the start does not lead to."""
    j = int(np.argmax(np.abs(q_end - q_b)))
    sv = np.linalg.svd(robot.jacobian(q_b), compute_uv=False)
    why = (' (goal_joints are at a singularity, where the pose does not fix the joints)'
           if sv[-1] < 1e-2 * sv[0] else '')
    return PathFollowError(
        f'the straight line cannot be followed by robot {robot.name!r} to goal_joints: at 100 % of the way '
        f'it reaches the goal pose in another configuration, joint {robot.joint_names[j]!r} at {q_end[j]:.6g} '
        f'instead of {q_b[j]:.6g}{why} (a LIN does not change the arm\'s branch; plan a PTP to these joints, or '
        f'give the goal as a pose); followable fraction 1.0000', fraction=1.0)


#: Tolerance (m, rad) of a trace that only finds the branch (seeds for the fast routes) or the
#: reason and place of a refusal.
SEED_TOLERANCE = 1e-5


class LineRoute:
    """The line route of :class:`~.planner.GeodesicPlanner` (its base: the attributes below are the
    planner's)."""

    robot: Chain
    metric: Metric
    redundant: RedundantEquations | None
    time_limit: float | None
    path_tolerance: float
    max_nodes: int
    check_limits: bool
    allow_long_way: bool
    _trace_memo: tuple[bytes, GeodesicPath | PathFollowError | None] | None
    _task_line: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
    _regular_ends: Callable[[np.ndarray, np.ndarray], bool]
    _pullback_route: Callable[[np.ndarray, np.ndarray, IKSolution | None, IKSolution | None, float,
                               Callable[[np.ndarray], np.ndarray] | None], GeodesicPath | None]

    def _check_exact_end(self, ik: IKSolution, end: str) -> None:
        check_exact_end(self.robot, ik, end)

    def _path_limits(self, path: GeodesicPath) -> None:
        check_path_limits(self.robot, path)

    def _line_is_geodesic(self) -> bool:
        """True where the geodesic between two poses is the line + slerp whenever it can be
        followed: the paper's metric without the ε term, on an arm that can hold any pose (6 or
        more joints; with fewer, the line + slerp is generally out of reach and the geodesic bows
        off it, as on the RRPP)."""
        return self.metric.kind == 'paper' and self.metric.epsilon == 0.0 and self.robot.dof >= 6

    def _line_route(self) -> bool:
        """True where a plan between two poses is the tool's line + slerp or a refusal (the promise
        of a LIN): the paper's metric on 6 joints with ε = 0, and beyond 6 joints with ε None or 0."""
        return self._line_is_geodesic() or self.redundant is not None

    def _solve_line(self, q_a: np.ndarray, q_b: np.ndarray, ik_a: IKSolution | None, ik_b: IKSolution | None,
                    t0: float) -> GeodesicPath:
        """The line + slerp from q_a, exactly, or the refusal that says why and where.

        Beyond 6 joints the least-motion path (redundant_solve) where it is found inside the limits;
        on 6 joints the pull-back at a mesh (the fast route) where the metric is regular at both ends
        and the mesh finds one branch. Otherwise the line is traced step by step (core/trace.py),
        which either follows it to the end or names the singularity, joint limit or reach where it
        stops: never a path off the line, and never the general solver's words.
        """
        deadline = None if self.time_limit is None else t0 + self.time_limit
        line_task = LineTask(*self._task_line(q_a, q_b))
        memo = self._trace_memo
        traced: GeodesicPath | None = None
        if memo is not None and memo[0] == q_a.tobytes() + q_b.tobytes():
            self._trace_memo = None                          # the goal IK's trace: used once
            if isinstance(memo[1], PathFollowError):
                if not self.allow_long_way:                  # (else the slerp the long way round too)
                    raise memo[1]                            # the line stops on the way: why and where
            else:
                traced = memo[1]
        if self.redundant is not None:
            path = self._least_motion(line_task, q_a, q_b, ik_a, ik_b, t0)
        else:
            path = self._pullback_route(q_a, q_b, ik_a, ik_b, t0, None) if traced is None else None
        if path is not None:
            return path
        singular_end = self.redundant is None and not self._regular_ends(q_a, q_b)
        if traced is None and ik_b is not None and not singular_end:
            # a coarse trace: seeds for the fast route on the line's branch, or the refusal with
            # its place (the singularity, limit or reach does not need the path's precision)
            traced, error = self._trace(line_task, q_a, None, ik_a, ik_b, t0, deadline, SEED_TOLERANCE)
            if traced is None and not self.allow_long_way:   # (else the slerp the long way round too)
                assert error is not None
                raise error
        if traced is not None:
            # the fast route again, started from the traced line (its nodes, on one branch): the
            # least-motion solve beyond 6 joints, the pull-back on 6; else the line traced exactly
            seeds = LineFollow(traced.s_nodes, traced.q_nodes, 1.0, None)
            q_end = traced.q_goal
            if self.redundant is not None:
                path = self._least_motion(line_task, q_a, q_end, ik_a, ik_b, t0, seeds)
            else:
                ik_end = None if ik_b is None else dataclasses.replace(ik_b, q=q_end)
                path = self._pullback_route(q_a, q_end, ik_a, ik_end, t0, seeds.seeds)
            if path is not None:
                return path
        goal_joints = None if ik_b is not None else q_b
        path, error = self._trace(line_task, q_a, goal_joints, ik_a, ik_b, t0, deadline)
        w = line_task.w_body
        if path is None and (goal_joints is not None or self.allow_long_way) and np.linalg.norm(w) > 1e-9:
            # the slerp the long way round (the tool turns by 2π − |w| the other way): a joint goal
            # asks for it, or allow_long_way permits it
            long = LineTask(line_task.T_a, line_task.T_b, w - 2.0 * np.pi * w / np.linalg.norm(w))
            path = self._trace(long, q_a, goal_joints, ik_a, ik_b, t0, deadline)[0]
        if path is None:
            assert error is not None
            raise error
        return self._finish_line(path, q_a, ik_a, ik_b, t0)

    def _least_motion(self, task: LineTask, q_a: np.ndarray, q_b: np.ndarray, ik_a: IKSolution | None,
                      ik_b: IKSolution | None, t0: float, seeds: LineFollow | None = None) -> GeodesicPath | None:
        """Beyond 6 joints: the least-motion path (redundant_solve), or None where it is not found
        inside the limits (``seeds``: the line already traced, to start the solve from)."""
        assert self.redundant is not None
        try:
            return plan_redundant(self.redundant, task, q_a, q_b, ik_a, ik_b, t0=t0,
                                  path_tolerance=self.path_tolerance, max_nodes=self.max_nodes,
                                  time_limit=self.time_limit,
                                  check_limits=self._path_limits if self.check_limits else None,
                                  seeds=seeds)
        except LimitError:
            return None          # the least-motion path leaves a limit: the trace may stay inside

    def _finish_line(self, path: GeodesicPath, q_a: np.ndarray, ik_a: IKSolution | None,
                     ik_b: IKSolution | None, t0: float) -> GeodesicPath:
        """A traced line's path with the ends' IK, the long-way and the limit checks, timed from t0."""
        path.ik_start = ik_a
        if ik_b is not None:
            if not self.allow_long_way:
                check_long_way(self.robot, q_a, path.q_goal, 'the goal pose, along the straight line,')
            path.ik_goal = dataclasses.replace(ik_b, q=path.q_goal)
        if self.check_limits:
            check_path_limits(self.robot, path)
        path.solver = dataclasses.replace(path.solver, time_ms=(time.perf_counter() - t0) * 1e3)
        return path

    def _trace(self, task: LineTask, q_a: np.ndarray, goal_joints: np.ndarray | None, ik_a: IKSolution | None,
               ik_b: IKSolution | None, t0: float, deadline: float | None, tolerance: float | None = None
               ) -> tuple[GeodesicPath, None] | tuple[None, PathFollowError]:
        """The line ``task`` traced from q_a (core/trace.py), ending at ``goal_joints`` if given;
        ``tolerance`` (m, rad): coarser than path_tolerance for seeds only."""
        result = trace(self.robot, line_curve(task.poses, task.twist), q_a, metric=self.metric,
                       tolerance=self.path_tolerance if tolerance is None else tolerance, t0=t0,
                       deadline=deadline, ik_start=ik_a, ik_goal=ik_b, q_end=goal_joints,
                       seeds_only=tolerance is not None)
        if result.path is None:
            assert result.error is not None
            return None, result.error
        if goal_joints is not None and not np.array_equal(result.path.q_goal, goal_joints):
            return None, other_configuration(self.robot, result.path.q_goal, goal_joints)
        return result.path, None

    def _remember_for(self, q_a: np.ndarray, q_b: np.ndarray) -> None:
        """Key the refusal that :meth:`_trace_to` remembered from q_a by the goal joints q_b too."""
        memo = self._trace_memo
        if memo is not None and memo[0] == q_a.tobytes():
            self._trace_memo = (q_a.tobytes() + q_b.tobytes(), memo[1])

    def _trace_to(self, T_goal: np.ndarray, q_a: np.ndarray) -> IKSolution | None:
        """The goal configuration the line + slerp from q_a leads to, by tracing it (core/trace.py),
        or None where the trace stops (the goal IK then says whether the goal is reachable at all,
        and not the long way round: those reasons come first). The traced path, or the reason it
        stops, is remembered for :meth:`_solve_line` (one trace per plan; :meth:`_remember_for`
        keys a refusal by the goal joints the IK finds)."""
        T_a = self.robot.fk(q_a)
        task = LineTask.between(T_a, check_transform(T_goal, 'goal pose'))
        t0 = time.perf_counter()
        deadline = None if self.time_limit is None else t0 + self.time_limit
        result = trace(self.robot, line_curve(task.poses, task.twist), q_a, metric=self.metric,
                       tolerance=SEED_TOLERANCE, t0=t0, deadline=deadline, seeds_only=True)
        if result.path is None:
            self._trace_memo = (q_a.tobytes(), result.error)
            return None
        q_end = result.path.q_goal
        dp, dr = pose_error(self.robot.fk(q_end), T_goal)
        self._trace_memo = (q_a.tobytes() + q_end.tobytes(), result.path)
        return IKSolution(q_end, True, 0, 0.0, float(dp), float(dr))
