"""geodesic-plan batch: real Ray (a local instance on 127.0.0.1) inside the loopback-only namespace.

Every row is checked against the library called directly (``parse_request``, ``plan``, ``timed``,
``sample``; the collision check through geodesic-plan's own ``plan_in_scene``), the failure codes
against the numbers of PlanErrorCode.msg written out here. Four jobs start Ray: a Parquet input
on 1 and on 2 workers (identical shards but for planning_time; the MCAP bag), and a JSON Lines
job killed (SIGKILL) after its first shards, then resumed.
"""
from __future__ import annotations

import copy
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tools import netns

pa = pytest.importorskip('pyarrow')
pq = pytest.importorskip('pyarrow.parquet')
pytest.importorskip('ray')

if not netns.is_loopback_only():
    pytest.skip(f'starts Ray: not inside a loopback-only network namespace (interfaces: '
                f'{", ".join(netns.network_interfaces())}): run through scripts/netns.sh (bash scripts/test.sh '
                'does); Ray must never look for this machine\'s public address', allow_module_level=True)

from geodesic_planner.cli.plan import plan_in_scene, scene_model  # noqa: E402
from geodesic_planner.core.robots import load_robot  # noqa: E402
from geodesic_planner.core.transforms import matrix_to_quat  # noqa: E402
from geodesic_planner.core.errors import RequestError  # noqa: E402
from geodesic_planner.io.batch_job import JobSpec, run_job  # noqa: E402
from geodesic_planner.io.batch_output import read_rows  # noqa: E402
from geodesic_planner.io.requests import parse_request  # noqa: E402
from geodesic_planner.timing.law import scaled_limits  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
PERIOD = 0.01
Q0 = [0.3, -1.2, 1.4, -1.5, -1.4, 0.2]
ORIENT = {'x': 0.670858, 'y': 0.724375, 'z': 0.072555, 'w': 0.141303}
GOAL = {'position': {'x': -0.386636, 'y': -0.323253, 'z': 0.359455}, 'orientation': ORIENT}
SEQUENCE = [
    {'motion': 'LIN', 'goal': GOAL, 'blend_radius': 0.03},
    {'motion': 'CIRC', 'goal': {'position': {'x': -0.286636, 'y': -0.223253, 'z': 0.359455}, 'orientation': ORIENT},
     'center': [-0.386636, -0.223253, 0.359455], 'blend_radius': 0.03},
    {'motion': 'PTP', 'goal_joints': Q0, 'ptp': 'joint_line'}]
SCENE = 'objects:\n  - id: far_box\n    type: box\n    dimensions: [0.2, 0.2, 0.2]\n' \
        '    pose: {position: [0.6, 0.6, 0.8], orientation: [0, 0, 0, 1]}\n'

# (batch request, the YAML request it means or the expected PlanErrorCode number)
CASES: list[tuple[dict[str, Any], Any]] = [
    ({'id': 'lin', 'motion': 'LIN', 'start_joints': Q0, 'goal': GOAL},
     {'robot': 'ur5e', 'start_joints': Q0, 'sequence': [{'motion': 'LIN', 'goal': GOAL}]}),
    ({'id': 'ptp-half-speed', 'motion': 'PTP', 'start_joints': Q0, 'goal_joints': [0.0, -1.0, 1.0, -1.2, -1.5, 0.0],
      'ptp': 'joint_line', 'velocity_scaling': 0.5, 'acceleration_scaling': 0.25},
     {'robot': 'ur5e', 'start_joints': Q0,
      'sequence': [{'motion': 'PTP', 'goal_joints': [0.0, -1.0, 1.0, -1.2, -1.5, 0.0], 'ptp': 'joint_line'}]}),
    ({'id': 'geodesic', 'start_joints': Q0, 'goal': GOAL}, {'robot': 'ur5e', 'start_joints': Q0, 'goal': GOAL}),
    ({'id': 'sequence', 'start_joints': Q0, 'sequence': SEQUENCE},
     {'robot': 'ur5e', 'start_joints': Q0, 'sequence': SEQUENCE}),
    ({'id': 'in-scene', 'motion': 'LIN', 'start_joints': Q0, 'goal': GOAL, 'scene': 'far'},
     {'robot': 'ur5e', 'start_joints': Q0, 'sequence': [{'motion': 'LIN', 'goal': GOAL}]}),
    ({'id': 'planar', 'robot': 'planar_3r', 'start_joints': [0.2, 0.4, 0.3], 'goal_joints': [0.5, 0.1, -0.2]},
     {'robot': 'planar_3r', 'start_joints': [0.2, 0.4, 0.3], 'goal_joints': [0.5, 0.1, -0.2]}),
    ({'id': 'five-joints', 'start_joints': Q0, 'goal_joints': [0.0, 0.0, 0.0, 0.0, 0.0]}, -101),  # INVALID_REQUEST
    ({'id': 'no-such-scene', 'motion': 'LIN', 'start_joints': Q0, 'goal': GOAL, 'scene': 'nope'}, -101),
    ({'id': 'too-slow', 'start_joints': Q0, 'sequence': SEQUENCE, 'time_limit': 0.001}, -6),       # TIMED_OUT
]


def _run(*args: str, timeout: float = 150.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, '-m', 'geodesic_planner.cli.plan', 'batch', *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout, check=False)


def _clean(stderr: str) -> None:
    assert 'Traceback' not in stderr, stderr
    assert 'Failed to determine local IP' not in stderr, stderr     # no look-up of a public address


def _direct(yaml_req: dict[str, Any], batch_req: dict[str, Any], scene: Path | None) -> dict[str, Any]:
    """The row's numbers from the library called directly, as geodesic-plan plans."""
    req = parse_request(copy.deepcopy(yaml_req))
    if scene is not None and batch_req.get('scene'):
        _, trajectory, found, _ = plan_in_scene(req, scene_model(req, str(scene)))
        clearance = found.min_clearance
    else:
        path = req.plan()
        v, a = batch_req.get('velocity_scaling', 1.0), batch_req.get('acceleration_scaling', 1.0)
        limits = {} if (v, a) == (1.0, 1.0) else scaled_limits(req.robot.max_velocity, req.robot.max_acceleration,
                                                                 1.0, v, a)
        trajectory, clearance = path.timed(**limits), float('nan')
    t, q, dq, ddq = trajectory.sample(PERIOD, check=True)
    return {'duration': trajectory.duration, 'min_clearance': clearance, 'times': t, 'positions': q,
            'velocities': dq, 'accelerations': ddq}


def _same(a: dict[str, Any], b: dict[str, Any]) -> None:
    """Every column of two rows equal bit for bit, but planning_time (a measurement)."""
    assert set(a) == set(b)
    for key in a:
        if key == 'planning_time':
            continue
        if isinstance(a[key], np.ndarray):
            np.testing.assert_array_equal(a[key], b[key], err_msg=key)
        elif isinstance(a[key], float) and np.isnan(a[key]):
            assert np.isnan(b[key]), key
        else:
            assert a[key] == b[key], key


@pytest.fixture(scope='module')
def parquet_jobs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    tmp = tmp_path_factory.mktemp('batch')
    scene = tmp / 'far.yaml'
    scene.write_text(SCENE)
    requests = tmp / 'requests.parquet'
    # pa.array infers the columns from every row (Table.from_pylist from the first row only)
    pq.write_table(pa.Table.from_struct_array(pa.array([r for r, _ in CASES])), requests, row_group_size=4)
    out = {'scene': scene}
    for workers in (1, 2):
        extra = ['--bag', str(tmp / 'bag')] if workers == 2 else []
        done = _run(str(requests), '-o', str(tmp / f'out{workers}'), '--robot', 'ur5e', '--scene', f'far={scene}',
                    '--workers', str(workers), '--shard-size', '4', *extra)
        assert done.returncode == 0, done.stderr
        _clean(done.stderr)
        out[workers] = list(read_rows(str(tmp / f'out{workers}')))
        out[f'stderr{workers}'] = done.stderr
    out['bag'] = tmp / 'bag'
    return out


def test_every_row_is_the_library_called_directly(parquet_jobs: dict[str, Any]) -> None:
    rows = parquet_jobs[1]
    assert [r['index'] for r in rows] == list(range(1, len(CASES) + 1))
    for row, (batch_req, expected) in zip(rows, CASES):
        assert row['id'] == batch_req['id']
        if isinstance(expected, int):
            assert row['status'] == expected, (row['id'], row['message'])
            assert np.isnan(row['duration']) and row['times'].size == 0
            continue
        assert row['status'] == 1, (row['id'], row['message'])
        assert row['message'] == '' and row['fraction'] == 1.0 and row['planning_time'] > 0
        direct = _direct(expected, batch_req, parquet_jobs['scene'])
        assert row['duration'] == direct['duration'], row['id']
        for key in ('times', 'positions', 'velocities', 'accelerations'):
            np.testing.assert_array_equal(row[key], direct[key], err_msg=f'{row["id"]}: {key}')
        if batch_req.get('scene'):
            assert row['min_clearance'] == direct['min_clearance'] and 0.0 < row['min_clearance'] < 2.0
        else:
            assert np.isnan(row['min_clearance'])
        assert row['joint_names'] == list(load_robot(expected['robot']).joint_names)
    by_id = {r['id']: r for r in rows}
    assert 'too-slow' in by_id and 'time limit of 0.001 s' in by_id['too-slow']['message']
    assert "no scene named 'nope'" in by_id['no-such-scene']['message']
    slow, fast = by_id['ptp-half-speed']['duration'], _direct(CASES[1][1], {}, None)['duration']
    assert slow > 1.5 * fast         # the scaling factors reached the time law


def test_one_and_two_workers_give_the_same_shards(parquet_jobs: dict[str, Any]) -> None:
    one, two = parquet_jobs[1], parquet_jobs[2]
    assert [r['id'] for r in one] == [r['id'] for r in two]
    for a, b in zip(one, two):
        _same(a, b)
    assert 'on 2 worker(s)' in parquet_jobs['stderr2']


def test_the_bag_replays_the_successful_rows(parquet_jobs: dict[str, Any]) -> None:
    from geodesic_planner.io.bags import read_trajectories
    records = read_trajectories(parquet_jobs['bag'])
    ok = [r for r in parquet_jobs[2] if r['status'] == 1]
    assert [rec.frame_id for rec in records] == [r['id'] for r in ok]
    for rec, row in zip(records, ok):
        assert not rec.problems
        np.testing.assert_allclose(rec.t, row['times'], atol=1e-9, rtol=0)   # time_from_start in ns
        np.testing.assert_array_equal(rec.positions, row['positions'])
        np.testing.assert_array_equal(rec.accelerations, row['accelerations'])


def _lin_requests(n: int) -> list[dict[str, Any]]:
    robot, rng = load_robot('ur5e'), np.random.default_rng(7)
    out = []
    for i in range(n):
        q = np.array(Q0) + rng.uniform(-0.1, 0.1, 6)
        T = robot.fk(q[None])[0]
        x, y, z, w = matrix_to_quat(T[None, :3, :3])[0]
        p = T[:3, 3] + rng.uniform(-0.05, 0.05, 3)
        out.append({'id': f'lin{i}', 'motion': 'LIN', 'start_joints': q.tolist(),
                    'goal': {'position': dict(zip('xyz', p.tolist())),
                             'orientation': {'x': float(x), 'y': float(y), 'z': float(z), 'w': float(w)}}})
    return out


def _session(sid: int) -> dict[int, str]:
    """The live processes of session ``sid``: pid -> command line."""
    alive = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                fields = Path(f'/proc/{entry}/stat').read_text().rsplit(')', 1)[1].split()
                cmd = Path(f'/proc/{entry}/cmdline').read_bytes().replace(b'\0', b' ').decode(errors='replace')
            except OSError:
                continue
            if int(fields[3]) == sid and fields[0] != 'Z':
                alive[int(entry)] = cmd
    return alive


#: Ray's agents outlive a killed raylet by ~60 s (they report its death to the dead GCS first).
AGENTS = ('ray::DashboardAgent', 'ray::RuntimeEnvAgent')


def test_malformed_lines_strict_and_a_killed_job_resumed(tmp_path: Path, request: pytest.FixtureRequest) -> None:
    requests = _lin_requests(100)
    lines = [json.dumps(r) for r in requests]
    lines.insert(4, '{"id": "broken", "motion": "LIN",')          # line 5: malformed JSON
    lines.insert(9, '')                                            # line 10: blank, not a request
    path = tmp_path / 'lin.jsonl'
    path.write_text('\n'.join(lines) + '\n')
    out = tmp_path / 'out'

    spec = JobSpec(str(path), str(out), 'ur5e', shard_size=10)     # refusals before Ray starts: in-process
    with pytest.raises(RequestError, match=r'^line 5: malformed JSON at column 34: .*--strict: nothing was planned'):
        run_job(spec, strict=True)
    assert not out.exists()                                         # refused before anything was made

    args = [str(path), '-o', str(out), '--robot', 'ur5e', '--workers', '1', '--shard-size', '10']
    ray_tmp = tempfile.mkdtemp(prefix='gpt', dir='/tmp')      # the killed job's Ray directory, removed here
    request.addfinalizer(lambda: shutil.rmtree(ray_tmp, ignore_errors=True))
    job = subprocess.Popen([sys.executable, '-m', 'geodesic_planner.cli.plan', 'batch', *args], cwd=ROOT,
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
                           env={**os.environ, 'TMPDIR': ray_tmp})
    def wait_for_shards(n: int) -> None:
        deadline = time.monotonic() + 90
        while len(list(out.glob('part-*.parquet'))) < n and job.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)

    wait_for_shards(1)
    workers = [pid for pid, cmd in _session(job.pid).items() if cmd.startswith('ray::_Worker')]
    assert len(workers) == 1, _session(job.pid)
    os.kill(workers[0], signal.SIGKILL)         # a worker lost: its requests are planned again
    wait_for_shards(3)
    os.kill(job.pid, signal.SIGKILL)            # the job itself killed
    job.wait(timeout=30)
    assert job.stderr is not None
    killed_err = job.stderr.read()
    assert 'WARNING: line 5: malformed JSON at column 34' in killed_err and 'skipped' in killed_err, killed_err
    first = {p.name: p.read_bytes() for p in out.glob('part-*.parquet')}
    assert 3 <= len(first) < 11, sorted(first)        # killed mid-way (11 shards in all)
    # Ray's processes (GCS, raylet, the worker) share the killed driver's fate; its two agents
    # are killed here (ours: started by the job) rather than waited for
    deadline = time.monotonic() + 30
    while any(not cmd.startswith(AGENTS) for cmd in _session(job.pid).values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = _session(job.pid)
    for pid in left:
        os.kill(pid, signal.SIGKILL)
    assert all(cmd.startswith(AGENTS) for cmd in left.values()), f'outlived the killed job: {left}'

    with pytest.raises(RequestError, match='holds the results of a job: --resume to go on'):
        run_job(spec)                                               # without --resume
    resumed = _run(*args, '--resume')
    assert resumed.returncode == 0, resumed.stderr
    _clean(resumed.stderr)
    assert ('line 5' in resumed.stderr) == ('part-000000.parquet' not in first)   # reported where read
    shards = {int(name[5:11]) for name in first}
    done_before = sum(1 for i, line in enumerate(lines) if line.strip() and i // 10 in shards)
    assert f'{done_before} done before' in resumed.stderr, resumed.stderr
    for name, data in first.items():
        assert (out / name).read_bytes() == data           # what was written is kept as it was
    rows = list(read_rows(str(out)))
    expected_lines = [i + 1 for i, line in enumerate(lines) if line.strip() and i != 4]
    assert [r['index'] for r in rows] == expected_lines     # every request once, in input order
    assert [r['id'] for r in rows] == [r['id'] for r in requests]
    assert all(r['status'] == 1 for r in rows), [r['message'] for r in rows if r['status'] != 1]
    for row in rows[::15]:
        req = requests[int(row['id'][3:])]
        yaml_req = {'robot': 'ur5e', 'start_joints': req['start_joints'],
                    'sequence': [{'motion': 'LIN', 'goal': req['goal']}]}
        direct = _direct(yaml_req, req, None)
        assert row['status'] == 1 and row['duration'] == direct['duration']
        np.testing.assert_array_equal(row['positions'], direct['positions'])
