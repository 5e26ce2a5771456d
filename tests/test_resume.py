"""Interrupted runs, resumed runs, write errors and bad output folders.

An interrupted run keeps valid outputs up to its last output step and ``masonry run --resume``
continues it from its checkpoint to the curve of an uninterrupted run (within the solver
tolerance); a write error (disk full) ends the run with exit code 1, a message naming the file
and the reason, and outputs that stay readable and resumable.
"""

from __future__ import annotations

import csv
import errno
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from conftest import interrupt_at as _interrupt_at
from conftest import stop_by_sigterm, wait_for_rows
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.io.checkpoint_file import load_checkpoint, save_checkpoint
from masonry_nscd.io.recorder import read_resume_point, truncate_csv
from masonry_nscd.io.results_h5 import ResultsFile, read_results
from masonry_nscd.io.runfolder import CHECKPOINT as CHECKPOINT_NAME
from masonry_nscd.nscd.checkpoint import CheckpointError, integrator_state, restore_integrator
from masonry_nscd.nscd.integrator import Integrator
from masonry_nscd.run import CSV_COLUMNS, RunFailure, RunInputError, run_case

SMOKE = "cases/smoke.yaml"
runner = CliRunner()
quiet = {"echo": lambda msg: None}


def _curve(out):
    with open(out / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def _pvd_files(out):
    return [d.get("file") for d in ET.parse(out / "wall.pvd").getroot().iter("DataSet")]


def _reference_and_interrupted(tmp_path, monkeypatch, sets: list[str], step: int):
    """The smoke case with ``sets`` run whole into ``tmp_path/ref`` and interrupted before step
    ``step`` into ``tmp_path/run``: ``(ref, out)``."""
    ref = tmp_path / "ref"
    run_case(load_case(SMOKE, sets), ref, **quiet)
    out = tmp_path / "run"
    _interrupt_at(monkeypatch, step)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE, sets), out, **quiet)
    return ref, out


def _assert_same_curve(a, b, rtol=1e-6):
    assert np.array_equal(a["step"], b["step"])
    assert np.allclose(a["time_s"], b["time_s"], rtol=1e-12)
    for k in ("ux_mm", "fx_kN", "uy_mm", "fy_kN", "fx_bottom_kN", "fy_bottom_kN",
              "max_joint_damage", "max_block_damage"):
        scale = max(np.abs(b[k]).max(), 1e-12)
        assert np.abs(a[k] - b[k]).max() <= rtol * scale, k


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The smoke case run without interruption."""
    out = tmp_path_factory.mktemp("ref") / "run"
    run_case(load_case(SMOKE), out, **quiet)
    return out


# --------------------------------------------------------------------------------------------
# Resume
# --------------------------------------------------------------------------------------------


def _interrupted_smoke_run(tmp_path):
    """Run the smoke case into ``tmp_path/run``, expecting a stop (KeyboardInterrupt);
    returns the folder and the lines of its CSV."""
    from masonry_nscd import run as run_mod

    out = tmp_path / "run"
    try:
        with pytest.raises(KeyboardInterrupt):
            run_case(load_case(SMOKE), out, **quiet)
    finally:
        run_mod.TERMINATE.clear()
    return out, (out / "force_displacement.csv").read_text().splitlines()


def test_a_stop_request_waits_while_the_files_are_written(tmp_path, monkeypatch):
    """The handler of SIGTERM and Ctrl-C raises at once, except while the run writes its
    files: a request in the middle of an output step lets the step's files be written whole
    (results.h5 closed and readable, the step in it), and the run stops at the next step."""
    from masonry_nscd import run as run_mod
    from masonry_nscd.io.recorder import Recorder

    try:
        with pytest.raises(KeyboardInterrupt):
            run_mod.request_stop()
        assert run_mod.TERMINATE.is_set()
        run_mod.TERMINATE.clear()
        run_mod.WRITING.set()
        run_mod.request_stop()  # no exception while writing
        assert run_mod.TERMINATE.is_set()
    finally:
        run_mod.TERMINATE.clear()
        run_mod.WRITING.clear()

    orig = Recorder.write_output

    def write_with_a_signal_inside(self, step, *args, **kwargs):
        if step == 10:
            run_mod.request_stop()  # as the signal handler would, in the middle of the write
        return orig(self, step, *args, **kwargs)

    monkeypatch.setattr(Recorder, "write_output", write_with_a_signal_inside)
    out, rows = _interrupted_smoke_run(tmp_path)
    assert not run_mod.WRITING.is_set()
    assert len(rows) == 1 + 10  # the step whose output was being written, then the stop
    with h5py.File(out / "results.h5", "r") as f:
        assert "000010" in f["steps"]
    assert read_resume_point(out).step == 10


def test_a_lost_sigterm_still_stops_the_run_at_the_next_step(tmp_path, monkeypatch):
    """The SIGTERM handler of ``masonry run`` sets ``run.TERMINATE`` and raises; if a library
    swallows the exception (numba loading its kernels), the step loop raises it at the next
    step and the outputs are those of an interrupted run."""
    from masonry_nscd import run as run_mod

    orig = Integrator.step

    def step_and_lose_the_signal(self):
        rep = orig(self)
        if rep.step == 12:
            run_mod.TERMINATE.set()  # the handler ran; its KeyboardInterrupt was lost
        return rep

    monkeypatch.setattr(Integrator, "step", step_and_lose_the_signal)
    out, rows = _interrupted_smoke_run(tmp_path)
    assert len(rows) == 1 + 12  # header and steps 1 to 12: step 13 was never made
    assert read_resume_point(out).step == 10


def test_interrupted_run_resumes_to_the_uninterrupted_curve(tmp_path, monkeypatch, reference):
    out = tmp_path / "run"
    _interrupt_at(monkeypatch, 37)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE), out, **quiet)
    # what an interrupted run leaves: complete CSV rows, results.h5 up to step 30, checkpoint
    rows = (out / "force_displacement.csv").read_text().splitlines()
    assert rows[0].split(",") == CSV_COLUMNS and len(rows) == 37
    assert [s.step for s in read_results(out / "results.h5")["steps"]] == [10, 20, 30]
    point = read_resume_point(out)
    assert point.step == 30 and not point.finished
    assert _pvd_files(out)[-1] == "vtu/joints_000030.vtu"

    res = runner.invoke(app, ["run", "--resume", str(out)])
    assert res.exit_code == 0, res.output
    assert "resumed from the checkpoint of step 30" in res.output
    _assert_same_curve(_curve(out), _curve(reference))
    r, ref = read_results(out / "results.h5"), read_results(reference / "results.h5")
    assert [s.step for s in r["steps"]] == [s.step for s in ref["steps"]]
    assert np.allclose(r["steps"][-1].fields["u"], ref["steps"][-1].fields["u"], rtol=1e-6,
                       atol=1e-12)
    assert np.array_equal(r["curve"]["step"], ref["curve"]["step"])
    assert _pvd_files(out) == _pvd_files(reference)
    assert sorted(os.listdir(out / "vtu")) == sorted(os.listdir(reference / "vtu"))
    assert read_resume_point(out).finished
    assert "resumed" in (out / "run.log").read_text()


def test_resume_drops_what_was_written_after_the_checkpoint(tmp_path, monkeypatch, reference):
    """A run killed between its HDF5 step and its checkpoint: the later outputs are dropped."""
    out = tmp_path / "run"
    import masonry_nscd.io.checkpoint_file as ck
    from masonry_nscd.io import recorder

    monkeypatch.setattr(recorder, "SYNC_EVERY_S", 0.0)  # a checkpoint at every output step
    orig = ck.write_checkpoint

    def write_until_20(path, state, extra=None):
        if int(extra["step"]) > 20:
            raise KeyboardInterrupt  # "killed" after the outputs of step 30, before its checkpoint
        orig(path, state, extra)

    monkeypatch.setattr(ck, "write_checkpoint", write_until_20)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE), out, **quiet)
    assert [s.step for s in read_results(out / "results.h5")["steps"]] == [10, 20, 30]
    assert (out / "vtu" / "blocks_000030.vtu").exists()
    assert read_resume_point(out).step == 20
    monkeypatch.setattr(ck, "write_checkpoint", orig)

    energy = (out / "energy.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in energy[1:]] == [10, 20, 30]
    run_case(load_case(out / "case.yaml"), out, resume=True, **quiet)
    _assert_same_curve(_curve(out), _curve(reference))
    assert [s.step for s in read_results(out / "results.h5")["steps"]] == list(range(10, 101, 10))
    # the energy rows after the checkpoint dropped and made again; the balance carried on
    mine = (out / "energy.csv").read_text().splitlines()
    ref = (reference / "energy.csv").read_text().splitlines()
    assert [int(r.split(",")[0]) for r in mine[1:]] == list(range(10, 101, 10))
    a = np.array([[float(x) for x in r.split(",")] for r in mine[1:]])
    b = np.array([[float(x) for x in r.split(",")] for r in ref[1:]])
    assert np.allclose(a[:, 2:-2], b[:, 2:-2], rtol=1e-5, atol=1e-9)


def test_bookkeeping_is_written_at_most_once_a_second_and_at_the_end(tmp_path, monkeypatch):
    """The PVD, the HDF5 curve and the checkpoint of an output step are written when
    ``SYNC_EVERY_S`` of wall time has passed since they last were, and at the last output step:
    every output step with 0 s, only the last with a day; the files at the end are the same."""
    from masonry_nscd.io import recorder

    steps = []
    orig = recorder.Recorder._sync

    def sync(self):
        steps.append(int(self._unsynced[3]["step"]))
        orig(self)

    monkeypatch.setattr(recorder.Recorder, "_sync", sync)
    outs = {}
    for every in (0.0, 86400.0):
        monkeypatch.setattr(recorder, "SYNC_EVERY_S", every)
        steps.clear()
        outs[every] = tmp_path / f"run_{every:g}"
        run_case(load_case(SMOKE), outs[every], **quiet)
        assert steps == (list(range(10, 101, 10)) if every == 0.0 else [100])
    a, b = outs[0.0], outs[86400.0]
    assert _pvd_files(a) == _pvd_files(b) and len(_pvd_files(a)) == 20
    ra, rb = read_results(a / "results.h5"), read_results(b / "results.h5")
    assert ra["curve"].keys() == rb["curve"].keys()
    assert all(np.array_equal(ra["curve"][k], rb["curve"][k]) for k in ra["curve"])
    assert read_resume_point(a).finished and read_resume_point(b).finished


def test_resumed_endo3d_run_matches_within_the_solver_tolerance(tmp_path, monkeypatch):
    """ENDO3D blocks: Gauss-point states restored; the solver caches rebuilt (other iterates)."""
    ref, out = _reference_and_interrupted(
        tmp_path, monkeypatch, ["blocks.material=endo3d", "output.vtu=false"], 64)
    state, _ = load_checkpoint(out / CHECKPOINT_NAME)
    assert state["material_state"].shape[0] == 8 * 10  # 10 units of one element, 8 points
    run_case(load_case(out / "case.yaml"), out, resume=True, **quiet)
    _assert_same_curve(_curve(out), _curve(ref))


def test_sigterm_then_resume(tmp_path, reference):
    """The CLI in a subprocess: SIGTERM (exit 130), then --resume finishes the run."""
    out = tmp_path / "run"
    sets = ["--set", "solver.time_step_s=5e-4", "--set", "output.vtu=false"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "masonry_nscd.cli", "run", SMOKE, "-o", str(out), *sets],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_rows(proc, out / "force_displacement.csv", 60)
    stop_by_sigterm(proc, 60)
    step = read_resume_point(out).step
    with h5py.File(out / "results.h5", "r") as f:
        assert len(f["steps"]) >= step // 10
    done = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", "--resume", str(out)],
                          capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    c = _curve(out)
    assert np.array_equal(c["step"], np.arange(1, 401))
    assert c["ux_mm"][-1] >= 0.5
    again = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", "--resume", str(out)],
                           capture_output=True, text=True, timeout=60, check=False)
    assert again.returncode == 0 and "finished" in again.stdout


def test_resume_of_a_finished_run_says_so(reference):
    res = runner.invoke(app, ["run", "--resume", str(reference)])
    assert res.exit_code == 0, res.output
    assert "finished" in res.output
    with pytest.raises(RunInputError, match="finished"):
        run_case(load_case(reference / "case.yaml"), reference, resume=True, **quiet)


def test_resume_without_checkpoint_exits_2(tmp_path):
    (tmp_path / "x").mkdir()
    for target in (tmp_path / "x", tmp_path / "missing"):
        res = runner.invoke(app, ["run", "--resume", str(target)])
        assert res.exit_code == 2, res.output
        assert "Traceback" not in res.output
    assert "no checkpoint" in runner.invoke(app, ["run", "--resume", str(tmp_path / "x")]).output


def test_resume_refuses_a_case_file_or_a_changed_case(tmp_path, monkeypatch):
    res = runner.invoke(app, ["run", SMOKE, "--resume", str(tmp_path)])
    assert res.exit_code == 2 and "--resume" in res.output
    assert runner.invoke(app, ["run"]).exit_code == 2
    out = tmp_path / "run"
    _interrupt_at(monkeypatch, 15)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE, ["output.vtu=false"]), out, **quiet)
    text = (out / "case.yaml").read_text()
    (out / "case.yaml").write_text(text.replace("mu: 0.7", "mu: 0.6"))
    res = runner.invoke(app, ["run", "--resume", str(out)])
    assert res.exit_code == 2 and "differs" in res.output, res.output


def test_resume_refuses_a_damaged_checkpoint(tmp_path, monkeypatch):
    out = tmp_path / "run"
    _interrupt_at(monkeypatch, 15)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE, ["output.vtu=false"]), out, **quiet)
    (out / CHECKPOINT_NAME).write_bytes(b"PK\x03\x04 not a zip")
    res = runner.invoke(app, ["run", "--resume", str(out)])
    assert res.exit_code == 2 and "checkpoint" in res.output, res.output
    assert "Traceback" not in res.output


def test_overwrite_drops_the_previous_checkpoint(tmp_path, monkeypatch):
    out = tmp_path / "run"
    run_case(load_case(SMOKE, ["output.vtu=false"]), out, **quiet)
    assert read_resume_point(out).finished
    _interrupt_at(monkeypatch, 5)  # before the first output step of the new run
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(SMOKE, ["output.vtu=false"]), out, overwrite=True, **quiet)
    assert read_resume_point(out) is None


# --------------------------------------------------------------------------------------------
# The pieces: checkpoint file, CSV truncation, results file reopened
# --------------------------------------------------------------------------------------------


def _stepped_integrator(steps: int, sets=()):
    from masonry_nscd.scenes import build_scene

    integ = build_scene(load_case(SMOKE, list(sets))).integrator()
    for _ in range(steps):
        integ.step()
    return integ


@pytest.mark.parametrize("sets", [(), ("blocks.material=endo3d",)])
def test_checkpoint_round_trip_and_next_step(tmp_path, sets):
    # with ENDO3D blocks the state holds the Gauss points' ENDO3D stresses too, where the
    # viscous relaxation of the next step starts from
    a = _stepped_integrator(12, sets)
    save_checkpoint(tmp_path / "c.npz", a, {"note": np.array("hello"), "n": np.int64(3)})
    state, extra = load_checkpoint(tmp_path / "c.npz")
    assert str(extra["note"]) == "hello" and int(extra["n"]) == 3
    if sets:
        assert np.abs(state["material_sigma_endo3d"]).max() > 1e3  # under gravity (Pa)
    b = _stepped_integrator(0, sets)
    restore_integrator(b, state)
    for k, v in integrator_state(a).items():
        assert np.array_equal(integrator_state(b)[k], v), k
    ra, rb = a.step(), b.step()
    assert ra.step == rb.step == 13 and ra.time == rb.time
    # the same step up to the solver tolerance (the solver's caches start empty in b)
    assert np.abs(a.u - b.u).max() <= 1e-6 * np.abs(a.u).max()
    assert not list(tmp_path.glob(".*.tmp"))  # the temporary file is gone


def test_checkpoint_of_another_scene_is_refused(tmp_path):
    save_checkpoint(tmp_path / "c.npz", _stepped_integrator(1), {})
    state, _ = load_checkpoint(tmp_path / "c.npz")
    other = _stepped_integrator(0, ["wall.courses=2"])
    with pytest.raises(CheckpointError, match="shape"):
        restore_integrator(other, state)
    del state["joint_beta"]
    with pytest.raises(CheckpointError, match="joint_beta"):
        restore_integrator(_stepped_integrator(0), state)
    (tmp_path / "bad.npz").write_text("garbage")
    with pytest.raises(CheckpointError):
        load_checkpoint(tmp_path / "bad.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(2))
    with pytest.raises(CheckpointError, match="not a"):
        load_checkpoint(tmp_path / "other.npz")


def test_failed_checkpoint_write_keeps_the_previous_one(tmp_path, monkeypatch):
    integ = _stepped_integrator(3)
    save_checkpoint(tmp_path / "c.npz", integ, {})
    before = (tmp_path / "c.npz").read_bytes()

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(np, "savez", full)
    with pytest.raises(OSError):
        save_checkpoint(tmp_path / "c.npz", integ, {})
    assert (tmp_path / "c.npz").read_bytes() == before
    assert not list(tmp_path.glob(".*.tmp"))


def test_truncate_csv(tmp_path):
    p = tmp_path / "f.csv"
    head = ",".join(CSV_COLUMNS) + "\r\n"
    ints = ("iterations", "converged", "failed_gauss_points", "substeps")  # read as int
    row = "{}," + ",".join("3" if c in ints else "1.5" for c in CSV_COLUMNS[1:]) + "\r\n"
    p.write_text(head + "".join(row.format(i) for i in range(1, 8)) + "8,0.1,1", newline="")
    curve = truncate_csv(p, 5, CSV_COLUMNS)
    assert curve["step"] == [1, 2, 3, 4, 5] and curve["fx_kN"] == [1.5] * 5
    assert curve["substeps"] == [3] * 5 and isinstance(curve["substeps"][0], int)
    with open(p, newline="") as f:
        assert f.read() == head + "".join(row.format(i) for i in range(1, 6))
    with pytest.raises(CheckpointError, match="ends at step 5"):
        truncate_csv(p, 6, CSV_COLUMNS)
    p.write_text("a,b\n")
    with pytest.raises(CheckpointError, match="header"):
        truncate_csv(p, 1, CSV_COLUMNS)


def test_results_file_reopened_at_a_step(tmp_path):
    p = tmp_path / "r.h5"
    with ResultsFile(p, "name: x\n", {"nodes": np.zeros((2, 3))}) as r:
        for s in (10, 20, 30):
            r.write_step(s, s * 0.1, {"u": np.full(3, s)})
        r.write_curve({"step": np.arange(1, 31)})
    with ResultsFile.reopen(p, last_step=20, curve_length=20) as r:
        with pytest.raises(ValueError, match="already"):
            r.write_step(20, 2.0, {"u": np.zeros(3)})
        r.write_step(25, 2.5, {"u": np.zeros(3)})
    back = read_results(p)
    assert [s.step for s in back["steps"]] == [10, 20, 25]
    assert np.array_equal(back["curve"]["step"], np.arange(1, 21))
    assert not list(tmp_path.glob(".*.tmp"))
    (tmp_path / "x.h5").write_text("no")
    with pytest.raises(OSError):
        ResultsFile.reopen(tmp_path / "x.h5")


# --------------------------------------------------------------------------------------------
# Write errors and output folders
# --------------------------------------------------------------------------------------------


def test_disk_full_in_results_h5_is_a_clean_failure_and_resumable(tmp_path, monkeypatch,
                                                                  reference):
    # the output steps are appended on the recorder's background thread (io.background): the
    # error comes back to the run at its next output step, which stops with the checkpoint of
    # the last complete one
    out = tmp_path / "run"
    orig = ResultsFile.staged_step

    def staged_step(self, step, time, fields):
        append = orig(self, step, time, fields)
        if step != 30:
            return append

        def full():
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        return full

    monkeypatch.setattr(ResultsFile, "staged_step", staged_step)
    res = runner.invoke(app, ["run", SMOKE, "-o", str(out)])
    assert res.exit_code == 1, res.output
    assert "results.h5" in res.output and "No space left on device" in res.output
    assert "Traceback" not in res.output and "--resume" in res.output
    # the partial results stay valid; the CSV keeps the steps made before the run stopped
    assert [s.step for s in read_results(out / "results.h5")["steps"]] == [10, 20]
    c = _curve(out)
    assert np.array_equal(c["step"], np.arange(1, len(c["step"]) + 1))
    assert 30 <= len(c["step"]) <= 40
    assert read_resume_point(out).step == 20
    # space freed: the run resumes and ends as the uninterrupted one
    monkeypatch.setattr(ResultsFile, "staged_step", orig)
    res = runner.invoke(app, ["run", "--resume", str(out)])
    assert res.exit_code == 0, res.output
    _assert_same_curve(_curve(out), _curve(reference))


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_disk_full_in_the_csv(tmp_path):
    """The CSV is a link to /dev/full, where every write fails with ENOSPC."""
    out = tmp_path / "run"
    out.mkdir()
    os.symlink("/dev/full", out / "force_displacement.csv")
    res = runner.invoke(app, ["run", SMOKE, "-o", str(out), "--overwrite",
                              "--set", "output.vtu=false"])
    assert res.exit_code == 1, res.output
    assert "force_displacement.csv" in res.output and "No space left" in res.output
    assert "Traceback" not in res.output
    assert read_resume_point(out) is None  # no checkpoint without its CSV rows


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs /proc")
def test_failed_csv_write_leaves_whole_rows(tmp_path, monkeypatch):
    """The rows of steps 21-30 reach the file, then fsync fails: they are cut off again."""
    real_fsync = os.fsync
    calls = []

    def fsync(fd):
        if os.readlink(f"/proc/self/fd/{fd}").endswith("force_displacement.csv"):
            calls.append(fd)
            if len(calls) >= 3:  # from then on (the final flush of the run tries again)
                raise OSError(errno.EIO, os.strerror(errno.EIO))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", SMOKE, "-o", str(out), "--set", "output.vtu=false"])
    assert res.exit_code == 1, res.output
    assert "force_displacement.csv" in res.output and "Input/output error" in res.output
    monkeypatch.setattr(os, "fsync", real_fsync)
    text = (out / "force_displacement.csv").read_text()
    assert text.endswith("\n") and np.array_equal(_curve(out)["step"], np.arange(1, 21))
    assert read_resume_point(out).step == 20


def test_write_error_in_the_vtu_files(tmp_path, monkeypatch):
    # the files are written on the recorder's background thread (io.background): the error
    # comes back to the run, which stops with the checkpoint of the last complete output step
    from masonry_nscd.io import vtu

    orig = vtu.VtuFile.write

    def write(self, path):
        if "joints_000020" in str(path):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return orig(self, path)

    monkeypatch.setattr(vtu.VtuFile, "write", write)
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", SMOKE, "-o", str(out)])
    assert res.exit_code == 1, res.output
    assert "joints_000020.vtu" in res.output and "Permission denied" in res.output
    assert _pvd_files(out)[-1] == "vtu/joints_000010.vtu"
    assert read_resume_point(out).step == 10


def test_output_folder_that_cannot_be_made(tmp_path):
    (tmp_path / "file").write_text("x")
    res = runner.invoke(app, ["run", SMOKE, "-o", str(tmp_path / "file" / "run")])
    assert res.exit_code == 2 and "cannot write to output folder" in res.output, res.output
    res = runner.invoke(app, ["run", SMOKE, "-o", str(tmp_path / "file")])
    assert res.exit_code == 2 and "not a folder" in res.output, res.output


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_output_folder(tmp_path):  # pragma: no cover - not run as root
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        res = runner.invoke(app, ["run", SMOKE, "-o", str(ro / "run")])
    finally:
        ro.chmod(0o700)
    assert res.exit_code == 2 and "cannot write" in res.output


def test_non_empty_folder_needs_overwrite(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    res = runner.invoke(app, ["run", SMOKE, "-o", str(tmp_path), "--set", "output.vtu=false"])
    assert res.exit_code == 2 and "--overwrite" in res.output
    res = runner.invoke(app, ["run", SMOKE, "-o", str(tmp_path), "--overwrite",
                              "--set", "output.vtu=false"])
    assert res.exit_code == 0, res.output


# --------------------------------------------------------------------------------------------
# No NaN in the outputs; solver exceptions end cleanly
# --------------------------------------------------------------------------------------------


def test_nan_never_reaches_the_csv(tmp_path, monkeypatch):
    orig = Integrator.point_forces

    def forces(self):
        f = orig(self)
        if self.step_index == 45:
            f[0, 0] = np.nan
        return f

    monkeypatch.setattr(Integrator, "point_forces", forces)
    out = tmp_path / "run"
    with pytest.raises(RunFailure, match=r"step 45 \(vertical stage.*not finite"):
        run_case(load_case(SMOKE), out, **quiet)
    text = (out / "force_displacement.csv").read_text().lower()
    assert "nan" not in text and "inf" not in text
    assert _curve(out)["step"][-1] == 44


def test_nan_in_a_field_never_reaches_the_vtu_or_hdf5(tmp_path, monkeypatch):
    orig = Integrator.step

    def step(self):
        rep = orig(self)
        if rep.step == 20:
            self.joints.u[3, 1] = np.inf  # a joint's slip: in the VTU and HDF5 fields only
        return rep

    monkeypatch.setattr(Integrator, "step", step)
    res = runner.invoke(app, ["run", SMOKE, "-o", str(tmp_path / "run")])
    assert res.exit_code == 1, res.output
    assert "step 20 (vertical stage" in res.output and "non-finite" in res.output
    assert "Traceback" not in res.output
    assert [s.step for s in read_results(tmp_path / "run" / "results.h5")["steps"]] == [10]


def test_solver_exception_is_a_clean_failure(tmp_path, monkeypatch):
    _interrupt_at(monkeypatch, 23, np.linalg.LinAlgError("Singular matrix"))
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", SMOKE, "-o", str(out)])
    assert res.exit_code == 1, res.output
    assert "step 23 (vertical stage" in res.output and "LinAlgError: Singular matrix" in res.output
    assert "Traceback" not in res.output
    assert "Traceback" in (out / "run.log").read_text()


@pytest.mark.parametrize("after", [0, 2])
def test_resumed_run_with_halved_steps_matches(tmp_path, monkeypatch, after):
    """The smoke wall with no vertical stress halves steps (tests/test_substeps.py); the
    half-step integrator is not checkpointed but built again on the first failure after the
    resume, and the resumed run must reach the uninterrupted curve, its halved steps included
    (with ``halved_steps_after_failure``, the step control's memory is in the checkpoint)."""
    ref, out = _reference_and_interrupted(
        tmp_path, monkeypatch, ["loading.vertical_stress.value_Pa=0", "output.vtu=false",
                                f"solver.halved_steps_after_failure={after}"], 75)
    assert read_resume_point(out).step == 70
    run_case(load_case(out / "case.yaml"), out, resume=True, **quiet)
    a, b = _curve(out), _curve(ref)
    _assert_same_curve(a, b)
    assert np.array_equal(a["substeps"], b["substeps"]) and (b["substeps"][70:] > 1).any()
    assert a["converged"].all()
