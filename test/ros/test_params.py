"""The parameter schema shared by both nodes; unknown names through real nodes (issue 37 #6).

A mistyped parameter (``-p colision_check:=false``, a typo in a ``--params-file``) is warned
about at start-up, naming the closest parameter of the node, and a ``set_parameters`` call with
an unknown name is refused with the same reason.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml

pytest.importorskip('rclpy')

from rcl_interfaces.msg import Log
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters, SetParametersAtomically
from rclpy.parameter import Parameter

from geodesic_planner.ros import params

from .launch import Collector, NodeProcess, call_service, rosout_collector, wait_until, warm_up_client

DEADLINE = 60.0


def test_both_nodes_declare_from_one_table() -> None:
    for name in params.PLANNER_PARAMETERS + params.PROCESSOR_PARAMETERS:
        spec = params.SCHEMA[name]
        assert spec.description, name
    shared = set(params.PLANNER_PARAMETERS) & set(params.PROCESSOR_PARAMETERS)
    assert shared == {'sample_period', 'velocity_scaling'}
    assert params.defaults(shared) == {'sample_period': 0.01, 'velocity_scaling': 1.0}


@pytest.mark.parametrize('name, value, reason', [
    ('velocity_scaling', 0.0, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', 1.5, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', math.nan, 'velocity_scaling: must be in (0, 1]'),
    ('velocity_scaling', 'fast', 'velocity_scaling: must be a number'),
    ('velocity_scaling', True, 'velocity_scaling: must be a number'),
    ('sample_period', -0.01, 'sample_period: must be in [1e-05, 10]'),
    ('sample_period', 5e-324, 'sample_period: must be in [1e-05, 10]'),
    ('plan_timeout', math.inf, 'plan_timeout: must be in [1e-06, 3600]'),
    ('plan_timeout', 1e300, 'plan_timeout: must be in [1e-06, 3600]'),
    ('orientation_weight', 1e300, 'orientation_weight: must be in [0.001, 1000]'),
    ('position_weight', 0.0, 'position_weight: must be in [0.001, 1000]'),
    ('max_tool_speed', -1.0, 'max_tool_speed: must be finite and >= 0'),
    ('allowed_start_tolerance', math.nan, 'allowed_start_tolerance: must be finite and >= 0'),
    ('metric', 'euclid', 'metric: must be one of paper, position'),
    ('storage', 'rosbag1', 'storage: must be one of mcap, sqlite3'),
    ('max_velocity', [1.0, -2.0], 'max_velocity: every value must be finite and > 0'),
    ('max_acceleration', ['a'], 'max_acceleration: expected an array of numbers'),
    ('joint_names', [1, 2], 'joint_names: expected an array of strings'),
    ('record_topics', [':'], 'record_topics: must be a list of topic names'),
    ('input_topic', '', 'input_topic: must be a non-empty topic name'),
])
def test_invalid_values_named(name: str, value: object, reason: str) -> None:
    found = params.problem(name, value)
    assert found is not None and found.startswith(reason), found


@pytest.mark.parametrize('name, value', [
    ('velocity_scaling', 1), ('velocity_scaling', 0.25), ('sample_period', 0.02),
    ('sample_period', 1e-5), ('plan_timeout', 3600), ('orientation_weight', 1000),
    ('max_tool_speed', 0.0), ('allowed_start_tolerance', 0),
    ('max_velocity', []), ('max_velocity', [1, 2.5]), ('joint_names', []), ('storage', 'sqlite3'),
    ('record_topics', ['/a', '/b=std_msgs/msg/String']), ('robot', 'anything'),
])
def test_valid_values_pass(name: str, value: object) -> None:
    assert params.problem(name, value) is None


def test_rejection_checks_only_owned_names() -> None:
    bad = Parameter('velocity_scaling', Parameter.Type.DOUBLE, 2.0)
    reason = params.rejection([bad], params.PROCESSOR_PARAMETERS)
    assert reason is not None and reason.startswith('velocity_scaling:')
    assert params.rejection([bad], ['sample_period']) is None
    unset = Parameter('sample_period')
    assert params.rejection([unset], ['sample_period']) == 'sample_period: cannot be undeclared'


def test_descriptors_type_numbers_dynamically() -> None:
    assert params.SCHEMA['velocity_scaling'].descriptor().dynamic_typing
    assert params.SCHEMA['max_velocity'].descriptor().dynamic_typing
    assert not params.SCHEMA['robot'].descriptor().dynamic_typing
    assert params.SCHEMA['bag_path'].descriptor().read_only


# =========================================================================== unknown names

@pytest.mark.parametrize('name, names, reason', [
    ('colision_check', params.PLANNER_PARAMETERS,
     "unknown parameter 'colision_check' (did you mean 'collision_check'?)"),
    ('Velocity-Scaling', params.PROCESSOR_PARAMETERS,
     "unknown parameter 'Velocity-Scaling' (did you mean 'velocity_scaling'?)"),
    ('sample_perod', params.PROCESSOR_PARAMETERS,
     "unknown parameter 'sample_perod' (did you mean 'sample_period'?)"),
    ('max_vel', params.PLANNER_PARAMETERS, "unknown parameter 'max_vel' (did you mean 'max_velocity'?)"),
    ('robot', params.PROCESSOR_PARAMETERS,
     "unknown parameter 'robot' (a parameter of the geodesic_planner node, not of this one)"),
    ('bag_path', params.PLANNER_PARAMETERS,
     "unknown parameter 'bag_path' (a parameter of the trajectory_processor node, not of this one)"),
])
def test_unknown_names_get_the_closest_parameter(name: str, names: tuple[str, ...], reason: str) -> None:
    assert params.unknown_reason(name, names) == reason


def test_unknown_name_far_from_every_parameter_lists_them() -> None:
    reason = params.unknown_reason('xyzzy', params.PROCESSOR_PARAMETERS)
    assert reason == ("unknown parameter 'xyzzy' (this node has: " + ', '.join(sorted(params.PROCESSOR_PARAMETERS))
                      + ')')


class ParameterClients:
    """The parameter services of a running node (through the session's helper node)."""

    def __init__(self, helper: Any, full_name: str, proc: NodeProcess) -> None:
        self.watch = [proc]
        self.set = helper.create_client(SetParameters, f'{full_name}/set_parameters')
        self.atomic = helper.create_client(SetParametersAtomically, f'{full_name}/set_parameters_atomically')
        self.get = helper.create_client(GetParameters, f'{full_name}/get_parameters')
        self.list = helper.create_client(ListParameters, f'{full_name}/list_parameters')
        for client, request in ((self.set, SetParameters.Request()), (self.atomic, SetParametersAtomically.Request()),
                                (self.get, GetParameters.Request()), (self.list, ListParameters.Request())):
            warm_up_client(client, request, DEADLINE, watch=self.watch)

    def set_one(self, name: str, value: Any) -> tuple[bool, str]:
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        result = call_service(self.set, req, DEADLINE, watch=self.watch).results[0]
        return result.successful, result.reason

    def set_atomically(self, **values: Any) -> tuple[bool, str]:
        req = SetParametersAtomically.Request(
            parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in values.items()])
        result = call_service(self.atomic, req, DEADLINE, watch=self.watch).result
        return result.successful, result.reason

    def value(self, name: str) -> Any:
        msg = call_service(self.get, GetParameters.Request(names=[name]), DEADLINE, watch=self.watch).values[0]
        return Parameter.from_parameter_msg(ParameterMsg(name=name, value=msg)).value

    def names(self) -> list[str]:
        return list(call_service(self.list, ListParameters.Request(), DEADLINE, watch=self.watch).result.names)


def _warnings(rosout: Collector, logger: str, proc: NodeProcess, n: int) -> list[str]:
    """The first ``n`` warnings of ``logger`` that name an unknown parameter, once they arrived."""
    def found() -> list[str]:
        return [m.msg for m in list(rosout.messages) if m.name == logger and m.level == Log.WARN
                and 'unknown parameter' in m.msg]
    wait_until(lambda: len(found()) >= n, DEADLINE, what=f'{n} unknown-parameter warnings of {logger} on /rosout',
               watch=[proc])
    return found()


ROOT = Path(__file__).resolve().parents[2]

#: Per node: the -p typos, the parameter file's typo (and the value), and the start-up warnings.
CASES = {
    'geodesic_planner': ({'colision_check': False, 'bag_path': '/tmp/x'}, ('velocty_scaling', 0.5), {
        'colision_check': "unknown parameter 'colision_check' (did you mean 'collision_check'?): ignored; "
                          'collision_check is true',
        'bag_path': "unknown parameter 'bag_path' (a parameter of the trajectory_processor node, not of this "
                    'one): ignored',
        'velocty_scaling': "unknown parameter 'velocty_scaling' (did you mean 'velocity_scaling'?): ignored; "
                           'velocity_scaling is 1.0'}),
    'trajectory_processor': ({'sample_perod': 0.02, 'robot': 'ur5e'}, ('velocity_scalling', 0.5), {
        'sample_perod': "unknown parameter 'sample_perod' (did you mean 'sample_period'?): ignored; "
                        'sample_period is 0.01',
        'robot': "unknown parameter 'robot' (a parameter of the geodesic_planner node, not of this one): ignored",
        'velocity_scalling': "unknown parameter 'velocity_scalling' (did you mean 'velocity_scaling'?): ignored; "
                             'velocity_scaling is 1.0'}),
}


@pytest.mark.ros
@pytest.mark.timeout(300)
@pytest.mark.parametrize('executable, node', [('geodesic_planner_node', 'geodesic_planner'),
                                              ('trajectory_processor_node', 'trajectory_processor')],
                         ids=['planner', 'processor'])
def test_unknown_parameters_warned_at_start_and_refused_at_run_time(
        helper: Any, start_node: Any, tmp_path: Path, executable: str, node: str) -> None:
    given, (typo, value), warnings = CASES[node]
    closest = 'velocity_scaling'
    ns = f'/unknown_{node}'
    names = params.PLANNER_PARAMETERS if node == 'geodesic_planner' else params.PROCESSOR_PARAMETERS
    # the package's parameter file (every parameter of the node: no warning), a second file with a
    # typo in the node's own section, the -p typos after them
    params_file = tmp_path / 'params.yaml'
    params_file.write_text(yaml.safe_dump({f'{ns}/{node}': {'ros__parameters': {typo: value}}}))
    rosout = rosout_collector(helper)
    logger = f'{ns.strip("/")}.{node}'
    try:
        proc = start_node(executable, '-r', f'__ns:={ns}', '--params-file', str(ROOT / 'config' / f'{node}.yaml'),
                          '--params-file', str(params_file), params=given)
        clients = ParameterClients(helper, f'{ns}/{node}', proc)       # it spins: its start-up is over
        assert sorted(_warnings(rosout, logger, proc, len(warnings))) == sorted(warnings.values())
        # the unknown names are not parameters of the node; the ones they resemble kept their values
        listed = clients.names()
        assert not set(warnings) & set(listed), listed
        assert set(names) <= set(listed), listed
        assert clients.value(closest) == 1.0
        if node == 'geodesic_planner':
            assert clients.value('collision_check') is True

        # at run time: refused, with the closest name (the warning without ': ignored...')
        refusals = {name: warning.split(': ignored')[0] for name, warning in warnings.items()}
        for name, refusal in refusals.items():
            assert clients.set_one(name, value) == (False, refusal)
        assert clients.set_atomically(**{closest: 0.25, typo: 0.25}) == (False, refusals[typo])
        assert clients.value(closest) == 1.0                          # atomically: nothing was set
        assert clients.set_one(closest, 0.25) == (True, '')           # a known name still works
        assert clients.value(closest) == 0.25
        assert proc.alive(), proc.log_text()
        log = proc.log_text()
        assert 'Traceback' not in log and len(_warnings(rosout, logger, proc, 0)) == len(warnings), log
    finally:
        helper.destroy_subscription(rosout.subscription)
