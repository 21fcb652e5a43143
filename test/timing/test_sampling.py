"""Path sampling (geodesic_planner.timing.sampling): the interpolation between the nodes."""
from __future__ import annotations

import numpy as np

from geodesic_planner.timing.sampling import refine_adaptively, sample_path
from timing_paths import curved


def test_path_interpolation_is_the_cubic_hermite_of_the_samples():
    """q', q'' between the nodes: the cubic Hermite basis (oracle) in any order of s."""
    base = refine_adaptively(curved(), sample_path(curved(), 20))
    rng = np.random.default_rng(3)
    s = rng.uniform(0.0, 1.0, 3000)
    a, b = base.interpolate(s)
    k = np.clip(np.searchsorted(base.s, s, side='right') - 1, 0, base.s.size - 2)
    h = (base.s[k + 1] - base.s[k])[:, None]
    x = ((s - base.s[k])[:, None]) / h
    h00, h10, h01, h11 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x, -2 * x**3 + 3 * x**2, x**3 - x**2
    a_ref = h00 * base.aR[k] + h10 * h * base.bR[k] + h01 * base.aL[k + 1] + h11 * h * base.bL[k + 1]
    b_ref = h00 * base.bR[k] + h10 * h * base.cR[k] + h01 * base.bL[k + 1] + h11 * h * base.cL[k + 1]
    np.testing.assert_allclose(a, a_ref, rtol=0.0, atol=1e-12 * np.abs(a_ref).max())
    np.testing.assert_allclose(b, b_ref, rtol=0.0, atol=1e-12 * np.abs(b_ref).max())
    order = np.argsort(s)
    a_sorted, b_sorted = base.interpolate(s[order])  # sorted s takes another code path
    np.testing.assert_array_equal(a_sorted, a[order])
    np.testing.assert_array_equal(b_sorted, b[order])
