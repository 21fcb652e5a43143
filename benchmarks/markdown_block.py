"""Write a benchmark's table into a Markdown file between its own markers, keeping the prose around it.

A block is ``<!-- begin NAME -->`` ... ``<!-- end NAME -->``; a file without the markers gets the
block appended.
"""
from __future__ import annotations

import os


def replace_block(path: str, name: str, text: str) -> None:
    """Put ``text`` between the markers of block ``name`` in the Markdown file ``path``."""
    begin, end = f'<!-- begin {name} -->', f'<!-- end {name} -->'
    old = ''
    if os.path.exists(path):
        with open(path, encoding='utf-8') as fh:
            old = fh.read()
    block = f'{begin}\n{text.strip()}\n{end}'
    if begin in old and end in old:
        new = old[:old.index(begin)] + block + old[old.index(end) + len(end):]
    else:
        new = old.rstrip('\n') + ('\n\n' if old else '') + block + '\n'
    with open(path, 'w', encoding='utf-8') as fh:
        fh.write(new)
