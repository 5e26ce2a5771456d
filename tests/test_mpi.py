"""The Krylov solve on several processes by PETSc (``nscd/petsc_solve.py``, ``nscd/mpi.py``,
``masonry run --processes P``), against the solve on one process and a direct solve.

* ``partition``: ranges of whole bodies, cut at the body boundary nearest to an equal share.
* the body system of the smoke wall's Newton matrix solved by PETSc on 2 and 3 processes
  (mpiexec): the residual ``|S v - rhs|`` computed here within the tolerance asked, the
  solution that of SciPy's direct solver to the system's conditioning; a second matrix
  (another set-up) with another right-hand side, likewise.
* a run of the smoke case on 2 and 3 processes: the log says so and names PETSc's solver and
  its coarse LU, and the curve is the run's on one process to the Newton tolerance, step for
  step; PETSc's options from the command line over the case's (PETSc's own coarse LU over
  MKL's PARDISO, which ``make mpi`` builds PETSc with wherever MKL is installed);
  ``-log_view`` among them prints PETSc's summary.
* the 8x elastic study wall on 2 and 3 processes: the one-process curve within the
  regression's bound (``test_regression.py``); the ENDO3D study wall to 2 mm on 2 and 3
  processes: its stored regression curve within that bound.
* a direct solver asked for, or a bad case, on several processes: exit 2, the message once.
* SIGTERM on two processes: exit 130, the outputs kept, no process left; --resume on two
  processes finishes the run.

Every test but the first two needs the distributed engine (``make mpi``: PETSc, petsc4py and
mpi4py on the system's MPICH) and is skipped without it.
"""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import test_regression
from conftest import stop_by_sigterm, wait_for_rows
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.nscd import linear, mpi, petsc_solve
from masonry_nscd.report import read_curve_csv
from masonry_nscd.scenes import build_scene

needs_petsc = pytest.mark.skipif(
    not petsc_solve.available(),
    reason="the distributed engine (PETSc, petsc4py, mpi4py) is not installed: make mpi")
MPIEXEC = shutil.which("mpiexec") or "mpiexec"
SMOKE = "cases/smoke.yaml"
QUIET = ["output.vtu=false", "output.hdf5=false", "output.energy=false"]

SCRIPT = r"""
import json, sys
import numpy as np
import scipy.sparse as sp
from masonry_nscd.nscd import mpi, petsc_solve

comm = mpi.world()
if comm.rank:
    mpi.serve(comm)
    sys.exit()
d = np.load(sys.argv[1])
n = len(d["body_of"])
solver = petsc_solve.PetscKrylovSolver(comm, d["body_of"], d["modes"], rtol=1e-8,
                                       max_iterations=500)
out = {"size": comm.size, "cuts": solver.part.cuts.tolist(), "v": [], "iterations": []}
for S_data, b in ((d["S1"], d["b1"]), (d["S2"], d["b2"])):
    S = sp.csr_matrix((S_data, d["indices"], d["indptr"]), shape=(n, n))
    v = solver.factorise_system(S, None, None, None).solve(b)
    out["v"].append(v.tolist())
    out["iterations"].append(solver.last_iterations)
json.dump(out, open(sys.argv[2], "w"))
mpi.shutdown()
"""


def test_partition_cuts_whole_bodies_nearest_to_equal_shares():
    body_of = np.repeat(np.arange(5), [3, 3, 5, 5, 2])  # 18 dofs, body boundaries 0 3 6 11 16
    assert mpi.partition(body_of, 1).tolist() == [0, 18]
    assert mpi.partition(body_of, 2).tolist() == [0, 11, 18]  # 9: 11 is 2 away, 6 is 3
    assert mpi.partition(body_of, 3).tolist() == [0, 6, 11, 18]  # 6 and 12
    with pytest.raises(ValueError, match="6 processes for 5 bodies"):
        mpi.partition(body_of, 6)


def test_direct_solvers_refuse_several_processes():
    assert linear.choose("auto", 1000, processes=2) == "krylov"
    assert linear.choose("krylov", 1000, processes=2) == "krylov"
    for name in ("lu", "pardiso"):
        with pytest.raises(ValueError, match=f"solver.linear: {name} runs on one process"):
            linear.choose(name, 1000, processes=2)


@pytest.fixture(scope="module")
def smoke_system(tmp_path_factory):
    """The body system ``S`` of the smoke wall's Newton matrix after 3 steps and at the next
    set-up that changed it, on the union of their patterns, with the bodies, their rigid modes
    and two right-hand sides."""
    integ = build_scene(load_case(SMOKE, [*QUIET, "solver.linear=krylov"])).integrator()
    N, s = integ.newton, integ.sys
    xyz = [bd.X if s.body_deformable[i] else None for i, bd in enumerate(integ.bodies)]
    modes = linear.rigid_body_modes(s.body_dof0, s.body_deformable, xyz)[N.free]
    body_of = np.searchsorted(s.body_dof0, N.free, side="right") - 1
    for _ in range(3):
        integ.step()
    systems = [N.lu.S.copy()]  # the body system of the last set-up
    while (N.lu.S != systems[0]).nnz == 0 and integ.step_index < 100:
        integ.step()
    systems.append(N.lu.S.copy())
    assert (systems[0] != systems[1]).nnz > 0  # another set-up, another matrix
    # one pattern for both (the union), the values of each on it
    pattern = (abs(systems[0]) + abs(systems[1])).tocsr()
    pattern.sort_indices()
    rows = np.repeat(np.arange(pattern.shape[0]), np.diff(pattern.indptr))
    S1, S2 = (np.asarray(S.tocsr()[rows, pattern.indices]).ravel() for S in systems)
    rng = np.random.default_rng(0)
    path = tmp_path_factory.mktemp("mpi") / "system.npz"
    np.savez(path, body_of=body_of, modes=modes, indptr=pattern.indptr,
             indices=pattern.indices, S1=S1, S2=S2,
             b1=rng.normal(size=len(body_of)), b2=rng.normal(size=len(body_of)))
    return path


@needs_petsc
@pytest.mark.parametrize("processes", [2, 3])
def test_the_body_system_solved_on_several_processes_is_solved_on_one(smoke_system,
                                                                      processes, tmp_path):
    script = tmp_path / "solve.py"
    script.write_text(SCRIPT)
    result = tmp_path / "out.json"
    proc = subprocess.run([str(MPIEXEC), "-n", str(processes), sys.executable, str(script),
                           str(smoke_system), str(result)], capture_output=True, text=True,
                          check=False, timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(result.read_text())
    assert out["size"] == processes and len(out["cuts"]) == processes + 1
    d = np.load(smoke_system)
    n = len(d["body_of"])
    for k in (1, 2):
        S = sp.csr_matrix((d[f"S{k}"], d["indices"], d["indptr"]), shape=(n, n))
        b = d[f"b{k}"]
        v = np.array(out["v"][k - 1])
        # the relative residual asked for (1e-8), computed here on the whole matrix
        assert np.linalg.norm(b - S @ v) <= 2e-8 * np.linalg.norm(b)
        assert 0 < out["iterations"][k - 1] < 500
        # SciPy's direct solution, to the conditioning of the glue springs (1e9 times the
        # blocks' stiffness: test_linear_solvers)
        v_ref = spla.spsolve(S.tocsc(), b)
        assert np.linalg.norm(v - v_ref) <= 1e-3 * np.linalg.norm(v_ref)


def _curve(outdir: Path) -> np.ndarray:
    return np.genfromtxt(outdir / "force_displacement.csv", delimiter=",", names=True)


def _quiet_env() -> dict:
    """This environment without mpiexec's variables (a test run under mpiexec itself would
    otherwise take the subprocess for one of its ranks)."""
    return {k: v for k, v in os.environ.items() if k not in mpi.SIZE_VARIABLES}


def _run_on(case: str, sets: list[str], processes: int, out: Path, *options: str) -> Path:
    """``masonry run`` of ``case`` into ``out`` on the Krylov solver on ``processes``
    processes, without fields (``QUIET``), the command line's further ``options`` after it;
    it must exit 0. Returns ``out``."""
    args = [a for s in (*sets, *QUIET, "solver.linear=krylov") for a in ("--set", s)]
    r = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", case, "-o", str(out),
                        *args, "--processes", str(processes), *options], capture_output=True,
                       text=True, check=False, timeout=900, env=_quiet_env())
    assert r.returncode == 0, r.stderr
    return out


@pytest.fixture(scope="module")
def one_process_curve(tmp_path_factory):
    one = tmp_path_factory.mktemp("one")
    sets = [a for s in (*QUIET, "solver.linear=krylov") for a in ("--set", s)]
    r1 = CliRunner().invoke(app, ["run", SMOKE, "-o", str(one), *sets])
    assert r1.exit_code == 0, r1.output
    return _curve(one)


@needs_petsc
@pytest.mark.parametrize("processes", [2, 3])
def test_a_run_on_several_processes_is_the_run_on_one(one_process_curve, processes, tmp_path):
    out = _run_on(SMOKE, [], processes, tmp_path / "run")
    log = (out / "run.log").read_text()
    assert f"linear solver krylov on {processes} processes" in log
    assert "0 solves made by LU" in log
    assert re.search(rf"\(PETSc KSP fgmres, PC mg, coarse LU (mkl_pardiso|petsc) on {processes} "
                     r"processes\)", log)
    # every process's peak memory, and their sum
    memory = re.search(r"memory: peak per process ([\d, +]+) = ([\d,]+) MiB", log)
    assert memory is not None
    each = [float(m.replace(",", "")) for m in memory.group(1).split(" + ")]
    assert len(each) == processes and all(m > 0.0 for m in each)
    assert abs(sum(each) - float(memory.group(2).replace(",", ""))) <= processes
    a, b = one_process_curve, _curve(out)
    assert len(a) == len(b) and np.array_equal(a["step"], b["step"])
    tol = load_case(SMOKE).solver.tolerance
    for col in ("fx_kN", "fy_kN"):
        scale = np.abs(a[col]).max()
        assert np.abs(a[col] - b[col]).max() <= 100.0 * tol * scale, col
    assert np.all(b["converged"] == 1)


#: The study's wall, eight times the units (44 courses of 12), elastic, to 0.5 mm: the
#: regression's settings (``test_regression.CASES``) on the Krylov solver.
STUDY_8X = ("cases/wall_0.5MPa_elastic.yaml",
            [*test_regression.CASES["study_elastic_0.5mm"][1], "wall.courses=44",
             "wall.units_per_course=12"])


@pytest.fixture(scope="module")
def study_8x_one_process(tmp_path_factory):
    out = _run_on(*STUDY_8X, 1, tmp_path_factory.mktemp("study8x") / "one")
    return read_curve_csv(out / "force_displacement.csv")


@needs_petsc
@pytest.mark.parametrize("processes", [2, 3])
def test_the_8x_study_wall_on_several_processes_is_the_run_on_one(study_8x_one_process,
                                                                  processes, tmp_path):
    """The 8x elastic study wall (18,000 dofs) on 2 and 3 processes: every physical column
    within the regression's bound of the one-process curve (the solver's tolerance, step for
    step while the runs step alike)."""
    case, sets = STUDY_8X
    new = read_curve_csv(_run_on(case, sets, processes, tmp_path / "run")
                         / "force_displacement.csv")
    ref = study_8x_one_process
    assert len(new["step"]) == len(ref["step"])
    assert not test_regression.moved(ref, new, load_case(case, sets).solver.tolerance)


@needs_petsc
@pytest.mark.parametrize("processes", [2, 3])
def test_the_endo3d_study_wall_keeps_its_regression_curve_on_several_processes(processes,
                                                                               tmp_path):
    """The study's wall with ENDO3D blocks to 2 mm, past the cracking of the heel, on 2 and 3
    processes: its stored regression curve (``tests/data/regression``, written with the
    direct solver on one process) within the regression's bound."""
    name = "study_endo3d_2mm"
    case, sets = test_regression.CASES[name]
    new = read_curve_csv(_run_on(case, sets, processes, tmp_path / "run")
                         / "force_displacement.csv")
    ref = read_curve_csv(test_regression.DATA / f"{name}.csv")
    assert len(new["step"]) == len(ref["step"])
    assert not test_regression.moved(ref, new, load_case(case, sets).solver.tolerance)


@needs_petsc
def test_petsc_options_of_the_command_line_go_over_the_case(one_process_curve, tmp_path):
    """The case asks for block Jacobi, the command line for overlapping Schwarz with ILU: the
    solve is PETSc's GMRES with ASM, and the curve is still the one-process curve."""
    out = _run_on(SMOKE, ["solver.petsc_options=-pc_type bjacobi -ksp_max_it 400"], 2,
                  tmp_path / "run", "--petsc-options", "-pc_type asm -sub_pc_type ilu")
    assert "(PETSc KSP fgmres, PC asm on 2 processes)" in (out / "run.log").read_text()
    a, b = one_process_curve, _curve(out)
    tol = load_case(SMOKE).solver.tolerance
    assert np.abs(a["fx_kN"] - b["fx_kN"]).max() <= 100.0 * tol * np.abs(a["fx_kN"]).max()


@needs_petsc
def test_the_distributed_engine_has_mkl_pardiso_where_the_venv_has_mkl():
    """``make mpi`` builds PETSc on the mkl wheel's libraries wherever they are installed, so
    that the coarse level's LU is MKL's PARDISO: PETSc says it has the package."""
    if not list(Path(sys.prefix, "lib").glob("libmkl_core.so.*")):
        pytest.skip("no MKL in this environment: PETSc's own LU is the coarse solver")
    ask = "from petsc4py import PETSc; print(PETSc.Sys.hasExternalPackage('mkl_pardiso'))"
    out = subprocess.run([sys.executable, "-c", ask], check=False, capture_output=True,
                         text=True, env=_quiet_env(), timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"


@needs_petsc
@pytest.mark.parametrize(("options", "coarse"), [
    # PETSc's own coarse LU, named on the command line, over MKL's PARDISO
    ("-mg_coarse_redundant_pc_factor_mat_solver_type petsc", "coarse LU petsc"),
    # the coarse level solved iteratively in place of the redundant LU: GMRES to 1e-10 on
    # block Jacobi (flexible GMRES outside takes a preconditioner that varies)
    ("-mg_coarse_pc_type bjacobi -mg_coarse_ksp_type gmres -mg_coarse_ksp_rtol 1e-10",
     "coarse PC bjacobi"),
])
def test_a_coarse_solver_from_the_command_line_is_named_and_gives_the_curve_of_one_process(
        one_process_curve, tmp_path, options, coarse):
    """The coarse solver that PETSc's options put in place of the default: the log names the
    one that ran, read from PETSc's objects, and the curve is the one-process curve."""
    out = _run_on(SMOKE, [], 2, tmp_path / "run", "--petsc-options", options)
    assert f"(PETSc KSP fgmres, PC mg, {coarse} on 2 processes)" in \
        (out / "run.log").read_text()
    a, b = one_process_curve, _curve(out)
    tol = load_case(SMOKE).solver.tolerance
    assert np.abs(a["fx_kN"] - b["fx_kN"]).max() <= 100.0 * tol * np.abs(a["fx_kN"]).max()


@needs_petsc
def test_petsc_log_view_from_the_command_line_prints_the_summary(tmp_path):
    """``--petsc-options -log_view``, an option PETSc reads at its initialisation only: the run
    ends normally (exit 0) and prints PETSc's performance summary with its message counts,
    written to the file the option names."""
    log = tmp_path / "log_view.txt"
    _run_on(SMOKE, ["loading.horizontal.target_m=1e-4"], 2, tmp_path / "run",
            "--petsc-options", f"-log_view :{log}")
    text = log.read_text()
    assert "PETSc Performance Summary" in text and "with 2 processes" in text
    counts = re.search(r"MPI Msg Count:\s+\S+\s+\S+\s+\S+\s+(\S+)", text)
    assert counts is not None and float(counts.group(1)) > 0.0


@needs_petsc
@pytest.mark.parametrize("bad, message", [
    (["solver.linear=lu"], "solver.linear: lu runs on one process"),
    (["solver.tolerance=2"], "solver.tolerance"),
    (["solver.linear=krylov", "solver.petsc_options=-pc_type nonsense"],
     "PETSc refuses '-pc_type nonsense': a type it does not know"),
])
def test_bad_input_on_two_processes_exits_2_with_the_message_once(bad, message, tmp_path):
    sets = [a for s in bad for a in ("--set", s)]
    proc = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", SMOKE, "-o",
                           str(tmp_path / "run"), *sets, "--processes", "2"],
                          capture_output=True, text=True, timeout=300, check=False,
                          env=_quiet_env())
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.count(message) == 1, proc.stderr


@needs_petsc
def test_sigterm_on_two_processes_stops_at_the_step_end_then_resumes(tmp_path):
    """SIGTERM to ``masonry run --processes 2``: every process stops (exit 130, the outputs
    kept, none left running), and ``--resume --processes 2`` finishes the run."""
    import psutil

    out = tmp_path / "run"
    sets = ["--set", "solver.time_step_s=5e-4", "--set", "output.vtu=false",
            "--set", "solver.linear=krylov"]
    env = _quiet_env()
    proc = subprocess.Popen([sys.executable, "-m", "masonry_nscd.cli", "run", SMOKE, "-o",
                             str(out), *sets, "--processes", "2"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    wait_for_rows(proc, out / "force_displacement.csv", 60)
    children = psutil.Process(proc.pid).children(recursive=True)
    assert len([c for c in children if c.name().startswith("python")]) == 2  # the ranks
    stop_by_sigterm(proc, 120)
    _, alive = psutil.wait_procs(children, timeout=10)
    assert not alive
    done = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", "--resume", str(out),
                           "--processes", "2"], capture_output=True, text=True, timeout=300,
                          check=False, env=env)
    assert done.returncode == 0, done.stderr
    c = _curve(out)
    assert np.array_equal(c["step"], np.arange(1, 401))
    assert c["ux_mm"][-1] >= 0.5


@needs_petsc
def test_bench_scaling_steps_a_wall_on_two_processes(tmp_path):
    """``bench-scaling --processes 1,2``: the wall stepped on one process and on two, each
    process's peak memory in the row of two, and the comparison of the two printed."""
    from masonry_nscd.studies import bench as bm

    r = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "bench-scaling", SMOKE,
                        "--largest", "1", "--steps", "3", "--processes", "1,2", "-o",
                        str(tmp_path), "--set", "solver.linear=krylov"], capture_output=True,
                       text=True, check=False, timeout=600, env=_quiet_env())
    assert r.returncode == 0, r.stdout + r.stderr
    with open(tmp_path / "scaling.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(row["wall"], row["processes"]) for row in rows] == \
        [("baseline", "1"), ("1x", "1"), ("1x", "2")]
    two = rows[-1]
    assert two["status"] == "ok" and int(two["steps"]) == 3
    others, each, total = (float(two[k]) for k in ("peak_rss_MiB_others", "peak_rss_MiB",
                                                  "peak_rss_MiB_all"))
    # each figure written to 1e-3 MiB
    assert others > 0.0 and each > 0.0 and total == pytest.approx(each + others, abs=0.01)
    assert rows[1]["peak_rss_MiB_others"] == ""  # none on one process (NaN, written empty)
    assert "1x on 2 processes against one: time per step" in r.stdout
    assert bm.SCALING_COLUMNS == list(rows[0])
