"""Every shipped case run to its end and compared with its record: the check that no case lost
its convergence or moved its curve, to run before a change lands.

The unit tests run the cases shortened (``tests/test_rig.py``, ``tests/test_regression.py``),
so a regression that shows only past the point where they stop goes unseen (the brick wall
once kept two unconverged steps at U_x = 0.93 mm through many changes: docs/performance.md).
This check runs each case as shipped, in a fresh process, without field
outputs (``output.vtu=false``, ``output.hdf5=false``: the curve does not depend on them), and
judges three things:

* the run exits 0 with every step converged (``summary.json``'s ``unconverged_steps``);
* its curve matches the record: ``ux_mm``, ``fx_kN``, ``uy_mm`` and ``fy_kN`` of
  ``force_displacement.csv`` read at the record's times (linear in ``time_s``), with
  ``|new - record| <= rtol max|record|`` per column (relative to the column's largest
  magnitude, so that the small forces of the gravity stage are not asked for digits the
  solver's tolerance does not give), and the run ends at the record's end time;
* its run time is reported beside the record's, not judged: this machine's speed moves by a
  third within an hour (docs/performance.md).

The verdict of a case (``status`` of ``check.csv``) is judged on the record of its run
(:mod:`masonry_nscd.studies.point`, its status from the process's exit code): ``failed`` when
the run's status is not ``ok`` or it left no summary, then ``unconverged``, ``changed``, ``no
record``, or ``written`` when the record is written; else ``ok``.

The record of a case ``cases/NAME.yaml``: ``RECORD/NAME.csv``, at most ``RECORD_ROWS`` rows of its
curve evenly spaced in the row index, with the rows of the largest |F_x| and the last; and
``RECORD/runs.json``, per case the steps, the run time (s), and the commit and date the record
was written at. ``write=True`` writes them from the runs, and refuses a run that did not
converge every step.
"""

from __future__ import annotations

import json
import math
import subprocess
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import CSV, SUMMARY, read_curve_csv
from masonry_nscd.io.summary_json import read_summary
from masonry_nscd.studies.bench import masonry_command, write_rows
from masonry_nscd.studies.point import RunRecord, status_of_exit

CASES_DIR = Path(__file__).resolve().parents[2] / "cases"
RECORD_DIR = CASES_DIR / "record"
RUNS = "runs.json"
RECORD_ROWS = 200  # rows of a curve kept in its record (count)
CURVE_COLUMNS = ("ux_mm", "fx_kN", "uy_mm", "fy_kN")  # compared (time_s is the abscissa)
DEFAULT_RTOL = 1e-3  # largest change of a column, relative to its largest magnitude
NO_FIELDS = ("output.vtu=false", "output.hdf5=false")


@dataclass
class CaseCheck:
    """One case's line of ``check.csv``."""

    case: str  # the case file's stem
    status: str  # ok, written, changed, unconverged, failed, no record
    run_s: float  # wall clock of the run's process, start-up and any compilation included (s)
    record_run_s: float  # the same when the record was written (s; NaN: no record)
    steps: int
    unconverged_steps: int
    deviation: float  # largest |new - record| / max|record| over the columns (NaN: not compared)
    column: str  # the column of that deviation
    note: str  # why the status, for the ones that are not ok


def shipped_cases(cases_dir: Path = CASES_DIR) -> list[Path]:
    """The case files of ``cases_dir``, sorted by name."""
    return sorted(cases_dir.glob("*.yaml"))


def reduce_curve(curve: dict[str, np.ndarray], rows: int = RECORD_ROWS) -> dict[str, np.ndarray]:
    """``time_s`` and :data:`CURVE_COLUMNS` at most ``rows`` rows evenly spaced in the row
    index, with the first, the last and the one of the largest |F_x|."""
    n = len(curve["time_s"])
    keep = np.unique(np.concatenate([np.linspace(0, n - 1, min(rows, n)).round().astype(int),
                                     [int(np.argmax(np.abs(curve["fx_kN"]))), n - 1]]))
    return {c: curve[c][keep] for c in ("time_s", *CURVE_COLUMNS)}


def curve_deviation(record: dict[str, np.ndarray],
                    curve: dict[str, np.ndarray]) -> tuple[float, str]:
    """The largest ``|curve - record| / max|record|`` over :data:`CURVE_COLUMNS`, the curve
    read at the record's times, and its column (``""`` when every column is the same);
    ``(inf, "time_s")`` when the runs end at different times (one stopped early, or went
    on)."""
    t_rec, t = record["time_s"], curve["time_s"]
    if len(t) == 0 or not math.isclose(t[-1], t_rec[-1], rel_tol=1e-9, abs_tol=1e-12):
        return math.inf, "time_s"
    worst, where = 0.0, ""
    for c in CURVE_COLUMNS:
        scale = float(np.max(np.abs(record[c]), initial=0.0))
        if scale == 0.0:
            continue
        dev = float(np.max(np.abs(np.interp(t_rec, t, curve[c]) - record[c]))) / scale
        if math.isnan(dev):  # worse than any number
            return dev, c
        if dev > worst:
            worst, where = dev, c
    return worst, where


def write_curve(path: Path, curve: dict[str, np.ndarray]) -> None:
    """A reduced curve as CSV, the columns of ``force_displacement.csv``'s names (written
    whole or not at all, as every file of the records)."""
    cols = ("time_s", *CURVE_COLUMNS)
    lines = [",".join(cols)]
    lines += [",".join(f"{curve[c][i]:.10g}" for c in cols) for i in range(len(curve["time_s"]))]
    text = "\n".join(lines) + "\n"
    atomic_write(path, lambda tmp: Path(tmp).write_text(text))


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "-C", str(CASES_DIR.parent), "describe", "--always",
                              "--dirty"], capture_output=True, text=True, check=False)
    except OSError:
        return "unknown"
    return out.stdout.strip() or "unknown"


def log_path(run_dir: Path) -> Path:
    """The log of the process that made ``run_dir``: ``run_dir`` + ``.log`` (not
    ``with_suffix``, which would take ``wall_0.5MPa``'s ``.5MPa`` for a suffix)."""
    return run_dir.with_name(run_dir.name + ".log")


def run_case_process(case: Path, outdir: Path, overrides: Sequence[str]) -> RunRecord:
    """``masonry run CASE -o OUTDIR`` without field outputs, in a fresh process: its record,
    the status of its exit code, the message ``masonry run exited CODE`` and the wall clock of
    the process (s). Its log is :func:`log_path`."""
    argv = [*masonry_command(), "run", str(case), "-o", str(outdir), "--overwrite"]
    for item in (*NO_FIELDS, *overrides):
        argv += ["--set", item]
    t0 = time.perf_counter()
    with open(log_path(outdir), "w") as log:
        code = subprocess.run(argv, stdout=log, stderr=subprocess.STDOUT, check=False).returncode
    return RunRecord(case.stem, status_of_exit(code), f"masonry run exited {code}",
                     seconds=time.perf_counter() - t0, run_dir=str(outdir))


def check_case(case: Path, outdir: Path, record_dir: Path, runs: dict, *, rtol: float,
               write: bool, overrides: Sequence[str], commit: str = "unknown") -> CaseCheck:
    """Run one case and judge it against its record (or write the record, ``write``, with
    ``commit``, the code it was run with)."""
    name = case.stem
    run_dir = outdir / name
    run = run_case_process(case, run_dir, overrides)
    recorded = runs.get(name, {})
    out = CaseCheck(name, "ok", run.seconds, float(recorded.get("run_s", math.nan)), 0, 0,
                    math.nan, "", "")
    if not run.ok or not (run_dir / SUMMARY).exists():
        out.status, out.note = "failed", f"{run.message}: {log_path(run_dir)}"
        return out
    summary = read_summary(run_dir)
    out.steps, out.unconverged_steps = int(summary["steps"]), int(summary["unconverged_steps"])
    curve = read_curve_csv(run_dir / CSV)
    if out.unconverged_steps:
        out.status = "unconverged"
        out.note = (f"{out.unconverged_steps} steps not converged (worst residual "
                    f"{summary['worst_residual']:.3g}): {log_path(run_dir)}")
    if write:
        if out.status == "ok":
            write_curve(record_dir / f"{name}.csv", reduce_curve(curve))
            runs[name] = {"steps": out.steps, "run_s": round(run.seconds, 1),
                          "commit": commit, "date": time.strftime("%Y-%m-%d")}
            out.status = "written"
        else:
            out.note += "; no record written"
        return out
    path = record_dir / f"{name}.csv"
    if not path.exists():
        if out.status == "ok":
            out.status, out.note = "no record", f"{path} missing (--write-record writes it)"
        return out
    out.deviation, out.column = curve_deviation(read_curve_csv(path), curve)
    if not out.deviation <= rtol and out.status == "ok":
        out.status = "changed"
        out.note = (f"{out.column} off by {out.deviation:.3g} of its largest value "
                    f"(rtol {rtol:g})" if out.column != "time_s" else
                    f"ends at t = {curve['time_s'][-1]:.6g} s, the record at another time")
    return out


def check_cases(cases: Sequence[Path], outdir: Path, *, record_dir: Path = RECORD_DIR,
                rtol: float = DEFAULT_RTOL, write: bool = False,
                overrides: Sequence[str] = (),
                echo: Callable[[str], None] = print) -> list[CaseCheck]:
    """Check (or record, ``write``) each case in turn; ``OUTDIR/check.csv`` is written again
    after each, so that an interrupted check keeps the cases done."""
    outdir.mkdir(parents=True, exist_ok=True)
    if write:
        record_dir.mkdir(parents=True, exist_ok=True)
    runs_path = record_dir / RUNS
    runs = json.loads(runs_path.read_text()) if runs_path.exists() else {}
    # the code the runs are made with: read before the first record is written, which would
    # make every later describe say "-dirty"
    commit = _git_commit() if write else "unknown"
    rows: list[CaseCheck] = []
    for i, case in enumerate(cases, 1):
        echo(f"[{i}/{len(cases)}] {case.stem} ...")
        row = check_case(case, outdir, record_dir, runs, rtol=rtol, write=write,
                         overrides=overrides, commit=commit)
        rows.append(row)
        echo("  " + format_row(row))
        write_rows(outdir / "check.csv", rows, [f.name for f in fields(CaseCheck)])
        if write:
            text = json.dumps(runs, indent=1, sort_keys=True) + "\n"
            atomic_write(runs_path, lambda tmp, text=text: Path(tmp).write_text(text))
    return rows


def format_row(r: CaseCheck) -> str:
    """One case in a line: status, times, steps, deviation."""
    rec = f" (record {r.record_run_s:.1f} s)" if math.isfinite(r.record_run_s) else ""
    dev = ("" if math.isnan(r.deviation) else ", the same curve" if r.deviation == 0.0
           else f", largest change {r.deviation:.2g} ({r.column})")
    note = f": {r.note}" if r.note else ""
    return (f"{r.case}: {r.status}, {r.run_s:.1f} s{rec}, {r.steps} steps, "
            f"{r.unconverged_steps} not converged{dev}{note}")


def failing(rows: Sequence[CaseCheck]) -> list[CaseCheck]:
    """The cases that were neither ok nor recorded."""
    return [r for r in rows if r.status not in ("ok", "written")]
