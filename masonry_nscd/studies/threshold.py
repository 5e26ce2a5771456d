"""The value of one case parameter between standing and collapse, by bisection.

``masonry threshold CASE --param PATH --bounds LOW:HIGH`` runs the limit-state case (an arch:
it has a collapse rule, :mod:`masonry_nscd.collapse`) with ``PATH`` at each bound; their
outcomes (``standing`` or ``collapse``, from the run's ``limit.json``) must differ. Then it
bisects: the middle of the bracket takes the side of the bound whose outcome it shares, until
the bracket is narrower than ``rtol`` times its middle (relative) or ``max_runs`` runs are made.
The threshold is the middle of the last bracket, with the bracket as its error bound: the
minimum thickness of an arch (``arch.thickness_m``; standing above, collapsing below), the
critical multiplier of a constant body force (``loading.body_force.multiplier``; standing
below), the settlement an arch takes...

A run's outcome depends on the case's collapse rule: a run stands when it reaches
``collapse.end_time_s`` without its blocks passing ``collapse.displacement_m``; near the
threshold a mechanism starts slowly (with rigid voussoirs the acceleration of the mechanism
grows with the distance to the threshold), so the end time bounds how close to the threshold
a collapse can be seen (docs/choices.md).

This reuses the machinery of :mod:`~masonry_nscd.studies.calibrate`: the parameter read and
checked (:func:`~masonry_nscd.studies.calibrate.parameter_value`), the bounds (``parse_range``),
the case loaded again with the parameter set for each run, its errors (exit code 2), one folder
per run.

Outputs (in the study folder): ``runs/NN_<param>_<value>/`` (each run, without VTU),
``threshold.csv`` (one row per run: ``run, value, status, side``, the loads at the onset of a
collapse, the mechanism and its hinges, steps, seconds, folder) and ``threshold.json`` (the
bracket, the threshold, the runs).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from masonry_nscd.errors import RunFailure
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.limit_files import read_limit
from masonry_nscd.io.summary_json import read_summary
from masonry_nscd.studies.calibrate import CalibrationError, parameter_value, parse_range
from masonry_nscd.studies.point import run_point

__all__ = ["THRESHOLD_COLUMNS", "Threshold", "ThresholdError", "ThresholdRun", "check_case",
           "find_threshold", "format_table", "parameter_value", "parse_range", "write_outputs"]

THRESHOLD_COLUMNS = ["run", "value", "status", "side", "loads_at_onset", "mechanism", "hinges",
                     "steps", "seconds", "run_dir"]


class ThresholdError(CalibrationError):
    """A threshold that cannot be searched with what was asked (exit code 2)."""


@dataclass
class ThresholdRun:
    """One run: the parameter value and what it ended in."""

    run: int
    value: float
    status: str  # collapse | standing
    loads_at_onset: dict[str, float] | None
    mechanism: str | None
    hinges: list[str]
    steps: int
    seconds: float
    run_dir: str
    side: str = ""  # low or high: the bound whose outcome it shares


@dataclass
class Threshold:
    """The result of :func:`find_threshold`."""

    param: str
    bounds: tuple[float, float]
    status_low: str
    status_high: str
    bracket: tuple[float, float]
    value: float
    rtol: float
    case_value: float
    runs: list[ThresholdRun] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["half_width"] = 0.5 * abs(self.bracket[1] - self.bracket[0])
        out["relative_half_width"] = out["half_width"] / abs(self.value) if self.value else None
        return out


def check_case(case) -> None:
    """Refuse a case without a collapse rule (a wall): nothing tells its runs apart."""
    if getattr(case, "limit_state", None) is None:
        raise ThresholdError(
            "the case has no arch:, vault: or assembly: section; threshold runs limit-state cases, whose runs end "
            "in collapse or standing (collapse: section), and a wall has none")


def hinge_names(hinges: Sequence[dict[str, Any]]) -> list[str]:
    """``joint 5 intrados`` or ``body / body`` for each hinge of a summary."""
    return [f"joint {h['joint']} {h.get('side') or ''}".strip() if h.get("joint") is not None
            else " / ".join(h["bodies"]) for h in hinges]


def evaluate(case, run_dir: Path, value: float, number: int,
             echo: Callable[[str], None] | None = None) -> ThresholdRun:
    """Run ``case`` into ``run_dir`` and read what it ended in (a run that fails raises its
    exception, :meth:`~masonry_nscd.studies.point.RunRecord.raise_failure`; RunFailure when it
    ended neither standing nor in a collapse)."""
    rec = run_point(case, run_dir, overwrite=True, echo=echo or (lambda _m: None))
    rec.raise_failure()
    record = read_limit(run_dir) or {}
    status = record.get("status")
    if status not in ("collapse", "standing"):
        raise RunFailure(f"{run_dir}: the run ended with status {status!r}")
    summary = read_summary(run_dir, missing_ok=True) or {}
    collapse = record.get("collapse") or {}
    return ThresholdRun(number, value, status, collapse.get("loads_at_onset"),
                        summary.get("mechanism"), hinge_names(summary.get("hinges") or []),
                        rec.steps, rec.loop_seconds, str(run_dir))


def find_threshold(case, load: Callable[[float], Any], param: str,
                   bounds: tuple[float, float], outdir: Path, *, rtol: float = 2e-3,
                   max_runs: int = 30, echo: Callable[[str], None] = print) -> Threshold:
    """Bisect ``param`` in ``bounds`` for the value between standing and collapse (module
    docstring). ``load(value)`` returns the case of a run with the parameter at ``value``
    (a CaseError for a value the case refuses)."""
    lo, hi = bounds
    case_value = parameter_value(case, param)
    for x in bounds:  # an invalid bound (CaseError) is refused before any run
        load(x)
    runs: list[ThresholdRun] = []

    def run(x: float) -> ThresholdRun:
        number = len(runs)
        run_dir = outdir / "runs" / f"{number:02d}_{param}_{x:.10g}"
        r = evaluate(load(x), run_dir, x, number)
        runs.append(r)
        loads = ", ".join(f"{k} {v:.5g}" for k, v in (r.loads_at_onset or {}).items())
        echo(f"  {param} = {x:.8g}: {r.status}" + (f" ({loads} at the onset)" if loads else "")
             + (f", {r.mechanism}" if r.mechanism and r.mechanism != "none" else "")
             + f" ({r.steps} steps, {r.seconds:.1f} s)")
        return r

    r_lo, r_hi = run(lo), run(hi)
    r_lo.side, r_hi.side = "low", "high"
    if r_lo.status == r_hi.status:
        raise ThresholdError(
            f"--bounds {lo:g}:{hi:g}: {param} = {lo:g} and {param} = {hi:g} both end in "
            f"{r_lo.status}; the threshold is not between them: widen --bounds")
    a, b = lo, hi
    while abs(b - a) > rtol * abs(0.5 * (a + b)) and len(runs) < max_runs:
        mid = 0.5 * (a + b)
        r = run(mid)
        if r.status == r_lo.status:
            a, r.side = mid, "low"
        else:
            b, r.side = mid, "high"
    return Threshold(param, (lo, hi), r_lo.status, r_hi.status, (a, b), 0.5 * (a + b), rtol,
                     case_value, runs)


def _cell(v: Any) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, dict):
        return "; ".join(f"{k}={x!r}" for k, x in v.items())
    if isinstance(v, list):
        return "; ".join(str(x) for x in v)
    return str(v)


def table_rows(result: Threshold) -> list[list[str]]:
    return [[_cell(getattr(r, c)) for c in THRESHOLD_COLUMNS] for r in result.runs]


def write_outputs(result: Threshold, outdir: Path) -> tuple[Path, Path]:
    """Write ``threshold.csv`` and ``threshold.json`` atomically."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(THRESHOLD_COLUMNS)
    w.writerows(table_rows(result))
    paths = (outdir / "threshold.csv", outdir / "threshold.json")
    texts = (buf.getvalue(), json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n")
    for path, text in zip(paths, texts, strict=True):
        atomic_write(path, lambda p, text=text: Path(p).write_text(text))
    return paths


def format_table(result: Threshold) -> list[str]:
    """The runs as a text table, then the threshold."""
    head = ["run", result.param, "status", "loads at the onset", "mechanism", "hinges", "s"]
    rows = [[str(r.run), f"{r.value:.8g}", r.status,
             ", ".join(f"{k} {v:.5g}" for k, v in (r.loads_at_onset or {}).items()),
             r.mechanism or "", ", ".join(r.hinges), f"{r.seconds:.1f}"]
            for r in sorted(result.runs, key=lambda r: r.value)]
    widths = [max(len(x) for x in col) for col in zip(head, *rows, strict=True)]
    lines = ["  ".join(x.ljust(w) for x, w in zip(row, widths, strict=True)).rstrip()
             for row in (head, *rows)]
    a, b = result.bracket
    half = 0.5 * abs(b - a)
    lines.append(f"{result.param} = {result.value:.8g} +- {half:.3g} "
                 f"({100 * half / abs(result.value) if result.value else math.nan:.2g} %): "
                 f"{result.status_low} at {a:.8g}, {result.status_high} at {b:.8g} "
                 f"({len(result.runs)} runs; value in the case file: {result.case_value:.8g})")
    return lines
