"""geodesic-compare: CLI output, oracles on the paper's 3R, figures, error paths; ee_profile maths."""
from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from geodesic_planner import chain_from_dh
from geodesic_planner.cli.compare import ee_profile, main, summarize
from geodesic_planner.core.transforms import line_slerp

ROOT = Path(__file__).resolve().parents[2]
PAPER_3R = ROOT / 'msg_examples' / 'paper_3r.yaml'
PAPER_RRPP = ROOT / 'msg_examples' / 'paper_rrpp.yaml'
FIGURES = ['ee_position.png', 'ee_position_derivatives.png', 'ee_orientation.png',
           'ee_orientation_derivatives.png', 'joints.png']
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'


def cli() -> list[str]:
    script = Path(sys.executable).with_name('geodesic-compare')
    return [str(script)] if script.exists() else [sys.executable, '-m', 'geodesic_planner.cli.compare']


def run(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*cli(), *args], capture_output=True, text=True, timeout=timeout)


def check_png(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f'{path.name} is not a PNG'
    assert data[12:16] == b'IHDR'
    width, height = struct.unpack('>II', data[16:24])
    assert width > 100 and height > 100
    assert data.rstrip(b'\x00')[-8:-4] == b'IEND' or b'IEND' in data[-16:]
    return width, height


def ik_3r(T: np.ndarray) -> np.ndarray:
    phi = math.atan2(T[1, 0], T[0, 0])
    wx, wy = T[0, 3] - math.cos(phi), T[1, 3] - math.sin(phi)
    t2 = math.acos((wx * wx + wy * wy - 2.0) / 2.0)
    t1 = math.atan2(wy, wx) - math.atan2(math.sin(t2), 1.0 + math.cos(t2))
    return np.array([t1, t2, phi - t1 - t2])


@pytest.fixture(scope='module')
def paper_3r_output(tmp_path_factory):
    out = tmp_path_factory.mktemp('cmp3r')
    res = run(str(PAPER_3R), '--output', str(out), '--samples', '501')
    assert res.returncode == 0, res.stderr
    return out, json.loads((out / 'comparison.json').read_text())


def test_3r_json_keys(paper_3r_output):
    _, data = paper_3r_output
    assert data['robot'] == 'planar_3r'
    assert data['joint_names'] == ['joint1', 'joint2', 'joint3']
    assert data['samples'] == 501
    for method in ('geodesic', 'polynomial'):
        block = data[method]
        for key in ('max_abs_jerk', 'max_abs_acceleration', 'max_abs_velocity'):
            entry = block[key]
            assert set(entry) >= {'joints', 'ee_position', 'ee_orientation', 'ee_orientation_matrix'}
            assert len(entry['joints']) == 3
            assert all(math.isfinite(v) for v in entry['joints'])
        assert block['timing_at_robot_limits']['duration_s'] > 0
    assert data['polynomial']['n_via'] == 11
    assert data['geodesic']['solver']['status'] == 0
    assert sorted(data['figures']) == sorted(FIGURES)


def test_3r_geodesic_end_effector_jerk_is_zero_polynomial_is_not(paper_3r_output):
    """Exact oracle: the 3R geodesic is the straight line with phi linear in s (docs/maths.md#oracles)."""
    _, data = paper_3r_output
    g, p = data['geodesic'], data['polynomial']
    assert g['max_abs_jerk']['ee_position'] < 1e-6
    assert g['max_abs_jerk']['ee_orientation'] < 1e-6
    assert g['max_abs_acceleration']['ee_position'] < 1e-6
    assert p['max_abs_jerk']['ee_position'] > 1.0
    assert p['max_abs_acceleration']['ee_position'] > 0.01
    # Constant speed |AB| = sqrt(2) m and dphi rad per unit s.
    dphi = math.atan2(0.7, 0.714) - math.atan2(0.5, 0.866)  # yaws of Table 1 n vectors
    assert g['max_abs_velocity']['ee_position'] == pytest.approx(math.sqrt(2.0), abs=1e-6)
    assert g['max_abs_velocity']['ee_orientation'] == pytest.approx(abs(dphi), abs=1e-6)
    # |R'''|_F of a constant-rate rotation about z is sqrt(2) |dphi|^3 (the paper's 0.022).
    assert g['max_abs_jerk']['ee_orientation_matrix'] == pytest.approx(math.sqrt(2.0) * abs(dphi) ** 3, rel=1e-6)
    assert g['line']['max_distance_to_line_m'] < 1e-9
    assert p['line']['max_distance_to_line_m'] > 1e-6


def test_3r_geodesic_joint_jerk_matches_closed_form_oracle(paper_3r_output):
    """max |q'''| of IK along the line (closed form, differentiated by a fine stencil here)."""
    _, data = paper_3r_output
    T_a = np.eye(4)
    T_b = np.eye(4)
    ya, yb = math.atan2(0.5, 0.866), math.atan2(0.7, 0.714)
    T_a[:2, :2] = [[math.cos(ya), -math.sin(ya)], [math.sin(ya), math.cos(ya)]]
    T_b[:2, :2] = [[math.cos(yb), -math.sin(yb)], [math.sin(yb), math.cos(yb)]]
    T_a[:2, 3], T_b[:2, 3] = (2.5, 1.5), (1.5, 2.5)
    s = np.linspace(0.0, 1.0, 501)
    h = 2e-4
    offsets = np.array([-3, -2, -1, 0, 1, 2, 3]) * h
    jerk = []
    for s0 in s:
        shift = offsets.max() if s0 + 3 * h > 1 else offsets.min() if s0 - 3 * h < 0 else 0.0
        pts = np.clip(s0 + offsets - shift, 0.0, 1.0)
        q = np.array([ik_3r(T) for T in line_slerp(T_a, T_b, pts)])
        # Third derivative of the degree-6 interpolant through seven points (one-sided at the ends).
        c = np.polyfit(pts - s0, q, 6)
        jerk.append(6.0 * c[3])
    oracle = np.abs(np.array(jerk)).max(axis=0)
    np.testing.assert_allclose(data['geodesic']['max_abs_jerk']['joints'], oracle, rtol=2e-3)


def test_3r_figures_are_valid_pngs(paper_3r_output):
    out, _ = paper_3r_output
    for name in FIGURES:
        check_png(out / name)


def test_rrpp_spatial_comparison(tmp_path):
    res = run(str(PAPER_RRPP), '--output', str(tmp_path / 'rrpp'), '--samples', '201')
    assert res.returncode == 0, res.stderr
    data = json.loads((tmp_path / 'rrpp' / 'comparison.json').read_text())
    assert data['robot'] == 'rrpp' and len(data['geodesic']['max_abs_jerk']['joints']) == 4
    # The geodesic is smoother than the polynomial, at the end effector and in every joint.
    g, p = data['geodesic']['max_abs_jerk'], data['polynomial']['max_abs_jerk']
    assert g['ee_position'] < p['ee_position'] / 10
    assert all(a < b for a, b in zip(g['joints'], p['joints']))
    # 4 joints cannot follow the exact line: the geodesic bows away from it by a fraction of a mm.
    assert 1e-6 < data['geodesic']['line']['max_distance_to_line_m'] < 1e-3
    for name in FIGURES:
        check_png(tmp_path / 'rrpp' / name)


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'req.yaml'
    path.write_text(text)
    return path


@pytest.mark.parametrize('text, match', [
    ('robot: planar_3r\nstart: [1, 2\n', 'YAML'),
    ('robot: no_such_robot\nstart_joints: [0, 0, 0]\ngoal_joints: [1, 1, 1]\n', 'no_such_robot'),
    ('robot: planar_3r\nstart_joints: [0, .nan, 0]\ngoal_joints: [1, 1, 1]\n', ''),
    ('robot: planar_3r\nstart:\n  position: {x: 9.0, y: 0.0, z: 0.0}\ngoal_joints: [1, 1, 1]\n', ''),
    ('robot: planar_3r\nstart_joints: [0, 0.5, 0]\nbogus: 1\ngoal_joints: [1, 1, 1]\n', 'bogus'),
])
def test_bad_requests_give_one_error_line(tmp_path, capsys, text, match):
    code = main([str(write(tmp_path, text)), '--output', str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('ERROR: '), err
    assert match in lines[0]
    assert not (tmp_path / 'out' / 'comparison.json').exists()


def test_bad_request_subprocess_exit_code(tmp_path):
    res = run(str(write(tmp_path, 'robot: planar_3r\nstart: [1, 2\n')), '--output', str(tmp_path / 'out'))
    assert res.returncode == 1
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith('ERROR: ') and 'YAML' in lines[0], res.stderr
    assert 'Traceback' not in res.stderr


def test_bad_arguments_and_paths(tmp_path, capsys):
    cases = [
        [str(tmp_path / 'missing.yaml'), '--output', str(tmp_path / 'o')],
        [str(PAPER_3R), '--output', str(tmp_path / 'o'), '--samples', '1'],
        [str(PAPER_3R), '--output', str(tmp_path / 'o'), '--samples', 'many'],
        [str(PAPER_3R)],
    ]
    blocker = tmp_path / 'a_file'
    blocker.write_text('x')
    cases.append([str(PAPER_3R), '--output', str(blocker), '--no-plots'])
    for argv in cases:
        code = main(argv)
        err = capsys.readouterr().err
        assert code == 1, argv
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith('ERROR: '), (argv, err)


# ------------------------------------------------------------------ ee_profile against closed forms
class CubicJointPath:
    """q(s) = c0 + c1 s + c2 s^2 + c3 s^3 per joint (exact derivatives)."""

    def __init__(self, c):
        self.c = np.asarray(c, dtype=float)

    def evaluate(self, s):
        c0, c1, c2, c3 = self.c
        s = s[:, None]
        return (c0 + c1 * s + c2 * s**2 + c3 * s**3, c1 + 2 * c2 * s + 3 * c3 * s**2,
                2 * c2 + 6 * c3 * s, np.broadcast_to(6 * c3, (s.shape[0], self.c.shape[1])))


def test_ee_profile_one_joint_closed_form():
    """1R arm, link 1 m: p = (cos q, sin q, 0), w = q' z; derivatives by the chain rule by hand."""
    robot = chain_from_dh('one_r', [(0.0, 0.0, 1.0, 0.0)], ['revolute'])
    path = CubicJointPath([[0.3], [1.2], [-0.7], [0.9]])
    s = np.linspace(0.0, 1.0, 41)
    prof = ee_profile(robot, path, s)
    q, q1, q2, q3 = (a[:, 0] for a in path.evaluate(s))
    e = np.stack([np.cos(q), np.sin(q)], axis=1)           # radial unit vector
    t = np.stack([-np.sin(q), np.cos(q)], axis=1)          # tangential
    dp = q1[:, None] * t
    ddp = q2[:, None] * t - (q1**2)[:, None] * e
    dddp = (q3 - q1**3)[:, None] * t - (3 * q1 * q2)[:, None] * e
    np.testing.assert_allclose(prof['dp'][:, :2], dp, atol=1e-9)
    np.testing.assert_allclose(prof['ddp'][:, :2], ddp, atol=1e-9)
    np.testing.assert_allclose(prof['dddp'][:, :2], dddp, atol=1e-8)
    np.testing.assert_allclose(prof['dddp'][:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(prof['w'][:, 2], q1, atol=1e-9)
    np.testing.assert_allclose(prof['dw'][:, 2], q2, atol=1e-9)
    np.testing.assert_allclose(prof['ddw'][:, 2], q3, atol=1e-8)
    np.testing.assert_allclose(prof['ddw'][:, :2], 0.0, atol=1e-8)
    summary = summarize(prof)
    assert summary['max_abs_jerk']['ee_orientation'] == pytest.approx(np.abs(q3).max(), abs=1e-8)
    assert summary['max_abs_jerk']['joints'] == pytest.approx([np.abs(q3).max()])


def test_ee_profile_matches_analytic_jacobian_and_hessian_on_ur5e():
    from geodesic_planner import load_robot
    robot = load_robot('ur5e')
    rng = np.random.default_rng(3)
    path = CubicJointPath(rng.uniform(-1.0, 1.0, size=(4, 6)))
    s = np.linspace(0.0, 1.0, 25)
    prof = ee_profile(robot, path, s)
    q, q1, q2, _ = path.evaluate(s)
    J = robot.jacobian(q)
    np.testing.assert_allclose(prof['dp'], np.einsum('nij,nj->ni', J[:, :3], q1), atol=1e-9)
    np.testing.assert_allclose(prof['w'], np.einsum('nij,nj->ni', J[:, 3:], q1), atol=1e-9)
    H = robot.hessian12(q, q1)
    np.testing.assert_allclose(prof['ddp'], np.einsum('nij,nj->ni', J[:, :3], q2) + H[:, :3], atol=1e-8)
    # Third derivative: against a central difference of the analytic second derivative.
    eps = 1e-5
    def acc(ss):
        qq, a1, a2, _ = path.evaluate(ss)
        return np.einsum('nij,nj->ni', robot.jacobian(qq)[:, :3], a2) + robot.hessian12(qq, a1)[:, :3]
    inner = s[1:-1]
    fd = (acc(inner + eps) - acc(inner - eps)) / (2 * eps)
    np.testing.assert_allclose(prof['dddp'][1:-1], fd, atol=1e-5)
