"""The path-coupled lower bound of test/timing/jerk_bound.py (used by benchmarks/peers.py).

On a straight joint line whose tightest joint's limits bind, the fastest rest-to-rest motion is
that joint's 7-segment profile. When it cruises, its speed is at every instant the smaller of the
fastest ramp from rest since the start and until the end, and the coupled bound is the optimum
itself; without a cruise the two ramps meet in a kink the profile cannot follow, and the bound is
lower. Checked against the closed-form minimum time (min_rest_to_rest_time, checked against a
linear program in test_jerk.py): never above it, and equal within its discretisation when it cruises.
"""
from __future__ import annotations

import numpy as np
import pytest

from jerk_bound import coupled_lower_bound, greedy_speed, min_rest_to_rest_time


@pytest.mark.parametrize('distance, jmax, cruises', [(0.05, 50.0, False), (0.6, 15.0, False), (2.5, 15.0, True),
                                                      (2.5, 400.0, True)])
def test_coupled_bound_on_a_line(distance: float, jmax: float, cruises: bool) -> None:
    vmax, amax = np.array([2.0, 3.0]), np.array([4.0, 5.0])
    jm = np.full(2, jmax)
    dq = np.tile([distance, 0.3 * distance], (801, 1))          # q' along s in [0, 1]
    best = float(min_rest_to_rest_time(np.abs(dq[0]), vmax, amax, jm).max())
    x_star = np.full(801, np.inf)                                  # no v/a cap: the ramps alone
    bound = coupled_lower_bound(dq, x_star, vmax, amax, jm, 0.5 * best, 1.5 * best)
    assert bound <= best * (1.0 + 1e-9)
    assert bound >= best * (1.0 - 2e-3 if cruises else 0.8)


def test_greedy_speed_is_the_seven_segment_ramp() -> None:
    """Integrated until it reaches vmax, the ramp covers the distance of the 7-segment profile's
    first half (which ends at vmax when the profile cruises)."""
    v, a, j = 2.0, 4.0, 15.0
    t_ramp = v / a + a / j
    t = np.linspace(0.0, t_ramp, 200001)
    speed = greedy_speed(t, v, a, j)
    assert speed[-1] == pytest.approx(v, rel=1e-12)
    assert np.all(np.diff(speed) >= -1e-15)
    covered = float(np.sum(0.5 * (speed[1:] + speed[:-1]) * np.diff(t)))
    d = 3.0       # cruises: T = t_ramp + d / v
    assert float(min_rest_to_rest_time(d, v, a, j)) == pytest.approx(2.0 * t_ramp + (d - 2.0 * covered) / v, rel=1e-9)
