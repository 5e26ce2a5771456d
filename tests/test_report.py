"""The run summary (masonry_nscd.report): synthetic curves with known answers, and a smoke run."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.cli import app
from masonry_nscd.io.results_h5 import read_fields
from masonry_nscd.io.runfolder import read_curve_csv, read_scene_info
from masonry_nscd.io.summary_json import write_summary
from masonry_nscd.report import (
    compute_summary,
    first_crossing,
    largest_damages,
    secant_stiffness,
    summarize_run,
)
from masonry_nscd.run import CSV_COLUMNS


def _curve(ux_mm, fx_kN, start_s=0.25, h=0.002, before=20, converged=None):
    """A curve in the CSV's columns: ``before`` rows at rest, then the horizontal stage."""
    ux = np.concatenate([np.zeros(before), ux_mm])
    fx = np.concatenate([np.zeros(before), fx_kN])
    n = len(ux)
    c = {k: np.zeros(n) for k in CSV_COLUMNS}
    c["step"] = np.arange(1, n + 1, dtype=float)
    c["time_s"] = start_s + h * (np.arange(n) - before)
    c["ux_mm"], c["fx_kN"] = ux, fx
    c["converged"] = np.ones(n) if converged is None else \
        np.concatenate([np.ones(before), converged])
    c["residual"] = np.full(n, 1e-9)
    c["iterations"] = np.full(n, 4.0)
    return c


def _bilinear(u):
    """71 kN/mm to 71 kN at 1 mm, 14.5 kN/mm to the peak of 100 kN at 3 mm, then down to
    60 kN at 10 mm (linear)."""
    return np.where(u <= 1.0, 71.0 * u,
                    np.where(u <= 3.0, 71.0 + 14.5 * (u - 1.0), 100.0 - 40.0 / 7.0 * (u - 3.0)))


def test_bilinear_curve_gives_its_slope_peak_and_force_at_the_target():
    u = np.linspace(0.0, 12.0, 241)  # 0.05 mm rows: 3 and 10 mm are rows, 1 mm too
    s = compute_summary(_curve(u, _bilinear(u)), target_ux_mm=10.0, horizontal_start_s=0.25)
    # 10 % and 40 % of the 100 kN peak are on the first branch: the secant is its slope
    assert s["initial_stiffness_kN_mm"] == pytest.approx(71.0, rel=1e-12)
    assert s["stiffness_force_low_kN"] == pytest.approx(10.0)
    assert s["stiffness_force_high_kN"] == pytest.approx(40.0)
    assert s["stiffness_ux_low_mm"] == pytest.approx(10.0 / 71.0)
    assert s["stiffness_ux_high_mm"] == pytest.approx(40.0 / 71.0)
    assert s["peak_force_kN"] == pytest.approx(100.0)
    assert s["ux_at_peak_mm"] == pytest.approx(3.0)
    assert s["force_at_target_kN"] == pytest.approx(60.0)
    assert s["target_reached"] is True
    assert s["unconverged_steps"] == 0 and s["peak_force_unconverged_kN"] is None


def test_secant_and_force_at_the_target_are_interpolated_between_coarse_rows():
    u = np.array([0.0, 0.07, 0.5, 1.0, 2.2, 4.1, 7.3, 9.6, 10.9])  # no row at 10 mm
    s = compute_summary(_curve(u, _bilinear(u)), target_ux_mm=10.0, horizontal_start_s=0.25)
    assert s["initial_stiffness_kN_mm"] == pytest.approx(71.0, rel=1e-12)
    # between (9.6, 63.43) and (10.9, 56.0) on the straight falling branch
    assert s["force_at_target_kN"] == pytest.approx(60.0, rel=1e-12)
    # when the upper level lies on the second branch, the secant is the chord between levels
    k, _, u_hi = secant_stiffness(u, _bilinear(u), 10.0, 85.5)
    assert u_hi == pytest.approx(2.0, rel=1e-12)  # 71 + 14.5 (u - 1) = 85.5 at u = 2
    assert k == pytest.approx(75.5 / (2.0 - 10.0 / 71.0), rel=1e-12)


def test_stiffness_is_undefined_when_the_stage_starts_above_the_lower_level():
    u = np.linspace(0.0, 5.0, 101)
    s = compute_summary(_curve(u, 20.0 + _bilinear(u)), horizontal_start_s=0.25)
    assert s["fx_at_horizontal_start_kN"] == pytest.approx(20.0)
    assert s["initial_stiffness_kN_mm"] is None  # 10 % of 120 kN = 12 kN < 20 kN at the start
    assert first_crossing([0.0, 1.0], [5.0, 6.0], 5.0) is None


def test_unconverged_steps_do_not_set_the_peak_and_are_counted():
    u = np.linspace(0.0, 5.0, 101)
    f = _bilinear(u)
    conv = np.ones_like(u)
    f[70], conv[70] = 250.0, 0  # a spurious spike of a step that did not converge
    s = compute_summary(_curve(u, f, converged=conv), target_ux_mm=10.0, horizontal_start_s=0.25)
    assert s["peak_force_kN"] == pytest.approx(100.0)
    assert s["peak_force_unconverged_kN"] == pytest.approx(250.0)
    assert s["unconverged_steps"] == 1
    assert s["force_at_target_kN"] is None and s["target_reached"] is False


def test_horizontal_stage_found_from_the_displacement_without_the_case():
    u = np.linspace(0.0, 4.0, 81)
    c = _curve(u, _bilinear(u))
    c["fx_kN"][:20] = 50.0  # whatever happens before U_x moves is not the horizontal stage
    s = compute_summary(c)
    assert s["initial_stiffness_kN_mm"] == pytest.approx(71.0, rel=1e-12)
    assert s["horizontal_stage_rows"] == 81


def test_csv_reader_drops_a_cut_last_row_and_summary_json_is_valid(tmp_path):
    path = tmp_path / "force_displacement.csv"
    path.write_text("step,time_s,ux_mm,fx_kN\n1,0.1,0,0\n2,0.2,0.5,3\n3,0.3,1.")
    c = read_curve_csv(path)
    assert list(c["step"]) == [1.0, 2.0]
    write_summary(tmp_path, {"peak_force_kN": 1.5, "initial_stiffness_kN_mm": None})
    assert json.loads((tmp_path / "summary.json").read_text())["peak_force_kN"] == 1.5
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "run"
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out)])
    assert res.exit_code == 0, res.output
    return out, res.output


def test_smoke_run_summary_is_consistent_with_its_csv(smoke_run):
    out, text = smoke_run
    s = json.loads((out / "summary.json").read_text())
    c = read_curve_csv(out / "force_displacement.csv")
    stage = c["time_s"] >= 0.1  # cases/smoke.yaml: loading.horizontal.start_s
    i = int(np.argmax(np.where(stage, c["fx_kN"], -np.inf)))
    assert s["peak_force_kN"] == pytest.approx(c["fx_kN"][i])
    assert s["ux_at_peak_mm"] == pytest.approx(c["ux_mm"][i])
    assert s["target_ux_mm"] == pytest.approx(0.5)
    assert s["force_at_target_kN"] == pytest.approx(
        np.interp(0.5, c["ux_mm"][stage], c["fx_kN"][stage]), rel=1e-9)
    assert s["unconverged_steps"] == int(np.sum(c["converged"] == 0))
    assert s["worst_residual"] == pytest.approx(c["residual"].max())
    assert s["steps"] == int(c["step"][-1])
    # the secant: levels at 10 and 40 % of the peak, crossings on the CSV rows
    f_lo, f_hi = 0.1 * s["peak_force_kN"], 0.4 * s["peak_force_kN"]
    assert s["stiffness_force_low_kN"] == pytest.approx(f_lo)
    u_lo = np.interp(f_lo, c["fx_kN"][stage][:i], c["ux_mm"][stage][:i])
    u_hi = np.interp(f_hi, c["fx_kN"][stage][:i], c["ux_mm"][stage][:i])
    assert s["initial_stiffness_kN_mm"] == pytest.approx((f_hi - f_lo) / (u_hi - u_lo), rel=1e-9)
    assert 50.0 < s["initial_stiffness_kN_mm"] < 5000.0
    # elastic blocks, 0.5 mm: no block damage, joints at their initial damage, read from HDF5
    assert s["damage_step"] == s["steps"]
    assert s["largest_damage"]["block_d_c"] == {"value": 0.0, "elements_above_0.5": 0,
                                                "where": None}
    assert s["largest_damage"]["joint_d_coh"]["value"] == pytest.approx(0.99944)
    assert "summary: initial stiffness" in text and "summary: peak force" in text


def test_largest_damages_say_where_they_are(smoke_run):
    """The smoke wall's mesh (3 courses, 3 and 4 units, one element per unit) with damage
    put by hand: the report names the unit, its course and position, and x, y."""
    out, _ = smoke_run
    f = read_fields(out / "results.h5")
    right_bottom = int(np.flatnonzero(f.block_of_element == 2)[0])  # 3rd unit of course 1
    f.d_c[right_bottom] = 0.7
    f.d_t[:] = 0.0
    f.d_t[int(np.flatnonzero(f.block_of_element == 3)[0])] = 0.4  # half unit, course 2, left
    # a bed-joint point under the 2nd unit of course 2 (x from 0.155 to 0.455 m, y0 = 0.11 m),
    # over the 2nd unit of course 1 (x from 0.31 to 0.61 m)
    bed = np.flatnonzero((f.contact_group == 0) & (np.abs(f.contact_points_m[:, 1] - 0.11) < 1e-9)
                         & (f.contact_points_m[:, 0] > 0.31) & (f.contact_points_m[:, 0] < 0.455))
    f.joint_beta[bed[0]] = 0.25
    d = largest_damages(f, read_scene_info(out))
    assert d["block_d_c"]["where"] == "course 1 (bottom), unit 3 of 3 (right end)"
    assert (d["block_d_c"]["x_m"], d["block_d_c"]["y_m"]) == pytest.approx((0.77, 0.05))
    assert d["block_d_c"]["unit_index"] == 2 and d["block_d_c"]["value"] == 0.7
    assert d["block_d_t"]["where"] == "course 2, unit 1 of 4 (left end)"
    assert (d["block_d_t"]["x_m"], d["block_d_t"]["y_m"]) == pytest.approx((0.0725, 0.16))
    j = d["joint_d_coh"]
    assert j["where"] == ("bed joint between course 1 (bottom), unit 2 of 3 and course 2, unit "
                          "2 of 4")
    assert (j["course"], j["position_in_course"]) == (2, 2)
    assert j["beta"] == 0.25 and j["value"] == pytest.approx(1.0 - 0.25 * (1.0 - 0.99944))
    assert j["y_m"] == pytest.approx(0.11)
    assert d["block_d_cpp"]["where"] is None


def test_interrupted_and_stopped_runs_still_write_their_summary(tmp_path):
    """``stop_when`` ends a run early (RunResult.stopped); an interruption (here raised by the
    callback, as Ctrl-C would be) still leaves a summary.json behind."""
    from masonry_nscd.case import load_case
    from masonry_nscd.run import run_case

    case = load_case("cases/smoke.yaml", ["output.vtu=false"])
    res = run_case(case, tmp_path / "stopped", echo=lambda m: None,
                   stop_when=lambda c: c["fx_kN"][-1] > 10.0)
    assert res.stopped and 10.0 < res.fx_kN < 20.0
    s = summarize_run(tmp_path / "stopped")
    assert s["last_fx_kN"] == pytest.approx(res.fx_kN) and s["target_reached"] is False

    def interrupt(c):
        if len(c["step"]) >= 60:
            raise KeyboardInterrupt
        return False

    with pytest.raises(KeyboardInterrupt):
        run_case(case, tmp_path / "cut", echo=lambda m: None, stop_when=interrupt)
    s = json.loads((tmp_path / "cut" / "summary.json").read_text())
    assert s["steps"] == 60 and s["target_reached"] is False
