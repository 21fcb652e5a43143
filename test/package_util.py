"""Facts about the package read from its sources (for the packaging and launch tests)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def console_scripts() -> dict[str, str]:
    """console_scripts of setup.py (name -> target), read from its source (not installed metadata)."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values):
                if isinstance(key, ast.Constant) and key.value == 'console_scripts':
                    entries = ast.literal_eval(value)
                    return dict(tuple(part.strip() for part in e.split('=', 1)) for e in entries)
    raise AssertionError('no console_scripts in setup.py')
