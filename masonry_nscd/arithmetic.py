r"""Reproducible arithmetic: a run gives the same bits on any x86-64 processor, on one thread or two.

A floating-point sum depends on its order, and the libraries under a run choose the order by
the processor they find and by their thread count. What enters a run, and what is done about
it:

1. **OpenBLAS** (numpy's and SciPy's dense algebra: Newton's Anderson step, the small inverses,
   SuperLU's dense kernels) picks its kernels by the processor when it loads (SkylakeX on an
   AVX-512 machine, Haswell or Zen on others), and their sums differ in order; it also splits
   long products among its threads. Pinned: one kernel set for every x86-64 processor,
   ``OPENBLAS_CORETYPE`` = :data:`OPENBLAS_CORE`, and one thread (``OPENBLAS_NUM_THREADS=1``;
   the run's own parallel work is the per-point kernels, ``threads.py``), both set by
   :func:`pin_environment` when ``masonry_nscd`` is imported, before numpy loads its library.
   The smoke wall with rigid blocks took another path with the Haswell kernels than with the
   SkylakeX ones (a step halved on one and not the other).
2. **MKL** (PARDISO, the sparse LU) picks its code path by the processor and splits the
   factorisation among OpenMP threads. Pinned through its conditional numerical
   reproducibility (CNR): the branch :data:`MKL_BRANCH` (:func:`pin_mkl`, before any other MKL
   call), and PARDISO's CNR mode (``iparm[33]``), in which one and two threads give the same
   bits (``nscd/pardiso.py``).
3. **numba kernels** are compiled for the processor they run on, but without ``fastmath``
   LLVM keeps every sum in its written order and contracts no product into an FMA: the same
   bits compiled for Haswell (AVX2) as for Zen 4 (AVX-512).
4. **The per-point kernels on threads** (joint law, ENDO3D) read and write their own points
   only: the same bits on any number of threads (``threads.py``).
5. **glibc's libm** (``exp``, ``log``, ``pow`` of the ENDO3D and joint kernels) has variants
   chosen by the processor (with FMA or without): a processor without FMA (made before 2013)
   may differ in the last bit of some results. Not pinned (the loader chooses before Python
   starts).

Within these, a run of a case gives the same bits on any x86-64 processor with the same
versions of the packages. Across linear solvers (PARDISO or SuperLU), whose pivots differ, and
across package versions, a run agrees to the solver's tolerance: the driven point follows its
path exactly (``loading.step_velocity``), so a step that one run makes as two halves and the
other whole moves the curve only for the few steps its inertia takes to settle
(docs/reproducibility.md).

Set ``MASONRY_ARITHMETIC=native`` to leave every library its own choice (the processor's
fastest kernels, its own threads, PARDISO without its CNR mode); a variable the environment sets already
(``OPENBLAS_CORETYPE``, ``OPENBLAS_NUM_THREADS``) is kept. :func:`describe` says what a run
used: the second line of its ``run.log``.
"""

from __future__ import annotations

import ctypes
import glob
import os
import platform
import sys
from pathlib import Path

#: OpenBLAS's kernels for every x86-64 processor that numpy runs on (SSE4.2, numpy's own
#: baseline): the one set that runs everywhere
OPENBLAS_CORE = "Nehalem"
#: MKL's CNR branch that runs on every x86-64 processor, Intel's and others (MKL's constant
#: ``MKL_CBWR_COMPATIBLE``); MKL's faster branches (AVX2, AVX-512) run on Intel processors only
MKL_BRANCH = "COMPATIBLE"
_MKL_BRANCHES = {"AUTO": 2, "COMPATIBLE": 3}  # MKL's ``MKL_CBWR_*`` constants

#: what :func:`pin_environment` found: whether the OpenBLAS core is pinned, and why not
_state: dict[str, str | bool] = {}


def native() -> bool:
    """Whether the run leaves every library its own choices (``MASONRY_ARITHMETIC=native``)."""
    return os.environ.get("MASONRY_ARITHMETIC", "").strip().lower() == "native"


def pin_environment() -> None:
    """Set ``OPENBLAS_CORETYPE`` and ``OPENBLAS_NUM_THREADS`` (module docstring) unless the
    environment sets them, on x86-64 only; called on importing ``masonry_nscd``. Numpy read
    them already if it was imported first: :func:`describe` then says so."""
    if native():
        _state["openblas"] = "native (MASONRY_ARITHMETIC=native)"
        return
    if platform.machine().lower() not in ("x86_64", "amd64"):
        _state["openblas"] = f"not pinned (a {platform.machine()} processor)"
        return
    late = "numpy" in sys.modules
    os.environ.setdefault("OPENBLAS_CORETYPE", OPENBLAS_CORE)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    if late:
        _state["openblas"] = "not pinned (numpy was imported before masonry_nscd)"


def pin_mkl(lib: ctypes.CDLL) -> str:
    """Put MKL (``libmkl_rt``, loaded, no other MKL function called yet) in its CNR branch
    :data:`MKL_BRANCH` (nothing with ``MASONRY_ARITHMETIC=native``). Returns what it set,
    for :func:`describe`."""
    if native():
        _state["mkl"] = "native (MASONRY_ARITHMETIC=native)"
        return str(_state["mkl"])
    branch = MKL_BRANCH
    try:
        setter = lib.MKL_CBWR_Set
    except AttributeError:
        _state["mkl"] = "MKL without CNR: not pinned"
        return str(_state["mkl"])
    setter.argtypes = [ctypes.c_int]
    setter.restype = ctypes.c_int
    code = setter(_MKL_BRANCHES[branch])
    _state["mkl"] = f"CNR branch {branch}" if code == 0 else \
        f"CNR branch {branch} refused (MKL code {code}): not pinned"
    return str(_state["mkl"])


def _openblas_cores() -> list[str]:
    """The kernel set of each OpenBLAS library loaded in this process (numpy's, SciPy's)."""
    names = []
    for lib_dir in {Path(m.__file__).parent.parent / f"{m.__name__}.libs"
                    for m in (sys.modules.get("numpy"), sys.modules.get("scipy")) if m}:
        for path in sorted(glob.glob(str(lib_dir / "libscipy_openblas*.so"))):
            try:
                lib = ctypes.CDLL(path)
            except OSError:
                continue
            for symbol in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename",
                           "openblas_get_corename"):
                get = getattr(lib, symbol, None)
                if get is not None:
                    get.restype = ctypes.c_char_p
                    names.append(get().decode())
                    break
    return names


def describe() -> dict[str, str]:
    """What the run's arithmetic is (``run.log``'s second line): the OpenBLAS kernels
    and threads, MKL's CNR branch (once PARDISO has loaded MKL), and whether the run is pinned
    as the module docstring says (``reproducible``: ``"bitwise"``, or ``"no: "`` and why)."""
    cores = sorted(set(_openblas_cores()))
    out = {"openblas_kernels": ", ".join(cores) or "not loaded",
           "openblas_threads": os.environ.get("OPENBLAS_NUM_THREADS", "its default"),
           "mkl": str(_state.get("mkl", "not loaded"))}
    why = [str(_state["openblas"])] if "openblas" in _state else []
    others = [c for c in cores if c.lower() != OPENBLAS_CORE.lower()]
    if others and not why:
        why.append(f"OpenBLAS runs the {', '.join(others)} kernels (OPENBLAS_CORETYPE)")
    if ("CNR branch" not in out["mkl"] and out["mkl"] != "not loaded"
            and not native()) or "refused" in out["mkl"]:
        why.append(out["mkl"])
    if native() and not why:
        why.append("MASONRY_ARITHMETIC=native")
    out["reproducible"] = "no: " + "; ".join(why) if why else "bitwise"
    return out
