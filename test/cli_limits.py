"""Console scripts run under a memory limit: a size the tool fails to bound fails the test (a
MemoryError) instead of eating the machine."""
from __future__ import annotations

import os
import resource
import subprocess
import time

#: Address space of a bounded run, bytes: the tools at their caps stay well under it (about 1 GB
#: for geodesic-compare with every size at its cap, figures included).
ADDRESS_SPACE = 2 << 30
#: A refusal of an over-large size returns within this, s: a bound on runaway work, not a speed
#: figure (start-up takes about 0.5 s on an idle machine; a whole-suite run on 2 busy cores took
#: over 30 s once). The memory limit is what catches a size left unbounded.
QUICK = 120.0


def _limit() -> None:  # pragma: no cover - runs in the child
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def run_bounded(argv: list[object], cwd: str | os.PathLike[str], timeout: float = 300.0
                ) -> tuple[subprocess.CompletedProcess[str], float]:
    """Run ``argv`` with at most :data:`ADDRESS_SPACE` of memory; the result and the seconds taken."""
    env = {**os.environ, 'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1'}
    t0 = time.monotonic()
    proc = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, check=False, preexec_fn=_limit)
    return proc, time.monotonic() - t0


def error_line(proc: subprocess.CompletedProcess[str]) -> str:
    """The one ``ERROR:`` line of a failed run (asserted: nothing else on stderr, no traceback)."""
    assert 'Traceback' not in proc.stderr, proc.stderr[-2000:]
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith('ERROR: '), proc.stderr[-2000:]
    return lines[0]
