"""The smoothed rest-to-rest law (geodesic_planner.timing.smoothing): continuity, evaluation order."""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner.timing import time_parameterize
from timing_paths import ZigZagPath, curved


def test_acceleration_is_continuous():
    traj = time_parameterize(curved())
    t = np.linspace(0.0, traj.duration, 200001)
    _, _, ddq = traj.at_time(t)
    jumps = np.max(np.abs(np.diff(ddq, axis=0)) / traj.max_acceleration)
    assert jumps < 0.01  # a bang-bang (TOPP) law would jump by about 2 amax here
    jerk = traj.jerk_at_time(t)
    assert np.all(np.isfinite(jerk))


@pytest.mark.parametrize('path', [curved(), ZigZagPath(np.linspace(0.0, 1.0, 6))], ids=['one piece', 'five pieces'])
def test_time_law_does_not_depend_on_the_order_of_the_times(path):
    traj = time_parameterize(path)
    t = np.concatenate([np.linspace(0.0, traj.duration, 2001), np.array(traj.rest_times)])
    t = np.concatenate([t, t + 1e-13])  # also just past each rest
    order = np.random.default_rng(5).permutation(t.size)
    sorted_t = np.sort(t)
    ref = traj._s_all(sorted_t)  # sorted times take another code path
    got = traj._s_all(t[order])
    rank = np.argsort(np.argsort(t[order], kind='stable'), kind='stable')
    for r, g in zip(ref, got):
        np.testing.assert_array_equal(g, r[rank])


@pytest.mark.parametrize('options, match', [(dict(grid_points=1), 'grid_points'), (dict(refine=0), 'refine'),
                                            (dict(smoothing=0.0), 'smoothing'), (dict(smoothing=1.5), 'smoothing')])
def test_law_options_out_of_range_are_refused(options, match):
    from geodesic_planner.core.errors import LimitError
    from geodesic_planner.timing import SmoothRestToRest
    with pytest.raises(LimitError, match=match):
        SmoothRestToRest(**options)
    with pytest.raises(LimitError, match=match):
        time_parameterize(curved(), **options)
