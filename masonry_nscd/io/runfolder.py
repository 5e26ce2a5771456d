"""The run folder: the names of the files a run writes, and the folder made ready for them.

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
"""

from __future__ import annotations

import csv
import re
from pathlib import Path

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

#: Columns of the CSV (units in the names; see the README).
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
