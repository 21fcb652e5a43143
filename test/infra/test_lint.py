"""ruff and mypy over the repository, with the configuration in pyproject.toml (marker ``linter``)."""
from __future__ import annotations

import importlib.util
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
#: Upper bound on one linter run, s; mypy's first run without a cache takes about 10 s here.
LINT_TIMEOUT = 240.0


def _run(module: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``python -m module args`` from the venv at the repository root, bounded in time."""
    if importlib.util.find_spec(module) is None:
        pytest.skip(f'{module} is not installed in {sys.executable} (pinned in requirements/lock.txt)')
    try:
        return subprocess.run([sys.executable, '-m', module, *args], cwd=ROOT, capture_output=True,
                              text=True, timeout=LINT_TIMEOUT, check=False)
    except subprocess.TimeoutExpired as err:
        pytest.fail(f'{module} did not finish within {LINT_TIMEOUT:.0f} s: {err}')


@pytest.mark.linter
def test_ruff() -> None:
    proc = _run('ruff', 'check', '--no-cache', '--output-format', 'concise', '.')
    assert proc.returncode == 0, f'ruff findings:\n{proc.stdout}{proc.stderr}'


@pytest.mark.linter
def test_mypy() -> None:
    cache = os.path.join(ROOT, '.venv', '.mypy_cache') if os.path.isdir(os.path.join(ROOT, '.venv')) else None
    args = ['--cache-dir', cache] if cache else []
    proc = _run('mypy', *args)
    assert proc.returncode == 0, f'mypy findings:\n{proc.stdout}{proc.stderr}'
