"""Two nodes of one name (issue 13 #4): the newcomer refuses to start; the first keeps serving."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

pytest.importorskip('rclpy')
pytest.importorskip('geodesic_planner_interfaces')

from geodesic_planner_interfaces.msg import PlanErrorCode
from geodesic_planner_interfaces.srv import PlanTrajectory

from tools.graph import StatusWatch

from .launch import call_service, popen_node, warm_up_client
from .test_plan_trajectory import plan_request
from .test_planner_node import GOAL_3R, START_3R, pose_3r

pytestmark = [pytest.mark.ros, pytest.mark.timeout(300)]

DEADLINE = 60.0


@pytest.mark.parametrize('executable, name', [('geodesic_planner_node', 'geodesic_planner'),
                                              ('trajectory_processor_node', 'trajectory_processor')])
def test_second_node_of_a_name_refuses_to_start(helper: Any, tmp_path: Path, executable: str,
                                                name: str) -> None:
    ns = f'/dup_{name}'
    full = f'{ns}/{name}'
    status = StatusWatch(helper)
    first = popen_node(executable, '-r', f'__ns:={ns}', name='first', log_dir=tmp_path)
    second = None
    try:
        # the first node has looked for namesakes for its whole start-up window and found none
        status.wait(full, 'name check', lambda v: v == 'unique', DEADLINE, watch=[first])
        second = popen_node(executable, '-r', f'__ns:={ns}', name='second', log_dir=tmp_path)
        assert second.wait(DEADLINE) == 1, second.log_text()
        log = second.log_text()
        assert f'cannot start: another node named {full} is already running' in log, log
        assert 'Traceback' not in log
        assert first.alive(), first.log_text()
        if executable == 'geodesic_planner_node':      # and it still plans
            client = helper.create_client(PlanTrajectory, f'{full}/plan_trajectory')
            try:
                warm_up_client(client, plan_request(goal=pose_3r(*GOAL_3R, frame='__warmup__')),
                               DEADLINE, watch=[first])
                resp = call_service(client, plan_request(pose_3r(*START_3R), pose_3r(*GOAL_3R)),
                                    DEADLINE, watch=[first])
                assert resp.error_code.val == PlanErrorCode.SUCCESS, resp.message
            finally:
                helper.destroy_client(client)
    finally:
        helper.destroy_subscription(status.subscription)
        if second is not None and second.alive():
            second.stop()
        assert first.stop() == 0, first.log_text()
