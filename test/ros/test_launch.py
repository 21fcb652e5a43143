"""launch/geodesic_planner.launch.py and config/*.yaml: what they describe, and the nodes running.

``launch`` and ``launch_ros`` are not on PyPI, so the launch file is loaded as a module (as
``ros2 launch`` loads it, without registering it in ``sys.modules``) and its plain-data
description is inspected; the ``ros`` tests then start the nodes it describes with the same
``--ros-args`` that launch_ros would pass, two namespaces side by side, and check on the ROS graph
and with real plans that each pair talks only to itself.
"""
from __future__ import annotations

import importlib.util
import re
import sys
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from package_util import console_scripts
import yaml

pytest.importorskip('rclpy')

from geometry_msgs.msg import PoseStamped
from nav_msgs.srv import GetPlan
from numpy.testing import assert_allclose, assert_array_equal
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from geodesic_planner.core.robots import load_robot
from geodesic_planner.io.joint_limits import apply_joint_limits, load_joint_limits
from geodesic_planner.ros import params
from tools.graph import Collector, StatusWatch, call_service, deliver, wait_discovered, wait_for_service
from tools.process import wait_until

ROOT = Path(__file__).resolve().parents[2]
LAUNCH_FILE = ROOT / 'launch' / 'geodesic_planner.launch.py'
CONFIG = ROOT / 'config'
DEADLINE = 60.0
#: s to wait for one plan to go through both nodes of a namespace before asking again
PROBE_TIMEOUT = 5.0
#: Values of the config files that differ from the schema's defaults on purpose: (file, key) -> why.
DELIBERATE = {
    ('trajectory_processor.yaml', 'input_topic'):
        'relative, so that it follows the planner into the namespace',
}
#: Parameters a config file leaves out on purpose, as a commented line (rcl cannot read an empty
#: array from a parameter file; record_topics' default is computed by the node).
COMMENTED = {'joint_names', 'max_velocity', 'max_acceleration', 'max_jerk', 'record_topics'}


def load_launch(path: Path = LAUNCH_FILE) -> types.ModuleType:
    """The launch file as a module, loaded the way ``ros2 launch`` loads it."""
    spec = importlib.util.spec_from_file_location('geodesic_planner_launch', path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def node_parameters(spec: Any) -> tuple[str, ...]:
    return {'geodesic_planner_node': params.PLANNER_PARAMETERS,
            'trajectory_processor_node': params.PROCESSOR_PARAMETERS}[spec.executable]


# =========================================================================== the description
def test_loads_without_launch_and_launch_ros(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in ('launch', 'launch.actions', 'launch.substitutions', 'launch_ros', 'launch_ros.actions'):
        monkeypatch.setitem(sys.modules, name, None)   # any import of them raises ImportError
    module = load_launch()
    assert len(module.describe()) == 2
    with pytest.raises(ImportError):
        module.generate_launch_description()


def test_describes_both_nodes_with_their_parameter_files() -> None:
    planner, processor = load_launch().describe()
    scripts = console_scripts()
    assert (planner.package, planner.executable, planner.name) == (
        'geodesic_planner', 'geodesic_planner_node', 'geodesic_planner')
    assert (processor.package, processor.executable, processor.name) == (
        'geodesic_planner', 'trajectory_processor_node', 'trajectory_processor')
    assert scripts[planner.executable] == 'geodesic_planner.ros.planner_node:main'
    assert scripts[processor.executable] == 'geodesic_planner.ros.processor_node:main'
    assert planner.namespace == processor.namespace == ''
    assert (planner.full_name, processor.full_name) == ('/geodesic_planner', '/trajectory_processor')
    assert [Path(p) for p in planner.parameter_files] == [CONFIG / 'geodesic_planner.yaml']
    assert [Path(p) for p in processor.parameter_files] == [CONFIG / 'trajectory_processor.yaml']
    assert planner.parameters == processor.parameters == ()
    for spec in (planner, processor):
        assert dict(spec.remappings) == {'/joint_states': 'joint_states', '/robot_description': 'robot_description'}
        assert spec.ros_arguments() == [
            '-r', f'__node:={spec.name}', '--params-file', spec.parameter_files[0],
            '-r', '/joint_states:=joint_states', '-r', '/robot_description:=robot_description']


@pytest.mark.parametrize('given, expected', [
    ('robot1', '/robot1'), ('/robot1', '/robot1'), ('/robot1/', '/robot1'), ('fleet/arm_2', '/fleet/arm_2'),
    ('', ''), ('/', ''),
])
def test_namespace_applied_to_both_nodes(given: str, expected: str) -> None:
    specs = load_launch().describe(namespace=given)
    assert [s.namespace for s in specs] == [expected, expected]
    assert [s.full_name for s in specs] == [f'{expected}/geodesic_planner', f'{expected}/trajectory_processor']
    for spec in specs:
        args = spec.ros_arguments()
        assert (f'__ns:={expected}' in args) == bool(expected)
        if expected:
            assert args[args.index(f'__ns:={expected}') - 1] == '-r'


@pytest.mark.parametrize('bad', ['1robot', 'robot 1', 'robot-1', 'a//b', '~/x'])
def test_invalid_namespace_rejected(bad: str) -> None:
    with pytest.raises(ValueError, match='not a valid ROS namespace'):
        load_launch().describe(namespace=bad)


def test_launch_arguments_reach_the_description(tmp_path: Path) -> None:
    module = load_launch()
    assert set(module.ARGUMENTS) == {'namespace', 'planner_config', 'processor_config', 'joint_limits'}
    defaults = {name: default for name, (default, _) in module.ARGUMENTS.items()}
    assert module.describe(**defaults) == module.describe()
    limits = str(CONFIG / 'joint_limits.yaml')
    mine = str(tmp_path / 'mine.yaml')
    planner, processor = module.describe('r', planner_config=mine, processor_config=mine, joint_limits=limits)
    assert planner.parameter_files == processor.parameter_files == (mine,)
    assert planner.parameters == (('joint_limits', limits),) and processor.parameters == ()
    args = planner.ros_arguments()
    assert args[args.index(f'joint_limits:={limits}') - 1] == '-p'
    assert args.index('--params-file') < args.index('-p')   # the argument wins over the file


def test_generate_launch_description_builds_the_described_nodes(monkeypatch: pytest.MonkeyPatch) -> None:
    """With stand-ins for launch/launch_ros (same call signatures): one declared argument per
    ARGUMENTS entry, and at launch time one Node per NodeSpec with its fields."""
    made: dict[str, list[Any]] = {'Node': [], 'DeclareLaunchArgument': []}

    def recorder(kind: str) -> Any:
        def make(*args: Any, **kwargs: Any) -> Any:
            made.setdefault(kind, []).append((args, kwargs))
            return (kind, args, kwargs)
        return make

    class LaunchConfiguration:
        def __init__(self, name: str) -> None:
            self.name = name

        def perform(self, context: Any) -> str:
            return context.launch_configurations[self.name]

    fake = {
        'launch': types.SimpleNamespace(LaunchDescription=list),
        'launch.actions': types.SimpleNamespace(DeclareLaunchArgument=recorder('DeclareLaunchArgument'),
                                                OpaqueFunction=lambda *, function: function),
        'launch.substitutions': types.SimpleNamespace(LaunchConfiguration=LaunchConfiguration),
        'launch_ros': types.SimpleNamespace(),
        'launch_ros.actions': types.SimpleNamespace(Node=recorder('Node')),
    }
    for name, module in fake.items():
        monkeypatch.setitem(sys.modules, name, module)
    module = load_launch()
    *declared, function = module.generate_launch_description()
    assert [(a[0], k['default_value'], k['description']) for a, k in made['DeclareLaunchArgument']] == [
        (name, default, description) for name, (default, description) in module.ARGUMENTS.items()]
    assert len(declared) == len(module.ARGUMENTS)

    values = {'namespace': 'robot7', 'planner_config': 'p.yaml', 'processor_config': 'q.yaml',
              'joint_limits': '/limits.yaml'}
    nodes = function(types.SimpleNamespace(launch_configurations=values))
    assert len(nodes) == 2
    for (args, kwargs), spec in zip(made['Node'], module.describe(**values), strict=True):
        assert args == ()
        assert kwargs == {
            'package': spec.package, 'executable': spec.executable, 'name': spec.name,
            'namespace': '/robot7',
            'parameters': [*spec.parameter_files, *([dict(spec.parameters)] if spec.parameters else [])],
            'remappings': list(spec.remappings), 'output': 'screen'}
    assert made['Node'][0][1]['parameters'] == ['p.yaml', {'joint_limits': '/limits.yaml'}]
    assert made['Node'][1][1]['parameters'] == ['q.yaml']


# =========================================================================== the config files
def ros_parameters(path: Path) -> dict[str, Any]:
    """The ``/**: ros__parameters:`` block of a parameter file (the only block there)."""
    data = yaml.safe_load(path.read_text())
    assert list(data) == ['/**'], f'{path.name}: expected one `/**:` block, got {list(data)}'
    assert list(data['/**']) == ['ros__parameters'], path.name
    return data['/**']['ros__parameters']


_KIND_TYPES = {params.STRING: (str,), params.DOUBLE: (float,), params.DOUBLES: (list,),
               params.STRINGS: (list,)}


@pytest.mark.parametrize('index', [0, 1], ids=['planner', 'processor'])
def test_config_keys_are_schema_parameters_with_valid_values(index: int) -> None:
    spec = load_launch().describe()[index]
    path = Path(spec.parameter_files[0])
    values = ros_parameters(path)
    owned = node_parameters(spec)
    for key, value in values.items():
        assert key in params.SCHEMA, (
            f'{path.name}: {key!r} is not a parameter of geodesic_planner.ros.params.SCHEMA')
        assert key in owned, f'{path.name}: {key!r} is not a parameter of the {spec.name} node ({owned})'
        problem = params.problem(key, value)
        assert problem is None, f'{path.name}: {problem}'
        kind = params.SCHEMA[key].kind
        if kind in _KIND_TYPES:   # doubles written as 1.0, not 1: rcl tells int from double
            assert isinstance(value, _KIND_TYPES[kind]), f'{path.name}: {key}: {value!r} is not a {kind}'
        why = DELIBERATE.get((path.name, key))
        if why is None:
            assert value == params.SCHEMA[key].default, f'{path.name}: {key}: {value!r} is not the default'
        else:
            assert value != params.SCHEMA[key].default, f'{path.name}: {key} now equals the default ({why})'


@pytest.mark.parametrize('index', [0, 1], ids=['planner', 'processor'])
def test_config_lists_every_parameter_of_its_node(index: int) -> None:
    """Each file documents every parameter of its node: set, or as a commented ``# name:`` line."""
    spec = load_launch().describe()[index]
    path = Path(spec.parameter_files[0])
    text = path.read_text()
    values = ros_parameters(path)
    commented = set(re.findall(r'^\s*#\s*([a-z_]+):', text, flags=re.MULTILINE))
    for name in node_parameters(spec):
        if name in COMMENTED:
            assert name in commented and name not in values, f'{path.name}: {name} should be a commented line'
        else:
            assert name in values, f'{path.name}: parameter {name!r} of {spec.name} is missing'


def test_new_parameters_have_the_agreed_defaults() -> None:
    """The parameters of issue 12 are in the files with the defaults the issue gives."""
    planner = ros_parameters(CONFIG / 'geodesic_planner.yaml')
    processor = ros_parameters(CONFIG / 'trajectory_processor.yaml')
    assert {k: planner[k] for k in ('allowed_start_tolerance', 'joint_limits', 'max_tool_speed',
                                     'max_tool_angular_speed')} == {
        'allowed_start_tolerance': 0.01, 'joint_limits': '', 'max_tool_speed': 0.0, 'max_tool_angular_speed': 0.0}
    assert processor['max_output_points'] == 100000
    assert processor['input_topic'] == 'geodesic_planner/joint_trajectory'


def test_joint_limits_example_loads_for_the_default_robot() -> None:
    path = CONFIG / 'joint_limits.yaml'
    raw = yaml.safe_load(path.read_text())['joint_limits']
    robot = load_robot(params.DEFAULT_ROBOT)
    assert list(raw) == robot.joint_names
    limited, notes = apply_joint_limits(robot, load_joint_limits(path))
    assert notes == []
    assert_array_equal(limited.max_velocity, [raw[n]['max_velocity'] for n in robot.joint_names])
    assert_array_equal(limited.max_acceleration, [raw[n]['max_acceleration'] for n in robot.joint_names])
    assert np.all(limited.max_velocity <= robot.max_velocity)
    assert limited.max_velocity[2] < limited.max_velocity[0]   # the example has a tighter joint


# =========================================================================== running the nodes
A_3R = (2.5, 1.5, np.radians(30.0))                      # paper Table 1: position and yaw of the tool
YAW = float(np.arctan2(0.7, 0.714))
#: goal (x, y) of attempt k per namespace; the two families never meet (robot1 y > 2.44 > robot2 y)
GOALS = {'/robot1': lambda k: (1.5, 2.495 - 0.001 * k), '/robot2': lambda k: (1.5, 2.395 - 0.001 * k)}
SPLIT_Y = 2.445


def _pose(x: float, y: float, psi: float) -> Any:
    msg = PoseStamped()
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation.z, msg.pose.orientation.w = np.sin(psi / 2), np.cos(psi / 2)
    return msg


def _end_xy(msg: Any) -> np.ndarray:
    """Tool position (m) of a planar 3R trajectory's last point (unit links, independent FK)."""
    c = np.cumsum(msg.points[-1].positions)
    return np.array([np.cos(c).sum(), np.sin(c).sum()])


def _endpoints(topic_info: list[Any]) -> set[tuple[str, str]]:
    return {(i.node_namespace, i.node_name) for i in topic_info}


@pytest.mark.ros
@pytest.mark.timeout(300)
def test_two_namespaces_side_by_side(start_node: Any, ros_node: Any, tmp_path: Path) -> None:
    """Both nodes of /robot1 and /robot2 started as the launch file describes; each planner
    feeds only its own processor, on the graph and with real plans."""
    module = load_launch()
    # robot2's planner gets a copy of the config with one value changed: the file is what counts
    planner_copy = tmp_path / 'planner_robot2.yaml'
    planner_copy.write_text((CONFIG / 'geodesic_planner.yaml').read_text().replace(
        'plan_timeout: 5.0', 'plan_timeout: 7.5'))
    specs = {'/robot1': module.describe('robot1'), '/robot2': module.describe('/robot2', str(planner_copy))}
    status = StatusWatch(ros_node)
    procs = {spec.full_name: start_node(spec.executable, *spec.ros_arguments(),
                                        name=spec.full_name.strip('/').replace('/', '_'))
             for pair in specs.values() for spec in pair}
    watch = list(procs.values())

    # 1. the graph: four nodes; each planner's topic has its planner and its processor only
    wanted = {(name, ns) for ns in specs for name in ('geodesic_planner', 'trajectory_processor')}
    wait_until(lambda: wanted <= set(ros_node.get_node_names_and_namespaces()), DEADLINE,
               what=f'nodes {sorted(wanted)} in the graph', watch=watch)
    for ns in specs:
        topic = f'{ns}/geodesic_planner/joint_trajectory'
        # (node names reach the graph after the endpoints: wait for the named ones, then compare)
        wait_until(lambda t=topic, n=ns: (n, 'trajectory_processor') in _endpoints(
            ros_node.get_subscriptions_info_by_topic(t)), DEADLINE, what=f'the processor on {topic}', watch=watch)
        wait_until(lambda t=topic, n=ns: (n, 'geodesic_planner') in _endpoints(
            ros_node.get_publishers_info_by_topic(t)), DEADLINE, what=f'the planner on {topic}', watch=watch)
        assert _endpoints(ros_node.get_publishers_info_by_topic(topic)) == {(ns, 'geodesic_planner')}
        assert _endpoints(ros_node.get_subscriptions_info_by_topic(topic)) == {(ns, 'trajectory_processor')}
        wait_until(lambda n=ns: ros_node.count_subscribers(f'{n}/joint_states') >= 1, DEADLINE,
                   what=f'the planner on {ns}/joint_states', watch=watch)
        # the processor's own view: exactly one publisher matched on its input
        status.wait(f'{ns}/trajectory_processor', 'input publishers matched', lambda v: v == '1', DEADLINE,
                    watch=watch)
    # none of the four uses the root topics (by endpoint owner, not by count: a node an earlier
    # test killed stays in the graph until its lease expires)
    ours = {(ns, name) for ns in specs for name in ('geodesic_planner', 'trajectory_processor')}
    for topic in ('/geodesic_planner/joint_trajectory', '/joint_states'):
        used = (_endpoints(ros_node.get_publishers_info_by_topic(topic))
                | _endpoints(ros_node.get_subscriptions_info_by_topic(topic)))
        assert not used & ours, (topic, used)

    # 2. the parameter files are in effect
    def parameter(node: str, name: str) -> Any:
        client = ros_node.create_client(GetParameters, f'{node}/get_parameters')
        try:
            value = call_service(client, GetParameters.Request(names=[name]), DEADLINE, watch=watch).values[0]
        finally:
            ros_node.destroy_client(client)
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=value)).value

    assert [parameter(f'{ns}/geodesic_planner', 'plan_timeout') for ns in specs] == [5.0, 7.5]
    assert [parameter(f'{ns}/trajectory_processor', 'input_topic') for ns in specs] == [
        'geodesic_planner/joint_trajectory'] * 2

    # 3. a plan asked for in one namespace comes out of that namespace's processor only
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    outs = {ns: Collector(ros_node, JointTrajectory, f'{ns}/trajectory_processor/joint_trajectory', qos)
            for ns in specs}
    clients = {ns: ros_node.create_client(GetPlan, f'{ns}/geodesic_planner/plan') for ns in specs}
    for ns in specs:
        wait_for_service(clients[ns], DEADLINE, watch=watch)
        wait_until(lambda n=ns: outs[n].subscription.get_publisher_count() > 0, DEADLINE,
                   what=f'{ns} processor output matched', watch=watch)
        wait_discovered(ros_node, f'{ns}/trajectory_processor', DEADLINE, watch=watch)

    def plan_in(ns: str, attempt: list[int]) -> Any:
        def action() -> Any:
            goal = GOALS[ns](attempt[0])
            attempt[0] += 1
            req = GetPlan.Request(start=_pose(*A_3R), goal=_pose(*goal, YAW))
            assert call_service(clients[ns], req, DEADLINE, watch=watch).plan.poses, f'{ns}: no plan to {goal}'
            return lambda msg: bool(np.allclose(_end_xy(msg), goal, atol=1e-6))
        return action

    attempts = {ns: [0] for ns in specs}
    for ns in ('/robot1', '/robot2', '/robot1', '/robot2'):   # each link proven, then once more each
        deliver(plan_in(ns, attempts[ns]), outs[ns], PROBE_TIMEOUT, DEADLINE,
                what=f'a plan through {ns}', watch=watch)
    for ns, out in outs.items():
        ends = np.array([_end_xy(m) for m in out.messages])
        assert len(ends) >= 2
        assert np.all(ends[:, 1] > SPLIT_Y) if ns == '/robot1' else np.all(ends[:, 1] < SPLIT_Y), (ns, ends)
        goals = np.array([GOALS[ns](k) for k in range(attempts[ns][0])])
        assert all(np.min(np.linalg.norm(goals - e, axis=1)) < 1e-6 for e in ends), (ns, ends)
    # every plan's first point is the start pose A in both namespaces (same robot, same config)
    c = np.cumsum(outs['/robot2'].messages[-1].points[0].positions)
    assert_allclose([np.cos(c).sum(), np.sin(c).sum()], A_3R[:2], atol=1e-6)

    for proc in watch:
        assert proc.stop() == 0, proc.log_tail()
