"""The per-point kernels on several threads (``masonry_nscd/threads.py``).

* ``ranges``: the ranges cover ``[0, n)`` once, in order, at most one per thread, none shorter
  than the minimum, of sizes differing by at most one.
* a point's law and a Gauss point's update touch nothing but their own point, so a run on
  three threads is the run on one bit for bit: the smoke wall with ENDO3D blocks (the joint
  law, the ENDO3D trial by elements and its tangent all split), the ranges made short enough
  that every kernel is split.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from masonry_nscd import threads
from masonry_nscd.case import load_case
from masonry_nscd.scenes import build_scene


@pytest.fixture(autouse=True)
def _restore_threads():
    yield
    threads.set_count(None)


def _check_cover(parts, n):
    assert parts[0][0] == 0 and parts[-1][1] == n
    for (_, hi), (lo, _) in itertools.pairwise(parts):
        assert hi == lo
    assert all(hi > lo for lo, hi in parts)


@pytest.mark.parametrize("n", [0, 1, 255, 511, 512, 1000, 1160, 10_001])
@pytest.mark.parametrize("k", [1, 2, 3, 8])
def test_ranges_cover_the_batch_once(n, k):
    parts = threads.ranges(n, k)
    if n == 0:
        assert parts == [(0, 0)]
        return
    _check_cover(parts, n)
    assert len(parts) <= k
    if len(parts) > 1:
        assert min(hi - lo for lo, hi in parts) >= threads.MIN_POINTS
        sizes = [hi - lo for lo, hi in parts]
        assert max(sizes) - min(sizes) <= 1
    # as many ranges as the threads allow while each keeps its minimum
    assert len(parts) == max(1, min(k, n // threads.MIN_POINTS))


def test_set_count_is_checked_and_used():
    with pytest.raises(ValueError, match="at least 1"):
        threads.set_count(0)
    threads.set_count(3)
    assert threads.count() == 3
    seen = []
    out = threads.run_ranges(lambda lo, hi: seen.append((lo, hi)) or hi - lo, 3000)
    assert sorted(seen) == threads.ranges(3000) and sum(out) == 3000 and len(out) == 3


def test_batches_run_together_as_they_would_alone():
    """Two batches in one hand-over: each kernel sees its own ranges once (a batch too small
    to split stays whole, on the calling thread), the results come back per batch in the
    order of its ranges, and ``meanwhile`` runs on the calling thread before the wait."""
    import threading

    threads.set_count(3)
    seen = {"a": [], "b": []}
    where = []

    def kernel(name):
        def run(lo, hi):
            seen[name].append((lo, hi, threading.get_ident()))
            return (name, lo, hi)
        return run

    out = threads.run_together([(kernel("a"), 3000, None), (kernel("b"), 100, None)],
                               meanwhile=lambda: where.append(threading.get_ident()))
    assert out[0] == [("a", lo, hi) for lo, hi in threads.ranges(3000)]
    assert out[1] == [("b", 0, 100)]  # under MIN_POINTS: one range
    assert where == [threading.get_ident()]
    assert sorted(x[:2] for x in seen["a"]) == threads.ranges(3000)
    first = [t for lo, _, t in seen["a"] if lo == 0]
    assert first == [threading.get_ident()] == [seen["b"][0][2]]
    # one batch alone is run_ranges
    assert threads.run_together([(kernel("a"), 3000, None)])[0] == \
        threads.run_ranges(kernel("a"), 3000)


def test_the_count_follows_numba_num_threads(monkeypatch):
    monkeypatch.setenv("NUMBA_NUM_THREADS", "5")
    assert threads.count() == 5
    monkeypatch.setenv("NUMBA_NUM_THREADS", "")
    assert threads.count() >= 1


def test_an_endo3d_run_on_three_threads_is_the_run_on_one(monkeypatch):
    monkeypatch.setattr(threads, "MIN_POINTS", 8)  # every kernel of the smoke wall split
    # PARDISO on one thread whatever the kernels' count: its factorisations on several threads
    # agree to round-off only (nscd/pardiso.py); the kernels must agree bit for bit
    monkeypatch.setenv("MKL_NUM_THREADS", "1")
    sets = ["output.vtu=false", "output.hdf5=false", "output.energy=false",
            "blocks.material=endo3d", "wall.elements_per_unit=[2, 1, 1]"]
    out = {}
    for k in (1, 3):
        threads.set_count(k)
        integ = build_scene(load_case("cases/smoke.yaml", sets)).integrator()
        assert len(threads.ranges(len(integ.sys.area))) == k  # the joint law split
        nel = integ.material.nel  # and the ENDO3D trial, by elements
        assert len(threads.ranges(nel, min_size=threads.MIN_POINTS // 8)) == k
        T, its = [], 0
        for _ in range(80):
            rep = integ.step()
            its += rep.sweeps
            T.append(integ.joints.T.copy())
        # the tangent kernel on the threads, at the last trial (the run may not have needed it)
        K = integ.material.tangent_stiffness()
        out[k] = np.array(T), its, integ.material.state_all.copy(), integ.tangent_updates, K
    (T1, it1, st1, tu1, K1), (T3, it3, st3, tu3, K3) = out[1], out[3]
    assert tu1 == tu3
    assert it3 == it1
    assert np.array_equal(T3, T1) and np.array_equal(st3, st1)
    assert all(np.array_equal(a, b) for a, b in zip(K1, K3)) and np.abs(K1[0]).max() > 0
    assert np.abs(T1).max() > 0


def test_the_cli_takes_the_thread_count(tmp_path):
    from typer.testing import CliRunner

    from masonry_nscd.cli import app

    runner = CliRunner()
    base = ["run", "cases/smoke.yaml", "-o", str(tmp_path / "r"), "--set", "output.vtu=false",
            "--set", "output.hdf5=false", "--set", "loading.horizontal.target_m=1e-5"]
    bad = runner.invoke(app, [*base, "--threads", "0"])
    assert bad.exit_code == 2 and "--threads" in bad.output
    ok = runner.invoke(app, [*base, "--threads", "1"])
    assert ok.exit_code == 0, ok.output
    assert "kernels on 1 thread(s)" in (tmp_path / "r" / "run.log").read_text()
