"""colcon build and colcon test of both packages, as a ROS 2 user runs them (scripts/colcon.sh).

One build into a temporary workspace (both packages: the interface package through rosidl, then
geodesic_planner), then ``colcon test`` of geodesic_planner restricted to the ament pep257 linter,
the lint configuration check and one ROS test, so that the suite does not run twice (flake8 runs
in the suite itself). ``colcon test`` runs outside any private network namespace; to show what
happens there, it runs in a nested namespace that has an interface besides ``lo`` (nothing leaves
it): the ROS test must be skipped with its reason, and ``colcon test-result`` must report no
failure. About 50 s on 2 cores; part of the README's test command, so CI runs the colcon build
and an ament linter through colcon on every submission.
"""
from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / 'scripts' / 'colcon.sh'
#: Upper bound of one colcon call, s (a cold build takes about 30 s here).
TIMEOUT = 300.0
ROS_TEST = 'test/ros/test_launch.py::test_two_namespaces_side_by_side'
#: The ament linter tests colcon test runs: pep257 through ament and the committed configuration
#: (flake8, 10 s, runs in the suite itself: test/infra/test_ament_lint.py).
AMENT_LINT_TESTS = ('test/infra/test_ament_lint.py::test_pep257',
                    'test/infra/test_ament_lint.py::test_lint_configuration_is_committed')
SKIP_REASON = 'ros: not inside a loopback-only network namespace'


def colcon(ws: Path, *args: str, outside_netns: bool = False) -> subprocess.CompletedProcess[str]:
    """``bash scripts/colcon.sh ws args...``; ``outside_netns``: in a nested namespace with an extra
    interface, as on a machine where no private namespace was made."""
    argv = ['bash', str(SCRIPT), str(ws), *args]
    if outside_netns:
        argv = ['unshare', '--net', 'sh', '-c',
                'ip link set lo up && ip link add gp_extra0 type bridge && exec "$@"', 'sh', *argv]
    env = {k: v for k, v in os.environ.items() if k != 'GEODESIC_PLANNER_NETNS'}
    try:
        return subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=TIMEOUT,
                              check=False)
    except subprocess.TimeoutExpired as err:
        pytest.fail(f'{" ".join(args)} did not finish within {TIMEOUT:.0f} s: {err}')


@pytest.mark.linter
def test_colcon_build_and_test_both_packages(tmp_path: Path) -> None:
    for tool in ('cc', 'c++', 'unshare', 'ip'):
        if shutil.which(tool) is None:
            pytest.skip(f'needs {tool}')
    if importlib.util.find_spec('colcon_core') is None:
        pytest.skip('colcon is not installed (colcon-common-extensions, pinned in requirements/lock.txt)')
    ws = tmp_path / 'ws'
    before = sorted(p.name for p in ROOT.iterdir())

    built = colcon(ws, 'build', '--event-handlers', 'console_direct-')
    assert built.returncode == 0, built.stdout + built.stderr
    assert 'Summary: 2 packages finished' in built.stdout, built.stdout
    share = ws / 'install' / 'geodesic_planner' / 'share' / 'geodesic_planner'
    for rel in ('launch/geodesic_planner.launch.py', 'config/geodesic_planner.yaml',
                'config/trajectory_processor.yaml', 'config/joint_limits.yaml', 'package.xml'):
        assert (share / rel).read_bytes() == (ROOT / rel).read_bytes(), rel
    for script in ('geodesic_planner_node', 'trajectory_processor_node'):   # where ros2 run looks
        assert os.access(ws / 'install' / 'geodesic_planner' / 'lib' / 'geodesic_planner' / script, os.X_OK)
    assert list((ws / 'install' / 'geodesic_planner_interfaces').rglob('_plan_trajectory.py'))
    # the installed launch file finds the installed config files
    spec = importlib.util.spec_from_file_location('installed_launch', share / 'launch' / 'geodesic_planner.launch.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert [Path(p).parent for s in module.describe() for p in s.parameter_files] == [share / 'config'] * 2

    tested = colcon(ws, 'test', '--packages-select', 'geodesic_planner', '--event-handlers', 'console_direct+',
                    '--pytest-args', '-p', 'no:cacheprovider', '-rs', *AMENT_LINT_TESTS, ROS_TEST,
                    outside_netns=True)
    if tested.returncode != 0 and 'Operation not permitted' in tested.stderr:
        pytest.skip(f'cannot create a nested network namespace here: {tested.stderr.strip()}')
    out = tested.stdout + tested.stderr
    assert tested.returncode == 0, out
    assert '2 passed, 1 skipped' in out, out
    skipped = [line for line in out.splitlines() if line.startswith('SKIPPED') and 'test_launch.py' in line]
    assert len(skipped) == 1 and SKIP_REASON in skipped[0] and 'GEODESIC_PLANNER_NETNS=off' in skipped[0], out

    result = colcon(ws, 'test-result', '--all')
    assert result.returncode == 0, result.stdout + result.stderr
    assert '3 tests, 0 errors, 0 failures, 1 skipped' in result.stdout, result.stdout
    # build/, install/, log/ stayed out (other workers of a parallel run may add their own
    # caches meanwhile, e.g. .hypothesis in a fresh clone: only colcon's names are looked for)
    added = {p.name for p in ROOT.iterdir()} - set(before)
    assert not added & {'build', 'install', 'log'}, sorted(added)
