r"""Where a run's time goes: wall-clock time and calls of the solver's parts and the outputs;
and the process's peak memory (``peak_memory_mib``).

The parts are timed where they are called (``with timing.part("factorisation"):``), on the
calling thread, once per call of the whole part (a kernel that the threads of
``masonry_nscd.threads`` share is timed around the hand-over, not per thread). A timer costs
about a microsecond, against parts of a tenth of a millisecond and more. ``masonry run`` writes
the table at the end of ``run.log`` and into ``summary.json``: calls, total seconds and the
median time of a call, which is what a change to a kernel moves (a slower kernel shows there
by name, where the run's total would only show a slower run).

The timers are the process's (one run at a time in a process, as ``masonry run`` and the
sweeps' workers do); ``reset`` starts a run's. Not re-entrant: a part does not contain itself.
"""

from __future__ import annotations

import statistics
import sys
import time
from dataclasses import dataclass


class _Timer:
    """Calls and their durations (s) of one part."""

    __slots__ = ("_start", "durations")

    def __init__(self):
        self.durations: list[float] = []
        self._start = 0.0

    def __enter__(self):
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.durations.append(time.perf_counter() - self._start)
        return False


_timers: dict[str, _Timer] = {}


def part(name: str) -> _Timer:
    """The timer of the part ``name``, a context manager: ``with part("linear solve"): ...``."""
    t = _timers.get(name)
    if t is None:
        t = _timers[name] = _Timer()
    return t


def record(name: str, seconds: float) -> None:
    """One call of the part ``name`` that took ``seconds``, timed by the caller (a part whose
    time is interleaved with other parts' on the calling thread)."""
    part(name).durations.append(seconds)


def reset() -> None:
    """Forget every part's calls (a run starts)."""
    _timers.clear()


@dataclass(frozen=True)
class PartTime:
    """One part's calls, total time (s) and median time of a call (ms)."""

    name: str
    calls: int
    total_s: float
    median_ms: float


def table() -> list[PartTime]:
    """The parts timed since ``reset``, the longest first."""
    rows = [PartTime(name, len(t.durations), sum(t.durations),
                     1e3 * statistics.median(t.durations))
            for name, t in _timers.items() if t.durations]
    return sorted(rows, key=lambda r: -r.total_s)



def peak_memory_mib() -> float:
    """The peak resident memory of this process so far (MiB: the kernel's high-water mark of
    its resident set, ``ru_maxrss``)."""
    import resource

    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 2**20 if sys.platform == "darwin" else rss / 1024.0  # bytes / KiB
