"""A batch of runs of one case: the points, their execution on Dask workers, resuming, the table.

A sweep (:mod:`~masonry_nscd.studies.sweep`: the combinations of some fields' values) and a
sensitivity study (:mod:`~masonry_nscd.studies.sensitivity`: the samples of SALib) are both a
batch: a list of :class:`Point`, each a validated case with a name, run into
``OUTDIR/runs/<name>`` as a point of the study (:func:`masonry_nscd.studies.point.run_point`),
and a table of their records, one row per point. :func:`run_batch` does it for both.

Execution
    The runs are tasks of ``dask.distributed``: by default on a ``LocalCluster`` of worker
    processes with one thread each (on the loopback address), or on an existing scheduler
    (``scheduler="tcp://host:8786"``). A worker runs :func:`point_task`, which needs nothing but
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
    A run that fails is recorded with its status and message and the others go on (the
    statuses of every study, :mod:`masonry_nscd.studies.point`): ``ok`` finished; ``failed``
    the computation failed (:class:`~masonry_nscd.run.RunFailure`: divergence, a non-finite
    value...); ``invalid`` the scene refused the case (:class:`~masonry_nscd.run.RunInputError`);
    ``error`` anything else (an unexpected exception, a lost worker), with the exception's type.
Resuming
    When a run ends, the marker ``sweep_run.json`` (status, message, run time, outputs and the
    SHA-256 of the case as run) is written atomically in its folder. Running the same batch
    again skips every run whose marker says ``ok`` for the same case; the others (failed,
    interrupted, never started, or whose case changed) are run again from scratch.
The table
    One row per point in the order of the points (rewritten as runs end): the fields of the
    batch (named by their path, values as validated, SI units), then the summary's key numbers
    (:data:`OUTPUT_KEYS`, definitions in :mod:`masonry_nscd.report`), ``run_time_s``
    (wall-clock time of the run on its worker, s), ``status``, ``message`` and ``run`` (the
    folder name). A run that was skipped keeps the numbers and the run time of the batch that
    made it.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import logging
import math
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from masonry_nscd import source_hash, threads
from masonry_nscd.case import case_from_dict, case_to_yaml, load_case, read_yaml
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.runfolder import CSV, SWEEP_MARKER, read_curve_csv
from masonry_nscd.studies.point import ERROR, OK, SUMMARY_KEYS, RunRecord, run_point

#: Summary values (masonry_nscd.report) kept per run, in the order of the table.
OUTPUT_KEYS = SUMMARY_KEYS
#: Columns of the table after the fields of the batch.
TAIL_COLUMNS = (*OUTPUT_KEYS, "run_time_s", "status", "message", "run")
RUNS_DIR = "runs"
DONE_MARKER = SWEEP_MARKER
WARMUP_STEPS = 2

log = logging.getLogger(__name__)


class SweepError(ValueError):
    """A sweep or a sensitivity study that cannot be started as asked (exit code 2);
    ``messages``: one line each."""

    def __init__(self, messages: str | Sequence[str]):
        self.messages = [messages] if isinstance(messages, str) else list(messages)
        super().__init__("\n".join(self.messages))


@dataclass(frozen=True)
class Point:
    """One run of a batch: its folder name, its values of the batch's fields and its full case.

    ``params``: field path -> value as validated in the case (SI units); ``case_yaml``: the
    case as :func:`masonry_nscd.case.case_to_yaml` writes it, every default filled in.
    """

    name: str
    params: dict[str, Any]
    case_yaml: str

    @property
    def case_sha256(self) -> str:
        return hashlib.sha256(self.case_yaml.encode()).hexdigest()


# ---------------------------------------------------------------------------------------------
# The points
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


def make_point(case_file: Path, name: str, swept: Sequence[tuple[str, str]],
               fixed: Sequence[str] = ()) -> Point:
    """The :class:`Point` of the case file with the ``fixed`` overrides (``PATH=VALUE``) and the
    swept values ``[(path, value text), ...]``; raises :class:`~masonry_nscd.case.CaseError`."""
    case = load_case(case_file, [*fixed, *(f"{p}={v}" for p, v in swept)])
    return Point(name, {p: field_value(case, p) for p, _ in swept}, case_to_yaml(case))


# ---------------------------------------------------------------------------------------------
# One run, on a worker
# ---------------------------------------------------------------------------------------------


def one_numba_thread() -> None:
    """Give numba and the per-point kernels (``masonry_nscd.threads``) one thread in this
    process (before numba is imported, if possible)."""
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
    data = read_yaml(case_yaml)
    kind = (data["blocks"]["material"], data["joint"]["law"], data["solver"]["method"])
    if kind in _warmed:
        return
    data["output"].update(vtu=False, hdf5=False)
    with cache_lock(), tempfile.TemporaryDirectory(prefix="masonry_warmup_") as tmp, \
            contextlib.suppress(Exception):
        run_point(case_from_dict(data), Path(tmp) / "run", outputs=False,
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
        try:
            curve = read_curve_csv(run_dir / CSV)
        except (OSError, ValueError):
            return None
    earlier = marker.get("message") or ""
    message = "finished in an earlier sweep, not run again" + (f"; {earlier}" if earlier else "")
    return RunRecord(point.name, OK, message, seconds=marker.get("run_time_s"),
                     run_dir=str(run_dir), outputs=dict(marker.get("outputs") or {}),
                     skipped=True, curve=curve)


def _write_marker(run_dir: Path, point: Point, record: RunRecord) -> None:
    text = json.dumps({"status": record.status, "message": record.message,
                       "run_time_s": record.seconds, "outputs": record.outputs,
                       "params": {k: list(v) if isinstance(v, tuple) else v
                                  for k, v in point.params.items()},
                       "case_sha256": point.case_sha256,
                       "finished_at": time.strftime("%Y-%m-%dT%H:%M:%S")}, indent=2)
    atomic_write(run_dir / DONE_MARKER, lambda p: Path(p).write_text(text + "\n"))


def point_task(point: Point, runs_dir: str, keep_curve: bool = False) -> RunRecord:
    """Run one point into ``runs_dir/<name>`` (the task of a worker) with
    :func:`~masonry_nscd.studies.point.run_point`; never raises for a run that fails: the
    failure is the record's status and message.

    A folder that holds the finished run of the same case is kept (skipped); any other content
    of the folder is removed first.
    """
    one_numba_thread()
    run_dir = Path(runs_dir) / point.name
    done = finished_record(point, run_dir, keep_curve)
    if done is not None:
        return done
    if run_dir.exists():
        shutil.rmtree(run_dir)
    warm_cache(point.case_yaml)
    record = run_point(case_from_dict(read_yaml(point.case_yaml)), run_dir, name=point.name)
    if record.ok:
        if record.outputs.get("unconverged_steps"):
            record.message = f"{record.outputs['unconverged_steps']} steps not converged"
        if keep_curve:
            try:
                record.curve = read_curve_csv(run_dir / CSV)
            except Exception as exc:  # noqa: BLE001
                record.status = ERROR
                record.message = f"no summary: {type(exc).__name__}: {exc}"
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

    futures = {client.submit(point_task, p, str(runs_dir), keep_curve, pure=False): p
               for p in points}
    out = {}
    for future in as_completed(futures):
        p = futures[future]
        try:
            rec = future.result()
        except Exception as exc:  # noqa: BLE001 (a lost worker, a task that could not run)
            rec = RunRecord(p.name, ERROR, f"the task failed: {type(exc).__name__}: {exc}")
        out[p.name] = rec
        on_record(rec)
    return out


# ---------------------------------------------------------------------------------------------
# The table and the batch
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
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*param_paths, *TAIL_COLUMNS])
    for p in points:
        r = records.get(p.name)
        if r is None:
            continue
        w.writerow([format_cell(p.params[k]) for k in param_paths]
                   + [format_cell(r.outputs.get(k)) for k in OUTPUT_KEYS]
                   + [format_cell(r.seconds), r.status, r.message, p.name])
    atomic_write(path, lambda tmp: Path(tmp).write_text(buf.getvalue()))
    return path


def prepare_outdir(outdir: Path, marker: str, description: dict[str, Any]) -> None:
    """Create OUTDIR, or reuse it if it holds a batch of the same kind (``marker`` file);
    refuse any other folder that is not empty (:class:`SweepError`). Writes the marker."""
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
    secs = f" in {record.seconds:.1f} s" if record.seconds is not None else ""
    what = "kept (finished in an earlier sweep)" if record.skipped else f"{record.status}{secs}"
    tail = f": {record.message}" if record.message and not record.skipped else ""
    return f"[{done}/{total}] {record.name}: {what}{tail}"


def run_batch(points: Sequence[Point], outdir: Path, *, marker: str,
              description: dict[str, Any], table: Path, param_paths: Sequence[str],
              intro: str, workers: int | None = None, scheduler: str | None = None,
              keep_curve: bool = False,
              echo: Callable[[str], None] = print) -> list[RunRecord]:
    """Run a batch into ``outdir``: the folder prepared (:func:`prepare_outdir` with its
    ``marker`` file holding ``description``), ``intro`` echoed (with the scheduler's address),
    then every point not yet finished run (:func:`run_points`), the ``table`` of the fields
    ``param_paths`` written again and a progress line echoed as each record comes. Returns the
    records in the order of ``points``."""
    prepare_outdir(outdir, marker, description)
    records: dict[str, RunRecord] = {}

    def on_record(rec: RunRecord) -> None:
        records[rec.name] = rec
        write_table(table, points, records, param_paths)
        echo(progress_line(rec, len(records), len(points)))

    echo(intro + (f" on the Dask scheduler {scheduler}" if scheduler else ""))
    return run_points(points, outdir / RUNS_DIR, workers=workers, scheduler=scheduler,
                      keep_curve=keep_curve, on_record=on_record)
