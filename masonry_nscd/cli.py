"""Command-line interface: parse, call, report. Nothing else lives here.

Heavy modules (numpy, numba kernels, h5py, meshio) are imported inside the commands so that
``masonry --help`` answers at once. Exit codes: 0 done, 1 the computation failed (solver not
converged, divergence), 2 invalid input (bad case file, bad option).
"""

from __future__ import annotations

import contextlib
import sys
from pathlib import Path
from typing import Annotated

import typer

# help texts are Markdown: paragraphs are wrapped to the terminal, a literal "<" is "\\<"
app = typer.Typer(
    add_completion=False,
    rich_markup_mode="markdown",
    no_args_is_help=True,
    help="masonry_nscd: masonry walls block by block with Non-Smooth Contact Dynamics.",
)
point_app = typer.Typer(
    no_args_is_help=True,
    rich_markup_mode="markdown",
    help="Material-point drivers: one joint point or one block element along a loading path.",
)
app.add_typer(point_app, name="point")


def _fail(message: str, code: int) -> None:
    """Print a one-paragraph error on stderr and leave with ``code``."""
    typer.echo(f"error: {message}", err=True)
    if "masonry_nscd.nscd.mpi" in sys.modules:  # under mpiexec: the code for the launcher
        sys.modules["masonry_nscd.nscd.mpi"].record_exit(code)
    raise typer.Exit(code)


def _study_outdir(output: Path | None, default: Path, overwrite: bool) -> Path:
    """A study's folder: ``output`` or ``default``; leave with code 2 if it is not empty and
    ``overwrite`` is not given."""
    outdir = output or default
    if outdir.exists() and (not outdir.is_dir() or any(outdir.iterdir())) and not overwrite:
        _fail(f"output folder {outdir} exists and is not empty: use --overwrite or another -o", 2)
    return outdir


@contextlib.contextmanager
def _study_runs(param: str, runs: str, what: str):
    """The errors of a search over one case parameter (calibrate, threshold) as exits: an
    invalid value or a study error 2, a failed run 1, an interruption 130 (``runs``: what the
    folder of the runs so far is called; ``what``: the study's name)."""
    from masonry_nscd.case import CaseError
    from masonry_nscd.run import RunFailure
    from masonry_nscd.studies.calibrate import CalibrationError

    try:
        yield
    except CaseError as exc:
        _fail(f"invalid value of {param}: {'; '.join(exc.messages)}", 2)
    except CalibrationError as exc:
        _fail(str(exc), 2)
    except RunFailure as exc:
        _fail(f"a {what} run failed: {exc}", 1)
    except KeyboardInterrupt:
        _fail(f"interrupted; {runs}", 130)


def _load_case_or_exit(path: Path | str, overrides: list[str] | None = None):  # -> Case
    """Load and validate a case file with its ``--set`` overrides (the schema, then its
    builder's checks), or leave with code 2.

    Every message of the :class:`~masonry_nscd.case.CaseError` goes to stderr, one per line.
    Returns the :class:`~masonry_nscd.case.Case`.
    """
    from masonry_nscd.case import CaseError, load_case
    from masonry_nscd.scenes import check_case

    try:
        return check_case(load_case(path, list(overrides or ())))
    except CaseError as exc:
        count = len(exc.messages)
        lines = "\n".join(f"  - {m}" for m in exc.messages)
        _fail(f"invalid case {path} ({count} problem{'s' if count > 1 else ''}):\n{lines}", 2)


@app.command()
def validate(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    overrides: Annotated[
        list[str] | None,
        typer.Option(
            "--set",
            metavar="PATH=VALUE",
            help="Override one field, e.g. --set joint.mu=0.5 or "
            "--set wall.elements_per_unit=[1,1,1] (VALUE is read as YAML; repeatable).",
        ),
    ] = None,
    print_case: Annotated[
        bool, typer.Option("--print", help="Write the full case, every default filled in, as YAML.")
    ] = False,
) -> None:
    """Check a case file: exit 0 with a one-line summary, or exit 2 listing every problem."""
    case = _load_case_or_exit(case_file, overrides)
    from masonry_nscd.case import case_to_yaml
    from masonry_nscd.scenes import describe_case

    try:
        summary = describe_case(case)
    except ValueError as exc:
        _fail(f"invalid case {case_file}: {exc}", 2)
    if case.step_growth_note:
        summary += f"; {case.step_growth_note}"
    if print_case:
        typer.echo(f"# {summary}\n{case_to_yaml(case)}", nl=False)
    else:
        typer.echo(f"ok {summary}")


@app.command()
def schema(
    markdown: Annotated[bool, typer.Option(
        "--markdown", help="The reference page of the case file (Markdown).")] = False,
    json_schema: Annotated[bool, typer.Option(
        "--json", help="The JSON Schema (draft 2020-12) of the case file, for editors.")] = False,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="FILE", help="Write to FILE instead of printing.")] = None,
) -> None:
    """The case file's reference, made from the case model: every section and field with its
    meaning, unit, default and allowed values (--markdown), or a JSON Schema that editors
    check case files with (--json). The committed copies are docs/reference/case.md and
    docs/reference/case.schema.json (`make reference` writes both)."""
    if markdown == json_schema:
        _fail("give one of --markdown and --json", 2)
    from masonry_nscd.case import reference

    text = reference.markdown_text() if markdown else reference.json_text()
    if output is None:
        typer.echo(text, nl=False)
        return
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        output.write_text(text, encoding="utf-8")
    except OSError as exc:
        _fail(f"cannot write {output}: {exc.strerror or exc}", 2)
    typer.echo(f"wrote {output}")


SetOption = Annotated[
    list[str] | None,
    typer.Option("--set", metavar="PATH=VALUE",
                 help="Override one field of the case (VALUE read as YAML; repeatable)."),
]
OverwriteOption = Annotated[
    bool, typer.Option("--overwrite", help="Write into a folder that is not empty.")]


@app.command()
def run(
    case_file: Annotated[Path | None, typer.Argument(
        metavar="[CASE.yaml]", help="The case file (YAML); none with --resume.")] = None,
    output: Annotated[Path | None, typer.Option("-o", "--output",
                      help="Run folder (default results/\\<case name>/).")] = None,
    overrides: SetOption = None,
    overwrite: Annotated[bool, typer.Option("--overwrite",
                         help="Write into a run folder that is not empty.")] = False,
    resume: Annotated[Path | None, typer.Option(
        "--resume", metavar="OUTDIR",
        help="Continue the interrupted run in OUTDIR from its last checkpoint "
        "(case from OUTDIR/case.yaml).")] = None,
    n_threads: Annotated[int | None, typer.Option(
        "--threads", min=1, metavar="N",
        help="Threads for the joint law and the ENDO3D kernels, and for PARDISO's "
        "factorisations unless MKL_NUM_THREADS is set (default: NUMBA_NUM_THREADS, else every "
        "core); the kernels give the same results on any number, PARDISO the same to "
        "round-off.")] = None,
    processes: Annotated[int | None, typer.Option(
        "--processes", min=1, metavar="P",
        help="Run on P processes (mpiexec; PETSc, installed by make mpi): the Krylov "
        "linear solve is PETSc's on all of them, the rest runs on the first; solver.linear "
        "must be krylov or auto.")] = None,
    petsc_options: Annotated[str | None, typer.Option(
        "--petsc-options", metavar="OPTIONS",
        help="PETSc's options for the solve on several processes, over the case's "
        "solver.petsc_options, e.g. \"-pc_type asm -sub_pc_type ilu\" (docs/guide/solvers.md)."
        )] = None,
) -> None:
    """Run a wall case to its target displacement and write CSV, HDF5 and VTU results."""
    from masonry_nscd.nscd import mpi

    if processes is not None and processes > 1 and mpi.launched_processes() == 1:
        argv = [*([str(case_file)] if case_file is not None else []),
                *(["-o", str(output)] if output is not None else []),
                *[a for s in overrides or () for a in ("--set", s)],
                *(["--overwrite"] if overwrite else []),
                *(["--resume", str(resume)] if resume is not None else []),
                *(["--threads", str(n_threads)] if n_threads is not None else []),
                *(["--petsc-options", petsc_options] if petsc_options is not None else [])]
        try:
            code = mpi.relaunch(processes, ["run", *argv])
        except RuntimeError as exc:
            _fail(str(exc), 2)
        raise typer.Exit(code)
    if mpi.take_part():  # mpiexec's other processes: the linear solves, no outputs
        return
    if mpi.launched_processes() > 1:
        try:  # MPI started now, so that an early exit (a bad case) still stops the others
            mpi.world()
        except RuntimeError as exc:
            _fail(str(exc), 2)
    if n_threads is not None:
        from masonry_nscd import threads

        threads.set_count(n_threads)
    if resume is not None:
        if case_file is not None or output is not None or overrides or overwrite:
            _fail("--resume OUTDIR continues the run in OUTDIR with its own case.yaml: give "
                  "no CASE.yaml, -o, --set or --overwrite with it", 2)
        outdir = resume
        from masonry_nscd.io.recorder import read_resume_point
        from masonry_nscd.nscd.checkpoint import CheckpointError

        if not outdir.is_dir():
            _fail(f"--resume {outdir}: no such run folder", 2)
        try:
            point = read_resume_point(outdir)
        except CheckpointError as exc:
            _fail(f"cannot resume: {exc}", 2)
        if point is None:
            _fail(f"cannot resume: {outdir} has no checkpoint (checkpoint.npz): not a run "
                  "folder, or the run stopped before its first output step", 2)
        if point.finished:
            typer.echo(f"the run in {outdir} is finished (step {point.step}): nothing to resume")
            return
        case = _load_case_or_exit(outdir / "case.yaml")
    else:
        if case_file is None:
            _fail("missing CASE.yaml (or --resume OUTDIR to continue an interrupted run)", 2)
        case = _load_case_or_exit(case_file, overrides)
        outdir = output or Path("results") / case.name
    import signal

    from masonry_nscd.run import (
        TERMINATE,
        RunFailure,
        RunInputError,
        RunOutputError,
        request_stop,
        run_case,
    )
    from masonry_nscd.warmup import compile_first_run

    if mpi.launched_processes() > 1:
        from masonry_nscd.nscd import petsc_solve

        petsc_solve.case_options = case.solver.petsc_options
        petsc_solve.command_line_options = petsc_options or ""
    TERMINATE.clear()
    # SIGTERM and Ctrl-C end the run with its outputs kept, never in the middle of writing them
    signal.signal(signal.SIGTERM, request_stop)
    signal.signal(signal.SIGINT, request_stop)
    try:
        compile_first_run(case, echo=typer.echo)  # kernels not yet in the cache: two processes
        res = run_case(case, outdir, overwrite=overwrite, echo=typer.echo,
                       resume=resume is not None)
    except RunInputError as exc:
        _fail(str(exc), 2)
    except RunOutputError as exc:
        _fail(f"{exc}; results up to the last output step are kept in {outdir} (once the "
              f"cause is fixed: masonry run --resume {outdir})", 1)
    except RunFailure as exc:
        _fail(f"the solver failed: {exc} (results up to the last output step are kept in "
              f"{outdir})", 1)
    except KeyboardInterrupt:
        _fail(f"interrupted; results up to the last output step are kept in {outdir} "
              f"(continue with: masonry run --resume {outdir})", 130)
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        mpi.shutdown()  # mpiexec's other processes stop (nothing on one process)
    typer.echo(f"results in {res.outdir}")


@point_app.command("joint")
def point_joint(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="Case file (joint part).")],
    path: Annotated[str, typer.Option("--path", help="opening | sliding | mixed")],
    to: Annotated[float, typer.Option("--to", help="Final displacement, m.")],
    output: Annotated[Path, typer.Option("-o", "--output", help="CSV file to write.")],
    normal_stress: Annotated[float, typer.Option("--normal-stress",
                             help="Held normal traction for sliding, Pa (negative: compression).")
                             ] = 0.0,
    steps: Annotated[int, typer.Option("--steps", min=1, help="Number of steps.")] = 2000,
    overrides: SetOption = None,
) -> None:
    """Drive one joint contact point of unit area and write step,u_n_m,u_t_m,T_n_Pa,T_t_Pa,d_coh."""
    from masonry_nscd.contact.point_driver import PATHS, drive_joint_point

    if path not in PATHS:
        _fail(f"--path must be one of {', '.join(PATHS)}, got {path!r}", 2)
    case = _load_case_or_exit(case_file, overrides)
    from masonry_nscd.contact.laws import params_from_case

    try:
        curve = drive_joint_point(params_from_case(case.joint), path, to, steps=steps,
                                  normal_stress=normal_stress)
    except ValueError as exc:
        _fail(str(exc), 1)
    curve.write_csv(output)
    i = int(abs(curve.T_t if path == "sliding" else curve.T_n).argmax())
    typer.echo(f"wrote {output}: {steps + 1} rows; peak |T| = "
               f"{max(abs(curve.T_n[i]), abs(curve.T_t[i])):.6g} Pa at step {i}")


@app.command("cache-clear")
def cache_clear() -> None:
    """Remove the compiled-kernel (numba) caches of every version of the sources."""
    import shutil

    from masonry_nscd import cache_root

    shutil.rmtree(cache_root(), ignore_errors=True)
    typer.echo(f"removed {cache_root()}")


@point_app.command("block")
def point_block(
    case_file: Annotated[
        Path,
        typer.Argument(
            metavar="CASE.yaml", help="Case file: blocks.E_Pa, blocks.nu and blocks.endo3d."
        ),
    ],
    path: Annotated[
        str, typer.Option("--path", metavar="tension|compression", help="Loading path.")
    ],
    to: Annotated[
        float,
        typer.Option(
            "--to",
            metavar="STRAIN",
            help="Final axial strain; made positive for tension, negative for compression.",
        ),
    ],
    output: Annotated[
        Path, typer.Option("-o", "--output", metavar="curve.csv", help="CSV file to write.")
    ],
    size: Annotated[
        float, typer.Option("--size", metavar="H", help="Element size h (m): cube of side h.")
    ] = 0.1,
    steps: Annotated[int, typer.Option("--steps", metavar="N", help="Strain steps.")] = 200,
    lateral: Annotated[
        str,
        typer.Option(
            "--lateral",
            metavar="free|fixed",
            help="Lateral faces stress free (uniaxial stress) or lateral strains zero.",
        ),
    ] = "free",
    overrides: Annotated[
        list[str] | None,
        typer.Option("--set", metavar="PATH=VALUE", help="Override one case field (repeatable)."),
    ] = None,
) -> None:
    """Drive one ENDO3D block element along a uniaxial path and write
    step,eps_axial,sigma_axial_Pa,d_t,d_c,d_cpp (compression negative, SI units)."""
    if path not in ("tension", "compression"):
        _fail(f"--path must be tension or compression, got {path!r}", 2)
    if lateral not in ("free", "fixed"):
        _fail(f"--lateral must be free or fixed, got {lateral!r}", 2)
    if not size > 0.0:
        _fail(f"--size must be > 0 (m), got {size}", 2)
    if steps < 1:
        _fail(f"--steps must be >= 1, got {steps}", 2)
    case = _load_case_or_exit(case_file, overrides)
    import numpy as np

    from masonry_nscd.materials.point_driver import (
        DriverError,
        drive_block_point,
        params_from_case,
        write_curve_csv,
    )

    try:
        params = params_from_case(case)
    except ValueError as exc:
        _fail(f"invalid ENDO3D parameters in {case_file}: {exc}", 2)
    try:
        curve = drive_block_point(params, path, to, size=size, steps=steps, lateral=lateral)
    except DriverError as exc:
        _fail(f"the point driver did not converge: {exc}", 1)
    write_curve_csv(output, curve)
    sig = curve["sigma_axial_Pa"]
    i = int(np.argmax(sig)) if path == "tension" else int(np.argmin(sig))
    typer.echo(
        f"wrote {output} ({len(sig)} rows): peak {sig[i] / 1e6:.4g} MPa at strain "
        f"{curve['eps_axial'][i]:.5g}; at the end {sig[-1] / 1e6:.4g} MPa, "
        f"d_t = {curve['d_t'][-1]:.4g}, d_c = {curve['d_c'][-1]:.4g}, "
        f"d_cpp = {curve['d_cpp'][-1]:.4g}"
    )


@app.command()
def plot(
    outdirs: Annotated[list[Path], typer.Argument(metavar="OUTDIR...",
                       help="Run folders (as written by masonry run).")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="DIR",
        help="Folder of the PNG files (default OUTDIR/plots for one run, ./plots for several).")
    ] = None,
    at: Annotated[str | None, typer.Option(
        "--at", metavar="MM,MM,...",
        help="U_x (mm) of the damage maps, nearest output step (default: the peak and the end).")
    ] = None,
    magnify: Annotated[float, typer.Option(
        "--magnify", metavar="M", help="Draw the deformed shape, displacements x M (0: no).")
    ] = 0.0,
    reference: Annotated[float, typer.Option(
        "--reference-stiffness", metavar="KN_MM", help="Slope of the reference line, kN/mm.")
    ] = 71.0,
) -> None:
    """Write PNG figures of runs: force-displacement curves and damage maps of the wall.

    The curves of all the runs go on one chart with the study's 71 kN/mm initial slope; the
    damage maps show the wall's face unit by unit (d_c, d_cpp, d_t, joint cohesion lost). An
    arch run gets its mechanism instead: the deformed arch with its hinges, and the load
    against the largest displacement.
    """
    try:
        at_mm = [float(v) for v in at.split(",")] if at else None
    except ValueError:
        _fail(f"--at must be displacements in mm separated by commas, got {at!r}", 2)
    if not magnify >= 0.0:
        _fail(f"--magnify must be >= 0, got {magnify}", 2)
    from masonry_nscd.plots import PlotInputError, plot_runs

    plot_dir = output or (outdirs[0] / "plots" if len(outdirs) == 1 else Path("plots"))
    try:
        written, notes = plot_runs(outdirs, plot_dir, at_mm, magnify, reference)
    except (PlotInputError, OSError) as exc:  # OSError: an unreadable results.h5
        _fail(str(exc), 2)
    for note in notes:
        typer.echo(note)
    for path in written:
        typer.echo(f"wrote {path}")


@app.command("calibrate")
def calibrate_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    target: Annotated[float, typer.Option("--target-stiffness", metavar="KN_MM",
                      help="Target initial stiffness of the wall, kN/mm.")],
    param: Annotated[str, typer.Option("--param", metavar="PATH",
                     help="Case field to calibrate.")] = "joint.d_spring",
    bounds: Annotated[str | None, typer.Option(
        "--bounds", metavar="LOW:HIGH",
        help="Interval of the parameter; must bracket the target (default 0.8:0.99 for "
        "joint.d_spring).")] = None,
    force_range: Annotated[str | None, typer.Option(
        "--force-range", metavar="LOW:HIGH",
        help="Force levels of the stiffness secant, kN (default 10 % and 40 % of mu N).")
    ] = None,
    rtol: Annotated[float, typer.Option("--rtol", help="Relative tolerance on the stiffness.")
                    ] = 1e-3,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Calibration folder (default results/\\<case name>_calibration/).")] = None,
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Find the value of one parameter that gives a target initial stiffness of the wall.

    Brent's method on short runs that stop once the stiffness is measured; writes the
    calibrated case and calibration.json.
    """
    case = _load_case_or_exit(case_file, overrides)
    from masonry_nscd.case import load_case
    from masonry_nscd.studies import calibrate as cal

    try:
        if bounds is None and param not in cal.DEFAULT_BOUNDS:
            raise cal.CalibrationError(f"--bounds LOW:HIGH is needed to calibrate {param}")
        lo_hi = cal.parse_range(bounds, "--bounds") if bounds else cal.DEFAULT_BOUNDS[param]
        f_range = cal.parse_range(force_range, "--force-range") if force_range else None
        cal.check_history(case)
        cal.parameter_value(case, param)
        if not (target > 0.0 and rtol > 0.0):
            raise cal.CalibrationError("--target-stiffness and --rtol must be > 0")
    except cal.CalibrationError as exc:
        _fail(str(exc), 2)
    outdir = _study_outdir(output, Path("results") / f"{case.name}_calibration", overwrite)
    if overwrite and (outdir / "runs").is_dir():
        import shutil

        shutil.rmtree(outdir / "runs")

    def load(value: float, for_run: bool):
        extra = [f"{param}={float(value)!r}"]
        extra += ["output.vtu=false", "output.hdf5=false"] if for_run else \
            [f"name={case.name}_calibrated"]
        return load_case(case_file, [*(overrides or ()), *extra])

    typer.echo(f"calibrating {param} of {case.name} in [{lo_hi[0]:g}, {lo_hi[1]:g}] to "
               f"{target:g} kN/mm (short runs in {outdir / 'runs'})")
    with _study_runs(param, f"the short runs so far are in {outdir / 'runs'}", "calibration"):
        result = cal.calibrate(case, load, param, target, lo_hi, outdir, force_range_kN=f_range,
                               rtol=rtol, echo=typer.echo)
    calibrated = load(result.value, False)
    result.case_file = str(outdir / f"{calibrated.name}.yaml")
    cal.write_calibrated_case(calibrated, result, Path(result.case_file))
    cal.write_report(result, outdir / "calibration.json")
    for line in cal.format_result(result):
        typer.echo(line)
    typer.echo(f"wrote {result.case_file} and {outdir / 'calibration.json'}")


@app.command("limit")
def limit_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--out", "--output", metavar="OUTDIR",
        help="Folder of limit.json, the mechanism and the joint forces "
        "(default results/\\<case name>_limit/).")] = None,
    facets: Annotated[int, typer.Option(
        "--facets", help="0: Coulomb's cone exactly (a second-order cone); 3 or more: the "
        "friction pyramid of that many facets (error bound 1 - cos(pi/facets)).")] = 0,
    solver: Annotated[str, typer.Option(
        "--solver", help="clarabel (interior point, direct factorisation; cone or pyramid) or "
        "highs (interior point with crossover; pyramid only).")] = "clarabel",
    compressive: Annotated[float | None, typer.Option(
        "--compressive-strength", metavar="PA", help="Bound the compression of each interface "
        "point by this stress times its area (default: infinite strength).")] = None,
    tension: Annotated[bool, typer.Option(
        "--tension", help="The joints carry the tensile strength and cohesion of the case's "
        "joint law (as built); without it, no tension and no cohesion.")] = False,
    flow: Annotated[str, typer.Option(
        "--flow", help="associative (the normality rule) or non-associative (the iteration of "
        "fixed friction capacities).")] = "associative",
    start: Annotated[str, typer.Option(
        "--start", help="With --flow non-associative, the normal forces the iteration starts "
        "from: elastic (the joints' springs under the dead loads, Coulomb friction), "
        "associative (the associative solution at collapse) or run (an NSCD run of the same "
        "case, --run).")] = "elastic",
    run_dir: Annotated[Path | None, typer.Option(
        "--run", metavar="OUTDIR", help="With --start run: the folder of an NSCD run of the "
        "same scene, whose joint tractions give the start's normal forces.")] = None,
    run_time: Annotated[float | None, typer.Option(
        "--run-time-s", metavar="T", help="With --start run: the run's output step nearest "
        "this time (s; default: its last).")] = None,
    method: Annotated[str, typer.Option(
        "--method", help="With --flow non-associative: fixed-point (the iteration of fixed "
        "friction capacities, seconds) or load-path (the load followed from rest on the "
        "joints' springs, the run's path without inertia; minutes on hundreds of blocks).")
    ] = "fixed-point",
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Rigid-block limit analysis: the collapse multiplier of the case's growing load and its
    mechanism, in seconds.

    Every body is taken as rigid and the scene's contact points as the joints' interface
    points, with no tension and Coulomb friction; the largest multiplier of the growing load
    (body force, point load) that admissible joint forces equilibrate, with the other loads
    dead, by a conic programme (Clarabel; Coulomb's cone or its pyramid); the mechanism from its
    dual. Writes limit.json,
    mechanism.vtu, joint_forces.csv, joint_forces.vtu and mechanism.png (docs/limit.md)."""
    case = _load_case_or_exit(case_file, overrides)
    from masonry_nscd.limit.analysis import (
        FLOWS,
        METHODS,
        RunStartError,
        analyse,
        format_result,
        write_outputs,
    )
    from masonry_nscd.limit.lp import SOLVERS, STARTS

    if flow not in FLOWS:
        _fail(f"--flow: one of {', '.join(FLOWS)}, got {flow!r}", 2)
    if start not in STARTS:
        _fail(f"--start: one of {', '.join(STARTS)}, got {start!r}", 2)
    if (start == "run") != (run_dir is not None) or (run_time is not None and run_dir is None):
        _fail("--start run takes the run's folder (--run OUTDIR, and --run-time-s T if not "
              "its last output step); --run and --run-time-s go with --start run only", 2)
    if method not in METHODS:
        _fail(f"--method: one of {', '.join(METHODS)}, got {method!r}", 2)
    if method == "load-path" and (tension or compressive is not None):
        _fail("--method load-path: the joints' springs carry no tension and crush nowhere; "
              "leave out --tension and --compressive-strength", 2)
    if not (facets == 0 or 3 <= facets <= 1024):
        _fail(f"--facets: 0 (the cone) or from 3 to 1024, got {facets}", 2)
    if solver not in SOLVERS or (solver == "highs" and not facets):
        _fail(f"--solver: one of {', '.join(SOLVERS)} (highs with --facets 3 or more), "
              f"got {solver!r}", 2)
    outdir = _study_outdir(output, Path("results") / f"{case.name}_limit", overwrite)
    if compressive is not None and not compressive > 0.0:
        _fail(f"--compressive-strength: a stress > 0 Pa, got {compressive:g}", 2)
    try:
        result = analyse(case, facets=facets, tension=tension, flow=flow, solver=solver,
                         compressive_Pa=compressive, start=start, run_dir=run_dir,
                         run_time_s=run_time, method=method,
                         progress=lambda line: typer.echo(line, err=True))
    except RunStartError as exc:  # a run of another case, or no results in its folder
        _fail(f"--run: {exc}", 2)
    for line in format_result(result.record):
        typer.echo(line)
    paths = write_outputs(result, outdir)
    typer.echo(f"wrote {', '.join(p.name for p in paths)} in {outdir}")
    if result.solution.status != "optimal":  # no admissible forces: not a valid analysis
        raise typer.Exit(1)


@app.command("threshold")
def threshold_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    param: Annotated[str, typer.Option("--param", metavar="PATH",
                     help="Case field to search, e.g. arch.thickness_m.")],
    bounds: Annotated[str, typer.Option(
        "--bounds", metavar="LOW:HIGH",
        help="Interval of the parameter; one bound must stand and the other collapse.")],
    rtol: Annotated[float, typer.Option(
        "--rtol", help="Stop when the bracket is narrower than this times its middle.")
    ] = 2e-3,
    max_runs: Annotated[int, typer.Option("--max-runs", help="At most this many runs.")] = 30,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Study folder (default results/\\<case name>_threshold/).")] = None,
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
    method: Annotated[str, typer.Option(
        "--method", help="nscd (a run per value) or limit (rigid-block limit analysis: whether "
        "the dead loads can be carried, the growing load at zero).")] = "nscd",
) -> None:
    """Find the value of a parameter between standing and collapse, by bisection on runs.

    The parameter of a limit-state case (its minimum thickness, its critical multiplier) is
    bisected between a value where the structure stands and one where it collapses; writes
    threshold.csv and threshold.json. With --method limit each value is one linear programme
    on the rigid blocks (docs/limit.md) and only threshold.json is written."""
    case = _load_case_or_exit(case_file, overrides)
    if method not in ("nscd", "limit"):
        _fail(f"--method: nscd or limit, got {method!r}", 2)
    if method == "limit":
        _threshold_by_limit(case_file, case, param, bounds, rtol, max_runs, output, overrides,
                            overwrite)
        return
    from masonry_nscd.case import load_case
    from masonry_nscd.studies import threshold as th

    try:
        th.check_case(case)
        lo_hi = th.parse_range(bounds, "--bounds")
        th.parameter_value(case, param)
        if not (rtol > 0.0 and max_runs >= 2):
            raise th.ThresholdError("--rtol must be > 0 and --max-runs at least 2")
    except th.CalibrationError as exc:
        _fail(str(exc), 2)
    outdir = _study_outdir(output, Path("results") / f"{case.name}_threshold", overwrite)

    def load(value: float):
        return load_case(case_file, [*(overrides or ()), f"{param}={float(value)!r}",
                                     "output.vtu=false"])

    typer.echo(f"threshold of {param} of {case.name} in [{lo_hi[0]:g}, {lo_hi[1]:g}] (runs in "
               f"{outdir / 'runs'})")
    with _study_runs(param, f"the runs so far are in {outdir / 'runs'}", "threshold"):
        result = th.find_threshold(case, load, param, lo_hi, outdir, rtol=rtol,
                                   max_runs=max_runs, echo=typer.echo)
    paths = th.write_outputs(result, outdir)
    for line in th.format_table(result):
        typer.echo(line)
    typer.echo(f"wrote {paths[0]} and {paths[1]}")


def _threshold_by_limit(case_file: Path, case, param: str, bounds: str, rtol: float,
                        max_runs: int, output: Path | None, overrides: list[str] | None,
                        overwrite: bool) -> None:
    """``masonry threshold --method limit``: bisection on the static programme's feasibility
    (:mod:`masonry_nscd.limit.thickness`)."""
    from masonry_nscd.case import CaseError, load_case
    from masonry_nscd.io.limit_analysis import write_threshold
    from masonry_nscd.limit.thickness import BracketError, threshold
    from masonry_nscd.studies import threshold as th

    try:
        lo_hi = th.parse_range(bounds, "--bounds")
        th.parameter_value(case, param)
    except th.CalibrationError as exc:
        _fail(str(exc), 2)
    if not (rtol > 0.0 and max_runs >= 2):
        _fail("--rtol must be > 0 and --max-runs at least 2", 2)
    outdir = _study_outdir(output, Path("results") / f"{case.name}_threshold", overwrite)

    def load(value: float):
        return load_case(case_file, [*(overrides or ()), f"{param}={float(value)!r}"])

    try:
        result = threshold(load, lo_hi, rtol=rtol, max_steps=max_runs)
    except BracketError as exc:
        _fail(str(exc), 2)
    except CaseError as exc:
        _fail(f"invalid value of {param}: {'; '.join(exc.messages)}", 2)
    typer.echo(f"threshold of {param} of {case.name} by limit analysis: {result['value']:.6g} "
               f"+- {result['uncertainty']:.2g} (stands at {result['standing']:.6g}, falls at "
               f"{result['falling']:.6g}; {len(result['steps'])} programmes, "
               f"{result['time_s']:.2f} s)")
    path = write_threshold(outdir, {"case": case.name, "param": param, "method": "limit",
                                    **result})
    typer.echo(f"wrote {path}")


@app.command("stress-test")
def stress_test_cmd(
    output: Annotated[Path, typer.Option("-o", "--output", metavar="OUTDIR",
                      help="Folder of the runs and of stress.csv.")] = Path("results/stress-test"),
    quick: Annotated[bool, typer.Option("--quick", help="Only the fast subset of variants.")
                     ] = False,
    only: Annotated[list[str] | None, typer.Option(
        "--only", metavar="NAME", help="Run this variant only (repeatable).")] = None,
    base: Annotated[Path | None, typer.Option(
        "--case", metavar="CASE.yaml", help="Base case (default cases/smoke.yaml).")] = None,
    time_limit: Annotated[float, typer.Option(
        "--time-limit", metavar="S", help="Wall-clock limit per variant, s.")] = 600.0,
    overwrite: OverwriteOption = False,
) -> None:
    """Run a matrix of variants of a small wall and write OUTDIR/stress.csv.

    The variants change the time step, theta, the stiffnesses, the stress, the friction, the
    joint damage, the geometry and the materials. Exit 0 when every variant finished in
    equilibrium or failed cleanly, 1 otherwise."""
    from masonry_nscd.studies import stress

    base_path = base or stress.DEFAULT_BASE
    _load_case_or_exit(base_path)
    try:
        stress.select(quick, only)
    except ValueError as exc:
        _fail(str(exc), 2)
    if not time_limit > 0.0:
        _fail(f"--time-limit must be > 0 s, got {time_limit}", 2)
    _study_outdir(output, output, overwrite)
    try:
        results = stress.stress_test(output, base=base_path, quick=quick, names=only,
                                     time_limit_s=time_limit, echo=typer.echo)
    except OSError as exc:
        _fail(f"cannot write in {output}: {exc.strerror or exc}", 1)
    except KeyboardInterrupt:
        _fail(f"interrupted; the variants done so far are in {output / 'stress.csv'}", 130)
    typer.echo(stress.format_table(results))
    bad = [r.case for r in results if not r.acceptable]
    typer.echo(f"wrote {output / 'stress.csv'}: {len(results) - len(bad)} of {len(results)} "
               f"variants acceptable" + (f"; not: {', '.join(bad)}" if bad else ""))
    if bad:
        raise typer.Exit(1)



@app.command("bench")
def bench_cmd(
    case_file: Annotated[Path | None, typer.Argument(
        metavar="[CASE.yaml]", help="The case file (YAML); may be left out with --startup.")
    ] = None,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Folder of bench.csv, bench.png and the runs (default results/bench/\\<case name>/)."
    )] = None,
    quick: Annotated[bool, typer.Option(
        "--quick", help="A short ladder: time step x2, rate x2, tolerance x100, one mesh.")
    ] = False,
    startup: Annotated[bool, typer.Option(
        "--startup", help="Also time `masonry --help` (median of 5) and `masonry run "
        "cases/smoke.yaml` (median of 3).")] = False,
    repeats: Annotated[int, typer.Option(
        "--repeats", metavar="N", help="Runs of each setting shorter than 30 s (median taken).")
    ] = 3,
    time_limit: Annotated[float, typer.Option(
        "--time-limit", metavar="S", help="Wall-clock limit of one run, s.")] = 600.0,
    check_reference: Annotated[bool, typer.Option(
        "--check-reference", help="Also run the reference with its time step halved again, "
        "and give every setting's largest error against that run (err_max_check): whether the "
        "reference is converged enough to measure the errors.")] = False,
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Run time against error of settings around the case's; writes bench.csv and bench.png.

    A ladder of settings around the case's (time step, loading rate, tolerance, mesh per unit,
    solver), each compared with a refined reference run (half the time step, tolerance ten
    times tighter). Exit 1 if the reference run did not finish."""
    if case_file is None and not startup:
        _fail("missing CASE.yaml (or --startup alone for the start-up figures)", 2)
    if repeats < 1 or not time_limit > 0.0:
        _fail("--repeats must be >= 1 and --time-limit > 0 s", 2)
    case = _load_case_or_exit(case_file, overrides) if case_file is not None else None
    if case is not None:
        from masonry_nscd.studies.bench import check_history

        try:
            check_history(case)
        except ValueError as exc:
            _fail(str(exc), 2)
    outdir = _study_outdir(output, Path("results") / "bench" / (case.name if case else "startup"),
                           overwrite)
    from masonry_nscd.studies import bench as bm

    if startup:
        try:
            lines = bm.format_startup(bm.startup_figures(outdir))
        except (OSError, RuntimeError) as exc:
            _fail(f"start-up figures: {exc}", 1)
        for line in lines:
            typer.echo(line)
    if case_file is None:
        return
    try:
        result = bm.bench(case_file, outdir, overrides=list(overrides or ()), quick=quick,
                          repeats=repeats, time_limit_s=time_limit,
                          check_reference=check_reference, echo=typer.echo)
    except KeyboardInterrupt:
        _fail(f"interrupted; the settings done so far are in {outdir / 'bench.csv'}", 130)
    typer.echo(bm.format_table(result.rows))
    for line in bm.verdict(result):
        typer.echo(line)
    typer.echo(f"wrote {result.csv_path}" + (f" and {result.png_path}" if result.png_path else ""))
    ref = result.row("reference")
    if ref is None or ref.status != "ok":
        _fail("the reference run did not finish: no errors measured", 1)


@app.command("bench-detection")
def bench_detection_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    repeats: Annotated[int, typer.Option(
        "--repeats", metavar="N", min=1, max=20,
        help="Times each step is repeated (median taken).")] = 3,
    overrides: SetOption = None,
) -> None:
    """Time the contact detection of a case's blocks: joints, then contact points.

    The scene is built once; its joints are found and their points made N times; prints the
    counts and the median times (for example a dome of 10,000 voussoirs: --set
    dome.courses=100 --set dome.voussoirs=100)."""
    from masonry_nscd.studies.detection_bench import detection_times

    case = _load_case_or_exit(case_file, overrides)
    for line in detection_times(case, repeats).lines():
        typer.echo(line)


@app.command("bench-limit")
def bench_limit_cmd(
    case_file: Annotated[Path | None, typer.Argument(
        metavar="[CASE.yaml]", help="The case file (default cases/dome_hemispherical.yaml).")
    ] = None,
    params: Annotated[list[str] | None, typer.Option(
        "--param", metavar="PATH", help="Case field set to each value (repeatable: all are set; "
        "default dome.courses and dome.voussoirs).")] = None,
    values: Annotated[str, typer.Option(
        "--values", metavar="V1,V2,...", help="The values, comma-separated.")] = "10,32,100",
    facets: Annotated[int, typer.Option(
        "--facets", help="0: Coulomb's cone; 3 or more: the friction pyramid.")] = 0,
    solver: Annotated[str, typer.Option(
        "--solver", help="clarabel or highs (pyramid only).")] = "clarabel",
    overrides: SetOption = None,
) -> None:
    """Time the limit analysis of a case scaled by a parameter: blocks, points, multiplier and
    the times of the scene, the model, the programme and its solve.

    By default the shipped dome of 10 x 10, 32 x 32 and 100 x 100 voussoirs (100, 1,024 and
    10,000 blocks); a vault: --param vault.voussoirs --values 24,96 --set vault.rings=10
    (docs/limit.md)."""
    from masonry_nscd.case import CaseError, load_case
    from masonry_nscd.limit.lp import SOLVERS
    from masonry_nscd.studies import limit_bench as lb

    case_file = case_file or Path(__file__).resolve().parents[1] / "cases" / \
        "dome_hemispherical.yaml"
    names = list(params or lb.DEFAULT_PARAMS)
    try:
        vals = [float(v) for v in values.split(",") if v.strip()]
    except ValueError:
        _fail(f"--values: numbers separated by commas, got {values!r}", 2)
    if not vals:
        _fail("--values: at least one value", 2)
    if solver not in SOLVERS or (solver == "highs" and not facets):
        _fail(f"--solver: one of {', '.join(SOLVERS)} (highs with --facets 3 or more)", 2)
    _load_case_or_exit(case_file, overrides)

    def load(value: float):
        text = repr(int(value)) if float(value).is_integer() else repr(float(value))
        return load_case(case_file, [*(overrides or ()), *(f"{p}={text}" for p in names)])

    typer.echo(f"limit analysis of {case_file.name}, {' and '.join(names)} set to each value; "
               + ("Coulomb's cone" if not facets else f"pyramid of {facets} facets")
               + f", {solver}; times in s")
    typer.echo(lb.format_header())
    try:
        lb.bench_limit(load, vals, facets=facets, solver=solver, echo=typer.echo)
    except CaseError as exc:
        _fail(f"invalid value: {'; '.join(exc.messages)}", 2)


@app.command("bench-scaling")
def bench_scaling_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Folder of scaling.csv and scaling.png (default results/bench-scaling/\\<case name>/)."
    )] = None,
    steps: Annotated[int, typer.Option(
        "--steps", metavar="N",
        help="Time steps per wall, at most: a wall stops where its case ends.")] = 40,
    largest: Annotated[int, typer.Option(
        "--largest", metavar="K",
        help="The largest wall, K times the units of the case (a power of two, 1 to 256; the "
        "walls are 1x, 2x, 4x, ... Kx).")] = 8,
    smallest: Annotated[int, typer.Option(
        "--smallest", metavar="K",
        help="The smallest wall (a power of two, at most --largest): the walls are Kx ... "
        "(the one-unit baseline is always made).")] = 1,
    time_limit: Annotated[float | None, typer.Option(
        "--time-limit", metavar="S",
        help="Per wall: no step starts after S seconds (build included), a step still going a "
        "minute later is killed; the wall is reported as 'timeout' with the steps it made "
        "(default: no limit).")] = None,
    memory_limit: Annotated[float | None, typer.Option(
        "--memory-limit", metavar="GIB",
        help="Per wall: the process's address space in GiB; a wall that needs more is reported "
        "as 'memory' and the larger walls are skipped (default: no limit).")] = None,
    processes: Annotated[str, typer.Option(
        "--processes", metavar="P,...",
        help="Step each wall on each of these numbers of processes (as masonry run "
        "--processes: PETSc's Krylov solve, installed by make mpi; solver.linear krylov or "
        "auto), e.g. 1,2: each process's peak memory, and each wall's time per step and "
        "memory against one process's.")] = "1",
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Time per step and peak memory of walls 1, 2, 4, ... K times the case's.

    For walls with 1, 2, 4, ... K times the units of the case: the time per step, the
    factorisations per step and the peak memory, against the number of contact points; each
    wall stepped N times in a fresh process (or processes: --processes)."""
    case = _load_case_or_exit(case_file, overrides)
    try:
        counts = sorted({int(p) for p in processes.split(",")})
    except ValueError:
        counts = []
    if not counts or counts[0] < 1:
        _fail(f"--processes takes numbers of processes of at least 1, separated by commas, "
              f"got {processes!r}", 2)
    if counts[-1] > 1 and case.solver.linear not in ("krylov", "auto"):
        _fail(f"--processes {processes}: several processes solve by PETSc's Krylov method; "
              f"solver.linear must be krylov or auto, got {case.solver.linear}", 2)
    if steps < 2:
        _fail(f"--steps must be >= 2, got {steps}", 2)
    if largest < 1 or largest > 256 or largest & (largest - 1):
        _fail(f"--largest must be a power of two from 1 to 256, got {largest}", 2)
    if smallest < 1 or smallest > largest or smallest & (smallest - 1):
        _fail(f"--smallest must be a power of two from 1 to --largest = {largest}, got "
              f"{smallest}", 2)
    if time_limit is not None and not time_limit > 0:
        _fail(f"--time-limit must be > 0 s, got {time_limit:g}", 2)
    if memory_limit is not None and not memory_limit >= 0.5:
        _fail(f"--memory-limit must be >= 0.5 GiB, got {memory_limit:g}", 2)
    outdir = _study_outdir(output, Path("results") / "bench-scaling" / case.name, overwrite)
    from masonry_nscd.studies import bench as bm

    try:
        rows, statements = bm.bench_scaling(case_file, outdir, overrides=list(overrides or ()),
                                            steps=steps, largest=largest, smallest=smallest,
                                            time_limit_s=time_limit,
                                            memory_limit_gib=memory_limit, processes=counts,
                                            echo=typer.echo)
    except KeyboardInterrupt:
        _fail("interrupted", 130)
    typer.echo(bm.format_scaling_table(rows))
    for line in statements:
        typer.echo(line)
    typer.echo(f"wrote {outdir / 'scaling.csv'} and {outdir / 'scaling.png'}")
    if any(r.status != "ok" for r in rows):
        _fail("some walls did not finish their steps (see the status column)", 1)


def _fail_list(what: str, messages: list[str], code: int) -> None:
    """``_fail`` with one problem per line."""
    if len(messages) == 1:
        _fail(f"{what}: {messages[0]}", code)
    lines = "\n".join(f"  - {m}" for m in messages)
    _fail(f"{what} ({len(messages)} problems):\n{lines}", code)


WorkersOption = Annotated[int | None, typer.Option(
    "--workers", metavar="N", min=1,
    help="Local worker processes, one thread each (default: the number of cores).")]
SchedulerOption = Annotated[str | None, typer.Option(
    "--scheduler", metavar="ADDRESS",
    help="Submit the runs to the Dask scheduler at ADDRESS (e.g. tcp://host:8786) instead of "
    "local processes; OUTDIR must be on a file system the workers share.")]


@app.command("check-cases")
def check_cases_cmd(
    case_files: Annotated[list[Path] | None, typer.Argument(
        metavar="[CASE.yaml]...", help="The cases (default: every cases/*.yaml).")] = None,
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Folder of check.csv and the runs (default results/check-cases/).")] = None,
    rtol: Annotated[float, typer.Option(
        "--rtol", metavar="R", help="Largest change of a curve's column against the record, "
        "relative to the column's largest magnitude.")] = 1e-3,
    write_record: Annotated[bool, typer.Option(
        "--write-record", help="Write the records from these runs instead of checking them "
        "(refused for a run with unconverged steps).")] = False,
    record: Annotated[Path | None, typer.Option(
        "--record", metavar="DIR", help="Folder of the records (default cases/record/).")
    ] = None,
    overrides: SetOption = None,
    overwrite: OverwriteOption = False,
) -> None:
    """Run every shipped case to its end and compare it with its record.

    Each case runs in a fresh process without field outputs; it passes when every step
    converged and the curve is within --rtol of the record; the run time is shown beside the
    record's. Writes OUTDIR/check.csv; exit 1 if a case failed, did not converge, changed or
    has no record."""
    from masonry_nscd.studies import check_cases as cc

    if not rtol > 0.0:
        _fail(f"--rtol must be > 0, got {rtol}", 2)
    cases = list(case_files) if case_files else cc.shipped_cases()
    missing = [str(c) for c in cases if not c.is_file()]
    if missing:
        _fail("no such case file: " + ", ".join(missing), 2)
    outdir = _study_outdir(output, Path("results") / "check-cases", overwrite)
    try:
        rows = cc.check_cases(cases, outdir, record_dir=record or cc.RECORD_DIR, rtol=rtol,
                              write=write_record, overrides=list(overrides or ()),
                              echo=typer.echo)
    except KeyboardInterrupt:
        _fail(f"interrupted; the cases done so far are in {outdir / 'check.csv'}", 130)
    typer.echo(f"wrote {outdir / 'check.csv'}")
    bad = cc.failing(rows)
    if bad:
        _fail(f"{len(bad)} of {len(rows)} cases did not pass: "
              + ", ".join(f"{r.case} ({r.status})" for r in bad), 1)


@app.command("sweep")
def sweep_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    sets: Annotated[list[str], typer.Option(
        "--set", metavar="PATH=V1,V2,...",
        help="Values of one field, each read as YAML (repeatable: the runs are the cartesian "
        "product; a single value is a fixed override of every run).")],
    output: Annotated[Path | None, typer.Option(
        "-o", "--output", metavar="OUTDIR",
        help="Sweep folder (default results/\\<case name>_sweep/).")] = None,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Run a case for every combination of the --set values, locally or on a Dask cluster.

    Writes OUTDIR/sweep.csv and OUTDIR/force_displacement.png.

    Each run has its folder in OUTDIR/runs; running the same sweep again keeps the finished
    runs. Exit 0 when every run finished, 1 when some did not (status column of sweep.csv).
    """
    case = _load_case_or_exit(case_file)
    if workers is not None and scheduler:
        _fail("--workers is for local processes; with --scheduler the cluster has its workers", 2)
    from masonry_nscd.studies.sweep import SweepError, run_sweep

    outdir = output or Path("results") / f"{case.name}_sweep"
    try:
        result = run_sweep(case_file, sets, outdir, workers=workers, scheduler=scheduler,
                           echo=typer.echo)
    except SweepError as exc:
        _fail_list("cannot start the sweep", exc.messages, 2)
    except KeyboardInterrupt:
        _fail(f"interrupted; the runs done so far are in {outdir / 'sweep.csv'} (the same "
              "command finishes the sweep)", 130)
    typer.echo(f"wrote {result.table}" + (f" and {result.plot}" if result.plot else ""))
    if result.failed:
        _fail(f"{len(result.failed)} of {len(result.records)} runs did not finish: "
              + ", ".join(f"{r.name} ({r.status})" for r in result.failed), 1)


@app.command("campaign")
def campaign_cmd(
    tests: Annotated[Path, typer.Argument(metavar="TESTS.csv",
                                          help="Table of tested walls (stone_walls/tests.csv).")],
    template: Annotated[Path, typer.Option(
        "--template", metavar="CASE.yaml",
        help="Case whose mesh, solver and outputs every test's run takes.")],
    output: Annotated[Path, typer.Option("-o", "--output", metavar="OUTDIR",
                                         help="Campaign folder.")],
    only: Annotated[str | None, typer.Option(
        "--only", metavar="TEST,...", help="Run these tests only (names of the test column).")
    ] = None,
    dry_run: Annotated[bool, typer.Option(
        "--dry-run", help="Write and validate the cases only.")] = False,
    workers: WorkersOption = None,
    cyclic: Annotated[bool, typer.Option(
        "--cyclic", help="Cyclic tests run reversed cycles (0.25, 0.5, 1 times the push's "
        "target), with the energy of the last cycle against the measured.")] = False,
    overrides: Annotated[list[str] | None, typer.Option(
        "--set", metavar="PATH=VALUE",
        help="Override one field of the template for every test (VALUE read as YAML; "
        "repeatable); the fields a test's row sets stay the row's.")] = None,
) -> None:
    """Predict tested walls from their material tests: one run per row, monotonic (or cyclic
    for cyclic tests with --cyclic).

    Writes OUTDIR/cases/TEST.yaml, OUTDIR/campaign.csv (predicted against measured peak, drift
    at the peak, initial stiffness, failure class, errors), OUTDIR/campaign_stats.json,
    OUTDIR/peaks.png and OUTDIR/curves/TEST.png (docs/campaign.md). Exit 1 when a run did not
    finish.
    """
    _load_case_or_exit(template, overrides)
    from masonry_nscd.studies.campaign import SweepError, run_campaign

    names = [n.strip() for n in only.split(",") if n.strip()] if only else []
    try:
        result = run_campaign(tests, template, output, only=names, dry_run=dry_run,
                              workers=workers, cyclic=cyclic, overrides=overrides or (),
                              echo=typer.echo)
    except SweepError as exc:
        _fail_list("cannot start the campaign", exc.messages, 2)
    except OSError as exc:
        _fail(f"cannot read or write: {exc}", 2)
    except KeyboardInterrupt:
        _fail(f"interrupted; running the same command again keeps the finished runs in "
              f"{output}", 130)
    typer.echo(f"wrote {result.table}")
    if not dry_run:
        peak = result.stats.get("peak", {})
        if peak.get("count"):
            typer.echo(f"peak: median absolute error {100 * peak['median_abs_error']:.1f} %, "
                       f"{peak['within']} of {peak['count']} within 15 %")
        bad = [r["test"] for r in result.rows if r.get("status") != "ok"]
        if bad:
            _fail(f"{len(bad)} of {len(result.rows)} runs did not finish: {', '.join(bad)}", 1)


@app.command("sensitivity")
def sensitivity_cmd(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    params: Annotated[list[str], typer.Option(
        "--param", metavar="PATH=LOW:HIGH",
        help="A numeric field and its range, SI units (repeatable).")],
    samples: Annotated[int, typer.Option(
        "--samples", metavar="N",
        help="Morris: trajectories, N (D + 1) runs; Sobol: base samples, a power of 2, "
        "N (D + 2) runs (D parameters).")],
    method: Annotated[str, typer.Option("--method", metavar="morris|sobol",
                                        help="Elementary effects or variance-based indices.")
                      ] = "morris",
    output_key: Annotated[str, typer.Option(
        "--output", metavar="KEY",
        help="Output analysed: peak_force_kN, initial_stiffness_kN_mm, force_at_target_kN or "
        "ux_at_peak_mm.")] = "peak_force_kN",
    outdir: Annotated[Path | None, typer.Option(
        "-o", "--outdir", metavar="OUTDIR",
        help="Study folder (default results/\\<case name>_\\<method>/).")] = None,
    overrides: SetOption = None,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the sampling and bootstrap.")
                    ] = 0,
    workers: WorkersOption = None,
    scheduler: SchedulerOption = None,
) -> None:
    """Sensitivity indices of one output of the run to some parameters of the case (SALib).

    Writes OUTDIR/samples.csv, OUTDIR/indices.csv and OUTDIR/indices.png.

    Every sample is a run (folders in OUTDIR/runs, kept when the same command runs again).
    The analysis needs every run: if some failed or have no value, they are listed and the
    command exits with 1 without indices.
    """
    case = _load_case_or_exit(case_file, overrides)
    if workers is not None and scheduler:
        _fail("--workers is for local processes; with --scheduler the cluster has its workers", 2)
    from masonry_nscd.studies import sensitivity as sa
    from masonry_nscd.studies.batch import SweepError

    outdir = outdir or Path("results") / f"{case.name}_{method}"
    try:
        result = sa.run_sensitivity(case_file, params, method, samples, output_key, outdir,
                                    fixed_sets=list(overrides or ()), workers=workers,
                                    scheduler=scheduler, seed=seed, echo=typer.echo)
    except SweepError as exc:
        _fail_list("cannot start the sensitivity study", exc.messages, 2)
    except KeyboardInterrupt:
        _fail(f"interrupted; the runs done so far are in {outdir / sa.SAMPLES_FILE} (the same "
              "command finishes them)", 130)
    if result.indices is None:
        _fail(f"no analysis: {len(result.missing)} of {len(result.records)} runs have no "
              f"{output_key} ({sa.describe_missing(result.missing)}); "
              f"{method} needs every run of its design (see {result.samples_table}; narrow "
              "the ranges or fix the cause, then run the same command again)", 1)
    for line in sa.format_indices(method, result.indices):
        typer.echo(line)
    typer.echo(f"wrote {result.samples_table}, {result.indices_csv} and {result.chart}")


def main() -> None:
    """The ``masonry`` console script: the app; ``masonry run`` then leaves by ``os._exit`` with
    its exit code once its output is flushed (its files are closed by then), skipping the
    interpreter's teardown of numba, LLVM and scipy, which costs every run time for nothing
    (docs/performance.md). Other commands (a sweep's cluster, say) end as Python
    ends them, and so does every process of a run under mpiexec, once process 0 has stopped
    the others (mpiexec loses the exit code of an ``os._exit`` after MPI's end)."""
    import os
    import sys

    try:
        app()
    except SystemExit as exc:
        code = 0 if exc.code is None else exc.code
        from masonry_nscd.nscd import mpi

        if mpi.launched_processes() > 1:
            mpi.shutdown()
            raise
        if sys.argv[1:2] != ["run"] or not isinstance(code, int):
            raise
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    main()
