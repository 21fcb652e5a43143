"""The interface package geodesic_planner_interfaces, as scripts/setup_env.sh builds it into the venv."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tools.process import popen_node

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / 'geodesic_planner_interfaces'

#: The error codes the service promises (values follow moveit_msgs/MoveItErrorCodes where it has them).
CODES = {'SUCCESS': 1, 'PLANNING_FAILED': -1, 'INVALID_MOTION_PLAN': -2, 'TIMED_OUT': -6,
         'START_STATE_IN_COLLISION': -10, 'GOAL_IN_COLLISION': -12, 'FRAME_TRANSFORM_FAILURE': -21,
         'NO_IK_SOLUTION': -31, 'INVALID_REQUEST': -101, 'START_STATE_MISMATCH': -102,
         'JOINT_LIMITS_VIOLATED': -103}
#: The scene's message and services: type name -> its fields (request and response for a service).
SCENE_TYPES = {
    'msg/CollisionObject': ['id', 'attached', 'pose', 'primitive', 'mesh', 'mesh_resource', 'mesh_scale'],
    'srv/SetCollisionObject': [['object'], ['success', 'message']],
    'srv/RemoveCollisionObject': [['id'], ['success', 'message']],
    'srv/ListCollisionObjects': [[], ['objects']],
}


def _constants(text: str) -> dict[str, int]:
    return {m.group(1): int(m.group(2)) for m in re.finditer(r'^int32\s+(\w+)\s*=\s*(-?\d+)', text, re.M)}


def _bare_python_json(code: str) -> dict:
    """Run ``code`` in the venv's python with a bare environment (no ROS set-up) and decode the
    JSON line it prints last."""
    import json
    env = {'PATH': '/usr/bin:/bin', 'HOME': os.environ.get('HOME', '/tmp')}
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1])


def test_error_code_definitions_are_the_promised_ones() -> None:
    assert _constants((PACKAGE / 'msg' / 'PlanErrorCode.msg').read_text()) == CODES


def test_built_package_imports_with_no_ros_environment() -> None:
    """The venv's python finds the generated module and its type support with a bare environment."""
    code = ('from geodesic_planner_interfaces.msg import PlanErrorCode\n'
            'from geodesic_planner_interfaces.srv import PlanTrajectory\n'
            'import json\n'
            'req, res = PlanTrajectory.Request(), PlanTrajectory.Response()\n'
            'print(json.dumps({"codes": {k: getattr(PlanErrorCode, k) for k in %r},'
            ' "request": sorted(req.get_fields_and_field_types()),'
            ' "response": sorted(res.get_fields_and_field_types()),'
            ' "execute": req.execute, "code": res.error_code.val}))\n').replace('%r', repr(sorted(CODES)))
    out = _bare_python_json(code)
    assert out['codes'] == CODES
    assert out['request'] == sorted(['start', 'goal', 'start_joints', 'goal_joints', 'via_poses',
                                     'velocity_scaling_factor', 'acceleration_scaling_factor', 'execute',
                                     'blend_radius'])
    assert out['response'] == sorted(['error_code', 'message', 'trajectory', 'tool_path', 'solver_method',
                                      'path_error', 'planning_time', 'blend_deviation',
                                      'fraction', 'min_clearance', 'ik_branch'])
    assert out['execute'] is False and out['code'] == 0


def test_scene_types_import_with_their_fields() -> None:
    """CollisionObject and the three scene services are built, with the promised fields (in order)."""
    code = ('import importlib, json\n'
            'out = {}\n'
            'for name in NAMES:\n'
            '    kind, typ = name.split("/")\n'
            '    cls = getattr(importlib.import_module("geodesic_planner_interfaces." + kind), typ)\n'
            '    if kind == "msg":\n'
            '        out[name] = list(cls.get_fields_and_field_types())\n'
            '    else:\n'
            '        out[name] = [list(cls.Request.get_fields_and_field_types()),\n'
            '                     list(cls.Response.get_fields_and_field_types())]\n'
            'obj = getattr(importlib.import_module("geodesic_planner_interfaces.msg"), "CollisionObject")()\n'
            'out["types"] = obj.get_fields_and_field_types()\n'
            'print(json.dumps(out))\n').replace('NAMES', repr(sorted(SCENE_TYPES)))
    out = _bare_python_json(code)
    assert out.pop('types') == {'id': 'string', 'attached': 'boolean', 'pose': 'geometry_msgs/Pose',
                                'primitive': 'shape_msgs/SolidPrimitive', 'mesh': 'shape_msgs/Mesh',
                                'mesh_resource': 'string', 'mesh_scale': 'geometry_msgs/Vector3'}
    assert out == SCENE_TYPES


@pytest.mark.ros
def test_service_type_is_served_and_called_across_processes(tmp_path: Path) -> None:
    """A server in one process and a client in another exchange PlanTrajectory (type support works)."""
    server = tmp_path / 'server.py'
    server.write_text(
        'import rclpy\n'
        'from rclpy.executors import ExternalShutdownException\n'
        'from geodesic_planner_interfaces.srv import PlanTrajectory\n'
        'def answer(req, res):\n'
        '    res.error_code.val = res.error_code.START_STATE_MISMATCH\n'
        '    res.message = f"execute={req.execute} vias={len(req.via_poses)}"\n'
        '    return res\n'
        'rclpy.init()\n'
        'node = rclpy.create_node("iface_server")\n'
        'node.create_service(PlanTrajectory, "plan_iface", answer)\n'
        'try:\n'
        '    rclpy.spin(node)\n'
        'except (KeyboardInterrupt, ExternalShutdownException):\n'
        '    pass\n')
    proc = popen_node('iface_server', name='iface_server', argv=[sys.executable, str(server)], log_dir=tmp_path)
    try:
        code = ('import rclpy\n'
                'from geometry_msgs.msg import PoseStamped\n'
                'from geodesic_planner_interfaces.srv import PlanTrajectory\n'
                'rclpy.init()\n'
                'node = rclpy.create_node("iface_client")\n'
                'client = node.create_client(PlanTrajectory, "plan_iface")\n'
                'assert client.wait_for_service(timeout_sec=60.0), "no service"\n'
                'req = PlanTrajectory.Request(execute=True, via_poses=[PoseStamped(), PoseStamped()])\n'
                'future = client.call_async(req)\n'
                'rclpy.spin_until_future_complete(node, future, timeout_sec=60.0)\n'
                'res = future.result()\n'
                'print(res.error_code.val, res.message)\n'
                'rclpy.shutdown()\n')
        result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120)
        assert result.returncode == 0, result.stderr[-3000:]
        assert result.stdout.strip().splitlines()[-1] == '-102 execute=True vias=2'
    finally:
        proc.stop(timeout=10.0)   # SIGINT, then SIGTERM, then SIGKILL: the reply is what is tested
