"""Collision layer (issue 22): distances, state checks and continuous motion checks against exact
oracles computed here, never against numbers the code printed.

The oracles:

- primitives: the distance between two spheres, |c1 - c2| - r1 - r2; from a sphere to a box or a
  cylinder, the distance from its centre to the solid (numpy, in the solid's frame) minus r. The
  moving body is a sphere attached to the tool (an exact sphere at a known place), and the tiny
  robots' link capsules are shown, by a bound computed here, to be farther from the obstacle.
- motions: the planar 3R (paper Fig. 4) moving its tool on a straight line at constant
  orientation, so the attached sphere's centre is at x = X_A + s (X_B - X_A) (checked on the
  path); a box face across that line is reached at an s* computed from the face, the radius and
  the padding.
- real meshes: pinocchio places the UR5's collision meshes (its URDF, urdfdom's reading) and coal
  computes the distance between their convex hulls (or the meshes themselves), independently of
  the library's model.
"""
from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pin_oracle as PO
import pytest
from numpy.testing import assert_allclose

from geodesic_planner import GeodesicPlanner, load_robot
from geodesic_planner.core.collision import (CLEARANCE_RESOLUTION, DEFAULT_LINK_RADIUS, DEFAULT_PADDING, CollisionModel,
                                             MotionClearance, SceneObject, Shape)
from geodesic_planner.core.errors import (CollisionError, GeodesicPlannerError, GoalInCollisionError,
                                          PathInCollisionError, StartInCollisionError)
from geodesic_planner.core.kinematics import REVOLUTE, chain_from_dh, rot_x, rot_z, trans

DATA = Path(__file__).resolve().parents[1] / 'data' / 'real_arms'
#: package_dirs for the corpus URDFs: package://example-robot-data/robots/... lies under it.
MESHES = DATA / 'meshes'
UR5_URDF = DATA / 'example-robot-data' / 'ur5_robot.urdf'
UR5_SRDF = MESHES / 'example-robot-data' / 'robots' / 'ur_description' / 'srdf' / 'ur5.srdf'
PANDA_URDF = DATA / 'example-robot-data' / 'panda.urdf'
PANDA_SRDF = MESHES / 'example-robot-data' / 'robots' / 'panda_description' / 'srdf' / 'panda.srdf'

#: The contract's resolution of the motion check (m): a motion may be refused where a clearance
#: is <= padding + RESOLUTION, and must be where it is <= padding.
RESOLUTION = 1e-3
#: Agreement with an analytic or coal distance, m.
DIST_TOL = 1e-6
#: Agreement with coal's signed distance between penetrating convex hulls (EPA), m.
DEPTH_TOL = 1e-5


def same_pair(pair: tuple[str, str], a: str, b: str) -> bool:
    """Whether ``pair`` names a and b, in either order."""
    return sorted(pair) == sorted((a, b))


def checked(model: CollisionModel, a: str, b: str) -> bool:
    """Whether the model checks the pair (a, b), in either order."""
    return any(same_pair(p, a, b) for p in model.pairs)


def skip_reason(model: CollisionModel, a: str, b: str) -> str | None:
    """The reason the model gives for skipping (a, b), in either order; None if not skipped."""
    return model.skipped.get((a, b), model.skipped.get((b, a)))


# ---------------------------------------------------------------------------- numpy oracles
def box_distance(points: np.ndarray, size: tuple[float, float, float], T: np.ndarray) -> np.ndarray:
    """Distance (m) from points (N, 3) outside a box (size x, y, z centred on its frame T) to it."""
    local = (points - T[:3, 3]) @ T[:3, :3]
    excess = np.abs(local) - 0.5 * np.asarray(size)
    return np.linalg.norm(np.maximum(excess, 0.0), axis=1)


def cylinder_distance(points: np.ndarray, height: float, radius: float, T: np.ndarray) -> np.ndarray:
    """Distance (m) from points (N, 3) outside a cylinder (along z of T, centred) to it."""
    local = (points - T[:3, 3]) @ T[:3, :3]
    radial = np.hypot(local[:, 0], local[:, 1]) - radius
    axial = np.abs(local[:, 2]) - 0.5 * height
    return np.hypot(np.maximum(radial, 0.0), np.maximum(axial, 0.0))


def segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) from points (N, 3) to the segments a -> b (N, 3 each)."""
    ab = b - a
    t = np.clip(np.einsum('ij,ij->i', points - a, ab) / np.einsum('ij,ij->i', ab, ab), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


# ---------------------------------------------------------------------------- a one-link arm
#: The attached sphere of the one-link arm: radius (m) and offset along the tool's x (m).
BALL_R, BALL_OFFSET = 0.1, 0.3


def one_link_arm():
    """One revolute joint about z and a 1 m link along x: the tool at (cos q, sin q, 0), x along the link."""
    return chain_from_dh('one_link', [(0.0, 0.0, 1.0, 0.0)], [REVOLUTE])


def ball(radius: float, offset: float) -> SceneObject:
    """A sphere attached to the tool, its centre ``offset`` m along the tool's x axis."""
    return SceneObject('ball', Shape('sphere', (radius,)), trans(x=offset), attached=True)


ARM_Q = np.linspace(-0.3, 0.8, 12)[:, None]


def arm_points(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(tool positions, ball centres), each (N, 3), of the one-link arm at q (N, 1)."""
    u = np.stack([np.cos(q[:, 0]), np.sin(q[:, 0]), np.zeros(q.shape[0])], axis=1)
    return u, (1.0 + BALL_OFFSET) * u


def link_bound(obstacle_distance: np.ndarray, q: np.ndarray) -> np.ndarray:
    """A lower bound on the link capsule's distance to an obstacle: the capsule lies within
    DEFAULT_LINK_RADIUS of the segment from the base to the tool, ``obstacle_distance(points)``
    gives the obstacle's distance from points (N, 3)."""
    tool, _ = arm_points(q)
    seg = np.linspace(0.0, 1.0, 201)
    d = np.min([obstacle_distance(s * tool) for s in seg], axis=0)   # the segment, finely sampled
    return d - 1.0 / 200 - DEFAULT_LINK_RADIUS                        # less the sampling's gap


def test_contract_constants():
    assert DEFAULT_PADDING == 0.01
    assert DEFAULT_LINK_RADIUS == 0.05
    assert CLEARANCE_RESOLUTION == 1e-3                   # min_clearance: at most 1 mm below the truth
    for err in (StartInCollisionError, GoalInCollisionError, PathInCollisionError):
        assert issubclass(err, CollisionError)
    assert issubclass(CollisionError, GeodesicPlannerError)


def test_sphere_sphere_distance_is_exact():
    centre, radius = np.array([2.0, 0.4, 0.1]), 0.2
    obstacle = SceneObject('obstacle', Shape('sphere', (radius,)), trans(*centre))
    model = CollisionModel.for_robot(one_link_arm()).with_objects([ball(BALL_R, BALL_OFFSET), obstacle])
    _, c = arm_points(ARM_Q)
    expected = np.linalg.norm(c - centre, axis=1) - BALL_R - radius
    # the premise: the link's capsule is farther from the obstacle than the ball, at every q
    capsule = link_bound(lambda p: np.linalg.norm(p - centre, axis=1) - radius, ARM_Q)
    assert np.all(capsule > expected + 0.05)
    d, pairs = model.distances(ARM_Q)
    assert_allclose(d, expected, rtol=0, atol=DIST_TOL)
    assert all(same_pair(p, 'ball', 'obstacle') for p in pairs), pairs


def test_box_sphere_distance_is_exact():
    size = (0.4, 0.3, 0.2)
    T_box = trans(1.9, 0.3, 0.05) @ rot_z(0.5) @ rot_x(0.3)      # turned about two axes
    box = SceneObject('box', Shape('box', size), T_box)
    model = CollisionModel.for_robot(one_link_arm()).with_objects([ball(BALL_R, BALL_OFFSET), box])
    _, c = arm_points(ARM_Q)
    expected = box_distance(c, size, T_box) - BALL_R
    assert np.all(expected > 0.01)                                   # outside, not touching
    capsule = link_bound(lambda p: box_distance(p, size, T_box), ARM_Q)
    assert np.all(capsule > expected + 0.05)
    d, pairs = model.distances(ARM_Q)
    assert_allclose(d, expected, rtol=0, atol=DIST_TOL)
    assert all(same_pair(p, 'ball', 'box') for p in pairs), pairs


def test_cylinder_sphere_distance_is_exact_with_the_solid_primitive_order():
    # shape_msgs/SolidPrimitive: CYLINDER_HEIGHT first, then CYLINDER_RADIUS; the axis is z
    height, radius = 0.6, 0.15
    T_cyl = trans(1.9, -0.2, 0.0) @ rot_x(0.4)
    cyl = SceneObject('cylinder', Shape('cylinder', (height, radius)), T_cyl)
    model = CollisionModel.for_robot(one_link_arm()).with_objects([ball(BALL_R, BALL_OFFSET), cyl])
    _, c = arm_points(ARM_Q)
    expected = cylinder_distance(c, height, radius, T_cyl) - BALL_R
    swapped = cylinder_distance(c, radius, height, T_cyl) - BALL_R   # what the other order would give
    assert np.all(expected > 0.01)
    assert np.abs(expected - swapped).max() > 0.05                  # the test tells the orders apart
    capsule = link_bound(lambda p: cylinder_distance(p, height, radius, T_cyl), ARM_Q)
    assert np.all(capsule > expected + 0.05)
    # the carried ball is also checked against the base's link (a sphere of link_radius at the
    # origin, the centre of a 1 m + BALL_OFFSET circle): the nearer of the two pairs is reported
    to_base = 1.0 + BALL_OFFSET - BALL_R - DEFAULT_LINK_RADIUS
    d, pairs = model.distances(ARM_Q)
    assert_allclose(d, np.minimum(expected, to_base), rtol=0, atol=DIST_TOL)
    for p, e in zip(pairs, expected):
        assert same_pair(p, 'ball', 'cylinder') if e < to_base else same_pair(p, 'ball', 'link_0'), pairs


def test_sphere_inside_a_box_is_in_contact():
    size = (0.4, 0.3, 0.2)                                           # holds the ball at q = 0
    box = SceneObject('box', Shape('box', size), trans(1.0 + BALL_OFFSET, 0.0, 0.0))
    model = CollisionModel.for_robot(one_link_arm()).with_objects([ball(BALL_R, BALL_OFFSET), box])
    d, pairs = model.distances(np.zeros((1, 1)))
    assert d[0] <= 0.0
    assert same_pair(pairs[0], 'ball', 'box')
    with pytest.raises(StartInCollisionError) as info:
        model.check_state(np.zeros(1))
    assert same_pair(info.value.pair, 'ball', 'box')
    with pytest.raises(GoalInCollisionError):
        model.check_state(np.zeros(1), 'goal')


def test_body_poses_place_objects_where_they_were_put():
    robot = one_link_arm()
    T_box = trans(1.9, 0.3, 0.05) @ rot_z(0.5)
    model = CollisionModel.for_robot(robot).with_objects(
        [ball(BALL_R, BALL_OFFSET), SceneObject('box', Shape('box', (0.1, 0.2, 0.3)), T_box)])
    q = np.array([0.7])
    poses = model.body_poses(q)
    assert_allclose(poses['ball'], robot.fk(q) @ trans(x=BALL_OFFSET), rtol=0, atol=1e-12)
    assert_allclose(poses['box'], T_box, rtol=0, atol=1e-12)
    assert set(model.body_names) <= set(poses)
    assert model.shapes()['box'] == Shape('box', (0.1, 0.2, 0.3))
    assert [o.id for o in model.objects] == ['ball', 'box']


# ---------------------------------------------------------------------------- planar 3R, a straight line
#: The tool's line: from (X_A, LINE_Y) to (X_B, LINE_Y), tool x axis along +y (phi = pi/2) all the
#: way, so link 3 stands upright from (x, 0) to (x, 1) and the attached sphere (offset along the
#: tool's x) moves on the line y = LINE_Y + offset.
X_A, X_B, LINE_Y, PHI = 0.5, 1.5, 1.0, np.pi / 2


def tool_pose(x: float) -> np.ndarray:
    return trans(x, LINE_Y) @ rot_z(PHI)


@pytest.fixture(scope='module')
def line_path():
    """The planar 3R's geodesic between the two tool poses (a straight line at constant orientation)."""
    robot = load_robot('planar_3r')
    return GeodesicPlanner(robot).plan(tool_pose(X_A), tool_pose(X_B))


def motion(traj):
    """check_motion's ``positions``: t (M,) -> (q (M, dof), s (M,)) of a trajectory."""
    def positions(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s = traj.s_of_t(t)[0]
        return traj.path.evaluate(s, order=0)[0], s
    return positions


def sphere_centres(path, s: np.ndarray, offset: float) -> np.ndarray:
    """Centres (N, 3) of the sphere attached at ``offset`` along the tool's x, at path parameters s."""
    T = path.robot.fk(path.evaluate(s, order=0)[0])
    return T[:, :3, 3] + offset * T[:, :3, 0]


def on_line(path, offset: float) -> None:
    """The oracle's premise: the sphere's centre is at (X_A + s (X_B - X_A), LINE_Y + offset, 0)."""
    s = np.linspace(0.0, 1.0, 401)
    expected = np.stack([X_A + s * (X_B - X_A), np.full_like(s, LINE_Y + offset), np.zeros_like(s)], axis=1)
    assert_allclose(sphere_centres(path, s, offset), expected, rtol=0, atol=1e-7)


#: Sphere and box of the crossing test: the box's face x = FACE spans y in [1.12, 1.40], z in
#: [-0.2, 0.2]; the sphere's centre runs at y = 1.25 (inside that span), link 3's capsule stays
#: below y = 1 + DEFAULT_LINK_RADIUS, 7 cm under the box.
CROSS_R, CROSS_OFFSET, FACE = 0.08, 0.25, 1.2
CROSS_BOX_SIZE = (0.1, 0.28, 0.4)


def cross_box(face: float = FACE, y_low: float = 1.12) -> SceneObject:
    sx, sy, sz = CROSS_BOX_SIZE
    return SceneObject('box', Shape('box', CROSS_BOX_SIZE), trans(face + sx / 2, y_low + sy / 2, 0.0))


def test_line_crossing_a_box_is_refused_where_the_sphere_reaches_the_padding(line_path):
    on_line(line_path, CROSS_OFFSET)
    traj = line_path.timed()
    model = CollisionModel.for_robot(line_path.robot).with_objects(
        [ball(CROSS_R, CROSS_OFFSET), cross_box()])
    pad = model.padding
    length = X_B - X_A
    # contact with the padding: the centre at FACE - r - padding; RESOLUTION earlier at the latest
    s_star = (FACE - CROSS_R - pad - X_A) / length
    s_low = s_star - RESOLUTION / length
    assert 0.1 < s_low < s_star < 0.9
    with pytest.raises(PathInCollisionError) as info:
        model.check_motion(motion(traj), traj.duration, traj.max_velocity)
    err = info.value
    assert same_pair(err.pair, 'ball', 'box'), err.pair
    assert s_low - 1e-7 <= err.fraction <= s_star + 1e-7, (s_low, err.fraction, s_star)
    # the clearance reported is the one at that place (sphere to face), within the refusal band
    assert_allclose(err.clearance, FACE - (X_A + err.fraction * length) - CROSS_R, rtol=0, atol=DIST_TOL)
    assert err.clearance <= pad + RESOLUTION + DIST_TOL
    assert 0.0 < err.time < traj.duration
    # the message says what the check guarantees: the pair is within the padding or its 1 mm margin
    assert f'collision on the way at {100 * err.fraction:.1f} % of the way' in str(err), str(err)
    if err.clearance > pad:
        assert (f"are {err.clearance:.4f} m apart, within the motion check's 1 mm margin of collision_padding "
                f'0.01 m (it refuses any distance it finds up to {pad + RESOLUTION:.4f} m') in str(err), str(err)
    else:
        assert f'are {err.clearance:.4f} m apart, closer than collision_padding 0.01 m' in str(err), str(err)
    assert_allclose(traj.s_of_t(err.time)[0][0], err.fraction, rtol=0, atol=1e-9)


def test_line_passing_under_a_box_reports_its_least_clearance(line_path):
    on_line(line_path, CROSS_OFFSET)
    traj = line_path.timed()
    gap = 0.03                             # the box's underside 3 cm above the sphere, over 10 cm of line
    box = cross_box(y_low=LINE_Y + CROSS_OFFSET + CROSS_R + gap)
    model = CollisionModel.for_robot(line_path.robot).with_objects([ball(CROSS_R, CROSS_OFFSET), box])
    result = model.check_motion(motion(traj), traj.duration, traj.max_velocity)
    assert isinstance(result, MotionClearance)
    assert gap - CLEARANCE_RESOLUTION - DIST_TOL <= result.min_clearance <= gap + DIST_TOL   # never above
    assert same_pair(result.pair, 'ball', 'box'), result.pair
    width = CROSS_BOX_SIZE[0] / (X_B - X_A)                          # the box's span in s
    s_in = (FACE - X_A) / (X_B - X_A)
    assert s_in - 1e-7 <= result.fraction <= s_in + width + 1e-7
    assert_allclose(traj.s_of_t(result.time)[0][0], result.fraction, rtol=0, atol=1e-9)
    assert result.checks >= 2


def test_least_clearance_between_checks_is_not_overstated(line_path):
    """A ball passing a fixed ball: the distance has a sharp minimum (gap at s0, an arbitrary place
    no check is sure to land on). min_clearance is within 1 mm below the gap, never above."""
    on_line(line_path, CROSS_OFFSET)
    traj = line_path.timed()
    gap, r_fixed, s0 = 0.04, 0.05, 0.3717
    centre = (X_A + s0 * (X_B - X_A), LINE_Y + CROSS_OFFSET + CROSS_R + r_fixed + gap, 0.0)
    fixed = SceneObject('post', Shape('sphere', (r_fixed,)), trans(*centre))
    model = CollisionModel.for_robot(line_path.robot).with_objects([ball(CROSS_R, CROSS_OFFSET), fixed])
    result = model.check_motion(motion(traj), traj.duration, traj.max_velocity)
    assert same_pair(result.pair, 'ball', 'post'), result.pair
    tol = CLEARANCE_RESOLUTION
    assert gap - tol - DIST_TOL <= result.min_clearance <= gap + DIST_TOL, result.min_clearance
    # the place: where the sphere-sphere distance is within the tolerance of the gap
    dx = X_B - X_A
    assert abs(result.fraction - s0) * dx <= np.sqrt((gap + tol + CROSS_R + r_fixed) ** 2
                                                     - (gap + CROSS_R + r_fixed) ** 2) + 1e-6
    # independently: exact sphere-sphere distances at 2001 times are never below it
    t = np.linspace(0.0, traj.duration, 2001)
    c = sphere_centres(line_path, traj.s_of_t(t)[0], CROSS_OFFSET)
    dense = np.linalg.norm(c - np.array(centre), axis=1) - CROSS_R - r_fixed
    assert dense.min() >= result.min_clearance - DIST_TOL
    assert_allclose(dense.min(), gap, rtol=0, atol=1e-5)


#: The thin plate: 5 mm thick across the line, the sphere (radius 1 cm) runs through its middle.
PLATE, PLATE_R, PLATE_OFFSET, DT = 0.005, 0.01, 0.2, 0.05


def test_plate_between_two_samples_is_caught_by_the_motion_check(line_path):
    on_line(line_path, PLATE_OFFSET)
    traj = line_path.timed(max_velocity=2.0, max_acceleration=8.0)   # fast: about 9 cm per sample
    t = traj.times(DT)
    s = traj.s_of_t(t)[0]
    x = sphere_centres(line_path, s, PLATE_OFFSET)[:, 0]
    i = int(np.argmax(np.diff(x)))
    x_plate = 0.5 * (x[i] + x[i + 1])
    plate = SceneObject('plate', Shape('box', (PLATE, 0.2, 0.2)), trans(x_plate, LINE_Y + PLATE_OFFSET, 0.0))
    model = CollisionModel.for_robot(line_path.robot).with_objects([ball(PLATE_R, PLATE_OFFSET), plate])
    pad = model.padding
    # at every sample the sphere is clear of the plate by more than the padding (and the resolution)
    at_samples = np.abs(x - x_plate) - PLATE / 2 - PLATE_R
    assert at_samples.min() > pad + RESOLUTION, at_samples.min()
    # so a check at the samples finds nothing
    qs = traj.path.evaluate(s, order=0)[0]
    d, _ = model.distances(qs)
    assert d.min() > pad, d.min()
    # the motion check does, where the sphere comes within the padding of the plate's near face
    with pytest.raises(PathInCollisionError) as info:
        model.check_motion(motion(traj), traj.duration, traj.max_velocity)
    err = info.value
    assert same_pair(err.pair, 'ball', 'plate'), err.pair
    length = X_B - X_A
    s_star = (x_plate - PLATE / 2 - PLATE_R - pad - X_A) / length
    assert s[i] < s_star - RESOLUTION / length and s_star < s[i + 1]
    assert s_star - RESOLUTION / length - 1e-7 <= err.fraction <= s_star + 1e-7, (err.fraction, s_star)


def test_start_and_goal_in_collision_name_the_end(line_path):
    traj = line_path.timed()
    for x, error, fraction, time in ((X_A, StartInCollisionError, 0.0, 0.0),
                                     (X_B, GoalInCollisionError, 1.0, traj.duration)):
        # a 5 cm cube around the sphere's centre at that end
        box = SceneObject('box', Shape('box', (0.05, 0.05, 0.05)), trans(x, LINE_Y + CROSS_OFFSET, 0.0))
        model = CollisionModel.for_robot(line_path.robot).with_objects([ball(CROSS_R, CROSS_OFFSET), box])
        with pytest.raises(error) as info:
            model.check_motion(motion(traj), traj.duration, traj.max_velocity)
        err = info.value
        assert same_pair(err.pair, 'ball', 'box'), err.pair
        assert err.fraction == fraction
        assert_allclose(err.time, time, rtol=0, atol=1e-12)
        # the sphere's centre inside the cube: they overlap by the radius plus half the cube's edge
        assert_allclose(err.clearance, -(CROSS_R + 0.025), rtol=0, atol=DEPTH_TOL)
        assert f"'ball' and 'box' overlap by {CROSS_R + 0.025:.4f} m (collision_padding 0.01 m)" in str(err), err
        # the same end alone, as check_state sees it
        q_end = line_path.evaluate(np.array([fraction]), order=0)[0][0]
        with pytest.raises(error):
            model.check_state(q_end, 'start' if error is StartInCollisionError else 'goal')


def test_free_line_passes_and_the_ends_pass_check_state(line_path):
    traj = line_path.timed()
    model = CollisionModel.for_robot(line_path.robot).with_objects(
        [ball(CROSS_R, CROSS_OFFSET), cross_box(face=X_B + CROSS_R + 0.1)])   # 10 cm beyond the goal
    result = model.check_motion(motion(traj), traj.duration, traj.max_velocity)
    assert 0.1 - CLEARANCE_RESOLUTION - DIST_TOL <= result.min_clearance <= 0.1 + DIST_TOL  # at the goal
    assert result.fraction == 1.0
    assert same_pair(result.pair, 'ball', 'box')
    assert model.check_state(line_path.q_start) > model.padding
    assert_allclose(model.check_state(line_path.q_goal, 'goal'), 0.1, rtol=0, atol=DIST_TOL)


# ---------------------------------------------------------------------------- UR5 with its meshes
#: The UR5's links in chain order (each has a collision mesh), and its joints in pairs of neighbours.
UR5_LINKS = ['base_link', 'shoulder_link', 'upper_arm_link', 'forearm_link', 'wrist_1_link', 'wrist_2_link',
             'wrist_3_link']
UR5_ADJACENT = list(itertools.pairwise(UR5_LINKS))
#: Folded into itself: the elbow bent back (2.75 rad) so that wrist 2 sinks into the upper arm's
#: hull (2.7 cm deep, coal below). Every other pair that ur5.srdf does not disable is 2.7 cm or
#: more apart (found by a seeded search over folded poses with coal; the test re-checks it).
Q_FOLD = np.array([-0.31, 0.39, 2.75, 1.31, -1.68, -0.03])
FOLD_PAIR = ('upper_arm_link', 'wrist_2_link')


@pytest.fixture(scope='module')
def ur5():
    """(chain base_link -> tool0, URDF text) of the UR5 of example-robot-data."""
    return load_robot(str(UR5_URDF), base_link='base_link', tip_link='tool0'), UR5_URDF.read_text()


class CoalOracle:
    """The UR5's collision geometry as pinocchio reads it (urdfdom, package_dirs) and coal's
    distances between the meshes' convex hulls (``buildConvexHull(True, 'Qt')``, qhull) or the
    meshes themselves (BVH)."""

    def __init__(self, joint_names: list[str]) -> None:
        pin = pytest.importorskip('pinocchio')
        self.coal = pytest.importorskip('coal')
        self.pin = pin
        self.model = pin.buildModelFromUrdf(str(UR5_URDF))
        self.data = self.model.createData()
        self.geom = pin.buildGeomFromUrdf(self.model, str(UR5_URDF), pin.GeometryType.COLLISION,
                                          package_dirs=[str(MESHES)])
        self.gdata = self.geom.createData()
        self.names = joint_names
        self.index: dict[str, int] = {}                     # link -> geometry object
        self.hull: dict[str, object] = {}
        self.mesh: dict[str, object] = {}
        for i, obj in enumerate(self.geom.geometryObjects):
            link = self.model.frames[obj.parentFrame].name
            self.index[link] = i
            self.mesh[link] = obj.geometry
            if isinstance(obj.geometry, self.coal.BVHModelBase):
                obj.geometry.buildConvexHull(True, 'Qt')
                self.hull[link] = obj.geometry.convex
            else:
                self.hull[link] = obj.geometry

    def placements(self, q: np.ndarray) -> dict[str, object]:
        """coal transforms of every link's geometry, base frame (the URDF root is base_link)."""
        qp = PO.configuration(self.model, self.names, q)
        self.pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gdata, qp)
        return {link: self.coal.Transform3s(self.gdata.oMg[i].rotation, self.gdata.oMg[i].translation)
                for link, i in self.index.items()}

    def distance(self, a: object, Ta: object, b: object, Tb: object) -> float:
        return float(self.coal.distance(a, Ta, b, Tb, self.coal.DistanceRequest(), self.coal.DistanceResult()))

    def pair_distances(self, q: np.ndarray, pairs: list[tuple[str, str]]) -> dict[tuple[str, str], float]:
        """Hull distance (m, negative: penetration depth) of each link pair at q."""
        X = self.placements(q)
        return {(a, b): self.distance(self.hull[a], X[a], self.hull[b], X[b]) for a, b in pairs}

    def sphere_distance(self, q: np.ndarray, links: list[str], centre: np.ndarray, radius: float,
                        exact: bool) -> float:
        """Least distance (m) from a sphere to the links' hulls (or meshes, ``exact``) at q."""
        X = self.placements(q)
        sphere, Ts = self.coal.Sphere(radius), self.coal.Transform3s(np.eye(3), centre)
        geometry = self.mesh if exact else self.hull
        return min(self.distance(geometry[link], X[link], sphere, Ts) for link in links)


@pytest.fixture(scope='module')
def oracle(ur5):
    return CoalOracle(ur5[0].joint_names)


def ur5_model(ur5, srdf: str | None = None, **kwargs) -> CollisionModel:
    robot, urdf = ur5
    return CollisionModel.for_robot(robot, urdf, package_dirs=[str(MESHES)], srdf=srdf, **kwargs)


def srdf_pairs(text: str) -> list[tuple[str, str, str | None]]:
    """(link1, link2, reason or None) of every <disable_collisions> of an SRDF text."""
    import xml.etree.ElementTree as ET
    return [(e.get('link1', ''), e.get('link2', ''), e.get('reason'))
            for e in ET.fromstring(text).iter('disable_collisions')]


def test_ur5_bodies_and_default_skips(ur5):
    model = ur5_model(ur5)
    assert set(UR5_LINKS) <= set(model.body_names)
    for a, b in UR5_ADJACENT:                              # one joint apart: never checked, reason given
        assert not checked(model, a, b), (a, b)
        reason = skip_reason(model, a, b)
        assert isinstance(reason, str) and reason, (a, b, reason)
    # every pair of bodies is either checked or skipped with a reason, never both
    for a, b in itertools.combinations(model.body_names, 2):
        assert checked(model, a, b) != (skip_reason(model, a, b) is not None), (a, b)
    # far apart links of the arm are checked
    for a, b in (('base_link', 'wrist_2_link'), ('shoulder_link', 'wrist_3_link'), FOLD_PAIR):
        assert checked(model, a, b), (a, b)


def test_ur5_scene_and_attached_skips(ur5):
    box = SceneObject('box', Shape('box', (0.2, 0.2, 0.2)), trans(0.6, 0.0, 0.3))
    tool_ball = SceneObject('tool_ball', Shape('sphere', (0.04,)), trans(z=0.05), attached=True)
    model = ur5_model(ur5).with_objects([box, tool_ball])
    # a scene object against a body fixed to the base: it cannot change
    assert not checked(model, 'base_link', 'box') and skip_reason(model, 'base_link', 'box')
    # an attached object against the tool link (touch link)
    assert not checked(model, 'wrist_3_link', 'tool_ball') and skip_reason(model, 'wrist_3_link', 'tool_ball')
    for a, b in (('forearm_link', 'box'), ('wrist_3_link', 'box'), ('upper_arm_link', 'tool_ball'),
                 ('box', 'tool_ball')):
        assert checked(model, a, b), (a, b)


def test_ur5_body_poses_are_pinocchios_link_frames(ur5, oracle):
    robot, _ = ur5
    q = np.array([0.3, -1.1, 1.4, -0.7, 1.2, 0.5])
    poses = ur5_model(ur5).body_poses(q)
    X = oracle.placements(q)
    for link in UR5_LINKS:               # collision origins are the identity: geometry frame = link frame
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = X[link].getRotation(), X[link].getTranslation()
        assert_allclose(poses[link], T, rtol=0, atol=1e-9, err_msg=link)


@pytest.mark.parametrize('with_srdf', [False, True], ids=['no_srdf', 'ur5_srdf'])
def test_ur5_folded_into_itself_is_refused_naming_the_pair(ur5, oracle, with_srdf):
    model = ur5_model(ur5, UR5_SRDF.read_text() if with_srdf else None)
    assert checked(model, *FOLD_PAIR)
    truth = oracle.pair_distances(Q_FOLD, list(model.pairs))
    depth = truth[next(p for p in truth if same_pair(p, *FOLD_PAIR))]
    assert depth < -0.02                                      # coal: the hulls truly intersect
    others = [d for p, d in truth.items() if not same_pair(p, *FOLD_PAIR)]
    assert min(others) > depth + 0.02                         # the deepest checked pair, by far
    with pytest.raises(StartInCollisionError) as info:
        model.check_state(Q_FOLD)
    assert same_pair(info.value.pair, *FOLD_PAIR), info.value.pair
    assert_allclose(info.value.clearance, depth, rtol=0, atol=DEPTH_TOL)
    with pytest.raises(GoalInCollisionError) as goal:
        model.check_state(Q_FOLD, 'goal')
    assert same_pair(goal.value.pair, *FOLD_PAIR)
    d, pairs = model.distances(Q_FOLD[None])
    assert_allclose(d, [depth], rtol=0, atol=DEPTH_TOL)
    assert same_pair(pairs[0], *FOLD_PAIR)


def test_ur5_srdf_pairs_are_skipped(ur5):
    text = UR5_SRDF.read_text()
    model = ur5_model(ur5, text)
    listed = srdf_pairs(text)
    assert len(listed) == 10
    for a, b, _ in listed:
        assert not checked(model, a, b), (a, b)
        assert skip_reason(model, a, b), (a, b)


def test_srdf_disabling_the_pair_accepts_the_pose(ur5, oracle):
    text = UR5_SRDF.read_text()
    assert not any(same_pair((a, b), *FOLD_PAIR) for a, b, _ in srdf_pairs(text))
    extended = text.replace('</robot>', '  <disable_collisions link1="upper_arm_link" link2="wrist_2_link" '
                                        'reason="Never"/>\n</robot>')
    model = ur5_model(ur5, extended)
    assert not checked(model, *FOLD_PAIR)
    reason = skip_reason(model, *FOLD_PAIR)
    assert reason is not None and 'Never' in reason, reason
    # the only pair in contact was the one disabled: the pose is accepted with the clearance coal finds
    truth = oracle.pair_distances(Q_FOLD, list(model.pairs))
    assert min(truth.values()) > DEFAULT_PADDING + 0.005
    clearance = model.check_state(Q_FOLD)
    assert_allclose(clearance, min(truth.values()), rtol=0, atol=DIST_TOL)
    # with ur5.srdf alone (which does not list the pair) the same pose is refused for that pair
    with pytest.raises(StartInCollisionError) as info:
        ur5_model(ur5, text).check_state(Q_FOLD)
    assert same_pair(info.value.pair, *FOLD_PAIR)


def all_robot_pairs_srdf(links: list[str]) -> str:
    """An SRDF disabling every pair of the given links (leaves only the scene's pairs)."""
    lines = [f'  <disable_collisions link1="{a}" link2="{b}" reason="Never"/>'
             for a, b in itertools.combinations(links, 2)]
    return '<robot name="ur5">\n' + '\n'.join(lines) + '\n</robot>\n'


#: Configurations for the hull test (seeded draws where the sphere beside the forearm is clear of
#: every link's mesh).
HULL_QS = np.array([[-2.6, -1.65, 1.89, 0.52, -2.55, -0.42],
                    [-0.13, -2.14, 1.47, -2.43, -0.68, 0.11],
                    [2.46, 0.54, -0.18, 1.72, -2.95, 1.3],
                    [1.15, 2.01, -0.45, 1.63, 2.38, -2.5]])
#: The sphere: 5 cm radius, 14 cm beside the forearm's axis, 20 cm along it (in the forearm's frame).
HULL_SPHERE_R, HULL_SPHERE_AT = 0.05, np.array([0.0, 0.14, 0.2])


def test_convex_hulls_are_conservative(ur5, oracle):
    robot, _ = ur5
    base = ur5_model(ur5)
    srdf = all_robot_pairs_srdf(list(base.body_names))
    hull_model = ur5_model(ur5, srdf)
    exact_model = ur5_model(ur5, srdf, exact_meshes=True)
    moving = [link for link in UR5_LINKS if link != 'base_link'] + (['ee_link'] if 'ee_link' in base.body_names
                                                                    else [])
    gaps = []
    for q in HULL_QS:
        forearm = oracle.placements(q)['forearm_link']
        centre = forearm.getRotation() @ HULL_SPHERE_AT + forearm.getTranslation()
        sphere = SceneObject('sphere', Shape('sphere', (HULL_SPHERE_R,)), trans(*centre))
        d_hull, pair_hull = hull_model.with_objects([sphere]).distances(q[None])
        d_exact, pair_exact = exact_model.with_objects([sphere]).distances(q[None])
        assert not any(p[0] in base.body_names and p[1] in base.body_names
                       for p in hull_model.with_objects([sphere]).pairs)   # only the sphere's pairs
        exact = oracle.sphere_distance(q, moving, centre, HULL_SPHERE_R, exact=True)
        hull = oracle.sphere_distance(q, moving, centre, HULL_SPHERE_R, exact=False)
        assert exact > 0.0
        assert_allclose(d_exact[0], exact, rtol=0, atol=DIST_TOL)
        assert_allclose(d_hull[0], hull, rtol=0, atol=DIST_TOL)
        assert d_hull[0] <= d_exact[0] + 1e-12                    # the hull never reports more room
        assert 'sphere' in pair_hull[0] and 'sphere' in pair_exact[0]
        gaps.append(d_exact[0] - d_hull[0])
    assert max(gaps) > 5e-3                                       # the hull does differ somewhere


# ---------------------------------------------------------------------------- Panda with its SRDF
def test_panda_srdf_reasons_are_kept_and_its_default_state_is_free():
    robot = load_robot(str(PANDA_URDF), base_link='panda_link0', tip_link='panda_hand_tcp')
    urdf, text = PANDA_URDF.read_text(), PANDA_SRDF.read_text()
    plain = CollisionModel.for_robot(robot, urdf, package_dirs=[str(MESHES)])
    model = CollisionModel.for_robot(robot, urdf, package_dirs=[str(MESHES)], srdf=text)
    arm = [f'panda_link{i}' for i in range(8)] + ['panda_hand']
    assert set(arm) <= set(model.body_names)
    listed = [(a, b, r) for a, b, r in srdf_pairs(text) if a in model.body_names and b in model.body_names]
    assert len(listed) >= 24                                  # the pairs among link0..link7 and the hand
    for a, b, why in listed:
        assert not checked(model, a, b), (a, b)
        reason = skip_reason(model, a, b)
        assert reason, (a, b)
        if skip_reason(plain, a, b) is None:                  # skipped for the SRDF alone: its reason
            assert str(why).lower() in reason.lower(), (a, b, why, reason)
    assert any(skip_reason(plain, a, b) is None for a, b, _ in listed)   # that case occurs
    # the SRDF's "default" group state (fingers aside): free
    q_default = np.array([0.0, -0.785398, 0.0, -2.35619, 0.0, 1.5707, 0.785398])
    assert model.check_state(q_default) > model.padding
