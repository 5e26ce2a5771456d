"""Files written on a background thread while the run steps on.

A run's VTU files and its HDF5 output step are written at every output step, and encoding the
VTU files (zlib) and writing them (an fsync each, :mod:`masonry_nscd.io.atomic`) takes a few
ms a step that the steps need not wait for: the compression and the fsyncs let other threads
run, so on a second core they overlap the next steps (docs/performance.md; h5py's own calls
hold the interpreter, the HDF5 step's fsync does not).
:class:`BackgroundWriter` runs ``write(path)`` calls, in the order given, on one thread of its
own:

* what it writes must be the caller's no longer (``io.vtu.VtuFile`` and
  ``ResultsFile.staged_step`` hold copies);
* an error of a write (an ``OSError`` becomes the ``RunOutputError`` naming the file, as
  :func:`~masonry_nscd.io.atomic.writing` makes it) is raised in the caller's thread at the
  next :meth:`~BackgroundWriter.submit`, :meth:`~BackgroundWriter.check` or
  :meth:`~BackgroundWriter.wait`;
* :meth:`~BackgroundWriter.wait` returns once every file given so far is on disk: call it
  before writing anything that names them (the PVD collection, the checkpoint);
* the caller bounds what waits: the recorder waits for an output step's files at the next
  one, so a writer that falls behind holds the run back instead of piling up copies.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor

from masonry_nscd.io.atomic import PathLike, writing


class BackgroundWriter:
    """Writes files in order on one thread (module docstring). Once a write has failed, every
    later call raises its error again: the files after it are not written."""

    def __init__(self):
        self._pool: ThreadPoolExecutor | None = None
        self._pending: deque[Future] = deque()
        self._error: BaseException | None = None

    def submit(self, write: Callable[[PathLike], None], path: PathLike) -> None:
        """Write ``path`` by ``write(path)`` on the writer's thread."""
        self.check()
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="masonry-writer")
        self._pending.append(self._pool.submit(_write, write, os.fspath(path)))

    def check(self) -> None:
        """Raise the error of a write that has ended in one (the first given)."""
        while self._pending and self._pending[0].done():
            self._end(self._pending.popleft())
        if self._error is not None:
            raise self._error

    def wait(self) -> None:
        """Return once every write given so far has ended; raise the first error."""
        while self._pending:
            self._end(self._pending.popleft())
        if self._error is not None:
            raise self._error

    def close(self) -> None:
        """Wait for the writes given so far (the first error raised) and stop the thread."""
        try:
            self.wait()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=True)
                self._pool = None
            self._pending.clear()

    def _end(self, future: Future) -> None:
        """Wait for one write; keep its error, the first one, to raise."""
        try:
            future.result()
        except Exception as exc:  # noqa: BLE001 (raised again by check, wait and close)
            if self._error is None:
                self._error = exc
            for f in self._pending:  # the writes after a failed one are not made
                f.cancel()


def _write(write: Callable[[PathLike], None], path: str) -> None:
    with writing(path):
        write(path)
