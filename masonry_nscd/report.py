"""The summary of a run: initial stiffness, peak, force at the target, convergence, damages.

Everything is computed from the force-displacement curve (the columns of
``force_displacement.csv``, see :mod:`masonry_nscd.run`), from what the run folder keeps of the
scene (``scene.json``: the stage whose curve is read, the target, the joint groups, the names
and places of the bodies) and, where the run wrote it, from the last output step of
``results.h5``. Units are in the key names (``_kN``, ``_mm``, ``_kN_mm``, ``_m``, ``_s``);
damages, residuals and counts are dimensionless. The run folder is read and written through
:mod:`masonry_nscd.io` (the readers of :mod:`~masonry_nscd.io.runfolder` and
:mod:`~masonry_nscd.io.results_h5`; ``summary.json`` by :mod:`~masonry_nscd.io.summary_json`,
``cycles.csv`` and ``envelope.csv`` by :mod:`~masonry_nscd.io.cycle_tables`): this module
computes.

Definitions (also in ``docs/choices.md``, "Run summary")
--------------------------------------------------------
Horizontal stage
    The rows with ``time_s`` at or after the start of the scene's push stage (``horizontal`` on
    a wall) when it is known; otherwise the rows from the last one with ``ux_mm <= 0`` before
    ``ux_mm`` first becomes positive.
Peak
    The largest ``fx_kN`` of the horizontal stage (the push is towards +x) and its ``ux_mm``,
    over the converged steps only (the force of a step whose solver did not converge can be
    far off: ``peak_force_unconverged_kN`` gives the largest force of those steps, and the
    stiffness and the force at the target are also read on converged steps only).
Initial stiffness (kN/mm)
    The secant between two force levels, ``F_low = 0.10 F_peak`` and ``F_high = 0.40 F_peak``:
    ``k = (F_high - F_low) / (u_high - u_low)``, where ``u_low`` and ``u_high`` are the
    displacements at which ``fx`` first reaches each level in the horizontal stage, linearly
    interpolated between the two rows around the crossing. The lower level skips the start of
    the stage (velocity ramp, the force left over from the vertical stage); the upper one stays
    below the force at which the joints start to slide and the curve bends. If ``fx`` is
    already above ``F_low`` when the stage starts, the secant is not defined (``None``).
    :func:`secant_stiffness` takes any two levels (the calibration uses fixed ones, see
    :mod:`masonry_nscd.studies.calibrate`).
Force at the target
    ``fx`` interpolated linearly in ``ux`` at the case's target displacement
    (``loading.horizontal.target_m``, 10 mm for the study), ``None`` if the run stopped before
    (and for cyclic and tabulated histories, which have no target).
Cyclic and tabulated histories (``history`` of ``scene.json``)
    The initial stiffness is read on the first loading branch only (the rows of the horizontal
    stage up to the first decrease of ``ux``), between 10 % and 40 % of the largest force of
    that branch: later branches reload a wall already cycled. The peaks in both directions,
    ``peak_force_pos_kN`` (the largest ``fx``, also ``peak_force_kN``) and
    ``peak_force_neg_kN`` (the smallest, signed), with their ``ux``; per cycle of the history
    the rows of ``cycles.csv`` and the envelope ``envelope.csv``
    (:mod:`masonry_nscd.post.cycles`, on the converged rows); ``cycles_completed`` and the
    sum of their ``dissipated_energy_J``.
Ground motion (``history`` of kind ``ground_motion``)
    ``ux_mm`` is the drift, the displacement of what the scene measures (the top beam's
    reference point, or the centre of mass of the top course without a top beam) relative to
    the moving base, and ``fx_bottom_kN`` the base shear (the force of the base on the wall).
    The push's keys (peak force, stiffness, force at a target) are ``None``; instead, over the
    converged rows of the ground-motion stage: ``peak_drift_mm`` (signed, the largest
    ``|ux|``) and its time, ``peak_drift_ratio_percent`` (of the wall's height),
    ``residual_drift_mm`` (the drift at the last row, the end of the record) and its ratio,
    ``peak_base_shear_kN`` (signed, the largest ``|fx_bottom|``) and its time;
    ``step_at_peak`` is the step of the peak drift (the failure mode "at the peak" is read
    there).
Energy balance (``energy.csv``, :mod:`masonry_nscd.nscd.energy`)
    ``energy``: the terms at the last output step (J); ``energy_relative_imbalance`` there and
    ``energy_worst_relative_imbalance`` over the output steps.
Failure mode
    Named from the joint and block damage at the output step nearest the peak
    (``failure_mode_at_peak``) and at the last one (``failure_mode``): base sliding, rocking,
    bed joint sliding, diagonal stair-step, toe crushing, or their combinations
    (:mod:`masonry_nscd.post.failure`).
Largest damages
    Read at the last output step of ``results.h5``: every damage is irreversible, so the last
    step holds the largest values. Blocks: ``d_c`` (post-peak compressive damage, crushing),
    ``d_cpp`` (pre-peak compressive damage), ``d_t`` (largest tensile crack damage); joints (the
    scene's joint groups, not the glue): ``d_coh = 1 - beta (1 - d_0)`` with ``d_0`` the damage
    of the point's law as built (``d_coh_initial``), and the integrity ``beta`` (1 as built, 0
    once the cohesion is lost). Each comes with where it is: the unit (index as in
    ``block_of_element``) and its name, the place keys its builder gave (on a wall: its course
    counted from 1 at the bottom, its position in the course counted from 1 at the left end),
    and the coordinates x, y (m) of the element centre or of the contact point (which lies on
    the face of the joint's candidate body: the unit above a bed joint, right of a head
    joint). A largest value of 0 (or an intact joint, ``beta = 1``) has no location
    (``None``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from masonry_nscd.case import load_case
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.cycle_tables import write_cycle_tables
from masonry_nscd.io.results_h5 import output_steps, read_fields
from masonry_nscd.io.runfolder import read_curve_csv, read_energy_csv, read_scene_info
from masonry_nscd.io.summary_json import write_summary
from masonry_nscd.post.cycles import cycle_rows, envelope_rows
from masonry_nscd.post.failure import COHESION_LOST_BETA, failure_mode, failure_sequence
from masonry_nscd.post.limit import format_limit, limit_summary

if TYPE_CHECKING:
    from masonry_nscd.io.results_h5 import RunFields

#: Fractions of the peak force between which the initial stiffness is measured.
STIFFNESS_FRACTIONS = (0.10, 0.40)

FloatArray = NDArray[np.float64]


# ---------------------------------------------------------------------------------------------
# The curve
# ---------------------------------------------------------------------------------------------


def horizontal_stage_start(curve: Mapping[str, Sequence[float]],
                           start_s: float | None = None) -> int:
    """Index of the first row of the horizontal stage (see the module docstring)."""
    t = np.asarray(curve["time_s"], dtype=float)
    if start_s is not None:
        idx = np.flatnonzero(t >= start_s - 1e-12)
        return int(idx[0]) if idx.size else len(t)
    ux = np.asarray(curve["ux_mm"], dtype=float)
    moved = np.flatnonzero(ux > 0.0)
    return max(0, int(moved[0]) - 1) if moved.size else len(ux)


def first_crossing(x: Sequence[float], y: Sequence[float], level: float) -> float | None:
    """``x`` where ``y`` first reaches ``level`` from below, linearly interpolated.

    ``None`` if ``y`` never reaches it, or if ``y[0]`` is already at or above it (the crossing
    is then before the data).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    above = np.flatnonzero(y >= level)
    if not above.size or above[0] == 0:
        return None
    i = int(above[0])
    x0, x1, y0, y1 = x[i - 1], x[i], y[i - 1], y[i]
    return float(x0 + (level - y0) * (x1 - x0) / (y1 - y0))


def secant_stiffness(ux_mm: Sequence[float], fx_kN: Sequence[float], f_low_kN: float,
                     f_high_kN: float) -> tuple[float | None, float | None, float | None]:
    """Secant stiffness (kN/mm) between the first crossings of two force levels (kN).

    ``ux_mm``, ``fx_kN``: the horizontal stage, in order. Returns ``(k_kN_mm, u_low_mm,
    u_high_mm)``, with ``None`` where a level is not crossed from below.
    """
    u_lo = first_crossing(ux_mm, fx_kN, f_low_kN)
    u_hi = first_crossing(ux_mm, fx_kN, f_high_kN)
    if u_lo is None or u_hi is None or not u_hi > u_lo:
        return None, u_lo, u_hi
    return (f_high_kN - f_low_kN) / (u_hi - u_lo), u_lo, u_hi


def value_at(x: Sequence[float], y: Sequence[float], x_target: float) -> float | None:
    """``y`` at the first ``x >= x_target``, interpolated linearly; ``None`` if not reached."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    reached = np.flatnonzero(x >= x_target)
    if not reached.size:
        return None
    i = int(reached[0])
    if i == 0 or x[i] == x[i - 1]:
        return float(y[i])
    return float(y[i - 1] + (x_target - x[i - 1]) * (y[i] - y[i - 1]) / (x[i] - x[i - 1]))


def first_branch_rows(ux: Sequence[float]) -> int:
    """How many rows of ``ux`` (in order) come before its first decrease: the first loading
    branch of a cyclic history (all the rows of a monotonic one)."""
    ux = np.asarray(ux, dtype=float)
    down = np.flatnonzero(np.diff(ux) < 0.0)
    return int(down[0]) + 1 if down.size else len(ux)


def curve_summary(curve: Mapping[str, Sequence[float]], *, target_ux_mm: float | None = None,
                  horizontal_start_s: float | None = None,
                  fractions: tuple[float, float] = STIFFNESS_FRACTIONS,
                  first_branch: bool = False) -> dict[str, Any]:
    """The part of the summary that comes from the curve alone (see the module docstring).

    ``curve``: columns of ``force_displacement.csv`` (at least ``step``, ``time_s``, ``ux_mm``,
    ``fx_kN``; ``residual``, ``converged``, ``iterations`` when present). ``target_ux_mm``: the
    displacement at which the force is reported (mm). ``first_branch``: the stiffness of the
    first loading branch, with the fractions of its own largest force (cyclic histories).
    """
    c = {k: np.asarray(v, dtype=float) for k, v in curve.items()}
    n = len(c["time_s"])
    out: dict[str, Any] = {"steps": int(c["step"][-1]) if n else 0,
                           "last_time_s": _num(c["time_s"][-1]) if n else None,
                           "last_ux_mm": _num(c["ux_mm"][-1]) if n else None,
                           "last_fx_kN": _num(c["fx_kN"][-1]) if n else None}
    out.update(_convergence(c))
    i0 = horizontal_stage_start(c, horizontal_start_s)
    stage = {k: v[i0:] for k, v in c.items()}
    out["horizontal_stage_rows"] = len(stage["ux_mm"])
    out["fx_at_horizontal_start_kN"] = _num(stage["fx_kN"][0]) if len(stage["fx_kN"]) else None
    ok = stage["converged"] != 0 if "converged" in stage else np.ones(len(stage["ux_mm"]), bool)
    out["peak_force_unconverged_kN"] = _num(stage["fx_kN"][~ok].max()) if (~ok).any() else None
    stage = {k: v[ok] for k, v in stage.items()}
    ux, fx = stage["ux_mm"], stage["fx_kN"]
    out.update(_peak_and_stiffness(stage, fractions))
    if first_branch:
        n = first_branch_rows(ux)
        branch = _peak_and_stiffness({k: v[:n] for k, v in stage.items()}, fractions)
        out.update({k: v for k, v in branch.items() if k.startswith("stiffness_")
                    or k == "initial_stiffness_kN_mm"})
        out["stiffness_branch_peak_kN"] = branch["peak_force_kN"]
    out["target_ux_mm"] = _num(target_ux_mm)
    at = value_at(ux, fx, target_ux_mm) if target_ux_mm is not None and len(ux) else None
    out["force_at_target_kN"] = _num(at)
    out["target_reached"] = at is not None
    return out


def _convergence(c: Mapping[str, FloatArray]) -> dict[str, Any]:
    conv = c.get("converged")
    res = c.get("residual")
    it = c.get("iterations")
    return {
        "unconverged_steps": int(np.sum(conv == 0)) if conv is not None else None,
        "worst_residual": _num(res.max()) if res is not None and len(res) else None,
        "max_iterations_per_step": int(it.max()) if it is not None and len(it) else None,
        "steps_with_failed_gauss_points": (int(np.sum(c["failed_gauss_points"] > 0))
                                           if "failed_gauss_points" in c else None),
        "steps_subdivided": int(np.sum(c["substeps"] > 1)) if "substeps" in c else None,
    }


def _peak_and_stiffness(stage: Mapping[str, FloatArray],
                        fractions: tuple[float, float]) -> dict[str, Any]:
    """Peak and secant stiffness of the (converged rows of the) horizontal stage."""
    ux, fx = stage["ux_mm"], stage["fx_kN"]
    empty = {"peak_force_kN": None, "ux_at_peak_mm": None, "step_at_peak": None,
             "stiffness_fractions_of_peak": list(fractions), "stiffness_force_low_kN": None,
             "stiffness_force_high_kN": None, "stiffness_ux_low_mm": None,
             "stiffness_ux_high_mm": None, "initial_stiffness_kN_mm": None}
    if not len(fx) or not fx.max() > 0.0:
        return empty
    ip = int(np.argmax(fx))
    f_lo, f_hi = fractions[0] * fx[ip], fractions[1] * fx[ip]
    k, u_lo, u_hi = secant_stiffness(ux[:ip + 1], fx[:ip + 1], f_lo, f_hi)
    return {**empty, "peak_force_kN": _num(fx[ip]), "ux_at_peak_mm": _num(ux[ip]),
            "step_at_peak": int(stage["step"][ip]), "stiffness_force_low_kN": _num(f_lo),
            "stiffness_force_high_kN": _num(f_hi), "stiffness_ux_low_mm": _num(u_lo),
            "stiffness_ux_high_mm": _num(u_hi), "initial_stiffness_kN_mm": _num(k)}


def _scaled(x: float | None, factor: float) -> float | None:
    """``x`` times ``factor``, None for None (a value the scene did not declare)."""
    return None if x is None else x * factor


def _num(x: float | None) -> float | None:
    """A JSON-friendly float: ``None`` for None, NaN and infinities."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _largest_ux_m(curve: Mapping[str, Sequence[float]], step: int) -> float | None:
    """The largest |U_x| of the curve's converged and unconverged steps up to ``step`` (m):
    the displacement a joint's slip is weighed against when the failure mode is named (for a
    cyclic run, the amplitude reached, not the displacement of the moment); None without one."""
    steps = np.asarray(curve.get("step", []), dtype=int)
    ux = np.abs(np.asarray(curve.get("ux_mm", []), dtype=float)[steps <= step])
    ux = ux[np.isfinite(ux)]
    return 1e-3 * float(ux.max()) if ux.size else None


# ---------------------------------------------------------------------------------------------
# The largest damages of one output step, and where they are
# ---------------------------------------------------------------------------------------------


def body_names(scene: Mapping[str, Any]) -> dict[int, str]:
    """Scene body index -> name."""
    return dict(enumerate(scene["bodies"]))


def largest_damages(fields: RunFields, scene: Mapping[str, Any]) -> dict[str, Any]:
    """The largest block and joint damages of one output step, and where they are."""
    centres = fields.nodes_m[fields.hexes].mean(axis=1)
    out: dict[str, Any] = {}
    for name, values in (("block_d_c", fields.d_c), ("block_d_cpp", fields.d_cpp),
                         ("block_d_t", fields.d_t)):
        out[name] = _block_entry(values, centres, fields.block_of_element, scene)
    out["joint_d_coh"] = _joint_entry(fields, scene)
    return out


def _place(scene: Mapping[str, Any], k: int) -> dict[str, Any]:
    """The builder's keys of structure body ``k`` (its name as ``where``)."""
    info = dict(scene["structure"][k])
    keys = {"where": info.pop("name"), "unit_index": k}
    keys.update({key: v for key, v in info.items() if key not in ("body", "kind")})
    return keys


def _block_entry(values: FloatArray, centres: FloatArray, block_of_element: NDArray[np.int64],
                 scene: Mapping[str, Any]) -> dict[str, Any]:
    if not len(values):
        return {"value": None, "where": None}
    e = int(np.argmax(values))
    entry: dict[str, Any] = {"value": _num(values[e]), "elements_above_0.5": int(
        np.sum(values > 0.5))}
    if not values[e] > 0.0:
        return {**entry, "where": None}
    return {**entry, **_place(scene, int(block_of_element[e])), "element": e,
            "x_m": _num(centres[e, 0]), "y_m": _num(centres[e, 1])}


def _joint_entry(fields: RunFields, scene: Mapping[str, Any]) -> dict[str, Any]:
    groups = list(scene["groups"])
    joint_ids = [groups.index(g) for g in scene["joint_groups"]]
    joints = np.flatnonzero(np.isin(fields.contact_group, joint_ids))
    if not joints.size:
        return {"value": None, "where": None}
    beta = fields.joint_beta[joints]
    a = int(joints[np.argmin(beta)])
    entry: dict[str, Any] = {
        "value": _num(fields.joint_d_coh[a]), "beta": _num(fields.joint_beta[a]),
        "d_coh_initial": _num(fields.contact_initial_damage[a]),
        "joint_points": int(joints.size),
        "points_cohesion_lost": int(np.sum(beta < COHESION_LOST_BETA)),
    }
    if not fields.joint_beta[a] < 1.0:
        return {**entry, "where": None}
    x, y = (float(v) for v in fields.contact_points_m[a, :2])
    group = groups[int(fields.contact_group[a])]
    names = body_names(scene)
    cand, ant = (int(b) for b in fields.contact_bodies[a])
    entry.update({"where": f"{group} joint between {names[ant]} and {names[cand]}",
                  "point": a, "joint": group, "x_m": x, "y_m": y})
    structure = [s["body"] for s in scene["structure"]]
    if cand in structure:
        place = _place(scene, structure.index(cand))
        place.pop("where")
        entry.update(place)
    return entry


# ---------------------------------------------------------------------------------------------
# The whole summary
# ---------------------------------------------------------------------------------------------


def push_stage_start(scene: Mapping[str, Any]) -> float:
    """Start (s) of the scene's push stage, whose force-displacement curve is summarised."""
    return next(st["start_s"] for st in scene["stages"] if st["name"] == scene["push_stage"])


def scene_history(scene: Mapping[str, Any] | None) -> dict[str, Any]:
    """The history of ``scene.json`` (a monotonic push for run folders written before it was
    kept)."""
    return dict((scene or {}).get("history") or {"kind": "monotonic", "cycles": []})


def run_cycles(curve: Mapping[str, Sequence[float]],
               scene: Mapping[str, Any]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The rows of ``cycles.csv`` and of ``envelope.csv`` of a run (empty when its history has
    no cycles): the cycles of the history completed by the last row, on the converged rows
    of the horizontal stage and the row before it (:mod:`masonry_nscd.post.cycles`)."""
    cycles = scene_history(scene).get("cycles") or []
    t = np.asarray(curve["time_s"], dtype=float)
    if not cycles or not len(t):
        return [], []
    i0 = max(0, horizontal_stage_start(curve, push_stage_start(scene)) - 1)
    ok = np.asarray(curve["converged"], dtype=float)[i0:] != 0 if "converged" in curve \
        else np.ones(len(t) - i0, dtype=bool)
    ux, fx = (np.asarray(curve[k], dtype=float)[i0:][ok] for k in ("ux_mm", "fx_kN"))
    rows = cycle_rows(t[i0:][ok], ux, fx, cycles, last_time_s=float(t[-1]))
    return rows, envelope_rows(rows)


def _both_directions(curve: Mapping[str, Sequence[float]], start_s: float | None,
                     rows: Sequence[Mapping[str, Any]], planned: int) -> dict[str, Any]:
    """The peaks in both directions (converged rows of the horizontal stage) and the cycles."""
    c = {k: np.asarray(v, dtype=float) for k, v in curve.items()}
    i0 = horizontal_stage_start(c, start_s)
    ok = c["converged"][i0:] != 0 if "converged" in c else np.ones(len(c["ux_mm"]) - i0, bool)
    ux, fx = c["ux_mm"][i0:][ok], c["fx_kN"][i0:][ok]
    out: dict[str, Any] = dict.fromkeys(("peak_force_pos_kN", "ux_at_peak_pos_mm",
                                         "peak_force_neg_kN", "ux_at_peak_neg_mm"))
    if len(fx):
        ip, ineg = int(np.argmax(fx)), int(np.argmin(fx))
        out.update(peak_force_pos_kN=_num(fx[ip]), ux_at_peak_pos_mm=_num(ux[ip]),
                   peak_force_neg_kN=_num(fx[ineg]), ux_at_peak_neg_mm=_num(ux[ineg]))
    out["cycles_planned"] = planned
    out["cycles_completed"] = len(rows)
    out["dissipated_energy_J"] = _num(sum(r["dissipated_energy_J"] for r in rows)) \
        if rows else None
    return out


#: Keys of a push's summary that mean nothing under ground motion (``None`` there).
PUSH_KEYS = ("peak_force_kN", "ux_at_peak_mm", "stiffness_force_low_kN",
             "stiffness_force_high_kN", "stiffness_ux_low_mm", "stiffness_ux_high_mm",
             "initial_stiffness_kN_mm", "force_at_target_kN", "target_ux_mm",
             "peak_force_unconverged_kN")


def ground_motion_summary(curve: Mapping[str, Sequence[float]], start_s: float | None,
                          scene: Mapping[str, Any] | None) -> dict[str, Any]:
    """Peak and residual drift and peak base shear of a ground-motion run (module
    docstring), the push's keys set to ``None``."""
    c = {k: np.asarray(v, dtype=float) for k, v in curve.items()}
    i0 = horizontal_stage_start(c, start_s)
    ok = c["converged"][i0:] != 0 if "converged" in c else np.ones(len(c["ux_mm"]) - i0, bool)
    t, ux, fb = (c[k][i0:][ok] for k in ("time_s", "ux_mm", "fx_bottom_kN"))
    steps = c["step"][i0:][ok]
    height = float((scene or {}).get("wall_height_m") or 0.0)
    history = scene_history(scene)
    out: dict[str, Any] = dict.fromkeys(PUSH_KEYS)
    out.update({"target_reached": False, "measured": (scene or {}).get("measured"),
                "base_motion_direction": history.get("direction"),
                "peak_base_acceleration_m_s2": history.get("peak_acceleration_m_s2"),
                "record_scale": history.get("scale")})
    keys = ("peak_drift_mm", "time_at_peak_drift_s", "peak_drift_ratio_percent",
            "residual_drift_mm", "residual_drift_ratio_percent", "peak_base_shear_kN",
            "time_at_peak_base_shear_s", "step_at_peak")
    out.update(dict.fromkeys(keys))
    if not len(ux):
        return out
    i, j = int(np.argmax(np.abs(ux))), int(np.argmax(np.abs(fb)))
    ratio = (lambda mm: _num(100.0 * abs(mm) / (1e3 * height))) if height > 0 else \
        (lambda mm: None)
    out.update(peak_drift_mm=_num(ux[i]), time_at_peak_drift_s=_num(t[i]),
               peak_drift_ratio_percent=ratio(ux[i]), residual_drift_mm=_num(ux[-1]),
               residual_drift_ratio_percent=ratio(ux[-1]), peak_base_shear_kN=_num(fb[j]),
               time_at_peak_base_shear_s=_num(t[j]), step_at_peak=int(steps[i]))
    return out


def read_energy(outdir: Path | str) -> dict[str, Any]:
    """The energy balance of a run folder's ``energy.csv``: the terms of its last row (J),
    its relative imbalance and the worst over the rows; ``{}`` without the file or rows."""
    rows = read_energy_csv(outdir)
    if rows is None or not len(rows.get("step", [])):
        return {}
    last = {k: _num(v[-1]) for k, v in rows.items() if k not in ("step", "relative_imbalance")}
    return {"energy": last,
            "energy_relative_imbalance": _num(rows["relative_imbalance"][-1]),
            "energy_worst_relative_imbalance": _num(rows["relative_imbalance"].max())}


def compute_summary(curve: Mapping[str, Sequence[float]], *, target_ux_mm: float | None = None,
                    horizontal_start_s: float | None = None, fields: RunFields | None = None,
                    scene: Mapping[str, Any] | None = None,
                    fractions: tuple[float, float] = STIFFNESS_FRACTIONS) -> dict[str, Any]:
    """The run summary from the curve and, if given, the fields of the last output step (with
    the scene's ``scene.json``, which says where things are, and the history: a cyclic or
    tabulated one adds the peaks in both directions and the cycles).

    A pure function: see the module docstring for the definitions. Keys carry their units.
    """
    history = scene_history(scene)
    ground = history["kind"] == "ground_motion"
    cyclic = history["kind"] not in ("monotonic", "ground_motion")
    out = curve_summary(curve, target_ux_mm=target_ux_mm, horizontal_start_s=horizontal_start_s,
                        fractions=fractions, first_branch=cyclic)
    out["history"] = history["kind"]
    if ground:
        out.update(ground_motion_summary(curve, horizontal_start_s, scene))
    if cyclic:
        rows, _ = run_cycles(curve, scene)
        out.update(_both_directions(curve, horizontal_start_s, rows,
                                    len(history.get("cycles") or [])))
    last = {k: list(v)[-1] for k, v in curve.items() if len(v)}
    out["curve_last_max_joint_damage"] = _num(last.get("max_joint_damage"))
    out["curve_last_max_block_damage"] = _num(last.get("max_block_damage"))
    out["curve_last_max_d_cpp"] = _num(last.get("max_d_cpp"))
    if fields is not None:
        ux_by_step = dict(zip(np.asarray(curve["step"], dtype=int),
                              np.asarray(curve["ux_mm"], dtype=float), strict=True))
        out["damage_step"] = fields.step
        out["damage_time_s"] = fields.time_s
        out["damage_ux_mm"] = _num(ux_by_step.get(fields.step))
        out["largest_damage"] = largest_damages(fields, scene)
        out["failure_mode"] = failure_mode(fields, scene, fields.joint_u_m,
                                           _largest_ux_m(curve, fields.step))
    return out


def summarize_run(outdir: Path | str,
                  curve: Mapping[str, Sequence[float]] | None = None) -> dict[str, Any]:
    """The summary of a finished or interrupted run folder.

    Reads ``case.yaml``, ``scene.json``, ``force_displacement.csv`` (or takes ``curve``, e.g.
    the run's in-memory curve when the CSV may not be flushed) and the last output step of
    ``results.h5`` when there is one.
    """
    outdir = Path(outdir)
    case = load_case(outdir / rf.CASE, check_files=False)
    scene = read_scene_info(outdir)
    if curve is None:
        curve = read_curve_csv(outdir / rf.CSV)
    h5 = outdir / rf.RESULTS
    fields = read_fields(h5) if h5.exists() else None
    start = push_stage_start(scene)
    target = scene.get("target_m")
    summary = compute_summary(curve, target_ux_mm=None if target is None else 1e3 * target,
                              horizontal_start_s=start, fields=fields, scene=scene)
    if fields is not None and summary.get("step_at_peak") is not None:
        steps = [k for k, _ in output_steps(h5)]
        peak = min(steps, key=lambda k: (abs(k - summary["step_at_peak"]), -k))
        at_peak = read_fields(h5, peak)
        ux_by_step = dict(zip(np.asarray(curve["step"], dtype=int),
                              (float(v) for v in curve["ux_mm"]), strict=True))
        summary["failure_mode_at_peak"] = {
            "step": peak, **failure_mode(at_peak, scene, at_peak.joint_u_m,
                                         _largest_ux_m(curve, peak))}
        summary["failure_sequence"] = failure_sequence(h5, scene, ux_by_step)
    if scene.get("limit_state"):  # an arch: its status, collapse and hinges
        keep = ("steps", "last_time_s", "unconverged_steps", "worst_residual",
                "max_iterations_per_step", "steps_with_failed_gauss_points", "steps_subdivided",
                "largest_damage")
        last = {k: _num(list(v)[-1]) for k, v in curve.items() if len(v)}
        reaction = scene.get("reaction_names") or ["left", "right"]  # an arch's supports
        return {"case_name": case.name, "builder": scene.get("builder"),
                "block_material": case.blocks.material, "joint_law": case.joint.law,
                **limit_summary(outdir, scene, fields),
                "support_forces_last_kN": {  # the force of each support on the structure
                    reaction[0]: [last.get("fx_kN"), last.get("fy_kN")],
                    reaction[1]: [last.get("fx_bottom_kN"), last.get("fy_bottom_kN")]},
                **{k: summary[k] for k in keep if k in summary}}
    head = {"case_name": case.name, "block_material": case.blocks.material,
            "vertical_stress_MPa": _scaled(scene.get("vertical_stress_Pa"), 1e-6),
            "vertical_force_kN": _scaled(scene.get("vertical_force_N"), 1e-3),
            "horizontal_start_s": start, **read_energy(outdir), "stiffness_definition": (
                "secant between the first crossings of 10 % and 40 % of the peak force in the "
                "horizontal stage, displacements interpolated linearly"
                + ("" if summary["history"] == "monotonic" else
                   "; on the first loading branch (up to the first reversal), of its own "
                   "largest force"))}
    return {**head, **summary}


def _fmt(x: float | None, spec: str, unit: str = "") -> str:
    return "n/a" if x is None else f"{x:{spec}}{unit}"


def format_summary(s: Mapping[str, Any]) -> list[str]:
    """A short human report of a summary, a few lines."""
    if "status" in s and "collapse" in s:  # a limit-state run (masonry_nscd/post/limit.py)
        return [*format_limit(s), f"steps not converged {s['unconverged_steps']} (worst "
                f"residual {_fmt(s['worst_residual'], '.2e')})"
                + (f"; {s['steps_subdivided']} steps made again as smaller ones"
                   if s.get("steps_subdivided") else "")]
    cyclic = s.get("history", "monotonic") not in ("monotonic", "ground_motion")
    if s.get("history") == "ground_motion":
        peak = (f"peak drift {_fmt(s['peak_drift_mm'], '.4g', ' mm')} "
                f"({_fmt(s['peak_drift_ratio_percent'], '.3g', ' %')} of the height) at t = "
                f"{_fmt(s['time_at_peak_drift_s'], '.4g', ' s')}; residual drift "
                f"{_fmt(s['residual_drift_mm'], '.4g', ' mm')}; peak base shear "
                f"{_fmt(s['peak_base_shear_kN'], '.4g', ' kN')} at t = "
                f"{_fmt(s['time_at_peak_base_shear_s'], '.4g', ' s')}")
    elif cyclic:
        peak = (f"peak forces {_fmt(s['peak_force_pos_kN'], '.4g', ' kN')} at Ux "
                f"{_fmt(s['ux_at_peak_pos_mm'], '.4g', ' mm')} and "
                f"{_fmt(s['peak_force_neg_kN'], '.4g', ' kN')} at Ux "
                f"{_fmt(s['ux_at_peak_neg_mm'], '.4g', ' mm')}; {s['cycles_completed']} of "
                f"{s['cycles_planned']} cycles, {_fmt(s['dissipated_energy_J'], '.4g', ' J')} "
                f"dissipated ({rf.CYCLES}, {rf.ENVELOPE})")
    else:
        peak = (f"peak force {_fmt(s['peak_force_kN'], '.4g', ' kN')} at Ux "
                f"{_fmt(s['ux_at_peak_mm'], '.4g', ' mm')}; force at Ux = "
                f"{_fmt(s['target_ux_mm'], '.4g', ' mm')}: "
                + (_fmt(s["force_at_target_kN"], ".4g", " kN") if s["target_reached"]
                   else f"not reached (last Ux {_fmt(s['last_ux_mm'], '.4g', ' mm')})"))
    lines = [] if s.get("history") == "ground_motion" else [
        (f"initial stiffness {_fmt(s['initial_stiffness_kN_mm'], '.4g', ' kN/mm')} (secant "
         f"between {_fmt(s['stiffness_force_low_kN'], '.4g')} and "
         f"{_fmt(s['stiffness_force_high_kN'], '.4g')} kN, 10 % and 40 % of the "
         + ("first branch's largest force)" if cyclic else "peak)"))]
    lines += [
        peak,
        f"steps not converged {s['unconverged_steps']} (worst residual "
        f"{_fmt(s['worst_residual'], '.2e')}"
        + (f"; {s['steps_with_failed_gauss_points']} with failed ENDO3D Gauss points"
           if s.get("steps_with_failed_gauss_points") else "") + ")"
        + (f"; {s['steps_subdivided']} steps made again as smaller ones"
           if s.get("steps_subdivided") else "")
        + (f"; their largest force, left out of the peak: {s['peak_force_unconverged_kN']:.4g} kN"
           if s.get("peak_force_unconverged_kN") is not None else ""),
    ]
    if s.get("energy"):
        e = s["energy"]
        lines.append(f"energy: external work {_fmt(e['external_work_J'], '.4g', ' J')}, "
                     f"dissipated {_fmt(sum(e[k] for k in e if k.startswith('dissipated')), '.4g', ' J')}"
                     f", numerical {_fmt(e['numerical_J'], '.4g', ' J')}; relative imbalance "
                     f"{_fmt(s['energy_relative_imbalance'], '.2e')} (worst "
                     f"{_fmt(s['energy_worst_relative_imbalance'], '.2e')}; {rf.ENERGY})")
    for name, e in (s.get("largest_damage") or {}).items():
        if e.get("where"):
            where = f" at {e['where']} (x {e['x_m']:.3f}, y {e['y_m']:.3f} m)"
        elif name == "joint_d_coh":
            where = " (the initial damage: no joint damaged further)"
        else:
            where = " (undamaged)"
        lines.append(f"largest {name.replace('_', ' ', 1)} {_fmt(e['value'], '.6g')}{where}")
    for key, when in (("failure_mode_at_peak", "at the peak"), ("failure_mode", "at the end")):
        if s.get(key):
            lines.append(f"failure mode {when}: {s[key]['mode']}")
    return lines


def report_run(outdir: Path | str, log: Callable[[str], None],
               curve: Mapping[str, Sequence[float]] | None = None) -> dict[str, Any] | None:
    """Summarise a run folder, write ``summary.json`` and log the short report.

    Never raises for an ordinary error (a report must not lose a run): the problem is logged
    and ``None`` returned.
    """
    try:
        summary = summarize_run(outdir, curve)
        path = write_summary(outdir, summary)
        if summary.get("history", "monotonic") not in ("monotonic", "ground_motion"):
            rows, envelope = run_cycles(curve if curve is not None else
                                        read_curve_csv(Path(outdir) / rf.CSV),
                                        read_scene_info(outdir))
            write_cycle_tables(outdir, rows, envelope)
    except Exception as exc:  # noqa: BLE001 (a bad report must not fail a finished run)
        log(f"summary not written: {type(exc).__name__}: {exc}")
        return None
    for line in format_summary(summary):
        log(f"summary: {line}")
    log(f"summary written to {path}")
    return summary
