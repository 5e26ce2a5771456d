"""Figure files: a matplotlib figure written as a PNG file, and the file-name form of a label.

Shared by the figures of runs (:mod:`masonry_nscd.plots`, :mod:`masonry_nscd.plots_limit`) and
of the studies. A PNG is written atomically (:mod:`masonry_nscd.io.atomic`) at 120 dots per
inch: a figure on disk is either the previous complete one or the new one.
"""

from __future__ import annotations

import re
from pathlib import Path

from masonry_nscd.io.atomic import atomic_write

#: Resolution of the PNG files (dots per inch).
DPI = 120


def slug(text: str) -> str:
    """``text`` as part of a file name: every run of characters other than letters, digits,
    ``_``, ``.`` and ``-`` replaced by one ``_`` (``run`` when nothing is left)."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "run"


def save_png(fig, path: Path) -> Path:
    """Save a matplotlib figure as PNG at ``path`` atomically; returns ``path``."""
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI))
    return path
