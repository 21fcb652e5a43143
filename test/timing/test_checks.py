"""timing.checks.range_max (the local slow-down's cap) against a loop over the intervals."""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner.timing.checks import range_max


def _by_loop(n: int, lo: np.ndarray, hi: np.ndarray, value: np.ndarray) -> np.ndarray:
    out = np.full(n, -np.inf)
    for a, b, f in zip(lo.tolist(), hi.tolist(), value.tolist()):
        if b > a:
            out[a:b] = np.maximum(out[a:b], f)
    return out


@pytest.mark.parametrize('seed', range(5))
def test_range_max_equals_the_loop(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(100):
        n = int(rng.integers(1, 300))
        k = int(rng.integers(0, 60))
        lo = rng.integers(0, n + 1, k)
        hi = np.minimum(lo + rng.integers(-3, n, k), n)      # some empty or reversed intervals
        value = rng.normal(size=k)
        assert np.array_equal(range_max(n, lo, hi, value), _by_loop(n, lo, hi, value))


def test_range_max_edges() -> None:
    assert np.array_equal(range_max(4, np.array([], int), np.array([], int), np.array([])), np.full(4, -np.inf))
    assert np.array_equal(range_max(5, np.array([0]), np.array([5]), np.array([2.0])), np.full(5, 2.0))
    got = range_max(6, np.array([1, 3]), np.array([2, 6]), np.array([7.0, 1.0]))
    assert np.array_equal(got, [-np.inf, 7.0, -np.inf, 1.0, 1.0, 1.0])
