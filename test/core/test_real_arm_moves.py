"""Random moves on real arms (issue 21, items 2, 4 and 5; issue 36): exact or refused with the place.

Each move starts at a random configuration within the limits and goes to the tool pose of a
nearby configuration (every joint moved by up to 0.3 rad), so both ends are reachable. Whether
its straight line + slerp can be followed is decided independently of the library: pinocchio's
FK and Jacobian, Newton IK from the previous sample over ``ORACLE_STEPS`` equal steps
(``pin_oracle.follow``). A move is *followable* when every step converges, no joint steps by more
than ``MAX_ORACLE_STEP`` (no flip), the Jacobian's smallest singular value stays at or above
``MIN_SIGMA`` (ends included) and every sample is within the limits. Followable moves must be
planned with the tool on the line and the slerp to 1e-8 m and 1e-8 rad (pinocchio's FK at 101
points of the path) and the goal pose reached; the others may be refused, with the reason named.
On the 6-joint arms the path is the pulled-back line ('pullback'); on the 7-joint ones (Panda,
xArm 7, iiwa 14) the least-motion path on the line ('redundant', test_redundant.py), for which a
followable move keeps σ_min >= ``MIN_SIGMA_7``. Any line path is on the line to the pose it
reaches. ``GP_REAL_ARM_MOVES`` sets the moves per arm (default 4; benchmarks/real_arms.py runs 30).
"""
from __future__ import annotations

import os
import re

import numpy as np
import pin_oracle as P
import pytest
import urdf_util as U
from planning_checks import CAUSES
from test_real_arms import ARMS, arm

from geodesic_planner import GeodesicPlanner
from geodesic_planner.core.errors import GeodesicPlannerError, PathFollowError

MOVES = int(os.environ.get('GP_REAL_ARM_MOVES', '4'))
ORACLE_STEPS = 1000
MAX_ORACLE_STEP = 0.02      # rad per 1/1000 of the line: 20 rad per line, a flip beyond
MIN_SIGMA = 1e-3
#: The same for 7 joints: closer to a singularity the least-motion path can turn too sharply for
#: the solver (2 of 106 followable real-arm moves, at 1.2e-3 and 1.8e-3), and the planner falls
#: back to the collocation of G + εI (docs/redundant-arms.md).
MIN_SIGMA_7 = 5e-3
LINE_TOL = 1e-8
SEVEN_JOINTS = ('panda', 'xarm7', 'kuka_iiwa14')


def random_move(robot, rng: np.random.Generator, scale: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """(start joints, nearby goal joints) within the limits (continuous joints within one turn)."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    q_a = rng.uniform(lo, hi)
    return q_a, np.clip(q_a + rng.uniform(-scale, scale, robot.dof), lo, hi)


def followable(robot, kin: P.Kinematics, q_a: np.ndarray, T_b: np.ndarray) -> bool:
    """The independent verdict (module docstring; MIN_SIGMA_7 for more than 6 joints)."""
    qs, sigma, step = P.follow(kin, q_a, T_b, ORACLE_STEPS)
    inside = np.all((qs >= robot.lower - 1e-9) & (qs <= robot.upper + 1e-9))
    min_sigma = MIN_SIGMA_7 if robot.dof > 6 else MIN_SIGMA
    return bool(np.all(np.isfinite(qs)) and sigma >= min_sigma and step <= MAX_ORACLE_STEP and inside)


@pytest.mark.parametrize('key', list(ARMS))
def test_random_moves_exact_or_refused_with_the_place(key: str) -> None:
    """Issue 36's sweep: seeded random moves on every corpus arm, half near (0.3 rad) and half far
    (1.0 rad, clipped at the limits: goals on a limit, singularities and limits on the way). A plan
    follows the requested line + slerp to 1e-8 m and rad and ends at the requested pose (pinocchio's
    FK), whatever its method (never the general collocation); a refusal names its cause with the
    fraction and the tool's place on the line (or the nearest reachable pose); a move the independent
    continuation follows is never refused."""
    _, base, tip, _ = ARMS[key]
    _, robot, m = arm(key)
    kin = P.Kinematics(m, robot.joint_names, base, tip)
    planner = GeodesicPlanner(robot)
    rng = np.random.default_rng(sum(map(ord, key)))
    s = np.linspace(0.0, 1.0, 101)
    for k in range(2 * MOVES):
        q_a, q_b = random_move(robot, rng, 0.3 if k % 2 == 0 else 1.0)
        T_a, T_b = kin.pose_and_jacobian(q_a)[0], kin.pose_and_jacobian(q_b)[0]
        try:
            path = planner.plan(None, T_b, start_joints=q_a)
        except GeodesicPlannerError as err:
            assert not followable(robot, kin, q_a, T_b), f'{key}: followable move refused: {err}'
            pattern = next(p for k, p in CAUSES.items() if isinstance(err, k))
            assert re.search(pattern, str(err)), f'{key}: refusal without its cause: {err}'
            if isinstance(err, PathFollowError):
                assert 0.0 <= err.fraction <= 1.0
                if 'to goal_joints' not in str(err):
                    x, y, z = U.line_slerp_oracle(T_a, T_b, np.array([err.fraction]))[0, :3, 3]
                    assert f'tool at {x:.4f}, {y:.4f}, {z:.4f} m' in str(err), (key, str(err))
            continue
        assert path.solver.method in ('redundant', 'trace') if key in SEVEN_JOINTS else ('pullback', 'trace'), key
        q = path.evaluate(s, order=0)[0]
        dp, dr = P.line_errors(m, robot.joint_names, base, tip, q, s, T_a, T_b)
        assert dp <= LINE_TOL and dr <= LINE_TOL, (key, q_a.tolist(), q_b.tolist(), dp, dr)
        assert np.all((q >= robot.lower - 1e-9) & (q <= robot.upper + 1e-9)), key
