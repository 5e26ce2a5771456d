"""The log of a run, ``run.log``: one line per message, headed by the wall-clock time.

A line is ``HH:MM:SS message`` (local time, :func:`time.strftime`), written and flushed at
once, so that the log of a run that is stopped or killed holds every line said before. A
resumed run appends to the log of the run it continues. What a run logs, and which lines it
also shows, is the run loop's (:mod:`masonry_nscd.run`); an OSError becomes a
:class:`~masonry_nscd.errors.RunOutputError` naming the file (:func:`~masonry_nscd.io.atomic.writing`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from masonry_nscd.io.atomic import writing
from masonry_nscd.io.runfolder import LOG


class RunLog:
    """``run.log`` of the run folder ``outdir`` (appended to when ``append``: a resumed run),
    echoing the lines shown with ``echo``."""

    def __init__(self, outdir: Path | str, append: bool, echo: Callable[[str], None]):
        self.path, self.echo = Path(outdir) / LOG, echo
        with writing(self.path):
            self.file = open(self.path, "a" if append else "w")  # noqa: SIM115 (closed by close)

    def __call__(self, msg: str, show: bool = True) -> None:
        """Write ``msg`` as a line of the log; ``show``: also echo it."""
        if show:
            self.echo(msg)
        with writing(self.path):
            self.file.write(f"{time.strftime('%H:%M:%S')} {msg}\n")
            self.file.flush()

    def close(self) -> None:
        self.file.close()
