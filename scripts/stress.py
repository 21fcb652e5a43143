"""Run chosen tests N times beside K CPU-bound processes; print the failures per test.

Usage (through scripts/stress.sh, which sets up the venv first):
    bash scripts/stress.sh [-n N] [-k K] [--keep DIR] [--] [PYTEST ARGS / TEST PATHS...]

Each run is ``bash scripts/test.sh ARGS -p no:randomly --junitxml=DIR/run-I.xml`` (the project's
venv and private network namespace), one run at a time; the K busy loops run during all of them
and are killed at the end (each also exits on its own when this script is gone or after
MAX_HOG_S). The runner's options go before ``--``, anything else to pytest (its own ``-k EXPR``
after ``--``). Exit code: 0 when no test failed in any run, else 1.
"""
from __future__ import annotations

import argparse
import shlex
import signal
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: a busy loop never outlives the runner, nor this many seconds
MAX_HOG_S = 6 * 3600
HOG = ('import os, sys, time\n'
       'parent, end = os.getppid(), time.monotonic() + float(sys.argv[1])\n'
       'while os.getppid() == parent and time.monotonic() < end:\n'
       '    for _ in range(100_000): pass\n')


def parse_args(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    parser = argparse.ArgumentParser(prog='scripts/stress.sh', description=__doc__.split('\n')[0],
                                     allow_abbrev=False)
    parser.add_argument('-n', type=int, default=5, metavar='N', help='runs (default 5)')
    parser.add_argument('-k', type=int, default=2, metavar='K',
                        help='CPU-bound processes alongside (default 2)')
    parser.add_argument('--keep', type=Path, metavar='DIR', help='keep the junit reports and logs in DIR')
    split = argv.index('--') if '--' in argv else len(argv)
    args, rest = parser.parse_known_args(argv[:split])
    return args, rest + argv[split + 1:]


def test_id(case: ET.Element) -> str:
    """``path::name`` (``path::Class::name`` for a method) from a junit xunit1 testcase."""
    file, classname, name = case.get('file'), case.get('classname', ''), case.get('name', '')
    if not file:
        return f'{classname}::{name}'
    parts = classname.split('.')
    cls = f'::{parts[-1]}' if parts and parts[-1][:1].isupper() else ''
    return f'{file}{cls}::{name}'


def outcomes(report: Path) -> dict[str, bool]:
    """test id -> failed (failure or error), for every test that ran (skipped ones left out)."""
    result: dict[str, bool] = {}
    for case in ET.parse(report).getroot().iter('testcase'):
        tags = {child.tag for child in case}
        if 'skipped' in tags and not tags & {'failure', 'error'}:
            continue
        key = test_id(case)
        result[key] = result.get(key, False) or bool(tags & {'failure', 'error'})
    return result


def main(argv: list[str]) -> int:
    args, pytest_args = parse_args(argv)
    # started in the background (`cmd &`), SIGINT is ignored and so it would be in every test
    # process: give the runs the disposition of a foreground run
    signal.signal(signal.SIGINT, signal.default_int_handler)
    out = args.keep or Path(tempfile.mkdtemp(prefix='gp_stress_'))
    out.mkdir(parents=True, exist_ok=True)
    hogs = [subprocess.Popen([sys.executable, '-c', HOG, str(MAX_HOG_S)]) for _ in range(args.k)]
    runs: dict[str, int] = defaultdict(int)
    failures: dict[str, int] = defaultdict(int)
    bad_runs: list[str] = []
    try:
        for i in range(1, args.n + 1):
            report, log = out / f'run-{i}.xml', out / f'run-{i}.log'
            t0 = time.monotonic()
            command = ['bash', str(ROOT / 'scripts' / 'test.sh'), *pytest_args, '-p', 'no:randomly',
                       '-o', 'junit_family=xunit1', f'--junitxml={report}']
            with open(log, 'wb') as f:
                rc = subprocess.run(command, cwd=ROOT, stdout=f, stderr=subprocess.STDOUT,
                                    check=False).returncode
            seen = outcomes(report) if report.exists() else {}
            for key, failed in seen.items():
                runs[key] += 1
                failures[key] += failed
            n_failed = sum(seen.values())
            print(f'run {i}/{args.n}: exit {rc}, {len(seen)} tests, {n_failed} failed, '
                  f'{time.monotonic() - t0:.0f} s (log {log})', flush=True)
            if rc != 0 and n_failed == 0:   # e.g. crashed, timed out, or nothing collected
                bad_runs.append(f'run {i}: exit {rc} without a failed test in its report (see {log})')
    finally:
        for hog in hogs:
            hog.kill()
        for hog in hogs:
            hog.wait()

    def shown(key: str, limit: int = 160) -> str:   # a parametrized id can be huge
        return key if len(key) <= limit else key[:limit - 3] + '...'

    width = max([len('test'), *(len(shown(k)) for k in runs)])
    command = shlex.join(['bash', 'scripts/test.sh', *pytest_args])
    print(f'\n{args.n} runs of `{command}` beside {args.k} CPU-bound process(es)\n')
    print(f'| {"test":<{width}} | runs | failures |')
    print(f'|{"-" * (width + 2)}|-----:|---------:|')
    for key in sorted(runs, key=lambda k: (-failures[k], k)):
        print(f'| {shown(key):<{width}} | {runs[key]:4d} | {failures[key]:8d} |')
    per_file: dict[str, list[int]] = defaultdict(lambda: [0, 0, 0])   # tests, test runs, failures
    for key in runs:
        row = per_file[key.split('::')[0]]
        row[0] += 1
        row[1] += runs[key]
        row[2] += failures[key]
    print('\n| file | tests | test runs | failures |\n|------|------:|----------:|---------:|')
    for file, (tests, test_runs, failed) in sorted(per_file.items()):
        print(f'| {file} | {tests} | {test_runs} | {failed} |')
    total = sum(failures.values())
    print(f'\n{len(runs)} tests, {sum(runs.values())} test runs, {total} failures'
          f'{"" if args.keep else f" (reports in {out})"}')
    for line in bad_runs:
        print(line)
    return 1 if total or bad_runs else 0


if __name__ == '__main__':
    raise SystemExit(main(sys.argv[1:]))
