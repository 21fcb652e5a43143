"""The package's compiled kernels (``_kernels.c``, ``_kernels_timing.c``), loaded with ctypes, and the switch to numpy.

setup.py builds them as one optional extension (``pip install -e .`` in the set-up compiles it).
They do, sample by sample, what numpy code of the library does on whole arrays: the serial
chains' forward kinematics (:mod:`.kinematics`) and the piecewise polynomials of the paths'
splines (:mod:`.polynomials`), wrapped here, and the time laws' hot loops, wrapped in
:mod:`geodesic_planner.timing.kernels`. Callers ask :func:`active` and otherwise run their numpy
code, which stays the reference: ``test/core/test_compiled.py`` and ``test/timing/test_kernels.py``
compare the two.

The kernels are off when the extension was not built (no C compiler at set-up), when the
environment sets ``GP_KERNELS=numpy``, or inside :func:`numpy_only`; :data:`REASON` says why.
"""
from __future__ import annotations

import contextlib
import ctypes
import os
import threading
from collections.abc import Iterator
from typing import Any

import numpy as np

__all__ = ['LIB', 'REASON', 'Pinned', 'active', 'capsule_distances', 'f64', 'frames', 'generators',
           'geodesic_acceleration', 'geodesic_jerk', 'jacobian_rate', 'numpy_only', 'polynomials', 'scratch']

_P = ctypes.c_void_p
_I = ctypes.c_int64
_D = ctypes.c_double

#: Argument types of the kernels (each returns nothing; arrays are passed by address).
SIGNATURES: dict[str, list[Any]] = {
    'gp_frames': [_I, _I, _P, _P, _P, _P, _P, _P],
    'gp_polynomials': [_I, _P, _I, _P, _P, _I, _I, _P],
    'gp_jacobian_rate': [_I, _I, _P, _P, _P, _P],
    'gp_geodesic_acceleration': [_I, _I, _P, _P, _P, _P, _D, _P, _P],
    'gp_geodesic_jerk': [_I, _I, _P, _P, _P, _P, _D, _P, _P, _P],
    'gp_capsule_distances': [_I, _I] + [_P] * 7,
    'gp_build_piecewise': [_P, _P, _I, _P, _D, _D, _P, _P, _P, _P, _P, _P, _P],
    'gp_refine': [_I, _I, _I] + [_P] * 11,
    'gp_hermite_coef': [_I, _I] + [_P] * 8,
    'gp_suspects': [_I, _I, _P, _P, _P, _P, _D, _P],
    'gp_piecewise_evaluate': [_I, _P, _I, _P, _P, _D, _I, _P, _P, _P, _P, _P, _P],
    'gp_box_evaluate': [_I, _P, _I] + [_P] * 13,
    'gp_hermite_ratios': [_I, _P, _P, _P, _P, _I, _P, _I, _P, _P, _P, _P, _P, _P, _P, _P],
    'gp_backward_pass': [_I, _I, _P, _P, _P, _P],
    'gp_forward_pass': [_I, _I, _P, _P, _P, _P, _P],
    'gp_topp_rows': [_I, _I] + [_P] * 15,
    'gp_box_search_grid': [_I, _I, _P, _I, _I, _I] + [_P] * 9 + [_I, _P, _I] + [_P] * 7,
    'gp_merge_columns': [_I, _I, _I, _P, _I, _I, _P, _P, _P],
    'gp_point_ratios': [_I, _I] + [_P] * 10,
    'gp_peak_samples': [_I, _P, _P, _D, _D, _I, _I, _P, _P],
    'gp_piecewise_check': [_I, _I, _P, _I, _P, _P, _I, _P, _P, _D, _I, _P, _P, _I, _P, _I] + [_P] * 5,
    'gp_box_search_max': [_I, _I, _P, _I, _I] + [_P] * 8 + [_I, _P, _I] + [_P] * 6 + [_D, _I] + [_P] * 9,
}


def _load() -> tuple[ctypes.PyDLL | None, str]:
    if os.environ.get('GP_KERNELS', '').strip().lower() == 'numpy':
        return None, 'off: GP_KERNELS=numpy'
    try:
        from . import _kernels  # type: ignore[attr-defined]
        # PyDLL: a call keeps the GIL (the kernels never touch Python objects and take micro- to
        # milliseconds); CDLL would release and retake it on every call, handing it to any other
        # thread that waits for it: in the planner node, hundreds of hand-offs per plan between
        # the plan and the executor's threads (docs/benchmarks.md, "the node's GIL").
        lib = ctypes.PyDLL(_kernels.__file__)
    except (ImportError, OSError) as err:
        return None, f'off: the compiled kernels are not built ({err}); the numpy code runs'
    for name, args in SIGNATURES.items():
        fn = getattr(lib, name)
        fn.argtypes = args
        fn.restype = None
    lib.gp_geodesic_acceleration.restype = _I
    lib.gp_geodesic_jerk.restype = _I
    lib.gp_box_search_grid.restype = _I
    lib.gp_box_search_max.restype = _I
    lib.gp_piecewise_check.restype = _I
    lib.gp_peak_samples.restype = _I
    return lib, 'on'


LIB, REASON = _load()
_ON = [LIB is not None]     # switched by numpy_only


def active() -> bool:
    """True when the compiled kernels are loaded and not switched off."""
    return _ON[0]


@contextlib.contextmanager
def numpy_only() -> Iterator[None]:
    """Within this block the library runs its numpy code (for tests and benchmarks; the switch is
    process-wide, not per thread)."""
    before = _ON[0]
    _ON[0] = False
    try:
        yield
    finally:
        _ON[0] = before


_SCRATCH = threading.local()


def scratch(name: str, size: int) -> np.ndarray:
    """A float64 work array of ``size`` entries, this thread's ``name`` buffer, reused from call to
    call (grown when too small; never shrunk, at most the largest size asked for).

    For the kernels' work space and the blocks a caller consumes before it returns: a view must
    not outlive the call that took it, since the next call with the same name overwrites it. The
    law checks allocate and free blocks of 0.2-0.8 MB dozens of times per law; each fresh block
    came from the operating system with page faults (1370 per blended law, about 3.5 of 23 ms).
    """
    buffers = getattr(_SCRATCH, 'buffers', None)
    if buffers is None:
        buffers = _SCRATCH.buffers = {}
    buf = buffers.get(name)
    if buf is None or buf.size < size:
        buf = buffers[name] = np.empty(max(size, 1024))
    return buf[:size]


def f64(a: np.ndarray) -> np.ndarray:
    """``a`` as a C-contiguous float64 array (no copy when it already is one)."""
    return np.ascontiguousarray(a, dtype=np.float64)


class Pinned:
    """Arrays in the layout the kernels read (C-contiguous float64; int64 for integers), kept
    alive, with their addresses: made once per table (taking an array's address costs 1-2 us in
    numpy, as much as a kernel call on a few hundred samples)."""

    __slots__ = ('arrays', 'ptrs')

    def __init__(self, *arrays: np.ndarray | None) -> None:
        self.arrays = tuple(None if a is None else np.ascontiguousarray(
            a, dtype=np.int64 if np.asarray(a).dtype.kind in 'iub' else np.float64) for a in arrays)
        self.ptrs = tuple(None if a is None else a.ctypes.data for a in self.arrays)


def _chain(chain: Pinned, q: np.ndarray, joint_frames: bool) -> tuple[np.ndarray, np.ndarray]:
    assert LIB is not None
    q = f64(q)
    N, dof = q.shape
    T = np.empty((N, 4, 4))
    out = np.empty((N, dof, 4, 4))
    LIB.gp_frames(N, dof, q.ctypes.data, chain.ptrs[0], chain.ptrs[1], out.ctypes.data if joint_frames else None,
                  T.ctypes.data, None if joint_frames else out.ctypes.data)
    return out, T


def frames(chain: Pinned, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`.kinematics.Chain.frames` compiled: ``chain`` pins the chain's constant transforms
    (dof + 1, 4, 4), axes folded onto z, and which joints are prismatic (dof,); at q (N, dof) the
    joint frames (N, dof, 4, 4) and the tool poses (N, 4, 4)."""
    return _chain(chain, q, True)


def generators(chain: Pinned, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`.kinematics.Chain.generators` compiled (``chain`` as :func:`frames`): the spatial
    twist matrices (N, dof, 4, 4) and the tool poses (N, 4, 4)."""
    return _chain(chain, q, False)


def jacobian_rate(X: np.ndarray, T: np.ndarray, u: np.ndarray) -> np.ndarray:
    """:meth:`.redundant.RedundantEquations.rate` compiled: X (..., dof, 4, 4), T (..., 4, 4) and u
    (..., dof) broadcast together; dJ[u] (..., 6, dof)."""
    assert LIB is not None
    dof = X.shape[-3]
    batch = np.broadcast_shapes(X.shape[:-3], T.shape[:-2], u.shape[:-1])
    Xb, Tb, ub = (f64(np.broadcast_to(a, batch + tail)) for a, tail in
                  ((X, (dof, 4, 4)), (T, (4, 4)), (u, (dof,))))
    out = np.empty(batch + (6, dof))
    LIB.gp_jacobian_rate(int(np.prod(batch, dtype=np.int64)), dof, Xb.ctypes.data, Tb.ctypes.data,
                         ub.ctypes.data, out.ctypes.data)
    return out


def geodesic_acceleration(X: np.ndarray, T: np.ndarray, v: np.ndarray, mask: np.ndarray, epsilon: float
                          ) -> np.ndarray | None:
    """The geodesic acceleration (N, dof) of :class:`.geodesic.GeodesicEquations` from the generators
    X (N, dof, 4, 4) and tool poses T (N, 4, 4) at q, the velocities v (N, dof), the metric's
    weights ``mask`` (4, 4) and ``epsilon``; None where its G is not numerically positive definite
    (the numpy path then decides, and names a singular metric)."""
    assert LIB is not None
    X, T, v, mask = f64(X), f64(T), f64(v), f64(mask)
    N, dof = v.shape
    a = np.empty((N, dof))
    work = np.empty(dof * (17 + dof) + 64)
    bad = LIB.gp_geodesic_acceleration(N, dof, X.ctypes.data, T.ctypes.data, v.ctypes.data, mask.ctypes.data,
                                       float(epsilon), a.ctypes.data, work.ctypes.data)
    return None if bad else a


def geodesic_jerk(X: np.ndarray, T: np.ndarray, v: np.ndarray, mask: np.ndarray, epsilon: float
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """The geodesic acceleration and its s-derivative, each (N, dof), of
    :meth:`.geodesic.GeodesicEquations.jerk`, from the same inputs as :func:`geodesic_acceleration`
    (None likewise where G is not numerically positive definite)."""
    assert LIB is not None
    X, T, v, mask = f64(X), f64(T), f64(v), f64(mask)
    N, dof = v.shape
    out = np.empty((2, N, dof))
    work = np.empty(dof * (50 + dof))
    bad = LIB.gp_geodesic_jerk(N, dof, X.ctypes.data, T.ctypes.data, v.ctypes.data, mask.ctypes.data, float(epsilon),
                               out.ctypes.data, out.ctypes.data + 8 * N * dof, work.ctypes.data)
    return None if bad else (out[0], out[1])


def polynomials(tables: Pinned, times: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
    """:func:`.polynomials.evaluate_polynomials` compiled: ``tables`` pins the knots (N,) and the
    coefficients (N - 1, 6, dof); values and derivatives up to ``order`` (<= 3) at ``times`` (M,),
    each (M, dof)."""
    assert LIB is not None
    t, c = tables.arrays
    assert t is not None and c is not None
    times = f64(times).reshape(-1)
    m, dof = times.size, c.shape[2]
    out = np.empty((order + 1, m, dof))
    LIB.gp_polynomials(m, times.ctypes.data, t.size, tables.ptrs[0], tables.ptrs[1], dof, order, out.ctypes.data)
    return tuple(out)


def capsule_distances(P: np.ndarray, half: np.ndarray, radius: np.ndarray, n: np.ndarray, ia: np.ndarray,
                      ib: np.ndarray) -> np.ndarray:
    """:func:`geodesic_planner.core.capsules.capsule_distances` in C (indices int64, (K,))."""
    assert LIB is not None
    P, half, radius = f64(P), f64(half), f64(radius)
    n, ia, ib = (np.ascontiguousarray(x, dtype=np.int64) for x in (n, ia, ib))
    out = np.empty(n.size)
    LIB.gp_capsule_distances(n.size, P.shape[1], P.ctypes.data, half.ctypes.data, radius.ctypes.data,
                             n.ctypes.data, ia.ctypes.data, ib.ctypes.data, out.ctypes.data)
    return out
