"""Launch the planner and the trajectory processor, parameters from config/*.yaml.

Usage::

    ros2 launch geodesic_planner geodesic_planner.launch.py
    ros2 launch geodesic_planner geodesic_planner.launch.py namespace:=robot1 joint_limits:=/path/to/limits.yaml

Arguments (``ros2 launch ... --show-args``): ``namespace``, ``planner_config``,
``processor_config`` (parameter files; default: this package's config/), ``joint_limits``.

Several robots side by side: one launch per namespace. Each pair then talks only within its
namespace: the processor's ``input_topic`` (config/trajectory_processor.yaml) is relative, so it
resolves to ``<namespace>/geodesic_planner/joint_trajectory``, and ``/joint_states`` (and
``/robot_description``) are remapped to the namespace's own topics, where a namespaced
joint_state_broadcaster and robot_state_publisher publish them. ``/diagnostics`` stays global,
as in ROS convention; the statuses carry each node's full name.

The description is plain data (:func:`describe`), so this file imports without ``launch`` and
``launch_ros`` (not on PyPI): the tests load it as a module, inspect it, and run the nodes it
describes with the arguments :meth:`NodeSpec.ros_arguments` gives. Only
:func:`generate_launch_description`, which ``ros2 launch`` calls, imports them.
"""
# No `from __future__ import annotations`: ros2 launch executes this file as a module that is not
# in sys.modules, where dataclasses cannot resolve string annotations.
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

PACKAGE = 'geodesic_planner'
#: config/ beside launch/: in the source tree and in the install space (share/geodesic_planner/).
CONFIG_DIR = Path(__file__).resolve().parent.parent / 'config'
PLANNER_CONFIG = CONFIG_DIR / 'geodesic_planner.yaml'
PROCESSOR_CONFIG = CONFIG_DIR / 'trajectory_processor.yaml'
#: Topics the nodes name absolutely that belong to one robot: remapped into the node's namespace
#: (a relative replacement resolves in the node's namespace; without a namespace nothing changes).
ROBOT_TOPICS = ('/joint_states', '/robot_description')

#: Launch arguments: name -> (default, description).
ARGUMENTS: dict[str, tuple[str, str]] = {
    'namespace': ('', 'Namespace of both nodes, e.g. robot1 (empty: none).'),
    'planner_config': (str(PLANNER_CONFIG), 'Parameter file of the geodesic_planner node.'),
    'processor_config': (str(PROCESSOR_CONFIG), 'Parameter file of the trajectory_processor node.'),
    'joint_limits': ('', "MoveIt-style joint_limits.yaml for the planner (empty: the config file's)."),
}

_NAMESPACE = re.compile(r'^(/[A-Za-z_][A-Za-z0-9_]*)*$')


@dataclass(frozen=True)
class NodeSpec:
    """One node to start, as launch_ros.actions.Node takes it.

    Attributes:
        package: ROS package of the executable.
        executable: console script (installed in ``lib/<package>``).
        name: node name.
        namespace: absolute namespace, or '' for none.
        parameter_files: parameter files, in the order they are applied (later ones win).
        parameters: single parameters set after the files.
        remappings: (from, to) topic remappings.
    """

    package: str
    executable: str
    name: str
    namespace: str
    parameter_files: tuple[str, ...]
    parameters: tuple[tuple[str, str], ...] = ()
    remappings: tuple[tuple[str, str], ...] = ()

    @property
    def full_name(self) -> str:
        """Fully qualified node name, e.g. ``/robot1/geodesic_planner``."""
        return f'{self.namespace}/{self.name}'

    def ros_arguments(self) -> list[str]:
        """The arguments after ``--ros-args`` that start this node as launch_ros does."""
        args = ['-r', f'__node:={self.name}']
        if self.namespace:
            args += ['-r', f'__ns:={self.namespace}']
        for path in self.parameter_files:
            args += ['--params-file', path]
        for key, value in self.parameters:
            args += ['-p', f'{key}:={value}']
        for old, new in self.remappings:
            args += ['-r', f'{old}:={new}']
        return args


def normalize_namespace(namespace: str) -> str:
    """``'robot1'``, ``'/robot1/'`` -> ``'/robot1'``; ``''`` and ``'/'`` -> ``''``.

    Raises:
        ValueError: not a valid ROS namespace (tokens of letters, digits and underscores, not
            starting with a digit).
    """
    ns = '/' + namespace.strip().strip('/') if namespace.strip().strip('/') else ''
    if not _NAMESPACE.match(ns):
        msg = f'namespace: {namespace!r} is not a valid ROS namespace'
        raise ValueError(msg)
    return ns


def describe(namespace: str = '', planner_config: str = str(PLANNER_CONFIG),
             processor_config: str = str(PROCESSOR_CONFIG), joint_limits: str = '') -> list[NodeSpec]:
    """The two nodes of one robot, in one namespace.

    Args:
        namespace: namespace of both nodes ('' for none; made absolute).
        planner_config: parameter file of the planner.
        processor_config: parameter file of the processor.
        joint_limits: path of a joint_limits.yaml for the planner ('' keeps the config file's).

    Returns:
        [planner, processor].

    Raises:
        ValueError: invalid namespace.
    """
    ns = normalize_namespace(namespace)
    remap = tuple((topic, topic.lstrip('/')) for topic in ROBOT_TOPICS)
    planner_params = (('joint_limits', joint_limits),) if joint_limits else ()
    return [
        NodeSpec(PACKAGE, 'geodesic_planner_node', 'geodesic_planner', ns, (planner_config,),
                 planner_params, remap),
        NodeSpec(PACKAGE, 'trajectory_processor_node', 'trajectory_processor', ns, (processor_config,),
                 (), remap),
    ]


def generate_launch_description() -> Any:  # noqa: ANN401 launch.LaunchDescription, imported lazily
    """The launch description ``ros2 launch`` runs: the arguments, then :func:`describe`'s nodes."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    def nodes(context: Any) -> list[Any]:  # noqa: ANN401 launch.LaunchContext
        values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
        return [
            Node(package=spec.package, executable=spec.executable, name=spec.name,
                 namespace=spec.namespace or None,
                 parameters=[*spec.parameter_files, dict(spec.parameters)] if spec.parameters
                 else list(spec.parameter_files),
                 remappings=list(spec.remappings), output='screen')
            for spec in describe(**values)
        ]

    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=description)
          for name, (default, description) in ARGUMENTS.items()),
        OpaqueFunction(function=nodes),
    ])
