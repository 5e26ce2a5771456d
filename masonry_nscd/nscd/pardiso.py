r"""Sparse LU of the Newton matrix by PARDISO, the direct solver of Intel oneMKL (through ctypes).

The Newton matrices of a scene all have one sparsity pattern (``newton._Pattern``), so the
expensive parts are split as PARDISO allows: the analysis (fill-reducing order, symbolic
factorisation; phase 11) once per pattern, then a numeric factorisation per matrix (phase 22)
and solves with it (phase 33). The matrix is handed over as the pattern keeps it, in compressed
columns (CSC); PARDISO reads compressed rows, so it sees ``J^T`` and is asked for the
transposed solve (``iparm[11] = 2``), ``J x = b``, with zero-based indices (``iparm[34] = 1``).
The other settings are MKL's defaults for a real nonsymmetric matrix (``pardisoinit``,
``mtype = 11``: scaling and weighted matching, pivots smaller than 1e-13 of the largest
perturbed) but two: the minimum degree order (``iparm[1] = 0``; MKL's default, nested dissection,
gives more fill on the study's matrix and slower factorisations; docs/choices.md), and iterative refinement only when a pivot was perturbed (``iparm[7] = 0``; the
default refines every solve twice, each refinement a solve more, for a residual SuperLU does
not improve on either).

Why: a numeric factorisation of the study's Newton matrix takes less time than SuperLU's with
the same fill, and the factorisations are a large part of an elastic run; a solve costs the
same (docs/performance.md). The solutions agree with SuperLU's to round-off (the same Newton
iterations).

Threads: a factorisation runs on ``MKL_NUM_THREADS`` OpenMP threads when it is set, else on as
many as the per-point kernels (``threads.count()``: the cores, one in a sweep's worker,
``--threads``); what a second thread gains is in docs/performance.md. MKL may not change the number
during a run (``MKL_Set_Dynamic(0)``). MKL's OpenMP threads sleep as soon as a factorisation
ends (``KMP_BLOCKTIME=0`` unless the environment sets it): by default they spin for a while
after a parallel region, on the cores that the kernels' threads need next (docs/choices.md).

Reproducibility (``arithmetic.py``): MKL is put in its conditional numerical reproducibility
branch for every x86-64 processor as it loads, and every handle factorises in PARDISO's CNR
mode (``iparm[33]``, the number of threads): the same bits on any processor and on one thread
or two. Without the mode, factorisations on two threads differed from one run to the next and
from those on one thread in the last bits.

MKL ships as the ``mkl`` wheel (x86_64); where it is missing, :func:`available` is False and
``solver.linear: auto`` keeps SuperLU.
"""

from __future__ import annotations

import contextlib
import ctypes
import glob
import os
import sys
from ctypes.util import find_library
from functools import cache
from pathlib import Path

import numpy as np

from masonry_nscd import arithmetic, threads

#: PARDISO's matrix type: real and nonsymmetric
MTYPE_REAL_NONSYMMETRIC = 11

_ERRORS = {
    -1: "input inconsistent", -2: "not enough memory", -3: "reordering problem",
    -4: "zero pivot, numerical factorisation or iterative refinement problem",
    -5: "unclassified (internal) error", -6: "reordering failed", -7: "diagonal matrix is singular",
    -8: "32-bit integer overflow", -9: "not enough memory for the out-of-core solver",
    -10: "error opening the out-of-core files", -11: "read/write error with the out-of-core files",
}


#: Why PARDISO cannot run where MKL is missing (the run's, the case check's and the solver's
#: message)
MISSING = ("the pardiso linear solver needs Intel MKL (pip install mkl, x86_64 only), which is "
           "not installed here; use lu or auto")


class PardisoError(RuntimeError):
    """PARDISO returned an error code (the message says which)."""


def _candidates() -> list[str]:
    """Paths to try for MKL's single dynamic library, ``libmkl_rt``: this environment's
    ``lib`` folder (where the ``mkl`` wheel puts it), then the system's search path."""
    found = []
    for prefix in dict.fromkeys([sys.prefix, sys.base_prefix]):
        found += sorted(glob.glob(str(Path(prefix) / "lib" / "libmkl_rt.so*")), key=len)
        found += sorted(glob.glob(str(Path(prefix) / "Library" / "bin" / "mkl_rt*.dll")), key=len)
    name = find_library("mkl_rt")
    if name:
        found.append(name)
    return found


@cache
def library() -> ctypes.CDLL | None:
    """MKL's ``libmkl_rt`` with the PARDISO entry points typed, or None when it is not
    installed (or cannot be loaded). On loading, MKL's reproducible branch is set
    (``arithmetic.pin_mkl``, before any other MKL call) and its dynamic threads are turned off
    (module docstring)."""
    # read by Intel's OpenMP runtime when it starts, at the first factorisation (docstring)
    os.environ.setdefault("KMP_BLOCKTIME", "0")
    for path in _candidates():
        try:
            lib = ctypes.CDLL(path)
            lib.pardiso  # noqa: B018 (the entry point must exist)
        except (OSError, AttributeError):
            continue
        p_i32 = ctypes.POINTER(ctypes.c_int32)
        p_f64 = ctypes.POINTER(ctypes.c_double)
        p_i64 = ctypes.POINTER(ctypes.c_int64)
        lib.pardisoinit.argtypes = [p_i64, p_i32, p_i32]
        lib.pardisoinit.restype = None
        lib.pardiso.argtypes = [p_i64, p_i32, p_i32, p_i32, p_i32, p_i32, p_f64, p_i32, p_i32,
                                p_i32, p_i32, p_i32, p_i32, p_f64, p_f64, p_i32]
        lib.pardiso.restype = None
        lib.MKL_Set_Num_Threads.argtypes = [ctypes.c_int]
        lib.MKL_Set_Dynamic.argtypes = [ctypes.c_int]
        arithmetic.pin_mkl(lib)
        lib.MKL_Set_Dynamic(0)
        return lib
    return None


_threads_set = 0  # the OpenMP threads last given to MKL (0: none yet)


def thread_count(fixed: int | None = None) -> int:
    """The OpenMP threads of a factorisation: ``fixed`` when given, else ``MKL_NUM_THREADS``
    when set, else the per-point kernels' count (module docstring)."""
    env = os.environ.get("MKL_NUM_THREADS", "").strip()
    return fixed if fixed else int(env) if env.isdigit() and int(env) > 0 else threads.count()


def _use_threads(lib: ctypes.CDLL, fixed: int | None = None) -> None:
    """Give MKL its threads before a factorisation (``thread_count``); set only when it
    changed."""
    global _threads_set
    n = thread_count(fixed)
    if n != _threads_set:
        lib.MKL_Set_Num_Threads(n)
        _threads_set = n


def available() -> bool:
    """Whether PARDISO can be used here (MKL found and loaded)."""
    return library() is not None


class Pardiso:
    """One PARDISO handle for the matrices of one sparsity pattern: analysed once, then
    factorised and solved as often as asked; only the last factorisation is kept.

    ``indptr``, ``indices``: the pattern in compressed columns (n + 1 and nnz entries, zero
    based, sorted within each column), the same for every matrix given to :meth:`factorise`.
    ``order``: PARDISO's fill-reducing order, ``iparm[1]`` (0 minimum degree, the default:
    module docstring; 2 nested dissection by METIS). ``n_threads``: this handle's
    factorisations on that many threads whatever the environment (None: module docstring).
    The factorisations are in PARDISO's conditional numerical reproducibility mode
    (``iparm[33]``, module docstring).
    """

    def __init__(self, indptr: np.ndarray, indices: np.ndarray, n: int, order: int = 0,
                 n_threads: int | None = None):
        lib = library()
        if lib is None:
            raise PardisoError(MISSING)
        self._lib = lib
        self.n = int(n)
        self.n_threads = n_threads
        self._ia = np.ascontiguousarray(indptr, dtype=np.int32)
        self._ja = np.ascontiguousarray(indices, dtype=np.int32)
        if len(self._ia) != self.n + 1 or int(self._ia[-1]) != len(self._ja):
            raise ValueError("the pattern's index arrays do not describe an n x n matrix")
        self._pt = np.zeros(64, dtype=np.int64)  # PARDISO's internal handle (opaque)
        self.iparm = np.zeros(64, dtype=np.int32)
        mtype = ctypes.c_int32(MTYPE_REAL_NONSYMMETRIC)
        lib.pardisoinit(self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                        ctypes.byref(mtype), self.iparm.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)))
        self.iparm[1] = order  # minimum degree by default (module docstring)
        self.iparm[7] = 0  # iterative refinement only after a perturbed pivot (two steps)
        self.iparm[11] = 2  # solve with the transposed matrix (the CSC arrays as CSR: J^T)
        self.iparm[34] = 1  # zero-based indices
        if not arithmetic.native():  # CNR mode: the same bits on one thread or two
            self.iparm[33] = thread_count(n_threads)
        self._data: np.ndarray | None = None
        self._analysed = False
        self.generation = 0  # counts the factorisations; a factor solves only if it is the last

    def _call(self, phase: int, data: np.ndarray, b: np.ndarray | None = None,
              x: np.ndarray | None = None) -> None:
        p_i32 = ctypes.POINTER(ctypes.c_int32)
        p_f64 = ctypes.POINTER(ctypes.c_double)
        one = ctypes.c_int32(1)
        nrhs = ctypes.c_int32(1)
        err = ctypes.c_int32(0)
        dummy = np.zeros(1)
        self._lib.pardiso(
            self._pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(one),
            ctypes.byref(one), ctypes.byref(ctypes.c_int32(MTYPE_REAL_NONSYMMETRIC)),
            ctypes.byref(ctypes.c_int32(phase)), ctypes.byref(ctypes.c_int32(self.n)),
            data.ctypes.data_as(p_f64), self._ia.ctypes.data_as(p_i32),
            self._ja.ctypes.data_as(p_i32), None, ctypes.byref(nrhs),
            self.iparm.ctypes.data_as(p_i32), ctypes.byref(ctypes.c_int32(0)),
            (dummy if b is None else b).ctypes.data_as(p_f64),
            (dummy if x is None else x).ctypes.data_as(p_f64), ctypes.byref(err))
        if err.value != 0:
            raise PardisoError(f"PARDISO phase {phase}: error {err.value} "
                               f"({_ERRORS.get(err.value, 'unknown')})")

    def factorise(self, data: np.ndarray) -> PardisoFactor:
        """Numeric factorisation of the matrix with values ``data`` (in the pattern's order);
        the pattern is analysed at the first call. Returns the factor, which solves until the
        next factorisation."""
        data = np.ascontiguousarray(data, dtype=np.float64)
        if len(data) != len(self._ja):
            raise ValueError(f"{len(data)} values for a pattern of {len(self._ja)} entries")
        _use_threads(self._lib, self.n_threads)
        if not self._analysed:
            self._call(11, data)
            self._analysed = True
        self._call(22, data)
        self._data = data  # kept: the solves' iterative refinement reads the matrix
        self.generation += 1
        return PardisoFactor(self, self.generation)

    def solve(self, b: np.ndarray, generation: int) -> np.ndarray:
        """``x`` with ``J x = b`` for the factorisation ``generation`` (the last one)."""
        if generation != self.generation or self._data is None:
            raise PardisoError("this factorisation was replaced by a later one")
        b = np.ascontiguousarray(b, dtype=np.float64)
        x = np.empty(self.n)
        self._call(33, self._data, b, x)
        return x

    def release(self) -> None:
        """Free PARDISO's memory for this handle (also on garbage collection)."""
        if self._analysed:
            self._call(-1, np.zeros(1))
        self._analysed = False
        self._data = None

    def __del__(self):
        with contextlib.suppress(Exception):  # never raise from a finaliser
            self.release()


class PardisoFactor:
    """A factorisation made by a :class:`Pardiso` handle: ``solve(b)`` gives ``J^-1 b``."""

    def __init__(self, handle: Pardiso, generation: int):
        self.handle, self.generation = handle, generation

    def solve(self, b: np.ndarray) -> np.ndarray:
        return self.handle.solve(b, self.generation)
