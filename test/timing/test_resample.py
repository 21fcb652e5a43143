"""Resampling and velocity scaling against exact polynomial oracles (no ROS)."""
from __future__ import annotations

import numpy as np
import pytest
from numpy.polynomial import Polynomial
from numpy.testing import assert_allclose, assert_array_equal

from geodesic_planner.core.errors import RequestError
from geodesic_planner.core.polynomials import quintic_coefficients
from geodesic_planner.timing.resample import (
    process_trajectory,
    resample,
    sample_times,
    scale_velocity,
)


def _random_polys(rng: np.random.Generator, degree: int, dof: int) -> list[Polynomial]:
    return [Polynomial(rng.uniform(-1.0, 1.0, degree + 1)) for _ in range(dof)]


def _eval(polys: list[Polynomial], t: np.ndarray, order: int = 0) -> np.ndarray:
    return np.stack([p.deriv(order)(t) if order else p(t) for p in polys], axis=1)


def _knots(rng: np.random.Generator, n: int, t_end: float) -> np.ndarray:
    inner = np.sort(rng.uniform(0.0, t_end, n - 2))
    return np.concatenate([[0.0], inner, [t_end]])


def _hermite_oracle(t0, t1, p0, v0, a0, p1, v1, a1, tau):
    """Quintic through the six boundary conditions by a linear solve (independent of the code)."""
    h = t1 - t0
    rows = [
        [1, 0, 0, 0, 0, 0],
        [0, 1, 0, 0, 0, 0],
        [0, 0, 2, 0, 0, 0],
        [1, h, h**2, h**3, h**4, h**5],
        [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
        [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3],
    ]
    c = np.linalg.solve(np.array(rows, dtype=float), np.array([p0, v0, a0, p1, v1, a1]))
    poly = Polynomial(c)
    return poly(tau), poly.deriv(1)(tau), poly.deriv(2)(tau)


@pytest.mark.parametrize('seed', range(5))
def test_global_quintic_reproduced_exactly(seed):
    rng = np.random.default_rng(seed)
    polys = _random_polys(rng, 5, 3)
    t = _knots(rng, 7, 2.0)
    q, dq, ddq = (_eval(polys, t, k) for k in range(3))
    t_new, q_new, dq_new, ddq_new = resample(t, q, dq, ddq, 0.013)
    assert_allclose(q_new, _eval(polys, t_new), rtol=0, atol=1e-12)
    assert_allclose(dq_new, _eval(polys, t_new, 1), rtol=0, atol=1e-11)
    assert_allclose(ddq_new, _eval(polys, t_new, 2), rtol=0, atol=1e-10)


def test_piecewise_quintic_matches_linear_solve_oracle():
    rng = np.random.default_rng(42)
    t = np.array([0.0, 0.4, 0.45, 1.3, 2.0])
    q, dq, ddq = (rng.uniform(-2, 2, (5, 2)) for _ in range(3))
    t_new, q_new, dq_new, ddq_new = resample(t, q, dq, ddq, 0.01)
    for j, tj in enumerate(t_new):
        i = min(np.searchsorted(t, tj, side='right') - 1, len(t) - 2)
        for d in range(2):
            exp = _hermite_oracle(t[i], t[i + 1], q[i, d], dq[i, d], ddq[i, d],
                                  q[i + 1, d], dq[i + 1, d], ddq[i + 1, d], tj - t[i])
            assert_allclose([q_new[j, d], dq_new[j, d], ddq_new[j, d]], exp, rtol=0, atol=1e-9)


def test_quintic_coefficients_reproduce_boundary_conditions():
    rng = np.random.default_rng(3)
    t = np.array([0.0, 0.7, 1.9])
    q, dq, ddq = (rng.normal(size=(3, 4)) for _ in range(3))
    c = quintic_coefficients(t, q, dq, ddq)
    assert c.shape == (2, 6, 4)
    for i in range(2):
        h = t[i + 1] - t[i]
        powers = h ** np.arange(6)
        assert_allclose(powers @ c[i], q[i + 1], atol=1e-12)
        assert_allclose((np.arange(6) * h ** np.maximum(np.arange(6) - 1, 0)) @ c[i], dq[i + 1], atol=1e-11)


def test_global_cubic_reproduced_from_positions_and_velocities():
    rng = np.random.default_rng(7)
    polys = _random_polys(rng, 3, 2)
    t = _knots(rng, 6, 1.5)
    t_new, q_new, dq_new, ddq_new = resample(t, _eval(polys, t), _eval(polys, t, 1), None, 0.02)
    assert_allclose(q_new, _eval(polys, t_new), atol=1e-12)
    assert_allclose(dq_new, _eval(polys, t_new, 1), atol=1e-11)
    assert_allclose(ddq_new, _eval(polys, t_new, 2), atol=1e-10)


def test_positions_only_clamped_spline_reproduces_rest_to_rest_cubic():
    # p(t) = 3 t^2 - 2 t^3 on [0, 1]: zero velocity at both ends, so the clamped spline is p itself.
    t = np.array([0.0, 0.2, 0.5, 0.9, 1.0])
    p = Polynomial([0.0, 0.0, 3.0, -2.0])
    q = np.stack([p(t), -2.0 * p(t)], axis=1)
    t_new, q_new, dq_new, ddq_new = resample(t, q, None, None, 0.05)
    assert_allclose(q_new[:, 0], p(t_new), atol=1e-12)
    assert_allclose(q_new[:, 1], -2.0 * p(t_new), atol=1e-12)
    assert_allclose(dq_new[:, 0], p.deriv()(t_new), atol=1e-11)
    assert_allclose(ddq_new[:, 0], p.deriv(2)(t_new), atol=1e-10)
    assert_array_equal(dq_new[[0, -1]], 0.0)


def test_uniform_grid_and_exact_end():
    rng = np.random.default_rng(0)
    t = np.array([0.0, 0.8, 2.1337])
    q, dq, ddq = (rng.normal(size=(3, 2)) for _ in range(3))
    t_new, q_new, dq_new, ddq_new = resample(t, q, dq, ddq, 0.01)
    assert t_new[0] == 0.0
    assert t_new[-1] == t[-1]
    assert_allclose(np.diff(t_new)[:-1], 0.01, rtol=0, atol=1e-12)
    assert 0.0 < t_new[-1] - t_new[-2] <= 0.01
    assert len(t_new) == 215  # 0, 0.01, ..., 2.13 and 2.1337
    # waypoints are reproduced exactly where the grid hits them (t = 0.8) and at both ends
    k = int(np.flatnonzero(np.isclose(t_new, 0.8, atol=1e-12))[0])
    assert_allclose(q_new[k], q[1], atol=1e-12)
    assert_array_equal(q_new[[0, -1]], q[[0, -1]])
    assert_array_equal(dq_new[[0, -1]], dq[[0, -1]])
    assert_array_equal(ddq_new[[0, -1]], ddq[[0, -1]])


def test_rest_to_rest_ends_at_rest():
    t = np.array([0.0, 1.0, 2.0])
    q = np.array([[0.0, 1.0], [0.5, 0.0], [1.0, -1.0]])
    dq = np.array([[0.0, 0.0], [0.7, -1.0], [0.0, 0.0]])
    ddq = np.zeros((3, 2))
    for f in (1.0, 0.5, 0.3):
        t_new, q_new, dq_new, ddq_new = process_trajectory(t, q, dq, ddq, sample_period=0.01, velocity_scaling=f)
        assert t_new[-1] == pytest.approx(2.0 / f, abs=1e-15)
        assert_array_equal(q_new[-1], q[-1])
        assert_array_equal(dq_new[-1], 0.0)
        assert_array_equal(ddq_new[-1], 0.0)
        assert_array_equal(dq_new[0], 0.0)


def test_sample_times_edge_cases():
    assert_allclose(sample_times(0.0, 0.3, 0.1), [0.0, 0.1, 0.2, 0.3], atol=1e-15)
    assert sample_times(0.0, 0.3, 0.1)[-1] == 0.3
    assert_allclose(sample_times(0.0, 0.35, 0.1), [0.0, 0.1, 0.2, 0.3, 0.35], atol=1e-15)
    assert_array_equal(sample_times(1.0, 1.0, 0.1), [1.0])
    # end a hair after a grid point: no sliver, the grid point is replaced by the end
    ts = sample_times(0.0, 0.3 + 1e-9, 0.1)
    assert len(ts) == 4
    assert ts[-1] == 0.3 + 1e-9
    assert_allclose(sample_times(0.0, 0.05, 0.1), [0.0, 0.05])


@pytest.mark.parametrize('f', [1.0, 0.5, 0.37, 1e-3])
def test_scale_velocity_identities_exact(f):
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 3, 9))
    dq, ddq = rng.normal(size=(9, 3)), rng.normal(size=(9, 3))
    ts, dqs, ddqs = scale_velocity(t, dq, ddq, f)
    assert_array_equal(ts, t / f)
    assert_array_equal(dqs, dq * f)
    assert_array_equal(ddqs, ddq * (f * f))
    assert scale_velocity(t, None, None, f)[1:] == (None, None)


@pytest.mark.parametrize('f', [0.5, 0.25, 0.8])
def test_scaled_resampling_is_time_scaled_original(f):
    """Q(t) = P(f t): positions on the same path, velocities x f, accelerations x f^2."""
    rng = np.random.default_rng(11)
    polys = _random_polys(rng, 5, 3)
    t = _knots(rng, 5, 1.7)
    q, dq, ddq = (_eval(polys, t, k) for k in range(3))
    t_new, q_new, dq_new, ddq_new = process_trajectory(t, q, dq, ddq, sample_period=0.01, velocity_scaling=f)
    assert t_new[-1] == t[-1] / f
    assert_allclose(np.diff(t_new)[:-1], 0.01, atol=1e-12)
    assert_allclose(q_new, _eval(polys, f * t_new), atol=1e-12)
    assert_allclose(dq_new, f * _eval(polys, f * t_new, 1), atol=1e-11)
    assert_allclose(ddq_new, f * f * _eval(polys, f * t_new, 2), atol=1e-10)
    # same path: the slowed samples are the unscaled interpolant's samples at f * t
    t_ref, q_ref, _, _ = resample(t, q, dq, ddq, 0.01 * f)
    assert len(t_ref) == len(t_new)
    assert_allclose(q_new, q_ref, atol=1e-12)


def test_single_point_trajectory():
    t_new, q_new, dq_new, ddq_new = resample(np.array([0.0]), np.array([[1.0, 2.0]]), None, None, 0.01)
    assert_array_equal(t_new, [0.0])
    assert_array_equal(q_new, [[1.0, 2.0]])
    assert_array_equal(dq_new, [[0.0, 0.0]])


@pytest.mark.parametrize('f', [0.0, -0.5, 1.5, float('nan'), float('inf'), 'fast'])
def test_bad_velocity_scaling_rejected(f):
    with pytest.raises(RequestError, match=r'velocity scaling'):
        scale_velocity(np.array([0.0, 1.0]), None, None, f)
    with pytest.raises(RequestError, match=r'velocity scaling'):
        process_trajectory(np.array([0.0, 1.0]), np.zeros((2, 1)), None, None, sample_period=0.1, velocity_scaling=f)


@pytest.mark.parametrize('period', [0.0, -0.01, float('nan'), float('inf')])
def test_bad_sample_period_rejected(period):
    with pytest.raises(RequestError, match='sample_period'):
        resample(np.array([0.0, 1.0]), np.zeros((2, 1)), None, None, period)


def test_bad_inputs_named():
    q = np.zeros((3, 2))
    with pytest.raises(RequestError, match=r'strictly increasing: t\[2\]'):
        resample(np.array([0.0, 1.0, 1.0]), q, None, None, 0.1)
    with pytest.raises(RequestError, match='positions contain non-finite'):
        resample(np.array([0.0, 1.0, 2.0]), np.array([[0, 0], [np.nan, 0], [1, 1.0]]), None, None, 0.1)
    with pytest.raises(RequestError, match=r'velocities must have shape \(3, 2\)'):
        resample(np.array([0.0, 1.0, 2.0]), q, np.zeros((3, 3)), None, 0.1)
    with pytest.raises(RequestError, match='times contain non-finite'):
        resample(np.array([0.0, np.inf, 2.0]), q, None, None, 0.1)
    with pytest.raises(RequestError, match='non-empty'):
        resample(np.array([]), np.zeros((0, 2)), None, None, 0.1)
    with pytest.raises(RequestError, match='limit'):
        resample(np.array([0.0, 1e6]), np.zeros((2, 1)), None, None, 1e-3)


def test_sample_count_is_what_sample_times_gives_at_most() -> None:
    """The one sample count (nodes check it before allocating): floor(span / dt) + 2, an upper
    bound of len(sample_times) that is reached when the span is not a multiple of the period."""
    from geodesic_planner.timing.resample import sample_count, sample_times

    for span, dt in ((1.0, 0.01), (1.005, 0.01), (0.3, 0.1), (2.5, 0.7), (0.0, 0.01), (1e-3, 1.0)):
        n = sample_count(span, dt)
        got = len(sample_times(0.0, span, dt))
        assert got <= n <= got + 1, (span, dt, got, n)
    assert sample_count(1.005, 0.01) == 102 == len(sample_times(0.0, 1.005, 0.01))
    assert sample_count(1.0, 1e-320) == float('inf')
    assert sample_count(float('inf'), 0.01) == float('inf')
