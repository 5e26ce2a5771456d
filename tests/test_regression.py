"""Regression: the study's walls give the curves they gave before the scene redesign (issue 14).

The reference curves in ``tests/data/regression/`` were written by the code of commit 4244c7a
(the last one before the generic block assembly and the scene layer), with

    python tests/test_regression.py --write

except ``smoke_rigid.csv``, written again after the redesign: the old wall builder tied every
bed-joint point of a rigid unit to the first unit of the course below, whether or not the point
faced it (it checked that a point's projection lies in the antagonist's face only on deformable
antagonists), so that rigid walls were lopsided (7 kN of horizontal force under the vertical
load alone on the smoke wall, where the new curve has none: tests/test_wall_run.py); and
``study_endo3d_2mm.csv``, ``study_elastic_0.5mm.csv``, written again when Newton's convergence
test took in the momentum residual (issue 16: at the friction limit the tractions stop changing
before the velocities are right). Those two curves moved by 2.2e-6 and 1.6e-6 of their largest
value, towards the solution: against the same runs at tolerance 1e-9, the old curves were
2.1e-6 and 1.7e-6 off, the new ones 1.3e-7 and 8.3e-7, for 2161 and 599 Newton iterations
against 2210 and 597. The smoke curves did not move. ``study_endo3d_2mm.csv`` was written
again when the viscous regularisation's relaxation became the exact solution over the step
(session 28, ``materials/blocks.py``): its F_x moved by 8.3e-5 and its U_y by 4.6e-4 of their
largest values, both under the vertical load, where the pre-peak compressive damage grows, and
its largest block damage by 6.8e-3 at the heel's cracking (U_x = 1.89 mm).

Each case below is run with ``masonry_nscd.run.run_case`` (no VTU, no HDF5: the curve only)
and every physical column of ``force_displacement.csv`` is compared with the stored one:
``|new - ref| <= 1e-6 max|ref|`` per column (relative to the column's largest magnitude, so
that the tiny forces of the gravity stage are not asked for digits that the solver tolerance
does not give). The solver's own columns (iterations, residual) are not compared: the order
of the contact points may change the path of the iterations, not their solution.

The cases: the smoke wall and variants of it that take each branch of the wall builder (rigid
blocks, stack bond, a top beam held in y, a top beam free to rotate, a finer mesh with 3 x 3
contact points per face), and the study's wall shortened: to 2 mm of horizontal displacement
with ENDO3D blocks (past the cracking of the heel, at 1.85 mm), to 0.5 mm with elastic blocks.
The study's cases are run as they were before issue 15 (no refined corners, no crushing length)
and before issue 19 (with ENDO3D blocks the tolerance 1e-6 and every step of 4e-3 s, with
elastic blocks every step of h, no adaptive step size, and the tolerance 1e-5), the
configuration their curves were written with.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "regression"

#: name -> (case file, --set overrides)
CASES: dict[str, tuple[str, list[str]]] = {
    "smoke": ("cases/smoke.yaml", []),
    "smoke_rigid": ("cases/smoke.yaml", ["blocks.material=rigid"]),
    "smoke_stack": ("cases/smoke.yaml", ["wall.bond=stack"]),
    "smoke_top_fixed": ("cases/smoke.yaml", ["supports.top_vertical=fixed",
                                             "loading.vertical_stress.value_Pa=0"]),
    "smoke_rotation_free": ("cases/smoke.yaml", ["supports.top_rotation=free"]),
    "smoke_mesh_2x2x2": ("cases/smoke.yaml", ["wall.elements_per_unit=[2,2,2]",
                                              "wall.contact_points_per_face=3"]),
    "study_endo3d_2mm": ("cases/wall_0.5MPa.yaml", ["loading.horizontal.target_m=2e-3",
                                                    "wall.refine=[]",
                                                    "blocks.endo3d.crushing_length_m=0",
                                                    "solver.tolerance=1e-6",
                                                    "solver.time_step_s=4e-3",
                                                    "solver.max_time_step_s=null",
                                                    "output.every_steps=5"]),
    "study_elastic_0.5mm": ("cases/wall_0.5MPa_elastic.yaml",
                            ["loading.horizontal.target_m=0.5e-3", "wall.refine=[]",
                             "solver.max_time_step_s=null", "solver.tolerance=1e-5"]),
}

#: The columns compared (the physical ones of the CSV).
COLUMNS = ("time_s", "ux_mm", "fx_kN", "uy_mm", "fy_kN", "fx_bottom_kN", "fy_bottom_kN",
           "max_joint_damage", "max_block_damage", "max_d_cpp")
RTOL = 1e-6


def run_curve(name: str, outdir: Path) -> dict[str, np.ndarray]:
    """Run case ``name`` of :data:`CASES` into ``outdir`` and return its CSV columns."""
    from masonry_nscd.case import load_case
    from masonry_nscd.report import read_curve_csv
    from masonry_nscd.run import run_case

    path, sets = CASES[name]
    case = load_case(ROOT / path, [*sets, "output.vtu=false", "output.hdf5=false"])
    run_case(case, outdir, overwrite=True, echo=lambda _msg: None)
    return read_curve_csv(outdir / "force_displacement.csv")


def _slow(name: str) -> bool:
    return name.startswith("study")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if _slow(n) else n
                                  for n in CASES])
def test_curve_unchanged(name, tmp_path):
    from masonry_nscd.report import read_curve_csv

    ref = read_curve_csv(DATA / f"{name}.csv")
    new = run_curve(name, tmp_path / name)
    assert len(new["step"]) == len(ref["step"]), "not the same number of steps"
    for col in COLUMNS:
        scale = float(np.abs(ref[col]).max())
        err = float(np.abs(new[col] - ref[col]).max())
        assert err <= RTOL * max(scale, 1e-300), \
            f"{name}: column {col} moved by {err:.3g} (max |ref| {scale:.3g})"


if __name__ == "__main__":  # python tests/test_regression.py --write [NAME ...]
    import shutil
    import tempfile

    if "--write" not in sys.argv:
        sys.exit("usage: python tests/test_regression.py --write [NAME ...]")
    names = [a for a in sys.argv[1:] if a != "--write"] or list(CASES)
    DATA.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            run_curve(name, Path(tmp) / name)
            shutil.copy(Path(tmp) / name / "force_displacement.csv", DATA / f"{name}.csv")
            print(f"wrote {DATA / name}.csv")
