"""The errors of a run, by what the user does about them (the CLI's exit codes)."""

from __future__ import annotations


class RunInputError(ValueError):
    """A problem with what the user asked for (exit code 2)."""


class RunFailure(RuntimeError):
    """The computation failed (exit code 1)."""


class RunOutputError(RunFailure):
    """An output file could not be written (disk full, permissions...; exit code 1)."""
