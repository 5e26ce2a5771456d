"""Cyclic and tabulated runs of the smoke wall (3 courses, 10 units, symmetric about its middle):
symmetric peaks, the envelope under the monotonic curve, the outputs, and the commands that take
or refuse the new histories. Each run is a few hundred steps (seconds)."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.cli import app
from masonry_nscd.io.cycle_tables import CYCLE_COLUMNS, ENVELOPE_COLUMNS
from masonry_nscd.io.runfolder import read_curve_csv
from masonry_nscd.studies import bench as bm

SMOKE = "cases/smoke.yaml"
#: Faster than the smoke case's push (20 mm/s, 20 ms ramps; the wall is light, the beam's
#: inertia is not in F_x), no VTU.
SHORT = ["loading.horizontal.ramp_s=0.02", "loading.horizontal.rate_m_s=0.02",
         "output.vtu=false"]
CYCLIC = [*SHORT, "loading.horizontal.history=cyclic"]


def _run(out, sets):
    args = ["run", SMOKE, "-o", str(out)]
    for s in sets:
        args += ["--set", s]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    return out


def _rows(path):
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        return reader.fieldnames, list(reader)


@pytest.fixture(scope="module")
def cyclic_run(tmp_path_factory):
    """One cycle at each of 0.5, 1 and 2 mm (the wall slides at about 0.5 mm, peaks at 1.4)."""
    return _run(tmp_path_factory.mktemp("cyc") / "run",
                [*CYCLIC, "loading.horizontal.amplitudes_m=[0.5e-3,1e-3,2e-3]"])


@pytest.fixture(scope="module")
def monotonic_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("mono") / "run",
                [*SHORT, "loading.horizontal.target_m=2.1e-3", "output.hdf5=false"])


def test_a_symmetric_cycle_gives_the_same_peak_both_ways(tmp_path):
    """One cycle of +-0.5 mm, past the sliding of the base: the peaks of the two directions
    within 2 % (measured: 1e-6)."""
    out = _run(tmp_path / "run", [*CYCLIC, "loading.horizontal.amplitudes_m=[0.5e-3]",
                                  "output.hdf5=false"])
    s = json.loads((out / "summary.json").read_text())
    assert s["history"] == "cyclic" and s["cycles_completed"] == s["cycles_planned"] == 1
    pos, neg = s["peak_force_pos_kN"], s["peak_force_neg_kN"]
    assert pos > 30.0 and neg < -30.0  # past the linear range (346 kN/mm x 0.5 mm = 173 kN)
    assert abs(pos + neg) <= 0.02 * pos
    assert s["ux_at_peak_pos_mm"] == pytest.approx(-s["ux_at_peak_neg_mm"], rel=0.02)


def test_the_envelope_lies_at_or_below_the_monotonic_curve(cyclic_run, monotonic_run):
    """One cycle per amplitude: every envelope point (both directions; the wall is symmetric,
    the negative one is compared with the monotonic curve mirrored) at or below the monotonic
    force at its displacement. 0.5 % is left for the rate (the cycle slows down to its
    reversals, the push does not) and the monotonic curve interpolated between its rows."""
    m = read_curve_csv(monotonic_run / "force_displacement.csv")
    up = m["time_s"] >= 0.1 - 1e-9  # the horizontal stage of the smoke case
    u, f = np.concatenate(([0.0], m["ux_mm"][up])), np.concatenate(([0.0], m["fx_kN"][up]))
    _, env = _rows(cyclic_run / "envelope.csv")
    assert len(env) == 6
    for e in env:
        U, F = float(e["ux_mm"]), float(e["fx_kN"])
        assert abs(U) <= u[-1]
        assert abs(F) <= 1.005 * np.interp(abs(U), u, f), e


def test_cyclic_run_outputs(cyclic_run):
    out = cyclic_run
    header, rows = _rows(out / "cycles.csv")
    assert tuple(header) == CYCLE_COLUMNS
    assert [float(r["amplitude_mm"]) for r in rows] == [0.5, 1.0, 2.0]
    for r in rows:  # the beam turns at the amplitude
        a = float(r["amplitude_mm"])
        assert float(r["ux_max_mm"]) == pytest.approx(a, abs=0.005)
        assert float(r["ux_min_mm"]) == pytest.approx(-a, abs=0.005)
        assert float(r["dissipated_energy_J"]) > 0.0
        assert 0.0 < float(r["damping_ratio_eq"]) < 1.0
    header, _ = _rows(out / "envelope.csv")
    assert tuple(header) == ENVELOPE_COLUMNS
    s = json.loads((out / "summary.json").read_text())
    assert s["dissipated_energy_J"] == pytest.approx(
        sum(float(r["dissipated_energy_J"]) for r in rows))
    assert s["peak_force_kN"] == s["peak_force_pos_kN"] > 0 > s["peak_force_neg_kN"]
    assert s["target_ux_mm"] is None and s["initial_stiffness_kN_mm"] > 0
    # the run ends when the last cycle does, the beam back at rest near 0
    scene = json.loads((out / "scene.json").read_text())
    assert scene["target_m"] is None and scene["history"]["kind"] == "cyclic"
    c = read_curve_csv(out / "force_displacement.csv")
    assert c["time_s"][-1] == pytest.approx(scene["history"]["end_s"], abs=2e-3)
    assert abs(c["ux_mm"][-1]) < 1e-6
    # the case as run keeps the history
    text = (out / "case.yaml").read_text()
    assert "history: cyclic" in text and "amplitudes_m: [5.0e-4, 0.001, 0.002]" in text


def test_plot_draws_the_cycles(cyclic_run, tmp_path):
    res = CliRunner().invoke(app, ["plot", str(cyclic_run), "-o", str(tmp_path)])
    assert res.exit_code == 0, res.output
    png = tmp_path / "cycles_smoke.png"
    assert png.exists() and png.stat().st_size > 20_000
    assert (tmp_path / "force_displacement.png").exists()


def test_a_table_run_follows_its_table_and_ends_with_it(tmp_path):
    table = tmp_path / "u.csv"
    table.write_text("time_s,displacement_m\n0,0\n0.03,0.6e-3\n0.09,-0.6e-3\n0.12,0\n")
    out = _run(tmp_path / "run", [*SHORT, "loading.horizontal.history=table",
                                  f"loading.horizontal.file={table}", "output.hdf5=false"])
    s = json.loads((out / "summary.json").read_text())
    assert s["history"] == "table" and s["cycles_completed"] == 1
    c = read_curve_csv(out / "force_displacement.csv")
    start, ramp = 0.1, 0.02
    t0 = start + ramp / 2  # the table's time 0
    for x in (0.02, 0.06):  # away from the corners: on the table (to a step's lead, 0.01 mm)
        u = np.interp(t0 + x, c["time_s"], c["ux_mm"])
        assert u == pytest.approx(1e3 * np.interp(x, [0, 0.03, 0.09, 0.12],
                                                  [0, 0.6e-3, -0.6e-3, 0]), abs=0.03)
    assert c["time_s"][-1] == pytest.approx(t0 + 0.12 + ramp / 2, abs=2e-3)


def test_a_relative_table_is_read_from_the_case_folder(tmp_path):
    (tmp_path / "u.csv").write_text("time_s,displacement_m\n0,0\n1,1e-3\n")
    case = tmp_path / "case.yaml"
    case.write_text("loading:\n  horizontal:\n    history: table\n    file: u.csv\n")
    res = CliRunner().invoke(app, ["validate", str(case), "--print"])
    assert res.exit_code == 0, res.output
    assert f"file: {(tmp_path / 'u.csv').resolve()}" in res.output
    case.write_text("loading:\n  horizontal:\n    history: table\n    file: v.csv\n")
    res = CliRunner().invoke(app, ["validate", str(case)])
    assert res.exit_code == 2 and "loading.horizontal.file: file not found" in res.output


def test_calibrate_refuses_a_cyclic_case_and_bench_a_table(tmp_path):
    res = CliRunner().invoke(app, ["calibrate", SMOKE, "--target-stiffness", "71", "-o",
                                   str(tmp_path / "cal"), "--set",
                                   "loading.horizontal.history=cyclic", "--set",
                                   "loading.horizontal.amplitudes_m=[1e-3]"])
    assert res.exit_code == 2 and "loading.horizontal.history" in res.output
    table = tmp_path / "u.csv"
    table.write_text("time_s,displacement_m\n0,0\n1,1e-3\n")
    res = CliRunner().invoke(app, ["bench", SMOKE, "-o", str(tmp_path / "b"), "--set",
                                   "loading.horizontal.history=table", "--set",
                                   f"loading.horizontal.file={table}"])
    assert res.exit_code == 2 and "loading.horizontal.history" in res.output
    assert not (tmp_path / "b").exists()


def test_bench_errors_of_a_cyclic_case_are_read_on_the_envelope():
    """Two loops of an elastic, perfectly plastic spring (10 kN/mm, 5 kN), the other run's
    forces 1 % lower: every error 1 %."""
    t = np.linspace(0.0, 2.0, 4001)
    a = np.where(t < 1.0, 1.0, 3.0)  # amplitudes 1 and 3 mm, one cycle each
    u = a * np.sin(2 * np.pi * t)
    f = np.zeros_like(u)
    for i in range(1, len(u)):
        f[i] = np.clip(f[i - 1] + 10.0 * (u[i] - u[i - 1]), -5.0, 5.0)
    curve = {"step": np.arange(len(t)), "time_s": t, "ux_mm": u, "fx_kN": f,
             "converged": np.ones(len(t)), "iterations": np.ones(len(t))}
    ref = {**curve, "fx_kN": f / 1.01}
    scene = {"stages": [{"name": "horizontal", "start_s": 0.0}], "push_stage": "horizontal",
             "history": {"kind": "cyclic", "cycles": [
                 {"index": 1, "amplitude_m": 1e-3, "repetition": 1, "start_s": 0.0,
                  "end_s": 1.0},
                 {"index": 2, "amplitude_m": 3e-3, "repetition": 1, "start_s": 1.0,
                  "end_s": 2.0}]}}
    err = bm.cyclic_errors(curve, scene, ref, scene)
    for k in (*bm.CYCLIC_ERROR_COLUMNS, "err_max"):
        assert err[k] == pytest.approx(0.01, rel=1e-9), k
    row = bm.BenchRow("s", "default", "", "", "newton", 1e-3, 1e-3, 1e-5, "1x1x1", status="ok")
    bm.fill_curve(row, curve, ref, 10.0, 0.0, scene, scene)
    assert row.err_envelope == pytest.approx(0.01) and math.isnan(row.err_rms_curve)
    assert bm.error_columns([row]) == bm.CYCLIC_ERROR_COLUMNS
