"""package.xml names every dependency the code and the tests import (format 3).

The third-party modules imported anywhere in the package, the launch file, the tests and tools/
are read with ``ast``; each must map to a rosdep key that package.xml lists (or, for the few
without a key, to a comment there naming the pip package).
"""
from __future__ import annotations

import ast
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SOURCES = ('geodesic_planner', 'launch', 'test', 'tools')
#: Imported module -> rosdep key (a ROS package, or a key of rosdistro's rosdep/python.yaml).
KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib', 'rosbags': 'python3-rosbags-pip',
    'pytest': 'python3-pytest', 'hypothesis': 'python3-hypothesis',
    'ament_flake8': 'ament_flake8', 'ament_pep257': 'ament_pep257',
    'launch': 'launch', 'launch_ros': 'launch_ros', 'pinocchio': 'pinocchio', 'coal': 'coal',
    **{pkg: pkg for pkg in ('rclpy', 'builtin_interfaces', 'rcl_interfaces', 'diagnostic_msgs',
                            'geometry_msgs', 'nav_msgs', 'sensor_msgs', 'shape_msgs', 'std_msgs',
                            'trajectory_msgs', 'visualization_msgs', 'geodesic_planner_interfaces',
                            'ament_index_python')},
}
#: Imported modules without a rosdep key: package.xml must name them in a comment.
PIP_ONLY = {'mcap', 'lz4', 'zstandard', 'ray', 'pyarrow', 'ompl'}
#: Used without an import: the pytest plugin behind @pytest.mark.timeout, and the linters run as
#: programs by test/infra/test_lint.py and test_colcon.py.
USED_NOT_IMPORTED = {'python3-pytest-timeout', 'python3-mypy', 'python3-colcon-common-extensions'}


def _local_modules() -> set[str]:
    names = {'geodesic_planner', 'tools', 'test'}
    for folder in ('test', 'tools'):
        names |= {p.stem for p in (ROOT / folder).rglob('*.py')}
        names |= {p.name for p in (ROOT / folder).rglob('*') if p.is_dir()}
    return names


def imported_third_party(folders: tuple[str, ...] = SOURCES) -> dict[str, str]:
    """Top-level third-party modules imported in ``folders`` -> the first file importing it."""
    local = _local_modules()
    found: dict[str, str] = {}
    for folder in folders:
        for path in sorted((ROOT / folder).rglob('*.py')):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.Import):
                    names = [alias.name for alias in node.names]
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names = [node.module]
                else:
                    continue
                for name in names:
                    top = name.split('.')[0]
                    if top not in sys.stdlib_module_names and top not in local:
                        found.setdefault(top, str(path.relative_to(ROOT)))
    # pytest.importorskip('mcap.reader') is an import too
    for path in sorted(p for folder in folders for p in (ROOT / folder).rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and getattr(node.func, 'attr', '') == 'importorskip'
                    and node.args and isinstance(node.args[0], ast.Constant)):
                found.setdefault(node.args[0].value.split('.')[0], str(path.relative_to(ROOT)))
    return found


def test_package_xml_lists_every_dependency() -> None:
    text = (ROOT / 'package.xml').read_text()
    root = ET.fromstring(text)
    assert root.tag == 'package' and root.get('format') == '3'
    exec_deps = {e.text for e in root.iter('exec_depend')}
    test_deps = {e.text for e in root.iter('test_depend')}
    listed = exec_deps | test_deps | {e.text for e in root.iter('depend')}
    imported = imported_third_party()
    assert {'numpy', 'rclpy', 'pytest', 'ament_flake8', 'mcap'} <= set(imported)   # the scan sees them
    for module, where in sorted(imported.items()):
        if module in PIP_ONLY:
            assert re.search(rf'pip install [^>]*\b{module}\b', text), (
                f'{module} (imported in {where}): no "pip install {module}" comment in package.xml')
            continue
        assert module in KEYS, f'{module} (imported in {where}): no rosdep key in KEYS; add it here and to package.xml'
        assert KEYS[module] in listed, f'{module} (imported in {where}): {KEYS[module]} missing from package.xml'
    assert test_deps >= USED_NOT_IMPORTED
    # what the installed package imports at run time is an exec dependency, not only a test one
    runtime = imported_third_party(('geodesic_planner',))
    for module in sorted(set(runtime) - PIP_ONLY):
        assert KEYS[module] in exec_deps, f'{module} (imported by {runtime[module]}) must be an exec_depend'
    assert listed - set(KEYS.values()) - USED_NOT_IMPORTED == {'util-linux', 'iproute2'}
