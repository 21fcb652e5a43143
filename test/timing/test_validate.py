"""JTC's trajectory rules (geodesic_planner.timing.validate): one mutation of a valid trajectory per case."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from geodesic_planner.core.errors import RequestError, TrajectoryError
from geodesic_planner.timing import check_trajectory, trajectory_problems
from geodesic_planner.timing.validate import MAX_PROBLEMS


def valid():
    """A valid 3-joint, 4-point trajectory at rest at the end (as lists, like a message)."""
    return dict(joint_names=['a', 'b', 'c'], times=[0.0, 0.5, 1.0, 1.5],
                positions=[[0.0, 0.1, 0.2], [0.1, 0.2, 0.3], [0.2, 0.3, 0.4], [0.3, 0.4, 0.5]],
                velocities=[[0.0] * 3, [0.2] * 3, [0.2] * 3, [0.0] * 3],
                accelerations=[[0.0] * 3, [0.1] * 3, [-0.1] * 3, [0.0] * 3])


def mutated(key, fn):
    traj = valid()
    traj[key] = fn(traj[key])
    return traj


def with_row(i, row):
    def fn(rows):
        rows = list(rows)
        rows[i] = row
        return rows
    return fn


CASES = {
    'no joint names': (mutated('joint_names', lambda _: []), 'no joint names'),
    'empty joint name': (mutated('joint_names', lambda n: ['a', '', 'c']), 'empty joint name at index 1'),
    'duplicate joint name': (mutated('joint_names', lambda n: ['a', 'b', 'a']), "duplicate joint names: ['a']"),
    'no points': ({**valid(), 'times': [], 'positions': [], 'velocities': [], 'accelerations': []}, 'no points'),
    'short positions': (mutated('positions', with_row(2, [0.2, 0.3])), 'point 2: 2 positions, expected 3'),
    'empty positions': (mutated('positions', with_row(1, [])), 'point 1: 0 positions'),
    'long velocities': (mutated('velocities', with_row(1, [0.2] * 4)), 'point 1: 4 velocities'),
    'short accelerations': (mutated('accelerations', with_row(2, [0.1])), 'point 2: 1 accelerations'),
    'nan position': (mutated('positions', with_row(3, [0.3, np.nan, 0.5])), 'point 3: positions contain NaN'),
    'inf velocity': (mutated('velocities', with_row(1, [0.2, np.inf, 0.2])), 'point 1: velocities contain NaN or inf'),
    'negative time': (mutated('times', lambda t: [-0.1] + t[1:]), 'point 0: time_from_start -0.1 s is negative'),
    'equal times': (mutated('times', lambda t: [0.0, 0.5, 0.5, 1.5]),
                    'point 2: time_from_start 0.5 s is not after point 1'),
    'equal after ns rounding': (mutated('times', lambda t: [0.0, 0.5, 0.5 + 1e-10, 1.5]), 'point 2:'),
    'decreasing time': (mutated('times', lambda t: [0.0, 1.0, 0.5, 1.5]), 'point 2:'),
    'nan time': (mutated('times', lambda t: [0.0, np.nan, 1.0, 1.5]), 'point 1: time_from_start nan'),
    'moving at the end': (mutated('velocities', with_row(3, [0.0, 0.01, 0.0])), "point 3: final velocity of joint 'b'"),
    'too few rows': (mutated('positions', lambda p: p[:3]), 'positions: 3 rows for 4 points'),
    'not numbers': (mutated('positions', with_row(0, ['x', 'y', 'z'])), 'positions: expected one row of numbers'),
}


def test_the_valid_trajectory_passes_in_every_form():
    assert trajectory_problems(**valid()) == []
    arrays = {k: (np.asarray(v) if k != 'joint_names' else v) for k, v in valid().items()}
    assert trajectory_problems(**arrays) == []
    # Empty velocity / acceleration rows are allowed (JTC), as is leaving them out.
    t = valid()
    assert trajectory_problems(t['joint_names'], t['times'], t['positions'], [[]] * 4, [[]] * 4) == []
    assert trajectory_problems(t['joint_names'], t['times'], t['positions']) == []


@pytest.mark.parametrize('case', sorted(CASES))
def test_one_mutation_one_problem(case):
    traj, expected = CASES[case]
    problems = trajectory_problems(**traj)
    assert len(problems) == 1, problems
    assert expected in problems[0]
    with pytest.raises(TrajectoryError, match='would be rejected') as err:
        check_trajectory(**traj)
    assert expected in str(err.value)
    assert isinstance(err.value, RequestError)


def test_nonzero_final_velocity_allowed_on_request():
    traj = mutated('velocities', with_row(3, [0.1, 0.1, 0.1]))
    assert len(trajectory_problems(**traj)) == 3  # one per moving joint
    assert trajectory_problems(**traj, require_rest_at_end=False) == []


def test_output_is_bounded():
    n = 10_000
    t = np.linspace(0.0, 1.0, n)
    t[1::2] = 0.0  # every other step goes back in time
    q = np.full((n, 2), np.nan)
    problems = trajectory_problems(['a', 'b'], t, q)
    assert len(problems) == MAX_PROBLEMS + 1
    hidden = int(problems[-1].split()[2])
    assert problems[-1] == f'... and {hidden} more' and hidden > n


def test_large_trajectory_is_checked_quickly():
    import time
    n = 200_000
    t = np.arange(n) * 1e-3
    q = np.zeros((n, 7))
    start = time.perf_counter()
    assert trajectory_problems([f'j{i}' for i in range(7)], t, q, q, q) == []
    assert time.perf_counter() - start < 0.5  # vectorised: no per-value Python loop


# ------------------------------------------------------------------ property: any one mutation is found
@st.composite
def trajectories(draw):
    dof = draw(st.integers(1, 6))
    n = draw(st.integers(1, 12))
    steps = draw(st.lists(st.floats(1e-3, 2.0), min_size=n, max_size=n))
    t = np.cumsum(steps) - steps[0]
    finite = st.floats(-10.0, 10.0)
    q = np.array(draw(st.lists(st.lists(finite, min_size=dof, max_size=dof), min_size=n, max_size=n)))
    v = np.array(draw(st.lists(st.lists(finite, min_size=dof, max_size=dof), min_size=n, max_size=n)))
    v[-1] = 0.0
    names = [f'joint_{i}' for i in range(dof)]
    return names, t, q, v


MUTATIONS = ['duplicate name', 'empty name', 'drop position', 'nan position', 'extra velocity',
             'time back', 'negative start', 'final velocity']


@settings(max_examples=150, deadline=None)
@given(trajectories(), st.sampled_from(MUTATIONS), st.data())
def test_random_valid_trajectories_pass_and_any_single_mutation_is_reported(traj, mutation, data):
    names, t, q, v = traj
    assert trajectory_problems(names, t, q, v) == []
    n, dof = q.shape
    i = data.draw(st.integers(0, n - 1))
    j = data.draw(st.integers(0, dof - 1))
    names, t, q, v = list(names), t.copy(), [list(r) for r in q], [list(r) for r in v]
    if mutation == 'duplicate name':
        if dof < 2:
            return
        names[j] = names[(j + 1) % dof]
    elif mutation == 'empty name':
        names[j] = ''
    elif mutation == 'drop position':
        q[i] = q[i][:-1]
    elif mutation == 'nan position':
        q[i][j] = float('nan')
    elif mutation == 'extra velocity':
        v[i] = v[i] + [0.0]
    elif mutation == 'time back':
        if n < 2:
            return
        k = max(i, 1)
        t[k] = t[k - 1]
    elif mutation == 'negative start':
        t[0] = -1e-3
    elif mutation == 'final velocity':
        v[-1][j] = 1e-3
    assert trajectory_problems(names, t, q, v), mutation
