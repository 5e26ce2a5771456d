"""Checkpoints of a run folder, and how a resumed run puts the folder back to its checkpoint.

At every output step ``run_case`` writes, after the CSV rows, the VTU/PVD files and the HDF5
step, the file ``checkpoint.npz`` (atomically, see :mod:`masonry_nscd.nscd.checkpoint`): the
integrator's state plus what the run needs to continue its outputs (the step, whether the run
is finished, the PVD entries, the count of unconverged steps, the worst residual, the case as
run). ``masonry run --resume OUTDIR`` reads it and, before stepping on:

* cuts ``force_displacement.csv`` back to the rows of steps ``1..step`` (rewritten atomically)
  and reads them back as the curve so far;
* reopens ``results.h5``, dropping the output steps written after the checkpoint;
* rewrites ``wall.pvd`` from the checkpoint's entries and deletes the VTU files of later steps.

So whatever was written between the checkpoint and the interruption is discarded, and the
resumed run writes it again.
"""

from __future__ import annotations

import csv
import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from masonry_nscd.nscd.checkpoint import CheckpointError, load_checkpoint

CHECKPOINT_NAME = "checkpoint.npz"
CSV_NAME = "force_displacement.csv"
_VTU = re.compile(r"^(blocks|joints)_(\d+)\.vtu$")
_INT_COLUMNS = ("step", "iterations", "converged", "failed_gauss_points", "substeps")


@dataclass
class ResumePoint:
    """What a run folder's checkpoint says (SI units)."""

    step: int  # steps done at the checkpoint
    finished: bool  # the run reached its end at that step
    state: dict[str, np.ndarray]  # the integrator's state (nscd.checkpoint)
    pvd: list[tuple[float, str, int]]  # (time s, file, part) entries of wall.pvd
    unconverged: int  # steps not converged so far
    worst_residual: float  # worst solver residual so far (dimensionless)
    case_yaml: str  # the case as run


def checkpoint_extra(step: int, finished: bool, pvd: list[tuple[float, str, int]],
                     unconverged: int, worst_residual: float, case_yaml: str) -> dict:
    """The run's own arrays of a checkpoint (for ``nscd.checkpoint.save_checkpoint``)."""
    return {
        "step": np.int64(step), "finished": np.int64(finished),
        "pvd_time": np.array([p[0] for p in pvd], dtype=float),
        "pvd_file": np.array([p[1] for p in pvd], dtype=str),
        "pvd_part": np.array([p[2] for p in pvd], dtype=np.int64),
        "unconverged": np.int64(unconverged), "worst_residual": np.float64(worst_residual),
        "case_yaml": np.array(case_yaml),
    }


def read_resume_point(outdir: str | os.PathLike[str]) -> ResumePoint | None:
    """The checkpoint of run folder ``outdir``, or None when it has none.

    Raises :class:`~masonry_nscd.nscd.checkpoint.CheckpointError` when the file is not a
    readable checkpoint of a run.
    """
    path = Path(outdir) / CHECKPOINT_NAME
    try:
        state, extra = load_checkpoint(path)
    except FileNotFoundError:
        return None
    need = ("step", "finished", "pvd_time", "pvd_file", "pvd_part", "unconverged",
            "worst_residual", "case_yaml")
    missing = [k for k in need if k not in extra]
    if missing:
        raise CheckpointError(f"{path}: not a run checkpoint (lacks {', '.join(missing)})")
    pvd = [(float(t), str(f), int(p)) for t, f, p in
           zip(extra["pvd_time"], extra["pvd_file"], extra["pvd_part"])]
    return ResumePoint(
        step=int(extra["step"]), finished=bool(extra["finished"]), state=state, pvd=pvd,
        unconverged=int(extra["unconverged"]), worst_residual=float(extra["worst_residual"]),
        case_yaml=str(extra["case_yaml"]))


def truncate_csv(path: str | os.PathLike[str], step: int, columns: list[str]) -> dict[str, list]:
    """Cut the force-displacement CSV back to steps ``1..step``; return those rows as columns.

    The file is rewritten atomically (the original bytes of the rows kept). Raises
    :class:`CheckpointError` when the header is not ``columns`` or a row of ``1..step`` is
    missing or malformed.
    """
    from masonry_nscd.io.vtu import atomic_write

    path = Path(path)
    try:
        with open(path, newline="") as f:
            lines = f.read().splitlines(keepends=True)
    except FileNotFoundError as exc:
        raise CheckpointError(f"{path} is missing: the run cannot be resumed") from exc
    if not lines or next(csv.reader([lines[0]])) != columns:
        raise CheckpointError(f"{path}: not the CSV of this program (header differs)")
    kept = [lines[0]]
    curve: dict[str, list] = {c: [] for c in columns}
    for n, line in enumerate(lines[1:step + 1], start=1):
        row = next(csv.reader([line]), [])
        try:
            if len(row) != len(columns) or int(row[0]) != n or not line.endswith("\n"):
                raise ValueError
            values = [int(v) if c in _INT_COLUMNS else float(v) for c, v in zip(columns, row)]
        except ValueError:
            raise CheckpointError(f"{path}: row of step {n} missing or malformed, the "
                                  f"checkpoint is at step {step}") from None
        kept.append(line)
        for c, v in zip(columns, values):
            curve[c].append(v)
    if len(kept) != step + 1:
        raise CheckpointError(f"{path} ends at step {len(kept) - 1}, the checkpoint is at "
                              f"step {step}")
    if len(lines) != len(kept):
        atomic_write(path, lambda p: Path(p).write_text("".join(kept), newline=""))
    return curve


def prune_vtu(vtu_dir: str | os.PathLike[str], step: int) -> int:
    """Delete ``blocks_NNNNNN.vtu``/``joints_NNNNNN.vtu`` files of steps after ``step``;
    return how many were deleted."""
    removed = 0
    folder = Path(vtu_dir)
    if not folder.is_dir():
        return 0
    for p in folder.iterdir():
        m = _VTU.match(p.name)
        if m and int(m.group(2)) > step:
            p.unlink()
            removed += 1
    return removed


def csv_text(rows: list[list]) -> str:
    """Rows formatted as the run's CSV lines (floats with 9 significant digits)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    for row in rows:
        w.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in row])
    return buf.getvalue()
