"""Where a run's time goes (``masonry_nscd.timing``): the timers count every call and its
duration, the solver's parts are timed once per call, and ``run.log`` reports them."""

from __future__ import annotations

import re
import time

from masonry_nscd import timing
from masonry_nscd.case import load_case
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

SMOKE = "cases/smoke.yaml"
QUIET = ["output.vtu=false", "output.hdf5=false", "output.energy=false"]


def test_a_timer_counts_calls_and_their_durations():
    timing.reset()
    for pause in (0.01, 0.02, 0.03):
        with timing.part("sleep"):
            time.sleep(pause)
    with timing.part("short"):
        pass
    rows = {r.name: r for r in timing.table()}
    assert rows["sleep"].calls == 3 and rows["short"].calls == 1
    # a sleep lasts at least what it was asked for
    assert rows["sleep"].total_s >= 0.06 and rows["sleep"].median_ms >= 20.0
    assert [r.name for r in timing.table()] == ["sleep", "short"]  # the longest first
    timing.record("short", 0.5)  # a call timed by the caller
    rows = {r.name: r for r in timing.table()}
    assert rows["short"].calls == 2 and rows["short"].total_s >= 0.5
    assert [r.name for r in timing.table()] == ["short", "sleep"]
    timing.reset()
    assert timing.table() == []


def test_the_solver_parts_are_timed_once_per_call():
    """Over a few steps of the smoke wall: one factorisation timed per factorisation the
    solver counts, and at least one joint-law evaluation per Newton iteration."""
    integ = build_scene(load_case(SMOKE, QUIET)).integrator()
    timing.reset()
    iterations = sum(integ.step().sweeps for _ in range(5))
    rows = {r.name: r for r in timing.table()}
    assert rows["factorisation"].calls == integ.solver_counts()["factorisations"]
    assert rows["joint law"].calls >= iterations > 0
    assert rows["linear solve"].calls >= 5


def test_run_log_ends_with_where_the_time_went(tmp_path):
    out = tmp_path / "smoke"
    res = run_case(load_case(SMOKE, QUIET + ["loading.horizontal.target_m=2e-4"]), out,
                   echo=lambda m: None)
    log = (out / "run.log").read_text()
    m = re.search(r"time: (.*), the rest (-?[\d.]+) s", log)
    assert m is not None
    outer = {name.strip(): float(s) for name, s in re.findall(r"([a-z ]+) ([\d.]+) s", m.group(1))}
    assert set(outer) == {"scene build", "steps", "outputs"}
    # the parts do not overlap: together at most the run's time (the rest is not negative)
    assert float(m.group(2)) >= -0.01 and sum(outer.values()) <= res.seconds + 0.01
    inner = [float(s) for s in re.findall(r"time in the steps: [^\n]*? ([\d.]+) s \(\d+ calls",
                                          log)]
    assert inner and sum(inner) <= outer["steps"] + 0.01
    # the process's peak memory: at least what it holds now, and the mesh's arrays besides
    peak = re.search(r"memory: peak ([\d,]+) MiB", log)
    assert peak is not None
    assert float(peak.group(1).replace(",", "")) >= timing.peak_memory_mib() - 1.0 > 0.0
