"""Batch runs of one case: parameter sweeps, on local worker processes or on a Dask cluster.

A sweep takes a case file and, for some of its fields, a list of values (the ``--set`` syntax
of ``masonry run`` with several values: ``loading.vertical_stress.value_Pa=0.3e6,0.5e6``). It
runs the cartesian product of the lists, one run per combination, each one in its own folder
``OUTDIR/runs/<name>`` with the usual outputs of :func:`masonry_nscd.run.run_case`. The name is
made of the values as typed, ``value_Pa=0.3e6__mu=0.5`` (the last part of each field path, the
whole path where two last parts are the same). A ``--set`` with one value is a fixed override
of every run; it is left out of the names and of the table.

Every value is read as YAML like a case file (YAML 1.2: ``0.3e6`` is a float, ``[2,2,1]`` a
list; commas inside brackets do not split values) and every combination is validated before
any run starts (:class:`SweepError`, one message per problem, naming the field).

Execution
    The runs are tasks of ``dask.distributed``: by default on a ``LocalCluster`` of worker
    processes with one thread each (on the loopback address), or on an existing scheduler
    (``scheduler="tcp://host:8786"``). A worker runs :func:`run_point`, which needs nothing but
    its arguments and masonry_nscd installed on the worker; the run folders are written by the
    workers, so OUTDIR must be on a file system the workers share (same path) for the run
    folders to be found there; the table and the figure are made from the values the tasks
    return, so they do not depend on it.
Numba
    A worker process runs numba with one thread (``NUMBA_NUM_THREADS=1``: the runs are the
    parallelism). Several processes compiling the same kernels at once can corrupt the on-disk
    cache, so the kernels are compiled by a short warm-up run (two steps of the case, no
    output files) under a file lock in the cache folder: by the parent before a local cluster
    starts, and once per worker process and kind of case (block material, joint law, solver),
    where they are then read from the cache.
Failures
    A run that fails is recorded with its status and message and the others go on:
    ``ok`` finished; ``failed`` the computation failed (:class:`~masonry_nscd.run.RunFailure`:
    divergence, a non-finite value...); ``invalid`` the scene refused the case
    (:class:`~masonry_nscd.run.RunInputError`); ``error`` anything else (an unexpected
    exception, a lost worker), with the exception's type.
Resuming
    When a run ends, the marker ``sweep_run.json`` (status, message, run time, outputs and the
    SHA-256 of the case as run) is written atomically in its folder. Running the same sweep
    again skips every run whose marker says ``ok`` for the same case; the others (failed,
    interrupted, never started, or whose case changed) are run again from scratch.

``sweep.csv``, one row per run in the order of the product (rewritten as runs end): the swept
fields (named by their path, values as validated, SI units), then ``initial_stiffness_kN_mm``,
``peak_force_kN``, ``ux_at_peak_mm``, ``force_at_target_kN``, ``target_ux_mm``, and for cyclic
and tabulated histories ``peak_force_neg_kN``, ``ux_at_peak_neg_mm``, ``dissipated_energy_J``,
for ground motion ``peak_drift_mm``, ``residual_drift_mm``, ``peak_base_shear_kN`` (empty
otherwise; definitions in :mod:`masonry_nscd.report`), ``unconverged_steps``, the failure
modes, for limit-state cases (arch, vault, assembly) ``collapse`` (true or false: standing),
``collapse_load_name`` and ``collapse_load`` (the first growing load, e.g. ``lambda``, at the
onset of the mechanism) and ``collapse_time_s`` (the onset; empty otherwise),
``run_time_s`` (wall-clock time of the run on its worker, s), ``status``, ``message`` and
``run`` (the folder name). A run that was skipped keeps the numbers and the run time of the
sweep that made it. ``force_displacement.png``: the
curves of the runs that finished (:func:`masonry_nscd.plots.plot_curves`).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import json
import logging
import math
import os
import re
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from masonry_nscd.io.runfolder import SWEEP_MARKER

#: Summary values (masonry_nscd.report) kept per run, in the order of the table.
OUTPUT_KEYS = ("initial_stiffness_kN_mm", "peak_force_kN", "ux_at_peak_mm", "force_at_target_kN",
               "target_ux_mm", "peak_force_neg_kN", "ux_at_peak_neg_mm", "dissipated_energy_J",
               "peak_drift_mm", "residual_drift_mm", "peak_base_shear_kN", "unconverged_steps", "failure_mode_at_peak", "failure_mode",
               "collapse", "collapse_load_name", "collapse_load", "collapse_time_s")
#: Columns of the table after the swept fields.
TAIL_COLUMNS = (*OUTPUT_KEYS, "run_time_s", "status", "message", "run")
STATUSES = ("ok", "failed", "invalid", "error")
RUNS_DIR = "runs"
DONE_MARKER = SWEEP_MARKER
SWEEP_FILE = "sweep.json"
TABLE_FILE = "sweep.csv"
PLOT_FILE = "force_displacement.png"
WARMUP_STEPS = 2

log = logging.getLogger(__name__)


class SweepError(ValueError):
    """A sweep that cannot be started as asked (exit code 2); ``messages``: one line each."""

    def __init__(self, messages: str | Sequence[str]):
        self.messages = [messages] if isinstance(messages, str) else list(messages)
        super().__init__("\n".join(self.messages))


@dataclass(frozen=True)
class Point:
    """One run of a batch: its folder name, its swept values and its full case.

    ``params``: field path -> value as validated in the case (SI units); ``case_yaml``: the
    case as :func:`masonry_nscd.case.case_to_yaml` writes it, every default filled in.
    """

    name: str
    params: dict[str, Any]
    case_yaml: str

    @property
    def case_sha256(self) -> str:
        return hashlib.sha256(self.case_yaml.encode()).hexdigest()


@dataclass
class RunRecord:
    """What a run gave: status, message, run time (s), outputs (units in the keys).

    ``curve``: the columns of ``force_displacement.csv`` (finished runs, when asked for);
    ``skipped``: finished in an earlier sweep, not run again.
    """

    name: str
    status: str
    message: str = ""
    run_time_s: float | None = None
    outputs: dict[str, Any] = field(default_factory=dict)
    skipped: bool = False
    curve: dict[str, Any] | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


# ---------------------------------------------------------------------------------------------
# The combinations
# ---------------------------------------------------------------------------------------------


def split_values(text: str) -> list[str]:
    """Split ``V1,V2,...`` at the commas outside brackets, braces and quotes."""
    parts, depth, quote, start = [], 0, "", 0
    for i, c in enumerate(text):
        if quote:
            quote = "" if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c in "[{":
            depth += 1
        elif c in "]}":
            depth -= 1
        elif c == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    parts.append(text[start:].strip())
    return parts


def parse_set(option: str) -> tuple[str, list[str]]:
    """``"PATH=V1,V2"`` -> ``(PATH, ["V1", "V2"])`` (values as typed), or :class:`SweepError`."""
    path, sep, values = option.partition("=")
    path = path.strip()
    if not sep or not path:
        raise SweepError(f"--set {option}: expected PATH=V1,V2,... e.g. "
                         "loading.vertical_stress.value_Pa=0.3e6,0.5e6")
    texts = split_values(values)
    if any(not t for t in texts):
        raise SweepError(f"--set {option}: an empty value in the list (two commas in a row, "
                         "or a comma at an end?)")
    if len(set(texts)) < len(texts):
        raise SweepError(f"--set {option}: a value is repeated")
    return path, texts


def field_value(case: Any, path: str) -> Any:
    """The value of the field ``path`` (``joint.mu``) of a validated case."""
    obj = case
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", text).strip("_") or "_"


def short_keys(paths: Sequence[str]) -> dict[str, str]:
    """Name of each path in the run folders: its last part, or the whole path when two
    paths end alike."""
    last = [p.rsplit(".", 1)[-1] for p in paths]
    return {p: (k if last.count(k) == 1 else p) for p, k in zip(paths, last, strict=True)}


def point_names(combos: Sequence[Sequence[tuple[str, str]]]) -> list[str]:
    """Folder names of the combinations ``[(path, value text), ...]``: ``key=value`` joined by
    ``__``; a name that repeats (values that differ only in symbols) gets ``~2``, ``~3``..."""
    keys = short_keys([p for p, _ in combos[0]]) if combos and combos[0] else {}
    names: list[str] = []
    for combo in combos:
        base = "__".join(f"{keys[p]}={_slug(v)}" for p, v in combo) or "run"
        name, n = base, 1
        while name in names:
            n += 1
            name = f"{base}~{n}"
        names.append(name)
    return names


def make_point(case_file: Path, name: str, swept: Sequence[tuple[str, str]],
               fixed: Sequence[str] = ()) -> Point:
    """The :class:`Point` of the case file with the ``fixed`` overrides (``PATH=VALUE``) and the
    swept values ``[(path, value text), ...]``; raises :class:`~masonry_nscd.case.CaseError`."""
    from masonry_nscd.case import case_to_yaml, load_case

    case = load_case(case_file, [*fixed, *(f"{p}={v}" for p, v in swept)])
    return Point(name, {p: field_value(case, p) for p, _ in swept}, case_to_yaml(case))


def sweep_points(case_file: Path, sets: Sequence[str]) -> tuple[list[Point], list[str]]:
    """Every combination of the ``--set`` options, validated: ``(points, swept paths)``.

    Raises :class:`SweepError` listing every problem (each combination is loaded; a message
    shared by several combinations is given once).
    """
    from masonry_nscd.case import CaseError

    parsed = [parse_set(s) for s in sets]
    paths = [p for p, _ in parsed]
    twice = sorted({p for p in paths if paths.count(p) > 1})
    if twice:
        raise SweepError(f"--set {', '.join(twice)}: given more than once (put every value "
                         "in one list)")
    fixed = [f"{p}={texts[0]}" for p, texts in parsed if len(texts) == 1]
    lists = [[(p, t) for t in texts] for p, texts in parsed if len(texts) > 1]
    combos = [list(c) for c in itertools.product(*lists)]
    points, problems = [], []
    for name, combo in zip(point_names(combos), combos, strict=True):
        try:
            points.append(make_point(case_file, name, combo, fixed))
        except CaseError as exc:
            problems += [m for m in exc.messages if m not in problems]
    if problems:
        raise SweepError(problems)
    return points, [p for p, texts in parsed if len(texts) > 1]


# ---------------------------------------------------------------------------------------------
# One run, on a worker
# ---------------------------------------------------------------------------------------------


def _quiet(_message: str) -> None:
    """An ``echo`` that prints nothing (the run's log is in its run.log)."""


def one_numba_thread() -> None:
    """Give numba and the per-point kernels (``masonry_nscd.threads``) one thread in this
    process (before numba is imported, if possible)."""
    from masonry_nscd import threads

    threads.set_count(1)
    if "numba" in sys.modules:
        import numba

        numba.set_num_threads(1)
    else:
        os.environ["NUMBA_NUM_THREADS"] = "1"


@contextlib.contextmanager
def cache_lock() -> Iterator[None]:
    """An exclusive lock on the numba cache folder, across processes of this machine."""
    folder = Path(os.environ.get("NUMBA_CACHE_DIR") or tempfile.gettempdir())
    folder.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # no flock (Windows): no lock
        yield
        return
    with open(folder / "warmup.lock", "w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


_warmed: set[tuple[str, ...]] = set()


def warm_cache(case_yaml: str) -> None:
    """Compile the kernels of this kind of case once in this process, under :func:`cache_lock`.

    A run of ``WARMUP_STEPS`` steps of the case in a temporary folder, with no VTU or HDF5
    output. A warm-up that fails is ignored (the real run will report the problem).
    """
    from masonry_nscd.case import case_from_dict, read_yaml
    from masonry_nscd.run import run_case

    data = read_yaml(case_yaml)
    kind = (data["blocks"]["material"], data["joint"]["law"], data["solver"]["method"])
    if kind in _warmed:
        return
    data["output"].update(vtu=False, hdf5=False)
    with cache_lock(), tempfile.TemporaryDirectory(prefix="masonry_warmup_") as tmp, \
            contextlib.suppress(Exception):
        run_case(case_from_dict(data), Path(tmp) / "run", echo=_quiet,
                 stop_when=lambda curve: len(curve["step"]) >= WARMUP_STEPS)
    _warmed.add(kind)


def _read_marker(run_dir: Path) -> dict[str, Any] | None:
    try:
        return json.loads((run_dir / DONE_MARKER).read_text())
    except (OSError, ValueError):
        return None


def finished_record(point: Point, run_dir: Path, keep_curve: bool = False) -> RunRecord | None:
    """The record of ``point`` if ``run_dir`` holds its finished run (marker ``ok`` with the
    same case), else None."""
    marker = _read_marker(run_dir)
    if not marker or marker.get("status") != "ok" or \
            marker.get("case_sha256") != point.case_sha256:
        return None
    curve = None
    if keep_curve:
        from masonry_nscd.io.runfolder import CSV, read_curve_csv

        try:
            curve = read_curve_csv(run_dir / CSV)
        except (OSError, ValueError):
            return None
    earlier = marker.get("message") or ""
    message = "finished in an earlier sweep, not run again" + (f"; {earlier}" if earlier else "")
    return RunRecord(point.name, "ok", message, marker.get("run_time_s"),
                     dict(marker.get("outputs") or {}), skipped=True, curve=curve)


def _outputs(run_dir: Path) -> dict[str, Any]:
    """The :data:`OUTPUT_KEYS` of the run's summary.json (computed if the file is missing)."""
    from masonry_nscd.io.summary_json import read_summary

    try:
        summary = read_summary(run_dir)
    except (OSError, ValueError):
        from masonry_nscd.report import summarize_run

        summary = summarize_run(run_dir)
    out = {k: summary.get(k) for k in OUTPUT_KEYS}
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


def _write_marker(run_dir: Path, point: Point, record: RunRecord) -> None:
    from masonry_nscd.io.atomic import atomic_write

    text = json.dumps({"status": record.status, "message": record.message,
                       "run_time_s": record.run_time_s, "outputs": record.outputs,
                       "params": {k: list(v) if isinstance(v, tuple) else v
                                  for k, v in point.params.items()},
                       "case_sha256": point.case_sha256,
                       "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S")}, indent=2)
    atomic_write(run_dir / DONE_MARKER, lambda p: Path(p).write_text(text + "\n"))


def run_point(point: Point, runs_dir: str, keep_curve: bool = False) -> RunRecord:
    """Run one point into ``runs_dir/<name>`` (the task of a worker); never raises for a run
    that fails: the failure is the record's status and message.

    A folder that holds the finished run of the same case is kept (skipped); any other content
    of the folder is removed first.
    """
    one_numba_thread()
    from masonry_nscd.case import case_from_dict, read_yaml
    from masonry_nscd.run import RunFailure, RunInputError, run_case

    run_dir = Path(runs_dir) / point.name
    done = finished_record(point, run_dir, keep_curve)
    if done is not None:
        return done
    if run_dir.exists():
        shutil.rmtree(run_dir)
    warm_cache(point.case_yaml)
    t0 = time.perf_counter()
    try:
        run_case(case_from_dict(read_yaml(point.case_yaml)), run_dir, echo=_quiet)
        status, message = "ok", ""
    except RunInputError as exc:
        status, message = "invalid", str(exc)
    except RunFailure as exc:
        status, message = "failed", str(exc)
    except Exception as exc:  # noqa: BLE001 (one run's bug must not end the sweep)
        status, message = "error", f"{type(exc).__name__}: {exc}"
    record = RunRecord(point.name, status, message, time.perf_counter() - t0)
    if record.ok:
        try:
            record.outputs = _outputs(run_dir)
            if record.outputs.get("unconverged_steps"):
                record.message = f"{record.outputs['unconverged_steps']} steps not converged"
            if keep_curve:
                from masonry_nscd.io.runfolder import CSV, read_curve_csv

                record.curve = read_curve_csv(run_dir / CSV)
        except Exception as exc:  # noqa: BLE001
            record.status, record.message = "error", f"no summary: {type(exc).__name__}: {exc}"
    _write_marker(run_dir, point, record)
    return record


# ---------------------------------------------------------------------------------------------
# Many runs: the Dask client
# ---------------------------------------------------------------------------------------------


@contextlib.contextmanager
def dask_client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A ``distributed.Client``: of the scheduler at ``scheduler``, or of a new
    ``LocalCluster`` of ``workers`` processes of one thread each on 127.0.0.1."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise SweepError("sweeps run on dask.distributed, which is not installed: "
                         "pip install 'masonry_nscd[dask]'") from None
    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise SweepError(f"cannot connect to the Dask scheduler at {scheduler}: "
                             f"{exc}") from None
        with client:
            _check_workers(client)
            yield client
        return
    # no dashboard; the scheduler's HTTP routes on a free port (8787 may be taken)
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      host="127.0.0.1", dashboard_address=None,
                      scheduler_kwargs={"dashboard_address": ":0"},
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def _check_workers(client: Any) -> None:
    """Warn when the workers of a cluster run other sources of masonry_nscd."""
    from masonry_nscd import source_hash

    try:
        hashes = client.run(source_hash)
    except Exception as exc:  # noqa: BLE001 (e.g. masonry_nscd not installed there)
        raise SweepError(f"the Dask workers cannot run masonry_nscd ({type(exc).__name__}: "
                         f"{exc}): install it on every worker machine") from None
    mine = source_hash()
    other = sorted(w for w, h in hashes.items() if h != mine)
    if other:
        log.warning("workers %s run other sources of masonry_nscd than this machine: their "
                    "results may differ", ", ".join(other))


def run_points(points: Sequence[Point], runs_dir: Path, *, workers: int | None = None,
               scheduler: str | None = None, keep_curve: bool = False,
               on_record: Callable[[RunRecord], None] = lambda r: None) -> list[RunRecord]:
    """Run every point not yet finished in ``runs_dir``; the records in the order of
    ``points``. ``on_record`` is called as each record comes (skipped runs first)."""
    runs_dir = Path(runs_dir).resolve()
    records: dict[str, RunRecord] = {}
    pending = []
    for p in points:
        rec = finished_record(p, runs_dir / p.name, keep_curve)
        if rec is None:
            pending.append(p)
        else:
            records[p.name] = rec
            on_record(rec)
    if pending:
        n_workers = max(1, min(workers or os.cpu_count() or 1, len(pending)))
        if not scheduler:
            warm_cache(pending[0].case_yaml)  # the local workers share this process's cache
        with dask_client(n_workers, scheduler) as client:
            records.update(_gather(client, pending, runs_dir, keep_curve, on_record))
    return [records[p.name] for p in points]


def _gather(client: Any, points: Sequence[Point], runs_dir: Path, keep_curve: bool,
            on_record: Callable[[RunRecord], None]) -> dict[str, RunRecord]:
    from distributed import as_completed

    futures = {client.submit(run_point, p, str(runs_dir), keep_curve, pure=False): p
               for p in points}
    out = {}
    for future in as_completed(futures):
        p = futures[future]
        try:
            rec = future.result()
        except Exception as exc:  # noqa: BLE001 (a lost worker, a task that could not run)
            rec = RunRecord(p.name, "error", f"the task failed: {type(exc).__name__}: {exc}")
        out[p.name] = rec
        on_record(rec)
    return out


# ---------------------------------------------------------------------------------------------
# The table and the figure
# ---------------------------------------------------------------------------------------------


def format_cell(value: Any) -> str:
    """A table cell: floats in full precision (``repr``), lists as ``[a, b]``, None empty."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(format_cell(v) for v in value) + "]"
    return str(value)


def write_table(path: Path, points: Sequence[Point], records: dict[str, RunRecord],
                param_paths: Sequence[str]) -> Path:
    """Write the table of the runs recorded so far (see the module docstring), atomically."""
    from masonry_nscd.io.atomic import atomic_write

    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*param_paths, *TAIL_COLUMNS])
    for p in points:
        r = records.get(p.name)
        if r is None:
            continue
        w.writerow([format_cell(p.params[k]) for k in param_paths]
                   + [format_cell(r.outputs.get(k)) for k in OUTPUT_KEYS]
                   + [format_cell(r.run_time_s), r.status, r.message, p.name])
    atomic_write(path, lambda tmp: Path(tmp).write_text(buf.getvalue()))
    return path


def plot_overlay(points: Sequence[Point], records: Sequence[RunRecord], runs_dir: Path,
                 path: Path) -> Path | None:
    """The force-displacement curves of the finished runs (with their curve) on one chart;
    None if there are none."""
    import numpy as np

    from masonry_nscd.case import case_from_dict, read_yaml
    from masonry_nscd.io.runfolder import read_scene_info
    from masonry_nscd.plots import RunData, plot_curves

    runs = [RunData(runs_dir / p.name, case_from_dict(read_yaml(p.case_yaml)),
                    read_scene_info(runs_dir / p.name),
                    {k: np.asarray(v, dtype=float) for k, v in r.curve.items()},
                    r.outputs, label=p.name)
            for p, r in zip(points, records, strict=True) if r.ok and r.curve]
    return plot_curves(runs, path) if runs else None


# ---------------------------------------------------------------------------------------------
# The sweep
# ---------------------------------------------------------------------------------------------


def prepare_outdir(outdir: Path, marker: str, description: dict[str, Any]) -> None:
    """Create OUTDIR, or reuse it if it holds a batch of the same kind (``marker`` file);
    refuse any other folder that is not empty (:class:`SweepError`). Writes the marker."""
    from masonry_nscd.io.atomic import atomic_write

    if outdir.exists() and not outdir.is_dir():
        raise SweepError(f"output path {outdir} exists and is not a folder")
    if outdir.is_dir() and any(outdir.iterdir()) and not (outdir / marker).exists():
        raise SweepError(f"output folder {outdir} is not empty and holds no {marker}: "
                         "not a folder of this command, use another -o")
    try:
        (outdir / RUNS_DIR).mkdir(parents=True, exist_ok=True)
        text = json.dumps(description, indent=2) + "\n"
        atomic_write(outdir / marker, lambda p: Path(p).write_text(text))
    except OSError as exc:
        raise SweepError(f"cannot write in {outdir}: {exc.strerror or exc}") from None


def progress_line(record: RunRecord, done: int, total: int) -> str:
    """``[2/3] value_Pa=0.3e6: ok in 1.2 s``."""
    secs = f" in {record.run_time_s:.1f} s" if record.run_time_s is not None else ""
    what = "kept (finished in an earlier sweep)" if record.skipped else f"{record.status}{secs}"
    tail = f": {record.message}" if record.message and not record.skipped else ""
    return f"[{done}/{total}] {record.name}: {what}{tail}"


@dataclass
class SweepResult:
    """The records of a sweep, in the order of the product, and the files written."""

    records: list[RunRecord]
    table: Path
    plot: Path | None

    @property
    def failed(self) -> list[RunRecord]:
        return [r for r in self.records if not r.ok]


def run_sweep(case_file: Path, sets: Sequence[str], outdir: Path, *, workers: int | None = None,
              scheduler: str | None = None,
              echo: Callable[[str], None] = print) -> SweepResult:
    """Validate, then run every combination of ``sets`` (see the module docstring).

    Raises :class:`SweepError` before any run for a bad option or combination.
    """
    points, paths = sweep_points(case_file, sets)
    prepare_outdir(outdir, SWEEP_FILE, {"case_file": str(case_file), "sets": list(sets),
                                        "runs": [p.name for p in points]})
    table = outdir / TABLE_FILE
    records: dict[str, RunRecord] = {}

    def on_record(rec: RunRecord) -> None:
        records[rec.name] = rec
        write_table(table, points, records, paths)
        echo(progress_line(rec, len(records), len(points)))

    echo(f"{len(points)} runs of {case_file} in {outdir / RUNS_DIR}"
         + (f" on the Dask scheduler {scheduler}" if scheduler else ""))
    done = run_points(points, outdir / RUNS_DIR, workers=workers, scheduler=scheduler,
                      keep_curve=True, on_record=on_record)
    try:
        plot = plot_overlay(points, done, outdir / RUNS_DIR, outdir / PLOT_FILE)
    except (OSError, ValueError) as exc:  # the table is written: a figure must not lose it
        echo(f"no figure: {type(exc).__name__}: {exc}")
        plot = None
    return SweepResult(done, table, plot)
