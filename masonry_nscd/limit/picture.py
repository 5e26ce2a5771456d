"""The picture of a collapse mechanism (``mechanism.png``): a projection on the x-y plane.

Every hexahedron of every body is drawn as the outline of its projected nodes (their convex
hull): the supports grey, the other bodies at rest in light grey and moved by the mechanism's
velocity times ``magnify`` (by default so that the fastest node moves by 6 % of the scene's
width) in colour; hinges are red dots at their pivots, sliding joints blue crosses at their
centres, open joints orange squares; an arch's line of thrust (:mod:`.thrust`) in purple
through the points where each joint's resultant crosses it. The title gives the multiplier
and the mechanism's name.
Matplotlib through its object-oriented API (Agg), as the other figures.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from masonry_nscd.figure_files import save_png

#: The fastest node moves by this fraction of the scene's width in the picture.
AUTO_MAGNIFY_FRACTION = 0.06


def _outline(xy: np.ndarray) -> np.ndarray:
    try:
        return xy[ConvexHull(xy).vertices]
    except (QhullError, ValueError):
        return xy


def draw_mechanism(path: Path, meshes, node_velocity, support: np.ndarray,
                   found: dict[str, Any], title: str, magnify: float = 0.0) -> Path:
    """Write the picture (module docstring) to ``path``; ``meshes`` per body (nodes, cells),
    ``node_velocity`` per body (nodes, 3), ``found`` the mechanism's summary
    (:func:`masonry_nscd.limit.mechanism.summary`)."""
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    allx = np.concatenate([X for X, c in meshes if len(c)])
    width = float(np.ptp(allx[:, :2], axis=0).max()) or 1.0
    if magnify <= 0.0:
        vmax = max((float(np.linalg.norm(v, axis=1).max()) for v, (_, c)
                    in zip(node_velocity, meshes) if len(c) and len(v)), default=0.0)
        magnify = AUTO_MAGNIFY_FRACTION * width / vmax if vmax > 0 else 0.0
    rest, moved, fixed = [], [], []
    for b, ((X, conn), v) in enumerate(zip(meshes, node_velocity)):
        for cell in conn:
            xy = X[cell, :2]
            if support[b]:
                fixed.append(_outline(xy))
            else:
                rest.append(_outline(xy))
                moved.append(_outline(xy + magnify * v[cell, :2]))
    fig = Figure(figsize=(8, 6))
    ax = fig.add_subplot()
    ax.add_collection(PolyCollection(fixed, facecolors="0.6", edgecolors="0.3", linewidths=0.5))
    ax.add_collection(PolyCollection(rest, facecolors="none", edgecolors="0.75",
                                     linewidths=0.5))
    ax.add_collection(PolyCollection(moved, facecolors="tab:olive", edgecolors="k",
                                     linewidths=0.4, alpha=0.35))
    for key, style, label in (("hinges", {"c": "red", "marker": "o", "s": 30}, "hinge"),
                              ("sliding_joints", {"c": "blue", "marker": "x", "s": 30},
                               "sliding"),
                              ("open_joints", {"c": "orange", "marker": "s", "s": 20}, "open")):
        joints = found.get(key) or []
        pts = np.array([j["pivot_m"] or j["centre_m"] for j in joints]).reshape(-1, 3)
        if len(pts):
            ax.scatter(pts[:, 0], pts[:, 1], zorder=5, label=f"{label} ({len(pts)})", **style)
    line = found.get("thrust_line") or []
    if line:
        xy = np.array([[r["x_m"], r["y_m"]] for r in line])
        ax.plot(xy[:, 0], xy[:, 1], "-", color="tab:purple", lw=1.2, marker=".", ms=4,
                zorder=6, label="line of thrust")
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)
    if any(found.get(k) for k in ("hinges", "sliding_joints", "open_joints", "thrust_line")):
        ax.legend(loc="upper right", fontsize=8)
    return save_png(fig, path)
