"""``geodesic-plan --scene`` with a sequence whose PTP a box blocks (issue 39, section 2): it goes
around by default, ``--no-ptp-around`` refuses it as before.

Oracle: the ur5e preset's capsules and the box (a collision model built here), their exact
distances at the written positions and the joint segments between them (0.5 mrad steps).
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from itertools import pairwise

import numpy as np

from geodesic_planner import load_robot
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.kinematics import trans

_script = shutil.which('geodesic-plan', path=os.path.dirname(sys.executable))
COMMAND = [_script] if _script else [sys.executable, '-m', 'geodesic_planner.cli.plan']
Q_A = [0.8, -1.2, 1.4, -1.8, -1.57, 0.0]
Q_B = [-0.8, -1.2, 1.4, -1.8, -1.57, 0.0]


def run(args, cwd):
    return subprocess.run(COMMAND + [str(a) for a in args], cwd=cwd, capture_output=True, text=True,
                          timeout=120, check=False)


def test_a_blocked_ptp_item_goes_around_and_the_flag_turns_it_off(tmp_path) -> None:
    robot = load_robot('ur5e')
    mid = [float(x) for x in robot.fk(0.5 * (np.array(Q_A) + Q_B))[:3, 3]]
    (tmp_path / 'req.yaml').write_text(f'robot: ur5e\nstart_joints: {Q_A}\nsequence:\n'
                                       f'  - {{motion: PTP, goal_joints: {Q_B}, ptp: joint_line}}\n')
    (tmp_path / 'scene.yaml').write_text('objects:\n  - id: box\n    type: box\n    dimensions: [0.12, 0.12, 0.12]\n'
                                         f'    pose: {{position: {mid}, orientation: [0, 0, 0, 1]}}\n')
    out = run(['req.yaml', '--scene', 'scene.yaml', '--samples', 2001, '-o', 'out.json'], tmp_path)
    assert out.returncode == 0, out.stderr
    data = json.loads((tmp_path / 'out.json').read_text())
    assert 'PTP went around obstacles' in data['notes'][0]
    model = CollisionModel.for_robot(robot).with_objects([SceneObject('box', Shape('box', (0.12,) * 3), trans(*mid))])
    for q in (np.array(data['positions']), np.array(data['trajectory']['positions'])):
        np.testing.assert_allclose(q[[0, -1]], [Q_A, Q_B], atol=1e-9)
        dense = np.concatenate([a + np.linspace(0.0, 1.0, max(int(np.abs(b - a).max() / 5e-4), 2))[:-1, None] * (b - a)
                                for a, b in pairwise(q)] + [q[-1:]])
        assert model.distances(dense)[0].min() >= model.padding
    assert data['collision']['min_clearance'] >= model.padding
    off = run(['req.yaml', '--scene', 'scene.yaml', '--no-ptp-around'], tmp_path)
    assert off.returncode == 1
    assert off.stderr.startswith('ERROR: collision on the way') and 'Traceback' not in off.stderr
