"""`masonry bench` and `masonry bench-scaling`: the error measures, the Pareto front, the ladder,
and short runs on the smoke wall (no timing is asserted: the figures depend on the machine)."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.studies import bench as bm

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
SMOKE = "cases/smoke.yaml"
NO_FIELDS = ["--set", "output.vtu=false", "--set", "output.hdf5=false"]


def _curve(ux_mm, fx_kN, t0=1.0):
    """A synthetic run curve: a horizontal stage from t0 (s), every step converged."""
    ux = np.asarray(ux_mm, dtype=float)
    n = len(ux)
    return {"step": np.arange(1, n + 1, dtype=float), "time_s": t0 + 0.01 * np.arange(n),
            "ux_mm": ux, "fx_kN": np.asarray(fx_kN, dtype=float), "converged": np.ones(n),
            "iterations": np.full(n, 3.0)}


def _wall_like(ux):
    """Rises with 50 kN/mm, then bends to a plateau at 40 kN (kN)."""
    return 40.0 * np.tanh(50.0 * ux / 40.0)


# --- error measures -------------------------------------------------------------------------


def test_rms_error_of_two_constant_curves_sampled_differently_is_their_ratio():
    # F_ref = 10 kN, F = 11 kN: RMS difference 1 kN, RMS of the reference 10 kN -> 0.1
    a = np.linspace(0.0, 2.0, 7)
    b = np.linspace(0.0, 2.5, 33)
    err = bm.curve_rms_error(b, np.full(b.size, 11.0), a, np.full(a.size, 10.0), 2.0)
    assert err == pytest.approx(0.1, rel=1e-12)


def test_rms_error_of_linear_curves_matches_the_grid_formula():
    # linear curves are interpolated exactly: F_ref = 2u + 1, F = 2u + 1.5 on other samplings
    a, b = np.linspace(0.0, 1.0, 5), np.linspace(0.0, 1.2, 17)
    grid = np.linspace(0.0, 1.0, bm.RMS_GRID_POINTS)
    expected = 0.5 / math.sqrt(np.mean((2 * grid + 1) ** 2))
    err = bm.curve_rms_error(b, 2 * b + 1.5, a, 2 * a + 1.0, 1.0)
    assert err == pytest.approx(expected, rel=1e-12)
    assert 0.5 / 2.1 < err < 0.5 / 1.7  # RMS of 2u + 1 over [0, 1] is sqrt(13/3) = 2.08


def test_rms_error_is_nan_when_a_curve_stops_short():
    u = np.linspace(0.0, 0.5, 11)
    assert math.isnan(bm.curve_rms_error(u, u, np.linspace(0, 1, 11), np.ones(11), 1.0))


def test_the_curve_starts_at_the_last_row_before_the_stage_when_the_first_has_moved():
    # a coarse time step: the first row of the stage (t >= 1 s) is already at U = 0.1 mm
    c = _curve([0.0, 0.1, 0.5, 1.0], [0.0, 5.0, 20.0, 30.0], t0=0.99)
    ux, fx = bm.horizontal_curve(c, start_s=1.0)
    assert ux.tolist() == [0.0, 0.1, 0.5, 1.0]
    assert bm.curve_rms_error(ux, fx, ux, fx, 1.0) == 0.0


def test_errors_of_the_reference_against_itself_are_zero():
    ux = np.concatenate([[0.0, 0.0], np.linspace(0.01, 1.2, 120)])
    ref = _curve(ux, _wall_like(ux))
    errs = bm.curve_errors(ref, ref, target_mm=1.0, start_s=1.0)
    assert set(errs) == {*bm.ERROR_COLUMNS, "err_max"}
    assert all(v == 0.0 for v in errs.values())


def test_errors_of_a_curve_scaled_by_3_percent_are_3_percent():
    ux = np.concatenate([[0.0], np.linspace(0.01, 1.2, 120)])
    ref = _curve(ux, _wall_like(ux))
    ux2 = np.concatenate([[0.0], np.linspace(0.007, 1.3, 200)])  # another sampling
    errs = bm.curve_errors(_curve(ux2, 1.03 * _wall_like(ux2)), ref, 1.0, start_s=1.0)
    for k in bm.ERROR_COLUMNS:
        assert errs[k] == pytest.approx(0.03, abs=2e-3), k
    assert errs["err_rms_curve"] == pytest.approx(0.03, abs=1e-4)  # interpolation error only
    assert errs["err_max"] == max(errs[k] for k in bm.ERROR_COLUMNS)


def test_clip_at_target_interpolates_the_last_row():
    c = _curve([0.0, 0.4, 0.8, 1.2], [0.0, 4.0, 8.0, 10.0])
    out = bm.clip_at_target(c, 1.0)
    assert out["ux_mm"].tolist() == [0.0, 0.4, 0.8, 1.0]
    assert out["fx_kN"][-1] == pytest.approx(9.0)
    assert out["converged"][-1] == 1.0


def test_relative_error_refuses_what_cannot_be_compared():
    assert bm.relative_error(1.1, 1.0) == pytest.approx(0.1)
    assert math.isnan(bm.relative_error(None, 1.0))
    assert math.isnan(bm.relative_error(1.0, 0.0))


# --- Pareto front ---------------------------------------------------------------------------


def test_pareto_front_of_a_known_set():
    #        0     1     2     3     4      5     6 (NaN error)
    times = [1.0, 2.0, 3.0, 2.5, 4.0, 1.0, 0.5]
    errors = [0.5, 0.1, 0.01, 0.2, 0.01, 0.6, math.nan]
    # 3 is beaten by 1 (faster and more accurate); 4 by 2 (same error, faster);
    # 5 by 0 (same time, less accurate); 6 has no error
    assert bm.pareto_front(times, errors).tolist() == [True, True, True, False, False, False,
                                                       False]


def test_pareto_front_keeps_exact_ties():
    assert bm.pareto_front([1.0, 1.0], [0.1, 0.1]).tolist() == [True, True]


# --- ladder ---------------------------------------------------------------------------------


@pytest.mark.parametrize("path", ["cases/smoke.yaml", "cases/wall_0.5MPa_elastic.yaml",
                                  "cases/wall_0.5MPa.yaml"])
def test_every_rung_of_the_ladder_is_a_valid_case(path):
    case = load_case(path)
    settings = [bm.reference_setting(case), *bm.ladder(case), *bm.ladder(case, quick=True)]
    for s in settings:
        load_case(path, list(s.overrides))  # CaseError if a rung is invalid
    names = [s.name for s in bm.ladder(case)]
    assert names[0] == "default" and len(names) == len(set(names))
    # with adaptive steps a time-step rung scales the largest step too (x4 of the 0.5 MPa
    # wall's 2e-3 s would otherwise be above its 4e-3 s)
    hmax = case.solver.max_time_step_s
    for s in bm.ladder(case):
        if s.name.startswith("time_step_x"):
            rung = load_case(path, list(s.overrides)).solver
            ratio = rung.time_step_s / case.solver.time_step_s
            assert rung.max_time_step_s == (None if hmax is None else
                                            pytest.approx(hmax * ratio, rel=1e-12))
    groups = {s.group for s in bm.ladder(case)}
    assert {"time_step", "rate", "tolerance", "mesh"} <= groups
    assert ("method" in groups) == (case.blocks.material != "endo3d")
    assert "method" not in {s.group for s in bm.ladder(case, quick=True)}


def test_reference_halves_the_time_step_and_tightens_the_tolerance_tenfold():
    case = load_case(SMOKE)
    ref = load_case(SMOKE, list(bm.reference_setting(case).overrides))
    assert ref.solver.time_step_s == pytest.approx(case.solver.time_step_s / 2)
    assert ref.solver.tolerance == pytest.approx(case.solver.tolerance / 10)
    assert ref.wall.elements_per_unit == case.wall.elements_per_unit


def test_mesh_neighbours():
    assert bm.mesh_neighbours((2, 2, 1)) == [(1, 1, 1), (3, 3, 1)]
    assert bm.mesh_neighbours((1, 1, 1)) == [(2, 2, 1)]


# --- scaling fits ---------------------------------------------------------------------------


def test_scaling_fits_on_a_known_set():
    x = [100.0, 200.0, 400.0, 800.0]
    assert bm.loglog_slope(x, [3.0 * v for v in x]) == pytest.approx(1.0)
    assert bm.loglog_slope(x, [v ** 1.5 for v in x]) == pytest.approx(1.5)
    assert bm.linear_fit(x, [50.0 + 0.01 * v for v in x]) == pytest.approx((0.01, 50.0))
    assert [k for k, *_ in bm.scaling_sizes(11, 6)] == [1, 2, 4, 8]
    assert bm.scaling_sizes(11, 6)[-1] == (8, 44, 12)


# --- short runs on the smoke wall -----------------------------------------------------------


@pytest.fixture(scope="module")
def quick_bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench")
    res = CliRunner().invoke(app, ["bench", SMOKE, "--quick", "--repeats", "1", "-o", str(out),
                                   "--overwrite", *NO_FIELDS])
    return out, res


def _read_csv(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


def test_quick_bench_writes_the_table_and_the_chart(quick_bench):
    out, res = quick_bench
    assert res.exit_code == 0, res.output
    header, rows = _read_csv(out / "bench.csv")
    assert header == bm.BENCH_COLUMNS
    names = [r["setting"] for r in rows]
    assert names[:2] == ["reference", "default"]
    assert {"time_step_x2", "rate_x2", "tolerance_x100", "mesh_2x2x1"} <= set(names)
    for r in rows:
        assert r["status"] == "ok", r
        for c in (*bm.ERROR_COLUMNS, "err_max", "run_s", "peak_rss_MiB", "median_iterations"):
            assert math.isfinite(float(r[c])), (r["setting"], c)
        assert int(r["steps"]) > 0 and int(r["contact_points"]) > 0
    ref = rows[0]
    assert all(float(ref[c]) == 0.0 for c in (*bm.ERROR_COLUMNS, "err_max"))
    assert any(float(r["err_max"]) > 0.0 for r in rows[1:])
    assert sum(int(r["pareto"]) for r in rows) >= 1 and rows[0]["pareto"] == "0"
    png = (out / "bench.png").read_bytes()
    assert png[:8] == PNG_SIGNATURE and len(png) > 10_000
    assert "default settings:" in res.output and "Pareto front" in res.output


def test_the_reference_check_measures_the_reference_s_own_error(tmp_path, monkeypatch):
    """``--check-reference`` runs the reference again with half its step. The smoke wall is
    pushed at 10 mm/s, where the step moves the curve at first order (implicit Euler): against
    that run (h/4) the case (h) is off by about three times as much as the reference (h/2),
    (h - h/4) / (h/2 - h/4) = 3."""
    monkeypatch.setattr(bm, "ladder", lambda case, quick=False: [
        bm.Setting("default", "default", "the case's own settings")])
    res = CliRunner().invoke(app, ["bench", SMOKE, "--repeats", "1", "--check-reference",
                                   "-o", str(tmp_path), "--overwrite", *NO_FIELDS])
    assert res.exit_code == 0, res.output
    header, rows = _read_csv(tmp_path / "bench.csv")
    assert header == bm.BENCH_COLUMNS
    assert [r["setting"] for r in rows] == ["reference", "reference_check", "default"]
    ref, check, default = rows
    assert float(check["time_step_s"]) == pytest.approx(0.5 * float(ref["time_step_s"]))
    assert float(check["tolerance"]) == pytest.approx(float(ref["tolerance"]))
    assert float(check["err_max_check"]) == 0.0 and check["pareto"] == "0"
    e_ref, e_default = float(ref["err_max_check"]), float(default["err_max_check"])
    assert 0.0 < e_ref < e_default
    assert 2.0 < e_default / e_ref < 4.5, (e_default, e_ref)
    assert "reference check (time step x0.25" in res.output and "check %" in res.output


def test_bench_refuses_a_non_empty_folder_and_a_missing_case(tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "bench.csv").write_text("")
    res = CliRunner().invoke(app, ["bench", SMOKE, "-o", str(tmp_path / "full")])
    assert res.exit_code == 2 and "not empty" in res.output
    res = CliRunner().invoke(app, ["bench-scaling", SMOKE, "-o", str(tmp_path / "full")])
    assert res.exit_code == 2 and "not empty" in res.output
    res = CliRunner().invoke(app, ["bench", "-o", str(tmp_path / "new")])
    assert res.exit_code == 2 and "CASE.yaml" in res.output


def test_scaling_on_the_smoke_wall(tmp_path):
    res = CliRunner().invoke(app, ["bench-scaling", SMOKE, "--steps", "3", "-o", str(tmp_path),
                                   "--set", "wall.courses=2", "--set", "wall.units_per_course=2"])
    assert res.exit_code == 0, res.output
    header, rows = _read_csv(tmp_path / "scaling.csv")
    assert header == bm.SCALING_COLUMNS
    assert [r["wall"] for r in rows] == ["baseline", "1x", "2x", "4x", "8x"]
    points = [int(r["contact_points"]) for r in rows]
    assert points == sorted(points) and points[-1] > 4 * points[1]
    assert all(math.isfinite(float(r["peak_rss_MiB"])) for r in rows)
    assert (tmp_path / "scaling.png").read_bytes()[:8] == PNG_SIGNATURE
    assert "KiB per contact point" in res.output and "log-log slope" in res.output
    # where each wall's step time went: every wall that stepped has its factorisations and
    # joint-law calls, and the parts are inside its steps (shares at most 1 in all)
    header, parts = _read_csv(tmp_path / "scaling_parts.csv")
    assert header == bm.PARTS_COLUMNS
    header, steps = _read_csv(tmp_path / "scaling_steps.csv")
    assert header == bm.STEP_COLUMNS
    assert [sum(s["wall"] == r["wall"] for s in steps) for r in rows] == [3] * len(rows)
    for r in rows:
        mine = {p["part"]: p for p in parts if p["wall"] == r["wall"]}
        assert int(mine["joint law"]["calls"]) >= int(r["steps"])
        assert "factorisation" in mine
        assert sum(float(p["share"]) for p in mine.values()) <= 1.0 + 1e-9
    assert "of the step time:" in res.output


def test_scaling_refuses_processes_it_cannot_use(tmp_path):
    """``--processes``: numbers of at least 1, and several only with a Krylov solve; exit 2
    naming the option before any wall is built."""
    for bad, words in ((["--processes", "0"], "--processes takes"),
                       (["--processes", "one"], "--processes takes"),
                       (["--processes", "1,2", "--set", "solver.linear=pardiso"],
                        "solver.linear must be krylov or auto")):
        res = CliRunner().invoke(app, ["bench-scaling", SMOKE, "-o", str(tmp_path / "x"), *bad])
        assert res.exit_code == 2 and words in res.output, res.output
        assert not (tmp_path / "x" / "scaling.csv").exists()


def test_processes_statements_compare_each_wall_with_one_process():
    """Each wall on several processes against the same wall on one: the ratios of its median
    time per step and of each process's peak memory."""
    one = bm.ScalingRow("8x", 44, 12, 1, steps=10, step_ms_median=100.0, peak_rss_MiB=1000.0)
    two = bm.ScalingRow("8x", 44, 12, 2, steps=10, step_ms_median=65.0, peak_rss_MiB=800.0,
                        peak_rss_MiB_others=400.0, peak_rss_MiB_all=1200.0)
    lines = bm.processes_statements([one, two])
    assert lines == [("8x on 2 processes against one: time per step 0.65 (medians after the "
                      "first steps), peak memory 0.80 on process 0 and 0.40 on the largest "
                      "other, 1.20 in all")]
    assert bm.processes_statements([one]) == []


def test_the_scaling_steps_stop_where_the_case_ends(tmp_path):
    """A wall given more steps than its case needs stops at the case's end, after the same
    steps as ``masonry run`` (the target displacement reached)."""
    sets = ["loading.horizontal.target_m=1e-4", "output.vtu=false", "output.hdf5=false"]
    res = CliRunner().invoke(app, ["run", SMOKE, "-o", str(tmp_path / "run"),
                                   *[a for s in sets for a in ("--set", s)]])
    assert res.exit_code == 0, res.output
    _, curve = _read_csv(tmp_path / "run" / "force_displacement.csv")
    out = bm._child_steps({"kind": "steps", "case": SMOKE, "overrides": sets, "steps": 10_000})
    assert out["finished"] and out["status"] == "ok"
    assert len(out["step_s"]) == len(curve) < 10_000
    assert out["t_s"][-1] == pytest.approx(float(curve[-1]["time_s"]), rel=1e-12)
    assert float(curve[-1]["ux_mm"]) >= 0.1 > float(curve[-2]["ux_mm"])
    row = bm._scaling_row("1x", 4, 4, {**out, "process_s": 1.0}, skip=2)
    assert row.finished and row.steps == len(curve)


def test_the_reference_run_gets_a_longer_time_limit(tmp_path, monkeypatch):
    """Without the reference no error can be measured: a loaded machine once stopped the ENDO3D
    wall's reference at 2594 of 2637 steps with the others' limit of 200 s."""
    limits = []

    def fake_run(spec, timeout_s=None):
        if "masonry-warm-" not in spec["outdir"]:
            limits.append((Path(spec["outdir"]).name, spec["time_limit_s"], timeout_s))
        return {"status": "failed", "message": "not run", "process_s": 0.0}

    monkeypatch.setattr(bm, "run_in_child", fake_run)
    monkeypatch.setattr(bm, "plot_bench", lambda rows, path, title: path)
    bm.bench("cases/smoke.yaml", tmp_path / "b", quick=True, time_limit_s=50.0,
             echo=lambda m: None)
    assert limits[0] == ("reference", 200.0, 800.0)
    assert limits[1:] and all(lim == 50.0 and t == 650.0 for _, lim, t in limits[1:])
