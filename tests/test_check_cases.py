"""``masonry check-cases``: the shipped cases run to their end against their records."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from masonry_nscd.cli import app
from masonry_nscd.io.runfolder import read_curve_csv
from masonry_nscd.studies import check_cases
from masonry_nscd.studies.check_cases import curve_deviation, log_path, reduce_curve


def _curve(n=50):
    t = np.linspace(0.01, 0.5, n)
    return {"time_s": t, "ux_mm": 2.0 * t, "fx_kN": 40.0 * np.sin(3.0 * t),
            "uy_mm": -1e-3 * t, "fy_kN": np.full(n, -80.0)}


def test_the_deviation_is_relative_to_each_columns_largest_value():
    rec = _curve()
    assert curve_deviation(rec, rec) == (0.0, "")
    new = {k: v.copy() for k, v in rec.items()}
    new["fx_kN"][10] += 0.2  # 0.5 % of the column's largest |F_x| (40 sin(1.5) = 39.9 kN)
    dev, col = curve_deviation(rec, new)
    assert col == "fx_kN" and math.isclose(dev, 0.2 / np.max(np.abs(rec["fx_kN"])))
    # read at the record's times: a finer curve of the same functions deviates by the
    # interpolation error only
    fine = _curve(400)
    dev, _ = curve_deviation(rec, fine)
    assert dev < 1e-4
    # a run that stops early ends at another time
    short = {k: v[:-3] for k, v in rec.items()}
    assert curve_deviation(rec, short) == (math.inf, "time_s")
    nan = {k: v.copy() for k, v in rec.items()}
    nan["fx_kN"][5] = np.nan  # not hidden by the columns after it
    dev, col = curve_deviation(rec, nan)
    assert math.isnan(dev) and col == "fx_kN"


def test_the_reduced_curve_keeps_the_ends_and_the_largest_force():
    c = _curve(1000)
    c["fx_kN"][777] = 500.0
    r = reduce_curve(c, rows=20)
    assert len(r["time_s"]) <= 22
    assert r["time_s"][0] == c["time_s"][0] and r["time_s"][-1] == c["time_s"][-1]
    assert 500.0 in r["fx_kN"]


def test_each_case_has_its_own_log():
    """The study's walls differ after their last dot (``wall_0.3MPa``, ``wall_0.5MPa``)."""
    logs = {log_path(Path("out") / name) for name in ("wall_0.3MPa", "wall_0.5MPa",
                                                       "wall_0.5MPa_cyclic")}
    assert logs == {Path("out/wall_0.3MPa.log"), Path("out/wall_0.5MPa.log"),
                    Path("out/wall_0.5MPa_cyclic.log")}


def _check(tmp_path, *extra):
    return CliRunner().invoke(app, ["check-cases", "cases/smoke.yaml", "-o",
                                    str(tmp_path / "out"), "--overwrite", "--record",
                                    str(tmp_path / "record"), *extra])


def _rows(tmp_path):
    with open(tmp_path / "out" / "check.csv") as f:
        return list(csv.DictReader(f))


def test_a_case_is_recorded_then_checked_and_a_change_is_caught(tmp_path, monkeypatch):
    res = _check(tmp_path)
    assert res.exit_code == 1 and "no record" in res.output

    # git describe --dirty, as it answers where the records are part of the tree: once a record
    # is written, the tree is dirty; the commit must be read before
    def describe():
        return "abc1234-dirty" if list((tmp_path / "record").glob("*.csv")) else "abc1234"

    monkeypatch.setattr(check_cases, "_git_commit", describe)
    res = _check(tmp_path, "--write-record")
    assert res.exit_code == 0, res.output
    runs = json.loads((tmp_path / "record" / "runs.json").read_text())
    assert runs["smoke"]["steps"] == 100
    assert runs["smoke"]["commit"] == "abc1234"
    rec = read_curve_csv(tmp_path / "record" / "smoke.csv")
    full = read_curve_csv(tmp_path / "out" / "smoke" / "force_displacement.csv")
    assert rec["time_s"][-1] == full["time_s"][-1] and np.max(rec["fx_kN"]) == np.max(
        full["fx_kN"])
    # the same code gives the same curve
    res = _check(tmp_path)
    assert res.exit_code == 0, res.output
    row = _rows(tmp_path)[0]
    assert row["status"] == "ok" and float(row["deviation"]) <= 1e-9
    # a record 2 % off in F_x is a change
    path = tmp_path / "record" / "smoke.csv"
    lines = path.read_text().splitlines()
    head = lines[0].split(",")
    i = head.index("fx_kN")
    out = [lines[0]]
    for line in lines[1:]:
        f = line.split(",")
        f[i] = repr(1.02 * float(f[i]))
        out.append(",".join(f))
    path.write_text("\n".join(out) + "\n")
    res = _check(tmp_path)
    assert res.exit_code == 1 and "smoke (changed)" in res.output
    row = _rows(tmp_path)[0]
    assert row["column"] == "fx_kN" and math.isclose(float(row["deviation"]), 0.02 / 1.02,
                                                     rel_tol=1e-5)  # 6 digits in the CSV


def test_unconverged_and_failed_runs_do_not_pass(tmp_path):
    # a tolerance below the round-off of the smoke wall's contact forces (some 1e-13 to
    # 1e-10 of them after 20 iterations on a fifth of its steps), no halving: steps are kept
    # unconverged
    res = _check(tmp_path, "--write-record", "--set", "solver.tolerance=1e-14", "--set",
                 "solver.max_step_halvings=0", "--set", "solver.max_iterations=20")
    assert res.exit_code == 1 and "smoke (unconverged)" in res.output
    assert (tmp_path / "out" / "smoke.log").read_text().count("not converged") >= 2
    assert not (tmp_path / "record" / "smoke.csv").exists()
    # two iterations per step: the run stops with a solver failure
    res = _check(tmp_path, "--set", "solver.max_iterations=2", "--set", "solver.check_every=1")
    assert res.exit_code == 1 and "smoke (failed)" in res.output
