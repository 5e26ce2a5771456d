"""The files of a limit analysis (``masonry limit``), in its output folder.

``limit.json``
    The result (:mod:`masonry_nscd.limit.analysis`): the multiplier and its kind, the
    mechanism, the programme's status, counts, facets and times; written as the run folder's
    ``limit.json`` is (:func:`masonry_nscd.io.limit_files.write_limit`: atomically, NaN and
    infinities as ``null``). The name is the NSCD run's: both say how the structure collapses.
``mechanism.vtu``
    Every body's mesh with the mechanism's velocity of each node (point data ``velocity``,
    normalised: the fastest node at 1) and per cell the body's index (``body``) and whether it
    is a support (``support``); ParaView's Warp By Vector draws the mechanism.
``joint_forces.csv``
    One row per interface point: ``point``, ``candidate``, ``antagonist`` (the bodies'
    names), ``group``, position ``x_m``, ``y_m``, ``z_m``, normal ``n_x``, ``n_y``, ``n_z``,
    ``area_m2``, the force on the candidate in the point's frame ``N_N`` (compression
    positive), ``T_N``, ``S_N``, and the mechanism's relative velocity ``opening_rate``,
    ``slip_rate`` (normalised as the VTU's).
``joint_forces.vtu``
    The interface points with the same fields (``force_N`` as a global vector).
``thrust_line.csv``
    For an arch, one row per joint: where the resultant of the joint's forces crosses it
    (:mod:`masonry_nscd.limit.thrust`): ``joint``, ``angle_from_crown_deg``, ``x_m``, ``y_m``,
    ``eccentricity_m`` (from the joint's middle towards the extrados), ``relative_eccentricity``
    (over half the joint's length), ``thickness_m``, ``N_N``, ``V_N``. The same rows are
    ``thrust_line`` of ``limit.json``.
``mechanism.png``
    The picture of the mechanism (:mod:`masonry_nscd.limit.picture`), with the line of thrust
    of an arch.

``masonry threshold --method limit`` writes in its study folder ``threshold.json``: the
parameter, its threshold, the bracket and each step (:mod:`masonry_nscd.limit.thickness`).
"""

from __future__ import annotations

import csv
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.limit_files import read_limit, write_limit
from masonry_nscd.io.runfolder import LIMIT_JSON
from masonry_nscd.io.vtu import write_blocks_vtu, write_points_vtu

MECHANISM_VTU = "mechanism.vtu"
MECHANISM_PNG = "mechanism.png"
JOINT_FORCES_CSV = "joint_forces.csv"
JOINT_FORCES_VTU = "joint_forces.vtu"
THRUST_LINE_CSV = "thrust_line.csv"
THRESHOLD_JSON = "threshold.json"
#: Every file of the folder, for the CLI's report.
FILES = (LIMIT_JSON, MECHANISM_VTU, JOINT_FORCES_CSV, JOINT_FORCES_VTU, THRUST_LINE_CSV,
         MECHANISM_PNG)


def prepare(outdir: Path | str) -> Path:
    """The output folder, made if needed."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    return out


def write_result(outdir: Path | str, record: Mapping[str, Any]) -> Path:
    """``limit.json``."""
    return write_limit(outdir, record)


def read_result(outdir: Path | str) -> dict[str, Any] | None:
    """``limit.json`` of a limit analysis' folder (None: none)."""
    return read_limit(outdir)


def write_mechanism_vtu(outdir: Path | str, meshes: Sequence[tuple[np.ndarray, np.ndarray]],
                        node_velocity: Sequence[np.ndarray], support: np.ndarray) -> Path:
    """``mechanism.vtu``: the meshes of the bodies (nodes m, hexahedra) and the velocity of
    each node."""
    nodes, cells, vel, body = [], [], [], []
    offset = 0
    for i, ((X, conn), v) in enumerate(zip(meshes, node_velocity, strict=True)):
        if not len(conn):
            continue
        nodes.append(X)
        cells.append(conn + offset)
        vel.append(v)
        body.append(np.full(len(conn), i))
        offset += len(X)
    path = Path(outdir) / MECHANISM_VTU
    body_ids = np.concatenate(body) if body else np.zeros(0, np.int64)
    write_blocks_vtu(path, np.concatenate(nodes) if nodes else np.zeros((0, 3)),
                     np.concatenate(cells) if cells else np.zeros((0, 8), np.int64),
                     point_data={"velocity": np.concatenate(vel) if vel else np.zeros((0, 3))},
                     cell_data={"body": body_ids,
                                "support": np.asarray(support)[body_ids].astype(np.int64)})
    return path


def write_joint_forces(outdir: Path | str, rows: Mapping[str, Any]) -> tuple[Path, Path]:
    """``joint_forces.csv`` and ``joint_forces.vtu`` from per-point arrays: ``candidate``,
    ``antagonist``, ``group`` (names), ``x`` (p, 3) m, ``frame`` (p, 3, 3), ``area`` m^2,
    ``forces`` (p, 3) N, ``velocity`` (p, 3)."""
    x, frame, f, u = (np.asarray(rows[k]) for k in ("x", "frame", "forces", "velocity"))
    slip = np.linalg.norm(u[:, 1:], axis=1) if len(u) else np.zeros(0)
    csv_path = Path(outdir) / JOINT_FORCES_CSV

    def write(tmp) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["point", "candidate", "antagonist", "group", "x_m", "y_m", "z_m",
                        "n_x", "n_y", "n_z", "area_m2", "N_N", "T_N", "S_N", "opening_rate",
                        "slip_rate"])
            for p in range(len(x)):
                w.writerow([p, rows["candidate"][p], rows["antagonist"][p], rows["group"][p],
                            *(repr(float(v)) for v in x[p]),
                            *(repr(float(v)) for v in frame[p, 0]),
                            repr(float(rows["area"][p])), *(repr(float(v)) for v in f[p]),
                            repr(float(u[p, 0])), repr(float(slip[p]))])

    atomic_write(csv_path, write)
    vtu_path = Path(outdir) / JOINT_FORCES_VTU
    force = np.einsum("pk,pkj->pj", f, frame) if len(f) else np.zeros((0, 3))
    write_points_vtu(vtu_path, x.reshape(-1, 3), {
        "force_N": force, "normal_force_N": f[:, 0] if len(f) else np.zeros(0),
        "opening_rate": u[:, 0] if len(u) else np.zeros(0), "slip_rate": slip})
    return csv_path, vtu_path


def write_thrust_line(outdir: Path | str, rows: Sequence[Mapping[str, Any]]) -> Path:
    """``thrust_line.csv`` from the rows of :func:`masonry_nscd.limit.thrust.thrust_line`."""
    from masonry_nscd.limit.thrust import COLUMNS

    path = Path(outdir) / THRUST_LINE_CSV

    def write(tmp) -> None:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            for r in rows:
                w.writerow(["" if r[k] is None else (r[k] if isinstance(r[k], int)
                                                     else repr(float(r[k]))) for k in COLUMNS])

    atomic_write(path, write)
    return path


def write_threshold(outdir: Path | str, record: Mapping[str, Any]) -> Path:
    """``threshold.json`` of a threshold by limit analysis, in the folder ``outdir``."""
    out = prepare(outdir)
    text = json.dumps(dict(record), indent=2, allow_nan=False) + "\n"
    path = out / THRESHOLD_JSON
    atomic_write(path, lambda p: Path(p).write_text(text))
    return path
