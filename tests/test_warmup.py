"""A first run compiles the solver's kernels on two processes (masonry_nscd/warmup.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from masonry_nscd import warmup
from masonry_nscd.case import load_case

ROOT = Path(__file__).resolve().parent.parent
SMOKE = ROOT / "cases" / "smoke.yaml"


def _entries(path: Path) -> set[str]:
    return {line for line in path.read_text().splitlines() if line and not line.startswith("#")}


def test_the_listed_types_are_those_the_study_walls_call(tmp_path):
    """Two short runs (elastic and ENDO3D blocks) in a fresh process call every listed kernel
    with the listed types and no others: a stale list would have the second process compile
    kernels no run loads (run ``python -m masonry_nscd.warmup --record`` after changing a
    kernel's arguments)."""
    out = tmp_path / "signatures.txt"
    subprocess.run([sys.executable, "-m", "masonry_nscd.warmup", "--record", str(out)],
                   check=True, cwd=ROOT, timeout=600)
    assert _entries(out) == _entries(warmup.SIGNATURES)
    listed = warmup.read_signatures()
    assert set(listed) == {name for group in warmup.GROUPS.values() for name in group}


def test_the_groups_follow_the_case():
    assert warmup.groups_for(load_case(SMOKE)) == (("joints",), ("newton",))
    endo = load_case(ROOT / "cases" / "wall_0.5MPa.yaml")
    assert warmup.groups_for(endo) == (("joints", "newton"), ("endo3d",))
    rigid = load_case(SMOKE, ["blocks.material=rigid", "joint.law=coulomb"])
    assert rigid.contact_solver == "nlgs" and warmup.groups_for(rigid) == ((), ())
    assert warmup.main(["no-such-group"]) == 2


def _masonry_run(env: dict, out: Path) -> str:
    done = subprocess.run([sys.executable, "-m", "masonry_nscd.cli", "run", str(SMOKE),
                           "--output", str(out), "--overwrite", "--set", "output.vtu=false"],
                          check=False, cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_a_first_run_compiles_on_two_processes_and_the_next_does_not(tmp_path):
    """With an empty cache folder the run says it compiles the kernels of its two groups,
    leaves their markers, and gives the curve of a run whose kernels compiled at their calls
    (``MASONRY_WARMUP=0``, another empty folder); the next run starts at once."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), MASONRY_WARMUP="1")
    first = _masonry_run(env, tmp_path / "first")
    assert "compiling the solver's kernels on two processes (joints, newton)" in first
    assert "kernels compiled in" in first
    assert {p.name for p in (tmp_path / "cache").glob("warm-*")} == {"warm-joints",
                                                                    "warm-newton"}
    again = _masonry_run(env, tmp_path / "again")
    assert "compiling" not in again
    plain = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "plain"), MASONRY_WARMUP="0")
    assert "compiling" not in _masonry_run(plain, tmp_path / "plain_run")
    curve = "force_displacement.csv"
    assert (tmp_path / "first" / curve).read_bytes() == (tmp_path / "plain_run" / curve) \
        .read_bytes()


def test_a_group_left_alone_compiles_in_the_run_process(tmp_path):
    """When only the second process's group is missing (here the Newton kernels, the joint
    law's marker already there), the run compiles it itself rather than wait for a helper."""
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / "warm-joints").touch()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache), MASONRY_WARMUP="1")
    out = _masonry_run(env, tmp_path / "run")
    assert "compiling the solver's kernels (newton)" in out
    assert "two processes" not in out
    assert (cache / "warm-newton").exists()
