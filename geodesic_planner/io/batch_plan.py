"""One request of a batch -> one result row: the library call behind ``geodesic-plan batch``.

A batch request is a mapping in the schema of the YAML requests (:mod:`.requests`), plus:

* ``id`` (optional): the row's name (a string or an integer); default: its line or row number;
* ``robot`` (optional): a preset name or a URDF path; default: the job's robot;
* ``scene`` (optional): the name of one of the job's scenes; default: the job's default scene
  (none when the job has none);
* ``motion`` (optional): ``LIN``, ``CIRC`` or ``PTP`` with the keys of a sequence item
  (``goal``/``goal_joints``, ``interim``/``center``, ``ptp``) at the top level: a one-motion
  sequence. Without ``motion`` and ``sequence`` the request is a geodesic, as a YAML request;
* ``velocity_scaling``, ``acceleration_scaling`` (optional, in (0, 1]): MoveIt's factors on the
  robot's joint limits (``timing.law.scaled_limits``);
* ``time_limit`` (optional, s): the request's own time limit, at most the job's.

:func:`plan_row` plans it as ``geodesic-plan`` does (``PlanRequest.plan``, ``path.timed``, the
collision check with other start branches, ``trajectory.sample``) and returns the row; it never
raises for a bad or failing request: the row carries the code (:mod:`..core.codes`) and the
reason. The same request gives the same row, bit for bit, whatever was planned before it in the
same process (only ``planning_time`` is a measurement).
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..core.cancel import CancelToken, Cancelled, cancellable
from ..core.codes import PlanCode, error_code
from ..core.collision import DEFAULT_LINK_RADIUS, DEFAULT_PADDING, CollisionModel
from ..core.errors import GeodesicPlannerError, PlanningFailedError, RequestError, quoted
from ..core.kinematics import Chain
from ..core.robots import load_robot, urdf_text
from ..timing.law import scaled_limits
from ..timing.resample import MAX_POINTS, sample_count
from .collision_setup import collision_model
from .requests import ITEM_KEYS, parse_request

__all__ = ['BATCH_KEYS', 'DEFAULT_SAMPLE_PERIOD', 'MAX_TIME_LIMIT', 'BatchContext', 'failure_row', 'plan_row']

#: Keys of a batch request beyond the YAML request's.
BATCH_KEYS = frozenset({'id', 'scene', 'motion', 'velocity_scaling', 'acceleration_scaling', 'time_limit'})
#: Time between a trajectory's points, s (the nodes' ``sample_period`` default).
DEFAULT_SAMPLE_PERIOD = 0.01
#: Largest time limit of one request, s.
MAX_TIME_LIMIT = 3600.0
#: Longest ``id`` kept, characters.
MAX_ID_CHARS = 200


@dataclasses.dataclass
class BatchContext:
    """What every request of a job shares: the default robot and the scenes, built once per worker.

    Attributes:
        robot: the default robot (preset name or URDF path; '' : every request names its own).
        scenes: scene name -> scene YAML path; the name '' is the default scene.
        base_dir: directory that relative URDF paths of the requests are read from.
        sample_period: time between a trajectory's points, s.
        time_limit: a request's time limit, s (the plan stops at its next checkpoint after it).
        ptp_around: in a scene, a sequence's blocked PTP items plan around the obstacles (OMPL,
            ``core.around``) instead of being refused; such rows depend on OMPL's random state,
            so they are not reproducible bit for bit (off by default, unlike ``geodesic-plan``).
        ptp_planning_timeout: the search's budget per PTP item, s.
    """

    robot: str = ''
    scenes: Mapping[str, str] = dataclasses.field(default_factory=dict)
    base_dir: str = '.'
    sample_period: float = DEFAULT_SAMPLE_PERIOD
    time_limit: float = 60.0
    ptp_around: bool = False
    ptp_planning_timeout: float = 1.0
    _robots: dict[tuple[str, Any, Any], Chain] = dataclasses.field(default_factory=dict, repr=False)
    _models: dict[tuple[int, str], CollisionModel] = dataclasses.field(default_factory=dict, repr=False)

    def __getstate__(self) -> dict[str, Any]:
        # sent to a worker without what was built here: a robot's compiled state (ctypes
        # buffers) and coal bodies do not survive pickling; each worker builds its own
        return {k: v for k, v in self.__dict__.items() if k not in ('_robots', '_models')}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state, _robots={}, _models={})

    def load(self) -> None:
        """Build the default robot and its collision models now (a worker's start-up).

        Raises:
            GeodesicPlannerError: the robot or a scene cannot be read.
        """
        if self.robot:
            robot = self.robot_loader(self._path(self.robot))
            for name in self.scenes:
                self.model(robot, self._path(self.robot), name)

    def _path(self, ref: str) -> str:
        if ref.endswith('.urdf') and not os.path.isabs(ref):
            return os.path.join(self.base_dir, ref)
        return ref

    def robot_loader(self, ref: str, *, base_link: Any = None, tip_link: Any = None) -> Chain:  # noqa: ANN401
        """``load_robot`` keeping what it built (``parse_request``'s ``robot_loader``)."""
        key = (ref, base_link, tip_link)
        if key not in self._robots:
            self._robots[key] = load_robot(ref, base_link=base_link, tip_link=tip_link)
        return self._robots[key]

    def model(self, robot: Chain, source: str, scene: str) -> CollisionModel:
        """The collision model of ``robot`` (built from ``source``) in the scene named ``scene``.

        Raises:
            RequestError: no scene of that name; GeodesicPlannerError: a bad scene file.
        """
        if scene not in self.scenes:
            known = sorted(self.scenes) or 'none'
            raise RequestError(f'scene: no scene named {quoted(scene)} in this job (scenes: {known})')
        key = (id(robot), scene)
        if key not in self._models:
            self._models[key] = collision_model(robot, urdf_text(source) if source else None,
                                                padding=DEFAULT_PADDING, link_radius=DEFAULT_LINK_RADIUS,
                                                scene=self.scenes[scene])
        return self._models[key]


def failure_row(index: int, ident: str, code: int, message: str, fraction: float = -1.0,
                planning_time: float = math.nan) -> dict[str, Any]:
    """The row of a request that gave no trajectory."""
    empty = np.zeros((0, 0))
    return {'index': index, 'id': ident, 'status': int(code), 'message': message, 'fraction': fraction,
            'planning_time': planning_time, 'duration': math.nan, 'min_clearance': math.nan,
            'robot': '', 'joint_names': [], 'times': np.zeros(0), 'positions': empty,
            'velocities': empty, 'accelerations': empty}


def request_id(data: object, index: int) -> str:
    """The row's ``id``: the request's own (a string or an integer, cut to MAX_ID_CHARS), else the
    line or row number."""
    raw = data.get('id') if isinstance(data, Mapping) else None
    if isinstance(raw, bool) or not isinstance(raw, (str, int)):
        return str(index)
    return str(raw)[:MAX_ID_CHARS]


def plan_row(data: object, context: BatchContext, index: int) -> dict[str, Any]:
    """Plan one batch request (see the module's doc) and return its result row.

    Args:
        data: the decoded request (a mapping; anything else is an INVALID_REQUEST row).
        context: the job's robot, scenes, sample period and time limit.
        index: the request's line (JSON Lines) or row (Parquet) number, from 1.
    Returns:
        The row: ``index``, ``id``, ``status`` (PlanErrorCode), ``message`` ('' on success),
        ``fraction`` (1 on success; a line's followable part, else -1), ``planning_time`` (s),
        ``duration`` (s), ``min_clearance`` (m; nan without a scene), ``robot``, ``joint_names``,
        ``times`` (N,), ``positions``, ``velocities``, ``accelerations`` (N, dof) every
        ``sample_period`` s.
    """
    ident = request_id(data, index)
    t0 = time.perf_counter()
    try:
        with cancellable(_Deadline(_time_limit(data, context.time_limit))):
            row = _plan(data, context, index, ident)
    except Cancelled as err:
        return failure_row(index, ident, PlanCode.TIMED_OUT, str(err), -1.0, time.perf_counter() - t0)
    except GeodesicPlannerError as err:
        return failure_row(index, ident, error_code(err), str(err),
                           float(getattr(err, 'fraction', -1.0)), time.perf_counter() - t0)
    except Exception as err:  # noqa: BLE001 a library bug fails this request, not the job
        return failure_row(index, ident, PlanCode.PLANNING_FAILED,
                           f'internal error: {type(err).__name__}: {err}', -1.0,
                           time.perf_counter() - t0)
    row['planning_time'] = time.perf_counter() - t0
    return row


class _Deadline(CancelToken):
    """A token that cancels itself at the first checkpoint past its time limit (no timer thread:
    starting one per request cost more than a clock read per checkpoint)."""

    def __init__(self, limit: float) -> None:
        super().__init__()
        self.limit = limit
        self.deadline = time.monotonic() + limit

    @property
    def cancelled(self) -> bool:
        if not self._event.is_set() and time.monotonic() > self.deadline:
            self.cancel(f'ran past its time limit of {self.limit:g} s')
        return self._event.is_set()


def _time_limit(data: object, job_limit: float) -> float:
    raw = data.get('time_limit') if isinstance(data, Mapping) else None
    if raw is None:
        return job_limit
    value = _fraction_or_number(raw, 'time_limit')
    if not 0.0 < value <= MAX_TIME_LIMIT:
        raise RequestError(f'request: time_limit must be in (0, {MAX_TIME_LIMIT:g}] s, got {raw!r}')
    return min(value, job_limit)


def _fraction_or_number(raw: object, what: str) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or not math.isfinite(raw):
        raise RequestError(f'request: {what} must be a finite number, got {raw!r}')
    return float(raw)


def yaml_request(data: Mapping[str, Any], default_robot: str) -> dict[str, Any]:
    """The YAML request of a batch request: its batch keys taken out, ``motion`` made a sequence.

    Raises:
        RequestError: ``motion`` beside ``sequence``, ``via`` or a key a motion does not take.
    """
    out = {k: v for k, v in data.items() if k not in BATCH_KEYS and v is not None}
    out.setdefault('robot', default_robot or None)
    if out['robot'] is None:
        raise RequestError('request: missing "robot" (preset name or URDF path), and the job has no --robot')
    motion = data.get('motion')
    if motion is None:
        return out
    if 'sequence' in out or 'via' in out:
        raise RequestError('request: motion makes a one-motion sequence: give motion or sequence (and no via)')
    item: dict[str, Any] = {k: out.pop(k) for k in ('goal', 'goal_joints', 'interim', 'center', 'ptp') if k in out}
    item['motion'] = motion
    assert set(item) <= ITEM_KEYS
    out['sequence'] = [item]
    return out


def _plan(data: object, context: BatchContext, index: int, ident: str) -> dict[str, Any]:
    if not isinstance(data, Mapping):
        raise RequestError(f'request: expected a mapping, got {type(data).__name__}')
    req = parse_request(yaml_request(data, context.robot), context.base_dir, robot_loader=context.robot_loader)
    factors = [_factor(data, key) for key in ('velocity_scaling', 'acceleration_scaling')]
    limits: dict[str, Any] = {}
    if factors != [1.0, 1.0]:
        limits = scaled_limits(req.robot.max_velocity, req.robot.max_acceleration, 1.0, *factors)
    scene = data.get('scene', '' if '' in context.scenes else None)
    model = None
    if scene is not None:
        if not isinstance(scene, str):
            raise RequestError(f'request: scene must be a scene name, got {scene!r}')
        model = context.model(req.robot, req.robot_source, scene)
        if context.ptp_around:
            from ..core.around import AroundOptions
            req.around = AroundOptions(model, context.ptp_planning_timeout)
    planner = req.planner()

    def attempt(q_start: np.ndarray | None) -> tuple[Any, Any]:
        r = req if q_start is None else dataclasses.replace(req, start=None, start_joints=q_start)
        path = r.plan(planner)
        return path, path.timed(**limits)

    clearance = math.nan
    if model is None:
        _, trajectory = attempt(None)
    else:
        from ..core.branches import first_clear, start_branches
        T_start = req.start
        pose_start = T_start is not None and req.start_joints is None

        def branches(first: Any) -> list[np.ndarray]:  # noqa: ANN401
            assert T_start is not None
            return start_branches(planner, T_start, first.q_start, req.tolerance)

        _, trajectory, found, _ = first_clear(attempt, model, branches if pose_start else None)
        clearance = float(found.min_clearance)
    duration = float(trajectory.duration)
    points = sample_count(duration, context.sample_period)
    if points > MAX_POINTS:
        raise PlanningFailedError(
            f'the trajectory would have {points:.0f} points ({duration:.3g} s every {context.sample_period:g} s), '
            f'more than {MAX_POINTS}: increase the sample period')
    t, q, dq, ddq = trajectory.sample(context.sample_period, check=True)
    return {'index': index, 'id': ident, 'status': int(PlanCode.SUCCESS), 'message': '', 'fraction': 1.0,
            'planning_time': math.nan, 'duration': duration, 'min_clearance': clearance,
            'robot': req.robot.name, 'joint_names': list(req.robot.joint_names), 'times': np.asarray(t, float),
            'positions': np.asarray(q, float), 'velocities': np.asarray(dq, float),
            'accelerations': np.asarray(ddq, float)}


def _factor(data: Mapping[str, Any], key: str) -> float:
    raw = data.get(key)
    if raw is None:
        return 1.0
    value = _fraction_or_number(raw, key)
    if not 0.0 < value <= 1.0:
        raise RequestError(f'request: {key} must be in (0, 1], got {raw!r}')
    return value
