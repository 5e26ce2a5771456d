"""Calibrate one parameter of a case so that the wall has a target initial stiffness (kN/mm).

The stiffness ``k(x)`` of the wall for a parameter value ``x`` (``joint.d_spring`` by default)
is measured on a short run that stops as soon as it is known (a point of the study,
:func:`masonry_nscd.studies.point.run_point` with a ``stop_when``), and
``k(x) = target`` is solved by Brent's method (``scipy.optimize.brentq``) between two bounds
that must bracket the target.

The stiffness measured
----------------------
The secant between two *fixed* force levels ``F_low`` and ``F_high`` (kN), between the first
crossings of each level by ``F_x`` in the horizontal stage, displacements interpolated linearly,
on converged steps only (:func:`masonry_nscd.report.secant_stiffness`). The run's summary uses
10 % and 40 % of the peak force, but the peak is not known before the run is over, and a
calibration run must stop early. So the levels are fixed in advance:

* by default 10 % and 40 % of ``mu N``, with ``N = sigma_N x wall length x thickness`` the
  vertical load and ``mu`` the joints' friction coefficient: ``mu N`` is what the bed joint at
  the base can carry by friction, the natural scale of the wall's strength in shear (the
  study's joints have almost no cohesion, ``d_coh_initial = 0.99944``). When the peak is close
  to ``mu N`` the two definitions agree; otherwise give the levels of a previous run's summary
  (``stiffness_force_low_kN``, ``stiffness_force_high_kN`` of ``summary.json``) with
  ``force_range_kN``. For the study's wall at 0.5 MPa: ``mu N = 0.7 x 138.75 = 97.1 kN``,
  so 9.7 to 38.9 kN.
* a run stops at the first converged step of the horizontal stage whose force exceeds
  ``F_high``.

Outputs (in the calibration folder)
-----------------------------------
* ``runs/NN_<param>_<value>/``: the short runs (CSV, case, log, summary; no VTU, no HDF5);
* ``<case name>_calibrated.yaml``: the case with the parameter set, every default filled in,
  named ``<case name>_calibrated`` (its runs do not overwrite those of the original case);
* ``calibration.json``: target, bounds, force levels, every evaluation, the value found.

Only the monotonic history is calibrated (:func:`check_history`): a case with a cyclic or
tabulated one is refused with a message naming ``loading.horizontal.history``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from masonry_nscd.case import case_to_yaml
from masonry_nscd.case.structures.wall import vertical_force_N
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import CSV, read_curve_csv
from masonry_nscd.report import horizontal_stage_start, secant_stiffness
from masonry_nscd.studies.point import run_point

#: Parameter calibrated by default, and its default bounds (dimensionless).
DEFAULT_PARAM = "joint.d_spring"
DEFAULT_BOUNDS = {"joint.d_spring": (0.80, 0.99)}
#: Default force levels of the stiffness secant, as fractions of mu N.
FORCE_FRACTIONS_OF_MU_N = (0.10, 0.40)


class CalibrationError(ValueError):
    """A calibration that cannot be done with what was asked (exit code 2)."""


@dataclass
class Evaluation:
    """One short run: the parameter value and the stiffness measured (kN/mm, None if not)."""

    value: float
    stiffness_kN_mm: float | None
    ux_low_mm: float | None
    ux_high_mm: float | None
    largest_force_kN: float | None
    steps: int
    seconds: float
    run_dir: str


@dataclass
class Calibration:
    """The result of :func:`calibrate`."""

    param: str
    target_stiffness_kN_mm: float
    bounds: tuple[float, float]
    force_low_kN: float
    force_high_kN: float
    value: float
    stiffness_kN_mm: float
    case_value: float
    evaluations: list[Evaluation] = field(default_factory=list)
    case_file: str = ""

    @property
    def stiffness_at_bounds_kN_mm(self) -> tuple[float | None, float | None]:
        by_value = {e.value: e.stiffness_kN_mm for e in self.evaluations}
        return by_value.get(self.bounds[0]), by_value.get(self.bounds[1])

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["stiffness_at_bounds_kN_mm"] = list(self.stiffness_at_bounds_kN_mm)
        out["runs"] = len(self.evaluations)
        return out


def default_force_range_kN(case) -> tuple[float, float]:
    """10 % and 40 % of ``mu N`` (kN): see the module docstring."""
    mu_n_kN = case.joint.mu * vertical_force_N(case) / 1e3
    if not mu_n_kN > 0.0:
        raise CalibrationError(
            f"no default force range: mu N = {case.joint.mu:g} x "
            f"{vertical_force_N(case) / 1e3:g} kN = 0; give --force-range LOW:HIGH (kN)")
    lo, hi = FORCE_FRACTIONS_OF_MU_N
    return lo * mu_n_kN, hi * mu_n_kN


def check_history(case) -> None:
    """Refuse a case whose horizontal history is not the monotonic push
    (:class:`CalibrationError`, exit code 2): a calibration run stops as soon as ``F_x``
    passes a force level on its way up, which a cycle or a table need not do; the initial
    stiffness is a property of the wall, the same on the first branch of any history, so the
    value found with the monotonic push holds for the cyclic case."""
    hz = case.loading.horizontal
    if hz.history == "none":
        raise CalibrationError(
            "loading.horizontal.history: got 'none' (a ground motion); calibrate measures the "
            "initial stiffness on a monotonic push: calibrate the wall on its rig with a "
            "monotonic case, then use the value in the ground-motion case")
    if hz.history != "monotonic":
        stray = {"cyclic": "amplitudes_m", "table": "file"}[hz.history]
        raise CalibrationError(
            f"loading.horizontal.history: got '{hz.history}'; calibrate measures the initial "
            "stiffness on a monotonic push (its runs stop once F_x passes a force level): "
            "calibrate with --set loading.horizontal.history=monotonic --set "
            f"loading.horizontal.{stray}=null, then use the value in the {hz.history} case")


def parameter_value(case, path: str) -> float:
    """The value of the numeric field ``path`` (``joint.d_spring``) of a case."""
    obj: Any = case
    for part in path.split("."):
        if part not in getattr(type(obj), "model_fields", {}):
            raise CalibrationError(f"{path}: no such field in the case")
        obj = getattr(obj, part)
    if isinstance(obj, bool) or not isinstance(obj, int | float):
        raise CalibrationError(f"{path}: a number is needed to calibrate, the field holds "
                               f"{obj!r}")
    return float(obj)


def stop_above(force_kN: float, start_s: float) -> Callable[[dict[str, list]], bool]:
    """A ``stop_when`` of a run (:func:`masonry_nscd.run.run_case`): True at the first
    converged step of the horizontal stage (``time_s >= start_s``) whose ``fx_kN`` exceeds
    ``force_kN``."""

    def stop(curve: dict[str, list]) -> bool:
        return (curve["time_s"][-1] >= start_s - 1e-12 and bool(curve["converged"][-1])
                and curve["fx_kN"][-1] > force_kN)

    return stop


def stiffness_of_run(run_dir: Path, f_low_kN: float, f_high_kN: float, start_s: float,
                     value: float, steps: int, seconds: float) -> Evaluation:
    """The secant stiffness of a finished short run, read from its CSV."""
    import numpy as np

    c = read_curve_csv(run_dir / CSV)
    i0 = horizontal_stage_start(c, start_s)
    ok = c["converged"][i0:] != 0
    ux, fx = c["ux_mm"][i0:][ok], c["fx_kN"][i0:][ok]
    k, u_lo, u_hi = secant_stiffness(ux, fx, f_low_kN, f_high_kN)
    largest = float(np.max(fx)) if len(fx) else None
    return Evaluation(value, k, u_lo, u_hi, largest, steps, seconds, str(run_dir))


def measure_stiffness(case, run_dir: Path, force_range_kN: tuple[float, float], value: float,
                      echo: Callable[[str], None] | None = None) -> Evaluation:
    """Run ``case`` into ``run_dir`` until ``F_x`` passes the upper force level, and measure
    the secant stiffness between the two levels (kN/mm); a run that fails raises its
    exception (:meth:`~masonry_nscd.studies.point.RunRecord.raise_failure`)."""
    start_s = case.loading.horizontal.start_s
    rec = run_point(case, run_dir, echo=echo or (lambda _m: None),
                    stop_when=stop_above(force_range_kN[1], start_s))
    rec.raise_failure()
    return stiffness_of_run(run_dir, *force_range_kN, start_s, value, rec.steps,
                            rec.loop_seconds)


class _Close(Exception):
    """Raised inside the root finder once the stiffness is within tolerance."""

    def __init__(self, value: float):
        self.value = value


def calibrate(case, load: Callable[[float, bool], Any], param: str, target_kN_mm: float,
              bounds: tuple[float, float], outdir: Path, *,
              force_range_kN: tuple[float, float] | None = None, rtol: float = 1e-3,
              xtol: float | None = None, maxiter: int = 30,
              echo: Callable[[str], None] = print) -> Calibration:
    """Find the value of ``param`` in ``bounds`` that gives ``target_kN_mm``.

    ``case``: the case as given (for the parameter's original value and the default force
    range); ``load(value, for_run)`` returns it with the parameter set to ``value``, and with
    ``for_run`` True as the case of a short run (no VTU/HDF5 output). Stops when the stiffness
    is within ``rtol`` (relative) of the target, or when Brent's bracket is narrower than
    ``xtol`` (default ``1e-6 x (high - low)``). Raises :class:`CalibrationError` when the
    target is not bracketed or a stiffness cannot be measured, and
    :class:`masonry_nscd.run.RunFailure` when a run fails.
    """
    from scipy.optimize import brentq

    lo, hi = bounds
    case_value = parameter_value(case, param)
    f_lo, f_hi = force_range_kN or default_force_range_kN(case)
    if not 0.0 <= f_lo < f_hi:
        raise CalibrationError(f"force range {f_lo:g}:{f_hi:g} kN: 0 <= LOW < HIGH needed")
    for x in bounds:  # an invalid bound (CaseError) is refused before any run
        load(x, True)
    evals: dict[float, Evaluation] = {}

    def stiffness(x: float) -> float:
        if x not in evals:
            run_dir = outdir / "runs" / f"{len(evals):02d}_{param}_{x:.10g}"
            e = measure_stiffness(load(x, True), run_dir, (f_lo, f_hi), x)
            evals[x] = e
            echo(f"  {param} = {x:.8g}: "
                 + (f"{e.stiffness_kN_mm:.6g} kN/mm" if e.stiffness_kN_mm is not None
                    else "no stiffness") + f" ({e.steps} steps, {e.seconds:.1f} s)")
            if e.stiffness_kN_mm is None:
                raise CalibrationError(_unmeasured(param, e, f_lo, f_hi))
        return evals[x].stiffness_kN_mm  # type: ignore[return-value]

    def residual(x: float) -> float:
        r = stiffness(x) - target_kN_mm
        if abs(r) <= rtol * abs(target_kN_mm) and x not in (lo, hi):
            raise _Close(x)
        return r

    k_lo, k_hi = stiffness(lo), stiffness(hi)
    if (k_lo - target_kN_mm) * (k_hi - target_kN_mm) > 0.0:
        raise CalibrationError(
            f"the target {target_kN_mm:g} kN/mm is not between the stiffnesses at the bounds: "
            f"{param} = {lo:g} gives {k_lo:.6g} kN/mm, {param} = {hi:g} gives {k_hi:.6g} "
            "kN/mm; widen --bounds")
    if abs(k_lo - target_kN_mm) <= rtol * abs(target_kN_mm):
        x = lo
    elif abs(k_hi - target_kN_mm) <= rtol * abs(target_kN_mm):
        x = hi
    else:
        try:
            x = brentq(residual, lo, hi, xtol=xtol or 1e-6 * abs(hi - lo), maxiter=maxiter)
        except _Close as close:
            x = close.value
    k = stiffness(x)
    return Calibration(param, target_kN_mm, (lo, hi), f_lo, f_hi, x, k, case_value,
                       list(evals.values()))


def _unmeasured(param: str, e: Evaluation, f_lo: float, f_hi: float) -> str:
    largest = "no converged step" if e.largest_force_kN is None else \
        f"the largest force was {e.largest_force_kN:.4g} kN"
    return (f"{param} = {e.value:g}: the stiffness between {f_lo:.4g} and {f_hi:.4g} kN could "
            f"not be measured ({largest}; the force must start below the lower level and pass "
            f"the upper one in the horizontal stage): change --force-range (see {e.run_dir})")


def write_calibrated_case(case, result: Calibration, path: Path) -> None:
    """Write the calibrated case (every default filled in) with a header saying how."""
    header = (f"# calibrated by `masonry calibrate`: {result.param} = {result.value:.10g} gives "
              f"an initial stiffness of {result.stiffness_kN_mm:.6g} kN/mm\n"
              f"# (target {result.target_stiffness_kN_mm:g} kN/mm; secant between "
              f"{result.force_low_kN:.6g} and {result.force_high_kN:.6g} kN of F_x; value in the "
              f"original case: {result.case_value:.10g})\n")
    text = header + case_to_yaml(case)
    atomic_write(path, lambda p: Path(p).write_text(text))


def write_report(result: Calibration, path: Path) -> None:
    """Write ``calibration.json``."""
    text = json.dumps(result.to_json(), indent=2, allow_nan=False) + "\n"
    atomic_write(path, lambda p: Path(p).write_text(text))


def parse_range(text: str, option: str) -> tuple[float, float]:
    """``"LOW:HIGH"`` -> ``(low, high)``, finite and increasing, else :class:`CalibrationError`."""
    parts = text.split(":")
    try:
        lo, hi = (float(p) for p in parts)
    except ValueError:
        raise CalibrationError(f"{option} must be LOW:HIGH (two numbers), got {text!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise CalibrationError(f"{option} must have finite LOW < HIGH, got {text!r}")
    return lo, hi


def format_result(result: Calibration) -> Sequence[str]:
    """A few lines for the terminal."""
    k_lo, k_hi = result.stiffness_at_bounds_kN_mm
    return [
        (f"{result.param} = {result.value:.8g} gives {result.stiffness_kN_mm:.6g} kN/mm "
         f"(target {result.target_stiffness_kN_mm:g}; value in the case file: "
         f"{result.case_value:.8g})"),
        (f"stiffness at the bounds: {result.param} = {result.bounds[0]:g} -> {k_lo:.6g} kN/mm, "
         f"{result.bounds[1]:g} -> {k_hi:.6g} kN/mm"),
        (f"{len(result.evaluations)} runs; secant between {result.force_low_kN:.4g} and "
         f"{result.force_high_kN:.4g} kN of F_x"),
    ]
