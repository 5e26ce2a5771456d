"""The cost of a limit analysis against the number of blocks: the benchmark behind ``masonry
bench-limit``.

One case, scaled by setting one or more of its parameters to each value of a list (by default
the shipped dome with ``dome.courses`` and ``dome.voussoirs`` both set to 10, 32 and 100: 100,
1,024 and 10,000 voussoirs). For each value the analysis of :func:`masonry_nscd.limit.analysis.
analyse` runs once, as ``masonry limit`` runs it without writing its files, and its stages are
timed (s, wall clock): the scene (the builder and its contact detection), the rigid model,
the programme's assembly and its solve, and the reading of the mechanism's joints. The table
says the blocks, interface points, the multiplier and the times; ``total`` is their sum, and
``CPU`` the process's CPU time over the same analysis (on a shared machine the wall clock
also counts the others' work).
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

#: The scaling of the default benchmark: the dome's courses and voussoirs per course.
DEFAULT_PARAMS = ("dome.courses", "dome.voussoirs")
DEFAULT_VALUES = (10, 32, 100)


@dataclass
class BenchRow:
    """One scaled case's counts, multiplier and times (s)."""

    value: float
    blocks: int
    points: int
    multiplier: float | None
    status: str
    times_s: dict[str, float]  # wall-clock, per stage
    cpu_s: float  # the process's CPU time over the whole analysis

    @property
    def total_s(self) -> float:
        return sum(self.times_s.values())


def bench_limit(load: Callable[[float], Any], values: Sequence[float], *, facets: int = 0,
                solver: str = "clarabel", echo: Callable[[str], None] | None = None
                ) -> list[BenchRow]:
    """The rows of the module docstring; ``load(value)`` is the case at ``value``; ``echo``
    receives each row's line as it is measured."""
    from masonry_nscd.limit.analysis import analyse

    rows = []
    for value in values:
        case = load(value)
        gc.collect()
        t0, c0 = time.perf_counter(), time.process_time()
        result = analyse(case, facets=facets, solver=solver)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rec = result.record
        times = {k: float(rec["times_s"][k]) for k in ("scene", "model", "assemble", "solve")}
        # what analyse spent beyond its timed stages (the mechanism's joints)
        times["joints"] = max(wall - sum(times.values()), 0.0)
        row = BenchRow(float(value), int(rec["counts"]["free_bodies"]),
                       int(rec["counts"]["points"]), rec["multiplier"]["value"],
                       str(rec["status"]), times, cpu)
        rows.append(row)
        if echo is not None:
            echo(format_row(row))
        del result, case
    return rows


def format_header() -> str:
    return (f"{'value':>8} {'blocks':>7} {'points':>8} {'multiplier':>11} {'scene':>7} "
            f"{'model':>7} {'assemble':>8} {'solve':>7} {'joints':>7} {'total s':>8} "
            f"{'CPU s':>7}")


def format_row(r: BenchRow) -> str:
    t = r.times_s
    lam = f"{r.multiplier:.5g}" if r.multiplier is not None else r.status
    return (f"{r.value:>8g} {r.blocks:>7d} {r.points:>8d} {lam:>11} {t['scene']:>7.2f} "
            f"{t['model']:>7.2f} {t['assemble']:>8.2f} {t['solve']:>7.2f} {t['joints']:>7.2f} "
            f"{r.total_s:>8.2f} {r.cpu_s:>7.2f}")
