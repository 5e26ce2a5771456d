"""Figures of finished (or interrupted) runs, as PNG files: curves and damage maps.

Matplotlib is used through its object-oriented API (``matplotlib.figure.Figure``, which draws
with the Agg backend): no window, no pyplot state, works on a machine without a display.

Figures
-------
``force_displacement.png`` (:func:`plot_curves`)
    ``F_x`` (kN) against ``U_x`` (mm) of the horizontal stage of every run on one chart, the
    converged steps as lines (the force of a step whose solver did not converge is drawn as a
    grey cross and does not set the scale), the peak of each run marked, and the study's
    initial slope (71 kN/mm) as a dashed line from the origin. A second panel zooms on the
    start, where the slopes are compared. Labels: case name, sigma_N, block material and the
    initial stiffness of the run's summary (secant 10-40 % of the peak, :mod:`report`); what
    every run shares is said once, above the charts, and more than eight curves (a sweep) put
    their legend below the charts, in columns.
``cycles_<run>.png`` (:func:`plot_cycles`, runs whose history has cycles)
    Three panels: the hysteresis loops ``F_x`` against ``U_x``, each cycle of the history in
    its colour (a colour scale over the cycle number), the envelope of each direction on top
    (the peak-force points of the first cycle at each amplitude, :mod:`post.cycles`); the two
    envelopes as ``|F_x|`` against ``|U_x|``, the negative one mirrored onto the positive, so
    that an asymmetry shows; the work done over each cycle (J, bars in the cycle's colour) with
    the equivalent viscous damping ratio (dots, right axis).
``ground_motion_<run>.png`` (:func:`plot_ground_motion`, ground-motion runs)
    Against time: the base acceleration (the record, scaled, when its file can be read), the
    drift (``U_x``: the top relative to the base, peak and residual marked), the base shear
    (``F_x,bottom``), and the energy terms of ``energy.csv`` (external work, kinetic, elastic,
    dissipated by friction, cohesion, impacts and the blocks, numerical, and the imbalance);
    beside them the base shear against the drift. A ground-motion run is left out of
    ``force_displacement.png`` (it has no push).
``damage_<run>_ux_<U>mm.png`` (:func:`plot_damage_map`)
    The wall's face (x-y plane) at the output step of ``results.h5`` nearest to ``U_x = U``,
    element by element (each unit is 1 or more elements; the joints are the gaps between the
    units), four panels with colour scales fixed to [0, 1] so that runs can be compared:

    * block crushing: the post-peak compressive damage ``d_c`` (the pre-peak damage
      ``d_cpp`` is drawn on its own: it grows under the pre-compression alone, to about 0.7
      at 0.5 MPa with the study's ``eps_pic_c``, and would hide the crushing in a
      ``max(d_c, d_cpp)`` map);
    * the pre-peak compressive damage ``d_cpp``;
    * block tensile cracking: the largest tensile damage ``d_t`` of the element;
    * joints: the cohesion lost since the start, ``1 - beta`` (0 as built, 1 cohesion lost),
      at the contact points of the scene's joint groups (bed and head joints, not the glue),
      drawn as short segments in the middle of the joint (half the point's gap from it, along
      its normal), as long as the points' tributary length. ``d_coh = 1 - beta (1 - d_0)``
      starts at ``d_coh_initial`` (0.99944 in the study), so ``d_coh`` itself would be one
      colour.

    Coordinates are the reference ones, or the deformed ones with the displacements
    multiplied by ``magnify`` (``magnify = 0``: undeformed).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.figure_files import save_png, slug
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.results_h5 import output_steps, read_fields
from masonry_nscd.io.runfolder import read_curve_csv, read_energy_csv, read_scene_info
from masonry_nscd.plots_limit import plot_limit_runs
from masonry_nscd.post.cycles import cut, envelope_arrays
from masonry_nscd.report import (
    compute_summary,
    horizontal_stage_start,
    push_stage_start,
    run_cycles,
)

if TYPE_CHECKING:
    from masonry_nscd.io.results_h5 import RunFields

#: The study's initial stiffness of the wall (kN/mm), the same for the three vertical stresses.
REFERENCE_STIFFNESS_KN_MM = 71.0
DAMAGE_CMAP = "YlOrRd"


class PlotInputError(ValueError):
    """A run folder that cannot be plotted, or a bad option (exit code 2)."""


@dataclass
class RunData:
    """What the figures need of one run folder."""

    outdir: Path
    case: Any  # masonry_nscd.case.Case
    scene: dict[str, Any]  # scene.json
    curve: dict[str, NDArray[np.float64]]
    summary: dict[str, Any]
    label: str = ""

    @property
    def has_fields(self) -> bool:
        return (self.outdir / rf.RESULTS).exists()


def load_run(outdir: Path | str) -> RunData:
    """Read the case and the curve of a run folder (raises :class:`PlotInputError`)."""
    outdir = Path(outdir)
    csv_path = outdir / rf.CSV
    if not csv_path.exists():
        raise PlotInputError(f"{outdir}: not a run folder (no {rf.CSV})")
    try:
        case = load_case(outdir / rf.CASE, check_files=False)
    except CaseError as exc:
        raise PlotInputError(f"{outdir}: cannot read its {rf.CASE}: {exc.messages[0]}") from None
    try:
        scene = read_scene_info(outdir)
        curve = read_curve_csv(csv_path)
    except (OSError, ValueError) as exc:
        raise PlotInputError(f"{exc}") from None
    target = scene.get("target_m")
    summary = compute_summary(curve, target_ux_mm=None if target is None else 1e3 * target,
                              horizontal_start_s=push_stage_start(scene), scene=scene)
    return RunData(outdir, case, scene, curve, summary)


def label_runs(runs: Sequence[RunData]) -> None:
    """Set each run's label: the case name, or the folder name when case names repeat."""
    names = [r.case.name for r in runs]
    for r in runs:
        r.label = r.case.name if names.count(r.case.name) == 1 else r.outdir.name


# ---------------------------------------------------------------------------------------------
# Force-displacement curves
# ---------------------------------------------------------------------------------------------


def _stage(run: RunData) -> tuple[NDArray, NDArray, NDArray]:
    """``ux_mm``, ``fx_kN`` and the converged mask of the horizontal stage."""
    c = run.curve
    i0 = horizontal_stage_start(c, push_stage_start(run.scene))
    ok = c["converged"][i0:] != 0 if "converged" in c else np.ones(len(c["ux_mm"]) - i0, bool)
    return c["ux_mm"][i0:], c["fx_kN"][i0:], ok


def _label_parts(run: RunData) -> list[str]:
    """What tells a curve apart: stress, block material and initial stiffness."""
    k = run.summary["initial_stiffness_kN_mm"]
    return [f"$\\sigma_N$ = {run.case.loading.vertical_stress.value_Pa / 1e6:g} MPa",
            f"{run.case.blocks.material} blocks"] + ([f"k = {k:.3g} kN/mm"] if k is not None else [])


def _curve_labels(runs: Sequence[RunData]) -> tuple[list[str], str]:
    """Each curve's label, and the parts every curve shares (said once, above the charts, when
    there are several curves)."""
    parts = [_label_parts(r) for r in runs]
    shared = [p for p in parts[0] if len(runs) > 1 and all(p in q for q in parts)]
    labels = []
    for run, own in zip(runs, parts):
        rest = [p for p in own if p not in shared]
        labels.append(run.label + (f" ({', '.join(rest)})" if rest else ""))
    return labels, ", ".join(shared)


#: More curves than this and the legend goes below the charts, in this many columns.
LEGEND_INSIDE_MAX = 8
LEGEND_COLUMNS = 5


def plot_curves(runs: Sequence[RunData], path: Path,
                reference_kN_mm: float = REFERENCE_STIFFNESS_KN_MM) -> Path:
    """The force-displacement curves of ``runs`` on one chart (see the module docstring)."""
    from matplotlib.figure import Figure

    # the legend's rows below the charts: a line per run and the study's slope
    legend_rows = -(-(len(runs) + 1) // LEGEND_COLUMNS) if len(runs) > LEGEND_INSIDE_MAX else 0
    fig = Figure(figsize=(13, 5.5 + 0.22 * legend_rows), layout="constrained")
    ax_all, ax_zoom = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    f_top, f_bottom, u_zoom, u_left = 1.0, 0.0, 0.0, 0.0
    labels, shared = _curve_labels(runs)
    for n, (run, label) in enumerate(zip(runs, labels)):
        ux, fx, ok = _stage(run)
        color = f"C{n % 10}"
        for ax in (ax_all, ax_zoom):
            ax.plot(ux[ok], fx[ok], color=color, lw=1.6, label=label)
            if (~ok).any():
                ax.plot(ux[~ok], fx[~ok], "x", color="0.5", ms=4)
            s = run.summary
            if s["peak_force_kN"] is not None:
                ax.plot(s["ux_at_peak_mm"], s["peak_force_kN"], "o", color=color, ms=6)
        if ok.any():
            f_top = max(f_top, float(fx[ok].max()))
            f_bottom = min(f_bottom, float(fx[ok].min()))
            reach = np.flatnonzero(fx[ok] >= 0.6 * fx[ok].max())
            u_zoom = max(u_zoom, float(ux[ok][reach[0]]) if reach.size else 0.0)
            u_left = min(u_left, float(ux[ok].min()))
    u_ref = 1.1 * f_top / reference_kN_mm
    for ax in (ax_all, ax_zoom):
        ax.plot([0.0, u_ref], [0.0, reference_kN_mm * u_ref], "k--", lw=1.2,
                label=f"study's initial slope, {reference_kN_mm:g} kN/mm")
        ax.set_xlabel("$U_x$, horizontal displacement of the top beam (mm)")
        ax.set_ylabel("$F_x$, horizontal force on the wall (kN)")
        ax.grid(True, alpha=0.3)
        ax.set_ylim(f_bottom - 0.05 * (f_top - f_bottom), 1.1 * f_top)
    ax_zoom.set_xlim(0.0, max(u_zoom, u_ref, 1e-6) * 1.2)
    ax_all.set_xlim(left=u_left * 1.05)
    ax_all.set_title("Force-displacement, horizontal stage (dots: peaks; x: steps not converged)")
    ax_zoom.set_title("Start of the horizontal stage: initial slopes")
    if shared:
        fig.suptitle(f"{len(runs)} runs, all with {shared}")
    if len(runs) > LEGEND_INSIDE_MAX:
        fig.legend(*ax_all.get_legend_handles_labels(), loc="outside lower center", fontsize=8,
                   ncol=LEGEND_COLUMNS)
    else:
        ax_all.legend(fontsize=8, loc="best")
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------------
# Cycles
# ---------------------------------------------------------------------------------------------


def plot_cycles(run: RunData, path: Path) -> Path | None:
    """Loops, envelopes and energy per cycle of ``run`` (module docstring); None if the run
    has no completed cycle."""
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    rows, env = run_cycles(run.curve, run.scene)
    if not rows:
        return None
    c = run.curve
    ok = c["converged"] != 0 if "converged" in c else np.ones(len(c["time_s"]), bool)
    t, u, f = c["time_s"][ok], c["ux_mm"][ok], c["fx_kN"][ok]
    n = len(rows)
    cmap, norm = colormaps["viridis"], Normalize(1, max(n, 2))
    fig = Figure(figsize=(16, 5.2), layout="constrained")
    ax_loops, ax_env, ax_energy = fig.subplots(1, 3, gridspec_kw={"width_ratios": [5, 3, 3]})
    for r in rows:
        uu, ff = cut(t, u, f, r["start_s"], r["end_s"])
        ax_loops.plot(uu, ff, color=cmap(norm(r["cycle"])), lw=1.1)
    for direction, color, sign in (("positive", "k", 1.0), ("negative", "C3", -1.0)):
        eu, ef = envelope_arrays(env, direction)
        ax_loops.plot(eu, ef, "o-", color=color, ms=4, lw=1.2, label=f"envelope, {direction}")
        ax_env.plot(sign * eu, sign * ef, "o-", color=color, ms=4, lw=1.4,
                    label=f"{direction} direction" + (" (mirrored)" if sign < 0 else ""))
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax_loops, label="cycle")
    bar.set_ticks(np.unique(np.linspace(1, n, min(n, 10)).round().astype(int)))
    ax_loops.set_title(f"{run.label}: hysteresis loops ({n} cycles)")
    ax_loops.set_xlabel("$U_x$, horizontal displacement of the top beam (mm)")
    ax_loops.set_ylabel("$F_x$, horizontal force on the wall (kN)")
    ax_env.set_title("Envelopes (first cycle at each amplitude)")
    ax_env.set_xlabel("$|U_x|$ at the peak force (mm)")
    ax_env.set_ylabel("$|F_x|$, peak force (kN)")
    ax_env.set_xlim(left=0.0)
    ax_env.set_ylim(bottom=0.0)
    idx = np.array([r["cycle"] for r in rows])
    energy = np.array([r["dissipated_energy_J"] for r in rows])
    ax_energy.bar(idx, energy, color=[cmap(norm(i)) for i in idx])
    ax_energy.set_xlabel("cycle")
    ax_energy.set_xticks(np.unique(np.linspace(1, n, min(n, 12)).round().astype(int)))
    ax_energy.set_ylabel("work over the cycle, $\\oint F\\,dU$ (J)")
    ax_energy.set_title("Energy dissipated per cycle, damping ratio")
    ax_xi = ax_energy.twinx()
    xi = np.array([np.nan if r["damping_ratio_eq"] is None else r["damping_ratio_eq"]
                   for r in rows])
    ax_xi.plot(idx, xi, "o", color="C1", ms=5)
    ax_xi.set_ylabel("equivalent viscous damping ratio (dimensionless)", color="C1")
    ax_xi.set_ylim(bottom=0.0)
    for ax in (ax_loops, ax_env):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8, loc="best")
    ax_energy.grid(True, alpha=0.3, axis="y")
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------------
# Ground motion
# ---------------------------------------------------------------------------------------------

#: The energy terms drawn (columns of energy.csv) and their labels.
ENERGY_CURVES = (("external_work_J", "external work"), ("kinetic_J", "kinetic"),
                 ("elastic_blocks_J", "elastic, blocks"), ("elastic_joints_J", "elastic, joints"),
                 ("dissipated_friction_J", "friction"), ("dissipated_cohesion_J", "cohesion"),
                 ("dissipated_impacts_J", "impacts"), ("dissipated_blocks_J", "blocks (ENDO3D)"),
                 ("numerical_J", "numerical (scheme)"))


def is_ground_motion(run: RunData) -> bool:
    return run.summary.get("history") == "ground_motion"


def plot_ground_motion(run: RunData, path: Path) -> Path:
    """Time histories of a ground-motion run (module docstring)."""
    from matplotlib.figure import Figure

    c, s = run.curve, run.summary
    ok = c["converged"] != 0 if "converged" in c else np.ones(len(c["time_s"]), bool)
    t = c["time_s"]
    fig = Figure(figsize=(15, 10), layout="constrained")
    grid = fig.add_gridspec(4, 2, width_ratios=[3, 2])
    ax_a = fig.add_subplot(grid[0, 0])
    ax_u, ax_f, ax_e = (fig.add_subplot(grid[i, 0], sharex=ax_a) for i in (1, 2, 3))
    ax_h = fig.add_subplot(grid[:2, 1])
    gm = run.case.loading.ground_motion
    try:
        g = gm.history()
        tt = np.linspace(0.0, float(t[-1]) if len(t) else g.end_s, 4000)
        ax_a.plot(tt, [g.acceleration(x) for x in tt], color="0.3", lw=0.8)
        ax_a.set_title(f"{run.label}: base acceleration along {gm.direction} (record x "
                       f"{gm.scale:g}, peak {g.peak_acceleration_m_s2:.3g} m/s$^2$)")
    except (ValueError, AttributeError) as exc:
        ax_a.set_title(f"{run.label}: base acceleration not drawn ({exc})")
    ax_a.set_ylabel("base acceleration (m/s$^2$)")
    ax_u.plot(t[ok], c["ux_mm"][ok], color="C0", lw=1.0)
    if s.get("peak_drift_mm") is not None:
        ax_u.plot(s["time_at_peak_drift_s"], s["peak_drift_mm"], "o", color="C3",
                  label=f"peak {s['peak_drift_mm']:.3g} mm")
        ax_u.axhline(s["residual_drift_mm"], color="C2", ls="--", lw=1,
                     label=f"residual {s['residual_drift_mm']:.3g} mm")
        ax_u.legend(fontsize=8, loc="best")
    ax_u.set_ylabel("drift (mm)")
    ax_u.set_title(f"drift: {s.get('measured') or 'U_x'}", fontsize=9)
    ax_f.plot(t[ok], c["fx_bottom_kN"][ok], color="C1", lw=1.0)
    ax_f.set_ylabel("base shear $F_{x,bottom}$ (kN)")
    e = read_energy_csv(run.outdir)
    if e is not None:
        for key, label in ENERGY_CURVES:
            if key in e and np.abs(e[key]).max() > 0.0:
                ax_e.plot(e["time_s"], e[key], lw=1.3 if key == "external_work_J" else 1.0,
                          color="k" if key == "external_work_J" else None, label=label)
        if "imbalance_J" in e:
            ax_e.plot(e["time_s"], e["imbalance_J"], "k:", lw=1.0, label="imbalance")
        ax_e.legend(fontsize=7, ncol=2, loc="upper left")
        ax_e.set_title(f"energy balance ({rf.ENERGY}): external work = the sum of the others",
                       fontsize=9)
    ax_e.set_ylabel("energy (J)")
    ax_e.set_xlabel("time (s)")
    ax_h.plot(c["ux_mm"][ok], c["fx_bottom_kN"][ok], color="C1", lw=0.8)
    ax_h.set_xlabel("drift (mm)")
    ax_h.set_ylabel("base shear (kN)")
    ax_h.set_title("base shear against drift")
    for ax in (ax_a, ax_u, ax_f, ax_e, ax_h):
        ax.grid(True, alpha=0.3)
    return save_png(fig, path)


# ---------------------------------------------------------------------------------------------
# Damage maps
# ---------------------------------------------------------------------------------------------


def nearest_output_step(run: RunData, ux_mm: float) -> int:
    """The output step of ``results.h5`` whose ``U_x`` is nearest to ``ux_mm`` (the latest one
    among equals, so that ``0`` gives the state just before the horizontal stage)."""
    steps = [s for s, _ in output_steps(run.outdir / rf.RESULTS)]
    if not steps:
        raise PlotInputError(f"{run.outdir}: {rf.RESULTS} has no output step")
    ux_of = dict(zip(run.curve["step"].astype(int), run.curve["ux_mm"], strict=True))
    known = [s for s in steps if s in ux_of]
    if not known:
        return steps[-1]
    dist = np.array([abs(ux_of[s] - ux_mm) for s in known])
    best = np.flatnonzero(dist <= dist.min() + 1e-12)
    return known[int(best[-1])]


def _element_polygons(fields: RunFields, disp: NDArray, magnify: float) -> NDArray:
    """(ne, 4, 2) corners of each element's z-min face (VTK order: counter-clockwise), m."""
    xy = fields.nodes_m[:, :2] + magnify * disp[:, :2]
    return xy[fields.hexes[:, :4]]


def joint_segments(fields: RunFields, joint_ids: Sequence[int], disp: NDArray,
                   magnify: float) -> tuple[NDArray, NDArray]:
    """Segments ``(n, 2, 2)`` (m) in the middle of the joints, and their ``1 - beta``.

    The contact points of ``joint_ids`` groups that share (x, y) (they differ in z) are merged:
    the segment lies half the gap from them across the joint (along the normal, which points
    from the antagonist to the candidate), across the normal in the wall's plane, as long as
    their area over the wall's thickness; its value the largest. With ``magnify``, a segment
    moves with the face of the candidate body (displacement interpolated linearly along the
    face's edge at the front of the wall).
    """
    idx = np.flatnonzero(np.isin(fields.contact_group, joint_ids))
    if not idx.size:
        return np.zeros((0, 2, 2)), np.zeros(0)
    thickness = float(np.ptp(fields.nodes_m[:, 2])) or 1.0
    keys: dict[tuple[float, float], list[int]] = {}
    for a in idx:
        x, y = fields.contact_points_m[a, :2]
        keys.setdefault((round(x, 6), round(y, 6)), []).append(a)
    segs, vals = [], []
    for members in keys.values():
        a = members[0]
        n = fields.contact_frame[a, 0, :2]
        along = np.array([-n[1], n[0]]) / (np.linalg.norm(n) or 1.0)
        mid = fields.contact_points_m[a, :2] - 0.5 * fields.contact_gap_m[a] * n
        half = 0.5 * float(fields.contact_area_m2[members].sum()) / thickness
        seg = np.array([mid - half * along, mid + half * along])
        if magnify:
            seg = seg + magnify * _face_displacement(fields, disp, a, along)
        segs.append(seg)
        vals.append(float(1.0 - fields.joint_beta[members].min()))
    return np.array(segs), np.array(vals)


def _face_displacement(fields: RunFields, disp: NDArray, a: int, along: NDArray) -> NDArray:
    """In-plane displacement (m) at contact point ``a``: linear along the front (z-min) edge of
    the candidate body's face that carries it."""
    body = int(fields.contact_bodies[a, 0])
    if body not in fields.structure_bodies:
        return np.zeros(2)
    k = int(np.flatnonzero(fields.structure_bodies == body)[0])
    ids = np.unique(fields.hexes[fields.block_of_element == k])
    nodes = fields.nodes_m
    x = fields.contact_points_m[a]
    n = fields.contact_frame[a, 0]
    ids = ids[(nodes[ids, 2] <= nodes[:, 2].min() + 1e-9)
              & (np.abs((nodes[ids] - x) @ n) < 1e-6 * max(1.0, np.abs(x).max()))]
    if not ids.size:
        return np.zeros(2)
    s = nodes[ids, :2] @ along
    order = np.argsort(s)
    return np.array([np.interp(x[:2] @ along, s[order], disp[ids[order], d]) for d in (0, 1)])


def plot_damage_map(run: RunData, step: int, path: Path, magnify: float = 0.0) -> Path:
    """The four damage panels of ``run`` at output ``step`` (see the module docstring)."""
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    case = run.case
    fields = read_fields(run.outdir / rf.RESULTS, step)
    disp = fields.nodal_displacement_m if fields.nodal_displacement_m is not None \
        else np.zeros_like(fields.nodes_m)
    polys = _element_polygons(fields, disp, magnify)
    groups = list(run.scene["groups"])
    segs, jvals = joint_segments(fields, [groups.index(g) for g in run.scene["joint_groups"]],
                                 disp, magnify)
    fig = Figure(figsize=(14, 9.5), layout="constrained")
    axes = fig.subplots(2, 2)
    panels = [
        (fields.d_c, "Block crushing", "post-peak compressive damage $d_c$"),
        (fields.d_cpp, "Block pre-peak compressive damage", "$d_{cpp}$"),
        (fields.d_t, "Block tensile cracking", "largest crack damage $d_t$"),
    ]
    for ax, (values, title, what) in zip(axes.flat, panels, strict=False):
        pc = PolyCollection(polys, array=values, cmap=DAMAGE_CMAP, clim=(0.0, 1.0),
                            edgecolors="0.55", linewidths=0.3)
        ax.add_collection(pc)
        fig.colorbar(pc, ax=ax, shrink=0.85, label=f"{what} (dimensionless)")
        ax.set_title(f"{title}: {what}, largest {values.max():.3g}")
    ax = axes.flat[3]
    ax.add_collection(PolyCollection(polys, facecolors="0.93", edgecolors="0.7",
                                     linewidths=0.3))
    lc = LineCollection(segs, array=jvals, cmap=DAMAGE_CMAP, clim=(0.0, 1.0), linewidths=3.5)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, shrink=0.85,
                 label=r"cohesion lost $1 - \beta$; $d_{coh} = 1 - \beta\,(1 - d_{coh,0})$")
    ax.set_title(r"Joint damage: cohesion lost since the start $1 - \beta$"
                 + (f" (largest {jvals.max():.3g})" if len(jvals) else ""))
    _frame_axes(axes.flat, polys)
    ux, fx = _ux_fx_at(run, fields.step)
    shape = f", displacements x {magnify:g}" if magnify else ", undeformed shape"
    fig.suptitle(f"{run.label}: damage at $U_x$ = {ux:.3f} mm, $F_x$ = {fx:.4g} kN "
                 f"(step {fields.step}, t = {fields.time_s:.4f} s; $\\sigma_N$ = "
                 f"{case.loading.vertical_stress.value_Pa / 1e6:g} MPa, "
                 f"{case.blocks.material} blocks{shape})")
    return save_png(fig, path)


def _frame_axes(axes, polys: NDArray) -> None:
    lo, hi = polys.reshape(-1, 2).min(axis=0), polys.reshape(-1, 2).max(axis=0)
    pad = 0.03 * float(max(hi - lo))
    for ax in axes:
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")


def _ux_fx_at(run: RunData, step: int) -> tuple[float, float]:
    rows = np.flatnonzero(run.curve["step"].astype(int) == step)
    if not rows.size:
        return math.nan, math.nan
    return float(run.curve["ux_mm"][rows[0]]), float(run.curve["fx_kN"][rows[0]])


def default_displacements(run: RunData) -> list[float]:
    """``U_x`` of the peak and of the last step (mm), without repeats."""
    s = run.summary
    out = [v for v in (s["ux_at_peak_mm"], s["last_ux_mm"]) if v is not None]
    return sorted({round(v, 6) for v in out})


def plot_runs(outdirs: Sequence[Path | str], plot_dir: Path, at_mm: Sequence[float] | None = None,
              magnify: float = 0.0,
              reference_kN_mm: float = REFERENCE_STIFFNESS_KN_MM) -> tuple[list[Path], list[str]]:
    """All the figures of ``outdirs`` into ``plot_dir``: the curves, then the damage maps of
    every run with a ``results.h5`` at ``at_mm`` (default: at its peak and at its end).

    Returns the PNG files written and notes on what was skipped.
    """
    runs = [load_run(d) for d in outdirs]
    label_runs(runs)
    written, notes = [], []
    limit = [r for r in runs if r.scene.get("limit_state")]  # arches: their mechanisms
    if limit:
        written, notes = plot_limit_runs(limit, plot_dir, magnify)
        runs = [r for r in runs if not r.scene.get("limit_state")]
        if not runs:
            return written, notes
    pushed = [r for r in runs if not is_ground_motion(r)]
    if pushed:
        written.append(plot_curves(pushed, plot_dir / "force_displacement.png", reference_kN_mm))
    for run in runs:
        if is_ground_motion(run):
            written.append(plot_ground_motion(run, plot_dir / f"ground_motion_{slug(run.label)}"
                                                              ".png"))
        elif run.summary.get("history", "monotonic") != "monotonic":
            png = plot_cycles(run, plot_dir / f"cycles_{slug(run.label)}.png")
            if png is None:
                notes.append(f"{run.outdir}: no completed cycle, no cycles figure")
            else:
                written.append(png)
        if not run.has_fields:
            notes.append(f"{run.outdir}: no {rf.RESULTS}, no damage map")
            continue
        for ux in (at_mm if at_mm is not None else default_displacements(run)):
            step = nearest_output_step(run, ux)
            name = f"damage_{slug(run.label)}_ux_{ux:.2f}mm.png"
            written.append(plot_damage_map(run, step, plot_dir / name, magnify))
    return written, notes
