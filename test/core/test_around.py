"""Around obstacles, first step (issue 39, section 2): OMPL's RRTConnect finds a way in joint space.

Oracle: the way's segments sampled densely (every 0.5 mrad of the largest joint move) by the
model's exact distances, each above the padding; the direct joint line is refused by the same
continuous check (the premise: the box blocks it).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from geodesic_planner import load_robot
from geodesic_planner.core.around import find_way
from geodesic_planner.core.cancel import CancelToken, Cancelled, cancellable
from geodesic_planner.core.collision import CollisionModel, SceneObject, Shape
from geodesic_planner.core.errors import PathInCollisionError
from geodesic_planner.core.kinematics import trans
from geodesic_planner.core.ptp import JointLinePath

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
MESHES = DATA / 'meshes'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
UR5_SRDF = MESHES / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
Q_A = np.array([0.8, -1.2, 1.4, -1.8, -1.57, 0.0])
Q_B = np.array([-0.8, -1.2, 1.4, -1.8, -1.57, 0.0])


@pytest.fixture(scope='module')
def blocked():
    robot = load_robot(str(UR5_URDF), tip_link='tool0')
    model = CollisionModel.for_robot(robot, UR5_URDF.read_text(), package_dirs=[str(MESHES)],
                                     srdf=UR5_SRDF.read_text())
    mid = robot.fk(0.5 * (Q_A + Q_B))[:3, 3]
    box = SceneObject('box', Shape('box', (0.12, 0.12, 0.12)), trans(*mid))
    return robot, model.with_objects([box])


def test_find_way_goes_around_a_box_the_joint_line_hits(blocked) -> None:
    robot, model = blocked
    with pytest.raises(PathInCollisionError):
        model.check_path(JointLinePath(robot, Q_A, Q_B))
    way = find_way(model, Q_A, Q_B, 5.0, seed=1)
    assert np.array_equal(way.waypoints[0], Q_A) and np.array_equal(way.waypoints[-1], Q_B)
    assert len(way.waypoints) >= 3
    for a, b in zip(way.waypoints[:-1], way.waypoints[1:]):
        k = max(int(np.abs(b - a).max() / 5e-4), 2)
        q = a + np.linspace(0.0, 1.0, k)[:, None] * (b - a)
        d, _ = model.distances(q)
        assert d.min() > model.padding, d.min()


def test_a_cancelled_plan_stops_the_search(blocked) -> None:
    robot, model = blocked
    token = CancelToken()
    token.cancel('plan_timeout passed')
    with cancellable(token), pytest.raises(Cancelled, match='plan_timeout passed'):
        find_way(model, Q_A, Q_B, 5.0, seed=1)
