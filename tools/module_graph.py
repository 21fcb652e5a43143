"""The library's import graph: which module imports which, read from the source with ``ast``.

Used by ``test/infra/test_layers.py`` (imports point down the layers) and, as a script, to draw
``docs/img/module_graph.png``::

    .venv/bin/python -m tools.module_graph docs/img/module_graph.png
"""
from __future__ import annotations

import argparse
import ast
import sys
from dataclasses import dataclass
from pathlib import Path

PACKAGE = 'geodesic_planner'
ROOT = Path(__file__).resolve().parents[1]

#: Layers from the bottom up; a module may import modules of its own layer or of layers below.
LAYERS = ('core', 'timing', 'io', 'ros', 'cli')
#: Rows whose labels are closer than this (plot units) alternate between two lines, STAGGER
#: above and below the row.
CROWDED = 0.6
STAGGER = 0.14
#: Layers that may not be imported by each other although both sit above ``io``.
SIDE_BY_SIDE = {('ros', 'cli'), ('cli', 'ros')}


@dataclass(frozen=True)
class Import:
    """One import statement of a library module.

    Attributes:
        source: importing module, dotted (``geodesic_planner.core.planner``).
        target: imported module, dotted; for ``from X import name`` this is ``X`` or ``X.name``
            when ``X.name`` is itself a module of the package.
        top_level: False when the import sits inside a function or class body (a deferred import);
            True at module level, ``if TYPE_CHECKING:`` blocks included.
        line: line number in the source file.
    """

    source: str
    target: str
    top_level: bool
    line: int


def module_name(path: Path, root: Path = ROOT) -> str:
    """Dotted module name of a file below ``root`` (``__init__`` names its package)."""
    parts = list(path.relative_to(root).with_suffix('').parts)
    if parts[-1] == '__init__':
        parts.pop()
    return '.'.join(parts)


def library_modules(root: Path = ROOT) -> dict[str, Path]:
    """Every module of the installed package, by dotted name."""
    return {module_name(p, root): p for p in sorted((root / PACKAGE).rglob('*.py'))}


def _resolve(source: str, is_package: bool, level: int, name: str | None) -> str:
    base = source.split('.') if is_package else source.split('.')[:-1]
    if level > 1:
        base = base[:len(base) - (level - 1)]
    return '.'.join(base + ([name] if name else []))


def imports_of(path: Path, root: Path = ROOT, modules: set[str] | None = None) -> list[Import]:
    """The import statements of one file, targets resolved to absolute dotted names."""
    modules = set(library_modules(root)) if modules is None else modules
    source = module_name(path, root)
    tree = ast.parse(path.read_text(), filename=str(path))
    top = {id(node) for node in tree.body}
    # ``if TYPE_CHECKING:`` imports at module level count as module-level imports: a type-only
    # import that goes up a layer couples the layers as much as a real one
    for node in tree.body:
        if isinstance(node, ast.If) and 'TYPE_CHECKING' in ast.unparse(node.test):
            top |= {id(child) for child in node.body}
    found: list[Import] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [Import(source, alias.name, id(node) in top, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = (_resolve(source, path.name == '__init__.py', node.level, node.module)
                    if node.level else (node.module or ''))
            for alias in node.names:
                candidate = f'{base}.{alias.name}'
                target = candidate if candidate in modules else base
                found.append(Import(source, target, id(node) in top, node.lineno))
    return found


def layer_of(module: str) -> str | None:
    """The layer of a library module (``None`` for the package's ``__init__``)."""
    parts = module.split('.')
    return parts[1] if len(parts) > 1 and parts[0] == PACKAGE and parts[1] in LAYERS else None


def internal_edges(root: Path = ROOT) -> list[Import]:
    """Imports from one library module to another."""
    modules = library_modules(root)
    names = set(modules)
    return [imp for path in modules.values() for imp in imports_of(path, root, names)
            if imp.target.startswith(PACKAGE + '.') and imp.target != imp.source]


def draw(output: Path, root: Path = ROOT) -> None:
    """Draw the module graph, one row per layer (core at the bottom), arrows from importer to imported."""
    import matplotlib
    matplotlib.use('Agg')
    from matplotlib.figure import Figure

    modules = [m for m in library_modules(root) if layer_of(m) and not m.endswith(('__init__',))
               and m.count('.') >= 2]
    rows: dict[str, list[str]] = {layer: sorted(m for m in modules if layer_of(m) == layer) for layer in LAYERS}
    y_of = {'core': 0.0, 'timing': 1.0, 'io': 2.0, 'ros': 3.0, 'cli': 3.0}
    pos: dict[str, tuple[float, float]] = {}
    for layer, members in rows.items():
        x0, width = (0.0, 14.0) if layer not in ('ros', 'cli') else ((0.0, 8.0) if layer == 'ros' else (8.6, 5.4))
        # a crowded row alternates between two lines, so that neighbouring labels do not overlap
        stagger = STAGGER if width / max(len(members), 1) < CROWDED else 0.0
        for i, m in enumerate(members):
            pos[m] = (x0 + width * (i + 0.5) / max(len(members), 1),
                      y_of[layer] + (stagger if i % 2 else -stagger))
    fig = Figure(figsize=(15, 7.5), dpi=150)
    ax = fig.add_subplot()
    colours = {'core': '#d9e8fb', 'timing': '#dcf2dc', 'io': '#fff0c8', 'ros': '#f6d7d7', 'cli': '#e8dcf5'}
    for imp in internal_edges(root):
        src, dst = imp.source, imp.target
        while dst not in pos and dst.count('.') > 2:
            dst = dst.rsplit('.', 1)[0]
        while src not in pos and src.count('.') > 2:
            src = src.rsplit('.', 1)[0]
        if src in pos and dst in pos and src != dst:
            (x1, y1), (x2, y2) = pos[src], pos[dst]
            style = {'arrowstyle': '->', 'lw': 0.6, 'alpha': 0.4,
                     'color': 'tab:red' if not imp.top_level else 'grey',
                     'linestyle': '--' if not imp.top_level else '-'}
            if layer_of(src) == layer_of(dst):   # within a layer: an arc below the row
                style['connectionstyle'] = f'arc3,rad={0.25 if x2 > x1 else -0.25}'
                ax.annotate('', xy=(x2, y2 - 0.1), xytext=(x1, y1 - 0.1), arrowprops=style)
            else:
                ax.annotate('', xy=(x2, y2 + 0.12), xytext=(x1, y1 - 0.12), arrowprops=style)
    for m, (x, y) in pos.items():
        layer = layer_of(m) or 'core'
        label = m.split('.', 2)[2]
        ax.text(x, y, label, ha='center', va='center', fontsize=8,
                bbox={'boxstyle': 'round,pad=0.3', 'fc': colours[layer], 'ec': 'grey'})
    for layer, y in y_of.items():
        x = -0.9 if layer != 'cli' else 14.4
        ax.text(x, y, f'{layer}/', ha='right' if layer != 'cli' else 'left', va='center',
                fontsize=11, fontweight='bold')
    ax.set_xlim(-2.2, 15.6)
    ax.set_ylim(-1.1, 3.6)
    ax.axis('off')
    ax.set_title('geodesic_planner: modules by layer; arrows point from importer to imported '
                 '(dashed red: a deferred, function-local import)', fontsize=10)
    fig.tight_layout()
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output)


def main(argv: list[str] | None = None) -> int:
    """Write the module graph picture."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('output', type=Path, nargs='?', default=ROOT / 'docs' / 'img' / 'module_graph.png')
    args = parser.parse_args(argv)
    draw(args.output)
    print(f'wrote {args.output}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
