"""`masonry calibrate`: finds back the d_spring of a run from its stiffness; clear errors."""

import json

import pytest
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.studies import calibrate as cal

# the smoke wall, short: loaded vertically by 0.04 s, then sheared; the stiffness is measured
# between 10 and 40 % of mu N = 0.7 x 69 kN, reached about 15 steps into the horizontal stage
SHORT = ["loading.gravity.ramp_s=0.01", "loading.vertical_stress.start_s=0.01",
         "loading.vertical_stress.ramp_s=0.03", "loading.horizontal.start_s=0.04",
         "loading.horizontal.ramp_s=0.02", "loading.horizontal.target_m=0.2e-3"]
SETS = [a for s in SHORT for a in ("--set", s)]
X0 = 0.95


@pytest.fixture(scope="module")
def k0(tmp_path_factory):
    """The stiffness of the short smoke wall at d_spring = X0 (kN/mm)."""
    case = load_case("cases/smoke.yaml", [*SHORT, f"joint.d_spring={X0}", "output.vtu=false",
                                          "output.hdf5=false"])
    e = cal.measure_stiffness(case, tmp_path_factory.mktemp("k0") / "run",
                              cal.default_force_range_kN(case), X0)
    assert e.stiffness_kN_mm is not None
    return e.stiffness_kN_mm


def test_calibrate_finds_back_the_value_of_a_run(k0, tmp_path):
    out = tmp_path / "cal"
    res = CliRunner().invoke(app, ["calibrate", "cases/smoke.yaml", "--target-stiffness",
                                   repr(k0), "--bounds", "0.9:0.98", "--rtol", "1e-4",
                                   "-o", str(out), *SETS])
    assert res.exit_code == 0, res.output
    report = json.loads((out / "calibration.json").read_text())
    assert report["value"] == pytest.approx(X0, abs=3e-4)
    assert report["stiffness_kN_mm"] == pytest.approx(k0, rel=1e-4)
    k_lo, k_hi = report["stiffness_at_bounds_kN_mm"]
    assert k_lo > k0 > k_hi  # a softer spring, a softer wall
    assert report["force_low_kN"] == pytest.approx(0.1 * 0.7 * 69.0)
    assert report["runs"] == len(report["evaluations"]) <= 10
    case = load_case(out / "smoke_calibrated.yaml")
    assert case.name == "smoke_calibrated"
    assert case.joint.d_spring == report["value"]
    assert case.loading.horizontal.start_s == 0.04  # the --set overrides are kept
    assert case.output.vtu is True  # the short runs' output settings are not
    assert "value in the case file: 0.953" in res.output


def test_calibrate_says_the_stiffness_at_the_bounds_when_the_target_is_not_bracketed(tmp_path):
    res = CliRunner().invoke(app, ["calibrate", "cases/smoke.yaml", "--target-stiffness", "1e5",
                                   "--bounds", "0.9:0.98", "-o", str(tmp_path / "c"), *SETS])
    assert res.exit_code == 2, res.output
    assert "not between the stiffnesses at the bounds" in res.output
    assert "joint.d_spring = 0.9 gives" in res.output and "0.98 gives" in res.output


@pytest.mark.parametrize("args, message", [
    (["--param", "joint.mu"], "--bounds LOW:HIGH is needed"),
    (["--param", "joint.nope", "--bounds", "0:1"], "no such field"),
    (["--bounds", "0.9:1.2"], "joint.d_spring: got 1.2"),
    (["--bounds", "0.98:0.9"], "LOW < HIGH"),
    (["--force-range", "abc"], "--force-range must be LOW:HIGH"),
])
def test_calibrate_refuses_bad_options_before_running(args, message, tmp_path):
    res = CliRunner().invoke(app, ["calibrate", "cases/smoke.yaml", "--target-stiffness", "71",
                                   "-o", str(tmp_path / "c"), *args])
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert not (tmp_path / "c" / "runs").exists()
