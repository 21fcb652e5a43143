"""colcon build and colcon test, as a ROS 2 user runs them (scripts/colcon.sh).

In the suite (the README's test command): ``colcon list`` finds both packages, then one build of
geodesic_planner into a temporary workspace against the interface package that setup_env.sh
built into the venv (``--interfaces-from-venv``: an underlay, found in the venv's ament index;
the same CMakeLists and rosidl build that colcon would run, already done by the set-up), then
``colcon test`` of geodesic_planner restricted to the ament pep257 linter, the lint configuration
check and one ROS test, so that the suite does not run twice (flake8 runs in the suite itself).
``colcon test`` runs outside any private network namespace; to show what happens there, it runs
in a nested namespace that has an interface besides ``lo`` (nothing leaves it): the ROS test must
be skipped with its reason, and ``colcon test-result`` must report no failure. 11-13 s of CPU
(20-26 s of wall time at a load of 5 on 2 cores); with both packages built it took 51 s of CPU
(38 s of wall time on quiet cores, 35 s of CPU the interface package's rosidl build) and timed out
at 300 s in a whole-suite run beside two busy loops.

Marked slow (``--run-slow``): the cold build of both packages, the interface package through
rosidl (C and C++ compilers) included.
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
#: Upper bound of one colcon call, s (a cold build of both packages takes about 30 s here).
TIMEOUT = 300.0
ROS_TEST = 'test/ros/test_launch.py::test_two_namespaces_side_by_side'
#: The ament linter tests colcon test runs: pep257 through ament and the committed configuration
#: (flake8, 10 s, runs in the suite itself: test/infra/test_ament_lint.py).
AMENT_LINT_TESTS = ('test/infra/test_ament_lint.py::test_pep257',
                    'test/infra/test_ament_lint.py::test_lint_configuration_is_committed')
SKIP_REASON = 'ros: not inside a loopback-only network namespace'


def colcon(ws: Path, *args: str, outside_netns: bool = False,
           both: bool = False, timeout: float = TIMEOUT) -> subprocess.CompletedProcess[str]:
    """``bash scripts/colcon.sh [--interfaces-from-venv] ws args...``; ``both``: both packages
    (else the interface package is the venv's); ``outside_netns``: in a nested namespace with an
    extra interface, as on a machine where no private namespace was made."""
    argv = ['bash', str(SCRIPT), *([] if both else ['--interfaces-from-venv']), str(ws), *args]
    if outside_netns:
        argv = ['unshare', '--net', 'sh', '-c',
                'ip link set lo up && ip link add gp_extra0 type bridge && exec "$@"', 'sh', *argv]
    env = {k: v for k, v in os.environ.items() if k != 'GEODESIC_PLANNER_NETNS'}
    try:
        return subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout,
                              check=False)
    except subprocess.TimeoutExpired as err:
        pytest.fail(f'{" ".join(args)} did not finish within {timeout:.0f} s: {err}')


def _needs(*tools: str) -> None:
    for tool in tools:
        if shutil.which(tool) is None:
            pytest.skip(f'needs {tool}')
    if importlib.util.find_spec('colcon_core') is None:
        pytest.skip('colcon is not installed (colcon-common-extensions, pinned in requirements/lock.txt)')


def _check_planner_install(ws: Path) -> None:
    """The installed share files, console scripts and launch file of geodesic_planner."""
    share = ws / 'install' / 'geodesic_planner' / 'share' / 'geodesic_planner'
    for rel in ('launch/geodesic_planner.launch.py', 'config/geodesic_planner.yaml',
                'config/trajectory_processor.yaml', 'config/joint_limits.yaml', 'package.xml'):
        assert (share / rel).read_bytes() == (ROOT / rel).read_bytes(), rel
    for script in ('geodesic_planner_node', 'trajectory_processor_node'):   # where ros2 run looks
        assert os.access(ws / 'install' / 'geodesic_planner' / 'lib' / 'geodesic_planner' / script, os.X_OK)
    # the installed launch file finds the installed config files
    spec = importlib.util.spec_from_file_location('installed_launch', share / 'launch' / 'geodesic_planner.launch.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert [Path(p).parent for s in module.describe() for p in s.parameter_files] == [share / 'config'] * 2


@pytest.mark.linter
def test_colcon_build_and_test(tmp_path: Path) -> None:
    _needs('unshare', 'ip')
    if importlib.util.find_spec('geodesic_planner_interfaces') is None:
        pytest.skip('the venv has no geodesic_planner_interfaces: run bash scripts/setup_env.sh')
    ws = tmp_path / 'ws'
    before = sorted(p.name for p in ROOT.iterdir())

    listed = colcon(ws, 'list', both=True)       # what a plain `colcon build` here would build
    assert listed.returncode == 0, listed.stdout + listed.stderr
    assert sorted(line.split('\t')[::2] for line in listed.stdout.splitlines()) == [
        ['geodesic_planner', '(ros.ament_python)'],
        ['geodesic_planner_interfaces', '(ros.ament_cmake)']], listed.stdout

    built = colcon(ws, 'build', '--event-handlers', 'console_direct-')
    assert built.returncode == 0, built.stdout + built.stderr
    assert 'Summary: 1 package finished' in built.stdout, built.stdout
    assert not (ws / 'install' / 'geodesic_planner_interfaces').exists()   # the venv's was used
    _check_planner_install(ws)

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


@pytest.mark.linter
@pytest.mark.slow
# A cold rosidl build: 30 s wall and 42 s CPU on 2 quiet cores, mostly C++ compiles; beside two
# busy loops and the suite's workers it got a sixth of a core and took more than 300 s.
@pytest.mark.timeout(900)
def test_colcon_builds_both_packages(tmp_path: Path) -> None:
    _needs('cc', 'c++')
    ws = tmp_path / 'ws'
    built = colcon(ws, 'build', '--event-handlers', 'console_direct-', both=True, timeout=850.0)
    assert built.returncode == 0, built.stdout + built.stderr
    assert 'Summary: 2 packages finished' in built.stdout, built.stdout
    assert list((ws / 'install' / 'geodesic_planner_interfaces').rglob('_plan_trajectory.py'))
    _check_planner_install(ws)
