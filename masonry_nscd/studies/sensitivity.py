"""Sensitivity of one output of a run to the case's parameters, with SALib, as a batch of runs.

Each parameter is a numeric field of the case, ``PATH=LOW:HIGH`` (SI units of the field),
uniform over ``[LOW, HIGH]``. SALib draws the samples, the samples are a batch of runs as a
sweep's (:mod:`masonry_nscd.studies.batch`: local worker processes or a Dask cluster,
resumable, folders ``OUTDIR/runs/sample_NNNN``), and SALib computes the indices of the chosen
output of the run summary (:data:`OUTPUTS`, definitions in :mod:`masonry_nscd.report`).

Methods (``D`` parameters, ``N`` = ``samples``)
-----------------------------------------------
``morris``
    Elementary effects (Morris 1991, Campolongo et al. 2007): ``N`` trajectories of ``D + 1``
    runs on a grid of :data:`MORRIS_LEVELS` levels per parameter, ``N (D + 1)`` runs. The
    elementary effect of parameter ``i`` is ``EE_i = (y(x + delta e_i) - y(x)) / delta`` with
    ``delta`` the step as a fraction of the range (2/3 with 4 levels): the change of the output
    for a move over the whole range, in the output's unit. Indices: ``mu`` (mean of EE),
    ``mu_star`` (mean of ``|EE|``: importance), ``sigma`` (standard deviation of EE:
    non-linearity and interactions) and ``mu_star_conf`` (half-width of the bootstrap 95 %
    interval of ``mu_star``). A screening method: a ranking with few runs.
``sobol``
    Variance-based indices (Saltelli 2002/2010, Sobol' sequence): ``N`` a power of 2,
    ``N (D + 2)`` runs (first and total orders, no second order). ``S1``: the share of the
    output's variance due to the parameter alone; ``ST``: with all its interactions;
    ``S1_conf``, ``ST_conf``: half-widths of the bootstrap 95 % intervals. Dimensionless.
    Reliable estimates need hundreds of runs per parameter.

Runs without a value
--------------------
Both designs need the output of every run: Morris' elementary effects are differences between
consecutive runs of a trajectory, the Sobol estimators combine rows of fixed sample matrices,
and dropping runs would bias them silently. So when a run failed, or finished without a value
of the output (e.g. ``force_at_target_kN`` of a run that stopped before the target), the
analysis is refused: the runs are listed, ``samples.csv`` holds all of them with their status
and message, and the command exits with code 1. Narrow the ranges, or fix the cause, and run
the same command again: the finished runs are kept.

Files in OUTDIR: ``samples.csv`` (the table of a batch, as a sweep's ``sweep.csv``: the parameter
values, the outputs, run time, status, message, run folder), ``indices.csv`` (one row per parameter,
columns above), ``indices.png`` (bar chart of the indices), ``sensitivity.json`` (the problem,
method, samples, seed and output).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from masonry_nscd.case import CaseError, case_from_dict, read_yaml
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.studies.batch import (
    RUNS_DIR,
    Point,
    SweepError,
    field_value,
    make_point,
    parse_set,
    run_batch,
)
from masonry_nscd.studies.point import RunRecord

METHODS = ("morris", "sobol")
#: Outputs of a run that can be analysed (keys of the run summary, unit in the name).
OUTPUTS = ("peak_force_kN", "initial_stiffness_kN_mm", "force_at_target_kN", "ux_at_peak_mm",
           "peak_force_neg_kN", "dissipated_energy_J",  # cyclic histories
           "peak_drift_mm", "residual_drift_mm", "peak_base_shear_kN")  # ground motion
MORRIS_LEVELS = 4
INDEX_COLUMNS = {"morris": ("mu", "mu_star", "sigma", "mu_star_conf"),
                 "sobol": ("S1", "S1_conf", "ST", "ST_conf")}
MARKER_FILE = "sensitivity.json"
SAMPLES_FILE = "samples.csv"
INDICES_FILE = "indices.csv"
CHART_FILE = "indices.png"


@dataclass(frozen=True)
class Param:
    """One parameter: a numeric field of the case and its range (SI units of the field)."""

    path: str
    low: float
    high: float


def parse_param(text: str) -> Param:
    """``"joint.mu=0.5:0.9"`` -> :class:`Param`, or
    :class:`~masonry_nscd.studies.batch.SweepError`."""
    path, sep, bounds = text.partition("=")
    parts = bounds.split(":")
    try:
        low, high = (float(p) for p in parts)
    except ValueError:
        low = high = math.nan
    if not sep or not path.strip() or not (math.isfinite(low) and math.isfinite(high)
                                           and low < high):
        raise SweepError(f"--param {text}: expected PATH=LOW:HIGH with finite LOW < HIGH, e.g. "
                         "joint.mu=0.5:0.9")
    return Param(path.strip(), low, high)


def problem(params: Sequence[Param]) -> dict[str, Any]:
    """The SALib problem: names are the field paths, bounds the ranges."""
    return {"num_vars": len(params), "names": [p.path for p in params],
            "bounds": [[p.low, p.high] for p in params]}


def check_design(method: str, samples: int, output: str) -> None:
    """Refuse a method, sample count or output that cannot be analysed (SweepError)."""
    if method not in METHODS:
        raise SweepError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    if output not in OUTPUTS:
        raise SweepError(f"--output must be one of {', '.join(OUTPUTS)}, got {output!r}")
    if method == "morris" and samples < 2:
        raise SweepError(f"--samples: Morris needs at least 2 trajectories, got {samples}")
    if method == "sobol" and (samples < 2 or samples & (samples - 1)):
        raise SweepError(f"--samples: Sobol needs a power of 2 (the Sobol' sequence), got "
                         f"{samples}")


def draw(prob: dict[str, Any], method: str, samples: int, seed: int):  # -> NDArray (n, D)
    """The sample matrix of the method (one row per run, SI units)."""
    if method == "morris":
        from SALib.sample import morris

        return morris.sample(prob, samples, num_levels=MORRIS_LEVELS, seed=seed)
    from SALib.sample import sobol

    return sobol.sample(prob, samples, calc_second_order=False, seed=seed)


def sample_points(case_file: Path, params: Sequence[Param], rows, fixed: Sequence[str]
                  ) -> list[Point]:
    """A validated :class:`~masonry_nscd.studies.batch.Point` per sample row
    (``sample_NNNN``)."""
    width = max(4, len(str(len(rows) - 1)))
    points, problems = [], []
    for i, row in enumerate(rows):
        swept = [(p.path, repr(float(x))) for p, x in zip(params, row, strict=True)]
        try:
            point = make_point(case_file, f"sample_{i:0{width}d}", swept, fixed)
        except CaseError as exc:
            problems += [m for m in exc.messages if m not in problems]
            continue
        points.append(point)
    if problems:
        raise SweepError(problems)
    return points


def check_numeric(case_file: Path, params: Sequence[Param], fixed: Sequence[str]) -> None:
    """Each parameter must be a numeric field that takes both of its bounds (SweepError)."""
    problems = []
    for p in params:
        for bound in (p.low, p.high):
            try:
                point = make_point(case_file, "check", [(p.path, repr(bound))], fixed)
            except CaseError as exc:
                problems += [m for m in exc.messages if m not in problems]
                continue
            value = field_value(case_from_dict(read_yaml(point.case_yaml)), p.path)
            if isinstance(value, bool) or not isinstance(value, int | float):
                problems.append(f"--param {p.path}: not a number (the field holds {value!r})")
                break
    if problems:
        raise SweepError(problems)


def output_values(records: Sequence[RunRecord], output: str
                  ) -> tuple[list[float], list[RunRecord]]:
    """The output of every run, and the runs without one (failed, or no value)."""
    values, missing = [], []
    for r in records:
        v = r.outputs.get(output) if r.ok else None
        if v is None or not math.isfinite(float(v)):
            missing.append(r)
            values.append(math.nan)
        else:
            values.append(float(v))
    return values, missing


def describe_missing(missing: Sequence[RunRecord]) -> str:
    """``sample_0003: failed, sample_0007: no value``."""
    return ", ".join(f"{r.name}: {r.status if not r.ok else 'no value'}" for r in missing)


def analyse(prob: dict[str, Any], method: str, X, Y, seed: int) -> list[dict[str, Any]]:
    """The indices, one dict per parameter (``parameter`` and :data:`INDEX_COLUMNS`)."""
    import numpy as np

    Y = np.asarray(Y, dtype=float)
    if method == "morris":
        from SALib.analyze import morris

        res = morris.analyze(prob, np.asarray(X), Y, num_levels=MORRIS_LEVELS, seed=seed)
    else:
        from SALib.analyze import sobol

        res = sobol.analyze(prob, Y, calc_second_order=False, seed=seed)
    return [{"parameter": name, **{k: float(res[k][i]) for k in INDEX_COLUMNS[method]}}
            for i, name in enumerate(prob["names"])]


def write_indices(path: Path, method: str, rows: Sequence[dict[str, Any]]) -> Path:
    """``indices.csv``: ``parameter`` then the index columns of the method."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    cols = ("parameter", *INDEX_COLUMNS[method])
    w.writerow(cols)
    for r in rows:
        w.writerow([r["parameter"], *(repr(r[c]) for c in cols[1:])])
    atomic_write(path, lambda tmp: Path(tmp).write_text(buf.getvalue()))
    return path


def format_indices(method: str, rows: Sequence[dict[str, Any]]) -> list[str]:
    """The indices as an aligned text table."""
    cols = INDEX_COLUMNS[method]
    width = max(len("parameter"), *(len(r["parameter"]) for r in rows))
    lines = [f"{'parameter':<{width}}" + "".join(f"{c:>14}" for c in cols)]
    lines += [f"{r['parameter']:<{width}}" + "".join(f"{r[c]:>14.4g}" for c in cols)
              for r in rows]
    return lines


def output_unit(output: str) -> str:
    """``peak_force_kN`` -> ``kN``, ``initial_stiffness_kN_mm`` -> ``kN/mm``."""
    for suffix, unit in (("_kN_mm", "kN/mm"), ("_kN", "kN"), ("_mm", "mm"), ("_J", "J")):
        if output.endswith(suffix):
            return unit
    return ""


def plot_indices(path: Path, method: str, rows: Sequence[dict[str, Any]], output: str) -> Path:
    """Bar chart of the indices: Morris ``mu_star`` (with its interval) and ``sigma``; Sobol
    ``S1`` and ``ST`` (with their intervals)."""
    import numpy as np
    from matplotlib.figure import Figure

    names = [r["parameter"] for r in rows]
    y = np.arange(len(rows))
    if method == "morris":
        unit = output_unit(output)
        bars = [("mu_star", "mu_star_conf", r"$\mu^*$ (mean |elementary effect|)"),
                ("sigma", None, r"$\sigma$ (spread of the effects)")]
        xlabel = f"effect on {output} of a move over the whole range ({unit})"
    else:
        bars = [("S1", "S1_conf", "$S_1$ (first order)"), ("ST", "ST_conf", "$S_T$ (total)")]
        xlabel = f"share of the variance of {output} (dimensionless)"
    fig = Figure(figsize=(9, 1.2 + 0.8 * len(rows)), layout="constrained")
    ax = fig.subplots()
    h = 0.8 / len(bars)
    for k, (col, conf, label) in enumerate(bars):
        ax.barh(y + (k - (len(bars) - 1) / 2) * h, [r[col] for r in rows], height=h,
                xerr=[r[conf] for r in rows] if conf else None, capsize=3, label=label,
                color=f"C{k}")
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel(xlabel)
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    ax.set_title(f"{method.capitalize()} sensitivity of {output} (error bars: 95 % intervals)")
    atomic_write(path, lambda tmp: fig.savefig(tmp, format="png", dpi=120))
    return path


@dataclass
class SensitivityResult:
    """The records of the samples, the indices (None when the analysis was refused) and the
    files written."""

    records: list[RunRecord]
    samples_table: Path
    indices: list[dict[str, Any]] | None
    missing: list[RunRecord]
    indices_csv: Path | None = None
    chart: Path | None = None


def run_sensitivity(case_file: Path, param_texts: Sequence[str], method: str, samples: int,
                    output: str, outdir: Path, *, fixed_sets: Sequence[str] = (),
                    workers: int | None = None, scheduler: str | None = None, seed: int = 0,
                    echo: Callable[[str], None] = print) -> SensitivityResult:
    """Sample, validate every sample, run them, analyse (see the module docstring).

    Raises :class:`~masonry_nscd.studies.batch.SweepError` before any run for a bad option.
    """
    check_design(method, samples, output)
    params = [parse_param(t) for t in param_texts]
    fixed = []
    for text in fixed_sets:
        path, values = parse_set(text)
        if len(values) != 1:
            raise SweepError(f"--set {text}: one value only (the parameters are --param)")
        fixed.append(f"{path}={values[0]}")
    paths = [p.path for p in params]
    clash = sorted({p for p in paths if paths.count(p) > 1}
                   | {p for p in paths if any(f.split("=", 1)[0].strip() == p for f in fixed)})
    if clash:
        raise SweepError(f"--param {', '.join(clash)}: given more than once (or also in --set)")
    check_numeric(case_file, params, fixed)
    prob = problem(params)
    X = draw(prob, method, samples, seed)
    points = sample_points(case_file, params, X, fixed)
    table = outdir / SAMPLES_FILE
    done = run_batch(points, outdir, marker=MARKER_FILE, description={
        "case_file": str(case_file), "method": method, "samples": samples, "seed": seed,
        "output": output, "fixed_sets": list(fixed_sets), "problem": prob, "runs": len(points)},
        table=table, param_paths=paths,
        intro=(f"{method}: {len(points)} runs of {case_file} for {len(params)} parameters in "
               f"{outdir / RUNS_DIR}"),
        workers=workers, scheduler=scheduler, echo=echo)
    Y, missing = output_values(done, output)
    if missing:  # no indices; none of an earlier analysis left beside the new samples
        for name in (INDICES_FILE, CHART_FILE):
            (outdir / name).unlink(missing_ok=True)
        return SensitivityResult(done, table, None, missing)
    rows = analyse(prob, method, X, Y, seed)
    return SensitivityResult(done, table, rows, [], write_indices(outdir / INDICES_FILE, method,
                                                                  rows),
                             plot_indices(outdir / CHART_FILE, method, rows, output))
