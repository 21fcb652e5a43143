"""scipy's OpenBLAS on one thread for the calling thread, while small optimisers run.

scipy's L-BFGS-B and SLSQP call BLAS on vectors of a few dozen entries; OpenBLAS then starts its
thread pool for each call, and on a loaded machine the pool's spinning costs 20-50 times the work
(SLSQP on 48 variables: 424 ms of CPU against 7 ms on one thread, measured here). OpenBLAS 0.3.27+
has ``openblas_set_num_threads_local``, which sets the count for the calling thread only, so the
rest of the process keeps its setting. Without that symbol (another BLAS) this is a no-op.
"""
from __future__ import annotations

import ctypes
from collections.abc import Iterator
from contextlib import contextmanager
from functools import cache
from pathlib import Path

__all__ = ['one_thread']


@cache
def _setter() -> ctypes._CFuncPtr | None:  # type: ignore[name-defined]
    try:
        import scipy
    except ImportError:      # pragma: no cover - scipy is a dependency
        return None
    libs = Path(scipy.__file__).resolve().parent.parent / 'scipy.libs'
    for path in sorted(libs.glob('libscipy_openblas*.so*')):
        try:
            fn = ctypes.CDLL(str(path)).openblas_set_num_threads_local
        except (OSError, AttributeError):
            continue
        fn.argtypes, fn.restype = [ctypes.c_int], ctypes.c_int
        return fn
    return None


@contextmanager
def one_thread() -> Iterator[None]:
    """Run the block with scipy's OpenBLAS on one thread (this thread only; restored after)."""
    fn = _setter()
    if fn is None:
        yield
        return
    previous = fn(1)
    try:
        yield
    finally:
        fn(previous)
