"""The imposed motions are followed exactly, whatever the steps: a step made again as smaller
ones, or an adaptive one, moves every driven dof by exactly its path's displacement over its
time (``loading.step_velocity``).

The halvings are forced by an iteration cap that no step meets (one or three Newton
iterations): every step of h is made again as halves, down to the deepest level allowed (three
halvings by default, sub-steps of h/2 to h/8). The steps are then left unconverged, which does
not matter here: the path is set by the imposed velocities, not by the solution.
"""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.case import load_case
from masonry_nscd.loading import RampedVelocity
from masonry_nscd.report import read_curve_csv
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

SMOKE = "cases/smoke.yaml"
ARCH = "cases/arch_semicircular.yaml"
QUIET = ["output.vtu=false", "output.hdf5=false"]
#: no step converges: every step of h is made again as smaller ones, to the deepest level
NEVER_CONVERGED = ["solver.max_iterations=1", "solver.check_every=1"]


def test_the_smoke_walls_push_ends_on_its_target_when_every_step_is_halved(tmp_path):
    """The smoke wall with rigid blocks, every step made again as smaller ones (three Newton
    iterations, three halvings): U_x at every step is the push's ``rate ramp S(x)``, and at
    the end (t = 0.2 s) its target, 0.5 mm, to round-off."""
    case = load_case(SMOKE, ["blocks.material=rigid", *QUIET, "solver.max_iterations=3",
                             "solver.check_every=1"])
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    c = read_curve_csv(tmp_path / "run" / "force_displacement.csv")
    hz = case.loading.horizontal
    push = RampedVelocity(hz.rate_m_s, hz.start_s, hz.ramp_s)
    path_mm = np.array([1e3 * push.displacement(t) for t in c["time_s"]])
    assert (c["substeps"] >= 2).all()  # every step was halved
    # to the 9 significant digits of the CSV
    assert np.abs(c["ux_mm"] - path_mm).max() <= 1e-8 * path_mm.max()
    assert c["time_s"][-1] == pytest.approx(0.2, rel=1e-12)
    assert c["ux_mm"][-1] == pytest.approx(0.5, rel=1e-12)


def _follows_its_path(sets, steps, case_file=SMOKE):
    """Step the scene of ``case_file`` with ``sets``, no step converging (so each is made again
    as halves, to the deepest level): after every step, each imposed dof must be where its
    motion's displacement puts it, to round-off. Returns the imposed dofs' largest travel (m)."""
    integ = build_scene(load_case(case_file, [*QUIET, *NEVER_CONVERGED, *sets])).integrator()
    largest = 0.0
    for _ in range(steps):
        rep = integ.step()
        assert rep.substeps >= 2
        for dof, motion in integ.imposed:
            path = motion.displacement(integ.t)
            assert integ.u[dof] == pytest.approx(path, abs=1e-15 + 1e-12 * abs(path))
            largest = max(largest, abs(path))
    return largest


@pytest.mark.parametrize("sets", [
    # the push, its ramp starting at once (the smoke case's push starts at 0.1 s)
    ["loading.horizontal.start_s=0", "loading.horizontal.ramp_s=0.02"],
    # cycles of 0.1 mm at 20 mm/s: reversals every 5 to 10 ms, the first at 10 ms
    ["loading.horizontal.start_s=0", "loading.horizontal.history=cyclic",
     "loading.horizontal.rate_m_s=0.02", "loading.horizontal.ramp_s=0.005",
     "loading.horizontal.amplitudes_m=[0.1e-3]"],
])
def test_the_top_beam_follows_the_push_and_the_cycles(sets):
    assert _follows_its_path(sets, 20) > 1e-5


def test_the_top_beam_follows_a_table(tmp_path):
    table = tmp_path / "path.csv"
    table.write_text("time_s,displacement_m\n0,0\n0.01,0.1e-3\n0.02,-0.05e-3\n0.03,0.2e-3\n")
    sets = ["loading.horizontal.start_s=0", "loading.horizontal.history=table",
            f"loading.horizontal.file={table}", "loading.horizontal.ramp_s=0.004"]
    assert _follows_its_path(sets, 20) > 1e-5


def test_the_base_follows_a_ground_motion(tmp_path):
    record = tmp_path / "record.csv"
    t = np.linspace(0.0, 0.04, 9)
    record.write_text("time_s,acceleration_m_s2\n"
                      + "".join(f"{a:g},{b:.9g}\n" for a, b in zip(t, 5.0 * np.sin(150 * t))))
    sets = ["loading.horizontal.history=none",
            f"loading.ground_motion={{file: {record}, start_s: 0}}"]
    assert _follows_its_path(sets, 20) > 1e-6


def test_a_settling_support_follows_its_motion():
    sets = ["loading.body_force.rate_per_s=0", "solver.max_time_step_s=null",
            "solver.max_iterations=3",
            ("loading.settlement={support: right, displacement_m: [0.02, -0.01, 0.0], "
             "duration_s: 0.02, start_s: 0}")]
    assert _follows_its_path(sets, 15, ARCH) > 1e-3
