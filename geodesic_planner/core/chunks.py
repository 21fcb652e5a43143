"""Large batches in cache-sized blocks of rows.

The batched kinematics and geodesic equations build several (N, dof, 4, 4) temporaries. Above a
few hundred rows these leave the CPU's caches and every product waits on memory: on the ur5e,
``Chain.frames`` of 20001 configurations took 55 ms at once and 16 ms in blocks of 256 rows. Every
row is computed independently, so the blocks give the same numbers as one call.
"""
from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

#: Rows per block (ur5e frames of 20001 rows: 64 rows 22 ms, 128 18 ms, 256 16 ms, 512 16 ms,
#: 1024 17 ms, all at once 55 ms).
CHUNK = 256


def in_chunks(fn: Callable[..., Any], *arrays: np.ndarray, chunk: int = CHUNK) -> Any:  # noqa: ANN401
    """``fn(*arrays)`` evaluated on blocks of at most ``chunk`` rows and joined along axis 0.

    Args:
        fn: a function of arrays with the same leading length N whose result is an array, or a
            tuple of arrays (or None), each with leading length N, row i depending only on the
            arguments' rows i.
        arrays: its arguments.
        chunk: rows per block.
    Returns:
        What ``fn(*arrays)`` returns; one call when N <= chunk.
    """
    n = arrays[0].shape[0]
    if n <= chunk:
        return fn(*arrays)
    parts = [fn(*(a[k:k + chunk] for a in arrays)) for k in range(0, n, chunk)]
    if not isinstance(parts[0], tuple):
        return np.concatenate(parts)
    return tuple(None if first is None else np.concatenate([p[i] for p in parts])
                 for i, first in enumerate(parts[0]))
