"""Command-line interface: parse, call, report. Nothing else lives here.

Heavy modules (numpy, numba kernels, h5py, meshio) are imported inside the commands so that
``masonry --help`` answers at once. Exit codes: 0 done, 1 the computation failed (solver not
converged, divergence), 2 invalid input (bad case file, bad option).
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

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


def _load_case_or_exit(path: Path | str, overrides: Optional[List[str]] = None):  # -> Case
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
    case_file: Path = typer.Argument(..., metavar="CASE.yaml", help="The case file (YAML)."),
    overrides: Optional[List[str]] = typer.Option(
        None,
        "--set",
        metavar="PATH=VALUE",
        help="Override one field, e.g. --set joint.mu=0.5 or --set wall.elements_per_unit=[1,1,1]"
        " (VALUE is read as YAML; repeatable).",
    ),
    print_case: bool = typer.Option(
        False, "--print", help="Write the full case, every default filled in, as YAML."
    ),
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


if __name__ == "__main__":  # pragma: no cover
    app()
