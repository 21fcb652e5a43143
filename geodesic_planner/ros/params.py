"""The parameter schema of both nodes: one table of names, types, defaults and checks.

Each node declares the subset it uses (:func:`declare`) and validates changes with
:func:`rejection` in its on-set-parameters callback, so a parameter the two nodes share
(``sample_period``, ``velocity_scaling``) has one default, one description and one rule. Checks
that need more than one value (a limit array against the robot's joint count, a loadable model)
belong to the planner's configuration (:func:`geodesic_planner.ros.planning.build_config`).

Rejection reasons read ``<name>: <problem>``, e.g. ``velocity_scaling: must be in (0, 1], got
1.5``.

A name the node does not have (``-p colision_check:=false``, a typo in a ``--params-file``) is
never silently ignored: both nodes are :class:`SchemaNode` s, which know the names of their
overrides, and :func:`check_unknown` warns about each override the node has no parameter for,
naming the closest one ("unknown parameter 'colision_check' (did you mean 'collision_check'?)"),
and refuses an unknown name at run time with the same reason (the ``set_parameters`` result, or
:class:`UnknownParameterError` from ``node.set_parameters``).
"""
from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import ParameterNotDeclaredException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.time_source import USE_SIM_TIME_NAME
from rclpy.type_description_service import START_TYPE_DESCRIPTION_SERVICE_PARAM

from ..io.storages import STORAGES
from ..timing.resample import MAX_POINTS

#: Robot used when neither ``robot`` nor ``robot_description`` is given: the paper's planar 3R arm.
DEFAULT_ROBOT = 'planar_3r'
METRICS = ('paper', 'position')
DEFAULT_INPUT_TOPIC = '/geodesic_planner/joint_trajectory'
DEFAULT_OUTPUT_TOPIC = '~/joint_trajectory'

STRING, DOUBLE, DOUBLES, STRINGS = 'string', 'double', 'double array', 'string array'
INTEGER = 'integer'
BOOL = 'bool'
#: Default largest number of points of one processed trajectory (1000 s at 0.01 s).
DEFAULT_MAX_OUTPUT_POINTS = MAX_POINTS

#: A check returns the problem with a value (without the parameter name), or None if it is fine.
Check = Callable[[object], 'str | None']


@dataclass(frozen=True)
class ParamSpec:
    """One parameter.

    Attributes:
        name: parameter name.
        kind: STRING, INTEGER, DOUBLE, DOUBLES or STRINGS (shown by ``ros2 param describe``).
        default: value when not overridden (None: the node computes it at start).
        description: what it means, with units.
        constraints: the accepted values, in words.
        check: per-value check (None: any value of the kind).
        read_only: fixed at start.
    """

    name: str
    kind: str
    default: Any
    description: str
    constraints: str = ''
    check: Check | None = None
    read_only: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """Descriptor for ``declare_parameter``.

        Numbers and arrays use dynamic typing so that the check, not rclpy, decides: an integer
        is a valid double, and an empty array of any element type means "defaults".
        """
        return ParameterDescriptor(
            description=self.description, read_only=self.read_only,
            additional_constraints=f'{self.kind}; {self.constraints}'.rstrip('; '),
            dynamic_typing=self.kind != STRING)


# --------------------------------------------------------------------------- value checks

def _not_number(value: object) -> bool:
    return isinstance(value, bool) or not isinstance(value, (int, float))


def positive(value: object) -> str | None:
    """Finite and > 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if not (math.isfinite(float(value)) and float(value) > 0.0):
        return f'must be finite and > 0, got {value!r}'
    return None


def in_range(lo: float, hi: float) -> Check:
    """Finite and in [lo, hi]: the values with which the node was checked to work."""
    def check(value: object) -> str | None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return f'must be a number, got {value!r}'
        if not (math.isfinite(float(value)) and lo <= float(value) <= hi):
            return f'must be in [{lo:g}, {hi:g}], got {value!r}'
        return None
    return check


def non_negative(value: object) -> str | None:
    """Finite and >= 0."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if not (math.isfinite(float(value)) and float(value) >= 0.0):
        return f'must be finite and >= 0, got {value!r}'
    return None


def unit_interval(value: object) -> str | None:
    """In (0, 1]."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f'must be a number, got {value!r}'
    if not (0.0 < float(value) <= 1.0):
        return f'must be in (0, 1], got {value!r}'
    return None


def positive_integer(value: object) -> str | None:
    """An integer > 0 (a double is refused, even an integral one)."""
    if isinstance(value, bool) or not isinstance(value, int):
        return f'must be an integer, got {value!r}'
    if value <= 0:
        return f'must be > 0, got {value!r}'
    return None


def integer_in(lo: int, hi: int) -> Check:
    """An integer in [lo, hi] (a double is refused, even an integral one)."""
    def check(value: object) -> str | None:
        if isinstance(value, bool) or not isinstance(value, int):
            return f'must be an integer, got {value!r}'
        if not lo <= value <= hi:
            return f'must be in [{lo}, {hi}], got {value!r}'
        return None
    return check


def one_of(choices: Sequence[str]) -> Check:
    """One of ``choices``."""
    def check(value: object) -> str | None:
        if value not in choices:
            return f'must be one of {", ".join(choices)}, got {value!r}'
        return None
    return check


def boolean(value: object) -> str | None:
    """True or false."""
    if not isinstance(value, bool):
        return f'must be true or false, got {value!r}'
    return None


def non_empty(value: object) -> str | None:
    """A non-empty string."""
    if not isinstance(value, str) or not value:
        return f'must be a non-empty topic name, got {value!r}'
    return None


def _array(value: object) -> list[Any] | None:
    if value is None:
        return []
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        return None
    return list(value)


def positive_array(value: object) -> str | None:
    """An array of finite numbers > 0 (empty allowed)."""
    vals = _array(value)
    if vals is None or any(_not_number(v) for v in vals):
        return f'expected an array of numbers, got {value!r}'
    if not all(math.isfinite(float(v)) and float(v) > 0.0 for v in vals):
        return f'every value must be finite and > 0, got {[float(v) for v in vals]}'
    return None


def finite_array(value: object) -> str | None:
    """An array of finite numbers (empty allowed)."""
    vals = _array(value)
    if vals is None or any(_not_number(v) for v in vals):
        return f'expected an array of numbers, got {value!r}'
    if not all(math.isfinite(float(v)) for v in vals):
        return f'every value must be finite, got {[float(v) for v in vals]}'
    return None


def string_array(value: object) -> str | None:
    """An array of strings (empty allowed)."""
    vals = _array(value)
    if vals is None or not all(isinstance(v, str) for v in vals):
        return f'expected an array of strings, got {value!r}'
    return None


def topic_list(value: object) -> str | None:
    """A list of topic entries (``name`` or ``name=pkg/msg/Type``)."""
    vals = _array(value)
    if vals is None or not all(isinstance(v, str) and v.strip(':') for v in vals):
        return f'must be a list of topic names, got {value!r}'
    return None


# --------------------------------------------------------------------------- the table

_SPECS = (
    # planner: robot model and metric
    ParamSpec('robot', STRING, DEFAULT_ROBOT,
              'Robot model: a preset name (planar_3r, rrpp, ur5e, panda) or a path to a .urdf file; '
              'empty: the URDF published on /robot_description (std_msgs/String, transient local, '
              'as robot_state_publisher publishes it). Ignored when robot_description is not empty.'),
    ParamSpec('robot_description', STRING, '',
              'URDF XML string (as robot_state_publisher publishes it); takes precedence over '
              'robot when not empty.'),
    ParamSpec('base_link', STRING, '', 'Base link of the chain in the URDF (empty: the URDF root).'),
    ParamSpec('tip_link', STRING, '', 'Tool link of the chain in the URDF (empty: the only leaf).'),
    ParamSpec('joint_names', STRINGS, [],
              'Joint names used on /joint_states and in published trajectories, in chain order '
              '(empty: the model names).', 'empty or one unique name per joint', string_array),
    ParamSpec('metric', STRING, 'paper',
              "Riemannian metric: 'paper' (position + orientation, Chen et al. 2016) or 'position'.",
              "'paper' or 'position'", one_of(METRICS)),
    ParamSpec('position_weight', DOUBLE, 1.0, 'Weight of the position term of the metric.',
              'in [0.001, 1000]; orientation_weight / position_weight in [0.001, 100]',
              in_range(1e-3, 1e3)),
    ParamSpec('orientation_weight', DOUBLE, 1.0,
              'Weight of the orientation term of the metric (a length, m: the lever arm at which a '
              'rotation counts like a translation).',
              'in [0.001, 1000]; orientation_weight / position_weight in [0.001, 100]',
              in_range(1e-3, 1e3)),
    # planner: limits and outputs
    ParamSpec('max_velocity', DOUBLES, [],
              'Joint velocity limits, rad/s or m/s (empty: URDF/robot defaults; one value: all '
              'joints).', 'empty, 1 or dof values, each finite and > 0', positive_array),
    ParamSpec('max_acceleration', DOUBLES, [],
              'Joint acceleration limits, rad/s^2 or m/s^2 (empty: robot defaults; one value: all '
              'joints).', 'empty, 1 or dof values, each finite and > 0', positive_array),
    ParamSpec('max_jerk', DOUBLES, [],
              'Joint jerk limits, rad/s^3 or m/s^3 (one value: all joints; empty: from joint_limits '
              'when it gives one for every joint, else no jerk limit). A jerk-limited plan takes '
              '25-100 ms more to time.', 'empty, 1 or dof values, each finite and > 0',
              positive_array),
    ParamSpec('joint_limits', STRING, '',
              'Path to a MoveIt-style joint_limits.yaml (has_velocity_limits, max_velocity, '
              'has_acceleration_limits, max_acceleration, has_jerk_limits, max_jerk per joint); it '
              'may lower the model\'s velocity limits and sets acceleration limits; max_velocity '
              'and max_acceleration, when given, override it. Empty: none.'),
    ParamSpec('max_tool_speed', DOUBLE, 0.0,
              'Largest linear speed of the tool frame origin, m/s (0: no limit).', 'finite, >= 0',
              non_negative),
    ParamSpec('max_tool_angular_speed', DOUBLE, 0.0,
              'Largest angular speed of the tool, rad/s (0: no limit).', 'finite, >= 0',
              non_negative),
    ParamSpec('allowed_start_tolerance', DOUBLE, 0.01,
              'Largest difference between a plan\'s first point and the current joint state, per '
              'joint, rad (m for prismatic joints); a plan beyond it is refused with '
              'START_STATE_MISMATCH (0: no check; no check either before a joint state arrives).',
              'finite, >= 0', non_negative),
    # planner: collisions
    ParamSpec('collision_check', BOOL, True,
              "Check every plan against the robot's own links and the scene (start, goal and the "
              'whole motion between its points); a collision is refused with '
              'START_STATE_IN_COLLISION, GOAL_IN_COLLISION or INVALID_MOTION_PLAN.', 'true or false',
              boolean),
    ParamSpec('collision_padding', DOUBLE, 0.01,
              'Clearance every checked pair of bodies keeps, m.', 'in [0, 1]', in_range(0.0, 1.0)),
    ParamSpec('link_radius', DOUBLE, 0.05,
              'Radius of the capsules along the links of a model without <collision> geometry '
              '(the presets), m.', 'in [0.0001, 1]', in_range(1e-4, 1.0)),
    ParamSpec('exact_meshes', BOOL, False,
              "Check meshes' triangles instead of their convex hulls (about 100x slower; hulls are "
              'conservative).', 'true or false', boolean),
    ParamSpec('srdf', STRING, '',
              "Path to an SRDF (a MoveIt configuration's); its <disable_collisions> pairs are not "
              'checked. Empty: none.'),
    ParamSpec('package_dirs', STRINGS, [],
              'Directories holding the packages that package:// mesh URIs name (DIR/PKG/...); the '
              "ament index (AMENT_PREFIX_PATH's share directories) is searched after them.", '',
              string_array),
    ParamSpec('scene', STRING, '',
              'Path to a scene YAML (objects with id, type and dimensions or mesh, pose; docs/usage.md); '
              'the scene services change it at run time. Empty: no objects.'),
    ParamSpec('ptp_around_obstacles', BOOL, True,
              'A PTP item of ~/plan_sequence whose path collides goes around the obstacles (OMPL '
              'RRTConnect, then the least-kinetic-energy path that keeps collision_padding; a pose '
              'goal tries its IK branches); false: it is refused (INVALID_MOTION_PLAN). LIN and CIRC '
              'never detour. Needs collision_check.', 'true or false', boolean),
    ParamSpec('ptp_planning_timeout', DOUBLE, 1.0,
              'Budget of the search around obstacles per PTP item, s; past it PLANNING_FAILED '
              '("no collision-free path found in T s").', 'in [0.001, 60]', in_range(1e-3, 60.0)),
    # planner: point clouds (ros/sensor_maps.py)
    ParamSpec('point_cloud_topics', STRINGS, [],
              'sensor_msgs/PointCloud2 topics whose clouds become occupancy octrees in the collision scene, one '
              'map per topic (each cloud replaces its topic\'s map; the pair is named after the topic). Empty: '
              'none. Fixed at start.', 'topic names', string_array, read_only=True),
    ParamSpec('point_cloud_frames', STRINGS, [],
              'The frame of each sensor of point_cloud_topics (in order): a cloud is used when its frame_id is '
              'this frame or the base frame, else refused with a warning (no TF). Fixed at start.',
              'one per topic', string_array, read_only=True),
    ParamSpec('point_cloud_poses', DOUBLES, [],
              'Each sensor frame\'s pose in the base frame, 7 values per topic of point_cloud_topics: x y z '
              '(m) qx qy qz qw (unit quaternion). Fixed at start.', '7 per topic', finite_array, read_only=True),
    ParamSpec('octree_resolution', DOUBLE, 0.02, 'Voxel side of the point clouds\' occupancy octrees, m.',
              'in [0.001, 1]', in_range(1e-3, 1.0)),
    ParamSpec('self_filter_padding', DOUBLE, 0.03,
              "Points inside the robot's collision bodies grown by this much (at the latest /joint_states) "
              'are removed from every cloud, m.', 'in [0, 0.5]', in_range(0.0, 0.5)),
    ParamSpec('max_cloud_points', INTEGER, 1_000_000,
              'Largest cloud (width x height) accepted; larger ones are refused with a warning.',
              'integer in [1, 100000000]', integer_in(1, 100_000_000)),
    ParamSpec('max_cloud_rate', DOUBLE, 10.0,
              "Most clouds used per second and sensor, Hz; the others are skipped.", 'in [0.001, 1000]',
              in_range(1e-3, 1e3)),
    ParamSpec('max_cloud_age', DOUBLE, 1.0,
              'With point_cloud_topics, every sensor needs a cloud younger than this (time of arrival), s: '
              'else plans are refused (PLANNING_FAILED), or planned with a warning (stale_clouds warn).',
              'in [0.001, 86400]', in_range(1e-3, 86400.0)),
    ParamSpec('stale_clouds', STRING, 'refuse',
              "What a plan does when a sensor's map is older than max_cloud_age: 'refuse' it, or 'warn' "
              '(planned against the maps there are, the warning in the log and the reply).', "'refuse' or 'warn'",
              one_of(('refuse', 'warn'))),
    # both nodes
    ParamSpec('velocity_scaling', DOUBLE, 1.0,
              'Time scaling factor f: durations / f, velocities * f, accelerations * f^2.',
              'in (0, 1]', unit_interval),
    ParamSpec('sample_period', DOUBLE, 0.01, 'Time between trajectory points, s.',
              'in [1e-05, 10]', in_range(1e-5, 10.0)),
    # planner
    ParamSpec('frame_id', STRING, '', 'Base frame of requests and outputs (empty: the model base link).'),
    ParamSpec('max_queued_requests', INTEGER, 32,
              'Plan requests (both services) that may wait or plan at once; a request beyond them '
              'is refused at once (PLANNING_FAILED, "planner overloaded"), counted on /diagnostics '
              'and in a rate-limited warning. Fixed at start.', 'integer in [1, 1000]',
              integer_in(1, 1000), read_only=True),
    ParamSpec('plan_timeout', DOUBLE, 5.0,
              'Longest time a request waits for its plan, s (late plans fail).', 'in [1e-06, 3600]',
              in_range(1e-6, 3600.0)),
    # processor (fixed at start)
    ParamSpec('input_topic', STRING, DEFAULT_INPUT_TOPIC,
              'JointTrajectory topic to process (reliable, keep_all).', 'non-empty', non_empty,
              read_only=True),
    ParamSpec('output_topic', STRING, DEFAULT_OUTPUT_TOPIC,
              'Where the processed JointTrajectory is published (remap to a controller).',
              'non-empty', non_empty, read_only=True),
    ParamSpec('max_output_points', INTEGER, DEFAULT_MAX_OUTPUT_POINTS,
              'Largest processed trajectory, in points; a longer output (or one of more than '
              '16 * max_output_points joint values per field, for arms of more than 16 joints) is '
              'refused with a reason and not published.', 'integer, > 0', positive_integer),
    ParamSpec('bag_path', STRING, '',
              'New bag directory for this run (existing non-empty: a timestamped one inside or next '
              'to it); empty disables recording.', read_only=True),
    ParamSpec('storage', STRING, 'mcap', 'Bag storage: mcap or sqlite3.', ', '.join(STORAGES),
              one_of(STORAGES), read_only=True),
    ParamSpec('record_topics', STRINGS, None,
              'Topics to record ("name", or "name=pkg/msg/Type" / "name:pkg/msg/Type" to give the '
              'type); default: input, output, /joint_states.', '', topic_list, read_only=True),
)

#: Every parameter of either node, by name.
SCHEMA: dict[str, ParamSpec] = {spec.name: spec for spec in _SPECS}

PLANNER_PARAMETERS = ('robot', 'robot_description', 'base_link', 'tip_link', 'joint_names',
                      'metric', 'position_weight', 'orientation_weight', 'max_velocity',
                      'max_acceleration', 'max_jerk', 'joint_limits', 'max_tool_speed',
                      'max_tool_angular_speed', 'allowed_start_tolerance', 'velocity_scaling',
                      'sample_period', 'frame_id', 'plan_timeout', 'max_queued_requests',
                      'collision_check', 'collision_padding', 'link_radius', 'exact_meshes', 'srdf',
                      'package_dirs', 'scene', 'ptp_around_obstacles', 'ptp_planning_timeout',
                      'point_cloud_topics', 'point_cloud_frames', 'point_cloud_poses', 'octree_resolution',
                      'self_filter_padding', 'max_cloud_points', 'max_cloud_rate', 'max_cloud_age', 'stale_clouds')
PROCESSOR_PARAMETERS = ('input_topic', 'output_topic', 'sample_period', 'velocity_scaling',
                        'max_output_points', 'bag_path', 'storage', 'record_topics')


def defaults(names: Iterable[str]) -> dict[str, Any]:
    """Default values of ``names``."""
    return {name: SCHEMA[name].default for name in names}


def problem(name: str, value: object) -> str | None:
    """Why ``value`` is not acceptable for ``name`` (``<name>: <problem>``), or None."""
    spec = SCHEMA.get(name)
    if spec is None or spec.check is None:
        return None
    found = spec.check(value)
    return None if found is None else f'{name}: {found}'


def rejection(params: Iterable[Parameter], names: Iterable[str]) -> str | None:
    """Reason to reject a parameter update (the first problem among ``names``), or None.

    Args:
        params: the changed parameters.
        names: the parameters the node owns (others are left to rclpy).
    """
    owned = set(names)
    for p in params:
        if p.name not in owned:
            continue
        if p.type_ == Parameter.Type.NOT_SET:
            return f'{p.name}: cannot be undeclared'
        reason = problem(p.name, p.value)
        if reason is not None:
            return reason
    return None


def declare(node: Node, names: Iterable[str], overrides: dict[str, Any] | None = None) -> None:
    """Declare ``names`` on ``node`` from the schema.

    Args:
        node: the node.
        names: parameter names, in declaration order.
        overrides: defaults computed by the node (e.g. from resolved topic names).
    """
    for name in names:
        spec = SCHEMA[name]
        default = (overrides or {}).get(name, spec.default)
        node.declare_parameter(name, default, spec.descriptor())


# --------------------------------------------------------------------------- unknown names

#: Parameters rclpy declares on every node itself.
RCLPY_PARAMETERS = (USE_SIM_TIME_NAME, START_TYPE_DESCRIPTION_SERVICE_PARAM)
#: The nodes' names and parameters (to tell a user that a name belongs to the other node).
NODE_PARAMETERS = {'geodesic_planner': PLANNER_PARAMETERS, 'trajectory_processor': PROCESSOR_PARAMETERS}


class SchemaNode(Node):
    """A node that knows the names of its parameter overrides; the base of both nodes.

    The overrides are what rcl resolved for this node from ``-p``, ``--params-file`` (the node's
    own sections and ``/**``) and ``parameter_overrides``. rclpy 7.1 has no getter for them; its
    public way to show them is ``automatically_declare_parameters_from_overrides``, which hands
    them all to ``declare_parameters`` during ``Node.__init__`` (with ``ignore_override=True``,
    before any other declaration). Declaring them that way fails on an empty array (type
    NOT_SET, e.g. ``package_dirs: []`` of config/geodesic_planner.yaml: ValueError), so this
    class keeps the names of that one call (:attr:`override_names`) and declares none of them:
    :func:`declare` declares the schema's own with their descriptors and checks, as before, and
    :func:`check_unknown` warns about the others.
    """

    def __init__(self, node_name: str, **kwargs: Any) -> None:  # noqa: ANN401 rclpy Node options, passed through
        self.override_names: tuple[str, ...] = ()
        self._taking_overrides = True
        super().__init__(node_name, **{**kwargs, 'automatically_declare_parameters_from_overrides': True,
                                       'allow_undeclared_parameters': False})
        self._taking_overrides = False

    def declare_parameters(self, namespace: str, parameters: list[Any],
                           ignore_override: bool = False) -> list[Parameter]:
        """``Node.declare_parameters``, except for the automatic declaration of the overrides."""
        if self._taking_overrides and ignore_override:
            self._taking_overrides = False
            self.override_names = tuple(namespace + p[0] for p in parameters)
            return []
        return super().declare_parameters(namespace, parameters, ignore_override)


class UnknownParameterError(ParameterNotDeclaredException):
    """A parameter the node does not have; ``str()`` is the reason, with the closest name.

    A ParameterNotDeclaredException (what rclpy raises for an undeclared name), so that rclpy's
    parameter services answer with ``str(error)`` as the reason.
    """

    def __init__(self, reason: str, name: str) -> None:
        super().__init__([name])
        self.reason = reason

    def __str__(self) -> str:
        return self.reason


def closest(name: str, names: Iterable[str]) -> str | None:
    """The name of ``names`` most like ``name`` (case and ``-``/``_`` aside), or None if none is close."""
    def key(n: str) -> str:
        return n.lower().replace('-', '_')
    by_key = {key(n): n for n in names}
    found = difflib.get_close_matches(key(name), list(by_key), n=1, cutoff=0.6)
    return by_key[found[0]] if found else None


def unknown_reason(name: str, names: Sequence[str]) -> str:
    """Why ``name`` is not a parameter of the node that has ``names``, naming the closest one.

    E.g. ``unknown parameter 'colision_check' (did you mean 'collision_check'?)``.
    """
    owners = [node for node, owned in NODE_PARAMETERS.items() if name in owned]
    if owners:
        return f'unknown parameter {name!r} (a parameter of the {owners[0]} node, not of this one)'
    near = closest(name, names)
    if near is not None:
        return f'unknown parameter {name!r} (did you mean {near!r}?)'
    return f'unknown parameter {name!r} (this node has: {", ".join(sorted(names))})'


def _shown(value: object) -> str:
    """A parameter value as a user writes it after ``-p name:=``."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, (Sequence, np.ndarray)):
        return f'[{", ".join(_shown(v) for v in value)}]'
    return repr(value)


def check_unknown(node: SchemaNode, names: Sequence[str]) -> list[str]:
    """Warn about every override that is not one of ``names``; refuse unknown names from now on.

    Call it once, in the node's ``__init__`` after declaring (before it spins). Each override
    that is neither in ``names`` nor one of rclpy's own (:data:`RCLPY_PARAMETERS`) gets one
    warning line: ``<reason>: ignored`` (:func:`unknown_reason`), with the value in force of the
    parameter it resembles. From then on a ``set_parameters`` call with a name the node has not
    declared is refused with :func:`unknown_reason` (a pre-set callback: it runs before
    rclpy's own check, whose reason names no parameter).

    Returns:
        The warnings logged, in name order.
    """
    logged = []
    for name in sorted(set(node.override_names) - set(names) - set(RCLPY_PARAMETERS)):
        reason = unknown_reason(name, names) + ': ignored'
        near = closest(name, names)
        if 'did you mean' in reason and near is not None and node.has_parameter(near):
            reason += f'; {near} is {_shown(node.get_parameter(near).value)}'
        node.get_logger().warning(reason)
        logged.append(reason)

    def refuse_unknown(changes: list[Parameter]) -> list[Parameter]:
        for p in changes:
            if not node.has_parameter(p.name):
                raise UnknownParameterError(unknown_reason(p.name, names), p.name)
        return changes

    node.add_pre_set_parameters_callback(refuse_unknown)
    return logged
