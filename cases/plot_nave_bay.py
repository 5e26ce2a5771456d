"""Draw a nave bay run (cases/nave_bay.yaml and its variants) as two cross-sections.

    python cases/plot_nave_bay.py results/nave_bay_spreading [-o picture.png] [--magnify M]

Reads the last output step of the run folder's ``results.h5`` and draws, seen along the nave
(the y-z plane), the blocks whose elements lie in two slices across the bay: at the piers and
transverse arch (x near the east end) and at mid-bay (x near 0). Each element is drawn by its
face of least x, deformed with its displacements times ``--magnify`` (by default the largest
displacement shows as 3 % of the bay's width), coloured by its displacement (mm), over the
outline of the undeformed elements. Writes ``<run folder>/nave_bay_sections.png`` unless told.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.results_h5 import read_fields


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("run", type=Path, help="the run folder")
    parser.add_argument("-o", "--output", type=Path, default=None)
    parser.add_argument("--magnify", type=float, default=0.0)
    args = parser.parse_args(argv)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    fields = read_fields(args.run / rf.RESULTS)
    if fields is None:
        parser.error(f"{args.run}: no output step in {rf.RESULTS}")
    X = fields.nodes_m
    hexes = fields.hexes
    u = fields.nodal_displacement_m if fields.nodal_displacement_m is not None \
        else np.zeros_like(X)
    width = float(np.ptp(X[:, 2]))
    largest = float(np.linalg.norm(u, axis=1).max(initial=0.0))
    magnify = args.magnify or (0.03 * width / largest if largest > 0 else 1.0)
    centre = X[hexes].mean(axis=1)
    x_end = float(X[:, 0].max())
    fig = Figure(figsize=(15, 7), layout="constrained")
    axes = fig.subplots(1, 2)
    # the x-min face of a VTK hexahedron is not known in general: take each element's four
    # nodes of least x
    for ax, (title, lo, hi) in zip(axes, (("at the east piers", 0.35 * x_end, x_end),
                                          ("at mid-bay", -0.12 * x_end, 0.12 * x_end)),
                                   strict=True):
        pick = np.flatnonzero((centre[:, 0] >= lo) & (centre[:, 0] <= hi))
        quads = []
        for e in pick:
            nodes = hexes[e][np.argsort(X[hexes[e], 0])[:4]]
            c = X[nodes][:, [2, 1]].mean(axis=0)
            ang = np.arctan2(X[nodes, 1] - c[1], X[nodes, 2] - c[0])
            quads.append(nodes[np.argsort(ang)])
        quads = np.array(quads)
        ref = X[:, [2, 1]]
        moved = ref + magnify * u[:, [2, 1]]
        disp = 1e3 * np.linalg.norm(u, axis=1)
        ax.add_collection(PolyCollection(ref[quads], facecolors="none", edgecolors="0.7",
                                         linewidths=0.4, linestyles="--"))
        pc = PolyCollection(moved[quads], array=disp[quads].mean(axis=1), cmap="viridis",
                            edgecolors="0.2", linewidths=0.3)
        ax.add_collection(pc)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_xlabel("z (m), across the nave")
        ax.set_ylabel("y (m)")
        ax.set_title(f"{title}: elements with {lo:.2f} <= x <= {hi:.2f} m")
        fig.colorbar(pc, ax=ax, shrink=0.7, label="displacement (mm)")
    fig.suptitle(f"{args.run.name}: step {fields.step}, t = {fields.time_s:.3f} s, "
                 f"displacements x {magnify:.3g} (largest {1e3 * largest:.1f} mm)")
    out = args.output or args.run / "nave_bay_sections.png"
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
