"""Parameter sweeps of one case: a run for every combination of some fields' values.

A sweep takes a case file and, for some of its fields, a list of values (the ``--set`` syntax
of ``masonry run`` with several values: ``loading.vertical_stress.value_Pa=0.3e6,0.5e6``). It
runs the cartesian product of the lists, one run per combination, each one in its own folder
``OUTDIR/runs/<name>`` with the usual outputs of :func:`masonry_nscd.run.run_case`. The name is
made of the values as typed, ``value_Pa=0.3e6__mu=0.5`` (the last part of each field path, the
whole path where two last parts are the same). A ``--set`` with one value is a fixed override
of every run; it is left out of the names and of the table.

Every value is read as YAML like a case file (YAML 1.2: ``0.3e6`` is a float, ``[2,2,1]`` a
list; commas inside brackets do not split values) and every combination is validated before
any run starts (:class:`SweepError`, one message per problem, naming the field).

The combinations are a batch (:mod:`masonry_nscd.studies.batch`): run on local worker
processes or on a Dask cluster, the failures recorded with their status, the finished runs
kept when the same sweep runs again.

``sweep.csv``, one row per run in the order of the product (rewritten as runs end): the swept
fields (named by their path, values as validated, SI units), then ``initial_stiffness_kN_mm``,
``peak_force_kN``, ``ux_at_peak_mm``, ``force_at_target_kN``, ``target_ux_mm``, and for cyclic
and tabulated histories ``peak_force_neg_kN``, ``ux_at_peak_neg_mm``, ``dissipated_energy_J``,
for ground motion ``peak_drift_mm``, ``residual_drift_mm``, ``peak_base_shear_kN`` (empty
otherwise; definitions in :mod:`masonry_nscd.report`), ``unconverged_steps``, the failure
modes, for limit-state cases (arch, vault, assembly) ``collapse`` (true or false: standing),
``collapse_load_name`` and ``collapse_load`` (the first growing load, e.g. ``lambda``, at the
onset of the mechanism) and ``collapse_time_s`` (the onset; empty otherwise),
``run_time_s`` (wall-clock time of the run on its worker, s), ``status``, ``message`` and
``run`` (the folder name). A run that was skipped keeps the numbers and the run time of the
sweep that made it. ``force_displacement.png``: the
curves of the runs that finished (:func:`masonry_nscd.plots.plot_curves`).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from masonry_nscd.case import CaseError, case_from_dict, read_yaml
from masonry_nscd.io.runfolder import read_scene_info
from masonry_nscd.plots import RunData, plot_curves
from masonry_nscd.studies import batch
from masonry_nscd.studies.batch import Point, SweepError, make_point, parse_set
from masonry_nscd.studies.point import RunRecord

__all__ = ["PLOT_FILE", "SWEEP_FILE", "TABLE_FILE", "SweepError", "SweepResult", "plot_overlay",
           "point_names", "run_sweep", "short_keys", "sweep_points"]

SWEEP_FILE = "sweep.json"
TABLE_FILE = "sweep.csv"
PLOT_FILE = "force_displacement.png"


# ---------------------------------------------------------------------------------------------
# The combinations
# ---------------------------------------------------------------------------------------------


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_") or "_"


def short_keys(paths: Sequence[str]) -> dict[str, str]:
    """Name of each path in the run folders: its last part, or the whole path when two
    paths end alike."""
    last = [p.rsplit(".", 1)[-1] for p in paths]
    return {p: (k if last.count(k) == 1 else p) for p, k in zip(paths, last, strict=True)}


def point_names(combos: Sequence[Sequence[tuple[str, str]]]) -> list[str]:
    """Folder names of the combinations ``[(path, value text), ...]``: ``key=value`` joined by
    ``__``; a name that repeats (values that differ only in symbols) gets ``~2``, ``~3``..."""
    keys = short_keys([p for p, _ in combos[0]]) if combos and combos[0] else {}
    names: list[str] = []
    for combo in combos:
        base = "__".join(f"{keys[p]}={_slug(v)}" for p, v in combo) or "run"
        name, n = base, 1
        while name in names:
            n += 1
            name = f"{base}~{n}"
        names.append(name)
    return names


def sweep_points(case_file: Path, sets: Sequence[str]) -> tuple[list[Point], list[str]]:
    """Every combination of the ``--set`` options, validated: ``(points, swept paths)``.

    Raises :class:`SweepError` listing every problem (each combination is loaded; a message
    shared by several combinations is given once).
    """
    parsed = [parse_set(s) for s in sets]
    paths = [p for p, _ in parsed]
    twice = sorted({p for p in paths if paths.count(p) > 1})
    if twice:
        raise SweepError(f"--set {', '.join(twice)}: given more than once (put every value "
                         "in one list)")
    fixed = [f"{p}={texts[0]}" for p, texts in parsed if len(texts) == 1]
    lists = [[(p, t) for t in texts] for p, texts in parsed if len(texts) > 1]
    combos = [list(c) for c in itertools.product(*lists)]
    points, problems = [], []
    for name, combo in zip(point_names(combos), combos, strict=True):
        try:
            points.append(make_point(case_file, name, combo, fixed))
        except CaseError as exc:
            problems += [m for m in exc.messages if m not in problems]
    if problems:
        raise SweepError(problems)
    return points, [p for p, texts in parsed if len(texts) > 1]


# ---------------------------------------------------------------------------------------------
# The figure and the sweep
# ---------------------------------------------------------------------------------------------


def plot_overlay(points: Sequence[Point], records: Sequence[RunRecord], runs_dir: Path,
                 path: Path) -> Path | None:
    """The force-displacement curves of the finished runs (with their curve) on one chart;
    None if there are none."""
    import numpy as np

    runs = [RunData(runs_dir / p.name, case_from_dict(read_yaml(p.case_yaml)),
                    read_scene_info(runs_dir / p.name),
                    {k: np.asarray(v, dtype=float) for k, v in r.curve.items()},
                    r.outputs, label=p.name)
            for p, r in zip(points, records, strict=True) if r.ok and r.curve]
    return plot_curves(runs, path) if runs else None


@dataclass
class SweepResult:
    """The records of a sweep, in the order of the product, and the files written."""

    records: list[RunRecord]
    table: Path
    plot: Path | None

    @property
    def failed(self) -> list[RunRecord]:
        return [r for r in self.records if not r.ok]


def run_sweep(case_file: Path, sets: Sequence[str], outdir: Path, *, workers: int | None = None,
              scheduler: str | None = None,
              echo: Callable[[str], None] = print) -> SweepResult:
    """Validate, then run every combination of ``sets`` (see the module docstring).

    Raises :class:`SweepError` before any run for a bad option or combination.
    """
    points, paths = sweep_points(case_file, sets)
    table = outdir / TABLE_FILE
    description = {"case_file": str(case_file), "sets": list(sets),
                   "runs": [p.name for p in points]}
    done = batch.run_batch(points, outdir, marker=SWEEP_FILE, description=description,
                           table=table, param_paths=paths,
                           intro=f"{len(points)} runs of {case_file} in {outdir / batch.RUNS_DIR}",
                           workers=workers, scheduler=scheduler, keep_curve=True, echo=echo)
    try:
        plot = plot_overlay(points, done, outdir / batch.RUNS_DIR, outdir / PLOT_FILE)
    except (OSError, ValueError) as exc:  # the table is written: a figure must not lose it
        echo(f"no figure: {type(exc).__name__}: {exc}")
        plot = None
    return SweepResult(done, table, plot)
