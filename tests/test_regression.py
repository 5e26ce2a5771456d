"""Regression: the smoke wall's variants and the study's wall keep their curves.

Each case below is run with ``masonry_nscd.run.run_case`` (no VTU, no HDF5: the curve only) and
every physical column of ``force_displacement.csv`` is compared with the stored one in
``tests/data/regression/``, row by row, within what the solver guarantees and no more:

* While the two runs made every step the same way (the same sizes, the same subdivisions, as
  the columns ``time_step_s`` and ``substeps`` say), they solve the same discrete equations,
  each step to the solver's tolerance ``tol`` (the relative change of the contact forces
  between Newton iterates, and the momentum residual; ``nscd/newton.py``). A converged
  iterate is then within about ``tol rho / (1 - rho)`` of the solution, ``rho`` the
  iterations' contraction (at most 0.9 before the matrix is refreshed), so the columns agree
  to ``RTOL_PER_TOLERANCE tol`` of each column's largest magnitude: the same bits on any x86-64
  processor and thread count (``arithmetic.py``), round-off apart with the other linear
  solver.
* From the first step made another way on (a step halved in one run and not in the other,
  which round-off can decide where Newton converges in about its iteration cap), the runs
  are two discretisations of the same path: the driven point is on its path in both
  (``loading.step_velocity``), and they differ by what one step changes, for the few steps
  the wall's inertia takes to settle (on the smoke wall with rigid blocks, a halving moved F_x
  by 0.023 kN where one step moves it by 0.6 kN, and 12 steps later by 1e-9). There the bound
  adds the largest change of the column over one step of the stored curve since the runs
  parted.

So no test depends on whether a particular step was halved, and a change of the physics that
moves a curve by more than the solver's tolerance fails. The solver's own columns (iterations,
residual) are not compared: the order of the contact points may change the path of the
iterations, not their solution.

The cases: the smoke wall and variants of it that take each branch of the wall builder (rigid
blocks, stack bond, a top beam held in y, a top beam free to rotate, a finer mesh with 3 x 3
contact points per face), and the study's wall shortened: to 2 mm of horizontal displacement
with ENDO3D blocks (past the cracking of the heel, at 1.85 mm), to 0.5 mm with elastic blocks,
both with every step of h (no adaptive size), without the refined corners and the crushing
length of the shipped case, and at the tolerances 1e-6 (ENDO3D) and 1e-5 (elastic).

The stored curves are written by ``python tests/test_regression.py --write [NAME ...]``. They
were last written when the push began to follow its path exactly (``RampedVelocity``): its
velocity had been sampled at the end of each step, which put U_x ahead of its path by half a
step's travel once the ramp was over (0.01 mm on the smoke wall), and by another amount
wherever a step was made as halves.
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
#: A column's bound while the runs step alike, in units of the solver's tolerance times its
#: largest magnitude (module docstring)
RTOL_PER_TOLERANCE = 10.0


def run_curve(name: str, outdir: Path) -> tuple[dict[str, np.ndarray], float]:
    """Run case ``name`` of :data:`CASES` into ``outdir``: its CSV columns and its solver
    tolerance."""
    from masonry_nscd.case import load_case
    from masonry_nscd.report import read_curve_csv
    from masonry_nscd.run import run_case

    path, sets = CASES[name]
    case = load_case(ROOT / path, [*sets, "output.vtu=false", "output.hdf5=false"])
    run_case(case, outdir, overwrite=True, echo=lambda _msg: None)
    return read_curve_csv(outdir / "force_displacement.csv"), float(case.solver.tolerance)


def stepped_alike(ref: dict[str, np.ndarray], new: dict[str, np.ndarray]) -> np.ndarray:
    """Per row, whether both runs made every step up to it the same way (its size and its
    subdivisions)."""
    same = (ref["time_step_s"] == new["time_step_s"]) & (ref["substeps"] == new["substeps"])
    return np.logical_and.accumulate(same)


def allowed_change(ref: np.ndarray, alike: np.ndarray, tolerance: float) -> np.ndarray:
    """The bound of each row of a column (module docstring): ``RTOL_PER_TOLERANCE tolerance
    max|ref|``, plus, from the first row where the runs stepped differently, the largest change
    of ``ref`` over one step since (that step's own included)."""
    bound = np.full(len(ref), RTOL_PER_TOLERANCE * tolerance * float(np.abs(ref).max()))
    if not alike.all():
        first = int(np.argmin(alike))
        change = np.abs(np.diff(ref, prepend=ref[0]))
        change[:first] = 0.0
        bound += np.maximum.accumulate(change)
    return bound


def _slow(name: str) -> bool:
    return name.startswith("study")


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if _slow(n) else n
                                  for n in CASES])
def test_curve_unchanged(name, tmp_path):
    from masonry_nscd.report import read_curve_csv

    ref = read_curve_csv(DATA / f"{name}.csv")
    new, tolerance = run_curve(name, tmp_path / name)
    assert len(new["step"]) == len(ref["step"]), "not the same number of steps"
    assert not moved(ref, new, tolerance), f"{name}: " + "; ".join(moved(ref, new, tolerance))


def moved(ref: dict[str, np.ndarray], new: dict[str, np.ndarray],
          tolerance: float) -> list[str]:
    """The columns of ``new`` that left the bound around ``ref`` (module docstring), each with
    its worst row."""
    alike = stepped_alike(ref, new)
    out = []
    for col in COLUMNS:
        err = np.abs(new[col] - ref[col])
        bound = allowed_change(ref[col], alike, tolerance)
        worst = int(np.argmax(err - bound))
        if not err[worst] <= bound[worst]:
            out.append(f"column {col} moved by {err[worst]:.3g} at step {worst + 1} (bound "
                       f"{bound[worst]:.3g}, max |ref| {np.abs(ref[col]).max():.3g})")
    return out


def test_a_change_of_the_physics_leaves_the_bound(tmp_path):
    """The bound is no wider than the solver's tolerance: the smoke wall with its joints'
    shear spring 0.1 % stiffer moves F_x out of it (by 0.017 kN, some 3,000 times the bound)."""
    from masonry_nscd.case import load_case
    from masonry_nscd.report import read_curve_csv
    from masonry_nscd.run import run_case

    case = load_case(ROOT / "cases" / "smoke.yaml",
                     ["joint.K_II_spring_Pa_m=1.8018e11", "output.vtu=false", "output.hdf5=false"])
    run_case(case, tmp_path / "stiffer", echo=lambda _msg: None)
    new = read_curve_csv(tmp_path / "stiffer" / "force_displacement.csv")
    changes = moved(read_curve_csv(DATA / "smoke.csv"), new, float(case.solver.tolerance))
    assert any(c.startswith("column fx_kN") for c in changes)


def test_the_bound_widens_by_one_steps_change_where_the_runs_stepped_differently():
    ref = {"time_step_s": np.full(6, 0.1), "substeps": np.array([1, 1, 1, 2, 1, 1])}
    new = {"time_step_s": np.full(6, 0.1), "substeps": np.ones(6)}
    alike = stepped_alike(ref, new)
    assert alike.tolist() == [True, True, True, False, False, False]
    column = np.array([0.0, 1.0, 3.0, 4.0, 4.5, 4.5])
    bound = allowed_change(column, alike, 1e-8)
    tight = 1e-7 * 4.5
    assert bound[:3] == pytest.approx([tight] * 3)
    # from the first step made differently: the largest one-step change since, its own (1.0)
    assert bound[3:] == pytest.approx([tight + 1.0] * 3)


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
