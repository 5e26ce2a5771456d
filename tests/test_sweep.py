"""`masonry sweep` and `masonry sensitivity`: short smoke walls on Dask, locally and through a
scheduler on the loopback address; resuming; failed runs; a small Morris study."""

import csv
import shutil
import subprocess
import sys

import pytest
from typer.testing import CliRunner

from masonry_nscd.cli import app
from masonry_nscd.studies.batch import SweepError, parse_set, split_values
from masonry_nscd.studies.sweep import point_names

pytest.importorskip("distributed")

CASE = "cases/smoke.yaml"
# 0.2 mm of horizontal displacement (85 steps of the smoke wall), no VTU files
SHORT = ["--set", "loading.horizontal.target_m=0.2e-3", "--set", "output.vtu=false"]
STRESSES = ["--set", "loading.vertical_stress.value_Pa=0.3e6,0.4e6,0.5e6"]
RUNS = ["value_Pa=0.3e6", "value_Pa=0.4e6", "value_Pa=0.5e6"]
RESULT_COLUMNS = ["loading.vertical_stress.value_Pa", "initial_stiffness_kN_mm", "peak_force_kN",
                  "ux_at_peak_mm", "force_at_target_kN", "target_ux_mm", "unconverged_steps",
                  "status", "run"]


def _sweep(*args):
    return CliRunner().invoke(app, ["sweep", CASE, *SHORT, *args])


def _table(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def scheduler():
    """The address of a Dask cluster of 2 worker processes on 127.0.0.1, for the module."""
    from distributed import LocalCluster

    with LocalCluster(host="127.0.0.1", n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        yield cluster.scheduler_address


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    """The three stresses on local worker processes (--workers 2)."""
    out = tmp_path_factory.mktemp("sweep") / "local"
    res = _sweep(*STRESSES, "--workers", "2", "-o", str(out))
    assert res.exit_code == 0, res.output
    return out


def test_a_sweep_on_a_scheduler_and_on_local_processes_gives_the_same_table(
        scheduler, local_sweep, tmp_path):
    res = _sweep(*STRESSES, "--scheduler", scheduler, "-o", str(tmp_path))
    assert res.exit_code == 0, res.output
    remote, local = _table(tmp_path / "sweep.csv"), _table(local_sweep / "sweep.csv")
    assert [r["run"] for r in remote] == RUNS
    assert [{k: r[k] for k in RESULT_COLUMNS} for r in remote] == \
        [{k: r[k] for k in RESULT_COLUMNS} for r in local]
    assert all(r["status"] == "ok" and float(r["run_time_s"]) > 0 for r in remote)
    peaks = [float(r["peak_force_kN"]) for r in remote]
    assert peaks[0] < peaks[1] < peaks[2]  # friction: more pre-compression, more strength
    for out in (tmp_path, local_sweep):
        assert (out / "force_displacement.png").stat().st_size > 10_000
        for name in RUNS:
            run = out / "runs" / name
            for f in ("case.yaml", "force_displacement.csv", "results.h5", "summary.json",
                      "sweep_run.json"):
                assert (run / f).is_file(), run / f


def test_running_a_sweep_again_skips_the_finished_runs(local_sweep, tmp_path):
    out = tmp_path / "again"
    shutil.copytree(local_sweep, out)  # copy2: modification times kept
    before = {n: (out / "runs" / n / "summary.json").stat().st_mtime_ns for n in RUNS}
    shutil.rmtree(out / "runs" / RUNS[1])
    res = _sweep(*STRESSES, "--workers", "2", "-o", str(out))
    assert res.exit_code == 0, res.output
    assert f"{RUNS[0]}: kept" in res.output and f"{RUNS[2]}: kept" in res.output
    assert f"{RUNS[1]}: ok in" in res.output
    for n in (RUNS[0], RUNS[2]):
        assert (out / "runs" / n / "summary.json").stat().st_mtime_ns == before[n]
    assert [{k: r[k] for k in RESULT_COLUMNS} for r in _table(out / "sweep.csv")] == \
        [{k: r[k] for k in RESULT_COLUMNS} for r in _table(local_sweep / "sweep.csv")]


def test_a_failed_run_is_reported_and_the_others_finish(scheduler, tmp_path):
    # one solver iteration per step: the forces still change by ~100 % when it stops, and the
    # run ends in the first step with a clean RunFailure
    args = ["--set", "solver.max_iterations=20000,1", "--set", "solver.check_every=1",
            "--scheduler", scheduler, "-o", str(tmp_path)]
    res = _sweep(*args)
    assert res.exit_code == 1, res.output
    ok, failed = _table(tmp_path / "sweep.csv")
    assert (ok["status"], failed["status"]) == ("ok", "failed")
    assert (ok["run"], failed["run"]) == ("max_iterations=20000", "max_iterations=1")
    assert "step 1" in failed["message"] and failed["peak_force_kN"] == ""
    assert float(ok["peak_force_kN"]) > 0
    assert f"1 of 2 runs did not finish: {failed['run']} (failed)" in res.output
    res = _sweep(*args)  # again: the finished run is kept, the failed one is tried again
    assert res.exit_code == 1
    assert f"{ok['run']}: kept" in res.output and f"{failed['run']}: failed" in res.output


def test_bad_values_stop_the_sweep_before_any_run(tmp_path):
    out = tmp_path / "never"
    res = _sweep("--set", "joint.mu=0.5,-1", "--set", "blocks.E_Pa=1e10,2e10", "-o", str(out))
    assert res.exit_code == 2
    assert "joint.mu" in res.output and res.output.count("joint.mu: got -1") == 1
    assert not out.exists()
    res = _sweep("--set", "joint.muu=0.5,0.6", "-o", str(out))
    assert res.exit_code == 2 and "unknown path joint.muu" in res.output
    res = _sweep("--set", "joint.mu=0.5,,0.6", "-o", str(out))
    assert res.exit_code == 2 and "empty value" in res.output
    res = _sweep("--set", "joint.mu=0.5,0.6", "--workers", "2", "--scheduler", "tcp://x:1")
    assert res.exit_code == 2 and "--workers" in res.output


def test_values_split_at_the_commas_outside_brackets_and_names_stay_apart():
    assert split_values("[1,1,1],[2, 2, 1]") == ["[1,1,1]", "[2, 2, 1]"]
    assert parse_set("loading.vertical_stress.value_Pa=0.3e6, 5e5") == \
        ("loading.vertical_stress.value_Pa", ["0.3e6", "5e5"])
    with pytest.raises(SweepError, match="repeated"):
        parse_set("joint.mu=0.5,0.5")
    combos = [[("a.x", "1/2"), ("b.x", "1")], [("a.x", "1_2"), ("b.x", "1")]]
    assert point_names(combos) == ["a.x=1_2__b.x=1", "a.x=1_2__b.x=1~2"]


def test_morris_indices_of_the_peak_force(scheduler, tmp_path):
    res = CliRunner().invoke(app, [
        "sensitivity", CASE, *SHORT, "--param", "joint.mu=0.5:0.9",
        "--param", "loading.vertical_stress.value_Pa=0.3e6:0.5e6", "--method", "morris",
        "--samples", "2", "--output", "peak_force_kN", "--scheduler", scheduler,
        "-o", str(tmp_path)])
    assert res.exit_code == 0, res.output
    samples = _table(tmp_path / "samples.csv")
    assert len(samples) == 2 * (2 + 1) and all(r["status"] == "ok" for r in samples)
    indices = _table(tmp_path / "indices.csv")
    assert list(indices[0]) == ["parameter", "mu", "mu_star", "sigma", "mu_star_conf"]
    assert [r["parameter"] for r in indices] == ["joint.mu", "loading.vertical_stress.value_Pa"]
    assert all(float(r["mu_star"]) > 0 and float(r["mu"]) > 0 for r in indices)
    assert (tmp_path / "indices.png").stat().st_size > 5_000


def test_sensitivity_refuses_to_analyse_runs_that_failed(scheduler, tmp_path):
    res = CliRunner().invoke(app, [
        "sensitivity", CASE, *SHORT, "--set", "solver.max_iterations=1", "--set",
        "solver.check_every=1", "--param", "joint.mu=0.5:0.9",
        "--samples", "2", "--scheduler", scheduler, "-o", str(tmp_path)])
    assert res.exit_code == 1
    assert "no analysis: 4 of 4 runs have no peak_force_kN" in res.output
    assert "sample_0000: failed" in res.output
    assert len(_table(tmp_path / "samples.csv")) == 4
    assert not (tmp_path / "indices.csv").exists()


def test_bad_sensitivity_options_exit_2(tmp_path):
    base = ["sensitivity", CASE, "-o", str(tmp_path / "never")]
    for extra, words in [
        (["--param", "joint.mu=0.9:0.5", "--samples", "2"], "LOW < HIGH"),
        (["--param", "joint.mu=0.5:0.9", "--samples", "6", "--method", "sobol"], "power of 2"),
        (["--param", "joint.law=0:1", "--samples", "2"], "joint.law"),
        (["--param", "joint.mu=0.5:0.9", "--samples", "2", "--output", "peak"], "--output"),
    ]:
        res = CliRunner().invoke(app, [*base, *extra])
        assert res.exit_code == 2 and words in res.output, (extra, res.output)
    assert not (tmp_path / "never").exists()


def test_the_cli_does_not_import_dask_or_salib():
    code = ("import sys, masonry_nscd.cli; "
            "print([m for m in ('distributed', 'dask', 'SALib') if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_sweep_of_an_arch_has_collapse_columns(tmp_path):
    """The shipped arch at t/R = 0.09 (below the minimum 0.1071 of limit analysis) collapses
    under its own weight, before the body force starts (0.2 s); at 0.15 its collapse multiplier
    (0.1467) is above the lambda = 0.125 that 0.1 /s reaches by 1.5 s: it stands."""
    out = tmp_path / "arch"
    res = CliRunner().invoke(app, [
        "sweep", "cases/arch_semicircular.yaml", "--set", "arch.thickness_m=0.15,0.09",
        "--set", "output.vtu=false", "--set", "loading.body_force.rate_per_s=0.1",
        "--set", "collapse.end_time_s=1.5", "--workers", "1", "-o", str(out)])
    assert res.exit_code == 0, res.output
    thick, thin = _table(out / "sweep.csv")
    assert (thick["collapse"], thin["collapse"]) == ("false", "true")
    assert thick["collapse_load"] == "" and thick["collapse_time_s"] == ""
    assert thin["collapse_load_name"] == "lambda" and float(thin["collapse_load"]) == 0.0
    assert float(thin["collapse_time_s"]) < 0.2
