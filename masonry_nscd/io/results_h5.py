r"""Results of a run in one HDF5 file (h5py): the case, the mesh, output steps and curves.

Layout
------
::

    /                      attrs: format="masonry_nscd.results", format_version=1, + caller's attrs
    /case/yaml             the case file as given (UTF-8 string dataset)
    /mesh/<name>           arrays given once (nodes, hexes, block_of_element, contact_points, ...)
    /steps/000123          one group per output step, attrs step (int) and time (s)
    /steps/000123/<field>  the step's arrays (displacement, velocity, damage, d_coh, tractions ...)
    /curve/<column>        1-D columns (e.g. time, imposed displacement, reaction force),
                           rewritten in place by each ``write_curve``

Step groups are named with at least six digits; read them back sorted by their ``step``
attribute (``read_results`` does). Datasets keep the caller's dtype (floating point as given,
integers as given, booleans as HDF5 enums).

Units
-----
Nothing is converted: give SI arrays (m, m/s, Pa, N, s, kg) and say the unit in the field name
or in the root attrs when it is not obvious.

Guarantees (tested in tests/test_io.py)
---------------------------------------
- Every array, attribute and the time is checked before the file is touched: numeric dtype,
  no NaN or infinity (``ValueError`` naming the field, e.g. ``fields['displacement']``), no
  duplicate step. A refused step leaves the file as it was.
- The file is not kept open between calls. The constructor writes the case and mesh to a
  temporary file beside ``path`` and renames it onto ``path`` (an older results file there is
  replaced only once the new one is complete); ``write_step`` and ``write_curve`` each open
  the file, write, close it and fsync it. Hence, between two calls:
  * the file is a complete, closed HDF5 file: a process killed at any moment outside a call
    (``os._exit``, SIGKILL, an exception that never reaches ``close``) leaves every step
    written so far readable by a plain ``h5py.File(path, "r")``;
  * other processes can open and read it with default h5py options while the run goes on;
  * a reader that keeps the file open does not block the writer (the writer opens it with
    ``locking=False``); such a reader may see stale or, during a write, inconsistent data:
    reopen the file to see new steps.
- The file uses ``libver="latest"`` (superblock v3). While a call is writing (typically
  milliseconds per step), the superblock carries the "open for write" flag and readers get
  ``OSError: ... file is already open for write``: ``read_results`` retries for ``wait_s``
  seconds. If the process is killed *during* a call, the flag stays set and the file may be
  inconsistent: readers refuse it; ``h5clear -s results.h5`` (HDF5 tools) clears the flag and
  the steps written before are usually readable. HDF5 offers no stronger guarantee for a
  write that is cut in the middle.
- ``ResultsFile.reopen`` continues an existing file (a resumed run): the steps after a given
  one and the curve rows beyond a given length are dropped on a copy that then replaces the
  file, so an interruption there also leaves the file as it was.
- Not guarded: two writers on the same path (the second one replaces the file).

Reading
-------
Every reader opens the file through :func:`open_for_reading` (which waits while a writer holds
it): :func:`read_results` reads the whole file; for the post-processing of a run folder,
:func:`output_steps` lists its complete output steps, :func:`read_fields` gives the mesh and
the fields of one of them (:class:`RunFields`), :func:`read_mesh_arrays` some arrays of the
mesh and :func:`read_step_field` one field over the output steps. No module outside ``io/``
opens the file itself.
"""

from __future__ import annotations

import contextlib
import shutil
import time as _time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, NamedTuple, Self

import h5py
import numpy as np
from numpy.typing import ArrayLike, NDArray

from masonry_nscd.io.atomic import PathLike, atomic_write, fsync_file

FORMAT = "masonry_nscd.results"
FORMAT_VERSION = 1
LIBVER = "latest"
_CURVE_CHUNK = 1024


class StepRecord(NamedTuple):
    """One output step read back: step number, time (s), fields by name."""

    step: int
    time: float
    fields: dict[str, NDArray]


def _check_name(name: object, where: str) -> str:
    if not isinstance(name, str) or not name or "/" in name or name in (".", ".."):
        raise ValueError(f"{where}: names must be non-empty strings without '/', got {name!r}")
    return name


def _checked(label: str, a: ArrayLike) -> NDArray:
    arr = np.asarray(a)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"{label}: numeric array expected, got dtype {arr.dtype}")
    if arr.dtype.kind == "f" and arr.size and not np.isfinite(arr).all():
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))
        raise ValueError(
            f"{label}: {bad.size} non-finite value(s) (NaN or inf), first at flat index {bad[0]}"
        )
    return np.ascontiguousarray(arr)


def _checked_dict(where: str, data: Mapping[str, ArrayLike] | None) -> dict[str, NDArray]:
    if data is not None and not isinstance(data, Mapping):
        raise TypeError(f"{where}: a mapping name -> array expected")
    return {
        _check_name(k, where): _checked(f"{where}[{k!r}]", v) for k, v in (data or {}).items()
    }


def _checked_attrs(attrs: Mapping[str, Any] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in (attrs or {}).items():
        if not isinstance(k, str) or not k:
            raise ValueError(f"attrs: names must be non-empty strings, got {k!r}")
        if isinstance(v, str):
            out[k] = v
        else:
            out[k] = _checked(f"attrs[{k!r}]", v)
    return out


def _create_dataset(group: h5py.Group, name: str, arr: NDArray, compression: str | None) -> None:
    """``group[name] = arr``; uncompressed through h5py's low-level calls (contiguous layout,
    as the high-level call makes it; an output step writes a dozen datasets, and the
    low-level calls skip the high-level call's checks and property lists for each)."""
    if compression is not None and arr.ndim >= 1 and arr.size > 0:
        group.create_dataset(name, data=arr, compression=compression, shuffle=True)
        return
    if arr.dtype.kind == "b":  # h5py's enum of bools: the high-level call knows it
        group.create_dataset(name, data=arr)
        return
    arr = np.ascontiguousarray(arr)
    space = (h5py.h5s.create_simple(arr.shape) if arr.ndim
             else h5py.h5s.create(h5py.h5s.SCALAR))
    dset = h5py.h5d.create(group.id, name.encode(), h5py.h5t.py_create(arr.dtype), space)
    if arr.size:
        dset.write(h5py.h5s.ALL, h5py.h5s.ALL, arr)


def _rewrite_column(curve: h5py.Group, name: str, v: NDArray) -> bool:
    """Resize the 1-D dataset ``curve/name`` to ``len(v)`` and write ``v`` into it, through
    h5py's low-level calls (a third of the high-level ones' time for the 17 columns of a run's
    curve); False, nothing written, when there is no such dataset of ``v``'s dtype that can
    grow without bound."""
    key = name.encode()
    if not curve.id.__contains__(key):
        return False
    obj = h5py.h5o.open(curve.id, key)
    if not isinstance(obj, h5py.h5d.DatasetID) or obj.dtype != v.dtype:
        return False
    space = obj.get_space()
    if space.get_simple_extent_ndims() != 1 or \
            space.get_simple_extent_dims(maxdims=True) != (h5py.h5s.UNLIMITED,):
        return False
    obj.set_extent((len(v),))
    if len(v):
        obj.write(h5py.h5s.create_simple((len(v),)), obj.get_space(), np.ascontiguousarray(v))
    return True


class ResultsFile:
    """Writer of a results file; see the module docstring for the layout and guarantees.

    ``ResultsFile(path, case_yaml, mesh, attrs)`` creates the file (replacing an older one);
    use it as a context manager or call ``close()``. ``compression`` ("gzip", "lzf" or None)
    applies to the mesh and step arrays.
    """

    def __init__(
        self,
        path: PathLike,
        case_yaml: str,
        mesh: Mapping[str, ArrayLike],
        attrs: Mapping[str, Any] | None = None,
        *,
        compression: str | None = None,
    ) -> None:
        if not isinstance(case_yaml, str):
            raise TypeError("case_yaml: the text of the case file (str) expected")
        mesh_arrays = _checked_dict("mesh", mesh)
        root_attrs = _checked_attrs(attrs)
        self.path = Path(path)
        self.compression = compression
        self._closed = False
        self._steps: set[int] = set()

        def create(tmp: str) -> None:
            with h5py.File(tmp, "w", libver=LIBVER) as f:
                f.attrs["format"] = FORMAT
                f.attrs["format_version"] = FORMAT_VERSION
                for k, v in root_attrs.items():
                    f.attrs[k] = v
                f.create_group("case").create_dataset(
                    "yaml", data=case_yaml, dtype=h5py.string_dtype("utf-8")
                )
                g = f.create_group("mesh")
                for k, v in mesh_arrays.items():
                    _create_dataset(g, k, v, compression)
                f.create_group("steps")
                f.create_group("curve")

        atomic_write(self.path, create)

    @classmethod
    def reopen(
        cls,
        path: PathLike,
        *,
        last_step: int | None = None,
        curve_length: int | None = None,
        compression: str | None = None,
    ) -> Self:
        """Continue writing an existing results file (a resumed run).

        Step groups after ``last_step`` and unfinished ones (no step/time attributes) are
        removed, and curve columns longer than ``curve_length`` are cut to it, so that the file
        ends where the run resumes. Those changes are made on a copy that then replaces
        ``path`` (``os.replace``): an interruption leaves the file as it was. Raises
        ``FileNotFoundError``, ``OSError`` (unreadable, or still flagged as open for write),
        ``ValueError`` (not a results file of this format).
        """
        target = Path(path)
        with open_for_reading(target, 0.5) as f:
            if _attr(f.attrs.get("format")) != FORMAT or "steps" not in f or "curve" not in f:
                raise ValueError(f"{target}: not a {FORMAT} file")
            kept: set[int] = set()
            drop: list[str] = []
            for name, g in f["steps"].items():
                done = "step" in g.attrs and "time" in g.attrs
                step = int(g.attrs["step"]) if done else None
                if step is None or (last_step is not None and step > last_step):
                    drop.append(name)
                else:
                    kept.add(step)
            trim = curve_length is not None and any(
                len(ds) > curve_length for ds in f["curve"].values()
            )
        if drop or trim:
            def cut(tmp: str) -> None:
                shutil.copyfile(target, tmp)
                with h5py.File(tmp, "r+", libver=LIBVER, locking=False) as f:
                    for name in drop:
                        del f["steps"][name]
                    if trim:
                        for ds in f["curve"].values():
                            if len(ds) > curve_length:
                                ds.resize((curve_length,))

            atomic_write(target, cut)
        self = cls.__new__(cls)
        self.path = target
        self.compression = compression
        self._closed = False
        self._steps = kept
        return self

    # -- context manager -------------------------------------------------------------------
    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Mark the writer closed (the file itself is closed after every call already)."""
        self._closed = True

    def _open(self) -> h5py.File:
        if self._closed:
            raise RuntimeError(f"{self.path}: ResultsFile is closed")
        return h5py.File(self.path, "r+", libver=LIBVER, locking=False)

    # -- writing ---------------------------------------------------------------------------
    def write_step(self, step: int, time: float, fields: Mapping[str, ArrayLike]) -> None:
        """Append output step ``step`` (int >= 0, not yet written) at ``time`` (s)."""
        append = self.staged_step(step, time, fields)
        try:
            append()
        except BaseException:
            self._steps.discard(int(step))  # not written: it may be given again
            raise

    def staged_step(self, step: int, time: float,
                    fields: Mapping[str, ArrayLike]) -> Callable[[], None]:
        """Check output step ``step`` now, as :meth:`write_step` does (ValueError, the file
        untouched), and return the call that appends it, to be made later and on any thread
        (a run's recorder hands it to its background writer): it holds copies of the arrays,
        so the caller may change them at once. The step counts as written from now on."""
        if isinstance(step, bool) or not isinstance(step, int | np.integer) or step < 0:
            raise ValueError(f"step must be a non-negative int, got {step!r}")
        step = int(step)
        t = float(time)
        if not np.isfinite(t):
            raise ValueError(f"time: {t} is not finite")
        arrays = {k: np.array(v) for k, v in _checked_dict("fields", fields).items()}
        name = f"{step:06d}"
        if step in self._steps:
            raise ValueError(f"step {step} already written")
        self._steps.add(step)

        def append() -> None:
            with self._open() as f:
                steps = f["steps"]
                if name in steps:
                    raise ValueError(f"step {step} already written")
                g = steps.create_group(name)
                try:
                    for k, v in arrays.items():
                        _create_dataset(g, k, v, self.compression)
                    # the attrs go last: a group without them is an unfinished step
                    g.attrs["step"] = step
                    g.attrs["time"] = t
                except BaseException:
                    with contextlib.suppress(Exception):
                        del steps[name]
                    raise
            fsync_file(self.path)

        return append

    def write_curve(self, columns: Mapping[str, ArrayLike]) -> None:
        """Write or replace the 1-D columns ``/curve/<name>`` (same length within one call).

        Columns not named are kept. A column is rewritten in place (resizable dataset), so
        calling this after every step does not grow the file beyond the data.
        """
        arrays = _checked_dict("columns", columns)
        lengths = {k: v.shape for k, v in arrays.items()}
        if any(len(s) != 1 for s in lengths.values()):
            raise ValueError(f"columns: 1-D arrays expected, got shapes {lengths}")
        if len({s[0] for s in lengths.values()}) > 1:
            raise ValueError(f"columns: all columns of one call must have one length: {lengths}")
        with self._open() as f:
            curve = f["curve"]
            for k, v in arrays.items():
                if v.dtype.kind == "f":
                    v = v.astype(np.float64)
                elif v.dtype.kind in "iu":
                    v = v.astype(np.int64)
                if not _rewrite_column(curve, k, v):
                    if k in curve:
                        del curve[k]
                    curve.create_dataset(
                        k, data=v, maxshape=(None,), chunks=(_CURVE_CHUNK,)
                    )
        fsync_file(self.path)


# -- reading -------------------------------------------------------------------------------
def open_for_reading(path: PathLike, wait_s: float) -> h5py.File:
    """The results file at ``path`` opened for reading (an ``h5py.File``, to be closed by the
    caller, e.g. ``with``). While a writer holds the file (the "open for write" flag, module
    docstring) the open is retried for ``wait_s`` seconds, then an OSError says how to clear
    the flag."""
    deadline = _time.monotonic() + wait_s
    while True:
        try:
            return h5py.File(path, "r")
        except OSError as e:
            if "already open for write" not in str(e) or _time.monotonic() >= deadline:
                if "already open for write" in str(e):
                    raise OSError(
                        f"{path}: still flagged as open for write after {wait_s} s; if the "
                        "writer was killed during a write, `h5clear -s` clears the flag"
                    ) from e
                raise
            _time.sleep(0.01)


def _attr(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def read_results(path: PathLike, *, wait_s: float = 2.0) -> dict[str, Any]:
    """Read a whole results file into memory (for tests and post-processing).

    Returns ``{"case_yaml": str, "mesh": {name: array}, "steps": [StepRecord(step, time,
    fields)] sorted by step, "curve": {name: array}, "attrs": {name: value}}``. Step groups
    without their step/time attributes (an interrupted write) are skipped. If the file is
    being written, retries for ``wait_s`` seconds.
    """
    with open_for_reading(path, wait_s) as f:
        attrs = {k: _attr(v) for k, v in f.attrs.items()}
        case_yaml = f["case/yaml"].asstr()[()]
        mesh = {k: ds[()] for k, ds in f["mesh"].items()}
        steps = []
        for g in f["steps"].values():
            if "step" not in g.attrs or "time" not in g.attrs:
                continue
            fields = {k: ds[()] for k, ds in g.items()}
            steps.append(StepRecord(int(g.attrs["step"]), float(g.attrs["time"]), fields))
        steps.sort(key=lambda s: s.step)
        curve = {k: ds[()] for k, ds in f["curve"].items()}
    return {"case_yaml": case_yaml, "mesh": mesh, "steps": steps, "curve": curve, "attrs": attrs}


# -- a run's output steps: the mesh and fields the recorder writes ------------------------------
#: Float arrays of a run's fields (SI units).
FloatArray = NDArray[np.float64]


@dataclass
class RunFields:
    """The mesh and the fields of one output step (SI units, damages dimensionless)."""

    nodes_m: FloatArray  # (nn, 3) reference coordinates
    hexes: NDArray[np.int64]  # (ne, 8) VTK order: the z-min face first, counter-clockwise
    block_of_element: NDArray[np.int64]  # (ne,) position of the element's body in the structure
    structure_bodies: NDArray[np.int64]  # (nb,) scene index of each structure body
    contact_points_m: FloatArray  # (npt, 3)
    contact_group: NDArray[np.int64]  # (npt,) joint group id (scene.json "groups")
    contact_bodies: NDArray[np.int64]  # (npt, 2) candidate and antagonist body (scene indices)
    contact_area_m2: FloatArray  # (npt,)
    contact_frame: FloatArray  # (npt, 3, 3) rows n (antagonist to candidate), t, s
    contact_gap_m: FloatArray  # (npt,)
    contact_initial_damage: FloatArray  # (npt,) d_0 of the point's law
    d_c: FloatArray  # (ne,) post-peak compressive damage
    d_cpp: FloatArray  # (ne,) pre-peak compressive damage
    d_t: FloatArray  # (ne,) largest tensile damage
    joint_beta: FloatArray  # (npt,) integrity, 1 as built
    step: int
    time_s: float
    nodal_displacement_m: FloatArray | None = None  # (nn, 3)
    joint_u_m: FloatArray | None = None  # (npt, 3) relative displacements (n, t, s)
    joint_T_Pa: FloatArray | None = None  # (npt, 3) tractions (n, t, s); compression n < 0

    @property
    def joint_d_coh(self) -> FloatArray:
        """Total cohesive damage ``1 - beta (1 - d_0)`` per contact point."""
        return 1.0 - self.joint_beta * (1.0 - self.contact_initial_damage)


def output_steps(h5_path: Path | str) -> list[tuple[int, float]]:
    """``(step, time_s)`` of every complete output step of a results file, in order (waits up
    to 2 s for a run that is writing the file, as :func:`read_results` does)."""
    with open_for_reading(h5_path, 2.0) as f:
        out = [(int(g.attrs["step"]), float(g.attrs["time"])) for g in f["steps"].values()
               if "step" in g.attrs and "time" in g.attrs]
    return sorted(out)


def read_fields(h5_path: Path | str, step: int | None = None) -> RunFields | None:
    """The fields of output ``step`` (default: the last one) of a results file; ``None`` if
    the file has no complete output step."""
    steps = output_steps(h5_path)
    if not steps:
        return None
    if step is None:
        step = steps[-1][0]
    with open_for_reading(h5_path, 2.0) as f:
        mesh = {k: ds[()] for k, ds in f["mesh"].items()}
        g = f["steps"][f"{step:06d}"]
        data = {k: ds[()] for k, ds in g.items()}
        time_s = float(g.attrs["time"])
    ne = len(mesh["hexes"])
    return RunFields(
        nodes_m=mesh["nodes_m"], hexes=mesh["hexes"], block_of_element=mesh["block_of_element"],
        structure_bodies=mesh["structure_bodies"], contact_points_m=mesh["contact_points_m"],
        contact_group=mesh["contact_group"],
        contact_bodies=mesh["contact_bodies"], contact_area_m2=mesh["contact_area_m2"],
        contact_frame=mesh["contact_frame"], contact_gap_m=mesh["contact_gap_m"],
        contact_initial_damage=mesh["contact_initial_damage"],
        d_c=data.get("element_d_c", np.zeros(ne)), d_cpp=data.get("element_d_cpp", np.zeros(ne)),
        d_t=data.get("element_d_t", np.zeros(ne)), joint_beta=data["joint_beta"],
        step=int(step), time_s=time_s, nodal_displacement_m=data.get("nodal_displacement_m"),
        joint_u_m=data.get("joint_u_m"), joint_T_Pa=data.get("joint_T_Pa"))


def read_mesh_arrays(h5_path: PathLike, names: Sequence[str]) -> dict[str, NDArray]:
    """The arrays ``names`` of the ``mesh`` group of a results file (waits up to 2 s for a run
    that is writing the file)."""
    with open_for_reading(h5_path, 2.0) as f:
        return {k: f["mesh"][k][()] for k in names}


def read_step_field(h5_path: PathLike, name: str, *,
                    last: int | None = None) -> list[tuple[int, NDArray]]:
    """``(step, array)`` of the field ``name`` at every complete output step of a results file
    (those with their step and time attributes), in the order of the steps; only the ``last``
    ones when given. Waits up to 2 s for a run that is writing the file."""
    with open_for_reading(h5_path, 2.0) as f:
        if "steps" not in f:
            return []
        steps = sorted((int(g.attrs["step"]), key) for key, g in f["steps"].items()
                       if "step" in g.attrs and "time" in g.attrs)
        if last is not None:
            steps = steps[max(0, len(steps) - last):]
        return [(step, f["steps"][key][name][()]) for step, key in steps]
