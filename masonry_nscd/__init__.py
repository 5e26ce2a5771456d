"""masonry_nscd: masonry walls block by block with Non-Smooth Contact Dynamics.

On import, the numba on-disk cache is pointed at a folder keyed on a hash of this package's
sources (unless ``NUMBA_CACHE_DIR`` is already set). numba checks a cached kernel against its
own module only, so a kernel that calls a kernel of another, edited module could otherwise be
served stale from the cache; with the key, any edit of the package starts a fresh cache.
``masonry cache-clear`` removes the cache folders.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__version__ = "0.1.0"

_PKG = Path(__file__).resolve().parent


def source_hash() -> str:
    """Short hash of every .py file of the package (names and contents)."""
    h = hashlib.sha256()
    for p in sorted(_PKG.rglob("*.py")):
        h.update(str(p.relative_to(_PKG)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def cache_root() -> Path:
    """Folder holding the numba caches of every version of the sources."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "masonry_nscd" / "numba"


if "NUMBA_CACHE_DIR" not in os.environ:
    os.environ["NUMBA_CACHE_DIR"] = str(cache_root() / source_hash())
