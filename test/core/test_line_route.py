"""Issue 36: a LIN is exact or refused, on the moves reported from real arms.

Every path is checked by pinocchio's FK of the URDF (test/pin_oracle.py) against the line + slerp
between the requested poses, at 401 points: the tool within 1e-8 m and 1e-8 rad, the goal pose
reached within 1e-8 m and 1e-6 rad, the joints inside their limits. Refusals are checked for their
cause, their fraction and the tool's place (the line's point there).
"""
from __future__ import annotations

import numpy as np
import pin_oracle as P
import pytest
import urdf_util as U
from test_real_arms import ARMS, arm

from geodesic_planner import GeodesicPlanner
from geodesic_planner.core.errors import IKError, PathFollowError

LINE_TOL = 1e-8
S = np.linspace(0.0, 1.0, 401)

#: Issue 36 item 1: the Panda (example-robot-data, panda_link0 -> panda_hand_tcp), goal = FK(Q1).
PANDA_Q0 = [-1.2177867371817617, 0.2668106904882701, -1.2390427114412115, -1.673232548558004,
            0.9953435016954462, 2.3101784670480976, 0.901274077134]
PANDA_Q1 = [-1.543000994324646, 0.1683991439919138, -1.4749029287461413, -1.3240708072153229,
            0.7461542520364723, 2.1311985770406356, 0.8013278760796689]
#: Item 2: a start with the elbow straight (UR arms), goal = FK of the second joints.
UR_SINGULAR_START = [0.07307679209112505, -0.6539112118757542, -0.0001695615150834051, -1.532672722344437,
                     1.5256984094537804, 1.8462618555368353]
UR_SINGULAR_GOAL = [-0.23580855564796688, -0.7531493588617872, 0.16087564295827506, -1.662706030491919,
                    1.5726332403088947, 1.7878615291573563]
#: Item 3: ur3 moves, the first through a singularity at about 8.4 % of the way, the second followable.
UR3_THROUGH = ([-1.5347254836881667, -1.8172403130543697, -0.7804656103017003, 0.856191103725072,
                -0.025714748883211236, 1.3304770342599532],
               [-1.7326775712231235, -1.9466123900539676, -0.9497670140034884, 1.1910018998450238,
                0.2829894473727932, 1.2189573573595096])
UR3_FOLLOWABLE = ([1.0595517221330493, 1.6116468221870237, -1.3204672858072366, 0.47549949236281464,
                   -1.343515507454419, -0.21439130049187538],
                  [1.2599510741696616, 1.8879352777673255, -1.139007577920066, 0.15028523521993026,
                   -1.4419270539507751, -0.4502515177968051])


def _setup(key: str) -> tuple[GeodesicPlanner, P.Kinematics, object]:
    _, base, tip, _ = ARMS[key]
    _, robot, m = arm(key)
    return GeodesicPlanner(robot), P.Kinematics(m, robot.joint_names, base, tip), m


def check_exact(key: str, planner: GeodesicPlanner, kin: P.Kinematics, m: object, q_a: np.ndarray,
                T_b: np.ndarray) -> None:
    """Plan from q_a to the pose T_b and check the path by pinocchio's FK."""
    _, base, tip, _ = ARMS[key]
    robot = planner.robot
    path = planner.plan(None, T_b, start_joints=q_a)
    assert path.solver.method in ('pullback', 'redundant', 'trace'), path.solver.method
    T_a = kin.pose_and_jacobian(q_a)[0]
    q = path.evaluate(S, order=0)[0]
    dp, dr = P.line_errors(m, robot.joint_names, base, tip, q, S, T_a, T_b)
    assert dp <= LINE_TOL and dr <= LINE_TOL, (dp, dr)
    T_end = kin.pose_and_jacobian(path.q_goal)[0]
    assert np.linalg.norm(T_end[:3, 3] - T_b[:3, 3]) <= 1e-8
    R = T_end[:3, :3].T @ T_b[:3, :3]
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    assert np.arctan2(0.5 * np.linalg.norm(w), 0.5 * (np.trace(R) - 1.0)) <= 1e-6
    assert np.all((q >= robot.lower - 1e-9) & (q <= robot.upper + 1e-9))


def test_seven_joints_line_followed_exactly_where_least_motion_leaves_the_limits() -> None:
    """Item 1: was the general collocation, 0.65-14 mm off the line, reported as success."""
    planner, kin, m = _setup('panda')
    q0, q1 = np.array(PANDA_Q0), np.array(PANDA_Q1)
    check_exact('panda', planner, kin, m, q0, kin.pose_and_jacobian(q1)[0])


@pytest.mark.parametrize('key', ['ur3', 'ur5', 'ur10', 'ur3e', 'ur5e'])
def test_line_followed_out_of_a_singular_start(key: str) -> None:
    """Item 2: was refused at once, "metric singular at the start", without place or fraction."""
    planner, kin, m = _setup(key)
    q_a = np.array(UR_SINGULAR_START)
    sv = np.linalg.svd(kin.pose_and_jacobian(q_a)[1], compute_uv=False)
    assert sv[-1] < 1e-3 * sv[0]                        # the premise: the elbow (nearly) straight
    check_exact(key, planner, kin, m, q_a, kin.pose_and_jacobian(np.array(UR_SINGULAR_GOAL))[0])


def test_singularity_on_the_way_named_with_its_place() -> None:
    """Item 3: was stepped over in 1/16 steps and refused as "maximum number of mesh nodes exceeded"."""
    planner, kin, _ = _setup('ur3')
    q_a, q_b = (np.array(v) for v in UR3_THROUGH)
    T_a, T_b = kin.pose_and_jacobian(q_a)[0], kin.pose_and_jacobian(q_b)[0]
    with pytest.raises(PathFollowError, match=r"passes through a singularity of robot") as info:
        planner.plan(None, T_b, start_joints=q_a)
    err = info.value
    assert 0.075 < err.fraction < 0.09, err.fraction
    x, y, z = U.line_slerp_oracle(T_a, T_b, np.array([err.fraction]))[0, :3, 3]
    assert f'tool at {x:.4f}, {y:.4f}, {z:.4f} m' in str(err)
    assert 'mesh' not in str(err) and 'solve_bvp' not in str(err)
    # independently: the Jacobian along the line (pinocchio, continuation) collapses just after
    qs = P.follow(kin, q_a, T_b, 2000)[0][:200]
    qs = qs[np.all(np.isfinite(qs), axis=1)]
    k = int(np.argmin([np.linalg.svd(kin.pose_and_jacobian(q)[1], compute_uv=False)[-1] for q in qs]))
    assert abs(k / 2000 - err.fraction) < 0.01, (k / 2000, err.fraction)


def test_followable_line_near_a_singularity_planned_exactly() -> None:
    """Item 3: was refused after 1.3 s in solver words."""
    planner, kin, m = _setup('ur3')
    q_a, q_b = (np.array(v) for v in UR3_FOLLOWABLE)
    check_exact('ur3', planner, kin, m, q_a, kin.pose_and_jacobian(q_b)[0])


@pytest.mark.parametrize('key', ['panda', 'kuka_iiwa14', 'ur5e'])
def test_goal_on_a_joint_limit_reached_exactly(key: str) -> None:
    """Item 6: a goal whose joints sit on a limit was reached only within the IK tolerance (1e-3)."""
    planner, kin, m = _setup(key)
    robot = planner.robot
    rng = np.random.default_rng(36)
    done = 0
    for _ in range(40):
        lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
        hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
        q_a = rng.uniform(lo + 0.3 * (hi - lo), hi - 0.3 * (hi - lo))
        q_b = q_a + rng.uniform(-0.2, 0.2, robot.dof)
        j = int(rng.integers(robot.dof))
        q_b[j] = hi[j] if q_b[j] > q_a[j] else lo[j]        # the goal's joint j on its limit
        q_b = np.clip(q_b, lo, hi)
        T_b = kin.pose_and_jacobian(q_b)[0]
        try:
            check_exact(key, planner, kin, m, q_a, T_b)
            done += 1
        except (PathFollowError, IKError) as err:          # refused, with a cause: allowed
            assert 'followable fraction' in str(err) or 'nearest reachable pose' in str(err)
        if done == 3:
            break
    assert done == 3, f'{key}: fewer than 3 goals on a limit planned'
