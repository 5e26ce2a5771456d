"""The tables of the cycles of a run, ``cycles.csv`` and ``envelope.csv`` of its run folder.

Written at the end of a run whose history has cycles (cyclic and tabulated histories), from
the rows computed by :mod:`masonry_nscd.post.cycles`, whose columns they are (units in the
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


def write_cycle_tables(outdir: Path | str, rows: Sequence[Mapping[str, Any]],
                       envelope: Sequence[Mapping[str, Any]]) -> list[Path]:
    """Write ``cycles.csv`` and ``envelope.csv`` in ``outdir`` atomically (floats in full
    precision, an undefined value as an empty field); returns their paths."""
    from masonry_nscd.post.cycles import CYCLE_COLUMNS, ENVELOPE_COLUMNS

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
