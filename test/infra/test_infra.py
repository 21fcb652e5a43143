"""Tests of the project's infrastructure: namespace scripts and detection, the conftest guard,
packaging consistency (package.xml / setup.py / console scripts), and .ci/run vs the README."""
from __future__ import annotations

import ast
import hashlib
import importlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from package_util import console_scripts

from tools import netns
from tools.process import bin_dir

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / 'scripts'


# The console scripts whose modules are in the tree; each is checked for real (module imports,
# the function exists, the script is installed in the venv). A script declared in setup.py must
# be in one of the two lists, so a new entry cannot go unchecked.
CHECKED_CONSOLE_SCRIPTS = {
    'geodesic-plan': 'geodesic_planner.cli.plan:plan_main',
    'geodesic-compare': 'geodesic_planner.cli.compare:main',
    'geodesic-bag': 'geodesic_planner.cli.bag:main',
    'geodesic_planner_node': 'geodesic_planner.ros.planner_node:main',
    'trajectory_processor_node': 'geodesic_planner.ros.processor_node:main',
}
PENDING_CONSOLE_SCRIPTS: dict[str, str] = {}  # declared in setup.py, module not written yet

HOST_PROC_NET_DEV = textwrap.dedent("""\
    Inter-|   Receive                                                |  Transmit
     face |bytes    packets errs drop fifo frame compressed multicast|bytes    packets errs drop fifo colls carrier compressed
        lo:  123456     789    0    0    0     0          0         0   123456     789    0    0    0     0       0          0
      eth0: 9876543   12345    0    0    0     0          0         0  1234567    2345    0    0    0     0       0          0
      ifb0:       0       0    0    0    0     0          0         0        0       0    0    0    0     0       0          0
    """)  # noqa: E501 a verbatim /proc/net/dev sample


def _run(argv: list[str], timeout: float = 120, **kwargs) -> subprocess.CompletedProcess:
    kwargs.setdefault('cwd', ROOT)
    return subprocess.run(argv, capture_output=True, text=True, timeout=timeout, **kwargs)


# --------------------------------------------------------------------------- namespace detection

def test_parse_proc_net_dev_host_and_namespace() -> None:
    assert netns.parse_proc_net_dev(HOST_PROC_NET_DEV) == ['lo', 'eth0', 'ifb0']
    ns_text = '\n'.join(HOST_PROC_NET_DEV.splitlines()[:3]) + '\n'
    assert netns.parse_proc_net_dev(ns_text) == ['lo']
    assert netns.parse_proc_net_dev('header\nheader\n') == []


def test_loopback_only_decision() -> None:
    assert netns.is_loopback_only(['lo'])
    assert not netns.is_loopback_only(['lo', 'eth0'])
    assert not netns.is_loopback_only([])          # not even lo: something is wrong
    assert not netns.is_loopback_only(['eth0'])


def test_isolation_problem_names_interfaces_and_opt_out() -> None:
    problem = netns.isolation_problem(['lo', 'eth0'], environ={})
    assert problem is not None
    assert 'lo, eth0' in problem and 'GEODESIC_PLANNER_NETNS=off' in problem
    assert 'scripts/netns.sh' in problem
    assert netns.isolation_problem(['lo'], environ={}) is None
    for value in ('off', 'OFF', '0', 'false', 'no'):
        assert netns.isolation_problem(['lo', 'eth0'], environ={netns.ENV_OPT_OUT: value}) is None
    for value in ('on', '', '1', 'yes'):
        assert netns.isolation_disabled({netns.ENV_OPT_OUT: value}) is False


def test_network_interfaces_reads_given_file(tmp_path: Path) -> None:
    f = tmp_path / 'dev'
    f.write_text(HOST_PROC_NET_DEV)
    assert netns.network_interfaces(f) == ['lo', 'eth0', 'ifb0']


def _netns_or_skip(*cmd: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    result = _run(['bash', str(SCRIPTS / 'netns.sh'), *cmd], env=env)
    if result.returncode == 2 and 'CAP_SYS_ADMIN' in result.stderr:
        pytest.skip(f'no permission to create network namespaces here: {result.stderr.strip()}')
    return result


def test_netns_script_gives_loopback_only_namespace() -> None:
    code = ('import os, json; from tools import netns; '
            'print(json.dumps([netns.network_interfaces(), sorted(os.listdir("/sys/class/net")), '
            'os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"], netns.isolation_problem(environ={})]))')
    result = _netns_or_skip(sys.executable, '-c', code)
    assert result.returncode == 0, result.stderr
    interfaces, sys_class_net, discovery, problem = json.loads(result.stdout)
    assert interfaces == ['lo']
    assert sys_class_net == ['lo']
    assert discovery == 'LOCALHOST'
    assert problem is None


def test_netns_script_loopback_is_up_and_shm_private() -> None:
    marker = f'gp_infra_{os.getpid()}'
    script = ('cat /sys/class/net/lo/flags; '
              f'touch /dev/shm/{marker}; ls /dev/shm')
    result = _netns_or_skip('sh', '-c', script)
    assert result.returncode == 0, result.stderr
    flags_line, *listing = result.stdout.split()
    assert int(flags_line, 16) & 0x1, 'lo is not up (IFF_UP)'
    assert listing == [marker]                     # a fresh tmpfs: nothing else in it
    assert not Path('/dev/shm', marker).exists()   # and not shared with this namespace


def test_netns_script_passes_arguments_verbatim_and_exit_code() -> None:
    args = ['a b', '$HOME', '"q"', "it's", '', '*', '-x']
    result = _netns_or_skip(sys.executable, '-c',
                            'import sys, json; print(json.dumps(sys.argv[1:])); sys.exit(7)', *args)
    assert result.returncode == 7, result.stderr
    assert result.stdout.strip() == json.dumps(args)


def test_netns_opt_out_runs_directly_with_warning() -> None:
    env = {**os.environ, 'GEODESIC_PLANNER_NETNS': 'off'}
    env.pop('ROS_AUTOMATIC_DISCOVERY_RANGE', None)
    result = _run(['bash', str(SCRIPTS / 'netns.sh'), 'sh', '-c',
                   'echo "$ROS_AUTOMATIC_DISCOVERY_RANGE"; exit 3'], env=env)
    assert result.returncode == 3
    assert result.stdout.strip() == 'LOCALHOST'
    assert 'WARNING' in result.stderr and 'without network isolation' in result.stderr


def test_netns_refusal_is_one_clear_message() -> None:
    if os.geteuid() != 0 or shutil.which('setpriv') is None:
        pytest.skip('needs root and setpriv to run the script as an unprivileged user')
    # The unprivileged user must reach the script: pytest's tmp_path lies under a 0700 directory.
    scratch = Path(tempfile.mkdtemp(prefix='gp_netns_refusal_'))
    try:
        scratch.chmod(0o755)
        script = scratch / 'netns.sh'
        shutil.copy(SCRIPTS / 'netns.sh', script)
        script.chmod(0o755)
        result = _run(['setpriv', '--reuid=65534', '--regid=65534', '--clear-groups',
                       'bash', str(script), 'sh', '-c', 'echo SHOULD-NOT-RUN'], cwd='/')
    finally:
        shutil.rmtree(scratch)
    assert result.returncode == 2
    assert 'SHOULD-NOT-RUN' not in result.stdout
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert 'unshare' in lines[0] and 'root or CAP_SYS_ADMIN' in lines[0]
    assert 'GEODESIC_PLANNER_NETNS=off' in lines[0]


def test_netns_script_without_command_is_usage_error() -> None:
    result = _run(['bash', str(SCRIPTS / 'netns.sh')])
    assert result.returncode == 2 and 'usage' in result.stderr


# --------------------------------------------------------------------------- packaging

def _setup_py_keyword(name: str) -> str:
    tree = ast.parse((ROOT / 'setup.py').read_text())
    constants = {t.id: n.value.value for n in tree.body if isinstance(n, ast.Assign)
                 for t in n.targets if isinstance(t, ast.Name) and isinstance(n.value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and getattr(node.func, 'id', '') == 'setup':
            for kw in node.keywords:
                if kw.arg == name:
                    if isinstance(kw.value, ast.Name):
                        return constants[kw.value.id]
                    return ast.literal_eval(kw.value)
    raise AssertionError(f'setup() has no {name}=')


def test_package_xml_matches_setup_py() -> None:
    root = ET.parse(ROOT / 'package.xml').getroot()
    assert root.get('format') == '3'
    assert root.findtext('name') == _setup_py_keyword('name') == 'geodesic_planner'
    assert root.findtext('version') == _setup_py_keyword('version')
    assert root.find('export/build_type').text == 'ament_python'
    assert (ROOT / 'resource' / 'geodesic_planner').is_file()
    assert (ROOT / 'geodesic_planner' / '__init__.py').is_file()
    cfg = (ROOT / 'setup.cfg').read_text()
    assert 'script_dir=$base/lib/geodesic_planner' in cfg       # so `ros2 run` finds the nodes
    assert 'install_scripts=$base/lib/geodesic_planner' in cfg


def test_package_xml_declares_every_ros_package_the_code_imports() -> None:
    root = ET.parse(ROOT / 'package.xml').getroot()
    declared = {e.text for tag in ('depend', 'exec_depend') for e in root.iter(tag)}
    imported: dict[str, str] = {}
    for path in sorted((ROOT / 'geodesic_planner').rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and node.module
                     and node.level == 0 else [])
            for name in names:
                parts = name.split('.')
                if parts[0] == 'rclpy' or (len(parts) > 1 and parts[1] in ('msg', 'srv', 'action')):
                    imported.setdefault(parts[0], str(path.relative_to(ROOT)))
    assert 'rclpy' in imported, 'expected the ROS layer to import rclpy'
    missing = {pkg: where for pkg, where in imported.items() if pkg not in declared}
    assert not missing, f'ROS packages imported but not exec_depend in package.xml: {missing}'


def test_console_scripts_are_all_accounted_for() -> None:
    declared = console_scripts()
    assert declared == {**CHECKED_CONSOLE_SCRIPTS, **PENDING_CONSOLE_SCRIPTS}


@pytest.mark.parametrize('script', sorted(CHECKED_CONSOLE_SCRIPTS))
def test_console_script_module_and_function_exist(script: str) -> None:
    target = console_scripts()[script]
    module_name, func_name = target.split(':')
    module_file = ROOT / (module_name.replace('.', '/') + '.py')
    assert module_file.is_file(), f'{script} -> {target}: {module_file} missing'
    module = importlib.import_module(module_name)
    assert Path(module.__file__).resolve() == module_file.resolve()
    assert callable(getattr(module, func_name, None)), f'{target}: no function {func_name}'
    installed = bin_dir() / script
    assert installed.is_file(), f'{installed} not installed: run bash scripts/setup_env.sh'
    assert f'from {module_name} import {func_name}' in installed.read_text()


def test_pending_console_scripts_are_really_pending() -> None:
    """When a pending module lands, move it to CHECKED_CONSOLE_SCRIPTS (this test says so)."""
    landed = [s for s, t in PENDING_CONSOLE_SCRIPTS.items()
              if (ROOT / (t.split(':')[0].replace('.', '/') + '.py')).exists()]
    assert not landed, f'modules now exist, move to CHECKED_CONSOLE_SCRIPTS: {landed}'


# --------------------------------------------------------------------------- README, .ci/run, test.sh

def _readme_command(script: str) -> str:
    readme = (ROOT / 'README.md').read_text()
    blocks = re.findall(r'```(?:bash|sh|console)?\n(.*?)```', readme, flags=re.S)
    lines = [ln.strip() for b in blocks for ln in b.splitlines()]
    hits = [ln for ln in lines if ln.startswith(f'bash scripts/{script}')]
    assert hits, f'README has no code line running scripts/{script}'
    return hits[0]


def test_ci_run_calls_exactly_the_readme_test_command() -> None:
    command = _readme_command('test.sh')
    assert command == 'bash scripts/test.sh'
    lines = [ln for ln in (ROOT / '.ci' / 'run').read_text().splitlines() if ln.strip()]
    assert lines == ['#!/usr/bin/env bash', 'set -euo pipefail', 'cd "$(dirname "$0")/.."',
                     f'exec {command}']
    assert _readme_command('demo.sh') == 'bash scripts/demo.sh'


def test_test_sh_turns_no_tests_collected_into_failure() -> None:
    # one process (GP_TEST_WORKERS=1): xdist's controller reports no 'deselected' count
    result = _run(['bash', str(SCRIPTS / 'test.sh'), '-q', '-k', 'zzz_no_such_test_zzz',
                   'test/infra/test_infra.py'], timeout=300,
                  env={**os.environ, 'GP_TEST_WORKERS': '1'})
    if result.returncode == 2 and 'CAP_SYS_ADMIN' in result.stderr:
        pytest.skip('no permission to create network namespaces here')
    assert result.returncode == 1, result.stdout + result.stderr
    assert 'collected no tests' in result.stderr
    assert 'deselected' in result.stdout


def test_each_xdist_worker_has_a_ros_domain_of_its_own() -> None:
    from tools.netns import WORKER_DOMAIN_BASE, worker_domain
    domains = [worker_domain(f'gw{i}') for i in range(8)]
    assert domains == [WORKER_DOMAIN_BASE + i for i in range(8)]
    assert all(0 <= d <= 101 for d in domains)       # valid with the default port mapping on Linux
    assert worker_domain(None) is None and worker_domain('') is None and worker_domain('master') is None
    worker = os.environ.get('PYTEST_XDIST_WORKER')
    if worker:                                        # this run: the domain is set in this worker
        assert os.environ['ROS_DOMAIN_ID'] == str(worker_domain(worker))


def test_long_first_names_existing_modules() -> None:
    # a renamed or removed module would silently drop out of the parallel run's ordering
    spec = importlib.util.spec_from_file_location('suite_conftest', ROOT / 'test' / 'conftest.py')
    assert spec is not None and spec.loader is not None
    suite_conftest = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(suite_conftest)
    LONG_FIRST = suite_conftest.LONG_FIRST
    missing = [p for p in LONG_FIRST if not (ROOT / p).is_file()]
    assert not missing and len(set(LONG_FIRST)) == len(LONG_FIRST), missing


def test_test_sh_runs_workers_unless_told_otherwise() -> None:
    text = (SCRIPTS / 'test.sh').read_text()
    assert 'GP_TEST_WORKERS:-3' in text and '--dist loadscope' in text


def test_setup_env_stamp_skips_pip_and_failures_are_visible(tmp_path: Path) -> None:
    venv = tmp_path / 'venv'
    (venv / 'bin').mkdir(parents=True)
    calls = tmp_path / 'calls'
    fake = venv / 'bin' / 'python'
    fake.write_text(f'#!/bin/sh\necho "$@" >> {calls}\n'
                    'echo "WARNING: Location \'file:///x\' is ignored: it is neither a file nor a directory."\n'
                    'echo "ERROR: No matching distribution found for ros-jazzy-rclpy==7.1.6"\nexit 1\n')
    fake.chmod(0o755)
    interfaces = ROOT / 'geodesic_planner_interfaces'
    sources = sorted((p for p in interfaces.rglob('*')
                      if p.is_file() and p.suffix in {'.msg', '.srv', '.txt', '.xml', '.cmake', '.toml'}
                      and 'build' not in p.relative_to(interfaces).parts),
                     key=lambda p: str(p.relative_to(interfaces)).encode())
    want = hashlib.sha256(b''.join(p.read_bytes() for p in [
        ROOT / 'requirements' / 'lock.txt', ROOT / 'setup.py', ROOT / 'pyproject.toml',
        *(ROOT / 'geodesic_planner' / 'core' / name for name in ('_kernels.c', '_kernels_timing.c', '_kernels.h')),
        *sources])).hexdigest()
    env = {**os.environ, 'GP_VENV': str(venv)}

    (venv / '.geodesic_planner_stamp').write_text(want + '\n')
    ok = _run(['bash', str(SCRIPTS / 'setup_env.sh')], env=env)
    assert ok.returncode == 0 and ok.stdout == '' and ok.stderr == ''
    assert not calls.exists()                       # matching stamp: no pip at all

    (venv / '.geodesic_planner_stamp').write_text('stale\n')
    bad = _run(['bash', str(SCRIPTS / 'setup_env.sh')], env=env)
    assert bad.returncode != 0
    assert 'No matching distribution found for ros-jazzy-rclpy==7.1.6' in bad.stderr
    assert 'command failed' in bad.stderr and 'pip install' in bad.stderr
    assert 'is ignored' not in bad.stderr           # pip's noise filtered out
    assert calls.read_text().startswith('-m pip install')
    assert (venv / '.geodesic_planner_stamp').read_text() == 'stale\n'   # not marked done


def test_lock_pins_everything_exactly() -> None:
    pins = [ln.strip() for ln in (ROOT / 'requirements' / 'lock.txt').read_text().splitlines()
            if ln.strip() and not ln.startswith('#')]
    assert all(re.fullmatch(r'[A-Za-z0-9_.\-]+==[A-Za-z0-9_.+\-]+', p) for p in pins), pins
    names = {p.split('==')[0].lower().replace('_', '-') for p in pins}
    direct = [ln.split('#')[0].strip() for ln in
              (ROOT / 'requirements' / 'direct.txt').read_text().splitlines()]
    direct = [d for d in direct if d]
    assert all(re.fullmatch(r'[A-Za-z0-9_.\-]+==[A-Za-z0-9_.+\-]+', d) for d in direct), direct
    direct_names = {d.split('==')[0].lower() for d in direct}
    assert {'numpy', 'scipy', 'rosbags', 'ros-jazzy-rclpy', 'ros-jazzy-rmw-fastrtps-cpp'} <= direct_names
    def canon(pin: str) -> str:   # PEP 503 names: scikit-build-core == scikit_build_core
        name, version = pin.split('==')
        return re.sub(r'[-_.]+', '-', name).lower() + '==' + version
    canonical = {canon(p) for p in pins}
    for d in direct:
        assert canon(d) in canonical, f'{d} not pinned identically in lock.txt'
    # Jazzy, not Kilted: rclpy 7.x and rcl 9.x.
    assert 'ros-rclpy==7.1.6' in pins and 'ros-rcl==9.2.8' in pins
    assert 'geodesic-planner' not in names
    assert 'rclpy' not in names                     # egg-info inside ros-rclpy, not a PyPI dist


# --------------------------------------------------------------------------- conftest guard and markers

GUARD_TESTS = textwrap.dedent("""\
    import pytest

    @pytest.mark.ros
    def test_ros_thing():
        pass

    @pytest.mark.slow
    def test_slow_thing():
        pass

    def test_plain():
        pass
    """)


def _pytest_with_our_conftest(tmp_path: Path, env_extra: dict[str, str],
                              extra_interface: bool) -> subprocess.CompletedProcess:
    """Run pytest on GUARD_TESTS with test/conftest.py as plugin, in a nested namespace."""
    if shutil.which('unshare') is None or shutil.which('ip') is None:
        pytest.skip('needs unshare and ip')
    (tmp_path / 'test_guard.py').write_text(GUARD_TESTS)
    add = ('(ip link add gp_extra0 type bridge 2>/dev/null || '
           'ip link add gp_extra0 type veth peer name gp_extra1) && ') if extra_interface else ''
    env = {**os.environ, 'PYTHONPATH': f"{ROOT / 'test'}:{ROOT}", **env_extra}
    if 'GP_RUN_SLOW' not in env_extra:
        env.pop('GP_RUN_SLOW', None)
    result = _run(['unshare', '--net', 'sh', '-c', f'ip link set lo up && {add}exec "$@"', 'sh',
                   sys.executable, '-m', 'pytest', '-p', 'conftest', '-p', 'no:cacheprovider',
                   '-rs', str(tmp_path / 'test_guard.py')], cwd=tmp_path, env=env)
    if result.returncode not in (0, 4) and 'Operation not permitted' in result.stderr:
        pytest.skip(f'cannot create nested namespaces here: {result.stderr.strip()}')
    return result


def test_conftest_skips_ros_tests_outside_loopback_namespace(tmp_path: Path) -> None:
    """Outside a private namespace (colcon test, a plain pytest) ros tests are skipped, with the
    reason; the run goes on and the other tests pass."""
    result = _pytest_with_our_conftest(tmp_path, {'GEODESIC_PLANNER_NETNS': 'on'}, True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert '1 passed, 2 skipped' in result.stdout, result.stdout
    skipped = [line for line in result.stdout.splitlines() if line.startswith('SKIPPED')]
    ros_line = next(line for line in skipped if 'test_guard.py:' in line and 'ros:' in line)
    assert 'not inside a loopback-only network namespace' in ros_line
    assert 'gp_extra0' in ros_line and 'GEODESIC_PLANNER_NETNS=off' in ros_line


def test_conftest_runs_ros_tests_in_loopback_namespace_and_skips_slow(tmp_path: Path) -> None:
    result = _pytest_with_our_conftest(tmp_path, {'GEODESIC_PLANNER_NETNS': 'on'}, False)
    assert result.returncode == 0, result.stdout + result.stderr
    assert '2 passed, 1 skipped' in result.stdout
    assert 'slow: run with --run-slow or GP_RUN_SLOW=1' in result.stdout


def test_conftest_opt_out_and_gp_run_slow(tmp_path: Path) -> None:
    result = _pytest_with_our_conftest(
        tmp_path, {'GEODESIC_PLANNER_NETNS': 'off', 'GP_RUN_SLOW': '1'}, True)
    assert result.returncode == 0, result.stdout + result.stderr
    assert '3 passed' in result.stdout


def test_running_venv_matches_the_lock() -> None:
    """The suite runs on exactly the pinned versions (scripts/setup_env.sh installed lock.txt)."""
    from importlib import metadata

    wrong = {}
    for line in (ROOT / 'requirements' / 'lock.txt').read_text().splitlines():
        if line.strip() and not line.startswith('#'):
            name, version = line.strip().split('==')
            try:
                have = metadata.version(name)
            except metadata.PackageNotFoundError:
                have = None
            if have != version:
                wrong[name] = (version, have)
    assert not wrong, f'pinned vs installed: {wrong}; run bash scripts/setup_env.sh'
