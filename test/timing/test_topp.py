"""The TOPP passes (geodesic_planner.timing.topp) against plain loops over steps and rows."""
from __future__ import annotations

import numpy as np
import pytest

from geodesic_planner.timing import topp
from geodesic_planner.timing.sampling import refine_adaptively, sample_path
from timing_paths import CornerPath, PolyPath, ZigZagPath, curved


def reference_topp(ps, vmax, amax):
    """The time-optimal profile of ``topp.topp`` written as plain loops over steps and rows.

    Step k, rows j (joints at the step start, then at its end): |ra_j u + rb_j x_k| <= amax_j, with
    x_{k+1} = x_k + 2 h u; static bound = min(velocity, rows that do not move, row pairs,
    x_{k+1} >= 0, cap); backward pass over all rows, then the greedy forward pass.
    """
    s, aL, aR, bL, bR = (np.asarray(v, dtype=float) for v in (ps.s, ps.aL, ps.aR, ps.bL, ps.bR))
    n, dof = s.size - 1, aR.shape[1]
    absa_n = np.maximum(np.abs(aL), np.abs(aR))
    tiny_n = 1e-12 * max(float(absa_n.max()), 1e-300)
    rows = []
    for k in range(n):
        h = float(s[k + 1] - s[k])
        ra = [float(aR[k, i]) for i in range(dof)] + [float(aL[k + 1, i] + 2.0 * h * bL[k + 1, i]) for i in range(dof)]
        rb = [float(bR[k, i]) for i in range(dof)] + [float(bL[k + 1, i]) for i in range(dof)]
        rows.append((h, ra, rb))
    peak = max(abs(v) for _, ra, _ in rows for v in ra)
    tiny = 1e-12 * max(peak, 1e-300)
    rl = [float(v) for v in amax] * 2
    static, lines, upper = [], [], []
    for k, (h, ra, rb) in enumerate(rows):
        xv = min([(vmax[i] / absa_n[k, i]) * (vmax[i] / absa_n[k, i]) for i in range(dof) if absa_n[k, i] > tiny_n]
                 or [np.inf])
        mov = [abs(v) > tiny for v in ra]
        xz = min([rl[j] / abs(rb[j]) for j in range(2 * dof) if not mov[j] and rb[j] != 0.0] or [np.inf])
        al = [-rb[j] / ra[j] if mov[j] else 0.0 for j in range(2 * dof)]
        c = [-rl[j] / abs(ra[j]) if mov[j] else -np.inf for j in range(2 * dof)]
        d = [rl[j] / abs(ra[j]) if mov[j] else np.inf for j in range(2 * dof)]
        xp = min([(d[m] - c[j]) / (al[j] - al[m]) for j in range(2 * dof) for m in range(2 * dof)
                  if mov[j] and mov[m] and al[j] - al[m] > 0] or [np.inf])
        coef = [-1.0 / (2.0 * h) - al[j] for j in range(2 * dof)]
        xl = min([d[j] / coef[j] for j in range(2 * dof) if mov[j] and coef[j] > 0] or [np.inf])
        st = 0.0 if ps.stop[k] else max(min(xv, xz, xp, xl, topp._X_CAP), 0.0)
        static.append(st)
        den = [1.0 + 2.0 * h * al[j] for j in range(2 * dof)]
        lines.append([(1.0 / den[j], -2.0 * h * c[j] / den[j]) for j in range(2 * dof) if mov[j] and den[j] > 0])
        upper.append(list(zip(al, d)))
    hi = [0.0] * (n + 1)
    for k in range(n - 1, -1, -1):
        hi[k] = min([static[k]] + [a * hi[k + 1] + b for a, b in lines[k]])
    x = [0.0] * (n + 1)
    for k in range(n):
        two_h = 2.0 * rows[k][0]
        u = min([(hi[k + 1] - x[k]) / two_h] + [a * x[k] + d for a, d in upper[k]])
        x[k + 1] = min(max(x[k] + two_h * u, 0.0), hi[k + 1])
    x[n] = 0.0
    return np.array(x)


def _fine_samples(path):
    return refine_adaptively(path, sample_path(path, 100)).refined(2)


def _topp_cases():
    rng = np.random.default_rng(7)
    cases = [('curved', curved(), 1.0), ('curved slow', curved(), 0.2),
             ('turning point, still joint', PolyPath([[0.0, 0.2], [2.0, 0.0], [-2.0, 0.0]], 1.0, 2.0), 1.0),
             ('corner', CornerPath([0.8, 0.0], [0.0, 0.6]), 1.0),
             ('zigzag', ZigZagPath(np.linspace(0.0, 1.0, 6)), 1.0)]
    for i in range(4):
        cases.append((f'random {i}', PolyPath(rng.standard_normal((5, 4)), rng.uniform(0.3, 2.0, 4),
                                              rng.uniform(0.5, 4.0, 4)), float(rng.choice([0.3, 1.0, 3.0]))))
    return cases


@pytest.mark.parametrize('name, path, scale', _topp_cases(), ids=[c[0] for c in _topp_cases()])
def test_topp_passes_equal_plain_all_rows_loops(name, path, scale, monkeypatch):
    ps = _fine_samples(path)
    vmax = path.robot.max_velocity * scale
    amax = path.robot.max_acceleration
    ref = reference_topp(ps, vmax, amax)
    assert ref.max() > 0.0
    # Default: the closed-form passes, accepted to 1e-12 per step; exact zeros at the rests.
    x = topp.topp(ps, vmax, amax)
    np.testing.assert_allclose(x, ref, rtol=1e-10, atol=0.0)
    np.testing.assert_array_equal(x[ref == 0.0], 0.0)
    # Closed form refused: the loops over all rows give exactly the reference floats.
    monkeypatch.setattr(topp, '_CLOSED_FORM_RTOL', -1.0)
    np.testing.assert_array_equal(topp.topp(ps, vmax, amax), ref)
