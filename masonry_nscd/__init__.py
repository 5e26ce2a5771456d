"""masonry_nscd: masonry walls block by block with Non-Smooth Contact Dynamics.

On import, the BLAS that numpy will load is given the same kernels on every processor
(``arithmetic.py``), and the numba on-disk cache is pointed at a folder keyed on a hash of the
package's kernel modules, the sources that hold ``njit`` functions (unless ``NUMBA_CACHE_DIR``
is already set). numba checks a cached kernel against its own module only, so a kernel that calls a kernel
of another, edited module could otherwise be served stale from the cache; with the key, any edit
of a kernel module starts a fresh cache, and edits elsewhere (the CLI, the run loop, the
reports) keep the compiled kernels.
``masonry cache-clear`` removes the cache folders.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

from masonry_nscd import arithmetic

# before numpy loads its BLAS: the same kernels and one BLAS thread on every processor
arithmetic.pin_environment()

__version__ = "0.1.0"

_PKG = Path(__file__).resolve().parent


def source_hash(kernels_only: bool = False) -> str:
    """Short hash of the package's .py files (names and contents); with ``kernels_only``, of
    the kernel modules only (the files that contain ``njit``)."""
    h = hashlib.sha256()
    for p in sorted(_PKG.rglob("*.py")):
        text = p.read_bytes()
        if not kernels_only or b"njit" in text:
            h.update(str(p.relative_to(_PKG)).encode())
            h.update(text)
    return h.hexdigest()[:16]


def cache_root() -> Path:
    """Folder holding the numba caches of every version of the sources."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "masonry_nscd" / "numba"


if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = str(cache_root() / source_hash(kernels_only=True))

#: the environment variables in which mpiexec gives its number of processes (MPICH's Hydra,
#: Open MPI): ``nscd/mpi.py``
MPI_SIZE_VARIABLES = ("PMI_SIZE", "OMPI_COMM_WORLD_SIZE")

# Under mpiexec with several processes (nscd/mpi.py) the processes share the cores: one BLAS
# thread each unless the environment says otherwise, set before numpy loads its BLAS: the
# processes are the parallelism, and BLAS threads on top of them would compete for the same
# cores (docs/scaling.md).
if any(os.environ.get(v, "").strip().isdigit() and int(os.environ[v]) > 1
       for v in MPI_SIZE_VARIABLES):
    for _name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")
