"""core.chunks: blocks of rows give exactly what one call gives (kinematics, geodesic equations)."""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner import load_robot
from geodesic_planner.core import compiled
from geodesic_planner.core.chunks import CHUNK, in_chunks
from geodesic_planner.core.geodesic import GeodesicEquations
from geodesic_planner.core.metric import Metric

SIZES = (1, CHUNK, CHUNK + 1, 3 * CHUNK + 17)


def test_in_chunks_joins_arrays_tuples_and_none() -> None:
    x = np.arange(2 * CHUNK + 5, dtype=float)
    calls: list[int] = []

    def fn(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, None, np.ndarray]:
        calls.append(a.shape[0])
        return a + b, None, a[:, None] * np.ones((1, 3))

    s, none, m = in_chunks(fn, x, 2 * x)
    assert calls == [CHUNK, CHUNK, 5]
    assert none is None
    np.testing.assert_array_equal(s, 3 * x)
    np.testing.assert_array_equal(m, x[:, None] * np.ones((1, 3)))
    assert in_chunks(lambda a: a * 2, x[:3]).tolist() == [0.0, 2.0, 4.0]


@pytest.mark.parametrize('name', ['ur5e', 'panda', 'rrpp'])
def test_blocks_are_bit_identical_to_one_call(name: str) -> None:
    """The unblocked private bodies are the reference: every row is computed independently."""
    robot = load_robot(name)
    eq = GeodesicEquations(robot, Metric(epsilon=1e-4))
    rng = np.random.default_rng(7)
    for n in SIZES:
        q = rng.uniform(-1.0, 1.0, (n, robot.dof))
        v = rng.uniform(-1.0, 1.0, (n, robot.dof))
        with compiled.numpy_only():      # jerk() is otherwise compiled, in one call
            jerk = (eq.jerk(q, v), eq._jerk(q, v))
        for got, ref in ((robot.frames(q), robot._frames(q)), (robot.generators(q), robot._generators(q)),
                         (eq.evaluate(q, v), eq._evaluate(q, v, True)), jerk):
            for g, r in zip(got, ref):
                np.testing.assert_array_equal(g, r)
