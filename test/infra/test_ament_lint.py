"""The ROS linters a ROS 2 package runs, ament_flake8 and ament_pep257, on the whole package.

As ROS 2 packages' standard ``test/test_flake8.py`` and ``test/test_pep257.py`` do (e.g. the
demos), with this repository's committed configuration: setup.cfg's ``[flake8]`` (passed as
``--config``) and ``[pydocstyle]`` (passed as ``--convention`` and ``--add-ignore``); each ignore
there says why. Style is ruff's (test_lint.py); these keep the package clean for ROS tooling too.
"""
from __future__ import annotations

import configparser
import contextlib
import io
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SETUP_CFG = ROOT / 'setup.cfg'
#: Directories of build output that the linters skip (relative to the package root).
BUILD_OUTPUT = ('.venv', 'build', 'install', 'log', 'geodesic_planner_interfaces/build')


def _values(text: str) -> list[str]:
    """A multi-line, comma-separated option value as a list (comment lines already dropped)."""
    return [v.strip() for v in text.replace('\n', ',').split(',') if v.strip()]


@pytest.fixture
def in_root(monkeypatch: pytest.MonkeyPatch) -> None:
    """ament's linters check paths relative to the working directory: the package root."""
    monkeypatch.chdir(ROOT)


@pytest.mark.linter
def test_flake8(in_root: None) -> None:
    main_with_errors = pytest.importorskip('ament_flake8.main').main_with_errors
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        rc, errors = main_with_errors(argv=['--config', str(SETUP_CFG), '.'])
    assert rc == 0, f'ament_flake8: {len(errors)} finding(s):\n' + '\n'.join(errors)
    assert 'files checked' in out.getvalue()


@pytest.mark.linter
def test_pep257(in_root: None) -> None:
    main = pytest.importorskip('ament_pep257.main').main
    cfg = configparser.ConfigParser()
    cfg.read(SETUP_CFG)
    section = cfg['pydocstyle']
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        # build output (e.g. a scikit-build tree inside the interface package) is not ours,
        # as in setup.cfg's flake8 extend-exclude
        rc = main(argv=['--convention', section['convention'],
                        '--add-ignore', ','.join(_values(section['add-ignore'])),
                        '--exclude', *BUILD_OUTPUT, '--', '.'])
    assert rc == 0, f'ament_pep257 findings:\n{out.getvalue()}'
    assert 'checking ./geodesic_planner/core/planner.py' in out.getvalue()   # the package was checked


def test_lint_configuration_is_committed() -> None:
    """Both sections exist, flake8 with ruff's line length, and a comment says why before each ignore line."""
    import tomllib

    cfg = configparser.ConfigParser()
    cfg.read(SETUP_CFG)
    ruff_length = tomllib.loads((ROOT / 'pyproject.toml').read_text())['tool']['ruff']['line-length']
    assert int(cfg['flake8']['max-line-length']) == ruff_length
    assert cfg['pydocstyle']['convention'] == 'google'
    lines = SETUP_CFG.read_text().splitlines()
    for section, option in (('[flake8]', 'extend-ignore'), ('[pydocstyle]', 'add-ignore')):
        start = lines.index(next(line for line in lines[lines.index(section):] if line.startswith(option)))
        block = []
        for line in lines[start + 1:]:
            if not line.startswith(' '):
                break
            block.append(line.strip())
        codes = [i for i, line in enumerate(block) if not line.startswith('#')]
        assert codes, (section, option)
        for i in codes:
            assert i > 0 and block[i - 1].startswith('#'), f'{section} {option}: {block[i]!r} has no comment saying why'
