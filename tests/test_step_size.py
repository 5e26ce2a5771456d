"""The adaptive step size (``solver.max_time_step_s``, ``nscd/step_size.py``): steps of
``h 2^k`` grown while they are easy, made again smaller when they fail."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.io.recorder import read_resume_point
from masonry_nscd.io.results_h5 import read_results
from masonry_nscd.nscd.step_size import StepSizeControl
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

SMOKE = "cases/smoke.yaml"  # h = 2e-3 s, tolerance 1e-8, fields every 10 steps
H = 2e-3
quiet = {"echo": lambda msg: None}


# --- the control ------------------------------------------------------------------------------
def test_a_step_starts_on_its_own_grid_and_ends_before_the_limit():
    c = StepSizeControl(max_level=3, level=3)
    assert c.level_for(0, 100) == 3
    assert c.level_for(4, 100) == 2  # 4 is not a multiple of 8
    assert c.level_for(6, 100) == 1
    assert c.level_for(7, 100) == 0
    assert c.level_for(8, 12) == 2  # 8 + 4 = 12 fits, 8 + 8 does not
    assert c.level_for(8, 9) == 0
    assert c.level_for(8, 8) == 0  # the limit is passed by any step: the smallest one


def test_the_step_doubles_after_easy_steps_and_falls_back_when_hard_or_failed():
    c = StepSizeControl(max_level=2, grow_after=2, easy_iterations=4)
    c.accepted(0, 3, True)
    assert c.level == 0
    c.accepted(0, 4, True)
    assert c.level == 1 and c.easy == 0
    c.accepted(1, 5, True)  # neither easy nor hard: the level holds, the count restarts
    assert c.level == 1 and c.easy == 0
    c.accepted(1, 2, True)
    c.accepted(1, 2, True)
    assert c.level == 2
    c.accepted(2, 2, True)
    c.accepted(2, 2, True)
    assert c.level == 2  # the largest
    c.accepted(2, 9, True)  # more than twice easy_iterations
    assert c.level == 1
    assert c.failed(1) == 0 and c.level == 0
    c.accepted(0, 2, False)  # subdivided: not easy, the level stays at 0
    assert c.level == 0 and c.easy == 0


def test_a_step_in_which_a_damage_grows_is_not_easy():
    c = StepSizeControl(max_level=2, grow_after=1, easy_iterations=4, easy_damage=0.02)
    c.accepted(0, 2, True, damage=0.03)  # few iterations, but a joint lost 3 % of integrity
    assert c.level == 0
    c.accepted(0, 2, True, damage=0.01)
    assert c.level == 1
    c.accepted(1, 2, True, damage=0.05)  # more than twice easy_damage: one level down
    assert c.level == 0


def test_the_control_refuses_meaningless_settings():
    with pytest.raises(ValueError, match="max_level"):
        StepSizeControl(max_level=-1)
    with pytest.raises(ValueError, match="grow_after"):
        StepSizeControl(max_level=1, grow_after=0)


# --- the case ---------------------------------------------------------------------------------
def test_the_largest_step_is_the_step_times_the_largest_power_of_two_that_fits():
    case = load_case(SMOKE, ["solver.max_time_step_s=8e-3", "output.every_steps=8"])
    assert case.solver.max_growth == 2 and case.step_growth == 2
    case = load_case(SMOKE, ["solver.max_time_step_s=1.5e-2", "output.every_steps=8"])
    assert case.solver.max_growth == 2  # 8e-3 s, not 1.6e-2 s
    assert load_case(SMOKE).solver.max_growth == 0
    assert load_case(SMOKE, ["solver.max_time_step_s=1"]).solver.max_growth == 8
    with pytest.raises(CaseError, match=r"solver\.max_time_step_s.*cannot be smaller"):
        load_case(SMOKE, ["solver.max_time_step_s=1e-3"])


def test_the_fields_fall_on_the_end_of_a_step():
    """Fields every 10 steps of h: steps of 2 h at most (10 is not a multiple of 4)."""
    case = load_case(SMOKE, ["solver.max_time_step_s=1.6e-2", "output.every_steps=10"])
    assert case.solver.max_growth == 3 and case.step_growth == 1
    from masonry_nscd.scenes import build_scene

    assert build_scene(case).solver.max_growth == 1


def test_a_largest_step_that_the_fields_cut_short_is_said():
    """The run's log and ``masonry validate`` say why the steps grow less than asked, and
    what output.every_steps would let them grow to; nothing when they grow as asked."""
    note = load_case(SMOKE, ["solver.max_time_step_s=1.6e-2", "output.every_steps=10"]) \
        .step_growth_note
    assert note is not None
    assert "steps grow to 0.004 s only" in note and "every_steps = 10" in note
    assert "not a multiple of 4" in note and "a multiple of 8" in note and "0.016 s" in note
    note = load_case(SMOKE, ["solver.max_time_step_s=8e-3", "output.every_steps=5"]) \
        .step_growth_note
    assert note is not None and "every step is time_step_s" in note
    assert load_case(SMOKE, ["solver.max_time_step_s=1.6e-2", "output.every_steps=8"]) \
        .step_growth_note is None
    assert load_case(SMOKE).step_growth_note is None
    from typer.testing import CliRunner

    from masonry_nscd.cli import app

    out = CliRunner().invoke(app, ["validate", str(SMOKE), "--set", "solver.max_time_step_s=8e-3",
                                   "--set", "output.every_steps=5"])
    assert out.exit_code == 0 and "every step is time_step_s" in out.output


# --- runs -------------------------------------------------------------------------------------
def _rows(out):
    with open(out / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _run(tmp_path, name, sets):
    case = load_case(SMOKE, ["output.vtu=false", "output.every_steps=8", f"name={name}", *sets])
    res = run_case(case, tmp_path / name, **quiet)
    return res, _rows(tmp_path / name)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The smoke wall at h/2 (the reference), at h, at 8 h, and adaptive up to 8 h."""
    tmp = tmp_path_factory.mktemp("steps")
    out = {name: _run(tmp, name, sets) for name, sets in (
        ("reference", ["solver.time_step_s=1e-3"]), ("fixed", []),
        ("fixed_8h", ["solver.time_step_s=1.6e-2"]),
        ("adaptive", ["solver.max_time_step_s=1.6e-2"]))}
    return out, tmp


def _force_error(curve, ref):
    """Largest difference of F_x from the reference's at the same U_x during the push,
    relative to the reference's peak force."""
    m, mr = curve["time_s"] >= 0.1, ref["time_s"] >= 0.1
    f_ref = np.interp(curve["ux_mm"][m], ref["ux_mm"][mr], ref["fx_kN"][mr])
    return np.abs(curve["fx_kN"][m] - f_ref).max() / np.abs(ref["fx_kN"]).max()


def test_adaptive_steps_are_on_the_grid_fewer_and_as_accurate_as_their_largest(runs):
    """Steps of h 2^k on the grid of h, each starting on its own grid; fewer than at h; and
    the curve no further from the reference (h/2) than the fixed step of the largest size is
    (the smoke wall is pushed fast, 10 mm/s, so the step size shows in its curve)."""
    out, _ = runs
    (res0, fixed), (res, b) = out["fixed"], out["adaptive"]
    assert res.unconverged_steps == 0
    span = np.round(b["time_step_s"] / H).astype(int)
    assert set(span) <= {1, 2, 4, 8} and span.max() > 1
    assert np.allclose(b["time_step_s"], span * H, rtol=1e-12)
    n_end = np.round(b["time_s"] / H).astype(int)
    assert np.allclose(b["time_s"], n_end * H, rtol=0, atol=1e-9)
    assert np.all((n_end - span) % span == 0)  # each step started on its own grid
    assert np.array_equal(np.diff(np.concatenate([[0], n_end])), span)
    assert res.steps == len(b["step"]) < res0.steps
    ref = out["reference"][1]
    assert _force_error(b, ref) <= _force_error(out["fixed_8h"][1], ref)
    assert b["ux_mm"][-1] >= 0.5 and fixed["ux_mm"][-1] >= 0.5  # both reached the target


def test_adaptive_fields_are_written_at_the_times_asked_for(runs):
    _, tmp = runs
    t_adaptive, t_fixed = ([s.time for s in read_results(tmp / name / "results.h5")["steps"]]
                           for name in ("adaptive", "fixed"))
    # every 8 steps of h, as in the fixed run, and at the last step
    assert len(t_adaptive) > 3
    assert np.allclose(t_adaptive[:-1], t_fixed[:len(t_adaptive) - 1], rtol=0, atol=1e-9)
    n = np.array(t_adaptive[:-1]) / (8 * H)
    assert np.allclose(n, np.round(n), rtol=0, atol=1e-6)


def test_adaptive_steps_are_of_h_where_a_cyclic_path_turns(tmp_path):
    """One cycle of +-0.5 then +-1 mm of the smoke wall with steps up to 8 h: every step that
    ends inside a turn of the path (a tanh ramp of 20 ms around each corner) or crosses into
    one is of h, so that the beam stops at the amplitudes as with every step of h (the path
    turns exactly at them, loading/histories.py), and larger steps are taken between turns."""
    sets = ["loading.horizontal.history=cyclic", "loading.horizontal.ramp_s=0.02",
            "loading.horizontal.rate_m_s=0.005", "loading.horizontal.amplitudes_m=[0.5e-3,1e-3]",
            "output.hdf5=false"]
    res_h, fixed = _run(tmp_path, "fixed", sets)
    res, b = _run(tmp_path, "adaptive", [*sets, "solver.max_time_step_s=1.6e-2"])
    assert res.unconverged_steps == 0 and res.steps < res_h.steps
    scene = build_scene(load_case(SMOKE, sets))
    turns = scene.turns_s
    assert len(turns) == 6  # from rest, four reversals, to rest
    end, span = b["time_s"], b["time_step_s"]
    start = end - span
    crosses = np.array([any(s0 < t1 - 1e-12 and e0 > t0 + 1e-12 for t0, t1 in turns)
                        for s0, e0 in zip(start, end, strict=True)])
    assert crosses.sum() > 20 and np.allclose(span[crosses], H, rtol=1e-12)
    assert span.max() >= 4 * H - 1e-12
    for amp in (0.5, 1.0):  # mm
        for sign in (1.0, -1.0):
            near = np.abs(fixed["ux_mm"] - sign * amp) < 0.05 * amp
            near_b = np.abs(b["ux_mm"] - sign * amp) < 0.05 * amp
            extreme = (lambda u: u.max()) if sign > 0 else (lambda u: u.min())
            assert extreme(b["ux_mm"][near_b]) == pytest.approx(
                extreme(fixed["ux_mm"][near]), abs=1e-6 * amp)


def test_a_failed_large_step_is_made_again_smaller(tmp_path):
    """The smoke wall with no vertical stress rocks on its joints and Newton fails at h on
    some steps (tests/test_substeps.py): with the adaptive step the large steps that fail are
    made again smaller, and every step converges."""
    res, b = _run(tmp_path, "rocking", ["loading.vertical_stress.value_Pa=0",
                                         "solver.max_time_step_s=1.6e-2"])
    assert res.unconverged_steps == 0 and b["converged"].all()
    assert b["time_step_s"].max() > H  # it did grow
    log = (tmp_path / "rocking" / "run.log").read_text()
    assert "step sizes:" in log


def test_a_rung_step_is_a_step_of_the_larger_size(tmp_path):
    """A step of level 1 is exactly the step of an integrator built at 2h from the same state
    with the same predictor: the rung is that integrator."""
    from masonry_nscd.nscd.checkpoint import integrator_state, restore_integrator
    from masonry_nscd.scenes import build_scene

    scene = build_scene(load_case(SMOKE, ["solver.max_time_step_s=4e-3",
                                          "output.every_steps=2"]))
    a = scene.integrator()
    for _ in range(40):  # through gravity, into the vertical stress ramp
        a.step()
    a.control.level, a.control.easy = 1, 0
    n = round(a.t / H)
    if n % 2:
        a.step()
    b = build_scene(load_case(SMOKE, ["solver.time_step_s=4e-3"])).integrator()
    restore_integrator(b, integrator_state(a))
    b.newton.adopt_solutions(a.newton if a._made_by == 0 else a._rungs[a._made_by].newton)
    rep = a.step()
    assert rep.span == 2
    b.step()
    assert np.array_equal(a.u, b.u) and np.array_equal(a.v, b.v)
    assert np.array_equal(a.joints.T, b.joints.T)


def test_a_resumed_adaptive_run_reaches_the_same_curve(tmp_path, interrupt_before_step):
    """Interrupted and resumed: the step control's level is in the checkpoint; the solver's
    factorisation is not, so the iterations (and with them the step sizes) may differ. Up to
    the resumed step the curves are the same; after it, each on its exact path, they differ by
    the time step's error only: at most one step's change of the force (compared at the rows
    of both)."""
    sets = ["output.vtu=false", "output.every_steps=8", "solver.max_time_step_s=1.6e-2"]
    ref = tmp_path / "ref"
    run_case(load_case(SMOKE, sets), ref, **quiet)
    interrupt_before_step(60)
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE, sets), out, **quiet)
    resumed = read_resume_point(out).step
    assert resumed < 60
    run_case(load_case(out / "case.yaml"), out, resume=True, **quiet)
    a, b = _rows(out), _rows(ref)
    assert a["converged"].all()
    before = a["step"] <= resumed
    assert np.array_equal(a["fx_kN"][before], b["fx_kN"][:before.sum()])
    f_ref = np.interp(a["time_s"], b["time_s"], b["fx_kN"])
    one_step = np.abs(np.diff(b["fx_kN"][before.sum() - 1:])).max()
    assert np.abs(a["fx_kN"] - f_ref).max() <= one_step
    assert abs(a["ux_mm"][-1] - b["ux_mm"][-1]) <= 1e-9 * b["ux_mm"][-1]


def test_the_step_report_gives_the_largest_loss_of_integrity():
    """``damage_growth`` of a step is ``max(beta_n - beta_n+1)`` over the joint points (the
    smoke wall's elastic blocks have no ENDO3D damage), pushed to 2 mm with no vertical stress
    so that its joints crack."""
    from masonry_nscd.scenes import build_scene

    integ = build_scene(load_case(SMOKE, ["loading.vertical_stress.value_Pa=0",
                                          "loading.horizontal.target_m=2e-3"])).integrator()
    seen = 0.0
    for _ in range(500):
        beta0 = integ.joints.beta.copy()
        rep = integ.step()
        assert rep.damage_growth == pytest.approx(max(0.0, np.max(beta0 - integ.joints.beta)),
                                                  rel=0, abs=1e-15)
        seen = max(seen, rep.damage_growth)
    assert seen > 0.0  # the push cracks joints: the check did see a loss
