"""Sphere and capsule distances (core.capsules): against coal's, separated and overlapping, and the
compiled kernel against the numpy reference."""
from __future__ import annotations

import coal
import numpy as np
import pytest
from numpy.testing import assert_allclose

from geodesic_planner.core import compiled
from geodesic_planner.core.capsules import capsule_distances, segment_distances
from geodesic_planner.core.transforms import make_transform, so3_exp


def random_bodies(seed: int, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[object]]:
    """``count`` random capsules and spheres (a third of the capsules parallel to the one before):
    frames (1, count, 4, 4), half lengths, radii and the coal geometries."""
    rng = np.random.default_rng(seed)
    frames, half, radius, geoms = [], [], [], []
    for k in range(count):
        R = so3_exp(rng.normal(size=3)) if k % 3 or not frames else frames[-1][:3, :3]
        frames.append(make_transform(rng.uniform(-0.4, 0.4, 3), R))
        h = float(rng.uniform(0.0, 0.4)) if rng.random() > 0.25 else 0.0
        r = float(rng.uniform(0.01, 0.15))
        half.append(h)
        radius.append(r)
        geoms.append(coal.Capsule(r, 2.0 * h) if h > 0.0 else coal.Sphere(r))
    return np.array(frames)[None], np.array(half), np.array(radius), geoms


def coal_distance(P: np.ndarray, geoms: list[object], i: int, j: int) -> float:
    result = coal.DistanceResult()
    Ti = coal.Transform3s(P[0, i, :3, :3], P[0, i, :3, 3])
    Tj = coal.Transform3s(P[0, j, :3, :3], P[0, j, :3, 3])
    return float(coal.distance(geoms[i], Ti, geoms[j], Tj, coal.DistanceRequest(), result))


@pytest.mark.parametrize('kernels', ['compiled', 'numpy'])
def test_capsule_distances_are_coal_distances(kernels: str) -> None:
    if kernels == 'compiled' and not compiled.active():
        pytest.skip(f'compiled kernels {compiled.REASON}')
    P, half, radius, geoms = random_bodies(1, 40)
    ia, ib = np.triu_indices(40, 1)
    n = np.zeros_like(ia)
    if kernels == 'numpy':
        with compiled.numpy_only():
            got = capsule_distances(P, half, radius, n, ia, ib)
    else:
        got = capsule_distances(P, half, radius, n, ia, ib)
    want = np.array([coal_distance(P, geoms, int(i), int(j)) for i, j in zip(ia, ib)])
    assert (want < 0.0).sum() > 20 and (want > 0.0).sum() > 200     # both overlapping and apart
    assert_allclose(got, want, rtol=0.0, atol=1e-13)


def test_compiled_and_numpy_agree_on_many_configurations() -> None:
    if not compiled.active():
        pytest.skip(f'compiled kernels {compiled.REASON}')
    rng = np.random.default_rng(7)
    P = np.stack([random_bodies(s, 6)[0][0] for s in range(50)])      # (50, 6, 4, 4)
    half = np.array([0.0, 0.1, 0.2, 0.0, 0.3, 1e-13])                # spheres, a tiny capsule
    radius = rng.uniform(0.01, 0.1, 6)
    n = rng.integers(0, 50, 500)
    ia = rng.integers(0, 6, 500)
    ib = (ia + rng.integers(1, 6, 500)) % 6
    fast = capsule_distances(P, half, radius, n, ia, ib)
    with compiled.numpy_only():
        slow = capsule_distances(P, half, radius, n, ia, ib)
    assert_allclose(fast, slow, rtol=0.0, atol=1e-15)


def test_segment_distance_cases() -> None:
    o, x, y = np.zeros(3), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    cases = [((o, x, o + y, x + y), 1.0),            # parallel, overlapping in x
             ((o, x, 2 * x + y, 3 * x + y), np.sqrt(2.0)),   # parallel, end to end
             ((o, x, 0.5 * x - y, 0.5 * x + y), 0.0),        # crossing
             ((o, o, x + y, x - y), 1.0),            # a point and a segment
             ((o, o, 3 * y, 3 * y), 3.0)]            # two points
    for (a0, a1, b0, b1), want in cases:
        got = segment_distances(*(np.asarray(v, dtype=float)[None] for v in (a0, a1, b0, b1)))
        assert got[0] == pytest.approx(want, abs=1e-15)
