"""The house rules of docs/architecture.md, checked on the source: imports point down the layers,
only ros/ touches ROS, no private rclpy, modules stay small, the core imports without ROS."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from tools.module_graph import LAYERS, ROOT, SIDE_BY_SIDE, imports_of, internal_edges, layer_of, library_modules

pytestmark = pytest.mark.linter

#: Deferred (function-local) imports that go up a layer on purpose, with the reason.
ALLOWED_UPWARD = {
    # JointPath.timed is public API: a convenience that hands the path to the timing layer.
    ('geodesic_planner.core.path', 'geodesic_planner.timing'),
}
ROS_PACKAGES = re.compile(r'^(rclpy|rosidl_\w+|rcl_interfaces|builtin_interfaces|\w+_msgs|\w+_srvs|'
                          r'geodesic_planner_interfaces)(\.|$)')
MAX_LINES = 600


def test_imports_point_down_the_layers() -> None:
    wrong = []
    for imp in internal_edges():
        src, dst = layer_of(imp.source), layer_of(imp.target)
        if src is None or dst is None:
            continue
        upward = LAYERS.index(dst) > LAYERS.index(src) or (src, dst) in SIDE_BY_SIDE
        allowed = not imp.top_level and any(imp.source == s and imp.target.startswith(t)
                                            for s, t in ALLOWED_UPWARD)
        if upward and not allowed:
            wrong.append(f'{imp.source}:{imp.line} imports {imp.target} ({src} -> {dst})')
    assert not wrong, 'imports that point up (or sideways) the layers:\n' + '\n'.join(wrong)


def test_only_ros_layer_imports_ros() -> None:
    wrong = []
    names = set(library_modules())
    for module, path in library_modules().items():
        if layer_of(module) == 'ros':
            continue
        wrong += [f'{module}:{imp.line} imports {imp.target}'
                  for imp in imports_of(path, modules=names) if ROS_PACKAGES.match(imp.target)]
    assert not wrong, '\n'.join(wrong)


def test_no_private_rclpy_api_and_no_frame_tricks() -> None:
    pattern = re.compile(r'rclpy\.impl|_rclpy_pybind11|_getframe|implementation_singleton')
    wrong = [f'{path.relative_to(ROOT)}:{i}: {line.strip()}'
             for path in library_modules().values()
             for i, line in enumerate(path.read_text().splitlines(), 1) if pattern.search(line)]
    assert not wrong, '\n'.join(wrong)


def test_library_never_imports_tooling() -> None:
    names = set(library_modules())
    wrong = [f'{module}:{imp.line} imports {imp.target}'
             for module, path in library_modules().items()
             for imp in imports_of(path, modules=names) if imp.target.split('.')[0] in ('tools', 'test')]
    assert not wrong, '\n'.join(wrong)


def test_modules_stay_small() -> None:
    sizes = {module: len(path.read_text().splitlines()) for module, path in library_modules().items()}
    big = {m: n for m, n in sizes.items() if n > MAX_LINES}
    assert not big, f'modules over {MAX_LINES} lines (one concept per module): {big}'


def test_library_below_ros_imports_without_ros() -> None:
    """Importing every non-ROS module works with rclpy and the message packages unavailable."""
    modules = sorted(m for m in library_modules() if layer_of(m) not in ('ros',))
    code = ('import sys\n'
            'class Block:\n'
            '    def find_spec(self, name, path=None, target=None):\n'
            f'        import re; return None if not re.match({ROS_PACKAGES.pattern!r}, name) else '
            '(_ for _ in ()).throw(ImportError("blocked: " + name))\n'
            'sys.meta_path.insert(0, Block())\n'
            'import importlib\n'
            f'for m in {modules!r}: importlib.import_module(m)\n'
            'print("ok", len([m for m in sys.modules if m.startswith("rclpy")]))\n')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=120,
                            cwd=Path(ROOT))
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ['ok', '0']


def test_type_only_imports_count_as_module_level(tmp_path: Path) -> None:
    """An ``if TYPE_CHECKING:`` import is a module-level import for the layer rule (a type-only
    import up a layer is flagged); a function-local one stays deferred."""
    pkg = tmp_path / 'geodesic_planner' / 'core'
    pkg.mkdir(parents=True)
    (tmp_path / 'geodesic_planner' / '__init__.py').write_text('')
    (pkg / '__init__.py').write_text('')
    src = pkg / 'thing.py'
    src.write_text('from typing import TYPE_CHECKING\n'
                   'if TYPE_CHECKING:\n    from ..timing.law import TimeLaw\n'
                   'def f():\n    from ..timing import parameterize\n')
    found = {(imp.target, imp.top_level) for imp in imports_of(src, root=tmp_path, modules=set())}
    assert ('geodesic_planner.timing.law', True) in found
    assert ('geodesic_planner.timing', False) in found


def test_no_import_cycles() -> None:
    """Module-level imports (type-only ones included) form no cycle, within a layer too (the time
    laws' shared types live in the leaf timing.types)."""
    graph: dict[str, set[str]] = {}
    for imp in internal_edges():
        if imp.top_level:
            graph.setdefault(imp.source, set()).add(imp.target)
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(node: str, stack: list[str]) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, stack)
        stack.pop()
        state[node] = 2
    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    assert not cycles, '\n'.join(' -> '.join(c) for c in cycles)
