"""``geodesic-plan`` end to end (real subprocesses of the installed console script).

Success: the paper's 3R request gives JSON whose samples match the exact oracle (closed-form IK
along the straight line with φ linear in s, and its s-derivatives); the RRPP joint request keeps
its boundary conditions; a URDF robot given by a path relative to the YAML file; via points.
Failure: one line ``ERROR: ...`` on stderr naming the cause, no traceback, non-zero exit code.
"""
from __future__ import annotations

import itertools
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
import yaml
from numpy.testing import assert_allclose

import urdf_util as U
from cli_limits import QUICK, error_line, run_bounded

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
EXAMPLES = os.path.join(ROOT, 'msg_examples')
KR6 = os.path.join(ROOT, 'geodesic_planner', 'data', 'kr6_like.urdf')
_script = shutil.which('geodesic-plan', path=os.path.dirname(sys.executable))
COMMAND = [_script] if _script else [sys.executable, '-m', 'geodesic_planner.cli.plan']
TIMEOUT = 120
PARALLEL = 3
KEYS = {'joint_names', 's', 'positions', 'velocities', 'accelerations', 'jerks', 'ee_positions',
        'ee_orientations', 'solver'}


def run(args, cwd):
    return subprocess.run(COMMAND + [str(a) for a in args], cwd=cwd, capture_output=True, text=True,
                          timeout=TIMEOUT, check=False)


def yaw_quat(psi):
    return {'x': 0.0, 'y': 0.0, 'z': float(np.sin(psi / 2)), 'w': float(np.cos(psi / 2))}


def pose(x, y, z, quat):
    return {'position': {'x': x, 'y': y, 'z': z}, 'orientation': quat}


# ---------------------------------------------------------------------- 3R oracle
def my_3r_ik(x, y, phi):
    wx, wy = x - np.cos(phi), y - np.sin(phi)
    t2 = np.arccos((wx**2 + wy**2 - 2.0) / 2.0)
    t1 = np.arctan2(wy, wx) - np.arctan2(np.sin(t2), 1 + np.cos(t2))
    return np.stack([t1, t2, phi - t1 - t2], axis=-1)


def j_xyphi(q):
    """Jacobian of (x, y, φ) for the unit-link planar 3R, (N, 3, 3)."""
    t1, t12, t123 = q[:, 0], q[:, 0] + q[:, 1], q.sum(axis=1)
    J = np.zeros((q.shape[0], 3, 3))
    J[:, 0] = -np.stack([np.sin(t1) + np.sin(t12) + np.sin(t123), np.sin(t12) + np.sin(t123), np.sin(t123)], 1)
    J[:, 1] = np.stack([np.cos(t1) + np.cos(t12) + np.cos(t123), np.cos(t12) + np.cos(t123), np.cos(t123)], 1)
    J[:, 2] = 1.0
    return J


class Oracle3R:
    """The exact geodesic of the paper's example: (x, y, φ) linear in s."""

    def __init__(self, request_path):
        with open(request_path, encoding='utf-8') as fh:
            req = yaml.safe_load(fh)
        a, b = req['start'], req['goal']
        self.pa = np.array([a['position'][k] for k in 'xyz'])
        self.pb = np.array([b['position'][k] for k in 'xyz'])
        yaw = lambda o: 2 * np.arctan2(o['z'], o['w'])  # noqa: E731
        self.phia, self.phib = yaw(a['orientation']), yaw(b['orientation'])
        self.xi = np.array([*(self.pb - self.pa)[:2], self.phib - self.phia])

    def pose(self, s):
        return self.pa + s[:, None] * (self.pb - self.pa), self.phia + s * (self.phib - self.phia)

    def q(self, s):
        p, phi = self.pose(s)
        return my_3r_ik(p[:, 0], p[:, 1], phi)

    def dq(self, s):
        return np.linalg.solve(j_xyphi(self.q(s)), np.broadcast_to(self.xi, (s.size, 3))[..., None])[..., 0]


@pytest.fixture(scope='module')
def paper_3r_json(tmp_path_factory):
    out = tmp_path_factory.mktemp('cli') / 'paper_3r.json'
    proc = run([os.path.join(EXAMPLES, 'paper_3r.yaml'), '--samples', 201, '--output', out], ROOT)
    assert proc.returncode == 0, proc.stderr
    assert 'ERROR' not in proc.stderr and 'Traceback' not in proc.stderr
    with open(out, encoding='utf-8') as fh:
        return json.load(fh)


def test_paper_3r_json_layout(paper_3r_json):
    d = paper_3r_json
    assert set(d) >= KEYS
    assert d['joint_names'] == ['joint1', 'joint2', 'joint3']
    assert_allclose(d['s'], np.linspace(0, 1, 201), atol=1e-15)
    for key in ('positions', 'velocities', 'accelerations', 'jerks', 'ee_positions'):
        assert np.array(d[key]).shape == (201, 3), key
    assert np.array(d['ee_orientations']).shape == (201, 4)
    sol = d['solver']
    assert {'status', 'iterations', 'max_residual', 'time_ms'} <= set(sol)
    assert sol['status'] == 0 and isinstance(sol['iterations'], int) and sol['iterations'] >= 0
    assert sol['method'] == 'pullback' and 0 < sol['path_error'] <= 1e-9
    assert np.isfinite(sol['max_residual']) and sol['time_ms'] > 0


def test_paper_3r_json_matches_exact_geodesic(paper_3r_json):
    d = paper_3r_json
    oracle = Oracle3R(os.path.join(EXAMPLES, 'paper_3r.yaml'))
    s = np.array(d['s'])
    q = np.array(d['positions'])
    assert np.abs(q - oracle.q(s)).max() <= 1e-5
    assert_allclose(q[0], [0.258, 0.583, -0.317], atol=6e-4)     # Table 2
    assert_allclose(q[-1], [0.969, 0.380, -0.574], atol=6e-4)
    p, phi = oracle.pose(s)
    assert np.abs(np.array(d['ee_positions']) - p).max() <= 1e-6
    quat = np.array(d['ee_orientations'])                         # (x, y, z, w) of a yaw φ
    ref = np.stack([np.zeros_like(phi), np.zeros_like(phi), np.sin(phi / 2), np.cos(phi / 2)], axis=1)
    assert np.abs(quat - ref).max() <= 1e-6
    # derivatives w.r.t. s: q' = J⁻¹ ξ exactly; q'', q''' by differences of the exact q'
    assert np.abs(np.array(d['velocities']) - oracle.dq(s)).max() <= 1e-5
    h = 1e-4
    ddq = (oracle.dq(s + h) - oracle.dq(s - h)) / (2 * h)
    dddq = (oracle.dq(s + h) - 2 * oracle.dq(s) + oracle.dq(s - h)) / h**2
    assert np.abs(np.array(d['accelerations']) - ddq).max() <= 1e-5 * max(1.0, np.abs(ddq).max())
    assert np.abs(np.array(d['jerks']) - dddq).max() <= 1e-4 * max(1.0, np.abs(dddq).max())


def test_method_collocation_from_flag_and_from_request(tmp_path, capsys):
    """``--method collocation`` (and the request's ``method:`` key) force the IK-free route; the
    path is still the exact geodesic of the paper's example (the same oracle as above)."""
    from geodesic_planner.cli.plan import plan_main
    oracle = Oracle3R(os.path.join(EXAMPLES, 'paper_3r.yaml'))
    with open(os.path.join(EXAMPLES, 'paper_3r.yaml'), encoding='utf-8') as fh:
        req = yaml.safe_load(fh)
    (tmp_path / 'colloc.yaml').write_text(yaml.safe_dump({**req, 'method': 'collocation'}))
    runs = {'flag': [os.path.join(EXAMPLES, 'paper_3r.yaml'), '--method', 'collocation'],
            'key': [str(tmp_path / 'colloc.yaml')],
            'flag over key': [str(tmp_path / 'colloc.yaml'), '--method', 'auto']}
    for name, args in runs.items():
        out = tmp_path / f'{name}.json'
        assert plan_main([*args, '--samples', '101', '--output', str(out)]) == 0, name
        summary = capsys.readouterr().err
        d = json.loads(out.read_text())
        method = 'pullback' if name == 'flag over key' else 'collocation'
        assert d['solver']['method'] == method, name
        assert summary.startswith(f'planar_3r: {method}, '), summary
        s = np.array(d['s'])
        assert np.abs(np.array(d['positions']) - oracle.q(s)).max() <= 1e-5, name
        assert np.abs(np.array(d['ee_positions']) - oracle.pose(s)[0]).max() <= 1e-6, name


def test_stdout_mode_and_samples(tmp_path):
    proc = run([os.path.join(EXAMPLES, 'paper_rrpp_joints.yaml'), '--samples', 5], tmp_path)
    assert proc.returncode == 0, proc.stderr
    d = json.loads(proc.stdout)
    assert d['joint_names'] == ['theta1', 'theta2', 'd3', 'd4']
    assert_allclose(d['s'], [0, 0.25, 0.5, 0.75, 1.0], atol=1e-15)
    q = np.array(d['positions'])
    assert_allclose(q[0], [0.123, -1.539, 0.276, -0.640], atol=1e-12)   # boundary conditions
    assert_allclose(q[-1], [0.129, -1.629, 0.239, -0.643], atol=1e-12)
    assert d['solver']['status'] == 0


def test_urdf_robot_relative_to_request_and_via_point(tmp_path):
    """A URDF next to the YAML; a via point placed so that the two pieces have equal length
    (the junction is then at s = 0.5, a sample): the tool is exactly there."""
    shutil.copy(KR6, tmp_path / 'arm.urdf')
    q0 = np.array([0.0, -1.2, 1.0, 0.0, 0.8, 0.0])
    fkb = U.arm_fk_batch(U.KR6)
    T0 = fkb(q0[None])[0]
    from scipy.spatial.transform import Rotation
    quat = lambda T: dict(zip('xyzw', map(float, Rotation.from_matrix(T[:3, :3]).as_quat())))  # noqa: E731
    p0 = T0[:3, 3]
    p1, p2 = p0 + [0.1, 0.0, 0.0], p0 + [0.1, 0.1, 0.0]
    req = {'robot': 'arm.urdf', 'start_joints': q0.tolist(),
           'via': [pose(*map(float, p1), quat(T0))], 'goal': pose(*map(float, p2), quat(T0))}
    (tmp_path / 'req.yaml').write_text(yaml.safe_dump(req))
    proc = run(['req.yaml', '--samples', 101, '--output', 'out.json'], tmp_path)
    assert proc.returncode == 0, proc.stderr
    d = json.loads((tmp_path / 'out.json').read_text())
    assert d['joint_names'] == U.KR6['joint_names']
    ee = np.array(d['ee_positions'])
    assert_allclose(ee[0], p0, atol=1e-9)
    assert_allclose(ee[50], p1, atol=1e-9)
    assert_allclose(ee[-1], p2, atol=1e-9)
    assert np.abs(ee[:51, 1] - p0[1]).max() < 1e-6 and np.abs(ee[50:, 0] - p1[0]).max() < 1e-6
    # the JSON's joints agree with the oracle FK of the JSON's own positions
    assert_allclose(fkb(np.array(d['positions']))[:, :3, 3], ee, atol=1e-12)


# ---------------------------------------------------------------------- failures
A = pose(2.5, 1.5, 0.0, yaw_quat(np.pi / 6))
B = pose(1.5, 2.5, 0.0, yaw_quat(0.7752))
FAILURES = {
    'nan_position': ({'robot': 'planar_3r', 'start': pose(float('nan'), 1.5, 0.0, yaw_quat(0.5)), 'goal': B},
                     'NaN'),
    'unreachable': ({'robot': 'planar_3r', 'start': A, 'goal': pose(5.0, 0.0, 0.0, yaw_quat(0.0))},
                    'IK failed'),
    'unknown_robot': ({'robot': 'kuka_kr1000', 'start': A, 'goal': B}, "unknown robot 'kuka_kr1000'"),
    'missing_urdf': ({'robot': 'nowhere.urdf', 'start': A, 'goal': B}, 'cannot read URDF'),
    'bad_quaternion': ({'robot': 'planar_3r', 'start': pose(2.5, 1.5, 0.0, {'z': 0.5, 'w': 0.5}), 'goal': B},
                       'not normalised'),
    'zero_quaternion_goal': ({'robot': 'planar_3r', 'start': A,
                              'goal': pose(1.5, 2.5, 0.0, {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 0.0})},
                             'goal.orientation: quaternion is not normalised (norm 0, expected 1 within 0.001): '
                             'all zero, the orientation is unset'),
    'joint_count': ({'robot': 'planar_3r', 'start_joints': [0.1, 0.2], 'goal': B}, 'has 3 joints'),
    'unknown_key': ({'robot': 'planar_3r', 'start': A, 'goal': B, 'speed': 3}, "unknown keys ['speed']"),
    'singular_metric': ({'robot': 'planar_3r', 'metric': 'position', 'start': A, 'goal': B}, 'singular'),
    'no_goal': ({'robot': 'planar_3r', 'start': A}, 'goal'),
    'top_level_list': ([1, 2, 3], 'expected a mapping'),
    'malformed_yaml': ('robot: [planar_3r\nstart: {position: {x: 1\n', 'malformed YAML'),
    'missing_file': (None, 'cannot read request'),
    'samples': ('samples', '--samples must be at least 2'),
    'bad_urdf': ('bad_urdf', 'URDF: not valid XML'),
    'bad_method_key': ({'robot': 'planar_3r', 'start': A, 'goal': B, 'method': 'newton'},
                       "request: method must be one of 'auto', 'collocation', got 'newton'"),
    'bad_method_flag': ('method_flag', "method must be one of 'auto', 'collocation', got 'pullback'"),
}
#: Run as real subprocesses of the console script (the rest in-process through plan_main, the
#: same code path, to keep the suite fast on 2 cores).
SUBPROCESS_CASES = ('nan_position', 'unreachable', 'unknown_robot', 'malformed_yaml', 'missing_file')


def write_case(d, name):
    content = FAILURES[name][0]
    if content is None:
        return ['does_not_exist.yaml']
    if content == 'samples':
        return [os.path.join(EXAMPLES, 'paper_3r.yaml'), '--samples', '1']
    if content == 'method_flag':
        return [os.path.join(EXAMPLES, 'paper_3r.yaml'), '--method', 'pullback']
    if content == 'bad_urdf':
        (d / 'broken.urdf').write_text('<robot name="broken"><link name="a"></robot>')
        content = {'robot': 'broken.urdf', 'start_joints': [0.0], 'goal_joints': [0.1]}
    (d / f'{name}.yaml').write_text(content if isinstance(content, str) else yaml.safe_dump(content))
    return [f'{name}.yaml']


@pytest.fixture(scope='module')
def failure_runs(tmp_path_factory):
    """Run every failure case at once (separate processes), collect (returncode, stdout, stderr)."""
    d = tmp_path_factory.mktemp('cli_fail')
    cases = [(name, write_case(d, name)) for name in SUBPROCESS_CASES]
    env = {**os.environ, 'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1'}
    out = {}
    for k in range(0, len(cases), PARALLEL):  # a few at a time: the machine has 2 cores
        batch = [(name, subprocess.Popen(COMMAND + args, cwd=d, env=env, stdout=subprocess.PIPE,
                                         stderr=subprocess.PIPE, text=True))
                 for name, args in cases[k:k + PARALLEL]]
        for name, proc in batch:
            try:
                stdout, stderr = proc.communicate(timeout=TIMEOUT)
            except subprocess.TimeoutExpired:
                proc.kill()
                stdout, stderr = proc.communicate()
            out[name] = (proc.returncode, stdout, stderr)
    return out


def check_failure(name, code, stdout, stderr):
    assert code not in (0, None), f'exit code {code}'
    assert 'Traceback' not in stderr and 'Traceback' not in stdout
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert lines[0].startswith('ERROR:'), lines[0]
    assert FAILURES[name][1] in lines[0], lines[0]
    assert stdout.strip() == ''


@pytest.mark.parametrize('name', SUBPROCESS_CASES)
def test_failure_prints_one_error_line(failure_runs, name):
    check_failure(name, *failure_runs[name])


@pytest.mark.parametrize('name', [n for n in FAILURES if n not in SUBPROCESS_CASES])
def test_failure_prints_one_error_line_in_process(name, tmp_path, capsys, monkeypatch):
    from geodesic_planner.cli.plan import plan_main
    monkeypatch.chdir(tmp_path)
    code = plan_main(write_case(tmp_path, name))
    out = capsys.readouterr()
    check_failure(name, code, out.out, out.err)


def test_urdf_tip_link_from_request_in_process(tmp_path, capsys, monkeypatch):
    """base_link/tip_link keys pick a chain out of a tree (test/data/branching.urdf, left branch:
    p = (0.5 c1 + 0.3 c12, 0.5 s1 + 0.3 s12, 1))."""
    from geodesic_planner.cli.plan import plan_main
    shutil.copy(os.path.join(ROOT, 'test', 'data', 'branching.urdf'), tmp_path / 'tree.urdf')
    req = {'robot': 'tree.urdf', 'tip_link': 'left_tool', 'start_joints': [0.2, 0.5], 'goal_joints': [0.6, 0.9]}
    (tmp_path / 'req.yaml').write_text(yaml.safe_dump(req))
    monkeypatch.chdir(tmp_path)
    assert plan_main(['req.yaml', '--samples', '3']) == 0
    d = json.loads(capsys.readouterr().out)
    assert d['joint_names'] == ['j1', 'j_left']
    q = np.array(d['positions'])
    assert_allclose(q[[0, -1]], [[0.2, 0.5], [0.6, 0.9]], atol=1e-12)
    q1, q12 = q[:, 0], q.sum(axis=1)
    assert_allclose(d['ee_positions'], np.stack([0.5 * np.cos(q1) + 0.3 * np.cos(q12),
                                                 0.5 * np.sin(q1) + 0.3 * np.sin(q12), np.ones(3)], 1),
                    atol=1e-12)


def test_unwritable_output_is_one_error_line(tmp_path, capsys):
    from geodesic_planner.cli.plan import plan_main
    code = plan_main([os.path.join(EXAMPLES, 'paper_rrpp_joints.yaml'), '--output', str(tmp_path)])
    out = capsys.readouterr()
    assert code != 0
    lines = [ln for ln in out.err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith('ERROR:') and 'Traceback' not in out.err


def test_via_example_with_blends(tmp_path, capsys):
    """``msg_examples/paper_3r_via_blend.yaml``: the JSON reports one blend zone per via pose; the
    tool (its own sampled positions) stays within blend_radius of the via pose inside each zone and
    is on the segments outside them (3R closed-form FK of the sampled joints, independently)."""
    from geodesic_planner.cli.plan import plan_main
    example = os.path.join(EXAMPLES, 'paper_3r_via_blend.yaml')
    with open(example, encoding='utf-8') as fh:
        req = yaml.safe_load(fh)
    r = req['blend_radius']
    pts = [np.array([p['position']['x'], p['position']['y']])
           for p in [req['start'], *req['via'], req['goal']]]
    out = tmp_path / 'via.json'
    assert plan_main([example, '--samples', '2001', '--output', str(out)]) == 0
    capsys.readouterr()
    d = json.loads(out.read_text())
    zones = d['blend_zones']
    assert [z['via'] for z in zones] == [1, 2, 3]
    s = np.array(d['s'])
    q = np.array(d['positions'])
    c = np.cumsum(q, axis=1)
    xy = np.stack([np.cos(c).sum(axis=1), np.sin(c).sum(axis=1)], axis=1)   # unit links
    assert_allclose(np.array(d['ee_positions'])[:, :2], xy, atol=1e-12)
    inside = np.zeros(s.size, dtype=bool)
    for z in zones:
        sel = (s >= z['s_start']) & (s <= z['s_end'])
        assert sel.sum() >= 20
        inside |= sel
        dist = np.linalg.norm(xy[sel] - pts[z['via']], axis=1)
        assert dist.max() <= r * (1 + 1e-9) and z['max_distance'] <= r * (1 + 1e-9)
        assert 0.0 < z['deviation'] <= r
    # outside the zones: on one of the four segments
    def cross2(u, v):
        return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]

    seg = np.min([np.abs(cross2(b - a, xy[~inside] - a)) / np.linalg.norm(b - a)
                  for a, b in itertools.pairwise(pts)], axis=0)
    assert seg.max() <= 1e-8


# ---------------------------------------------------------------------- every size bounded
def _vias(n):
    return {'robot': 'planar_3r', 'start': A, 'goal': B,
            'via': [pose(2.0 + 0.001 * i, 2.0, 0.0, yaw_quat(0.6)) for i in range(n)]}


def _items(n):
    return {'robot': 'planar_3r', 'start': A, 'sequence': [{'motion': 'LIN', 'goal': B}] * n}


def _bounded_case(name, d):
    """(arguments, expected exit code, the ERROR line's regular expression) of one bounded option."""
    from geodesic_planner.core.collision import MAX_OBJECTS
    from geodesic_planner.core.request import MAX_ITEMS, MAX_VIA_POSES
    from geodesic_planner.io.requests import MAX_YAML_BYTES
    from geodesic_planner.timing.resample import MAX_POINTS
    paper = os.path.join(EXAMPLES, 'paper_3r.yaml')
    big = MAX_YAML_BYTES + 1
    if name == 'samples':
        return [paper, '--samples', 100_000_000], 2, rf'--samples: 100000000 points, more than {MAX_POINTS}$'
    if name == 'samples_cap_plus_one':
        return [paper, '--samples', MAX_POINTS + 1], 2, rf'--samples: {MAX_POINTS + 1} points, more than {MAX_POINTS}$'
    if name == 'sample_period':    # the node's message: 1.69 s at 1 ns is 1.7e9 points
        return ([paper, '--sample-period', '1e-9'], 1,
                rf'the trajectory would have \d+ points \(1\.69 s every 1e-09 s\), more than {MAX_POINTS}: '
                'increase --sample-period$')
    if name == 'via':
        (d / 'via.yaml').write_text(yaml.safe_dump(_vias(MAX_VIA_POSES + 1)))
        return ['via.yaml'], 1, rf'request: via: {MAX_VIA_POSES + 1} poses, more than {MAX_VIA_POSES}$'
    if name == 'sequence':
        (d / 'seq.yaml').write_text(yaml.safe_dump(_items(MAX_ITEMS + 1)))
        return ['seq.yaml'], 1, rf'request: sequence: {MAX_ITEMS + 1} items, more than {MAX_ITEMS}$'
    if name == 'request_bytes':
        (d / 'big.yaml').write_text('robot: planar_3r\n' + '#' * (big - 18) + '\n')
        return ['big.yaml'], 1, rf"request 'big.yaml': {big} bytes, more than {MAX_YAML_BYTES}$"
    if name == 'request_device':
        return ['/dev/zero'], 1, r"cannot read request '/dev/zero': not a regular file$"
    if name == 'scene_bytes':
        (d / 'scene.yaml').write_text('objects: []\n' + '#' * (big - 13) + '\n')
        return [paper, '--scene', 'scene.yaml'], 1, rf"scene 'scene.yaml': {big} bytes, more than {MAX_YAML_BYTES}$"
    if name == 'scene_objects':
        objects = [{'id': f'o{i}', 'type': 'sphere', 'dimensions': [0.01], 'pose': {'position': [9, 9, i]}}
                   for i in range(MAX_OBJECTS + 1)]
        (d / 'many.yaml').write_text(yaml.safe_dump({'objects': objects}))
        return ([paper, '--scene', 'many.yaml'], 1,
                rf'scene: objects: {MAX_OBJECTS + 1} objects, at most {MAX_OBJECTS}$')
    raise AssertionError(name)


BOUNDED = ('samples', 'samples_cap_plus_one', 'sample_period', 'via', 'sequence', 'request_bytes',
           'request_device', 'scene_bytes', 'scene_objects')


@pytest.mark.parametrize('name', BOUNDED)
def test_every_size_is_bounded(name, tmp_path):
    """Each size a user gives is refused past its cap at once, with the cap in the message, and
    under a 2 GB address space (``--samples 100000000`` grew to 23 GB before)."""
    import re
    argv, code, pattern = _bounded_case(name, tmp_path)
    proc, seconds = run_bounded(COMMAND + [*argv, '-o', 'out.json'], tmp_path)
    line = error_line(proc)
    assert proc.returncode == code, (proc.returncode, line)
    assert re.search(pattern, line), line
    assert seconds < QUICK, seconds
    assert not (tmp_path / 'out.json').exists()


def test_at_the_caps_a_plan_fits_in_memory(tmp_path):
    """--samples at MAX_POINTS and a timed trajectory of nearly MAX_POINTS points: written, in
    under 2 GB; the counts are those asked."""
    from geodesic_planner.timing.resample import MAX_POINTS
    period = 1.69 / (MAX_POINTS - 10)            # the 3R plan lasts 1.685 s
    proc, seconds = run_bounded(COMMAND + [os.path.join(EXAMPLES, 'paper_3r.yaml'), '--samples', MAX_POINTS,
                                           '--sample-period', repr(period), '-o', 'out.json'], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    d = json.loads((tmp_path / 'out.json').read_text())
    assert len(d['s']) == MAX_POINTS
    n = len(d['trajectory']['times'])
    assert MAX_POINTS - 1000 < n <= MAX_POINTS
    assert seconds < 240, seconds


# ---------------------------------------------------------------------- the timed trajectory
def fk_3r_tool(q):
    """Tool (x, y, φ) of the unit-link planar 3R, (N, 3), by hand."""
    c = np.cumsum(q, axis=1)
    return np.stack([np.cos(c).sum(axis=1), np.sin(c).sum(axis=1), c[:, -1]], axis=1)


@pytest.fixture(scope='module')
def timed_3r(tmp_path_factory):
    d = tmp_path_factory.mktemp('timed')
    proc = run([os.path.join(EXAMPLES, 'paper_3r.yaml'), '--samples', 11, '--sample-period', 0.02,
                '-o', d / 'out.json'], d)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == '' and '-> ' in proc.stderr
    return json.loads((d / 'out.json').read_text())


def test_timed_trajectory_times_and_rest(timed_3r):
    tr = timed_3r['trajectory']
    t = np.array(tr['times'])
    assert tr['sample_period'] == 0.02 and t[0] == 0.0 and t[-1] == tr['duration'] > 1.0
    assert_allclose(np.diff(t)[:-1], 0.02, rtol=0, atol=1e-12)
    assert 0.0 < t[-1] - t[-2] <= 0.02 * (1 + 1e-6)
    v, a = np.array(tr['velocities']), np.array(tr['accelerations'])
    assert np.array(tr['positions']).shape == v.shape == a.shape == (t.size, 3)
    assert_allclose(v[[0, -1]], 0.0, atol=1e-12)              # rest to rest
    from geodesic_planner import load_robot
    robot = load_robot('planar_3r')
    assert np.all(np.abs(v) <= np.asarray(robot.max_velocity) * (1 + 1e-9))
    assert np.all(np.abs(a) <= np.asarray(robot.max_acceleration) * (1 + 1e-9))


def test_timed_trajectory_keeps_the_tool_on_the_line(timed_3r):
    """Hand FK of the written positions: on the segment A-B, φ linear along it, monotonic."""
    oracle = Oracle3R(os.path.join(EXAMPLES, 'paper_3r.yaml'))
    tool = fk_3r_tool(np.array(timed_3r['trajectory']['positions']))
    ab = oracle.pb[:2] - oracle.pa[:2]
    rel = tool[:, :2] - oracle.pa[:2]
    lam = rel @ ab / (ab @ ab)
    assert np.abs(rel[:, 0] * ab[1] - rel[:, 1] * ab[0]).max() / np.linalg.norm(ab) <= 1e-6
    assert np.abs(tool[:, 2] - (oracle.phia + lam * (oracle.phib - oracle.phia))).max() <= 1e-6
    assert_allclose(lam[[0, -1]], [0.0, 1.0], atol=1e-6)
    assert np.all(np.diff(lam) >= -1e-9)


def test_timed_trajectory_velocities_and_accelerations_integrate_to_the_positions(timed_3r):
    """Between points, q1 - q0 = h (v0 + v1) / 2 - h^2 (a1 - a0) / 12 + O(h^4 jerk's jump): the
    written derivatives belong to the written positions."""
    tr = timed_3r['trajectory']
    t, q = np.array(tr['times']), np.array(tr['positions'])
    v, a = np.array(tr['velocities']), np.array(tr['accelerations'])
    h = np.diff(t)[:, None]
    resid = np.diff(q, axis=0) - h * (v[1:] + v[:-1]) / 2 + h**2 * np.diff(a, axis=0) / 12
    assert np.abs(resid).max() <= 1e-5
    assert np.abs(np.diff(q, axis=0)).max() > 1e-3            # not a trivially still trajectory


def test_timed_trajectory_matches_the_library_at_the_written_times(timed_3r):
    from geodesic_planner.io.requests import load_request
    tr = timed_3r['trajectory']
    traj = load_request(os.path.join(EXAMPLES, 'paper_3r.yaml')).plan().timed()
    q, dq, ddq = traj.at_time(np.array(tr['times']))
    assert_allclose(tr['positions'], q, atol=1e-12)
    assert_allclose(tr['velocities'], dq, atol=1e-12)
    assert_allclose(tr['accelerations'], ddq, atol=1e-12)


# ---------------------------------------------------------------------- --scene
def _segment_distance(c, p0, p1):
    """Distance from the point c (2,) to the segments p0-p1, (N, 2) each."""
    d = p1 - p0
    lam = np.clip(((c - p0) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p0 + lam[:, None] * d - c, axis=1)


def test_scene_clear_reports_min_clearance_against_hand_distances(tmp_path):
    """A ball beside the line: the plan passes; min_clearance is never above the smallest distance
    between the ball and the link capsules (radius 0.05 m, joint to joint, by hand) at the written
    points, and within 1 mm or 10 % below it."""
    from geodesic_planner.core.collision import DEFAULT_LINK_RADIUS
    centre, radius = np.array([2.35, 2.35]), 0.1
    (tmp_path / 'ball.yaml').write_text(yaml.safe_dump({'objects': [
        {'id': 'ball', 'type': 'sphere', 'dimensions': [radius], 'pose': {'position': [*centre.tolist(), 0.0]}}]}))
    proc = run([os.path.join(EXAMPLES, 'paper_3r.yaml'), '--scene', 'ball.yaml', '--sample-period', 0.002,
                '-o', 'out.json'], tmp_path)
    assert proc.returncode == 0, proc.stderr
    d = json.loads((tmp_path / 'out.json').read_text())
    col = d['collision']
    assert col['scene'] == 'ball.yaml' and col['branch'] == 'default' and 'ball' in col['pair']
    q = np.array(d['trajectory']['positions'])
    c = np.cumsum(q, axis=1)
    joints = np.zeros((q.shape[0], 4, 2))
    joints[:, 1:] = np.cumsum(np.stack([np.cos(c), np.sin(c)], axis=2), axis=1)
    dist = np.min([_segment_distance(centre, joints[:, k], joints[:, k + 1]) for k in range(3)]
                  + [np.linalg.norm(centre) * np.ones(len(q))], axis=0) - radius - DEFAULT_LINK_RADIUS
    least = float(dist.min())
    assert 0.1 < least < 0.5
    assert col['min_clearance'] <= least + 1e-9
    assert col['min_clearance'] >= least - max(1e-3, 0.1 * least) - 1e-6
    assert f"min_clearance {col['min_clearance']:.4g} m" in proc.stderr


def test_scene_collision_is_refused_with_its_reason(tmp_path):
    proc, seconds = run_bounded(COMMAND + [os.path.join(EXAMPLES, 'paper_3r.yaml'), '--scene',
                                           os.path.join(EXAMPLES, 'scene_box.yaml'), '-o', 'out.json'], tmp_path)
    line = error_line(proc)
    assert proc.returncode == 1
    assert line.startswith("ERROR: collision on the way at ") and "'box' and 'link_3' are " in line, line
    assert not (tmp_path / 'out.json').exists() and proc.stdout == ''


@pytest.mark.parametrize('target, why', [('.', 'it is a directory'), ('no_dir/out.json', 'no such directory'),
                                         ('a_file/out.json', 'not a directory')])
def test_unwritable_output_is_refused_before_planning(tmp_path, capsys, monkeypatch, target, why):
    from geodesic_planner.cli import plan as plan_cli
    (tmp_path / 'a_file').write_text('x')
    monkeypatch.chdir(tmp_path)
    planned = []
    monkeypatch.setattr(plan_cli, 'plan_in_scene', lambda *a: planned.append(a))
    code = plan_cli.plan_main([os.path.join(EXAMPLES, 'paper_3r.yaml'), '-o', target])
    out = capsys.readouterr()
    assert code == 1 and out.out == '' and planned == []
    lines = [ln for ln in out.err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith(f'ERROR: cannot write {target!r}') and why in lines[0], lines
