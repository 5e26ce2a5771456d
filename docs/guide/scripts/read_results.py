"""Read a run folder with plain numpy, h5py and matplotlib: the curve from the CSV, the joints'
cohesion lost by the last output step from results.h5, and one figure of both.

    python docs/guide/scripts/read_results.py results/wall_0.5MPa [-o figure.png]

Prints the peak of the curve and the joints most damaged; writes OUTDIR/read_results.png.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("outdir", type=Path, help="a run folder written by masonry run")
    parser.add_argument("-o", "--output", type=Path, help="the figure (PNG)")
    args = parser.parse_args()
    run = args.outdir

    # 1. The curve: one row per step, a header naming each column with its unit.
    curve = np.genfromtxt(run / "force_displacement.csv", delimiter=",", names=True)
    peak = int(np.argmax(curve["fx_kN"]))
    print(f"{len(curve)} steps; peak F_x = {curve['fx_kN'][peak]:.2f} kN "
          f"at U_x = {curve['ux_mm'][peak]:.3f} mm")

    # 2. The summary: the numbers masonry run printed at its end.
    summary = json.loads((run / "summary.json").read_text())
    print(f"initial stiffness {summary['initial_stiffness_kN_mm']:.1f} kN/mm; "
          f"failure mode at the end: {summary['failure_mode']['mode']}")

    # 3. The fields: the mesh once, then one group per output step (sorted by its number).
    with h5py.File(run / "results.h5", "r") as h5:
        points = h5["mesh/contact_points_m"][:]          # (n, 3) m
        d0 = h5["mesh/contact_initial_damage"][:]        # (n,)
        steps = sorted(h5["steps"], key=lambda name: h5["steps"][name].attrs["step"])
        last = h5["steps"][steps[-1]]
        time_s = float(last.attrs["time"])
        beta = last["joint_beta"][:]                     # cohesive integrity, 1 intact
    d_coh = 1.0 - beta * (1.0 - d0)                      # the joints' damage, 0 to 1
    lost = 1.0 - beta                                    # cohesion lost since the start
    print(f"{len(steps)} output steps; at t = {time_s:.3f} s {(lost > 0.99).sum()} of "
          f"{len(lost)} contact points have lost their cohesion since the start "
          f"(largest joint damage d_coh {d_coh.max():.5f})")

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2),
                                      gridspec_kw={"width_ratios": [1, 1.4]})
    left.plot(curve["ux_mm"], curve["fx_kN"], color="k")
    left.plot(curve["ux_mm"][peak], curve["fx_kN"][peak], "o", color="tab:red")
    left.set_xlabel("U_x (mm)")
    left.set_ylabel("F_x (kN)")
    left.set_title("force_displacement.csv")
    left.grid(alpha=0.3)
    order = np.argsort(lost)                             # the most damaged drawn last
    dots = right.scatter(points[order, 0], points[order, 1], c=lost[order], s=6,
                         cmap="magma_r", vmin=0.0, vmax=1.0)
    right.set_aspect("equal")
    right.set_xlabel("x (m)")
    right.set_ylabel("y (m)")
    right.set_title(f"results.h5: cohesion lost by the joints at t = {time_s:.2f} s")
    fig.colorbar(dots, ax=right, label="1 - beta")
    fig.tight_layout()
    out = args.output or run / "read_results.png"
    fig.savefig(out, dpi=110)
    print(f"figure: {out}")


if __name__ == "__main__":
    main()
