"""A test campaign: predict tested walls from their material tests, one run per tested wall.

``masonry campaign TESTS.csv --template CASE.yaml -o OUTDIR`` reads a table of tested walls
(the columns of ``stone_walls/tests.csv``: geometry, rig, material tests, vertical stress and
the measured peaks, drifts and stiffness) and makes, for each row, the template's case with:

Geometry
    The row's wall (L x H x t) in running bond with the template's joint thickness j: the
    number of courses ``round((H + j) / (h_u + j))`` and of units per course
    ``max(2, round((L + j) / (l_u + j)))`` from the mean unit height h_u and length l_u (a range
    ``110-140`` is its mean), then the unit height and length that make the model's wall exactly
    H and L.
Rig
    Shear span H0 over H above 0.75: a cantilever (top beam free to rotate, the displacement
    imposed H0 - H above the wall's top); else the wall fixed at both ends (top beam held
    level, H0 = H / 2).
Loads
    The applied vertical stress (the self-weight comes from gravity and the units' density,
    the tables' 20 kN/m^3), and a monotonic push to 1.5 times the larger measured drift at the
    peak. Cyclic tests run monotonic, compared with the envelope of the measured cycles,
    unless ``cyclic``: then reversed cycles of 0.25, 0.5 and 1 times that target, one each,
    and the energy of the last cycle against ``4 F_max U_max`` beside the measured cycle of
    the nearest amplitude. The push lasts as long as the template's (its target over its
    rate), so a tall push is a faster one.
Materials
    The rules of :mod:`masonry_nscd.materials.rules` (joint and ENDO3D units), the same for
    every row.

Outputs: ``runs/<test>/`` (the usual run folders of a batch, :mod:`~masonry_nscd.studies.batch`,
kept when the same campaign runs again; ``runs.csv`` the batch's own table of them),
``cases/<test>.yaml`` (the cases as run), ``campaign.csv`` (per test: measured and predicted
peak, drift at the peak, initial stiffness and failure class, the relative errors; the
statistics in ``campaign_stats.json``), ``peaks.png`` (predicted against measured peaks) and
``curves/<test>.png`` (the predicted curve over the measured one and its envelopes) and
``curves.png`` (all of them, one panel each).

Definitions. Measured peak: the mean of the two directions' peaks where both are measured.
Initial stiffness: the secant at 15 % of the peak (the tables' definition), of the predicted
curve's first point at or above 0.15 F_max. Relative error: predicted / measured - 1. Failure
class of a run (the tables' synthetic class): 0 shear (diagonal stair-step or sliding without
rocking or toe crushing), 1 flexure (rocking or toe crushing without a diagonal crack),
0.5 hybrid (both).
"""

from __future__ import annotations

import copy
import csv
import json
import math
import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.case import Case, CaseError, case_from_dict, case_to_yaml, read_yaml
from masonry_nscd.case.overrides import apply_override
from masonry_nscd.materials import rules
from masonry_nscd.post.cycles import loop_work
from masonry_nscd.report import first_crossing
from masonry_nscd.studies import batch
from masonry_nscd.studies.batch import Point, SweepError

__all__ = ["CAMPAIGN_MARKER", "TABLE_FILE", "CampaignResult", "campaign_points", "case_for_row",
           "envelope", "failure_class", "read_tests", "run_campaign", "secant_stiffness",
           "statistics_of", "wall_layout"]

CAMPAIGN_MARKER = "campaign.json"
TABLE_FILE = "campaign.csv"
STATS_FILE = "campaign_stats.json"
PEAKS_FILE = "peaks.png"
CURVES_FILE = "curves.png"
#: Shear span over height above which a test is a cantilever.
CANTILEVER_RATIO = 0.75
#: Push to this multiple of the larger measured drift at the peak.
PUSH_FACTOR = 1.5
#: ``--cyclic``: the amplitudes of a cyclic row's reversed cycles, one cycle each, as fractions
#: of its push's target (the largest is the target itself)
CYCLE_FRACTIONS = (0.25, 0.5, 1.0)
#: Within this relative error a prediction "hits".
HIT = 0.15
#: Secant stiffness at this fraction of the peak.
SECANT_FRACTION = 0.15


# ---------------------------------------------------------------------------------------------
# The table of tests
# ---------------------------------------------------------------------------------------------


def number(text: str | None) -> float | None:
    """A cell as a number: empty None, a range ``a-b`` its mean."""
    text = (text or "").strip()
    if not text:
        return None
    if "-" in text[1:]:
        lo, hi = text.split("-", 1) if not text.startswith("-") else (text, "")
        return (float(lo) + float(hi)) / 2.0
    return float(text)


def read_tests(path: Path) -> list[dict[str, str]]:
    """The rows of a test table (a list of column -> text). The columns every row's rules read
    must be there; those whose cells may be empty (the units' and the mortar's strengths, the
    masonry's, the mortar's modulus, the second direction's results) may be absent too."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise SweepError(f"{path}: no tests in the table")
    need = ("test", "H_mm", "L_mm", "t_mm", "H0_mm", "unit_height_mm", "unit_length_mm",
            "masonry_E_compression_MPa", "unit_E_MPa", "sigma0_applied_MPa", "Vmax_pos_kN",
            "drift_at_Vmax_pos_pct")
    missing = [c for c in need if c not in rows[0]]
    if missing:
        raise SweepError(f"{path}: missing columns {', '.join(missing)}")
    return rows


def measured(row: dict[str, str]) -> dict[str, float | None]:
    """The measured peak (mean of both directions where both), the larger drift at a peak (%),
    the mean initial stiffness and the synthetic failure class of a row."""
    peaks = [abs(v) for v in (number(row.get("Vmax_pos_kN")), number(row.get("Vmax_neg_kN")))
             if v is not None]
    drifts = [abs(v) for v in (number(row.get("drift_at_Vmax_pos_pct")),
                               number(row.get("drift_at_Vmax_neg_pct"))) if v is not None]
    stiff = [abs(v) for v in (number(row.get("Kel_pos_kN_mm")), number(row.get("Kel_neg_kN_mm")))
             if v is not None]
    return {"peak_kN": sum(peaks) / len(peaks) if peaks else None,
            "drift_pct": sum(drifts) / len(drifts) if drifts else None,
            "max_drift_pct": max(drifts) if drifts else None,
            "stiffness_kN_mm": sum(stiff) / len(stiff) if stiff else None,
            "failure_class": number(row.get("failure_class"))}


# ---------------------------------------------------------------------------------------------
# One row's case
# ---------------------------------------------------------------------------------------------


def wall_layout(L_mm: float, H_mm: float, unit_length_mm: float, unit_height_mm: float,
                joint_mm: float) -> dict[str, float | int]:
    """Courses, units per course and the unit sizes (mm) of a running-bond wall exactly L x H
    (module docstring)."""
    courses = max(1, round((H_mm + joint_mm) / (unit_height_mm + joint_mm)))
    n = max(2, round((L_mm + joint_mm) / (unit_length_mm + joint_mm)))
    h = (H_mm - (courses - 1) * joint_mm) / courses
    length = (L_mm - (n - 1) * joint_mm) / n
    return {"courses": courses, "units_per_course": n, "unit_height_mm": h,
            "unit_length_mm": length, "half_unit_length_mm": (length - joint_mm) / 2.0}


def dry_joints(row: dict[str, str]) -> bool:
    """Whether a row's wall has dry joints: its ``joints`` column names them dry."""
    return "dry" in (row.get("joints") or "").lower()


def required(row: dict[str, str], column: str, why: str) -> float:
    """A row's number in ``column``; ValueError naming the column and what needs it when the
    cell is empty."""
    value = number(row.get(column))
    if value is None:
        raise ValueError(f"{column} is empty{'' if column in row else ' (no such column)'}: "
                         f"{why}")
    return value


def case_for_row(template: dict[str, Any], row: dict[str, str], cyclic: bool = False
                 ) -> dict[str, Any]:
    """The template's case (a mapping as read from YAML) made into the row's test; with
    ``cyclic``, a cyclic row's push is reversed cycles of ``CYCLE_FRACTIONS`` of its target."""
    d = copy.deepcopy(template)
    name = row["test"].strip()
    H, L, t = number(row["H_mm"]), number(row["L_mm"]), number(row["t_mm"])
    H0 = number(row["H0_mm"])
    wall = d.setdefault("wall", {})
    dry = dry_joints(row)
    if dry:
        wall["joint_thickness_m"] = 0.0  # the units touch
    joint_mm = 1e3 * float(wall.get("joint_thickness_m", 0.010))
    lay = wall_layout(L, H, number(row["unit_length_mm"]), number(row["unit_height_mm"]),
                      joint_mm)
    wall.update({"unit_length_m": lay["unit_length_mm"] * 1e-3,
                 "unit_height_m": lay["unit_height_mm"] * 1e-3, "thickness_m": t * 1e-3,
                 "courses": lay["courses"], "units_per_course": lay["units_per_course"],
                 "bond": "running", "half_unit_length_m": lay["half_unit_length_mm"] * 1e-3})
    wall.pop("pattern", None)
    wall.pop("openings", None)
    sup = d.setdefault("supports", {})
    sup["top_vertical"] = "load"
    if H0 / H > CANTILEVER_RATIO:
        sup["top_rotation"] = "free"
        sup["load_height_m"] = max(0.0, (H0 - H) * 1e-3)
    else:
        sup["top_rotation"] = "fixed"
    E_u = required(row, "unit_E_MPa", "the units' modulus sets their elasticity and the joints'")
    mortar_E = number(row.get("mortar_E_MPa"))
    if dry or not mortar_E:  # the joints' stiffness from the prism: the masonry's modulus needed
        E_m = required(row, "masonry_E_compression_MPa",
                       "the joints' stiffness comes from the masonry's modulus")
    else:
        E_m = number(row.get("masonry_E_compression_MPa"))
    if dry:  # the dry law alone: the template's cohesive numbers do not apply
        d["joint"] = rules.dry_joint_parameters(E_m, E_u, lay["unit_height_mm"])
    else:
        joint = rules.joint_parameters(
            E_m, E_u, lay["unit_height_mm"],
            number(row.get("mortar_fc_MPa")),  # None: the weakest mortars' published values
            mortar_E_MPa=mortar_E, joint_mm=joint_mm)
        d["joint"] = {**{k: v for k, v in d.get("joint", {}).items()
                         if k not in ("regions", "scatter", "K_n_Pa_m", "K_t_Pa_m")}, **joint}
    masonry_fc = number(row.get("masonry_fc_MPa"))
    # the units crush at the masonry's strength where it was measured, else at their own
    unit_fc = number(row.get("unit_fc_MPa")) if masonry_fc else required(
        row, "unit_fc_MPa", "without masonry_fc_MPa the units' ENDO3D strength comes from it")
    units = rules.unit_parameters(unit_fc, E_u, masonry_fc)
    blocks = d.setdefault("blocks", {})
    blocks["density_kg_m3"] = rules.density_kg_m3()
    blocks["E_Pa"], blocks["nu"] = units.pop("E_Pa"), units.pop("nu")
    if blocks.get("material", "endo3d") == "endo3d":
        blocks["endo3d"] = {**blocks.get("endo3d", {}), **units}
    loading = d.setdefault("loading", {})
    loading.setdefault("vertical_stress", {})["value_Pa"] = number(row["sigma0_applied_MPa"]) * 1e6
    hor = loading.setdefault("horizontal", {})
    duration = float(hor.get("target_m", 0.010)) / float(hor.get("rate_m_s", 0.002))
    target = PUSH_FACTOR * measured(row)["max_drift_pct"] / 100.0 * H * 1e-3
    hor.update({"target_m": target, "rate_m_s": target / duration})
    run_cyclic = cyclic and row.get("loading", "").strip().lower() == "cyclic"
    if run_cyclic:
        hor.update({"history": "cyclic", "cycles_per_amplitude": 1,
                    "amplitudes_m": [f * target for f in CYCLE_FRACTIONS]})
    d["name"] = name
    d["description"] = (f"{row.get('reference', '').strip()} {name}: {L:g} x {H:g} x {t:g} mm, "
                        f"H0 {H0:g} mm, {row.get('loading', '').strip().lower()} test run "
                        f"{'cyclic' if run_cyclic else 'monotonic'}, parameters from the "
                        "material tests (masonry_nscd.materials.rules)")
    return d


def campaign_points(tests: Path, template: Path, only: Sequence[str] = (),
                    cyclic: bool = False, overrides: Sequence[str] = ()) -> list[Point]:
    """The validated case of every row (or of the rows ``only``; cyclic rows cyclic with
    ``cyclic``), the template's fields first overridden by ``overrides`` (``--set
    PATH=VALUE``; a field that the row sets is the row's); :class:`SweepError` listing every
    problem."""
    rows = read_tests(tests)
    names = [r["test"].strip() for r in rows]
    unknown = [o for o in only if o not in names]
    if unknown:
        raise SweepError(f"--only: no test {', '.join(unknown)} in {tests} ({', '.join(names)})")
    base = read_yaml(Path(template).read_text())
    try:
        for override in overrides:
            apply_override(base, override, Case)
    except CaseError as exc:
        raise SweepError(exc.messages) from None
    points, problems = [], []
    for row in rows:
        name = row["test"].strip()
        if only and name not in only:
            continue
        try:
            case = case_from_dict(case_for_row(base, row, cyclic),
                                  case_dir=Path(template).parent)
        except CaseError as exc:
            problems += [f"{name}: {m}" for m in exc.messages]
            continue
        except (ValueError, TypeError, KeyError) as exc:
            problems.append(f"{name}: {exc}")
            continue
        points.append(Point(name, {}, case_to_yaml(case)))
    if problems:
        raise SweepError(problems)
    return points


# ---------------------------------------------------------------------------------------------
# Curves and statistics
# ---------------------------------------------------------------------------------------------


def secant_stiffness(u_mm: np.ndarray, f_kN: np.ndarray, fraction: float = SECANT_FRACTION
                     ) -> float | None:
    """Secant stiffness (kN/mm) at the first point where the force reaches ``fraction`` of its
    largest value (:func:`masonry_nscd.report.first_crossing`; the first point itself where the
    curve starts above that level)."""
    u, f = np.asarray(u_mm, float), np.asarray(f_kN, float)
    if len(f) < 2 or not np.max(f) > 0:
        return None
    level = fraction * np.max(f)
    if f[0] >= level:  # the curve starts above the level: its first point
        return float(f[0] / u[0]) if u[0] > 0 else None
    u_at = first_crossing(u, f, level)
    return float(level / u_at) if u_at is not None and u_at > 0 else None


def envelope(u_mm: np.ndarray, f_kN: np.ndarray, sign: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """The envelope of a cyclic curve in one direction: the points where ``sign * u`` passes
    its largest earlier value (the first excursions), as positive numbers. A curve whose
    displacements never decrease is already an envelope (a backbone listed from the largest
    pull to the largest push): its points on the ``sign`` side, from the origin out."""
    u, f = sign * np.asarray(u_mm, float), sign * np.asarray(f_kN, float)
    if len(u) > 1 and np.all(np.diff(sign * u) >= 0):
        side = np.flatnonzero(u > 0)
        order = side[np.argsort(u[side], kind="stable")]
        return u[order], f[order]
    keep, top = [], 0.0
    for k, x in enumerate(u):
        if x > top:
            keep.append(k)
            top = x
    keep = np.asarray(keep, int)
    return u[keep], f[keep]


#: :func:`energy_per_cycle`: a cycle ends where u comes back to zero from below ``-BAND`` times
#: the history's largest ``|u|`` (a measured signal crosses zero many times in its noise)
CYCLE_BAND = 0.02


def energy_per_cycle(u_mm: np.ndarray, f_kN: np.ndarray, band: float = CYCLE_BAND
                     ) -> list[dict[str, float]]:
    """The reversed cycles of a history of top displacement ``u_mm`` and force ``f_kN``, each
    from one upward return of u to zero to the next (a return counts after u went below
    ``-band max|u|``): its amplitude ``U`` (the largest ``|u|``, mm), the work the wall took
    ``E = oint F du`` (trapezoids, kN mm = J), and ``E / (4 F_max U)`` with ``F_max`` its
    largest ``|F|`` (1 for a rigid-plastic loop, 0 for an elastic one). A closed loop encloses
    at most its bounding box, ``4 F_max U``: a stretch of a measured signal that would take
    more is a glitch, not a cycle, and is left out. None for a curve whose displacements never
    decrease (an envelope)."""
    u, f = np.asarray(u_mm, float), np.asarray(f_kN, float)
    if len(u) < 2 or np.all(np.diff(u) >= 0.0):
        return []
    low = -band * float(np.abs(u).max())
    moved = np.flatnonzero(u != 0.0)
    ends = [max(int(moved[0]) - 1, 0)] if len(moved) else [0]  # the last sample at rest
    below = False
    for k in range(len(u)):
        if u[k] < low:
            below = True
        elif below and u[k] >= 0.0:
            ends.append(k)
            below = False
    if ends[-1] != len(u) - 1:
        ends.append(len(u) - 1)
    out = []
    for a, b in pairwise(ends):
        uu, ff = u[a:b + 1], f[a:b + 1]
        U, F = float(np.abs(uu).max()), float(np.abs(ff).max())
        if U <= 0.0 or F <= 0.0 or uu.max() <= 0.0 or uu.min() >= low:
            continue  # not a reversed cycle
        E = loop_work(uu, ff)
        if abs(E) > 4.0 * F * U:
            continue  # more than its bounding box holds: not a closed loop (a glitch)
        out.append({"amplitude_mm": U, "energy_J": E, "ratio": E / (4.0 * F * U)})
    return out


def failure_class(mode: str | None) -> float | None:
    """The synthetic class of a run's failure mode (module docstring); None if unknown."""
    if not mode or mode == "n/a":
        return None
    flexural = any(w in mode for w in ("rocking", "toe crushing"))
    shear = any(w in mode for w in ("diagonal", "sliding"))
    if "diagonal" in mode and flexural:
        return 0.5
    if flexural:
        return 1.0
    return 0.0 if shear else None


def statistics_of(errors: Sequence[float | None], hit: float = HIT) -> dict[str, Any]:
    """Median absolute relative error, mean error, and the count within ``hit``, of the errors
    that are not None."""
    e = [x for x in errors if x is not None and math.isfinite(x)]
    if not e:
        return {"count": 0, "median_abs_error": None, "mean_error": None, "within": 0}
    return {"count": len(e), "median_abs_error": statistics.median(abs(x) for x in e),
            "mean_error": statistics.fmean(e), "within": sum(abs(x) <= hit + 1e-12 for x in e)}


def relative_error(predicted: float | None, meas: float | None) -> float | None:
    if predicted is None or meas is None or meas == 0:
        return None
    return predicted / meas - 1.0


def read_measured_curve(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Top displacement (mm) and force (kN) of a curve file of the tables (four header
    lines: test, reference, names, units)."""
    u, f = [], []
    with open(path, newline="") as fh:
        for k, r in enumerate(csv.reader(fh)):
            if k < 4 or len(r) < 2:
                continue
            try:
                u.append(float(r[0]))
                f.append(float(r[1]))
            except ValueError:
                continue
    return np.asarray(u), np.asarray(f)


# ---------------------------------------------------------------------------------------------
# The campaign
# ---------------------------------------------------------------------------------------------


COLUMNS = ("test", "rig", "sigma0_MPa", "measured_peak_kN", "predicted_peak_kN", "peak_error",
           "measured_peak_push_kN", "predicted_peak_push_kN", "peak_push_error",
           "measured_peak_pull_kN", "predicted_peak_pull_kN", "peak_pull_error",
           "measured_drift_pct", "predicted_drift_pct", "drift_ratio",
           "measured_stiffness_kN_mm", "predicted_stiffness_kN_mm", "stiffness_ratio",
           "measured_class", "predicted_class", "failure_mode_at_peak",
           "predicted_cycle_amplitude_mm", "predicted_cycle_ratio", "measured_cycle_amplitude_mm",
           "measured_cycle_ratio", "status", "run_time_s")


def result_row(row: dict[str, str], point: Point, record: Any,
               measured_curve: tuple[np.ndarray, np.ndarray] | None = None) -> dict[str, Any]:
    """One line of ``campaign.csv``; for a cyclic run, the energy of its last cycle against
    ``4 F_max U_max`` and the measured cycle nearest its amplitude (:func:`energy_per_cycle`).

    The peak in each direction: the push (positive U_x, the table's ``Vmax_pos``) and, for a
    cyclic run, the pull (``Vmax_neg``), both as magnitudes; a monotonic run has no pull."""
    meas = measured(row)
    push, pull = (number(row.get(c)) for c in ("Vmax_pos_kN", "Vmax_neg_kN"))
    case = case_from_dict(read_yaml(point.case_yaml))
    H = case.wall.wall_height_m * 1e3
    out: dict[str, Any] = {"test": point.name,
                           "rig": "cantilever" if case.supports.top_rotation == "free"
                           else "fixed-fixed",
                           "sigma0_MPa": case.loading.vertical_stress.value_Pa / 1e6,
                           "measured_peak_kN": meas["peak_kN"],
                           "measured_peak_push_kN": None if push is None else abs(push),
                           "measured_peak_pull_kN": None if pull is None else abs(pull),
                           "measured_drift_pct": meas["drift_pct"],
                           "measured_stiffness_kN_mm": meas["stiffness_kN_mm"],
                           "measured_class": meas["failure_class"],
                           "status": getattr(record, "status", "not run"),
                           "run_time_s": getattr(record, "seconds", None)}
    if record is not None and record.ok and record.curve:
        u = np.asarray(record.curve["ux_mm"], float)
        f = np.asarray(record.curve["fx_kN"], float)
        k = int(np.argmax(f))
        out["predicted_peak_kN"] = float(f[k])
        out["predicted_drift_pct"] = float(u[k] / H * 100.0)
        out["predicted_stiffness_kN_mm"] = secant_stiffness(u, f)
        mode = record.outputs.get("failure_mode_at_peak")
        mode = mode.get("mode") if isinstance(mode, dict) else mode
        out["failure_mode_at_peak"] = mode
        out["predicted_class"] = failure_class(mode)
        out["peak_error"] = relative_error(out["predicted_peak_kN"], meas["peak_kN"])
        out["predicted_peak_push_kN"] = out["predicted_peak_kN"]
        out["peak_push_error"] = relative_error(out["predicted_peak_kN"],
                                                out["measured_peak_push_kN"])
        if case.loading.horizontal.history == "cyclic" and f.min() < 0.0:
            out["predicted_peak_pull_kN"] = float(-f.min())
            out["peak_pull_error"] = relative_error(out["predicted_peak_pull_kN"],
                                                    out["measured_peak_pull_kN"])
        if meas["drift_pct"]:
            out["drift_ratio"] = out["predicted_drift_pct"] / meas["drift_pct"]
        if meas["stiffness_kN_mm"] and out["predicted_stiffness_kN_mm"]:
            out["stiffness_ratio"] = out["predicted_stiffness_kN_mm"] / meas["stiffness_kN_mm"]
        cycles = energy_per_cycle(u, f) if case.loading.horizontal.history == "cyclic" else []
        if cycles:
            last = cycles[-1]
            out["predicted_cycle_amplitude_mm"] = last["amplitude_mm"]
            out["predicted_cycle_ratio"] = last["ratio"]
            tested = energy_per_cycle(*measured_curve) if measured_curve is not None else []
            if tested:
                near = min(tested, key=lambda c: abs(c["amplitude_mm"] - last["amplitude_mm"]))
                out["measured_cycle_amplitude_mm"] = near["amplitude_mm"]
                out["measured_cycle_ratio"] = near["ratio"]
    return out


def write_rows(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([batch.format_cell(r.get(c)) for c in COLUMNS])


def campaign_statistics(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    peaks = statistics_of([r.get("peak_error") for r in rows])
    drifts = [r.get("drift_ratio") for r in rows if r.get("drift_ratio")]
    stiff = [r.get("stiffness_ratio") for r in rows if r.get("stiffness_ratio")]
    classes = [(r.get("measured_class"), r.get("predicted_class")) for r in rows
               if r.get("predicted_class") is not None and r.get("measured_class") is not None]
    return {"peak": peaks,
            "drift_within_factor_2": sum(0.5 <= x <= 2.0 for x in drifts),
            "stiffness_within_factor_1.5": sum(1 / 1.5 <= x <= 1.5 for x in stiff),
            "class_right": sum(abs(a - b) < 1e-9 for a, b in classes),
            "compared": len(drifts)}


def plot_peaks(rows: Sequence[dict[str, Any]], path: Path) -> Path | None:
    from matplotlib.figure import Figure

    pts = [(r["measured_peak_kN"], r["predicted_peak_kN"], r["test"]) for r in rows
           if r.get("predicted_peak_kN") is not None and r.get("measured_peak_kN")]
    if not pts:
        return None
    fig = Figure(figsize=(5.5, 5.5), layout="constrained")
    ax = fig.subplots()
    top = 1.1 * max(max(a, b) for a, b, _ in pts)
    ax.plot([0, top], [0, top], "k-", lw=0.8)
    ax.plot([0, top], [0, (1 + HIT) * top], "k:", lw=0.8)
    ax.plot([0, top], [0, (1 - HIT) * top], "k:", lw=0.8, label="±15 %")
    for a, b, name in pts:
        ax.plot(a, b, "o", color="C0" if name.startswith("SC") else "C3")
    boxes = [(a - 0.01 * top, b - 0.01 * top, a + 0.01 * top, b + 0.01 * top) for a, b, _ in pts]
    for a, b, name in sorted(pts, key=lambda p: p[1]):
        x, y = _label_place(a, b, len(name), top, boxes)
        ax.annotate(name, (a, b), xytext=(x, y), fontsize=8, va="bottom",
                    arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "0.5"})
    ax.set(xlim=(0, top), ylim=(0, top), xlabel="measured peak (kN)",
           ylabel="predicted peak (kN)", title="Predicted against measured peak")
    ax.legend(loc="upper left")
    fig.savefig(path, dpi=120)
    return path


def _label_place(a: float, b: float, chars: int, top: float,
                 boxes: list[tuple[float, float, float, float]]) -> tuple[float, float]:
    """Where the label of the point ``(a, b)`` goes (its lower left corner, data units): the
    first of the places around the point, nearest first, whose box overlaps none of ``boxes``
    (the points and the labels placed), else the first; its box is added to ``boxes``."""
    w, h, d = 0.0135 * chars * top, 0.03 * top, 0.012 * top
    places = [(a + d, b + d / 2), (a + d, b - h - d / 2), (a - w - d, b + d / 2),
              (a - w - d, b - h - d / 2), (a - w / 2, b + d), (a - w / 2, b - h - d)]
    places += [(x, y + k * h) for k in (1, -1, 2, -2) for x, y in places[:4]]

    def free(x: float, y: float) -> bool:
        return all(x + w <= x0 or x >= x1 or y + h <= y0 or y >= y1 for x0, y0, x1, y1 in boxes)

    x, y = next((p for p in places if free(*p)), places[0])
    boxes.append((x, y, x + w, y + h))
    return x, y


def plot_curve(name: str, record: Any, measured_curve: tuple[np.ndarray, np.ndarray] | None,
               path: Path) -> Path:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 4.2), layout="constrained")
    ax = fig.subplots()
    if measured_curve is not None and len(measured_curve[0]):
        u, f = measured_curve
        ax.plot(u, f, color="0.8", lw=0.6, label="measured")
        for sign, style in ((1.0, "-"), (-1.0, "--")):
            eu, ef = envelope(u, f, sign)
            if len(eu):
                ax.plot(eu, ef, "k" + style, lw=1.2,
                        label="measured envelope, " + ("push" if sign > 0 else "pull, mirrored"))
    if record is not None and record.ok and record.curve:
        ax.plot(record.curve["ux_mm"], record.curve["fx_kN"], "C3-", lw=1.5, label="model")
    ax.set(xlabel="top displacement (mm)", ylabel="horizontal force (kN)", title=name)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    return path


def plot_all_curves(names: Sequence[str], records: Sequence[Any],
                    measured_curves: Sequence[tuple[np.ndarray, np.ndarray] | None],
                    path: Path) -> Path:
    """Every test's predicted curve over its measured envelopes, one panel each."""
    from matplotlib.figure import Figure

    cols = 4
    rows_n = -(-len(names) // cols)
    fig = Figure(figsize=(3.2 * cols, 2.5 * rows_n), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows_n, cols)).ravel()
    for ax, name, rec, meas in zip(axes, names, records, measured_curves, strict=False):
        if meas is not None and len(meas[0]):
            for sign, style in ((1.0, "-"), (-1.0, "--")):
                eu, ef = envelope(*meas, sign)
                if len(eu):
                    ax.plot(eu, ef, "k" + style, lw=1.0)
        if rec is not None and rec.ok and rec.curve:
            ax.plot(rec.curve["ux_mm"], rec.curve["fx_kN"], "C3-", lw=1.3)
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
    for ax in axes[len(names):]:
        ax.set_axis_off()
    fig.supxlabel("top displacement (mm)")
    fig.supylabel("horizontal force (kN): model red, measured envelopes black (pull dashed)")
    fig.savefig(path, dpi=100)
    return path


@dataclass
class CampaignResult:
    """The rows of ``campaign.csv``, its statistics and the files written."""

    rows: list[dict[str, Any]]
    stats: dict[str, Any]
    table: Path


def run_campaign(tests: Path, template: Path, outdir: Path, *, only: Sequence[str] = (),
                 dry_run: bool = False, workers: int | None = None, cyclic: bool = False,
                 overrides: Sequence[str] = (),
                 echo: Callable[[str], None] = print) -> CampaignResult:
    """Validate every row's case, write them to OUTDIR/cases, then (unless ``dry_run``) run
    them and write the comparison (module docstring; cyclic rows cyclic with ``cyclic``; the
    template's fields overridden by ``overrides``, ``campaign_points``)."""
    points = campaign_points(tests, template, only, cyclic, overrides)
    rows = {r["test"].strip(): r for r in read_tests(tests)}
    outdir = Path(outdir)
    description = {"tests": str(tests), "template": str(template), "set": list(overrides),
                   "runs": [p.name for p in points]}
    if not dry_run:
        batch.prepare_outdir(outdir, CAMPAIGN_MARKER, description)
    (outdir / "cases").mkdir(parents=True, exist_ok=True)
    for p in points:
        (outdir / "cases" / f"{p.name}.yaml").write_text(p.case_yaml)
    echo(f"{len(points)} cases written and validated in {outdir / 'cases'}")
    table = outdir / TABLE_FILE
    if dry_run:
        out = [result_row(rows[p.name], p, None) for p in points]
        write_rows(table, out)
        return CampaignResult(out, {}, table)
    records = batch.run_batch(points, outdir, marker=CAMPAIGN_MARKER, description=description,
                              table=outdir / "runs.csv", param_paths=[],
                              intro=f"{len(points)} tested walls in {outdir / batch.RUNS_DIR}",
                              workers=workers, keep_curve=True, echo=echo)
    curves = []
    for p in points:
        curve_file = rows[p.name].get("curve", "").strip()
        path = Path(tests).parent / curve_file if curve_file else None
        curves.append(read_measured_curve(path) if path is not None and path.is_file() else None)
    out = [result_row(rows[p.name], p, r, c)
           for p, r, c in zip(points, records, curves, strict=True)]
    write_rows(table, out)
    stats = campaign_statistics(out)
    (outdir / STATS_FILE).write_text(json.dumps(stats, indent=2) + "\n")
    try:
        plot_peaks(out, outdir / PEAKS_FILE)
        (outdir / "curves").mkdir(exist_ok=True)
        for p, r, meas in zip(points, records, curves, strict=True):
            plot_curve(p.name, r, meas, outdir / "curves" / f"{p.name}.png")
        plot_all_curves([p.name for p in points], records, curves, outdir / CURVES_FILE)
    except (OSError, ValueError) as exc:  # the table is written: a figure must not lose it
        echo(f"no figure: {type(exc).__name__}: {exc}")
    return CampaignResult(out, stats, table)
