"""The tables of the cycles of a run, ``cycles.csv`` and ``envelope.csv`` of its run folder.

Written at the end of a run whose history has cycles (cyclic and tabulated histories), from
the rows computed by :mod:`masonry_nscd.post.cycles` with the columns below (units in the
column names: mm, kN, kN/mm, J, s; the damping ratio dimensionless): a header, then one row per
cycle (``cycles.csv``) and per point of the envelope (``envelope.csv``), floats in full
precision (``repr``), an undefined value as an empty field, ``\\n`` line ends. Each file is
written atomically (:mod:`masonry_nscd.io.atomic`).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import CYCLES, ENVELOPE

#: Columns of ``cycles.csv`` (units in the names; ``damping_ratio_eq`` is dimensionless).
CYCLE_COLUMNS = (
    "cycle", "amplitude_mm", "repetition", "start_s", "end_s",
    "peak_force_pos_kN", "ux_at_peak_pos_mm", "peak_force_neg_kN", "ux_at_peak_neg_mm",
    "ux_max_mm", "fx_at_ux_max_kN", "ux_min_mm", "fx_at_ux_min_kN",
    "secant_stiffness_kN_mm", "dissipated_energy_J", "damping_ratio_eq",
)
#: Columns of ``envelope.csv``: ``direction`` is ``positive`` or ``negative``.
ENVELOPE_COLUMNS = ("direction", "amplitude_mm", "cycle", "ux_mm", "fx_kN")


def write_cycle_tables(outdir: Path | str, rows: Sequence[Mapping[str, Any]],
                       envelope: Sequence[Mapping[str, Any]]) -> list[Path]:
    """Write ``cycles.csv`` and ``envelope.csv`` in ``outdir`` atomically (floats in full
    precision, an undefined value as an empty field); returns their paths."""
    paths = []
    for name, columns, data in ((CYCLES, CYCLE_COLUMNS, rows),
                                (ENVELOPE, ENVELOPE_COLUMNS, envelope)):
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(columns)
        for r in data:
            w.writerow(["" if r[c] is None else repr(r[c]) if isinstance(r[c], float) else r[c]
                        for c in columns])
        path, text = Path(outdir) / name, buf.getvalue()
        atomic_write(path, lambda p, text=text: Path(p).write_text(text))
        paths.append(path)
    return paths
