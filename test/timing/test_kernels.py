"""The compiled kernels (geodesic_planner.timing.kernels) against the numpy code they replace.

Each kernel is compared with the numpy fallback on the same inputs, or with a plain loop written
here (the TOPP recursions); the time laws are then run both ways on synthetic and real paths,
plain and blended, with and without jerk and tool limits: same durations, same motion.
"""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from geodesic_planner.timing import box_check, kernels, time_parameterize
from geodesic_planner.timing.sampling import sample_path

from timing_paths import CornerPath, ZigZagPath, _ur5e_line_path, curved

# GP_KERNELS=numpy runs the whole suite on the fallback: nothing compiled to compare then.
pytestmark = pytest.mark.skipif(os.environ.get('GP_KERNELS', '').strip().lower() == 'numpy',
                                reason='GP_KERNELS=numpy: the kernels are off for this run')


def test_kernels_are_built_and_on():
    # The set-up builds the extension with the package: a silent fallback would hide a broken build.
    assert kernels.REASON == 'on' and kernels.active()
    with kernels.numpy_only():
        assert not kernels.active()
    assert kernels.active()


def test_environment_switches_them_off():
    code = 'from geodesic_planner.timing import kernels; print(kernels.active(), kernels.REASON)'
    out = subprocess.run([sys.executable, '-c', code], env={**os.environ, 'GP_KERNELS': 'numpy'},
                         capture_output=True, text=True, check=True).stdout
    assert out.strip() == 'False off: GP_KERNELS=numpy'


def _times(law, rng):
    """Sorted times over [-0.1, duration + 0.1], the rests exactly and within round-off of them."""
    T = law.duration
    offs = np.asarray(law.t_offsets, dtype=float)
    t = np.concatenate([np.linspace(-0.1, T + 0.1, 3001), offs, offs + 1e-13 * T, offs - 1e-13 * T,
                        rng.uniform(0.0, T, 500)])
    return np.sort(t)


def _law_cases():
    zig = ZigZagPath([0.0, 0.3, 0.55, 1.0])
    return [('curved', curved(), 3.0), ('zigzag', zig, 5.0), ('corner', CornerPath([1.0, 0.5], [0.2, -1.0]), 4.0)]


@pytest.mark.parametrize('name,path,jerk', _law_cases(), ids=lambda v: v if isinstance(v, str) else '')
def test_law_evaluation_matches_numpy(name, path, jerk):
    rng = np.random.default_rng(7)
    for kw in ({}, {'max_jerk': jerk}):
        law = time_parameterize(path, **kw).scaling
        t = _times(law, rng)
        for order in (t, rng.permutation(t)):       # sorted and unsorted times
            for jerk_too in (True, False):
                got = law.evaluate(order, jerk=jerk_too)
                with kernels.numpy_only():
                    want = law.evaluate(order, jerk=jerk_too)
                assert (got[3] is None) == (want[3] is None) == (not jerk_too)
                for g, w in zip(got, want):
                    if w is not None:
                        np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12 * max(1.0, np.abs(w).max()))


def test_hermite_ratios_match_the_interpolation():
    path = curved()
    ps = sample_path(path, 40)
    rng = np.random.default_rng(3)
    s = np.concatenate([ps.s, rng.uniform(0.0, 1.0, 700), [0.0, 1.0]])
    sd, sdd, sddd = rng.uniform(0.0, 2.0, s.size), rng.normal(0.0, 3.0, s.size), rng.normal(0.0, 9.0, s.size)
    vmax, amax, jmax = np.array([1.0, 1.5, 0.8]), np.array([3.0, 2.0, 4.0]), np.array([10.0, 20.0, 30.0])
    a, b = ps.interpolate_t(s)
    c = ps.third_derivative_t(np.sort(s))[:, np.argsort(np.argsort(s))]
    want_v = (np.abs(a * sd) / vmax[:, None]).max(axis=0)
    want_a = (np.abs(a * sdd + b * sd**2) / amax[:, None]).max(axis=0)
    want_j = (np.abs(a * sddd + 3.0 * b * sd * sdd + c * sd**3) / jmax[:, None]).max(axis=0)
    lim = kernels.limit_tables(vmax, amax, jmax)
    rv, ra, rj = kernels.hermite_ratios(ps.kernel_tables3, lim, s, sd, sdd, sddd)
    for got, want in ((rv, want_v), (ra, want_a), (rj, want_j)):
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14)
    rv2, ra2, none = kernels.hermite_ratios(ps.kernel_tables, lim, s, sd, sdd)
    assert none is None
    np.testing.assert_array_equal(rv2, rv)
    np.testing.assert_array_equal(ra2, ra)
    # NaN propagates, as numpy's max does (a bad sample is never taken for a small ratio)
    sd[5] = np.nan
    rv3, ra3, _ = kernels.hermite_ratios(ps.kernel_tables, lim, s, sd, sdd)
    assert np.isnan(rv3[5]) and np.isnan(ra3[5]) and np.isfinite(rv3[6])


def _backward_loop(A, B, static):
    hi = np.zeros(static.size + 1)
    for k in range(static.size - 1, -1, -1):
        hi[k] = min([static[k]] + [a * hi[k + 1] + b for a, b in zip(A[k], B[k])])
    return hi


def _forward_loop(alpha, d, two_h, hi):
    x = np.zeros(two_h.size + 1)
    for k in range(two_h.size):
        u = min([(hi[k + 1] - x[k]) / two_h[k]] + [a * x[k] + b for a, b in zip(alpha[k], d[k])])
        x[k + 1] = min(max(x[k] + two_h[k] * u, 0.0), hi[k + 1])
    return x


def test_topp_passes_are_the_exact_recursions():
    rng = np.random.default_rng(11)
    n, R = 300, 12
    A = rng.uniform(0.5, 1.5, (n, R))
    B = rng.uniform(0.0, 2.0, (n, R))
    B[rng.random((n, R)) < 0.05] = np.inf                 # rows that do not bind
    static = rng.uniform(0.5, 5.0, n)
    static[[40, 41, 200]] = 0.0                           # rests
    hi = kernels.backward_pass(A, B, static)
    np.testing.assert_array_equal(hi, _backward_loop(A, B, static))
    alpha, d = rng.normal(0.0, 1.0, (n, R)), rng.uniform(0.1, 3.0, (n, R))
    two_h = np.full(n, 2.0 / n)
    x = kernels.forward_pass(alpha, d, two_h, hi)
    np.testing.assert_array_equal(x, _forward_loop(alpha, d, two_h, hi))
    assert x[0] == 0.0 and np.all(x <= hi) and np.all(x >= 0.0)


def _same_law(path, **kw):
    got = time_parameterize(path, **kw)
    with kernels.numpy_only():
        want = time_parameterize(path, **kw)
    assert got.duration == pytest.approx(want.duration, rel=1e-9)
    assert got.rest_times == pytest.approx(want.rest_times, rel=1e-9, abs=1e-12)
    t = np.linspace(0.0, got.duration, 401)
    for g, w in zip(got.at_time(t), want.at_time(t * (want.duration / got.duration))):
        np.testing.assert_allclose(g, w, rtol=1e-7, atol=1e-7 * max(1.0, np.abs(w).max()))
    return got


@pytest.mark.parametrize('name,path,jerk', _law_cases(), ids=lambda v: v if isinstance(v, str) else '')
def test_laws_are_the_same_with_numpy(name, path, jerk):
    _same_law(path)
    _same_law(path, max_jerk=jerk)
    _same_law(path, duration=1.3 * _same_law(path).duration)


def test_real_arm_laws_are_the_same_with_numpy():
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    path = planner.plan(T_a, T_b, start_joints=q_a)
    free = _same_law(path)
    _same_law(path, max_tool_speed=0.1)                        # tool rows in the check
    peak = np.abs(free.jerk_at_time(np.linspace(0.0, free.duration, 4001))).max(axis=0)
    _same_law(path, max_jerk=0.3 * peak)
    # a blended sequence (many pieces of s*, local slow-down passes, the cruise cap)
    poses = [T_a, T_b, T_a.copy()]
    poses[2][:3, 3] += [0.05, 0.1, -0.05]
    seq = planner.plan_through(poses, start_joints=q_a, blend_radius=0.02)
    _same_law(seq)
    _same_law(seq, max_jerk=50.0)


def _search_checks(path, monkeypatch, **kw):
    """(checker, law) of every width-search check while ``path`` is timed with ``kw``."""
    from geodesic_planner.timing.box_filter import build_box_law
    seen, search = [], box_check.BoxCheck.search

    def spy(checker, pieces, tables, width, above=np.inf):
        seen.append((checker, build_box_law(pieces, width, tables)))
        return search(checker, pieces, tables, width, above)
    monkeypatch.setattr(box_check.BoxCheck, 'search', spy)
    time_parameterize(path, **kw)
    monkeypatch.setattr(box_check.BoxCheck, 'search', search)
    return seen


def test_search_grid_is_the_numpy_grid(monkeypatch):
    # gp_box_search_grid builds the width search's grid itself (uniform times, np.interp of the
    # s-uniform samples, the middles of the jerk events' gaps, sorted and each once): the same
    # times, bit for bit, as BoxCheck._dense(full=False), and the same law and ratios there
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    poses = [T_a, T_b, T_a.copy()]
    poses[2][:3, 3] += [0.05, 0.1, -0.05]
    seq = planner.plan_through(poses, start_joints=q_a, blend_radius=0.02)
    cases = [(path, {'max_jerk': j}) for _, path, j in _law_cases()] + [(seq, {'max_jerk': 50.0})]
    checked = 0
    for path, kw in cases:
        seen = _search_checks(path, monkeypatch, **kw)
        assert seen
        for checker, law in seen[::3]:
            got = kernels.box_search(law.tables, checker.ps.kernel_tables3, checker._limits, box_check.UNIFORM_S_PINNED,
                                     checker._samples(False), 2 * box_check.SEARCH_SAMPLES)
            checker._last.clear()
            with kernels.numpy_only():
                t, cols, rv, ra, rj, _ = checker._dense(law, full=False)
            checker._last.clear()
            np.testing.assert_array_equal(got[0], t)
            for g, w in zip(got[1:5], cols):
                np.testing.assert_array_equal(g, w)
            for g, w in zip(got[5:], (rv, ra, rj)):       # round-off (limits as reciprocals)
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-14)
            checked += 1
    assert checked >= 10


def _topp_cases():
    from timing_paths import PolyPath
    still = PolyPath([[0.1, 0.0, 0.2], [1.0, 0.0, -0.5], [0.5, 0.0, 1.0]], vmax=(1.0, 1.0, 0.7), amax=2.0)
    return [('curved', curved(), None), ('curved, x cap', curved(), 0.8),
            ('corner', CornerPath([1.0, 0.5], [0.2, -1.0]), None), ('zigzag', ZigZagPath([0.0, 0.3, 0.55, 1.0]), None),
            ('a joint that never moves', still, None)]


@pytest.mark.parametrize('name,path,cap', _topp_cases(), ids=lambda v: v if isinstance(v, str) else '')
def test_topp_matches_numpy(name, path, cap):
    from geodesic_planner.timing.topp import topp
    ps = sample_path(path, 60).refined(2)
    vmax, amax = path.robot.max_velocity, path.robot.max_acceleration
    x_max = None if cap is None else np.full(ps.s.size, cap)
    for scale in (1.0, 0.3):                       # as the jerk law's acceleration scales
        got = topp(ps, vmax, scale * amax, x_max)
        with kernels.numpy_only():
            want = topp(ps, vmax, scale * amax, x_max)
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * want.max())
        assert got[0] == got[-1] == 0.0


def test_piecewise_law_tables_match_numpy():
    from geodesic_planner.timing.smoothing import build_piecewise_law
    from geodesic_planner.timing.topp import topp
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    poses = [T_a, T_b, T_a.copy()]
    poses[2][:3, 3] += [0.05, 0.1, -0.05]
    paths = [planner.plan(T_a, T_b, start_joints=q_a), planner.plan_through(poses, start_joints=q_a),
             planner.plan_through(poses, start_joints=q_a, blend_radius=0.02),     # valleys at the blend
             ZigZagPath([0.0, 0.3, 0.55, 1.0])]
    pieces_seen, valleys_seen = set(), False
    for path in paths:
        fine = sample_path(path, 100).refined(2)
        x = topp(fine, path.robot.max_velocity, path.robot.max_acceleration)
        for smoothing in (0.05, 0.3):
            got = build_piecewise_law(fine.s, x, smoothing)
            with kernels.numpy_only():
                want = build_piecewise_law(fine.s, x, smoothing)
            pieces_seen.add(want.n_pieces)
            tau, t_star = want.pieces[0], want.pieces[5]
            valleys_seen |= bool(np.any(tau < 0.4 * smoothing * t_star))   # a kernel narrowed by a valley
            assert got.key_step == want.key_step
            for name in ('t_offsets', 'pieces', 'seg_key', 'seg', 'node_s', 'node_t'):
                g, w = getattr(got, name), getattr(want, name)
                assert g.shape == w.shape, name
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-14, err_msg=name)
    assert 1 in pieces_seen and max(pieces_seen) >= 3 and valleys_seen     # every branch was exercised


@pytest.mark.parametrize('factor', [2, 3])
def test_refined_samples_match_numpy(factor):
    for path in (curved(), CornerPath([1.0, 0.5], [0.2, -1.0]), ZigZagPath([0.0, 0.3, 0.55, 1.0])):
        ps = sample_path(path, 50)
        got = ps.refined(factor)
        with kernels.numpy_only():
            want = ps.refined(factor)
        for name in ('s', 'aL', 'aR', 'bL', 'bR', 'cL', 'cR', 'stop'):
            g, w = getattr(got, name), getattr(want, name)
            assert g.shape == w.shape, name
            np.testing.assert_allclose(g, w, rtol=1e-13, atol=1e-14, err_msg=name)
        assert got.s.size == factor * (ps.s.size - 1) + 1 and np.all(np.diff(got.s) > 0)


def test_interpolation_suspects_match_numpy():
    from geodesic_planner.timing.sampling import _interpolation_suspects, refine_adaptively
    rng = np.random.default_rng(21)
    dof, n = 4, 500
    left, right = rng.normal(size=(n, 6 * dof)), rng.normal(size=(n, 6 * dof))
    scale = np.abs(rng.normal(size=(3, dof))) + 0.1
    h = rng.uniform(1e-4, 0.05, (n, 1))
    for tol in (1e-5, 1e-2, 1.0):                  # from all steps suspect to some to none
        got = _interpolation_suspects(h, left, right, scale, dof, tol)
        with kernels.numpy_only():
            want = _interpolation_suspects(h, left, right, scale, dof, tol)
        np.testing.assert_array_equal(got, want)
    # and the bisections they lead to, on a path that needs them (the paper's 3R, by collocation)
    from pathlib import Path
    from geodesic_planner import GeodesicPlanner
    from geodesic_planner.io.requests import load_request
    req = load_request(Path(__file__).resolve().parents[2] / 'msg_examples' / 'paper_3r.yaml')
    path = GeodesicPlanner(req.robot).plan(req.start, req.goal)
    got = refine_adaptively(path, sample_path(path, 20))
    with kernels.numpy_only():
        want = refine_adaptively(path, sample_path(path, 20))
    assert got.s.size == want.s.size > 21
    np.testing.assert_array_equal(got.s, want.s)


def test_hermite_coefficients_match_numpy():
    for path in (curved(), CornerPath([1.0, 0.5], [0.2, -1.0]), _ur5e_line_path()[1].plan(
            _ur5e_line_path()[3], _ur5e_line_path()[4], start_joints=_ur5e_line_path()[2])):
        got = sample_path(path, 30).coef
        with kernels.numpy_only():
            want = sample_path(path, 30).coef
        assert got.shape == want.shape and got.flags.c_contiguous
        np.testing.assert_array_equal(got, want)       # the same formulas, in the same order


def _jerk_law_cases():
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    path = planner.plan(T_a, T_b, start_joints=q_a)
    free = time_parameterize(path)
    peak = np.abs(free.jerk_at_time(np.linspace(0.0, free.duration, 2001))).max(axis=0)
    poses = [T_a, T_b, T_a.copy()]
    poses[2][:3, 3] += [0.05, 0.1, -0.05]
    seq = planner.plan_through(poses, start_joints=q_a, blend_radius=0.02)    # breakpoints crossed
    return [(name, p, {'max_jerk': j}) for name, p, j in _law_cases()] + [
        ('ur5e', path, {'max_jerk': 0.3 * peak}), ('ur5e loose', path, {'max_jerk': 3.0 * peak}),
        ('ur5e blended', seq, {'max_jerk': 50.0})]


def _same_bits(a, b):
    assert a.duration == b.duration and a.rest_times == b.rest_times
    np.testing.assert_array_equal(a.scaling.width, b.scaling.width)


def test_search_maxima_are_the_search_grid_maxima(monkeypatch):
    # gp_box_search_max (offsets from the window, blocks from an origin, early stop, breakpoints)
    # against gp_box_search_grid on the law built in Python, and the crossed breakpoints as
    # BoxCheck.ratios checks them: the same duration and maxima, bit for bit
    from geodesic_planner.timing.box_filter import star_tables
    checked = crossed = 0
    for _name, path, kw in _jerk_law_cases():
        for checker, law in _search_checks(path, monkeypatch, **kw)[::4]:
            pieces = list(zip(law.s_start.tolist(), law.stars))
            tables = star_tables(pieces)
            args = (tables, law.width, checker.ps.kernel_tables3, checker._limits, box_check.UNIFORM_S_PINNED,
                    checker._samples(False), 2 * box_check.SEARCH_SAMPLES)
            grid = kernels.box_search(law.tables, *args[2:])
            want = tuple(float(r.max()) for r in grid[5:8])
            for origin in (0.0, 0.37, 1.0):
                rv, ra, rj, duration, peak, stopped = kernels.box_search_max(*args, (np.inf,) * 3, origin)
                assert (rv, ra, rj) == want and duration == law.duration and not stopped
            if checker._crossings is not None:
                got = kernels.box_search_max(*args, (np.inf,) * 3, 0.5, checker._crossings)
                assert got[:3] == checker.ratios(law, exact=False)
                assert all(g >= w for g, w in zip(got[:3], want))
                crossed += 1
                need = np.maximum(np.maximum(grid[5], np.sqrt(grid[6])), np.cbrt(grid[7]))
                at = np.argmin(np.abs(grid[0] - peak * duration))    # a sample where the need peaks (ties: any)
                assert need[at] == pytest.approx(need.max(), rel=1e-12)
            # bounds below the maxima: it stops after a block over them, with maxima over it
            half = tuple(0.5 * w for w in want)
            rv, ra, rj, _, _, stopped = kernels.box_search_max(*args, half, 0.5)
            assert stopped and (rv > half[0] or ra > half[1] or rj > half[2])
            assert rv <= want[0] and ra <= want[1] and rj <= want[2]
            checked += 1
    assert checked >= 10 and crossed >= 3


@pytest.mark.parametrize('name,path,kw', _jerk_law_cases(), ids=lambda v: v if isinstance(v, str) else '')
def test_width_search_shortcuts_change_nothing(name, path, kw, monkeypatch):
    # The two shortcuts of the jerk law's search give the same law, bit for bit, as without them:
    # checks that stop once longer than a known duration, and acceleration scales left unsearched
    # when even their shortest conceivable law (width factor WIDTH_SCAN[0], no stretch) is longer.
    from geodesic_planner.timing import jerk
    fast = time_parameterize(path, **kw)
    search = box_check.BoxCheck.search
    monkeypatch.setattr(box_check.BoxCheck, 'search', lambda self, pieces, tables, width, above=np.inf:
                        search(self, pieces, tables, width))
    _same_bits(fast, time_parameterize(path, **kw))
    monkeypatch.setattr(jerk, '_floor', lambda pieces, w_ref: 0.0)      # every scale searched
    _same_bits(fast, time_parameterize(path, **kw))


def test_scale_floor_is_below_every_law_tried(monkeypatch):
    # _floor's promise, checked on every width the search tries: stretch x duration >= the floor
    from geodesic_planner.timing import jerk
    floors, tried = {}, []
    best_width, search = jerk._best_width, box_check.BoxCheck.search

    def spy_best(pieces, w_ref, checker, *args, **kwargs):
        floors[id(pieces)] = (pieces, jerk._floor(pieces, w_ref))      # kept alive: ids stay unique
        return best_width(pieces, w_ref, checker, *args, **kwargs)

    def spy_search(checker, pieces, tables, width, *args, **kwargs):
        lam, duration, exact = search(checker, pieces, tables, width, *args, **kwargs)
        known = floors.get(id(pieces))
        tried.append((known[1] if known is not None and known[0] is pieces else None, lam * duration))
        return lam, duration, exact
    monkeypatch.setattr(jerk, '_best_width', spy_best)
    monkeypatch.setattr(box_check.BoxCheck, 'search', spy_search)
    for _, path, kw in _jerk_law_cases():
        for f in (1.0, 0.1):
            time_parameterize(path, max_jerk=np.asarray(kw['max_jerk']) * f)
    assert len([t for t in tried if t[0] is not None]) > 50
    assert all(total >= floor for floor, total in tried if floor is not None)


def test_smoothed_law_check_grid_is_the_numpy_grid():
    # gp_piecewise_check builds smooth_check.check_law's grid itself (uniform times, the rests
    # between pieces, np.interp of the s-uniform samples; sorted, each once): the same times bit
    # for bit, the same law there, and the ratios of _ratios within round-off
    from geodesic_planner.timing import smooth_check
    from geodesic_planner.timing.checks import UNIFORM_S, UNIFORM_S_PINNED, distinct_times
    robot, planner, q_a, T_a, T_b = _ur5e_line_path()
    cases = [path for _, path, _ in _law_cases()] + [planner.plan(T_a, T_b, start_joints=q_a)]
    for path in cases:
        law = time_parameterize(path).scaling
        ps = sample_path(path, 60)
        vmax, amax = np.full(ps.aR.shape[1], 1.3), np.full(ps.aR.shape[1], 2.1)
        for m in (10, 1000, 3001):
            t, s, sd, sdd, rv, ra = kernels.piecewise_check(
                law.kernel_tables, kernels.Pinned(law.node_s, law.node_t), ps.kernel_tables,
                kernels.limit_tables(vmax, amax), UNIFORM_S_PINNED, m)
            want = np.linspace(0.0, law.duration, m)
            if law.n_pieces > 1:
                want = np.union1d(want, law.t_offsets)
            want = distinct_times(np.concatenate([want, law.times_at(UNIFORM_S)]))
            np.testing.assert_array_equal(t, want)
            with kernels.numpy_only():
                cols = smooth_check._ratios(ps, law, want, vmax, amax, None, None)
            for g, w in zip((s, sd, sdd), cols[:3]):
                np.testing.assert_allclose(g, w, rtol=1e-12, atol=1e-12)
            for g, w in zip((rv, ra), cols[3:]):
                np.testing.assert_allclose(g, w, rtol=1e-9, atol=1e-12)
    assert any(time_parameterize(p).scaling.n_pieces > 1 for p in cases)


def test_peak_samples_match_numpy():
    # gp_peak_samples against the numpy code (stable order: equal peaks at the cut, the later
    # ones), on random needs, plateaus (many equal peaks), no peak, a single peak and NaN
    from geodesic_planner.timing import checks
    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(0.0, 2.0, 400))
    cases = [rng.uniform(0.0, 1.0, 400), np.round(rng.uniform(0.0, 1.0, 400), 1),    # many ties
             np.ones(400), np.linspace(0.0, 1.0, 400), np.r_[0.0, 1.0, np.zeros(398)],
             np.where(rng.uniform(size=400) < 0.1, np.nan, rng.uniform(size=400))]
    for need in cases:
        for spacing in (1e-3, 0.3):
            got = checks.peak_samples(t, need, spacing, 2.0)
            with kernels.numpy_only():
                want = checks.peak_samples(t, need, spacing, 2.0)
            np.testing.assert_array_equal(got, want)
    assert checks.peak_samples(t[:2], np.ones(2), 0.1, 2.0).size == 0
