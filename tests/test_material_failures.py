"""A step whose ENDO3D return mapping fails at some Gauss point is reported, not hidden:
counted as not converged, its count in ``failed_gauss_points`` of the CSV and in the
summary, and a log line naming the step and the element."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from masonry_nscd.case import load_case
from masonry_nscd.materials import blocks
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

SMOKE = Path(__file__).resolve().parents[1] / "cases" / "smoke.yaml"


def test_failed_gauss_points_are_counted_and_located(tmp_path, monkeypatch):
    # no halving: the failure injected at the third commit must stay in the step that had it
    case = load_case(SMOKE, ["blocks.material=endo3d", "loading.horizontal.target_m=0.05e-3",
                             "solver.max_step_halvings=0"])
    fail_on_step = 3
    calls = {"step": 0}
    orig_failed = blocks.Endo3dBlocks.failed_points
    orig_batch = blocks.Endo3dBlocks.trial_batch
    orig_commit = blocks.Endo3dBlocks.commit

    def trial_batch(self, u, fint, departure=None, scale=1.0):
        kernel, n, min_size, finish = orig_batch(self, u, fint, departure, scale)

        def finish_with_a_failure(results):
            finish(results)
            if calls["step"] + 1 == fail_on_step:
                self.failures += 1  # one more point than the kernel found

        return kernel, n, min_size, finish_with_a_failure

    def failed_points(self):
        found = orig_failed(self)
        return np.concatenate([[5], found]).astype(np.int64)

    def commit(self):
        calls["step"] += 1
        orig_commit(self)

    monkeypatch.setattr(blocks.Endo3dBlocks, "trial_batch", trial_batch)
    monkeypatch.setattr(blocks.Endo3dBlocks, "failed_points", failed_points)
    monkeypatch.setattr(blocks.Endo3dBlocks, "commit", commit)
    out = tmp_path / "run"
    lines: list[str] = []
    run_case(case, out, echo=lines.append)
    with open(out / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    failed = [int(r["failed_gauss_points"]) for r in rows]
    assert failed[fail_on_step - 1] == 1 and sum(failed) == 1
    assert rows[fail_on_step - 1]["converged"] == "0"
    assert all(r["converged"] == "1" for i, r in enumerate(rows) if i != fail_on_step - 1)
    log = (out / "run.log").read_text()
    assert f"step {fail_on_step} " in log and "ENDO3D return mapping not converged at 1 Gauss" in log
    assert "element centred at x = " in log
    summary = json.loads((out / "summary.json").read_text())
    assert summary["unconverged_steps"] == 1
    assert summary["steps_with_failed_gauss_points"] == 1


def test_failed_points_finds_the_points_the_batch_counted():
    """``failed_points`` runs the kernel point by point: on a state the kernel handles, none."""
    case = load_case(SMOKE, ["blocks.material=endo3d"])
    integ = build_scene(case).integrator()
    mat = integ.material
    u = np.zeros(integ.sys.ndof)
    fint = np.zeros_like(u)
    mat.internal_forces(u, fint)
    assert mat.failures == 0 and len(mat.failed_points()) == 0
