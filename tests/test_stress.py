"""The stress test (``masonry stress-test``): a fast subset of the variants, and how outcomes are
judged (finished in equilibrium, clean failure, solver exception)."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.nscd.integrator import DivergenceError, Integrator
from masonry_nscd.studies import stress

runner = CliRunner()

# each a second or two on the smoke wall
FAST = ["time_step_x10", "theta_0.5", "stress_5MPa", "friction_0", "joints_broken",
        "one_course", "slender", "rigid_blocks"]


def test_variants_are_valid_cases():
    base = load_case(stress.DEFAULT_BASE)
    names = [v.name for v in stress.VARIANTS]
    assert len(set(names)) == len(names)
    for v in stress.VARIANTS:
        case = load_case(stress.DEFAULT_BASE, v.overrides(base))
        assert case.wall.courses >= 1, v.name
    assert set(FAST) <= {v.name for v in stress.select(quick=True)}
    with pytest.raises(ValueError, match="unknown"):
        stress.select(names=["nope"])


def test_fast_subset_finishes_in_equilibrium(tmp_path):
    results = stress.stress_test(tmp_path, names=FAST, echo=lambda m: None)
    bad = [(r.case, r.outcome, r.message) for r in results if r.outcome != "ok"]
    assert not bad
    for r in results:
        assert r.steps > 0 and r.worst_residual <= 1e-8
        assert r.equilibrium_error <= stress.EQUILIBRIUM_TOLERANCE
        assert (tmp_path / r.case / "force_displacement.csv").exists()
    with open(tmp_path / "stress.csv") as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == stress.CSV_HEADER
    assert [r["case"] for r in rows] == FAST and {r["outcome"] for r in rows} == {"ok"}


def test_cli_stress_test(tmp_path):
    out = tmp_path / "st"
    res = runner.invoke(app, ["stress-test", "-o", str(out), "--only", "time_step_x10",
                              "--only", "rigid_blocks"])
    assert res.exit_code == 0, res.output
    assert "time_step_x10" in res.output and "2 of 2 variants acceptable" in res.output
    assert (out / "stress.csv").exists()
    res = runner.invoke(app, ["stress-test", "-o", str(out), "--only", "time_step_x10"])
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = runner.invoke(app, ["stress-test", "-o", str(tmp_path / "x"), "--only", "nope"])
    assert res.exit_code == 2 and "unknown variant" in res.output


def _variant(name):
    return next(v for v in stress.VARIANTS if v.name == name)


def test_divergence_is_a_clean_failure(tmp_path, monkeypatch):
    orig = Integrator.step

    def step(self):
        if self.step_index == 6:
            raise DivergenceError(self.step_index + 1, 0.042, "body velocities")
        return orig(self)

    monkeypatch.setattr(Integrator, "step", step)
    r = stress.run_variant(stress.DEFAULT_BASE, _variant("time_step_x3"), tmp_path / "v")
    assert r.outcome == "failed" and r.acceptable
    assert "step 7" in r.message and "vertical stage" in r.message and "not finite" in r.message
    assert r.steps == 6  # the rows before the failing step


def test_solver_exception_is_reported_cleanly(tmp_path, monkeypatch):
    orig = Integrator.step

    def step(self):
        if self.step_index == 40:
            raise ZeroDivisionError("division by zero")
        return orig(self)

    monkeypatch.setattr(Integrator, "step", step)
    r = stress.run_variant(stress.DEFAULT_BASE, _variant("reference"), tmp_path / "v")
    # run_case turns it into a RunFailure naming the step and the stage
    assert r.outcome == "failed"
    assert "step 41 (vertical stage" in r.message and "ZeroDivisionError" in r.message


def test_exception_outside_the_steps_is_an_error(tmp_path, monkeypatch):
    import masonry_nscd.studies.point as point_mod

    def broken(*args, **kwargs):
        raise KeyError("oops")

    monkeypatch.setattr(point_mod, "run_case", broken)
    r = stress.run_variant(stress.DEFAULT_BASE, _variant("reference"), tmp_path / "v")
    assert r.outcome == "error" and not r.acceptable and "KeyError" in r.message


def test_equilibrium_error_is_the_momentum_balance():
    """P(k2) - P(k1) = sum h (F + F_b + W): a wall at rest under balanced forces, then one
    accelerated by an unbalanced force with the matching change of momentum, balance; the
    same force without the momentum change is off by the force over the largest force."""
    n, h = 20, 1e-3
    curve = {"step": np.arange(1, n + 1), "fx_kN": np.full(n, 10.0),
             "fx_bottom_kN": np.full(n, -10.0), "fy_kN": np.full(n, -50.0),
             "fy_bottom_kN": np.full(n, 51.0)}
    rest = (np.zeros(2), np.zeros(2))
    assert stress.equilibrium_error(curve, 1.0, h, (10, 20), rest) == 0.0
    curve["fx_bottom_kN"][10:] = -9.0  # 1 kN unbalanced over steps 11..20
    moving = (np.zeros(2), np.array([1e3 * h * 10 * 1.0, 0.0]))  # N s
    assert stress.equilibrium_error(curve, 1.0, h, (10, 20), moving) == pytest.approx(0.0,
                                                                                      abs=1e-12)
    assert stress.equilibrium_error(curve, 1.0, h, (10, 20), rest) == pytest.approx(1.0 / 51.0)
    assert np.isnan(stress.equilibrium_error({}, 1.0, h, (10, 20), rest))
    assert np.isnan(stress.equilibrium_error(curve, 1.0, h, (10, 30), rest))


def test_a_lost_step_stops_the_run_and_keeps_a_summary(tmp_path, monkeypatch):
    """A step whose forces still change by more than LOST_RESIDUAL per iteration ends the run
    (exit 1 path) instead of being recorded; summary.json describes what was computed."""
    import dataclasses
    import json

    from masonry_nscd import run as run_mod

    orig = Integrator.step

    def step(self):
        rep = orig(self)
        if rep.step == 20:
            return dataclasses.replace(rep, residual=0.5, converged=False)
        return rep

    monkeypatch.setattr(Integrator, "step", step)
    r = stress.run_variant(stress.DEFAULT_BASE, _variant("reference"), tmp_path / "v")
    assert r.outcome == "failed"
    assert "step 20" in r.message and "0.5" in r.message
    assert run_mod.LOST_RESIDUAL < 0.5
    summary = json.loads((tmp_path / "v" / "summary.json").read_text())
    assert summary["steps"] == 19
