"""The summary of a run folder, ``summary.json``: written at the end of a run, read by studies.

A JSON object whose keys carry their units (``_kN``, ``_mm``, ``_kN_mm``, ``_m``, ``_s``;
damages, residuals and counts dimensionless), as computed by :mod:`masonry_nscd.report`;
NaN and infinities are refused (the summary holds ``null`` for an undefined value). Written
atomically (:mod:`masonry_nscd.io.atomic`), indented by two spaces, with a final newline.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import SUMMARY


def write_summary(outdir: Path | str, summary: Mapping[str, Any]) -> Path:
    """Write ``summary.json`` in ``outdir`` atomically; returns its path."""
    path = Path(outdir) / SUMMARY
    text = json.dumps(summary, indent=2, allow_nan=False) + "\n"
    atomic_write(path, lambda p: Path(p).write_text(text))
    return path


def read_summary(outdir: Path | str, *, missing_ok: bool = False) -> dict[str, Any] | None:
    """The ``summary.json`` of run folder ``outdir``: ``None`` when the file is missing and
    ``missing_ok``, else FileNotFoundError; ValueError when it is not JSON."""
    path = Path(outdir) / SUMMARY
    if missing_ok and not path.exists():
        return None
    return json.loads(path.read_text())
