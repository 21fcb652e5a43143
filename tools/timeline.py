"""pytest plugin: one JSON line per test (worker, node id, start and end, s since the epoch).

``bash scripts/test.sh -p tools.timeline`` with ``GP_TEST_TIMELINE=FILE`` appends to FILE (every
xdist worker writes its own lines); ``python -m tools.timeline FILE`` prints each worker's busy
time, its last test's end and the modules that ended last. Used to balance the parallel suite
(docs/testing.md); nothing is written without GP_TEST_TIMELINE.
"""
from __future__ import annotations

import json
import os
import sys
import time
from collections import defaultdict
from collections.abc import Generator

import pytest


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> Generator[None, None, None]:
    start = time.time()
    yield
    path = os.environ.get('GP_TEST_TIMELINE')
    if path:
        line = {'worker': os.environ.get('PYTEST_XDIST_WORKER', 'main'), 'id': item.nodeid,
                'start': start, 'end': time.time()}
        with open(path, 'a', encoding='utf-8') as fh:
            fh.write(json.dumps(line) + '\n')


def main(argv: list[str]) -> int:
    with open(argv[0], encoding='utf-8') as fh:
        rows = [json.loads(ln) for ln in fh if ln.strip()]
    t0 = min(r['start'] for r in rows)
    busy: dict[str, float] = defaultdict(float)
    last: dict[str, float] = defaultdict(float)
    module_end: dict[str, float] = defaultdict(float)
    module_time: dict[str, float] = defaultdict(float)
    for r in rows:
        busy[r['worker']] += r['end'] - r['start']
        last[r['worker']] = max(last[r['worker']], r['end'] - t0)
        mod = r['id'].split('::')[0]
        module_end[mod] = max(module_end[mod], r['end'] - t0)
        module_time[mod] += r['end'] - r['start']
    for w in sorted(busy):
        print(f'{w}: busy {busy[w]:.1f} s, last test ended at {last[w]:.1f} s')
    print('modules that ended last (end s, own s):')
    for mod, end in sorted(module_end.items(), key=lambda kv: -kv[1])[:12]:
        print(f'  {end:7.1f} {module_time[mod]:6.1f}  {mod}')
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
