"""Figures of limit-state runs (an arch): the mechanism, and the load against the motion.

``mechanism_<run>.png`` (:func:`plot_mechanism`), two panels:

* the structure at the last output step of ``results.h5`` (the collapse, or the end of a run
  that stands), the front face (z-min) of each element on the structure's front plane (an
  arch: all; a vault: its first ring, with the joints within its depth) drawn deformed with its displacements
  multiplied by ``magnify`` (by default so that the largest displacement shows as 4 % of the
  structure's width), over the outline of the undeformed structure and the supports; the hinges
  of the summary (:mod:`masonry_nscd.post.limit`) marked at their pivots (a red dot, labelled
  with the joint and the face), sliding joints with a blue cross, joints open over their whole
  face (separated) with an orange square at their centre; blocks removed by then
  (``loading.removal``) as red dotted outlines where they were, not drawn deformed;
* the growing load (the first of the scene's load factors: the body-force multiplier ``lambda``,
  the force on a block) against the largest displacement of a block point (``limit.csv``;
  relative to the supports' rigid motion when a support moves, which the axis says), with
  the onset of the mechanism and its detection marked; without a growing load, the largest
  displacement against time.

Matplotlib through its object-oriented API (Agg), as :mod:`masonry_nscd.plots`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from masonry_nscd.figure_files import save_png, slug
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.limit_files import read_limit, read_limit_table
from masonry_nscd.io.results_h5 import read_fields
from masonry_nscd.post.limit import limit_summary, removal_groups

#: The largest displacement is drawn as this fraction of the structure's width by default.
AUTO_MAGNIFY_FRACTION = 0.04
#: The faces of a drawn hexahedron (VTK order)
_HEX_FACES = np.array([[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6],
                       [3, 0, 4, 7]])


def plot_mechanism(run, path: Path, magnify: float = 0.0) -> Path:
    """The mechanism figure of a limit-state run folder (module docstring); ``run`` is a
    :class:`masonry_nscd.plots.RunData`."""
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    fields = read_fields(run.outdir / rf.RESULTS)
    if fields is None:
        raise ValueError(f"{run.outdir}: {rf.RESULTS} has no output step")
    summary = limit_summary(run.outdir, run.scene, fields)
    disp = fields.nodal_displacement_m if fields.nodal_displacement_m is not None \
        else np.zeros_like(fields.nodes_m)
    # the front: the elements whose z-min face lies on the structure's front plane (an arch's
    # all; a vault's first ring), and the joints within their depth
    z = fields.nodes_m[:, 2]
    tol = 1e-9 * (1.0 + float(np.ptp(z)))
    at_front = np.abs(z[fields.hexes[:, :4]] - z.min()).max(axis=1) <= tol
    # the blocks removed by then are drawn apart, as outlines where they were
    removal = [g for g in removal_groups(run.scene.get("removal"))
               if fields.time_s > g["at_s"] + 1e-9]
    gone = np.zeros(len(fields.hexes), dtype=bool)
    if removal:
        names = [b.get("name") for b in run.scene.get("structure", [])]
        left = {name for g in removal for name in g["blocks"]}
        out = [k for k, name in enumerate(names) if name in left]
        gone = np.isin(fields.block_of_element, out)
    removed = fields.hexes[at_front & gone, :4]
    at_front &= ~gone
    front = fields.hexes[at_front, :4]
    z_back = float(z[fields.hexes[at_front]].max(initial=z.min()))

    def in_front(joint) -> bool:  # not the joints on the back plane (a vault's next ring)
        return joint["centre_m"][2] < z_back - tol
    ref = fields.nodes_m[:, :2]
    width = float(np.ptp(ref[:, 0])) or 1.0
    largest = float(np.linalg.norm(disp, axis=1).max(initial=0.0))
    if magnify <= 0.0:
        magnify = AUTO_MAGNIFY_FRACTION * width / largest if largest > 0.0 else 1.0
    moved = ref + magnify * disp[:, :2]
    fig = Figure(figsize=(14, 6), layout="constrained")
    if not len(front):  # no front plane (a dome, a cross vault): the blocks in perspective
        grid = fig.add_gridspec(1, 2, width_ratios=(1.4, 1.0))
        ax = fig.add_subplot(grid[0], projection="3d")
        bx = fig.add_subplot(grid[1])
        magnify = _draw_in_perspective(ax, fields, disp, summary, magnify, gone)
        _draw_load_panel(fig, ax, bx, run, summary, fields, magnify,
                         _removal_note(removal, gone.any()))
        return save_png(fig, path)
    ax, bx = fig.subplots(1, 2, width_ratios=(1.4, 1.0))
    builder = run.scene.get(run.scene.get("builder", "arch")) or {}
    for box in builder.get("supports_xy_m", []):
        x0, y0, x1, y1 = box
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="0.8", edgecolor="0.5",
                               hatch="//", linewidth=0.5))
    ax.add_collection(PolyCollection(ref[front], facecolors="none", edgecolors="0.75",
                                     linewidths=0.6, linestyles="--"))
    if len(removed):
        ax.add_collection(PolyCollection(ref[removed], facecolors="none", edgecolors="red",
                                         linewidths=0.8, linestyles=":"))
    node_disp = np.linalg.norm(disp[:, :2], axis=1)
    pc = PolyCollection(moved[front], array=1e3 * node_disp[front].mean(axis=1), cmap="viridis",
                        edgecolors="0.2", linewidths=0.5)
    ax.add_collection(pc)
    fig.colorbar(pc, ax=ax, shrink=0.8, label="displacement (mm)")

    def placed(point) -> np.ndarray:
        """A reference point moved with the nearest node of the front faces."""
        p = np.asarray(point, dtype=float)
        nodes = np.unique(front)
        k = nodes[np.argmin(np.linalg.norm(fields.nodes_m[nodes] - p, axis=1))]
        return p[:2] + magnify * disp[k, :2]

    for h in filter(in_front, summary["hinges"]):
        p = placed(h["pivot_m"])
        ax.plot(*p, "o", color="red", markersize=9, markeredgecolor="k", zorder=5)
        label = f"joint {h['joint']}\n{h['side']}" if h.get("joint") is not None else \
            "\n".join(h["bodies"])
        ax.annotate(label, p, textcoords="offset points", xytext=(8, 6), fontsize=8,
                    color="darkred")
    for j in filter(in_front, summary["sliding_joints"]):
        p = placed(j["centre_m"])
        ax.plot(*p, "x", color="blue", markersize=10, markeredgewidth=2, zorder=5)
    for j in filter(in_front, summary["open_joints"]):
        p = placed(j["centre_m"])
        ax.plot(*p, "s", color="orange", markersize=7, markeredgecolor="k", zorder=5)
    lo, hi = np.minimum(ref.min(axis=0), moved.min(axis=0)), np.maximum(ref.max(axis=0),
                                                                         moved.max(axis=0))
    pad = 0.08 * float(max(hi - lo))
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - 2 * pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    _draw_load_panel(fig, ax, bx, run, summary, fields, magnify,
                     _removal_note(removal, len(removed) > 0))
    return save_png(fig, path)


def _removal_note(removal: list[dict], shown: bool) -> str:
    """The title's lines on the blocks removed by then (drawn red dotted), a line a group, if
    any are shown."""
    if not shown:
        return ""
    return "".join(f"\n{', '.join(g['blocks'])} removed at t = {g['at_s']:.4g} s (red dotted)"
                   for g in removal)


def _draw_in_perspective(ax, fields, disp: np.ndarray, summary: dict, magnify: float,
                         gone: np.ndarray) -> float:
    """Every element's faces, moved by ``magnify`` times their displacements (the largest drawn
    as AUTO_MAGNIFY_FRACTION of the structure's size when ``magnify`` is 0) and coloured by
    it, in perspective (y up), with the hinges (red) and sliding joints (blue) at their places,
    and the elements ``gone`` (removed by then) as red dotted outlines where they were;
    returns the magnification drawn."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    X = fields.nodes_m
    size = float(np.ptp(X, axis=0).max()) or 1.0
    largest = float(np.linalg.norm(disp, axis=1).max(initial=0.0))
    if magnify <= 0.0:
        magnify = AUTO_MAGNIFY_FRACTION * size / largest if largest > 0.0 else 1.0
    moved = X + magnify * disp
    faces = fields.hexes[~gone][:, _HEX_FACES].reshape(-1, 4)
    shown = moved[:, [0, 2, 1]]  # x, z on the ground, y up
    if gone.any():
        ax.add_collection3d(Poly3DCollection(
            X[:, [0, 2, 1]][fields.hexes[gone][:, _HEX_FACES].reshape(-1, 4)],
            facecolors="none", edgecolors="red", linestyles=":", linewidths=0.8))
    value = 1e3 * np.linalg.norm(disp, axis=1)[faces].mean(axis=1)
    norm = Normalize(0.0, float(value.max(initial=0.0)) or 1.0)
    mappable = ScalarMappable(norm=norm, cmap="viridis")
    ax.add_collection3d(Poly3DCollection(shown[faces], facecolors=mappable.to_rgba(value),
                                         edgecolors="0.25", linewidths=0.2))
    ax.figure.colorbar(mappable, ax=ax, shrink=0.6, label="displacement (mm)")

    def placed(point) -> np.ndarray:
        p = np.asarray(point, dtype=float)
        k = int(np.argmin(np.linalg.norm(X - p, axis=1)))
        return (p + magnify * disp[k])[[0, 2, 1]]

    for h in summary["hinges"]:
        ax.scatter(*placed(h["pivot_m"]), color="red", s=30, edgecolors="k", depthshade=False)
    for j in summary["sliding_joints"]:
        ax.scatter(*placed(j["centre_m"]), color="blue", marker="x", s=30, depthshade=False)
    lo, hi = shown.min(axis=0), shown.max(axis=0)
    half = 0.5 * float((hi - lo).max())
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), 0.5 * (lo + hi), strict=True):
        set_lim(c - half, c + half)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_zlabel("y (m)")
    ax.view_init(elev=25.0, azim=-60.0)
    return magnify


def _draw_load_panel(fig, ax, bx, run, summary: dict, fields, magnify: float,
                     removal_note: str) -> None:
    """The mechanism's title (``removal_note`` its last line), and the load against the motion
    in ``bx``."""
    c = summary.get("collapse")
    loads = (c or {}).get("loads_at_onset") or {}
    ax.set_title(f"{summary['status']}: {summary['mechanism']} mechanism"
                 + (f" ({', '.join(f'{k} = {v:.4g}' for k, v in loads.items())} at the onset)"
                    if loads else "")
                 + f"\nstep {fields.step}, t = {fields.time_s:.3f} s, displacements x "
                 f"{magnify:.3g}; hinges (red) at their pivots, sliding (blue x), open "
                 "(orange)" + removal_note)

    table = read_limit_table(run.outdir)
    factors = [f["name"] for f in summary.get("load_factors", []) if f["name"] in table]
    # with moving supports, the watch's displacements are relative to their rigid motion
    relative = (read_limit(run.outdir) or {}).get("displacements")
    label = "largest displacement of a block point (mm)" + (f"\n{relative}" if relative else "")
    if table and len(table.get("time_s", [])):
        d = 1e3 * table["max_displacement_m"]
        if factors:
            name = factors[0]
            bx.plot(d, table[name], color="C0")
            bx.set_ylabel(name)
            bx.set_xlabel(label)
            y_of = dict(zip(table["step"].astype(int), table[name], strict=True))
        else:
            bx.plot(table["time_s"], d, color="C0")
            bx.set_xlabel("t (s)")
            bx.set_ylabel(label)
            y_of = None
        x_of = dict(zip(table["step"].astype(int), d, strict=True))
        t_of = dict(zip(table["step"].astype(int), table["time_s"], strict=True))
        for key, mark, text in (("onset_step", "o", "onset"), ("detected_step", "s",
                                                                "detected")):
            step = (c or {}).get(key)
            if step is None or step not in x_of:
                continue
            xy = (x_of[step], y_of[step]) if y_of else (t_of[step], x_of[step])
            bx.plot(*xy, mark, color="red")
            bx.annotate(text, xy, textcoords="offset points", xytext=(6, -12), fontsize=8)
        bx.grid(alpha=0.3)
        bx.set_title("load against motion" if factors else "motion")
    fig.suptitle(f"{run.label}: {run.scene.get('builder', '')} "
                 f"({run.case.blocks.material} blocks, joints {run.case.joint.law})")


def plot_limit_runs(runs: Sequence, plot_dir: Path,
                    magnify: float = 0.0) -> tuple[list[Path], list[str]]:
    """The mechanism figure of each limit-state run with a ``results.h5``."""
    written, notes = [], []
    for run in runs:
        if not run.has_fields:
            notes.append(f"{run.outdir}: no {rf.RESULTS}, no mechanism figure")
            continue
        written.append(plot_mechanism(run, plot_dir / f"mechanism_{slug(run.label)}.png",
                                      magnify))
    return written, notes
