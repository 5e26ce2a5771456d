r"""The recorder: everything a run writes into its folder, behind one interface.

* ``case.yaml`` and ``scene.json`` at the start (:mod:`masonry_nscd.io.runfolder`);
* ``force_displacement.csv``: a row per step (:meth:`Recorder.add_row`), written to the file
  (and fsynced) at output steps, whole rows only: after a failed write the file is cut back;
* ``energy.csv``: a row per output step (the energy balance, ``nscd/energy.py``), appended
  and fsynced before the checkpoint;
* at output steps (:meth:`Recorder.write_output`): the VTU files of the blocks and of the joint
  points and the HDF5 step (checked at once, written on a background thread while the run
  steps on, :mod:`masonry_nscd.io.background`); then, at most once every
  :data:`SYNC_EVERY_S` of wall time, at the last output step, and when the run stops for any
  reason (:meth:`Recorder.close`), the bookkeeping of the last output step
  (:meth:`Recorder._sync`): the PVD collection, the curve in the HDF5 file, and last
  ``checkpoint.npz``: the integrator's state plus what the run needs
  to continue its outputs (the step, whether the run is finished, the PVD entries, the count
  of unconverged steps, the worst residual, the case), taken at that output step. So a run
  stopped by Ctrl-C, SIGTERM or a failure has its checkpoint at its last output step, and one
  killed outright at most a second before (``--resume`` makes the steps after it again).

Every file but the CSV is written atomically (:mod:`masonry_nscd.io.atomic`); an OSError
becomes a :class:`~masonry_nscd.errors.RunOutputError` naming the file, and a NaN or infinity
in what is to be written a :class:`~masonry_nscd.errors.RunFailure` naming the field: no output
file ever holds one.

Resuming (``masonry run --resume OUTDIR``): :func:`read_resume_point` reads the checkpoint;
:meth:`Recorder.resume` puts the folder back to it before the run steps on: the CSV cut back to
the rows of steps ``1..step`` (rewritten atomically) and read back as the curve so far,
``energy.csv`` cut back to the rows of steps up to it, ``results.h5`` reopened without the
output steps written after the checkpoint, ``wall.pvd``
rewritten from the checkpoint's entries and the VTU files of later steps deleted. Whatever was
written between the checkpoint and the interruption is discarded, and written again.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from time import monotonic
from typing import Any

import numpy as np

from masonry_nscd.errors import RunFailure, RunInputError, RunOutputError
from masonry_nscd.io import checkpoint_file
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.atomic import atomic_write, writing
from masonry_nscd.io.background import BackgroundWriter
from masonry_nscd.io.results_h5 import ResultsFile
from masonry_nscd.io.vtu import blocks_file, points_file, write_pvd
from masonry_nscd.nscd.checkpoint import CheckpointError
from masonry_nscd.nscd.energy import ENERGY_COLUMNS

_INT_COLUMNS = ("step", "iterations", "converged", "failed_gauss_points", "substeps")

#: The PVD collection, the curve of results.h5 and the checkpoint are brought up to the last
#: output step when this much wall time (s) has passed since they last were (module
#: docstring; why: docs/choices.md, "What a run writes, and when").
SYNC_EVERY_S = 1.0


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


def read_resume_point(outdir: str | os.PathLike[str]) -> ResumePoint | None:
    """The checkpoint of run folder ``outdir``, or None when it has none.

    Raises :class:`~masonry_nscd.nscd.checkpoint.CheckpointError` when the file is not a
    readable checkpoint of a run.
    """
    path = Path(outdir) / rf.CHECKPOINT
    try:
        state, extra = checkpoint_file.load_checkpoint(path)
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


def truncate_energy_csv(path: str | os.PathLike[str], step: int) -> None:
    """Cut ``energy.csv`` back to its rows of steps up to ``step`` (rewritten atomically); a
    missing file (a run folder written before it existed) is left missing."""
    path = Path(path)
    try:
        lines = path.read_text().splitlines(keepends=True)
    except FileNotFoundError:
        return
    kept = lines[:1]
    for line in lines[1:]:
        head = line.split(",", 1)[0]
        if not line.endswith("\n") or not head.isdigit() or int(head) > step:
            break
        kept.append(line)
    if len(kept) != len(lines):
        atomic_write(path, lambda p: Path(p).write_text("".join(kept)))


def prune_vtu(vtu_dir: str | os.PathLike[str], step: int) -> int:
    """Delete the VTU files of output steps after ``step``; return how many were deleted."""
    removed = 0
    folder = Path(vtu_dir)
    if not folder.is_dir():
        return 0
    for p in folder.iterdir():
        m = rf.VTU_FILE.match(p.name)
        if m and int(m.group(2)) > step:
            p.unlink()
            removed += 1
    return removed


@dataclass
class StepOutput:
    """What an output step writes: the VTU fields and the HDF5 fields (SI units)."""

    block_points: dict[str, np.ndarray]  # per output node
    block_cells: dict[str, np.ndarray]  # per element
    joint_points: dict[str, np.ndarray]  # per contact point
    h5: dict[str, np.ndarray]  # the step's group of results.h5


class Recorder:
    """Writes a run folder (module docstring). Build it with :meth:`start` or :meth:`resume`."""

    def __init__(self, outdir: Path, case_yaml: str, *, vtu: bool, hdf5: bool,
                 nodes: np.ndarray, hexes: np.ndarray, points: np.ndarray):
        self.outdir = Path(outdir)
        self.case_yaml = case_yaml
        self.vtu, self.hdf5 = vtu, hdf5
        self.nodes, self.hexes, self.points = nodes, hexes, points
        self.csv_path = self.outdir / rf.CSV
        self.h5_path = self.outdir / rf.RESULTS
        self.pvd_path = self.outdir / rf.PVD
        self.ckpt_path = self.outdir / rf.CHECKPOINT
        self.energy_path = self.outdir / rf.ENERGY
        self.h5 = None
        self.pvd: list[tuple[float, str, int]] = []
        self.curve: dict[str, list] = {c: [] for c in rf.CSV_COLUMNS}
        # the bookkeeping of the last output step not yet written (``_sync``): the number of
        # PVD entries and of curve rows then, the integrator's state and the run's scalars;
        # ``_queued``, that of the output step whose VTU files and HDF5 step are still being
        # written, which becomes ``_unsynced`` once they are on disk (``_settle``)
        self._unsynced: tuple[int, int, dict[str, np.ndarray], dict[str, Any]] | None = None
        self._queued: tuple[int, int, dict[str, np.ndarray], dict[str, Any]] | None = None
        self._synced = monotonic()
        self._pending = io.StringIO()  # CSV rows not yet in the file
        # the VTU files and the HDF5 output steps, encoded and written while the run steps on
        # (io.background)
        self._files = BackgroundWriter() if vtu or hdf5 else None
        self._writer = csv.writer(self._pending)
        self._csv = None

    # --- opening ----------------------------------------------------------------------------
    @classmethod
    def start(cls, outdir: Path, case_yaml: str, scene_info: dict[str, Any],
              mesh: dict[str, np.ndarray], *, vtu: bool, hdf5: bool,
              energy: bool = True) -> Recorder:
        """A new run in ``outdir`` (already prepared, :func:`runfolder.prepare_outdir`):
        ``case.yaml``, ``scene.json``, ``results.h5`` with ``mesh`` (``nodes_m``, ``hexes``,
        ``contact_points_m``...), the CSV header."""
        self = cls(outdir, case_yaml, vtu=vtu, hdf5=hdf5, nodes=mesh["nodes_m"],
                   hexes=mesh["hexes"], points=mesh["contact_points_m"])
        with writing(self.ckpt_path):
            self.ckpt_path.unlink(missing_ok=True)  # an older run's checkpoint, never to resume
        for name, text in ((rf.CASE, case_yaml),
                           (rf.SCENE, json.dumps(scene_info, indent=1, allow_nan=False) + "\n")):
            with writing(self.outdir / name):
                atomic_write(self.outdir / name, lambda p, t=text: Path(p).write_text(t))
        if hdf5:
            with writing(self.h5_path):
                self.h5 = ResultsFile(self.h5_path, case_yaml, mesh)
        self._open_csv(append=False)
        self._writer.writerow(rf.CSV_COLUMNS)
        with writing(self.energy_path):
            self.energy_path.unlink(missing_ok=True)
            if energy:
                self.energy_path.write_text(",".join(ENERGY_COLUMNS) + "\n")
        return self

    @classmethod
    def resume(cls, outdir: Path, point: ResumePoint, mesh: dict[str, np.ndarray], *,
               vtu: bool, hdf5: bool) -> Recorder:
        """Continue the run of ``outdir`` from its checkpoint ``point`` (module docstring);
        RunInputError when the outputs do not fit it, RunOutputError when they cannot be
        read or written."""
        self = cls(outdir, point.case_yaml, vtu=vtu, hdf5=hdf5, nodes=mesh["nodes_m"],
                   hexes=mesh["hexes"], points=mesh["contact_points_m"])
        try:
            self.curve = truncate_csv(self.csv_path, point.step, rf.CSV_COLUMNS)
            if hdf5:
                self.h5 = ResultsFile.reopen(self.h5_path, last_step=point.step,
                                             curve_length=point.step)
        except (CheckpointError, ValueError) as exc:
            raise RunInputError(f"cannot resume the outputs in {outdir}: {exc}") from exc
        except OSError as exc:  # unreadable, flagged as open for write, or disk full
            raise RunOutputError(f"cannot resume the outputs in {outdir}: {exc}") from exc
        try:
            truncate_energy_csv(self.energy_path, point.step)
        except OSError as exc:
            raise RunOutputError(f"cannot resume the outputs in {outdir}: {exc}") from exc
        self.pvd = list(point.pvd)
        if vtu:
            with writing(self.pvd_path):
                write_pvd(self.pvd_path, self.pvd)
                prune_vtu(self.outdir / rf.VTU_DIR, point.step)
        self._open_csv(append=True)
        return self

    def _open_csv(self, append: bool) -> None:
        with writing(self.csv_path):  # unbuffered: whole rows only, see flush_rows
            self._csv = open(self.csv_path, "ab" if append else "wb", buffering=0)  # noqa: SIM115

    # --- writing ----------------------------------------------------------------------------
    def add_row(self, row: list) -> None:
        """One step's row (the columns of ``runfolder.CSV_COLUMNS``); every value finite, or
        RunFailure naming the columns (the row is not written)."""
        bad = [c for c, v in zip(rf.CSV_COLUMNS, row) if not math.isfinite(v)]
        if bad:
            raise RunFailure(f"{', '.join(bad)} not finite (the step is not written)")
        self._writer.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in row])
        for c, v in zip(rf.CSV_COLUMNS, row):
            self.curve[c].append(v)

    def flush_rows(self) -> None:
        """Append the pending CSV rows to the file and fsync it; after a failed write the file
        is cut back to where it was, so that it only ever holds whole rows."""
        data = memoryview(self._pending.getvalue().encode())
        end = self._csv.seek(0, os.SEEK_END)
        try:
            with writing(self.csv_path):
                while data:
                    data = data[self._csv.write(data):]
                os.fsync(self._csv.fileno())
        except RunOutputError:
            with contextlib.suppress(OSError):
                os.ftruncate(self._csv.fileno(), end)
            raise
        self._pending.seek(0)
        self._pending.truncate()

    def write_output(self, step: int, time: float, out: StepOutput, integ, *, done: bool,
                     unconverged: int, worst_residual: float,
                     energy_row: list | None = None) -> None:
        """An output step: the CSV rows so far, the energy row, the VTU files, the HDF5 step,
        and the bookkeeping (PVD, HDF5 curve, checkpoint) now or at a later sync (module
        docstring). A NaN or infinity in a field raises ValueError naming it (nothing of it
        written)."""
        self._settle()  # the last output step's files (long written, as a rule)
        self.flush_rows()
        if energy_row is not None:
            if not all(math.isfinite(v) for v in energy_row):
                raise ValueError("energy balance not finite")
            line = ",".join(f"{v:.9g}" if isinstance(v, float) else str(v)
                            for v in energy_row) + "\n"
            with writing(self.energy_path), open(self.energy_path, "a") as f:
                f.write(line)
                f.flush()
                os.fsync(f.fileno())
        if self.vtu:
            files = (rf.vtu_file("blocks", step), rf.vtu_file("joints", step))
            # both checked (and copied) before either is written, then written meanwhile
            vtus = (blocks_file(self.nodes, self.hexes, point_data=out.block_points,
                                cell_data=out.block_cells),
                    points_file(self.points, point_data=out.joint_points))
            for name, vtu in zip(files, vtus, strict=True):
                self._files.submit(vtu.write, self.outdir / name)
            self.pvd += [(time, files[0], 0), (time, files[1], 1)]
        if self.h5 is not None:
            # checked (and copied) now, appended meanwhile, after the step's VTU files
            append = self.h5.staged_step(step, time, out.h5)
            self._files.submit(lambda _path: append(), self.h5_path)
        self._queued = (len(self.pvd), len(self.curve[rf.CSV_COLUMNS[0]]),
                        checkpoint_file.checkpoint_arrays(integ), {
                            "step": np.int64(step), "finished": np.int64(done),
                            "unconverged": np.int64(unconverged),
                            "worst_residual": np.float64(worst_residual)})
        if done or monotonic() - self._synced >= SYNC_EVERY_S:
            self._settle()
            self._sync()

    def _settle(self) -> None:
        """Wait for the VTU files and the HDF5 step of the last output step: on disk, its
        bookkeeping is the one to sync; a failed write drops it (the run stops, its checkpoint
        the one before) and raises the RunOutputError naming the file."""
        queued, self._queued = self._queued, None
        if self._files is not None:
            self._files.wait()
        if queued is not None:
            self._unsynced = queued

    def _sync(self) -> None:
        """Write the bookkeeping of the last output step (module docstring): the PVD
        collection, the curve of results.h5 up to that step, then its checkpoint (last, so
        that what it points to is on disk before it; its VTU files and HDF5 step are,
        ``_settle``)."""
        entries, rows, state, scalars = self._unsynced
        pvd = self.pvd[:entries]
        if self.vtu:
            with writing(self.pvd_path):
                write_pvd(self.pvd_path, pvd)
        if self.h5 is not None:
            with writing(self.h5_path):
                self.h5.write_curve({c: np.asarray(v[:rows], dtype=float)
                                     for c, v in self.curve.items()})
        with writing(self.ckpt_path):
            checkpoint_file.write_checkpoint(self.ckpt_path, state, {
                **scalars,
                "pvd_time": np.array([p[0] for p in pvd], dtype=float),
                "pvd_file": np.array([p[1] for p in pvd], dtype=str),
                "pvd_part": np.array([p[2] for p in pvd], dtype=np.int64),
                "case_yaml": np.array(self.case_yaml),
            })
        self._unsynced = None
        self._synced = monotonic()

    def close(self) -> None:
        """Write the pending rows (complete steps after the last output step) and the
        bookkeeping of the last output step if it is not written yet, and close."""
        with contextlib.suppress(RunOutputError, OSError):
            if self._csv is not None:
                self.flush_rows()
        with contextlib.suppress(RunOutputError, OSError):
            self._settle()  # a failed write: the last output step whose files are whole
        if self._files is not None:
            with contextlib.suppress(RunOutputError, OSError):
                self._files.close()
        if self._unsynced is not None:  # a run stopped between two syncs
            with contextlib.suppress(RunOutputError, OSError):
                self._sync()
        with contextlib.suppress(OSError):
            if self._csv is not None:
                self._csv.close()
        if self.h5 is not None:
            self.h5.close()
