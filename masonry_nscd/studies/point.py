"""One point of a study: one run of a case into its own folder, and the record of what happened.

Every study is made of runs of a case, each in its folder: the settings of a benchmark, the
combinations of a sweep, the samples of a sensitivity study, the variants of the stress test,
the short runs of a calibration, the bisection of a threshold, the shipped cases of
check-cases. :func:`run_point` makes one run with :func:`masonry_nscd.run.run_case` and returns
its :class:`RunRecord`. It never raises for a run that does not finish (KeyboardInterrupt
excepted, so that Ctrl-C still ends a study): what happened is the record's status, one of
:data:`STATUSES`:

``ok``
    the run reached its end, or the ``stop_when`` of the study (a calibration stops once its
    stiffness is measured);
``invalid``
    the scene refused the case (:class:`~masonry_nscd.errors.RunInputError`): the input is to
    be fixed, exit code 2 of ``masonry run``;
``failed``
    the computation failed (:class:`~masonry_nscd.errors.RunFailure`: a divergence, a
    non-finite value, an output that could not be written), exit code 1;
``error``
    any other exception: a bug; the message starts with the exception's type;
``timeout``
    stopped by the study's wall-clock limit (``time_limit_s``) before its end.

A study's own verdicts are judged from the record and are not part of it: check-cases'
``changed``, ``no record`` and ``written``, the stress test's ``imbalance`` or ``non_finite``,
a threshold's ``standing`` or ``collapse``.

The record holds the point's name and run folder, the status and its message, the steps made
(of a run that failed: the steps before the one that failed), the wall-clock time of the run
(s: scene build, steps, outputs, summary) and, for a run that finished, its own time as its
run.log ends with (``done: N steps in X s``: scene build and steps, without the summary), the
steps left above the solver tolerance, the
driven body's displacement (mm) and force (kN) at the last step, and the key numbers of the
run's summary (:data:`SUMMARY_KEYS`, definitions in :mod:`masonry_nscd.report`). With
``time_steps`` it also holds the wall-clock time of every step of the solver (s) and the size
of the system (contact points, degrees of freedom).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from masonry_nscd.errors import RunFailure, RunInputError
from masonry_nscd.io.summary_json import read_summary
from masonry_nscd.nscd.integrator import Integrator
from masonry_nscd.report import summarize_run
from masonry_nscd.run import run_case

OK, INVALID, FAILED, ERROR, TIMEOUT = "ok", "invalid", "failed", "error", "timeout"
#: The statuses of a run, shared by every study (module docstring).
STATUSES = (OK, INVALID, FAILED, ERROR, TIMEOUT)
#: The exit codes of ``masonry run`` (``masonry_nscd.cli``) and the status each one means.
EXIT_STATUS = {0: OK, 1: FAILED, 2: INVALID}

#: Summary values (masonry_nscd.report) kept in a record, in the order of a sweep's table.
SUMMARY_KEYS = ("initial_stiffness_kN_mm", "peak_force_kN", "ux_at_peak_mm",
                "force_at_target_kN", "target_ux_mm", "peak_force_neg_kN", "ux_at_peak_neg_mm",
                "dissipated_energy_J", "peak_drift_mm", "residual_drift_mm",
                "peak_base_shear_kN", "unconverged_steps", "failure_mode_at_peak",
                "failure_mode", "collapse", "collapse_load_name", "collapse_load",
                "collapse_time_s")


@dataclass
class RunRecord:
    """What one run of a study gave (module docstring; units in the names).

    ``outputs``: the :data:`SUMMARY_KEYS` of a finished run (empty otherwise); ``skipped``:
    finished by an earlier run of the study and not run again; ``curve``: the columns of the
    run's curve, when the study asks for them; ``error_type``: the class name of the exception
    that ended the run (empty for ``ok`` and ``timeout``); ``exception``: that exception, in the
    process that ran the point only (it is not pickled: a Dask worker returns the record).
    """

    name: str
    status: str
    message: str = ""
    seconds: float | None = None
    loop_seconds: float | None = None
    steps: int = 0
    unconverged_steps: int = 0
    run_dir: str = ""
    ux_mm: float = math.nan
    fx_kN: float = math.nan
    outputs: dict[str, Any] = field(default_factory=dict)
    error_type: str = ""
    step_seconds: list[float] | None = None
    contact_points: int | None = None
    dofs: int | None = None
    skipped: bool = False
    curve: dict[str, Any] | None = None
    exception: BaseException | None = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        return self.status == OK

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "exception": None}

    def raise_failure(self) -> None:
        """Raise again what ended a run that did not finish (nothing for ``ok``): the run's own
        exception, for a study that stops at the first run that fails."""
        if self.exception is not None:
            raise self.exception
        if self.status not in (OK, TIMEOUT):
            raise RuntimeError(self.message)


def as_error(record: RunRecord) -> tuple[str, str]:
    """``(status, message)`` for a table whose statuses have no ``invalid`` (the benchmark's and
    the stress test's): a case the scene refuses is an ``error`` there, its message starting
    with the exception's type."""
    if record.status == INVALID:
        return ERROR, f"{record.error_type}: {record.message}"
    return record.status, record.message


def status_of_exit(code: int) -> str:
    """The status of a ``masonry run`` process that exited with ``code``."""
    return EXIT_STATUS.get(code, ERROR)


def _quiet(_message: str) -> None:
    """An ``echo`` that prints nothing (the run's log is in its run.log)."""


@contextlib.contextmanager
def timed_steps(durations: list[float], info: dict[str, Any]) -> Iterator[None]:
    """Inside the block, every ``Integrator.step`` appends its wall-clock time (s) to
    ``durations``; ``info`` gets the number of contact points and dofs of the first system
    stepped."""
    original = Integrator.step

    def step(self):
        info.setdefault("contact_points", int(self.sys.npt))
        info.setdefault("dofs", int(self.sys.ndof))
        t0 = time.perf_counter()
        try:
            return original(self)
        finally:
            durations.append(time.perf_counter() - t0)

    Integrator.step = step
    try:
        yield
    finally:
        Integrator.step = original


def summary_outputs(run_dir: Path) -> dict[str, Any]:
    """The :data:`SUMMARY_KEYS` of the run's summary.json (computed if the file is missing)."""
    try:
        summary = read_summary(run_dir)
    except (OSError, ValueError):
        summary = summarize_run(run_dir)
    out = {k: summary.get(k) for k in SUMMARY_KEYS}
    for k in ("failure_mode_at_peak", "failure_mode"):  # the name of the mechanism
        out[k] = (out[k] or {}).get("mode")
    # a limit-state run: whether it collapsed, the first growing load and the time at the onset
    limit = summary.get("status") if summary.get("load_factors") is not None else None
    collapse = summary.get("collapse") if limit is not None else None
    loads = (collapse or {}).get("loads_at_onset") or {}
    name = next(iter(loads), None)
    out.update({"collapse": None if limit is None else limit == "collapse",
                "collapse_load_name": name, "collapse_load": loads.get(name),
                "collapse_time_s": (collapse or {}).get("onset_time_s")})
    return out


def run_point(case, run_dir: Path, *, name: str | None = None, overwrite: bool = False,
              echo: Callable[[str], None] = _quiet,
              stop_when: Callable[[dict[str, list]], bool] | None = None,
              time_limit_s: float | None = None, time_steps: bool = False,
              outputs: bool = True) -> RunRecord:
    """Run ``case`` into ``run_dir`` and record what happened (module docstring).

    ``name``: the point's name (default: the folder's); ``overwrite``, ``echo`` and
    ``stop_when`` go to :func:`~masonry_nscd.run.run_case`; ``time_limit_s``: the run stops
    after that many seconds of wall clock (status ``timeout``); ``time_steps``: time every step
    of the solver; ``outputs``: read the summary's key numbers of a finished run (a run that
    finished without a readable summary is an ``error``).
    """
    run_dir = Path(run_dir)
    rec = RunRecord(name or run_dir.name, OK, run_dir=str(run_dir))
    seen = {"step": 0, "timed_out": False}
    deadline = None if time_limit_s is None else time.perf_counter() + time_limit_s

    def stop(curve: dict[str, list]) -> bool:
        seen["step"] = int(curve["step"][-1]) if len(curve["step"]) else 0
        if stop_when is not None and stop_when(curve):
            return True
        seen["timed_out"] = deadline is not None and time.perf_counter() > deadline
        return seen["timed_out"]

    durations: list[float] = []
    info: dict[str, Any] = {}
    timing = timed_steps(durations, info) if time_steps else contextlib.nullcontext()
    t0 = time.perf_counter()
    try:
        with timing:
            res = run_case(case, run_dir, overwrite=overwrite, echo=echo, stop_when=stop)
    except Exception as exc:  # noqa: BLE001 (one point's failure, or bug, is its record)
        rec.seconds, rec.steps, rec.exception = time.perf_counter() - t0, seen["step"], exc
        rec.error_type = type(exc).__name__
        if isinstance(exc, RunInputError):
            rec.status, rec.message = INVALID, str(exc)
        elif isinstance(exc, RunFailure):
            rec.status, rec.message = FAILED, str(exc)
        else:
            rec.status, rec.message = ERROR, f"{rec.error_type}: {exc}"
    else:
        rec.seconds, rec.loop_seconds = time.perf_counter() - t0, res.seconds
        rec.steps, rec.unconverged_steps = res.steps, res.unconverged_steps
        rec.ux_mm, rec.fx_kN = res.ux_mm, res.fx_kN
        if res.stopped and seen["timed_out"]:
            rec.status = TIMEOUT
            rec.message = f"stopped after {time_limit_s:g} s at step {res.steps}"
    if time_steps:
        rec.step_seconds = durations
        rec.contact_points, rec.dofs = info.get("contact_points"), info.get("dofs")
    if rec.ok and outputs:
        try:
            rec.outputs = summary_outputs(run_dir)
        except Exception as exc:  # noqa: BLE001 (a finished run without a summary: a bug)
            rec.status, rec.message = ERROR, f"no summary: {type(exc).__name__}: {exc}"
    return rec
