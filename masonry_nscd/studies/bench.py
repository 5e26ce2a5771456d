"""Benchmarks: run time against error, scaling with the size of the wall, start-up time.

Run time against error (:func:`bench`, ``masonry bench CASE.yaml``)
-------------------------------------------------------------------
A *ladder* of settings around the case's own (:func:`ladder`): the time step, the loading rate,
the solver tolerance, the mesh density per unit (``wall.elements_per_unit``), the other contact
solver where the case allows it, and rigid blocks for an elastic case. Each setting is the case
with a few ``--set`` overrides. Every setting is compared with a *reference* run of the same case,
refined: half the time step and a tolerance ten times tighter (:data:`REFERENCE_TIME_STEP_FACTOR`,
:data:`REFERENCE_TOLERANCE_FACTOR`), the same mesh, rate and solver.

Errors, all relative to the reference (dimensionless; :func:`curve_errors`), on the converged
steps of the horizontal stage (as in :mod:`masonry_nscd.report`) up to the target displacement,
the row at the target interpolated (:func:`clip_at_target`):

* ``err_peak_force``: ``|P - P_ref| / |P_ref|`` of the peak force;
* ``err_initial_stiffness``: the same for the 10-40 % secant stiffness of the summary;
* ``err_force_at_target``: the same for the force at the target displacement;
* ``err_rms_curve``: the relative L2 difference of the F-U curves over ``0 <= U <= target``,
  both interpolated linearly on a common uniform grid of :data:`RMS_GRID_POINTS` values of U:
  ``sqrt(mean((F - F_ref)^2)) / sqrt(mean(F_ref^2))`` (:func:`curve_rms_error`);
* ``err_max``: the largest of the four, the error of the setting on the chart.

Cyclic cases (``loading.horizontal.history: cyclic``) have no target and a curve that turns
back, so the errors are read on the cycles of each run (:func:`cyclic_errors`, the cycles and
the envelope of :mod:`masonry_nscd.post.cycles` from the run folder's ``scene.json``):

* ``err_peak_force``: the larger of the relative errors of the peak forces of the envelope in
  the two directions;
* ``err_initial_stiffness``: as above, on the first loading branch (the summary's definition);
* ``err_envelope``: the relative RMS difference of the envelope forces, the points of both
  directions matched by direction and amplitude,
  ``sqrt(mean((F - F_ref)^2)) / sqrt(mean(F_ref^2))``;
* ``err_energy``: the relative error of the work summed over the cycles (J);
* ``err_max``: the largest of these four (``err_force_at_target`` and ``err_rms_curve`` stay
  empty; for a monotonic case ``err_envelope`` and ``err_energy`` do).

A tabulated history (``table``) is refused (exit code 2, naming
``loading.horizontal.history``): a table need not have cycles nor a target, and no error
measure fits every table.

The reference has the case's mesh: the errors measure the time integration and the solver, not
the mesh. The mesh rungs show how far a coarser or finer mesh per unit moves the curve (the mesh
is part of the model: the study prescribes 2 x 2 x 1 hexahedra per unit).

Timing. Every run is made in a fresh subprocess (``python -m masonry_nscd.studies.bench
SPEC.json``), so that its time and memory are its own; the numba cache is warmed first by tiny
runs of the same solvers and materials. Per run: ``run_s``, the wall-clock time of
:func:`masonry_nscd.run.run_case` (scene build, steps, outputs of the case, summary; not the
interpreter's start-up); ``process_s``, the whole subprocess including start-up;
``step_ms_median``, the median wall-clock time of one ``Integrator.step`` (the solver alone,
timed by wrapping the method in the child process); ``peak_rss_MiB``, the child's peak resident
memory (``resource.getrusage``). A setting whose first run takes less than ``cheap_s`` is run
``repeats`` times and its times are medians (the ``repeats`` column says how many). The Pareto
front (:func:`pareto_front`) is the set of settings that no other setting beats in both run
time and ``err_max``; the reference is not on the chart (its error is 0 by construction).
A run still going after ``time_limit_s`` is stopped (status ``timeout``); the reference, which
makes twice the steps of the default with a tighter tolerance and without which no error can be
measured, gets ``REFERENCE_TIME_FACTOR`` times that limit.

The reference's own error (``check_reference``): half the step need not be converged to the
errors it measures. Where the curve has events (a crack, a crushing toe) whose position moves
with the step, a force read near one can move by as much at every halving (docs/performance.md).
For an error of first order in h, the reference's own error against a run of h/4 is a third of
the setting's. A second reference with half the reference's step (:func:`reference_check_setting`)
tells. Each setting's largest error against it is ``err_max_check``, and the reference's own is
that of its row. When the reference's is half the default's ``err_max`` or more, the errors
against the reference understate the default's, and :func:`verdict` says so.

Scaling (:func:`bench_scaling`, ``masonry bench-scaling CASE.yaml``)
--------------------------------------------------------------------
Walls with about 1, 2, 4 and 8 times the units of the case (courses and units per course
doubled in turn; up to 256 times with ``largest``), each built and stepped ``steps`` times in a
fresh subprocess, or fewer where the case ends first (its target displacement or time limit,
the stop rule of ``masonry run``), under a time and an address-space limit when given: build
time, the time per step as the mean over every step (the first, hard ones included: a run's
time over its steps) and as the median over the steps after the first few, factorisations and
Krylov iterations per step, peak memory, against the number of contact points; each step's
time, iterations and factorisations in ``scaling_steps.csv``. A one-unit wall stepped the same way gives the baseline (interpreter,
libraries, compiled kernels); the growth of memory is the log-log slope of the increments above
that baseline against the number of contact points (1: linear).

Start-up (:func:`startup_figures`, ``masonry bench --startup``)
---------------------------------------------------------------
``masonry --help`` (median of 5) and ``masonry run cases/smoke.yaml`` (median of 3, after one
untimed run that warms the caches), each timed as a subprocess from launch to exit.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from masonry_nscd import timing
from masonry_nscd.case import load_case
from masonry_nscd.figure_files import save_png
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import CSV, SCENE, read_curve_csv, read_scene_info
from masonry_nscd.report import (
    curve_summary,
    horizontal_stage_start,
    push_stage_start,
    run_cycles,
    scene_history,
)
from masonry_nscd.scenes import build_scene
from masonry_nscd.studies.point import ERROR, FAILED, as_error, run_point

FloatArray = NDArray[np.float64]

#: The reference run: time step times this factor...
REFERENCE_TIME_STEP_FACTOR = 0.5
#: ... and the solver tolerance times this one (same mesh, loading rate and solver).
REFERENCE_TOLERANCE_FACTOR = 0.1
#: NLGS tolerance of the anchor, the reference NSCD code the project is compared with
#: (dimensionless).
ANCHOR_NLGS_TOLERANCE = 1e-5
#: Points of the uniform U grid on which the RMS difference of two curves is taken.
RMS_GRID_POINTS = 401
#: A run shorter than this (s) is repeated (``repeats`` times in all), else run once.
CHEAP_S = 30.0
#: The reference run's time limit, in units of the others' (``time_limit_s``).
REFERENCE_TIME_FACTOR = 4.0
#: Errors below this are drawn at this value on the log scale of the chart.
ERROR_FLOOR = 1e-7
#: The limit on the errors of the default settings (relative).
DEFAULT_ERROR_LIMIT = 0.02
#: A log-log slope of memory increments against contact points up to this counts as linear.
LINEAR_SLOPE_LIMIT = 1.1
#: Start-up targets: ``masonry --help`` and a run of the smoke case (s).
HELP_TARGET_S = 0.5
SMOKE_TARGET_S = 10.0
SMOKE_CASE = Path(__file__).resolve().parents[2] / "cases" / "smoke.yaml"


# ---------------------------------------------------------------------------------------------
# The ladder of settings
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Setting:
    """One rung of the ladder: the case with ``overrides`` (``--set`` syntax)."""

    name: str
    group: str  # default, reference, time_step, rate, tolerance, mesh, method, model
    description: str
    overrides: tuple[str, ...] = ()


def allowed_methods(case) -> tuple[str, ...]:
    """Contact solvers the case can use: ENDO3D blocks need Newton; any other case takes
    both."""
    if case.blocks.material == "endo3d":
        return ("newton",)
    return ("newton", "nlgs")


def reference_setting(case, check: bool = False) -> Setting:
    """The refined run every setting is compared with (see the module docstring); ``check``:
    the reference's own reference, its time step halved again (the same tolerance)."""
    f = REFERENCE_TIME_STEP_FACTOR ** (2 if check else 1)
    h = case.solver.time_step_s * f
    tol = case.solver.tolerance * REFERENCE_TOLERANCE_FACTOR
    return Setting("reference_check" if check else "reference", "reference",
                   f"time step x{f:g} ({h:.3g} s), tolerance "
                   f"x{REFERENCE_TOLERANCE_FACTOR:g} ({tol:.3g})",
                   (f"solver.time_step_s={h!r}", f"solver.tolerance={tol!r}",
                    "solver.max_time_step_s=null"))


def reference_check_setting(case) -> Setting:
    """The run that measures the reference's own error (module docstring)."""
    return reference_setting(case, check=True)


def _scaled(name: str, group: str, what: str, path: str, base: float, factor: float,
            unit: str) -> Setting:
    value = base * factor
    return Setting(name, group, f"{what} x{factor:g} ({value:.3g}{unit})", (f"{path}={value!r}",))


def _time_step(h: float, factor: float, max_h: float | None) -> Setting:
    """The time step times ``factor``; with an adaptive step size its largest step too, so
    that the rung keeps the case's ratio of the two (``max_h`` None: every step of h)."""
    rung = _scaled(f"time_step_x{factor:g}", "time_step", "time step", "solver.time_step_s", h,
                   factor, " s")
    if max_h is None:
        return rung
    return Setting(rung.name, rung.group,
                   f"{rung.description}, adaptive up to {max_h * factor:.3g} s",
                   (*rung.overrides, f"solver.max_time_step_s={max_h * factor!r}"))


def _mesh(divisions: Sequence[int]) -> Setting:
    text = "x".join(str(d) for d in divisions)
    return Setting(f"mesh_{text}", "mesh", f"{text} hexahedra per unit",
                   (f"wall.elements_per_unit=[{','.join(str(d) for d in divisions)}]",))


def mesh_neighbours(divisions: Sequence[int]) -> list[tuple[int, int, int]]:
    """A coarser (halved along length and height, when possible) and a finer (one more along
    length and height) mesh per unit than ``divisions``."""
    nx, ny, nz = (int(d) for d in divisions)
    out = []
    coarse = (max(1, nx // 2), max(1, ny // 2), nz)
    if coarse != (nx, ny, nz):
        out.append(coarse)
    if nx < 8 and ny < 8:
        out.append((nx + 1, ny + 1, nz))
    return out


def ladder(case, quick: bool = False) -> list[Setting]:
    """The settings to run, the case's own (``default``) first; the reference is apart.

    ``quick``: a few cheap rungs (time step x2, rate x2, tolerance x100, one mesh), no second
    solver (NLGS can be slower by orders of magnitude at the same tolerance).
    """
    s, hz = case.solver, case.loading.horizontal
    h, tol, rate = s.time_step_s, s.tolerance, hz.rate_m_s
    out = [Setting("default", "default", "the case's own settings")]
    steps = (2.0,) if quick else (0.5, 2.0, 4.0)
    out += [_time_step(h, f, s.max_time_step_s) for f in steps]
    if s.max_time_step_s is not None:  # the adaptive step size against every step at h
        out.append(Setting("fixed_step", "time_step", f"every step {h:.3g} s (not adaptive)",
                           ("solver.max_time_step_s=null",)))
    elif not quick:
        out.append(Setting("adaptive_x8", "time_step", f"adaptive steps up to {8 * h:.3g} s",
                           (f"solver.max_time_step_s={8 * h!r}",)))
    rates = (2.0,) if quick else (0.5, 2.0, 5.0)
    if hz.history == "cyclic":  # a faster rate must leave every reversal its ramp
        rates = tuple(f for f in rates if min(hz.amplitudes_m) >= f * rate * hz.ramp_s)
    out += [_scaled(f"rate_x{f:g}", "rate", "loading rate", "loading.horizontal.rate_m_s",
                    rate, f, " m/s") for f in rates]
    tols = (100.0,) if quick else (10.0, 100.0, 1000.0)
    out += [_scaled(f"tolerance_x{f:g}", "tolerance", "tolerance", "solver.tolerance", tol, f,
                    "") for f in tols if tol * f < 0.1]
    meshes = mesh_neighbours(case.wall.elements_per_unit)
    out += [_mesh(m) for m in (meshes[:1] if quick else meshes)]
    if not quick:
        out += _method_settings(case)
        if case.blocks.material == "elastic":
            out.append(Setting("rigid", "model", "rigid blocks", ("blocks.material=rigid",)))
    return out


def _method_settings(case) -> list[Setting]:
    """The other contact solver at the case's tolerance, and NLGS at the anchor's tolerance."""
    out = []
    tol = case.solver.tolerance
    for m in allowed_methods(case):
        if m != case.contact_solver:
            out.append(Setting(m, "method", f"solver {m} (tolerance {tol:.3g})",
                               (f"solver.method={m}",)))
    if "nlgs" in allowed_methods(case) and not math.isclose(tol, ANCHOR_NLGS_TOLERANCE):
        out.append(Setting(f"nlgs_tol_{ANCHOR_NLGS_TOLERANCE:g}", "method",
                           f"solver nlgs, tolerance {ANCHOR_NLGS_TOLERANCE:g} (the anchor's)",
                           ("solver.method=nlgs", f"solver.tolerance={ANCHOR_NLGS_TOLERANCE!r}")))
    return out


# ---------------------------------------------------------------------------------------------
# Errors against the reference
# ---------------------------------------------------------------------------------------------


def horizontal_curve(curve: Mapping[str, Sequence[float]],
                     start_s: float | None = None) -> tuple[FloatArray, FloatArray]:
    """``(ux_mm, fx_kN)`` of the converged rows of the horizontal stage, ``ux`` strictly
    increasing (of rows with the same ``ux`` the last one is kept). When the first row of the
    stage has already moved, the row before it (the state at ``U = 0``) is kept too."""
    i0 = horizontal_stage_start(curve, start_s)
    if 0 < i0 < len(curve["ux_mm"]) and curve["ux_mm"][i0] > 0.0:
        i0 -= 1
    ux = np.asarray(curve["ux_mm"], dtype=float)[i0:]
    fx = np.asarray(curve["fx_kN"], dtype=float)[i0:]
    if "converged" in curve:
        ok = np.asarray(curve["converged"], dtype=float)[i0:] != 0
        ux, fx = ux[ok], fx[ok]
    keep = np.ones(len(ux), dtype=bool)
    if len(ux) > 1:
        keep[:-1] = ux[1:] > ux[:-1]  # the last of a run of equal values
        keep &= ux >= np.maximum.accumulate(ux)  # drop any step back
    return ux[keep], fx[keep]


def clip_at_target(curve: Mapping[str, Sequence[float]],
                   target_mm: float) -> dict[str, FloatArray]:
    """The rows of ``curve`` up to ``ux_mm = target_mm``: those below it, and one row
    interpolated linearly at exactly the target between the rows around the first crossing
    (``converged`` there is the smaller of the two). A run stops at the first step at or past
    the target, so without this the peak of a curve still rising at the end would depend on
    how far the last step overshoots."""
    c = {k: np.asarray(v, dtype=float) for k, v in curve.items()}
    ux = c["ux_mm"]
    reached = np.flatnonzero(ux >= target_mm)
    if not reached.size:
        return c
    i = int(reached[0])
    if i == 0 or ux[i] == target_mm:
        return {k: v[:i + 1] for k, v in c.items()}
    w = (target_mm - ux[i - 1]) / (ux[i] - ux[i - 1])
    last = {k: v[i - 1] + w * (v[i] - v[i - 1]) for k, v in c.items()}
    if "converged" in c:
        last["converged"] = min(c["converged"][i - 1], c["converged"][i])
    last["ux_mm"] = target_mm
    return {k: np.append(v[:i], last[k]) for k, v in c.items()}


def relative_error(value: float | None, ref: float | None) -> float:
    """``|value - ref| / |ref|`` (dimensionless); NaN when either is missing or ``ref`` is 0."""
    if value is None or ref is None or not math.isfinite(value) or not math.isfinite(ref) \
            or ref == 0.0:
        return math.nan
    return abs(value - ref) / abs(ref)


def curve_rms_error(ux_mm: Sequence[float], fx_kN: Sequence[float], ux_ref_mm: Sequence[float],
                    fx_ref_kN: Sequence[float], target_mm: float,
                    points: int = RMS_GRID_POINTS) -> float:
    """Relative RMS difference of two F-U curves over ``0 <= U <= target_mm`` (dimensionless).

    Both curves (``ux`` in mm increasing, ``fx`` in kN) are interpolated linearly on a uniform
    grid of ``points`` values of U from 0 to ``target_mm``; the result is
    ``sqrt(mean((F - F_ref)^2)) / sqrt(mean(F_ref^2))``. NaN when a curve does not cover the
    grid (a run stopped short) or the reference is zero on it.
    """
    grid = np.linspace(0.0, target_mm, points)
    curves = [(np.asarray(u, dtype=float), np.asarray(f, dtype=float))
              for u, f in ((ux_mm, fx_kN), (ux_ref_mm, fx_ref_kN))]
    if any(len(u) < 2 or u[0] > 1e-9 * max(1.0, target_mm) or u[-1] < target_mm * (1 - 1e-9)
           for u, _ in curves):
        return math.nan
    f, f_ref = (np.interp(grid, u, fv) for u, fv in curves)
    scale = math.sqrt(float(np.mean(f_ref ** 2)))
    if scale == 0.0:
        return math.nan
    return math.sqrt(float(np.mean((f - f_ref) ** 2))) / scale


ERROR_COLUMNS = ("err_peak_force", "err_initial_stiffness", "err_force_at_target",
                 "err_rms_curve")
#: The errors of a cyclic case (module docstring).
CYCLIC_ERROR_COLUMNS = ("err_peak_force", "err_initial_stiffness", "err_envelope",
                        "err_energy")


def check_history(case) -> None:
    """Refuse a tabulated history and a ground motion (ValueError naming the field; the CLI
    exits with 2)."""
    hz = case.loading.horizontal
    if hz.history == "table":
        raise ValueError(
            "loading.horizontal.history: got 'table'; masonry bench measures errors on a "
            "monotonic push to its target or on the cycles of a cyclic history, and a table "
            "need have neither: benchmark the case with a monotonic or cyclic history")
    if hz.history == "none":
        raise ValueError(
            "loading.horizontal.history: got 'none' (a ground motion); masonry bench measures "
            "errors on a monotonic push or on cycles: benchmark the wall with a monotonic or "
            "cyclic history")


def error_columns(rows: Sequence[BenchRow]) -> tuple[str, ...]:
    """The error columns of the rows' case: cyclic when the rows say so."""
    cyclic = any(math.isfinite(r.err_envelope) for r in rows)
    return CYCLIC_ERROR_COLUMNS if cyclic else ERROR_COLUMNS


def cyclic_metrics(curve: Mapping[str, Sequence[float]],
                   scene: Mapping[str, Any]) -> dict[str, Any]:
    """Peak forces of the envelope in both directions (kN), the first-branch stiffness
    (kN/mm), the envelope rows and the work summed over the cycles (J) of a cyclic run, with
    the number of cycles completed and planned."""
    rows, env = run_cycles(curve, scene)
    s = curve_summary(curve, horizontal_start_s=push_stage_start(scene), first_branch=True)
    pos = [e["fx_kN"] for e in env if e["direction"] == "positive"]
    neg = [e["fx_kN"] for e in env if e["direction"] == "negative"]
    return {"peak_pos_kN": max(pos) if pos else None, "peak_neg_kN": min(neg) if neg else None,
            "initial_stiffness_kN_mm": s["initial_stiffness_kN_mm"], "envelope": env,
            "energy_J": sum(r["dissipated_energy_J"] for r in rows) if rows else None,
            "cycles": len(rows), "planned": len(scene_history(scene).get("cycles") or [])}


def cyclic_errors(curve: Mapping[str, Sequence[float]], scene: Mapping[str, Any],
                  ref: Mapping[str, Sequence[float]],
                  ref_scene: Mapping[str, Any]) -> dict[str, float]:
    """The four errors of a cyclic run against the reference and ``err_max`` (module
    docstring); NaN where either run did not complete its cycles."""
    m, r = cyclic_metrics(curve, scene), cyclic_metrics(ref, ref_scene)
    nan = math.nan
    if m["cycles"] != m["planned"] or r["cycles"] != r["planned"] or not m["cycles"]:
        out = dict.fromkeys(CYCLIC_ERROR_COLUMNS, nan)
        out["err_initial_stiffness"] = relative_error(m["initial_stiffness_kN_mm"],
                                                      r["initial_stiffness_kN_mm"])
        out["err_max"] = nan
        return out
    key = {(e["direction"], e["amplitude_mm"]): e["fx_kN"] for e in r["envelope"]}
    pairs = [(e["fx_kN"], key.get((e["direction"], e["amplitude_mm"]))) for e in m["envelope"]]
    env_err = nan
    if pairs and all(b is not None for _, b in pairs):
        f, f_ref = np.array(pairs, dtype=float).T
        scale = math.sqrt(float(np.mean(f_ref ** 2)))
        env_err = math.sqrt(float(np.mean((f - f_ref) ** 2))) / scale if scale else nan
    out = {
        "err_peak_force": max(relative_error(m["peak_pos_kN"], r["peak_pos_kN"]),
                              relative_error(m["peak_neg_kN"], r["peak_neg_kN"])),
        "err_initial_stiffness": relative_error(m["initial_stiffness_kN_mm"],
                                                r["initial_stiffness_kN_mm"]),
        "err_envelope": env_err,
        "err_energy": relative_error(m["energy_J"], r["energy_J"]),
    }
    values = list(out.values())
    out["err_max"] = nan if any(math.isnan(v) for v in values) else max(values)
    return out


def curve_metrics(curve: Mapping[str, Sequence[float]], target_mm: float,
                  start_s: float | None) -> dict[str, float | None]:
    """Peak force (kN), initial stiffness (kN/mm) and force at the target (kN) of a curve up to
    the target (:func:`clip_at_target`), as in :func:`masonry_nscd.report.curve_summary`."""
    s = curve_summary(clip_at_target(curve, target_mm), target_ux_mm=target_mm,
                      horizontal_start_s=start_s)
    return {k: s[k] for k in ("peak_force_kN", "initial_stiffness_kN_mm", "force_at_target_kN")}


def curve_errors(curve: Mapping[str, Sequence[float]], ref: Mapping[str, Sequence[float]],
                 target_mm: float, start_s: float | None = None) -> dict[str, float]:
    """The four relative errors of ``curve`` against ``ref`` and their largest, ``err_max``
    (see the module docstring). ``target_mm``: the target displacement (mm); ``start_s``: the
    start of the horizontal stage (s)."""
    m, r = curve_metrics(curve, target_mm, start_s), curve_metrics(ref, target_mm, start_s)
    out = {
        "err_peak_force": relative_error(m["peak_force_kN"], r["peak_force_kN"]),
        "err_initial_stiffness": relative_error(m["initial_stiffness_kN_mm"],
                                                r["initial_stiffness_kN_mm"]),
        "err_force_at_target": relative_error(m["force_at_target_kN"], r["force_at_target_kN"]),
        "err_rms_curve": curve_rms_error(*horizontal_curve(curve, start_s),
                                         *horizontal_curve(ref, start_s), target_mm),
    }
    values = list(out.values())
    out["err_max"] = math.nan if any(math.isnan(v) for v in values) else max(values)
    return out


# ---------------------------------------------------------------------------------------------
# Pareto front
# ---------------------------------------------------------------------------------------------


def pareto_front(times: Sequence[float], errors: Sequence[float]) -> NDArray[np.bool_]:
    """Which points no other point beats in both (smaller or equal in both, smaller in one).

    Points with a NaN time or error are never on the front (nor do they beat any other).
    """
    t, e = np.asarray(times, dtype=float), np.asarray(errors, dtype=float)
    valid = np.isfinite(t) & np.isfinite(e)
    front = valid.copy()
    for i in np.flatnonzero(valid):
        beaten = valid & (t <= t[i]) & (e <= e[i]) & ((t < t[i]) | (e < e[i]))
        front[i] = not beaten.any()
    return front


# ---------------------------------------------------------------------------------------------
# Child processes
# ---------------------------------------------------------------------------------------------


def _child_run(spec: Mapping[str, Any]) -> dict[str, Any]:
    """One run of a case to its target (``kind: run``), every step timed, as a point of the
    study (:func:`~masonry_nscd.studies.point.run_point`); see :func:`run_in_child`."""
    case = load_case(spec["case"], spec["overrides"])
    rec = run_point(case, Path(spec["outdir"]), overwrite=True,
                    time_limit_s=float(spec["time_limit_s"]), time_steps=True)
    status, message = as_error(rec)
    if status == ERROR:  # the child's outcome, as for an exception outside the run
        return {"status": status, "message": message}
    out: dict[str, Any] = {"status": status, "message": message}
    if rec.contact_points is not None:
        out.update(contact_points=rec.contact_points, dofs=rec.dofs)
    durations = rec.step_seconds or []
    if status == FAILED:
        out["steps"] = len(durations)  # the one that failed included
    else:
        out.update(steps=rec.steps, unconverged_steps=rec.unconverged_steps)
    out["run_s"] = rec.seconds
    out["solver_s"] = float(sum(durations))
    out["step_ms_median"] = 1e3 * statistics.median(durations) if durations else math.nan
    return out


def _child_steps(spec: Mapping[str, Any]) -> dict[str, Any]:
    """Build a wall and step it ``steps`` times (``kind: steps``); see :func:`run_in_child`.

    With ``time_limit_s``, no step starts after that many seconds from the start of the build
    (status ``timeout``, the steps made so far reported). The result so far is written to
    ``result`` after the build and after every step, so that a parent that has to kill a step
    that never ends still reads the build time and the steps before it."""
    case = load_case(spec["case"], spec["overrides"])
    limit = spec.get("time_limit_s")
    t0 = time.perf_counter()
    scene = build_scene(case)
    scene_s = time.perf_counter() - t0
    integ = scene.integrator()
    build_s = time.perf_counter() - t0
    timing.reset()  # the steps' parts only
    (mx, wx), _ = scene.measured_dofs(integ.sys.body_dof0)
    out: dict[str, Any] = {
        "status": "ok", "message": "", "scene_s": scene_s, "build_s": build_s, "step_s": [],
        "sweeps": [], "t_s": [], "finished": False, "counts": [integ.solver_counts()],
        "units": len(scene.structure), "contact_points": int(integ.sys.npt),
        "dofs": int(integ.sys.ndof)}
    _write_partial(spec, out)
    for _ in range(int(spec["steps"])):
        if limit is not None and time.perf_counter() - t0 > float(limit):
            out.update(status="timeout", message=f"stopped after {float(limit):g} s at step "
                       f"{len(out['step_s'])}")
            break
        t1 = time.perf_counter()
        rep = integ.step()
        out["step_s"].append(time.perf_counter() - t1)
        out["sweeps"].append(rep.sweeps)
        out["t_s"].append(rep.time)
        out["counts"].append(integ.solver_counts())
        out["parts"] = [[r.name, r.calls, r.total_s, r.median_ms] for r in timing.table()]
        # the case's own end (its target displacement or its time limit), as ``masonry run``
        out["finished"] = scene.finished(float(wx @ integ.u[mx]), rep.time)
        _write_partial(spec, out)
        if out["finished"]:
            break
    return out


def _write_partial(spec: Mapping[str, Any], out: Mapping[str, Any]) -> None:
    """The result so far, with the peak memory so far, written atomically to ``result``."""
    if "result" not in spec:
        return
    path = Path(spec["result"])
    tmp = path.with_suffix(".part")
    tmp.write_text(json.dumps({**out, "status": "partial",
                               "peak_rss_MiB": timing.peak_memory_mib()}))
    tmp.replace(path)


def _limit_memory(gib: float | None) -> None:
    """Cap this process's address space at ``gib`` GiB (``RLIMIT_AS``): an allocation beyond it
    fails with MemoryError instead of pushing a shared machine into swap."""
    if gib is None:
        return
    import resource

    cap = int(float(gib) * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))


def _child_main(spec_path: str) -> int:
    """Entry point of a child process: read the spec, run it, write the result JSON. Launched
    on several processes (``processes`` in the spec), process 0 runs it and the others take
    part in its linear solves (``nscd/mpi.py``); the result has every process's peak memory
    (``peak_rss_MiB_per_process``)."""
    from masonry_nscd.nscd import mpi

    if mpi.take_part():
        return 0
    if mpi.launched_processes() > 1:
        mpi.world()  # MPI started before the run, so that an early error still stops the others
    spec = json.loads(Path(spec_path).read_text())
    try:
        _limit_memory(spec.get("memory_limit_gib"))
        out = (_child_run if spec["kind"] == "run" else _child_steps)(spec)
    except MemoryError as exc:
        out = _partial_result(spec)
        out.update(status="memory", message=f"out of the {spec.get('memory_limit_gib')} GiB "
                   f"address space: MemoryError {exc}")
    except Exception as exc:  # noqa: BLE001 - reported to the parent as the run's outcome
        out = {"status": "error", "message": f"{type(exc).__name__}: {exc}"}
    out["peak_rss_MiB_per_process"] = mpi.peak_memory_per_process()
    out["peak_rss_MiB"] = out["peak_rss_MiB_per_process"][0]
    Path(spec["result"]).write_text(json.dumps(out))
    mpi.shutdown()  # the other processes stop (nothing on one process)
    return 0


def _partial_result(spec: Mapping[str, Any]) -> dict[str, Any]:
    """What a child wrote to ``result`` so far (an empty dict if nothing)."""
    path = Path(spec.get("result", ""))
    try:
        return json.loads(path.read_text()) if path.is_file() else {}
    except (OSError, ValueError):
        return {}


def run_in_child(spec: Mapping[str, Any], timeout_s: float | None = None) -> dict[str, Any]:
    """Run ``spec`` in a fresh Python process and return its result, plus ``process_s``.

    ``spec``: ``kind`` (``run``: :func:`masonry_nscd.studies.point.run_point` of ``case`` with
    ``overrides`` into ``outdir``, stopped after ``time_limit_s``; ``steps``: build the wall and
    make ``steps`` steps, no outputs), and ``processes`` (default 1: more launches the child
    under ``mpiexec``, ``mpi.launcher``). The result always has ``status`` (``ok``,
    ``timeout``, ``failed``, ``error``), ``message`` and, unless the process died,
    ``peak_rss_MiB`` (process 0's) and ``peak_rss_MiB_per_process``.
    """
    from masonry_nscd.nscd import mpi

    processes = int(spec.get("processes", 1))
    python = mpi.launcher(processes) if processes > 1 else [sys.executable]
    with tempfile.TemporaryDirectory(prefix="masonry-bench-") as tmp:
        spec_path, result = Path(tmp) / "spec.json", Path(tmp) / "result.json"
        spec_path.write_text(json.dumps({**spec, "result": str(result)}))
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([*python, "-m", "masonry_nscd.studies.bench", str(spec_path)],
                                  check=False, capture_output=True, text=True,
                                  timeout=timeout_s)
        except subprocess.TimeoutExpired:
            # a step that never ended: what the child wrote before it (``_write_partial``)
            return {**_partial_result({"result": str(result)}), "status": "timeout",
                    "message": f"child process killed after {timeout_s:g} s",
                    "process_s": time.perf_counter() - t0}
        process_s = time.perf_counter() - t0
        if not result.exists():
            tail = (proc.stderr or "").strip().splitlines()[-3:]
            return {"status": "error", "process_s": process_s, "message":
                    f"child process exited with code {proc.returncode}: {' | '.join(tail)}"}
        return {**json.loads(result.read_text()), "process_s": process_s}


# ---------------------------------------------------------------------------------------------
# Run time against error
# ---------------------------------------------------------------------------------------------


@dataclass
class BenchRow:
    """One row of ``bench.csv`` (times in s, memory in MiB, errors relative)."""

    setting: str
    group: str
    description: str
    overrides: str
    method: str
    time_step_s: float
    rate_m_s: float
    tolerance: float
    elements_per_unit: str
    status: str = ""
    message: str = ""
    repeats: int = 0
    run_s: float = math.nan  # median over the repeats
    run_s_min: float = math.nan
    run_s_max: float = math.nan
    process_s: float = math.nan  # whole subprocess, start-up included (median)
    steps: int = 0
    step_ms_median: float = math.nan  # solver alone, median over the steps (median of repeats)
    ms_per_step: float = math.nan  # run_s / steps (build and outputs included)
    median_iterations: float = math.nan
    max_iterations: float = math.nan
    unconverged_steps: int = 0
    contact_points: int = 0
    peak_rss_MiB: float = math.nan
    peak_force_kN: float = math.nan
    initial_stiffness_kN_mm: float = math.nan
    force_at_target_kN: float = math.nan
    err_peak_force: float = math.nan
    err_initial_stiffness: float = math.nan
    err_force_at_target: float = math.nan
    err_rms_curve: float = math.nan
    err_envelope: float = math.nan  # cyclic cases
    err_energy: float = math.nan  # cyclic cases
    err_max: float = math.nan
    err_max_check: float = math.nan  # against the reference's own reference (check_reference)
    pareto: int = 0


BENCH_COLUMNS = [f.name for f in fields(BenchRow)]


@dataclass
class BenchResult:
    """What :func:`bench` measured: the rows (reference first) and the files written."""

    rows: list[BenchRow]
    csv_path: Path
    png_path: Path | None
    reference: Setting

    def row(self, name: str) -> BenchRow | None:
        return next((r for r in self.rows if r.setting == name), None)


def _num(x: Any) -> float:
    return math.nan if x is None else float(x)


def new_row(case, setting: Setting) -> BenchRow:
    """The row of ``setting`` with the parameters of ``case`` (the case with its overrides)."""
    s = case.solver
    return BenchRow(setting.name, setting.group, setting.description,
                    " ".join(setting.overrides), s.method, s.time_step_s,
                    case.loading.horizontal.rate_m_s, s.tolerance,
                    "x".join(str(d) for d in case.wall.elements_per_unit))


def fill_timing(row: BenchRow, runs: Sequence[Mapping[str, Any]]) -> None:
    """Put the child results of the repeats of one setting in its row."""
    last = runs[-1]
    row.status, row.message, row.repeats = last["status"], last.get("message", ""), len(runs)
    times = [r["run_s"] for r in runs if "run_s" in r]
    if times:
        row.run_s, row.run_s_min, row.run_s_max = statistics.median(times), min(times), max(times)
    row.process_s = statistics.median(r["process_s"] for r in runs)
    row.steps = int(last.get("steps", 0))
    steps_ms = [r["step_ms_median"] for r in runs if math.isfinite(_num(r.get("step_ms_median")))]
    row.step_ms_median = statistics.median(steps_ms) if steps_ms else math.nan
    row.ms_per_step = 1e3 * row.run_s / row.steps if row.steps else math.nan
    row.unconverged_steps = int(last.get("unconverged_steps", 0))
    row.contact_points = int(last.get("contact_points", 0))
    rss = [_num(r.get("peak_rss_MiB")) for r in runs]
    row.peak_rss_MiB = max((v for v in rss if math.isfinite(v)), default=math.nan)


def _cyclic(scene: Mapping[str, Any] | None) -> bool:
    return scene is not None and (scene.get("history") or {}).get("kind") == "cyclic"


def errors_against(curve: Mapping[str, Sequence[float]], ref: Mapping[str, Sequence[float]],
                   target_mm: float, start_s: float, scene: Mapping[str, Any] | None = None,
                   ref_scene: Mapping[str, Any] | None = None) -> dict[str, float]:
    """The errors of ``curve`` against ``ref`` (relative), ``err_max`` among them: on the cycles
    when ``scene`` says the case is cyclic (none without ``ref_scene``), else on the push up to
    the target."""
    if _cyclic(scene):
        return {} if ref_scene is None else cyclic_errors(curve, scene, ref, ref_scene)
    return curve_errors(curve, ref, target_mm, start_s)


def fill_curve(row: BenchRow, curve: Mapping[str, Sequence[float]] | None,
               ref: Mapping[str, Sequence[float]] | None, target_mm: float,
               start_s: float, scene: Mapping[str, Any] | None = None,
               ref_scene: Mapping[str, Any] | None = None) -> None:
    """Iterations, summary values and errors of one setting from its curve and the reference's
    (and, for a cyclic case, their ``scene.json``: ``scene`` and ``ref_scene``).

    Errors stay NaN unless the setting and the reference both finished (status ``ok``)."""
    if not curve or not len(curve.get("step", ())):
        return
    it = np.asarray(curve["iterations"], dtype=float)
    row.median_iterations, row.max_iterations = float(np.median(it)), float(it.max())
    if _cyclic(scene):
        m = cyclic_metrics(curve, scene)
        row.peak_force_kN = _num(m["peak_pos_kN"])
        row.initial_stiffness_kN_mm = _num(m["initial_stiffness_kN_mm"])
    else:
        m = curve_metrics(curve, target_mm, start_s)
        row.peak_force_kN = _num(m["peak_force_kN"])
        row.initial_stiffness_kN_mm = _num(m["initial_stiffness_kN_mm"])
        row.force_at_target_kN = _num(m["force_at_target_kN"])
    if row.status == "ok" and ref is not None:
        for k, v in errors_against(curve, ref, target_mm, start_s, scene, ref_scene).items():
            setattr(row, k, v)


def _fmt_csv(v: Any) -> Any:
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return v


def write_rows(path: Path, rows: Sequence[Any], columns: Sequence[str]) -> None:
    """Write dataclass rows as a CSV file atomically (NaN as an empty field)."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(columns)
    for r in rows:
        d = asdict(r)
        w.writerow([_fmt_csv(d[c]) for c in columns])
    atomic_write(path, lambda p: Path(p).write_text(buf.getvalue(), newline=""))


def warm_up_specs(case_path: Path, overrides: Sequence[str], case,
                  settings: Sequence[Setting]) -> list[dict[str, Any]]:
    """Tiny runs (2 x 2 units, one hexahedron per unit, about 150 loose steps) with every
    solver and block material of ``settings``, to fill the numba cache before timing."""
    combos = []
    for s in settings:
        c = load_case(case_path, [*overrides, *s.overrides])
        combo = (c.contact_solver, c.blocks.material)
        if combo not in combos:
            combos.append(combo)
    hz = case.loading.horizontal
    end_s = hz.start_s + hz.ramp_s / 2.0 + hz.target_m / hz.rate_m_s  # a monotonic push
    h = max(case.solver.time_step_s, end_s / 150.0)
    tiny = ["wall.courses=2", "wall.units_per_course=2", "wall.elements_per_unit=[1,1,1]",
            f"solver.time_step_s={h!r}", "solver.tolerance=1e-4", "solver.max_iterations=500",
            "output.vtu=true", "output.hdf5=true"]
    if hz.history == "cyclic":  # the kernels are the same: warm them on a short push
        tiny += ["loading.horizontal.history=monotonic", "loading.horizontal.amplitudes_m=null"]
    return [{"kind": "run", "case": str(case_path), "time_limit_s": 120.0,
             "overrides": [*overrides, f"solver.method={m}", f"blocks.material={mat}", *tiny]}
            for m, mat in combos]


def bench(case_path: Path | str, outdir: Path | str, *, overrides: Sequence[str] = (),
          quick: bool = False, repeats: int = 3, cheap_s: float = CHEAP_S,
          time_limit_s: float = 600.0, check_reference: bool = False,
          echo: Callable[[str], None] = print) -> BenchResult:
    """Run the ladder of ``case_path`` (with ``overrides``) and its reference into
    ``outdir/runs/<setting>/``; write ``outdir/bench.csv`` (after every setting) and
    ``outdir/bench.png``. ``check_reference``: also the reference's own reference, right after
    it, and every row's ``err_max_check``. See the module docstring."""
    case_path, outdir = Path(case_path), Path(outdir)
    case = load_case(case_path, list(overrides))
    check_history(case)
    outdir.mkdir(parents=True, exist_ok=True)
    target_mm, start_s = 1e3 * case.loading.horizontal.target_m, case.loading.horizontal.start_s
    ref_setting = reference_setting(case)
    ref_limit_s = REFERENCE_TIME_FACTOR * time_limit_s
    check = reference_check_setting(case) if check_reference else None
    settings = [ref_setting, *([check] if check else []), *ladder(case, quick)]
    t0 = time.perf_counter()
    for spec in warm_up_specs(case_path, overrides, case, settings):
        with tempfile.TemporaryDirectory(prefix="masonry-warm-") as tmp:
            run_in_child({**spec, "outdir": tmp})
    echo(f"numba cache warmed in {time.perf_counter() - t0:.1f} s; reference: "
         f"{ref_setting.description}")
    rows: list[BenchRow] = []
    ref_curve = ref_scene = None
    check_run = None  # (curve, scene) of the reference's own reference, once it finished

    def against_check(c, sc) -> float:
        return errors_against(c, check_run[0], target_mm, start_s, sc,
                              check_run[1]).get("err_max", math.nan)

    for s in settings:
        all_overrides = [*overrides, *s.overrides]
        row = new_row(load_case(case_path, all_overrides), s)
        # the check has half the reference's step: twice its time
        limit_s = (ref_limit_s * (2.0 if s is check else 1.0) if s.group == "reference"
                   else time_limit_s)
        spec = {"kind": "run", "case": str(case_path), "overrides": all_overrides,
                "outdir": str(outdir / "runs" / s.name), "time_limit_s": limit_s}
        runs = [run_in_child(spec, timeout_s=limit_s + 600.0)]
        while (len(runs) < repeats and runs[0]["status"] == "ok"
               and runs[0].get("run_s", math.inf) < cheap_s):
            runs.append(run_in_child(spec, timeout_s=limit_s + 600.0))
        fill_timing(row, runs)
        run_dir = outdir / "runs" / s.name
        csv_path = run_dir / CSV
        curve = read_curve_csv(csv_path) if csv_path.exists() else None
        scene = read_scene_info(run_dir) if (run_dir / SCENE).exists() else None
        if s is ref_setting and row.status == "ok":
            ref_curve, ref_scene = curve, scene
        fill_curve(row, curve, ref_curve, target_mm, start_s, scene, ref_scene)
        rows.append(row)
        if s is check and row.status == "ok" and curve:
            check_run = (curve, scene)
            if ref_curve is not None:  # the reference's own error (rows[0] is its row)
                rows[0].err_max_check = against_check(ref_curve, ref_scene)
        if check_run is not None and row.status == "ok" and curve:
            row.err_max_check = against_check(curve, scene)
        write_rows(outdir / "bench.csv", rows, BENCH_COLUMNS)
        echo(progress_line(row))
    mark_pareto(rows)
    write_rows(outdir / "bench.csv", rows, BENCH_COLUMNS)
    png = plot_bench(rows, outdir / "bench.png", f"{case.name}: run time against error "
                     f"(reference: {ref_setting.description})")
    return BenchResult(rows, outdir / "bench.csv", png, ref_setting)


def progress_line(row: BenchRow) -> str:
    """One line per setting while the benchmark runs."""
    text = (f"{row.setting}: {row.status}, {row.run_s:.2f} s (median of {row.repeats}), "
            f"{row.steps} steps, {row.step_ms_median:.3g} ms per step (solver)")
    if math.isfinite(row.err_max):
        text += f", largest error {100 * row.err_max:.3g} %"
    return text + (f": {row.message}" if row.message else "")


def mark_pareto(rows: Sequence[BenchRow]) -> None:
    """Set ``pareto`` on the rows (the reference excluded) that no other beats."""
    cands = [r for r in rows if r.group != "reference"]
    front = pareto_front([r.run_s for r in cands], [r.err_max for r in cands])
    for r, on in zip(cands, front, strict=True):
        r.pareto = int(on)


def format_table(rows: Sequence[BenchRow]) -> str:
    """The rows as a fixed-width text table (errors in %)."""
    head = (f"{'setting':18s} {'status':8s} {'run s':>8s} {'rep':>3s} {'steps':>6s} "
            f"{'unconv':>6s} {'ms/step':>8s} {'it/step':>7s} {'RSS MiB':>7s} {'peak %':>8s} "
            f"{'k %':>8s} {'F@tgt %':>8s} {'RMS %':>8s} {'front':>5s}")
    columns = error_columns(rows)
    if columns is CYCLIC_ERROR_COLUMNS:
        head = head.replace(f"{'F@tgt %':>8s} {'RMS %':>8s}", f"{'env %':>8s} {'E %':>8s}")
    if any(math.isfinite(r.err_max_check) for r in rows):  # against the reference's reference
        columns = (*columns, "err_max_check")
        head = head.replace(f"{'RMS %':>8s}", f"{'RMS %':>8s} {'check %':>8s}").replace(
            f"{'E %':>8s}", f"{'E %':>8s} {'check %':>8s}")
    lines = [head]
    for r in rows:
        errs = " ".join(f"{100 * getattr(r, c):8.3g}" for c in columns)
        lines.append(f"{r.setting:18s} {r.status:8s} {r.run_s:8.3g} {r.repeats:3d} "
                     f"{r.steps:6d} {r.unconverged_steps:6d} {r.step_ms_median:8.3g} "
                     f"{r.median_iterations:7.3g} {r.peak_rss_MiB:7.0f} {errs} "
                     f"{'*' if r.pareto else '':>5s}")
    return "\n".join(lines)


def verdict(result: BenchResult) -> list[str]:
    """Whether the default settings are on the Pareto front, and their errors."""
    d = result.row("default")
    if d is None or not math.isfinite(d.err_max):
        why = "the reference or the default run did not finish"
        return [f"default settings: errors not measured ({why})"]
    errs = ", ".join(f"{c[4:].replace('_', ' ')} {100 * getattr(d, c):.3g} %"
                     for c in error_columns(result.rows))
    under = "yes" if d.err_max < DEFAULT_ERROR_LIMIT else "NO"
    lines = [(f"default settings: {d.run_s:.3g} s, {d.step_ms_median:.3g} ms per step "
              f"(solver), errors against the reference: {errs}; largest "
              f"{100 * d.err_max:.3g} % (under {100 * DEFAULT_ERROR_LIMIT:g} %: {under})")]
    lines += _check_lines(result, d)
    if d.pareto:
        faster = [f"{r.setting} ({r.run_s:.3g} s, {100 * r.err_max:.3g} %)" for r in result.rows
                  if r.pareto and r is not d and r.run_s < d.run_s]
        lines.append("default settings: on the Pareto front" + (
            f"; faster on the front, at a larger error: {', '.join(faster)}" if faster else ""))
    else:
        better = [r.setting for r in result.rows if r.group != "reference" and r is not d
                  and r.run_s <= d.run_s and r.err_max <= d.err_max]
        lines.append(f"default settings: NOT on the Pareto front (beaten by {', '.join(better)})")
    for r in result.rows:
        if r.group == "mesh" and math.isfinite(r.err_max):
            lines.append(f"mesh {r.elements_per_unit} per unit (the reference has the case's "
                         f"mesh, {d.elements_per_unit}): the curve moves by up to "
                         f"{100 * r.err_max:.3g} %")
    return lines


def _check_lines(result: BenchResult, d: BenchRow) -> list[str]:
    """What the reference's own reference says (none without ``check_reference``)."""
    c, ref = result.row("reference_check"), result.row("reference")
    if c is None:
        return []
    if ref is None or not math.isfinite(ref.err_max_check):
        return ["reference check: not measured (the check run did not finish)"]
    lines = [(f"reference check ({c.description}): the reference is "
              f"{100 * ref.err_max_check:.3g} % from it, the default settings "
              f"{100 * d.err_max_check:.3g} %")]
    if ref.err_max_check >= 0.5 * d.err_max:
        lines.append("reference check: the reference's own error is half the default's or "
                     "more, so the errors against it understate the default's: read "
                     "err_max_check")
    return lines


def plot_bench(rows: Sequence[BenchRow], path: Path, title: str) -> Path | None:
    """Run time (s) against the largest error (log scales), the Pareto front as a line, the
    default settings as a red star. Rows without a finite time and error are left out; errors
    below :data:`ERROR_FLOOR` are drawn at it. ``None`` when nothing can be drawn."""
    from matplotlib.figure import Figure

    pts = [r for r in rows if r.group != "reference" and math.isfinite(r.run_s)
           and math.isfinite(r.err_max)]
    if not pts:
        return None
    fig = Figure(figsize=(9, 6), layout="constrained")
    ax = fig.add_subplot()
    err = np.array([max(r.err_max, ERROR_FLOOR) for r in pts])
    t = np.array([r.run_s for r in pts])
    ax.scatter(err, t, c="tab:blue", s=30, zorder=3, label="settings")
    front = sorted((e, ti) for e, ti, r in zip(err, t, pts, strict=True) if r.pareto)
    if front:
        fe, ft = zip(*front, strict=True)
        ax.step(fe, ft, where="post", color="tab:green", lw=1.5, zorder=2)
        ax.scatter(fe, ft, facecolors="none", edgecolors="tab:green", s=140, lw=1.5,
                   zorder=4, label="Pareto front")
    for e, ti, r in zip(err, t, pts, strict=True):
        ax.annotate(r.setting, (e, ti), textcoords="offset points", xytext=(5, 4), fontsize=8)
        if r.setting == "default":
            ax.scatter([e], [ti], marker="*", c="tab:red", s=260, zorder=5,
                       label="default settings")
    ax.axvline(DEFAULT_ERROR_LIMIT, color="grey", ls=":", lw=1,
               label=f"{100 * DEFAULT_ERROR_LIMIT:g} % (limit for the default settings)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("largest relative error against the reference (peak, stiffness, force at "
                  "target, RMS of the curve; cyclic: peaks, stiffness, envelope, energy)")
    ax.set_ylabel("run time (s, median)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------------
# Scaling with the size of the wall
# ---------------------------------------------------------------------------------------------


def scaling_sizes(courses: int, units_per_course: int, largest: int = 8
                  ) -> list[tuple[int, int, int]]:
    """``(factor, courses, units_per_course)`` of walls with about 1, 2, 4, ... ``largest``
    times the units: the courses and the units per course doubled in turn (``largest`` a power
    of two, 1 to 256)."""
    if largest < 1 or largest > 256 or largest & (largest - 1):
        raise ValueError(f"largest must be a power of two from 1 to 256, got {largest}")
    c, n = courses, units_per_course
    out = [(1, c, n)]
    while out[-1][0] < largest:
        k, c, n = out[-1]
        out.append((2 * k, 2 * c, n) if len(out) % 2 else (2 * k, c, 2 * n))
    return out


@dataclass
class ScalingRow:
    """One row of ``scaling.csv`` (times in s or ms, memory in MiB)."""

    wall: str  # baseline, 1x, 2x, 4x, 8x, ...
    courses: int
    units_per_course: int
    processes: int = 1  # the processes the wall was stepped on (``masonry run --processes``)
    units: int = 0
    contact_points: int = 0
    dofs: int = 0
    steps: int = 0
    simulated_s: float = math.nan  # the time the last step ended at (s)
    finished: bool = False  # the case's end reached (its target displacement or time limit)
    scene_s: float = math.nan  # the scene builder: layout, meshes, contact detection
    build_s: float = math.nan  # the scene and the integrator (system matrices)
    step_ms_median: float = math.nan  # over the steps after the first ``skip``
    step_ms_mean: float = math.nan  # every step, the first ones included: summed time / steps
    median_iterations: float = math.nan
    ms_per_iteration: float = math.nan  # median over the same steps of step time / iterations
    # over the same steps: factorisations of the Newton matrix (or of its preconditioner),
    # Krylov iterations, and Krylov solves made again by LU, per step
    factorisations_per_step: float = math.nan
    linear_iterations_per_step: float = math.nan
    linear_fallbacks: int = 0
    peak_rss_MiB: float = math.nan  # process 0's
    rss_above_baseline_MiB: float = math.nan
    peak_rss_MiB_others: float = math.nan  # the largest of the other processes' (none on one)
    peak_rss_MiB_all: float = math.nan  # every process's, summed
    process_s: float = math.nan
    status: str = ""
    message: str = ""


SCALING_COLUMNS = [f.name for f in fields(ScalingRow)]


@dataclass
class PartRow:
    """One row of ``scaling_parts.csv``: where a wall's step time went (``masonry_nscd.timing``)
    over all its steps; ``share`` of the summed step times."""

    wall: str
    part: str
    calls: int
    total_s: float
    median_ms: float
    share: float


PARTS_COLUMNS = [f.name for f in fields(PartRow)]


@dataclass
class StepRow:
    """One row of ``scaling_steps.csv``: one step of one wall."""

    wall: str
    step: int
    end_s: float  # the time the step ended at (s)
    step_ms: float  # its wall-clock time (ms)
    iterations: int  # Newton iterations (or sweeps) of the step
    factorisations: int  # of the Newton matrix or of its preconditioner, in the step


STEP_COLUMNS = [f.name for f in fields(StepRow)]


def scaling_steps(name: str, res: Mapping[str, Any]) -> list[StepRow]:
    """The rows of ``scaling_steps.csv`` of one wall from its child's result."""
    step_s, sweeps, t_s = res.get("step_s", []), res.get("sweeps", []), res.get("t_s", [])
    counts = res.get("counts", [])
    fact = ([b["factorisations"] - a["factorisations"] for a, b in itertools.pairwise(counts)]
            if len(counts) == len(step_s) + 1 else [-1] * len(step_s))
    return [StepRow(name, k + 1, t, 1e3 * d, int(it), int(f))
            for k, (d, it, t, f) in enumerate(zip(step_s, sweeps, t_s, fact, strict=False))]


def scaling_parts(name: str, res: Mapping[str, Any]) -> list[PartRow]:
    """The rows of ``scaling_parts.csv`` of one wall from its child's result (none when it
    made no step)."""
    steps_s = float(sum(res.get("step_s", [])))
    return [PartRow(name, part, calls, total, median,
                    total / steps_s if steps_s > 0 else math.nan)
            for part, calls, total, median in res.get("parts", [])]


def loglog_slope(x: Sequence[float], y: Sequence[float]) -> float:
    """Least-squares slope of ``log y`` against ``log x`` over the positive pairs; NaN with
    fewer than two."""
    xy = [(a, b) for a, b in zip(x, y, strict=True) if a > 0 and b > 0 and math.isfinite(b)]
    if len(xy) < 2:
        return math.nan
    lx, ly = np.log([a for a, _ in xy]), np.log([b for _, b in xy])
    return float(np.polyfit(lx, ly, 1)[0])


def linear_fit(x: Sequence[float], y: Sequence[float]) -> tuple[float, float]:
    """``(slope, intercept)`` of the least-squares line through the finite pairs (NaN, NaN
    with fewer than two)."""
    xy = [(a, b) for a, b in zip(x, y, strict=True) if math.isfinite(a) and math.isfinite(b)]
    if len(xy) < 2:
        return math.nan, math.nan
    slope, intercept = np.polyfit([a for a, _ in xy], [b for _, b in xy], 1)
    return float(slope), float(intercept)


def _scaling_row(name: str, courses: int, units: int, res: Mapping[str, Any],
                 skip: int, processes: int = 1) -> ScalingRow:
    """The row of one wall stepped on ``processes`` processes from its child's result; a wall
    stopped by its time or memory limit keeps its build time and the steps it made."""
    each = [_num(m) for m in res.get("peak_rss_MiB_per_process") or [res.get("peak_rss_MiB")]]
    row = ScalingRow(name, courses, units, processes=processes, status=res["status"],
                     message=res.get("message", ""), process_s=res["process_s"],
                     peak_rss_MiB=each[0], peak_rss_MiB_all=float(sum(each)),
                     peak_rss_MiB_others=max(each[1:]) if len(each) > 1 else math.nan)
    if "build_s" in res:
        row.units, row.contact_points, row.dofs = res["units"], res["contact_points"], res["dofs"]
        row.scene_s, row.build_s = res["scene_s"], res["build_s"]
    step_s, sweeps = res.get("step_s", []), res.get("sweeps", [])
    row.steps = len(step_s)
    row.finished = bool(res.get("finished", False))
    if res.get("t_s"):
        row.simulated_s = float(res["t_s"][-1])
    if step_s:
        row.step_ms_mean = 1e3 * float(np.mean(step_s))
        kept = slice(skip, None) if len(step_s) > skip else slice(None)
        t = np.asarray(step_s[kept], dtype=float)
        its = np.maximum(1.0, np.asarray(sweeps[kept], dtype=float))
        row.step_ms_median = 1e3 * float(np.median(t))
        row.median_iterations = float(np.median(its))
        row.ms_per_iteration = 1e3 * float(np.median(t / its))
        counts = res.get("counts", [])
        if len(counts) == len(step_s) + 1:  # cumulative, before the first step and after each
            first = counts[0 if kept.start is None else kept.start]
            last, n = counts[-1], len(t)
            row.factorisations_per_step = (last["factorisations"] - first["factorisations"]) / n
            row.linear_iterations_per_step = (last["linear_iterations"]
                                              - first["linear_iterations"]) / n
            row.linear_fallbacks = int(last["linear_fallbacks"])
    return row


def bench_scaling(case_path: Path | str, outdir: Path | str, *, overrides: Sequence[str] = (),
                  steps: int = 40, largest: int = 8, smallest: int = 1,
                  time_limit_s: float | None = None,
                  memory_limit_gib: float | None = None, processes: Sequence[int] = (1,),
                  echo: Callable[[str], None] = print
                  ) -> tuple[list[ScalingRow], list[str]]:
    """Step walls of ``smallest``, ..., 4, ... ``largest`` times the units of the case (powers
    of two) ``steps`` times each, in fresh subprocesses, after a one-unit baseline; write
    ``scaling.csv`` and ``scaling.png`` in ``outdir``. Returns the rows (baseline first) and
    the fit statements (:func:`scaling_statements`). Each wall is stepped once on each number
    of ``processes`` (``masonry run --processes``: PETSc's Krylov solve, ``solver.linear:
    krylov``); the fits and the figure are of one process, and each wall on more is compared
    with it (:func:`processes_statements`).

    ``time_limit_s``: per wall, no step starts after that long (s, build included), and a step
    still going a minute later is killed with its process; the wall is reported with status
    ``timeout`` and the steps it made. ``memory_limit_gib``: the address space of each wall's
    process (GiB); a wall that needs more is reported with status ``memory``, and the larger
    walls are not tried."""
    case_path, outdir = Path(case_path), Path(outdir)
    case = load_case(case_path, list(overrides))
    sizes = scaling_sizes(case.wall.courses, case.wall.units_per_course, largest)
    outdir.mkdir(parents=True, exist_ok=True)
    skip = min(5, steps // 4)
    walls = [("baseline", 1, 1)] + [(f"{k}x", c, n) for k, c, n in sizes if k >= smallest]

    def spec(c: int, n: int, p: int = 1) -> dict[str, Any]:
        return {"kind": "steps", "case": str(case_path), "steps": steps, "processes": p,
                "time_limit_s": time_limit_s, "memory_limit_gib": memory_limit_gib,
                "overrides": [*overrides, f"wall.courses={c}", f"wall.units_per_course={n}"]}

    run_in_child(spec(1, 1))  # warms the numba cache: no compilation in the measured runs
    kill_s = None if time_limit_s is None else float(time_limit_s) + 60.0
    rows: list[ScalingRow] = []
    parts: list[PartRow] = []
    step_rows: list[StepRow] = []
    runs = [(name, c, n, p) for name, c, n in walls
            for p in ((1,) if name == "baseline" else processes)]
    for name, c, n, p in runs:
        label = name if p == 1 else f"{name} on {p} processes"
        if rows and rows[-1].status in ("memory", "skipped"):
            rows.append(ScalingRow(name, c, n, p, status="skipped",
                                   message=f"not tried: {rows[-1].wall} hit its limit"))
            echo(f"{label}: skipped ({rows[-1].message})")
            continue
        res = run_in_child(spec(c, n, p), timeout_s=kill_s)
        row = _scaling_row(name, c, n, res, skip, p)
        rows.append(row)
        wall_parts = scaling_parts(label, res)
        parts += wall_parts
        step_rows += scaling_steps(label, res)
        end = (f"the case's end (t = {row.simulated_s:.4g} s)" if row.finished else
               f"t = {row.simulated_s:.4g} s")
        memory = (f"{row.peak_rss_MiB:.0f} MiB" if p == 1 else
                  f"{row.peak_rss_MiB:.0f} MiB on process 0, {row.peak_rss_MiB_others:.0f} "
                  f"on the largest other, {row.peak_rss_MiB_all:.0f} in all")
        echo(f"{label}: {c} courses x {n} units per course, {row.units} units, "
             f"{row.contact_points} contact points: {row.status}, build {row.build_s:.3g} s, "
             f"{row.steps} steps to {end}, {row.step_ms_mean:.3g} ms per step on average "
             f"({row.step_ms_median:.3g} median after the first {skip}), "
             f"{row.factorisations_per_step:.2g} factorisations per step, "
             + memory + (f": {row.message}" if row.message else ""))
        top = wall_parts[:4]  # the longest first (timing.table)
        if top:
            echo("  of the step time: " + ", ".join(
                f"{p.part} {100 * p.share:.0f} % ({p.calls} x {p.median_ms:.3g} ms)"
                for p in top))
    base = rows[0].peak_rss_MiB
    for r in rows[1:]:
        if r.processes == 1:
            r.rss_above_baseline_MiB = r.peak_rss_MiB - base
    write_rows(outdir / "scaling.csv", rows, SCALING_COLUMNS)
    write_rows(outdir / "scaling_parts.csv", parts, PARTS_COLUMNS)
    write_rows(outdir / "scaling_steps.csv", step_rows, STEP_COLUMNS)
    plot_scaling(rows, outdir / "scaling.png",
                 f"{case.name}: up to {steps} steps per wall (fewer where the case ends)")
    return rows, scaling_statements(rows) + processes_statements(rows)


def _measured_walls(rows: Sequence[ScalingRow]) -> list[ScalingRow]:
    """The walls that made steps: finished, or stopped by their time limit after some steps
    (their peak memory and time per step are measured; a wall out of memory is not)."""
    return [r for r in rows if r.wall != "baseline" and r.steps > 0 and r.processes == 1
            and r.status in ("ok", "timeout")]


def scaling_statements(rows: Sequence[ScalingRow]) -> list[str]:
    """The linear fit of peak memory against contact points, the log-log slope of the memory
    increments above the baseline, and the log-log slope of the time per step."""
    walls = _measured_walls(rows)
    npt = [float(r.contact_points) for r in walls]
    timed = [r for r in rows if r.wall != "baseline" and r.processes == 1
             and math.isfinite(r.step_ms_median)]
    slope, intercept = linear_fit(npt, [r.peak_rss_MiB for r in walls])
    above = [r.rss_above_baseline_MiB for r in walls]
    s_mem = loglog_slope(npt, above)
    s_last = loglog_slope(npt[-2:], above[-2:])
    s_time = loglog_slope([float(r.contact_points) for r in timed],
                          [r.step_ms_median for r in timed])
    s_mean = loglog_slope([float(r.contact_points) for r in timed],
                          [r.step_ms_mean for r in timed])
    if math.isnan(s_mem):
        growth = "not measurable (fewer than two walls above the baseline)"
    else:
        growth = (f"{s_mem:.2f} over all the walls, {s_last:.2f} between the two largest; "
                  + ("no faster than linear" if max(s_mem, s_last) <= LINEAR_SLOPE_LIMIT else
                     "no faster than linear for the largest walls" if s_last <= LINEAR_SLOPE_LIMIT
                     else "FASTER than linear")
                  + f" (a slope up to {LINEAR_SLOPE_LIMIT:g} counts as linear)")
    return [
        (f"peak memory ~ {intercept:.1f} MiB + {1024 * slope:.2f} KiB per contact point "
         f"(least squares over {len(walls)} walls)"),
        ("log-log slope of the memory above the one-unit baseline against contact points: "
         f"{growth}"),
        (f"log-log slope of the time per step against contact points: {s_time:.2f} "
         f"(medians after the first steps), {s_mean:.2f} (means over all the steps)"),
    ]


def processes_statements(rows: Sequence[ScalingRow]) -> list[str]:
    """Each wall stepped on several processes against the same wall on one: its median time
    per step, and each process's peak memory, as ratios of one process's."""
    one = {r.wall: r for r in rows if r.processes == 1 and r.steps > 0}
    out = []
    for r in rows:
        ref = one.get(r.wall)
        if r.processes == 1 or r.steps == 0 or ref is None:
            continue
        out.append(f"{r.wall} on {r.processes} processes against one: time per step "
                   f"{r.step_ms_median / ref.step_ms_median:.2f} (medians after the first "
                   f"steps), peak memory {r.peak_rss_MiB / ref.peak_rss_MiB:.2f} on process 0 "
                   f"and {r.peak_rss_MiB_others / ref.peak_rss_MiB:.2f} on the largest other, "
                   f"{r.peak_rss_MiB_all / ref.peak_rss_MiB:.2f} in all")
    return out


def format_scaling_table(rows: Sequence[ScalingRow]) -> str:
    """The scaling rows as a fixed-width text table."""
    lines = [(f"{'wall':8s} {'P':>2s} {'courses':>7s} {'upc':>4s} {'units':>6s} {'points':>7s} "
              f"{'dofs':>7s} {'scene s':>8s} {'build s':>8s} {'steps':>5s} {'mean ms':>8s} "
              f"{'ms/step':>8s} {'it/step':>7s} "
              f"{'ms/it':>7s} {'LU/step':>7s} {'kry/st':>6s} "
              f"{'RSS MiB':>8s} {'above base':>10s} status")]
    for r in rows:
        lines.append(f"{r.wall:8s} {r.processes:2d} {r.courses:7d} {r.units_per_course:4d} "
                     f"{r.units:6d} "
                     f"{r.contact_points:7d} {r.dofs:7d} {r.scene_s:8.3g} {r.build_s:8.3g} "
                     f"{r.steps:5d} {r.step_ms_mean:8.3g} "
                     f"{r.step_ms_median:8.3g} {r.median_iterations:7.3g} "
                     f"{r.ms_per_iteration:7.3g} {r.factorisations_per_step:7.2g} "
                     f"{r.linear_iterations_per_step:6.3g} {r.peak_rss_MiB:8.1f} "
                     f"{r.rss_above_baseline_MiB:10.1f} {r.status}")
    return "\n".join(lines)


def plot_scaling(rows: Sequence[ScalingRow], path: Path, title: str) -> Path | None:
    """Time per step and memory above the baseline against contact points (log-log), with a
    line of slope 1 through the smallest wall."""
    from matplotlib.figure import Figure

    walls = _measured_walls(rows)
    if not walls:
        return None
    fig = Figure(figsize=(12, 5), layout="constrained")
    npt = np.array([r.contact_points for r in walls], dtype=float)
    # per panel: its curves (attribute, legend; the first one annotated and given the line of
    # slope 1) and its axis label
    panels = [
        ([("step_ms_median", "median after the first steps"),
          ("step_ms_mean", "mean over every step")], "time per step (ms)"),
        ([("rss_above_baseline_MiB", "measured")],
         "peak memory above the one-unit baseline (MiB)"),
    ]
    for k, (series, label) in enumerate(panels):
        ax = fig.add_subplot(1, 2, k + 1)
        for j, (attr, name) in enumerate(series):
            y = np.array([getattr(r, attr) for r in walls], dtype=float)
            ok = np.isfinite(y) & (y > 0)
            ax.loglog(npt[ok], y[ok], "o-" if j == 0 else "s:", label=name)
            if j == 0:
                for x, v, r in zip(npt[ok], y[ok],
                                   [w for w, o in zip(walls, ok, strict=True) if o], strict=True):
                    ax.annotate(r.wall, (x, v), textcoords="offset points", xytext=(5, -10),
                                fontsize=8)
                if ok.any():
                    x0, y0 = npt[ok][0], y[ok][0]
                    ax.loglog(npt, y0 * npt / x0, "k--", lw=1, label="linear (slope 1)")
        ax.set_xlabel("contact points")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------------
# Start-up
# ---------------------------------------------------------------------------------------------


@dataclass
class StartupRow:
    """One row of ``startup.csv``: a command timed from launch to exit (s)."""

    what: str
    command: str
    repeats: int
    median_s: float
    min_s: float
    max_s: float
    target_s: float


def masonry_command() -> list[str]:
    """The ``masonry`` console script beside this interpreter, or ``python -m`` of the CLI."""
    script = Path(sys.executable).with_name("masonry")
    return [str(script)] if script.exists() else [sys.executable, "-m", "masonry_nscd.cli"]


def time_command(argv: Sequence[str], repeats: int) -> list[float]:
    """Wall-clock times (s) of ``repeats`` runs of ``argv``; RuntimeError if one fails."""
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        proc = subprocess.run(list(argv), check=False, capture_output=True, text=True)
        out.append(time.perf_counter() - t0)
        if proc.returncode != 0:
            raise RuntimeError(f"{' '.join(argv)} exited with code {proc.returncode}: "
                               f"{proc.stderr.strip()[-300:]}")
    return out


def startup_figures(outdir: Path | str, *, help_repeats: int = 5, run_repeats: int = 3,
                    smoke_case: Path = SMOKE_CASE) -> list[StartupRow]:
    """Time ``masonry --help`` and ``masonry run <smoke case>`` (after one untimed run) as
    subprocesses; write ``outdir/startup.csv``. The smoke run writes into
    ``outdir/startup_smoke/``."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    if not smoke_case.exists():
        raise FileNotFoundError(f"{smoke_case}: the smoke case is not there (an installed "
                                "package without the repository's cases/)")
    cmd = masonry_command()
    run_argv = [*cmd, "run", str(smoke_case), "-o", str(outdir / "startup_smoke"), "--overwrite"]
    time_command(run_argv, 1)  # warm: numba cache, imports in the page cache
    rows = []
    for what, argv, n, target in (("masonry --help", [*cmd, "--help"], help_repeats,
                                   HELP_TARGET_S),
                                  ("masonry run cases/smoke.yaml", run_argv, run_repeats,
                                   SMOKE_TARGET_S)):
        t = time_command(argv, n)
        rows.append(StartupRow(what, " ".join(argv), n, statistics.median(t), min(t), max(t),
                               target))
    write_rows(outdir / "startup.csv", rows, [f.name for f in fields(StartupRow)])
    return rows


def format_startup(rows: Sequence[StartupRow]) -> list[str]:
    """One line per command: median, range and target."""
    return [f"{r.what}: {r.median_s:.3g} s (median of {r.repeats}, {r.min_s:.3g}-"
            f"{r.max_s:.3g} s; target under {r.target_s:g} s: "
            f"{'met' if r.median_s < r.target_s else 'MISSED'})" for r in rows]


if __name__ == "__main__":  # a child of the benchmark: python -m masonry_nscd.studies.bench SPEC
    sys.exit(_child_main(sys.argv[1]))
