"""Reproducible arithmetic (``arithmetic.py``): the libraries pinned as ``masonry_nscd`` loads,
and a run that gives the same bits on one thread or two and whatever code path MKL would pick
for the processor."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from masonry_nscd.nscd import pardiso

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, **env: str) -> str:
    """What ``code`` prints in a fresh interpreter with ``env`` added to this environment
    (less the variables the pins set, so that the fresh process sets them itself)."""
    base = {k: v for k, v in os.environ.items()
            if k not in ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "MASONRY_ARITHMETIC")}
    out = subprocess.run([sys.executable, "-c", code], env={**base, **env}, cwd=ROOT,
                         capture_output=True, text=True, check=True)
    return out.stdout


DESCRIBE = ("import json, masonry_nscd, numpy, scipy.linalg\n"
            "from masonry_nscd import arithmetic\n"
            "from masonry_nscd.nscd import pardiso\n"
            "pardiso.available()\n"
            "print(json.dumps(arithmetic.describe()))")


def test_importing_the_package_pins_openblas_and_mkl():
    a = json.loads(_python(DESCRIBE))
    assert a["openblas_kernels"] == "Nehalem" and a["openblas_threads"] == "1"
    assert a["mkl"] == ("CNR branch COMPATIBLE" if pardiso.available() else "not loaded")
    assert a["reproducible"] == "bitwise"


def test_native_arithmetic_and_a_late_import_are_said_to_be_unpinned():
    a = json.loads(_python(DESCRIBE, MASONRY_ARITHMETIC="native"))
    assert a["reproducible"].startswith("no: native")
    late = json.loads(_python("import numpy\n" + DESCRIBE))
    assert "numpy was imported before masonry_nscd" in late["reproducible"]


def _curve(tmp_path: Path, name: str, *args: str, **env: str) -> bytes:
    """The bytes of ``force_displacement.csv`` of the study's ENDO3D wall pushed to 0.1 mm,
    run in a fresh process."""
    out = tmp_path / name
    code = ("from masonry_nscd.cli import main; import sys; sys.argv = ['masonry', 'run', "
            "'cases/wall_0.5MPa.yaml', '-o', " + repr(str(out)) + ", '--set', "
            "'loading.horizontal.target_m=0.1e-3', '--set', 'output.vtu=false', '--set', "
            "'output.hdf5=false', " + ", ".join(repr(a) for a in args) + "]; main()")
    _python(code, **env)
    return (out / "force_displacement.csv").read_bytes()


@pytest.mark.skipif(not pardiso.available(), reason="MKL (PARDISO) is not installed")
def test_a_run_gives_the_same_bits_on_one_thread_or_two_and_on_any_mkl_code_path(tmp_path):
    """The ENDO3D wall's factorisations are split between two OpenMP threads when there are
    two; in MKL's default mode that changed the last bits of every step. With MKL held to
    SSE4.2 (as on an older processor), on one thread: the same bytes."""
    two = _curve(tmp_path, "two", "--threads", "2")
    one = _curve(tmp_path, "one", "--threads", "1", MKL_ENABLE_INSTRUCTIONS="SSE4_2")
    assert one == two
