"""The files of a limit-state run (an arch): ``limit.csv`` step by step, ``limit.json`` at the end.

``limit.csv``
    A header, then one row per step: ``step``, ``time_s`` (s), the value of each of the
    scene's load factors (its own unit: the body-force multiplier ``lambda`` dimensionless, a
    force in N, a settlement in m), ``max_displacement_m`` (m) and ``max_speed_m_s`` (m/s) of
    the structure's block points, ``kinetic_energy_J`` (J). Integers as such, floats in full
    precision (``repr``), each row flushed as it is written. A resumed run keeps the rows up to
    the step of its checkpoint (:class:`LimitTable`) and writes on.
``limit.json``
    The status of the run and its collapse (``status``, ``message``, ``rule``, ``collapse``,
    ``last``: :meth:`masonry_nscd.collapse.CollapseMonitor.record`), NaN and infinities as
    ``null``, indented by two spaces, written atomically (:mod:`masonry_nscd.io.atomic`); the
    summary and the studies read it back (:func:`read_limit`).

What the columns and the record mean is the collapse watch's (:mod:`masonry_nscd.collapse`).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import LIMIT_CSV, LIMIT_JSON


class LimitTable:
    """``limit.csv`` of the run folder ``outdir`` being written, with ``columns``.

    With ``resume_step`` (a resumed run), the rows of the interrupted run's file up to that
    step are kept, as they were, and given in :attr:`kept` (each row as ``{column: value}``)
    for the collapse watch to replay; the first row that is cut, malformed or later ends them.
    """

    def __init__(self, outdir: Path | str, columns: Sequence[str], *,
                 resume_step: int | None = None):
        path = Path(outdir) / LIMIT_CSV
        self.columns = list(columns)
        self.kept: list[dict[str, float]] = []
        lines: list[str] = []
        if resume_step is not None and path.exists():
            for line in path.read_text().splitlines(keepends=True)[1:]:
                try:
                    values = [float(v) for v in line.split(",")]
                except ValueError:
                    break
                if len(values) != len(self.columns) or values[0] > resume_step:
                    break
                lines.append(line)
                self.kept.append(dict(zip(self.columns, values, strict=True)))
        self.file = open(path, "w")  # noqa: SIM115 (closed by close)
        self.file.write(",".join(self.columns) + "\n")
        for line in lines:
            self.file.write(line)
        self.file.flush()

    def write_row(self, values: Sequence[float | int]) -> None:
        """One step's row, in the order of the columns (flushed at once)."""
        self.file.write(",".join(repr(float(v)) if not isinstance(v, int) else str(v)
                                 for v in values) + "\n")
        self.file.flush()

    def close(self) -> None:
        self.file.close()


def read_limit_table(outdir: Path | str) -> dict[str, np.ndarray]:
    """The columns of the run folder's ``limit.csv`` as float arrays (``{}`` for an empty
    file); the rows end at the first one that is malformed, a row of another length is
    skipped."""
    with open(Path(outdir) / LIMIT_CSV, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    head, body = rows[0], []
    for row in rows[1:]:
        try:
            values = [float(v) for v in row]
        except ValueError:
            break
        if len(values) == len(head):
            body.append(values)
    data = np.array(body, dtype=float).reshape(-1, len(head))
    return {k: data[:, j] for j, k in enumerate(head)}


def write_limit(outdir: Path | str, record: Mapping[str, Any]) -> Path:
    """Write ``record`` as the run folder's ``limit.json`` (atomically); returns its path."""
    path = Path(outdir) / LIMIT_JSON
    text = json.dumps(_finite(record), indent=2, allow_nan=False) + "\n"
    atomic_write(path, lambda p: Path(p).write_text(text))
    return path


def read_limit(outdir: Path | str) -> dict[str, Any] | None:
    """``limit.json`` of a run folder (None: none written)."""
    path = Path(outdir) / LIMIT_JSON
    if not path.exists():
        return None
    return json.loads(path.read_text())


def _finite(obj):
    """NaN and infinities as None, for JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj
