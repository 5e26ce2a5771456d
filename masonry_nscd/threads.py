r"""The per-point kernels on several cores: a batch of independent points split into ranges.

A joint point's law and an ENDO3D Gauss point's update read their own inputs and write their
own outputs, nothing shared: a batch ``[0, n)`` split into ranges ``[lo, hi)`` run on threads
gives the same numbers bit for bit, whatever the number of threads. The kernels are compiled
with ``nogil=True``, so the threads run them at the same time; the calling thread runs the
first range itself and waits for the others.

How many threads: ``NUMBA_NUM_THREADS`` when set (the variable numba's own parallel loops
read), else the cores this process may run on; ``set_count`` overrides both (a sweep's worker
runs one thread, the runs being the parallelism). A range is at least ``MIN_POINTS`` points,
so a small batch stays on the calling thread, where a thread's hand-over (a wake-up
of an idle core) would cost more than it saves.
"""

from __future__ import annotations

import functools
import itertools
import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

R = TypeVar("R")

MIN_POINTS = 256
_count: int | None = None
_pool: ThreadPoolExecutor | None = None
_pool_size = 0


def count() -> int:
    """Threads the per-point kernels use (at least 1)."""
    if _count is not None:
        return _count
    env = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if env:
        try:
            return max(1, int(env))
        except ValueError:
            pass
    return _cores()


@functools.cache
def _cores() -> int:
    """The cores this process may run on, asked once (a system call: ``count`` is asked at
    every batch, some 20,000 times a run)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def set_count(n: int | None) -> None:
    """Use ``n`` threads from now on (None: back to ``NUMBA_NUM_THREADS`` or the cores)."""
    global _count, _pool, _pool_size
    if n is not None and n < 1:
        raise ValueError(f"threads: at least 1, got {n}")
    _count = n
    if _pool is not None:
        _pool.shutdown(wait=True)
        _pool, _pool_size = None, 0


def ranges(n: int, threads: int | None = None,
           min_size: int | None = None) -> list[tuple[int, int]]:
    """``[0, n)`` cut into at most ``threads`` ranges of at least ``min_size`` items each
    (default ``MIN_POINTS``; one range when ``n`` is small), of sizes differing by at most
    one."""
    k = max(1, min(threads or count(), n // max(1, min_size or MIN_POINTS)))
    cuts = [i * n // k for i in range(k + 1)]
    return list(itertools.pairwise(cuts))


def run_ranges(kernel: Callable[[int, int], R], n: int,
               min_size: int | None = None) -> list[R]:
    """``kernel(lo, hi)`` over the ranges of ``[0, n)`` (``ranges``), in threads; the results
    in the order of the ranges. ``kernel`` must touch items ``lo`` to ``hi - 1`` only and
    release the GIL (a numba kernel compiled ``nogil=True``) to gain anything."""
    return run_together([(kernel, n, min_size)])[0]


def run_together(jobs: Sequence[tuple[Callable[[int, int], Any], int, int | None]],
                 meanwhile: Callable[[], None] | None = None) -> list[list[Any]]:
    """Several batches ``(kernel, n, min_size)``, each over its ranges as in ``run_ranges``,
    with one hand-over to each helper thread for all of them: helper ``k`` runs range ``k`` of
    every batch that has one, in the order of ``jobs``, while the calling thread runs every
    first range, then ``meanwhile()`` (work of its own that needs none of the batches' results,
    so that it fills the wait), then waits. Returns each batch's results in the order of its
    ranges.

    A hand-over costs the wake-up of an idle core, far more than a call:
    two batches of one Newton evaluation (the joint law, the ENDO3D trial) run together pay it
    once, and the calling thread's serial work fills it."""
    global _pool, _pool_size
    parts = [ranges(n, min_size=m) for _, n, m in jobs]
    helpers = max(len(p) for p in parts) - 1 if parts else 0
    if helpers > 0 and (_pool is None or _pool_size < helpers):
        if _pool is not None:
            _pool.shutdown(wait=True)
        _pool_size = helpers
        _pool = ThreadPoolExecutor(max_workers=_pool_size, thread_name_prefix="masonry-kernel")

    def helper(k: int) -> list[Any]:
        return [kernel(*p[k]) for (kernel, _, _), p in zip(jobs, parts, strict=True)
                if len(p) > k]

    futures = [_pool.submit(helper, k) for k in range(1, helpers + 1)] if helpers else []
    out = [[kernel(*p[0])] for (kernel, _, _), p in zip(jobs, parts, strict=True)]
    if meanwhile is not None:
        meanwhile()
    for k, f in enumerate(futures, start=1):
        done = iter(f.result())
        for res, p in zip(out, parts, strict=True):
            if len(p) > k:
                res.append(next(done))
    return out
