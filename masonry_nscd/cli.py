"""Command-line interface: parse, call, report. Nothing else lives here.

Heavy modules (numpy, numba kernels, h5py, meshio) are imported inside the commands so that
``masonry --help`` answers at once. Exit codes: 0 done, 1 the computation failed (solver not
converged, divergence), 2 invalid input (bad case file, bad option).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="masonry_nscd: masonry walls block by block with Non-Smooth Contact Dynamics.",
)
point_app = typer.Typer(
    no_args_is_help=True,
    help="Material-point drivers: one joint point or one block element along a loading path.",
)
app.add_typer(point_app, name="point")


def _fail(message: str, code: int) -> None:
    """Print a one-paragraph error on stderr and leave with ``code``."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(code)


def _load_case_or_exit(path: Path | str, overrides: list[str] | None = None):  # -> Case
    """Load and validate a case file with its ``--set`` overrides, or leave with code 2.

    Every message of the :class:`~masonry_nscd.case.CaseError` goes to stderr, one per line.
    Returns the :class:`~masonry_nscd.case.Case`.
    """
    from masonry_nscd.case import CaseError, load_case

    try:
        return load_case(path, list(overrides or ()))
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

    w, loading = case.wall, case.loading
    summary = (
        f"{case.name}: {w.units_per_course} units per course x {w.courses} courses "
        f"({w.bond} bond, {w.wall_length_m:.3f} x {w.wall_height_m:.3f} m), "
        f"blocks {case.blocks.material}, joints {case.joint.law}, "
        f"sigma_N = {loading.vertical_stress.value_Pa / 1e6:g} MPa "
        f"({case.vertical_force_N / 1e3:g} kN), U_x to {loading.horizontal.target_m * 1e3:g} mm, "
        f"about {case.step_count} steps of {case.solver.time_step_s:g} s"
    )
    if print_case:
        typer.echo(f"# {summary}\n{case_to_yaml(case)}", nl=False)
    else:
        typer.echo(f"ok {summary}")


SetOption = Annotated[
    list[str] | None,
    typer.Option("--set", metavar="PATH=VALUE",
                 help="Override one field of the case (VALUE read as YAML; repeatable)."),
]


@app.command()
def run(
    case_file: Annotated[Path, typer.Argument(metavar="CASE.yaml", help="The case file (YAML).")],
    output: Annotated[Path | None, typer.Option("-o", "--output",
                      help="Run folder (default results/<case name>/).")] = None,
    overrides: SetOption = None,
    overwrite: Annotated[bool, typer.Option("--overwrite",
                         help="Write into a run folder that is not empty.")] = False,
) -> None:
    """Run a wall case to its target displacement and write CSV, HDF5 and VTU results."""
    case = _load_case_or_exit(case_file, overrides)
    from masonry_nscd.run import RunFailure, RunInputError, run_case

    outdir = output or Path("results") / case.name
    import signal

    def _terminate(signum, frame):  # SIGTERM ends the run like Ctrl-C: outputs are kept
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _terminate)
    try:
        res = run_case(case, outdir, overwrite=overwrite, echo=typer.echo)
    except RunInputError as exc:
        _fail(str(exc), 2)
    except RunFailure as exc:
        _fail(f"the solver failed: {exc} (results up to the last output step are kept in "
              f"{outdir})", 1)
    except KeyboardInterrupt:
        _fail(f"interrupted; results up to the last output step are kept in {outdir}", 130)
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
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
    from masonry_nscd.scenes.wall import joint_params_from_case

    try:
        curve = drive_joint_point(joint_params_from_case(case), path, to, steps=steps,
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


if __name__ == "__main__":  # pragma: no cover
    app()
