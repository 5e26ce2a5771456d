"""A first run's kernel compilation, on two processes.

numba compiles a kernel the first time it is called and keeps it in the on-disk cache (one
folder per version of the kernel modules, ``masonry_nscd/__init__.py``). A first run with an
empty cache therefore compiles the solver's kernels one after the other at their first calls,
on one core: the joint law and its tangent, the Newton matrix and the residual's products,
and for ENDO3D blocks the material's trial, by far the largest. :func:`compile_first_run`
splits that work: a second process (``python -m masonry_nscd.warmup GROUP...``) compiles one
group of kernels while this process compiles the other, each for the argument types the run
calls it with, and the run then finds every kernel in the cache. A group keeps together the
kernels that share compiled callees (the joint law's solution and its tangent; the ENDO3D
trial and its tangent), so that neither process compiles what the other does.

The argument types are listed in ``kernel_signatures.txt``, one line per kernel and call:
the kernel's module and name, then the tuple of numba types (their ``repr``). ``python -m
masonry_nscd.warmup --record`` writes the file from two short runs of the study's wall, one
with elastic and one with ENDO3D blocks; ``tests/test_warmup.py`` records them again in a fresh
process and fails when the file differs. A kernel called with other types compiles at its
call, as without this module; a listed signature that no longer compiles is skipped.

A group compiled once leaves a marker in the cache folder (``warm-<group>``), so that later
runs, and runs of cases that need no other group, start at once; ``masonry cache-clear`` and
any edit of a kernel module (a new cache folder) start over.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from masonry_nscd.case import load_case
from masonry_nscd.run import run_case

SIGNATURES = Path(__file__).resolve().parent / "kernel_signatures.txt"

#: The kernels of each group, in the order a run first calls them.
GROUPS: dict[str, tuple[str, ...]] = {
    # the joint law: its solution and its tangent share the law's compiled functions
    "joints": ("masonry_nscd.contact.laws.solve_points",
               "masonry_nscd.contact.laws.tangent_points"),
    # the residual's products and the Newton matrix
    "newton": ("masonry_nscd.nscd.kernels.local_velocities",
               "masonry_nscd.nscd.step_residual.evaluate_multipliers",
               "masonry_nscd.nscd.step_residual.subtract_impulses",
               "masonry_nscd.nscd.step_residual.momentum_rows",
               "masonry_nscd.nscd.step_residual.traction_change",
               "masonry_nscd.nscd.step_residual.change_norm",
               "masonry_nscd.nscd.newton._jacobian_entries"),
    # the ENDO3D blocks: the trial and its tangent share the material's update
    "endo3d": ("masonry_nscd.fe.element.forces_from_gradients",
               "masonry_nscd.materials.blocks.trial_forces",
               "masonry_nscd.materials.blocks.gather_element_vectors",
               "masonry_nscd.materials.endo3d.endo3d_tangent_elements",
               "masonry_nscd.fe.element.stiffness_from_gradients"),
}

#: Seconds a run waits for the second process before it goes on without it.
WAIT_S = 300.0


def groups_for(case) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The groups a run of ``case`` compiles here and in the second process, the larger
    second: the ENDO3D group (about twice the other two together) alone against the rest, else
    the joint law against the Newton kernels. Nothing for a case the Gauss-Seidel solver runs
    (its kernels compile at their calls)."""
    if case.contact_solver != "newton":
        return (), ()
    if case.blocks.material == "endo3d":
        return ("joints", "newton"), ("endo3d",)
    return ("joints",), ("newton",)


def read_signatures(path: Path = SIGNATURES) -> dict[str, list[str]]:
    """``{kernel: [types, ...]}`` from ``path`` (the types as ``repr`` strings)."""
    out: dict[str, list[str]] = {}
    for line in path.read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, types = line.split(" ", 1)
            out.setdefault(name, []).append(types.strip())
    return out


def kernel(name: str):
    """The numba dispatcher ``module.function``."""
    module, function = name.rsplit(".", 1)
    return getattr(importlib.import_module(module), function)


def compile_groups(groups: Sequence[str], signatures: dict[str, list[str]] | None = None) -> int:
    """Compile (or load from the cache) every kernel of ``groups`` for its listed types;
    returns how many signatures did not compile (skipped)."""
    from numba.core import types

    names = vars(types)
    signatures = read_signatures() if signatures is None else signatures
    skipped = 0
    for group in groups:
        for name in GROUPS[group]:
            for sig in signatures.get(name, ()):
                try:
                    kernel(name).compile(eval(sig, dict(names)))  # the file's repr strings
                except Exception:  # noqa: BLE001 (any failure to compile one: left to its call)
                    skipped += 1
    return skipped


def _cache_dir() -> Path | None:
    folder = os.environ.get("NUMBA_CACHE_DIR")
    return Path(folder) if folder else None


def _marker(group: str) -> Path | None:
    folder = _cache_dir()
    return None if folder is None else folder / f"warm-{group}"


def compile_first_run(case, echo: Callable[[str], None] = print) -> float:
    """Compile the kernels a run of ``case`` needs on two processes, if some are not in the
    cache yet (module docstring); returns the seconds it took (0 when nothing was to do).
    Set ``MASONRY_WARMUP=0`` to leave every kernel to compile at its first call."""
    here, there = groups_for(case)
    markers = {g: _marker(g) for g in (*here, *there)}
    todo = [g for g, m in markers.items() if m is not None and not m.exists()]
    if not todo or os.environ.get("MASONRY_WARMUP", "1") == "0":
        return 0.0
    t0 = time.perf_counter()
    mine, others = [g for g in here if g in todo], [g for g in there if g in todo]
    if not mine:  # this process would only wait (e.g. the ENDO3D group after an elastic run)
        mine, others = others, []
    echo("first run with these sources: compiling the solver's kernels"
         + (" on two processes" if others else "") + f" ({', '.join(todo)})")
    helper = None
    if others:
        try:
            helper = subprocess.Popen([sys.executable, "-m", "masonry_nscd.warmup", *others],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        except OSError:  # no second process: those kernels compile at their calls
            others = []
    done = list(mine)
    try:
        compile_groups(mine)
        if helper is not None:
            helper.wait(timeout=WAIT_S)
            if helper.returncode == 0:
                done += others
    except BaseException as exc:  # a stop request, or the helper too slow: it goes
        if helper is not None and helper.poll() is None:
            helper.kill()
            helper.wait()
        if not isinstance(exc, subprocess.TimeoutExpired):
            raise
    with contextlib.suppress(OSError):  # a cache folder we may not write: no markers
        for g in done:
            markers[g].parent.mkdir(parents=True, exist_ok=True)
            markers[g].touch()
    secs = time.perf_counter() - t0
    echo(f"kernels compiled in {secs:.1f} s (kept in {_cache_dir()})")
    return secs


def record(path: Path = SIGNATURES) -> dict[str, list[str]]:
    """The types each listed kernel is called with in two short runs of the study's wall
    (elastic blocks, then ENDO3D blocks; no files kept), written to ``path``."""
    import tempfile

    cases = Path(__file__).resolve().parent.parent / "cases"
    short = ["loading.horizontal.target_m=0.00002", "output.vtu=false", "output.hdf5=false"]
    with tempfile.TemporaryDirectory() as tmp:
        for name in ("wall_0.5MPa_elastic.yaml", "wall_0.5MPa.yaml"):
            run_case(load_case(cases / name, short), Path(tmp) / name, echo=lambda m: None)
    used = {name: sorted(repr(tuple(sig)) for sig in kernel(name).signatures)
            for group in GROUPS.values() for name in group}
    lines = ["# argument types of the kernels a first run compiles on two processes",
             "# (masonry_nscd/warmup.py; written by python -m masonry_nscd.warmup --record)"]
    lines += [f"{name} {sig}" for name, sigs in sorted(used.items()) for sig in sigs]
    path.write_text("\n".join(lines) + "\n")
    return used


def main(argv: Sequence[str]) -> int:
    """``python -m masonry_nscd.warmup GROUP...`` compiles the groups (the second process of
    :func:`compile_first_run`); ``--record [PATH]`` writes ``kernel_signatures.txt`` (or
    ``PATH``)."""
    if argv and argv[0] == "--record" and len(argv) <= 2:
        record(Path(argv[1]) if len(argv) == 2 else SIGNATURES)
        return 0
    unknown = [g for g in argv if g not in GROUPS]
    if unknown:
        print(f"unknown group(s) {unknown}: {sorted(GROUPS)}", file=sys.stderr)
        return 2
    compile_groups(argv)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
