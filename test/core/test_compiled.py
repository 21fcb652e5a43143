"""The compiled kernels of core (the splines' polynomials, the chains' kinematics) against the numpy code."""
from __future__ import annotations

import os
import re

import numpy as np
import pytest

from geodesic_planner.core import compiled
from geodesic_planner.core.polynomials import QuinticHermite, evaluate_polynomials

# GP_KERNELS=numpy runs the whole suite on the fallback: nothing compiled to compare then.
pytestmark = pytest.mark.skipif(os.environ.get('GP_KERNELS', '').strip().lower() == 'numpy',
                                reason='GP_KERNELS=numpy: the kernels are off for this run')


def test_kernels_are_built_and_on():
    # The set-up builds the extension with the package: a silent fallback would hide a broken build.
    assert compiled.REASON == 'on' and compiled.active()


@pytest.mark.parametrize('dof', [1, 6, 7])
def test_polynomials_match_numpy(dof):
    rng = np.random.default_rng(dof)
    n = 40
    t = np.concatenate([[0.0], np.sort(rng.uniform(0.0, 2.0, n - 2)), [2.0]])
    c = rng.normal(size=(n - 1, 6, dof))
    inside = np.sort(rng.uniform(0.0, 2.0, 300))
    times = np.concatenate([inside, t, [-0.5, 2.5]])          # knots exactly, and beyond both ends
    for x in (np.sort(times), rng.permutation(times)):
        for order in range(4):
            got = evaluate_polynomials(c, t, x, order)
            with compiled.numpy_only():
                want = evaluate_polynomials(c, t, x, order)
            assert len(got) == len(want) == order + 1
            for g, w in zip(got, want):
                assert g.shape == w.shape == (x.size, dof)
                np.testing.assert_allclose(g, w, rtol=1e-13, atol=1e-13 * np.abs(w).max())


def test_quintic_hermite_matches_numpy_and_its_knots():
    rng = np.random.default_rng(5)
    x = np.linspace(0.0, 1.0, 12)
    y, dy, ddy = (rng.normal(size=(12, 3)) for _ in range(3))
    spline = QuinticHermite(x, y, dy, ddy)
    got = spline(x, order=3)
    with compiled.numpy_only():
        want = spline(x, order=3)
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, w, rtol=1e-13, atol=1e-13)
    # an independent oracle: the interpolant meets its data at the knots
    for g, data in zip(got[:3], (y, dy, ddy)):
        np.testing.assert_allclose(g, data, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize('name', ['ur5e', 'panda', 'rrpp', 'planar_3r'])
def test_kinematics_match_numpy(name):
    from geodesic_planner import load_robot
    robot = load_robot(name)
    rng = np.random.default_rng(len(name))
    lo, hi = np.maximum(robot.lower, -3.0), np.minimum(robot.upper, 3.0)
    q = rng.uniform(lo, hi, (300, robot.dof))
    got = robot.frames(q), robot.generators(q), robot.fk(q), robot.jacobian(q)
    with compiled.numpy_only():
        want = robot.frames(q), robot.generators(q), robot.fk(q), robot.jacobian(q)
    for g, w in zip(got, want):
        for a, b in zip(g if isinstance(g, tuple) else (g,), w if isinstance(w, tuple) else (w,)):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13)
    # an independent oracle: the generators are the derivative of the tool pose
    h = 1e-6
    X, T = got[1]
    for k in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[k] = h
        fd = (robot.fk(q + dq) - robot.fk(q - dq)) / (2 * h)
        np.testing.assert_allclose(X[:, k] @ T, fd, atol=1e-7)


def test_jacobian_rate_matches_numpy_and_finite_differences():
    from geodesic_planner import load_robot
    from geodesic_planner.core.redundant import RedundantEquations
    robot = load_robot('panda')
    rng = np.random.default_rng(9)
    q = robot.home + rng.normal(0.0, 0.3, (20, robot.dof))
    u = rng.normal(size=(20, 3, robot.dof))
    X, T = robot.generators(q)
    got = RedundantEquations.rate(X[:, None], T[:, None], u)      # broadcast as the Newton step does
    with compiled.numpy_only():
        want = RedundantEquations.rate(X[:, None], T[:, None], u)
    assert got.shape == want.shape == (20, 3, 6, robot.dof)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    # an independent oracle: the derivative of the Jacobian along u
    h = 1e-6
    fd = (robot.jacobian(q[:, None] + h * u) - robot.jacobian(q[:, None] - h * u)) / (2 * h)
    np.testing.assert_allclose(got, fd, atol=1e-6)


def _equations(name, metric, seed, n):
    """A factory of fresh geodesic equations (nothing remembered) of robot ``name`` under
    ``metric``, and n random joint positions (within the limits, |q| <= 2) and velocities."""
    from geodesic_planner import load_robot
    from geodesic_planner.core.geodesic import GeodesicEquations
    from geodesic_planner.core.metric import Metric
    robot = load_robot(name)
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(robot.lower, -2.0), np.minimum(robot.upper, 2.0)
    q = rng.uniform(lo, hi, (n, robot.dof))
    return (lambda: GeodesicEquations(robot, Metric(**metric))), q, rng.normal(size=(n, robot.dof))


@pytest.mark.parametrize('name,metric', [('ur5e', {}), ('ur5e', {'position_weight': 2.0, 'orientation_weight': 0.5}),
                                         ('panda', {'epsilon': 1e-3}), ('rrpp', {}), ('planar_3r', {})])
def test_geodesic_acceleration_matches_numpy(name, metric):
    fresh, q, v = _equations(name, metric, 13, 200)
    got = fresh().acceleration(q, v)
    with compiled.numpy_only():
        want = fresh().acceleration(q, v)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())


@pytest.mark.parametrize('name,metric', [('ur5e', {}), ('panda', {'epsilon': 1e-3}), ('rrpp', {}), ('planar_3r', {})])
def test_geodesic_jerk_matches_numpy_and_the_acceleration_s_derivative(name, metric):
    fresh, q, v = _equations(name, metric, 17, 100)
    eq = fresh()
    a, j = eq.jerk(q, v)
    with compiled.numpy_only():
        a0, j0 = fresh().jerk(q, v)
    np.testing.assert_allclose(a, a0, rtol=1e-9, atol=1e-9 * np.abs(a0).max())
    np.testing.assert_allclose(j, j0, rtol=1e-9, atol=1e-9 * np.abs(j0).max())
    # independent: q''' = d/ds a(q(s), q'(s)) = da/dq q' + da/dq' q'', central differences of the
    # (compiled) acceleration along (q + h q', q' + h q'')
    h = 1e-5
    fd = (eq.acceleration(q + h * v, v + h * a) - eq.acceleration(q - h * v, v - h * a)) / (2 * h)
    np.testing.assert_allclose(j, fd, rtol=1e-5, atol=1e-5 * np.abs(j).max())


def test_singular_metric_is_named_as_before():
    # the position metric on a 6-joint arm leaves the orientation free: G is singular, and the
    # compiled path hands over to numpy, which raises the same error
    from geodesic_planner import load_robot
    from geodesic_planner.core.errors import SingularMetricError
    from geodesic_planner.core.geodesic import GeodesicEquations
    from geodesic_planner.core.metric import Metric
    robot = load_robot('ur5e')
    q, v = robot.home[None] + 0.1, np.ones((1, robot.dof))
    with pytest.raises(SingularMetricError) as got:
        GeodesicEquations(robot, Metric(kind='position')).acceleration(q, v)
    with compiled.numpy_only(), pytest.raises(SingularMetricError) as want:
        GeodesicEquations(robot, Metric(kind='position')).acceleration(q, v)
    def words(err: BaseException) -> str:     # the message without its numbers (round-off differs)
        return re.sub(r'[-+]?\d[\d.e+-]*', '#', str(err))
    assert words(got.value) == words(want.value) and "singular for robot 'ur5e'" in str(got.value)
