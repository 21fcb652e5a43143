"""Lines the coarse mesh misses are followed by continuation and planned exactly; lines that cannot
be followed are refused with the reason, the place and the followable fraction (issue 21, items
4 and 5). Oracles: the UR5e's published DH table written out in test/urdf_util.py (independent FK)
and the exact path of the same line on the unrestricted arm."""
from __future__ import annotations

import numpy as np
import pytest
import urdf_util as U
from line_cases import MISSED, THROUGH_ELBOW

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.continuation import follow_line
from geodesic_planner.core.errors import LineLimitError, PathFollowError
from geodesic_planner.core.kinematics import chain_from_dh
from geodesic_planner.core.transforms import line_slerp, so3_log

def line_errors(T: np.ndarray, T_a: np.ndarray, T_b: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """Largest distance (m) and rotation angle (rad) of poses T (N, 4, 4) from line + slerp at s."""
    ref = line_slerp(T_a, T_b, s)
    dp = np.linalg.norm(T[:, :3, 3] - ref[:, :3, 3], axis=1).max()
    dr = max(np.linalg.norm(so3_log(R.T @ Q)) for R, Q in zip(ref[:, :3, :3], T[:, :3, :3]))
    return float(dp), float(dr)


@pytest.mark.parametrize('case', list(MISSED))
def test_a_followable_line_the_mesh_misses_is_planned_exactly(case: str) -> None:
    q_a, q_b = (np.array(v) for v in MISSED[case])
    planner = GeodesicPlanner(load_robot('ur5e'))
    T_a, T_b = U.ur5e_fk_batch(np.stack([q_a, q_b]))
    path = planner.plan(None, T_b, start_joints=q_a)
    # the mesh missed the branch: traced (issue 36), the pull-back seeded by the trace where it applies
    assert path.solver.method in ('pullback', 'trace')
    s = np.linspace(0.0, 1.0, 2001)
    q = path.evaluate(s, order=0)[0]
    dp, dr = line_errors(U.ur5e_fk_batch(q), T_a, T_b, s)
    assert dp <= 1e-8 and dr <= 1e-8, (dp, dr)
    # one branch, no joint jump: neighbouring samples 1/2000 of the way apart stay close
    assert np.abs(np.diff(q, axis=0)).max() < 0.05


def test_a_line_through_a_singularity_is_refused_with_the_place() -> None:
    q_a, q_b = (np.array(v) for v in THROUGH_ELBOW)
    robot = load_robot('ur5e')
    planner = GeodesicPlanner(robot)
    T_a, T_b = U.ur5e_fk_batch(np.stack([q_a, q_b]))
    with pytest.raises(PathFollowError, match=r"passes through a singularity of robot 'ur5e' at") as info:
        planner.plan(None, T_b, start_joints=q_a)
    err = info.value
    assert 0.5 < err.fraction < 1.0 and f'followable fraction {err.fraction:.4f}' in str(err)
    follow = follow_line(robot, q_a, T_a, T_b, so3_log(T_a[:3, :3].T @ T_b[:3, :3]))
    assert abs(follow.fraction - err.fraction) < 1e-3      # the planner's trace and the continuation agree
    # up to the stop: on the line by the independent FK; at the stop: the elbow folded (q3 = -pi)
    dp, dr = line_errors(U.ur5e_fk_batch(follow.q), T_a, T_b, follow.s)
    assert dp <= 1e-9 and dr <= 1e-9
    assert abs(follow.q[-1][2] + np.pi) < 0.05
    x, y, z = U.line_slerp_oracle(T_a, T_b, np.array([err.fraction]))[0, :3, 3]    # the line's point there
    assert f'tool at {x:.4f}, {y:.4f}, {z:.4f} m' in str(err)


def test_a_line_that_crosses_a_joint_limit_names_the_joint_and_where() -> None:
    """The same followable line on an arm whose joint 1 stops halfway along its travel: the
    crossing is where the unrestricted arm's exact path reaches that limit."""
    q_a, q_b = (np.array(v) for v in MISSED['wrist_through_q5_zero'])
    free = GeodesicPlanner(load_robot('ur5e'))
    T_b = U.ur5e_fk_batch(q_b[None])[0]
    exact = free.plan(None, T_b, start_joints=q_a)
    s = np.linspace(0.0, 1.0, 20001)
    q1 = exact.evaluate(s, order=0)[0][:, 0]
    assert np.all(np.diff(q1) < 0)                       # joint 1 falls monotonically
    limit = 0.5 * (q1[0] + q1[-1])
    expected = float(np.interp(-limit, -q1, s))
    ur = load_robot('ur5e')
    lower = np.full(6, -2 * np.pi)
    lower[0] = limit
    arm = chain_from_dh('ur5e_stop', U.UR5E_DH, ['revolute'] * 6, joint_names=ur.joint_names,
                        lower=lower, upper=np.full(6, 2 * np.pi))
    assert np.allclose(arm.fk(q_a), ur.fk(q_a), atol=1e-14)
    with pytest.raises(LineLimitError, match=f'joint {ur.joint_names[0]!r} would pass its limit') as info:
        GeodesicPlanner(arm).plan(None, T_b, start_joints=q_a)
    assert abs(info.value.fraction - expected) < 1e-3, (info.value.fraction, expected)
    assert f'at {100 * info.value.fraction:.3g} % of the way' in str(info.value)


def test_the_whole_followed_line_is_on_the_line_and_ends_at_the_goal_pose() -> None:
    q_a, q_b = (np.array(v) for v in MISSED['goal_on_the_other_wrist_branch'])
    robot = load_robot('ur5e')
    T_a, T_b = U.ur5e_fk_batch(np.stack([q_a, q_b]))
    follow = follow_line(robot, q_a, T_a, T_b, so3_log(T_a[:3, :3].T @ T_b[:3, :3]))
    assert follow.error is None and follow.fraction == 1.0 and follow.s[-1] == 1.0
    dp, dr = line_errors(U.ur5e_fk_batch(follow.q), T_a, T_b, follow.s)
    assert dp <= 1e-9 and dr <= 1e-9
    # this goal pose is reached on the other wrist branch than the sampled goal joints
    assert np.abs(follow.q[-1] - q_b).max() > 3.0


def test_a_limit_passed_between_two_samples_is_found() -> None:
    """Unitree Z1 (corpus URDF): the goal has joint4 on its upper limit and the line takes joint4
    3.4e-4 rad past it and back around 60 % of the way, within one continuation step. The refusal
    names joint4 and the place, where pinocchio's own continuation (1000 steps) crosses it."""
    import pin_oracle as P
    from test_real_arms import ARMS, arm
    _, base, tip, _ = ARMS['unitree_z1']
    _, robot, m = arm('unitree_z1')
    q_a = np.array([0.6041550309385775, 1.1383942199377417, -0.00803480812535362, 1.4602358089562382,
                    0.4987010536003409, 0.840323123533171])
    q_b = np.array([0.7172230692811415, 1.071747074325204, -0.22697690511190688, 1.5184364492350666,
                    0.5139136470857764, 0.7264682488685443])
    kin = P.Kinematics(m, robot.joint_names, base, tip)
    T_b = kin.pose_and_jacobian(q_b)[0]
    qs, _, _ = P.follow(kin, q_a, T_b, 1000)
    over = np.flatnonzero(qs[:, 3] > robot.upper[3])
    assert over.size and qs[-1, 3] <= robot.upper[3] + 1e-9          # out and back within the line
    with pytest.raises(LineLimitError, match=r"joint 'joint4' would pass its limit 1\.51844") as info:
        GeodesicPlanner(robot).plan(None, T_b, start_joints=q_a)
    assert abs(info.value.fraction - over[0] / 1000) < 2e-3, (info.value.fraction, over[0] / 1000)
