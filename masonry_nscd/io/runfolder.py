"""The run folder: the names of the files a run writes, the folder made ready for them, and
the readers of its small files.

::

    OUTDIR/
      case.yaml                   the case as run, every default filled in
      scene.json                  what the scene builder declared (groups, stages, bodies...)
      force_displacement.csv      one row per step
      energy.csv                  the energy balance, one row per output step
      results.h5                  mesh, per output step the states, the curve
      wall.pvd, vtu/              ParaView time series: blocks_NNNNNN.vtu, joints_NNNNNN.vtu
      checkpoint.npz              the state at the last output step (``masonry run --resume``;
                                  at most a second behind it, ``io/recorder.py``)
      summary.json                stiffness, peak, damages (written at the end)
      cycles.csv, envelope.csv    per cycle, and the envelope (cyclic and tabulated histories)
      limit.csv, limit.json       per step, and the status and collapse (limit-state runs)
      run.log
      sweep_run.json              what a sweep recorded of the run (runs made by a sweep)

Every name is a constant of this module, and ``io/`` writes and reads every file of a run
(a sweep writes and reads its own ``sweep_run.json``):

* :mod:`~masonry_nscd.io.recorder`: ``case.yaml``, ``scene.json``, the CSV, ``energy.csv``,
  ``results.h5`` (:mod:`~masonry_nscd.io.results_h5`), the VTU files and the PVD collection
  (:mod:`~masonry_nscd.io.vtu`), the checkpoint (:mod:`~masonry_nscd.io.checkpoint_file`);
* :mod:`~masonry_nscd.io.run_log`: ``run.log``;
* :mod:`~masonry_nscd.io.summary_json`: ``summary.json``; :mod:`~masonry_nscd.io.cycle_tables`:
  ``cycles.csv`` and ``envelope.csv``;
* :mod:`~masonry_nscd.io.limit_files`: ``limit.csv`` and ``limit.json``;
* readers: the curve (:func:`read_curve_csv`), the scene (:func:`read_scene_info`), the energy
  balance (:func:`read_energy_csv`) here; the output steps and their fields in
  :mod:`~masonry_nscd.io.results_h5`; the summary and the limit files in their modules.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.errors import RunInputError

CASE = "case.yaml"
SCENE = "scene.json"
CSV = "force_displacement.csv"
ENERGY = "energy.csv"
RESULTS = "results.h5"
PVD = "wall.pvd"
VTU_DIR = "vtu"
CHECKPOINT = "checkpoint.npz"
SUMMARY = "summary.json"
CYCLES = "cycles.csv"
ENVELOPE = "envelope.csv"
LOG = "run.log"
LIMIT_CSV = "limit.csv"
LIMIT_JSON = "limit.json"
#: What a sweep recorded of one of its runs (:mod:`masonry_nscd.studies.sweep`), in the run's folder.
SWEEP_MARKER = "sweep_run.json"

#: Columns of the CSV (units in the names; see docs/guide/outputs.md).
CSV_COLUMNS = [
    "step", "time_s", "ux_mm", "fx_kN", "uy_mm", "fy_kN", "fx_bottom_kN", "fy_bottom_kN",
    "iterations", "residual", "converged", "max_joint_damage", "max_block_damage", "max_d_cpp",
    "failed_gauss_points", "substeps", "time_step_s",
]

#: The VTU files of one output step: ``blocks_NNNNNN.vtu`` and ``joints_NNNNNN.vtu``.
VTU_FILE = re.compile(r"^(blocks|joints)_(\d+)\.vtu$")


def vtu_file(part: str, step: int) -> str:
    """Path of an output step's VTU file relative to the run folder (``part``: blocks or
    joints)."""
    return f"{VTU_DIR}/{part}_{step:06d}.vtu"


def prepare_outdir(outdir: Path, overwrite: bool) -> None:
    """Create the run folder; refuse a non-empty one unless ``overwrite``."""
    if outdir.exists() and not outdir.is_dir():
        raise RunInputError(f"output path {outdir} exists and is not a folder")
    if outdir.exists() and any(outdir.iterdir()) and not overwrite:
        raise RunInputError(f"output folder {outdir} exists and is not empty: "
                            "use --overwrite or another -o")
    try:
        (outdir / VTU_DIR).mkdir(parents=True, exist_ok=True)
        probe = outdir / ".write_test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise RunInputError(f"cannot write to output folder {outdir}: {exc.strerror}") from exc


def read_curve_csv(path: Path | str) -> dict[str, np.ndarray]:
    """The columns of ``force_displacement.csv`` as float arrays.

    A last row cut by an interruption (fewer fields, or text that is not a number) is dropped.
    """
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None:
            raise ValueError(f"{path}: empty file, no header")
        rows = []
        for row in reader:
            try:
                values = [float(v) for v in row]
            except ValueError:
                break
            if len(values) != len(header):
                break
            rows.append(values)
    data = np.array(rows, dtype=float).reshape(-1, len(header))
    return {name: data[:, j] for j, name in enumerate(header)}


def read_scene_info(outdir: Path | str) -> dict[str, Any]:
    """What the run folder keeps of its scene (``scene.json``)."""
    path = Path(outdir) / SCENE
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(f"{path} is missing: the run folder was written by an older "
                                "version of masonry_nscd (run the case again)") from None


def read_energy_csv(outdir: Path | str) -> dict[str, np.ndarray] | None:
    """The columns of the run folder's ``energy.csv`` (J, the relative imbalance
    dimensionless) as :func:`read_curve_csv` reads them; None when the run wrote none."""
    path = Path(outdir) / ENERGY
    if not path.exists():
        return None
    return read_curve_csv(path)
