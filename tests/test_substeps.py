"""A step the solver does not finish is made again as two steps of h/2 (``solver.max_step_halvings``).
"""

from __future__ import annotations

import csv
import json

import numpy as np

from masonry_nscd.case import load_case
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

SMOKE = "cases/smoke.yaml"


def test_a_subdivided_step_is_two_steps_of_half_the_size():
    """One iteration per step never converges, so the step at h is made again at h/2; the state
    it ends in must be, bit for bit, that of an integrator built at h/2 stepped twice (the
    failed attempt leaves nothing behind, not even in the predictor: the halves predict from
    the run's last solutions, and the next step from the halves, as ``b`` does by itself)."""
    unconverging = ["solver.max_iterations=1", "solver.check_every=1"]
    a = build_scene(load_case(SMOKE, [*unconverging, "solver.max_step_halvings=1"])).integrator()
    b = build_scene(load_case(SMOKE, [*unconverging, "solver.max_step_halvings=0",
                                     "solver.time_step_s=1e-3"])).integrator()
    for _ in range(3):
        rep = a.step()
        reps = [b.step(), b.step()]
        assert rep.substeps == 2 and not rep.converged
        assert rep.step == a.step_index and a.step_index == b.step_index // 2
        assert rep.time == a.t and abs(a.t - b.t) < 1e-15
        assert rep.sweeps > sum(r.sweeps for r in reps)  # the failed attempt counts
        assert rep.residual == max(r.residual for r in reps)
        assert np.array_equal(a.u, b.u) and np.array_equal(a.v, b.v)
        for name in ("u", "U", "uc", "beta", "T", "status"):
            assert np.array_equal(getattr(a.joints, name), getattr(b.joints, name)), name


def _run(tmp_path, name, extra):
    case = load_case(SMOKE, ["loading.vertical_stress.value_Pa=0", "output.vtu=false",
                             "output.hdf5=false", f"name={name}", *extra])
    res = run_case(case, tmp_path / name, echo=lambda m: None)
    with open(tmp_path / name / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    summary = json.loads((tmp_path / name / "summary.json").read_text())
    return res, rows, summary


def test_the_rocking_wall_converges_when_its_hard_steps_are_halved(tmp_path):
    """The smoke wall with no vertical stress rocks on its joints; at h = 2e-3 s Newton and the
    Gauss-Seidel sweeps leave steps above the tolerance 1e-8. Halving those steps must leave
    none, and the run must still end on the grid of h with one CSV row per step of h."""
    res0, _, _ = _run(tmp_path, "kept", ["solver.max_step_halvings=0"])
    assert res0.unconverged_steps > 0
    res, rows, summary = _run(tmp_path, "halved", [])
    assert res.unconverged_steps == 0
    assert len(rows) == res.steps == res0.steps
    h = 2e-3
    for r in rows:
        assert abs(float(r["time_s"]) - int(r["step"]) * h) < 1e-12
        assert float(r["residual"]) <= 1e-8
    sub = [int(r["substeps"]) for r in rows]
    assert summary["steps_subdivided"] == sum(s > 1 for s in sub) > 0
    assert summary["unconverged_steps"] == 0


def test_a_step_that_diverges_is_halved_and_named_if_it_still_diverges(monkeypatch):
    """A NaN at h is tried again at h/2 (here it is gone there); a NaN at every size is
    raised with the step's number in the run and the smallest size tried."""
    from masonry_nscd.nscd import integrator as integ_mod

    orig = integ_mod.Integrator._step
    sizes: list[float] = []

    def step(self, diverge_below=1.5e-3):
        sizes.append(self.sys.h)
        if self.step_index == 4 and self.sys.h > diverge_below:
            self.step_index += 1
            raise integ_mod.DivergenceError(self.step_index, self.t + self.sys.h,
                                            "body velocities")
        return orig(self)

    monkeypatch.setattr(integ_mod.Integrator, "_step", step)
    a = build_scene(load_case(SMOKE, ["solver.max_step_halvings=2"])).integrator()
    reps = [a.step() for _ in range(6)]
    assert [r.substeps for r in reps] == [1, 1, 1, 1, 2, 1]
    assert all(r.converged for r in reps) and a.step_index == 6
    assert abs(a.t - 6 * 2e-3) < 1e-15 and np.isfinite(a.u).all()

    monkeypatch.setattr(integ_mod.Integrator, "_step",
                        lambda self: step(self, diverge_below=0.0))
    b = build_scene(load_case(SMOKE, ["solver.max_step_halvings=2"])).integrator()
    for _ in range(4):
        b.step()
    sizes.clear()
    try:
        b.step()
    except integ_mod.DivergenceError as exc:
        msg = str(exc)
    else:
        raise AssertionError("no DivergenceError")
    assert msg.startswith("step 5 (t = ") and "body velocities not finite" in msg
    assert "also in steps of 0.001 s and smaller" in msg
    assert sizes == [2e-3, 1e-3, 5e-4]  # each size once: the first half diverges at every one


def test_after_a_failure_the_next_steps_are_halved_at_once(monkeypatch):
    """``solver.halved_steps_after_failure: 2``: a step that fails at h (here steps 5 to 9,
    forced) is made as halves; the next two steps are made as halves at once, without the
    attempt at h; the attempt after them fails again, so the next run of halves is twice as
    long; the first attempt at h that converges ends the memory."""
    from masonry_nscd.nscd import integrator as integ_mod

    orig = integ_mod.Integrator._step
    tried: list[int] = []

    def step(self):
        if self.sys.h > 1.5e-3:
            tried.append(self.step_index + 1)
            if 5 <= self.step_index + 1 <= 9:
                self.step_index += 1
                raise integ_mod.DivergenceError(self.step_index, self.t + self.sys.h, "forced")
        return orig(self)

    monkeypatch.setattr(integ_mod.Integrator, "_step", step)
    a = build_scene(load_case(SMOKE, ["solver.halved_steps_after_failure=2"])).integrator()
    reps = [a.step() for _ in range(16)]
    # h tried at 1-5, fails at 5 -> 6, 7 halved; tried at 8, fails -> 9 to 12 halved; tried
    # at 13, converges; 14 to 16 at h again
    assert tried == [1, 2, 3, 4, 5, 8, 13, 14, 15, 16]
    assert [r.substeps for r in reps] == [1] * 4 + [2] * 8 + [1] * 4
    assert [r.tried_h for r in reps] == [True] * 5 + [False] * 2 + [True] + [False] * 4 \
        + [True] * 4
    assert all(r.converged for r in reps) and a.step_index == 16
    assert abs(a.t - 16 * 2e-3) < 1e-15


def test_the_stiffest_springs_of_the_stress_test_converge_by_halving(tmp_path):
    """The stress test's 1e13 Pa/m springs close with a stiffness 300 times the wall's, where
    Newton may fail at h (9 of 100 steps did with another round-off, 19 at h/2 throughout):
    with the halving the variant must end ``ok`` (finite, converged, in equilibrium), whichever
    steps round-off makes fail."""
    from masonry_nscd.studies import stress

    variant = next(v for v in stress.VARIANTS if v.name == "spring_1e13")
    r = stress.run_variant(stress.DEFAULT_BASE, variant, tmp_path / "v")
    assert r.outcome == "ok", r.message
    assert r.unconverged_steps == 0 and r.worst_residual <= 1e-8


def test_a_step_whose_newton_iterations_cycle_is_halved_and_the_log_says_why(tmp_path,
                                                                            monkeypatch):
    """``newton._Cycle``: a step whose iterations close a cycle is given up at once and made
    again as halves; the count reaches ``solver_counts`` and the run log names the reason.
    The cycle is forced at step 5's attempt at h (at its first iterate), as a wall's step can
    meet one at a kink of the residual."""
    from masonry_nscd.nscd import integrator as integ_mod
    from masonry_nscd.nscd import newton

    forced = {"on": False}
    step_orig = integ_mod.Integrator._step
    closed_orig = newton._Cycle.closed_by

    def step(self):
        forced["on"] = self.sys.h > 1.5e-3 and self.step_index + 1 == 5
        try:
            return step_orig(self)
        finally:
            forced["on"] = False

    def closed_by(self, norm, measure):
        return True if forced["on"] else closed_orig(self, norm, measure)

    monkeypatch.setattr(integ_mod.Integrator, "_step", step)
    monkeypatch.setattr(newton._Cycle, "closed_by", closed_by)
    res, rows, summary = _run(tmp_path, "cycled", ["loading.vertical_stress.value_Pa=1e5",
                                                   "loading.horizontal.target_m=2e-4"])
    assert [int(r["substeps"]) for r in rows[:6]] == [1, 1, 1, 1, 2, 1]
    assert res.unconverged_steps == 0 and summary["steps_subdivided"] == 1
    log = (tmp_path / "cycled" / "run.log").read_text()
    assert ("step 5 (t = 0.0100 s): not converged with h = 0.002 s (Newton's iterations "
            f"cycled: an iterate met {newton.CYCLE_VISITS} times), made again as 2 smaller steps "
            "(converged)"
            in log)
