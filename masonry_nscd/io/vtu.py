r"""VTK output for ParaView: blocks and joint contact points as ``.vtu``, time series as ``.pvd``.

Anything else that needs VTK files calls the functions below. The files are written here
directly (VTK's XML format, every array in raw appended data, compressed block by block with
zlib at level 1), not by meshio, whose base64 text inside the XML and zlib's default level
make larger files more slowly (docs/choices.md). VTK and meshio read them
back to the same arrays (``tests/test_io.py`` reads them with meshio).

What is written
---------------
``write_blocks_vtu``
    an UnstructuredGrid of VTK_HEXAHEDRON cells (VTK type 12). The node order of a cell is the
    VTK one, which is also the order of ``masonry_nscd.fe.hex8``: the bottom face
    (``zeta = -1``) counter-clockwise seen from above, then the top face in the same order. A
    tetrahedron, which the outputs draw as a collapsed hexahedron (``fe.tet4.DRAWN_AS``), is
    written as a VTK_TETRA (type 10) of its four corners.
    Point data are nodal fields (displacement, velocity, ...), cell data element fields
    (block id, damage per Gauss point as ``(ne, 8)``, ...).
``write_points_vtu``
    an UnstructuredGrid of VTK_VERTEX cells, one per point: the joint contact points with
    their fields (d_coh, opening, slip, normal and shear tractions, status, ...).
``write_pvd``
    a ParaView collection (``VTKFile type="Collection"``) listing ``(time, file)`` or
    ``(time, file, part)`` entries; entries sharing a time with different ``part`` numbers are
    shown together (e.g. part 0 the blocks, part 1 the joints).

Units
-----
The writers do not convert anything: give SI arrays (coordinates and displacements in m,
velocities in m/s, tractions and stresses in Pa, times in s) and name the fields accordingly.
Floating arrays are written as Float64 (float32 is kept as Float32), integer arrays with their
own width, boolean arrays as UInt8 (0/1).

Guarantees
----------
- Every array is checked before anything touches the disk: shapes, numeric dtype, and no NaN
  or infinity (``ValueError`` naming the field, e.g. ``point_data['displacement']``).
- Every file is written atomically (:mod:`masonry_nscd.io.atomic`): a failing or
  interrupted write leaves the previous version of the target untouched, never a truncated
  ``.vtu``/``.pvd``. The parent folder is created if missing.

Limitations: a file is built in memory before it is written (its compressed arrays, about
the size of the arrays), and a file with zero points or cells is written uncompressed (VTK
and ParaView read it; meshio reads no file with zero points).
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Mapping, Sequence
from functools import lru_cache
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
from numpy.typing import ArrayLike, NDArray

from masonry_nscd.fe import tet4
from masonry_nscd.io.atomic import PathLike, atomic_write

_NUMERIC_KINDS = "biuf"


def checked_array(name: str, a: ArrayLike) -> NDArray:
    """``a`` as a contiguous, native-endian numeric array; ValueError on NaN/inf or bad dtype."""
    arr = np.asarray(a)
    if arr.dtype.kind not in _NUMERIC_KINDS:
        raise ValueError(f"{name}: numeric array expected, got dtype {arr.dtype}")
    if arr.dtype.kind == "f" and arr.size and not np.isfinite(arr).all():
        bad = np.flatnonzero(~np.isfinite(arr.ravel()))
        raise ValueError(
            f"{name}: {bad.size} non-finite value(s) (NaN or inf), first at flat index {bad[0]}"
        )
    if arr.dtype.kind == "b":
        arr = arr.astype(np.uint8)
    elif arr.dtype.kind == "f" and arr.dtype != np.float32:
        arr = arr.astype(np.float64)  # VTK knows Float32 and Float64 only
    if not arr.dtype.isnative:
        arr = arr.astype(arr.dtype.newbyteorder("="))
    return np.ascontiguousarray(arr)


def _check_name(name: object, where: str) -> str:
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"{where}: field names must be non-empty strings, got {name!r}")
    return name


def _data_arrays(
    where: str, data: Mapping[str, ArrayLike] | None, n: int, what: str
) -> dict[str, NDArray]:
    out: dict[str, NDArray] = {}
    for name, value in (data or {}).items():
        label = f"{where}[{_check_name(name, where)!r}]"
        arr = checked_array(label, value)
        if arr.ndim not in (1, 2) or arr.shape[0] != n:
            raise ValueError(f"{label}: shape ({n},) or ({n}, k) expected ({what}), got {arr.shape}")
        if arr.ndim == 2 and arr.shape[1] == 0:
            raise ValueError(f"{label}: zero components")
        out[name] = arr
    return out


def _points_array(points: ArrayLike) -> NDArray[np.float64]:
    pts = checked_array("points", points)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"points: shape (n, 3) expected, got {pts.shape}")
    return np.ascontiguousarray(pts, dtype=np.float64)


#: VTK's name of each dtype the writers emit (``checked_array`` gives no other)
_VTK_TYPES = {np.dtype(t): n for t, n in (
    (np.float64, "Float64"), (np.float32, "Float32"), (np.int8, "Int8"), (np.uint8, "UInt8"),
    (np.int16, "Int16"), (np.uint16, "UInt16"), (np.int32, "Int32"), (np.uint32, "UInt32"),
    (np.int64, "Int64"), (np.uint64, "UInt64"))}
_CELL_TYPES = {"hexahedron": 12, "vertex": 1}  # VTK_HEXAHEDRON, VTK_VERTEX
VTK_TETRA = tet4.TET4.vtk_type
#: the positions in a collapsed hexahedron of a tetrahedron's four corners (the first of each
#: in ``fe.tet4.DRAWN_AS``)
_TET_CORNERS = np.array([0, 1, 2, 4])
#: bytes per compressed block (VTK's own default is 32 KiB; any size is valid)
BLOCK_BYTES = 1 << 16
#: zlib's level: 1 compresses the study's fields to about the size level 6 gives, in a third
#: of the time (the arrays are mostly doubles, which no level compresses much)
ZLIB_LEVEL = 1
_COMPRESSORS = {"zlib": "vtkZLibDataCompressor", "lzma": "vtkLZMADataCompressor"}


class _Repeats:
    """The compressed bytes of arrays that come again, by their bytes: a run writes the same
    nodes, connectivity and cell types (and often the same all-zero damage fields) into every
    output step's files, and compressing them is half of a file's time. An array is kept from
    its second appearance on (its first only leaves its hash), up to ``budget`` bytes of raw
    and compressed data, the least recently used dropped first."""

    def __init__(self, budget: int = 64 << 20):
        self.budget = budget
        self.seen: set[int] = set()
        self.kept: dict[tuple[bytes, str], bytes] = {}
        self.size = 0

    def get(self, raw: bytes, compression: str) -> bytes | None:
        packed = self.kept.pop((raw, compression), None)
        if packed is not None:
            self.kept[(raw, compression)] = packed  # the most recently used last
        return packed

    def put(self, raw: bytes, compression: str, packed: bytes) -> None:
        key = hash((raw, compression))
        if key not in self.seen:
            if len(self.seen) > 1 << 16:
                self.seen.clear()
            self.seen.add(key)
            return
        if len(raw) + len(packed) > self.budget // 4 or (raw, compression) in self.kept:
            return
        self.kept[(raw, compression)] = packed
        self.size += len(raw) + len(packed)
        while self.size > self.budget:
            oldest = next(iter(self.kept))
            self.size -= len(oldest[0]) + len(self.kept.pop(oldest))


_REPEATS = _Repeats()
#: the cache is shared by the threads that write files (a run's background writer, ``io.recorder``)
_REPEATS_LOCK = threading.Lock()


def _encoded(arr: NDArray, compression: str | None) -> bytes:
    """One array of the appended data: its bytes behind VTK's UInt64 header, ``[nbytes]``
    uncompressed, or ``[nblocks, block size, size of the last block when partial (else 0),
    compressed size of each block]`` followed by the compressed blocks (kept for arrays that
    come again, :class:`_Repeats`)."""
    raw = arr.tobytes()
    if compression is None:
        return np.uint64(len(raw)).tobytes() + raw
    with _REPEATS_LOCK:
        packed = _REPEATS.get(raw, compression)
    if packed is None:
        packed = _compressed(raw, compression)  # outside the lock: zlib lets other threads run
        with _REPEATS_LOCK:
            _REPEATS.put(raw, compression, packed)
    return packed


def _compressed(raw: bytes, compression: str) -> bytes:
    """``raw`` in VTK's compressed blocks, behind their header (:func:`_encoded`)."""
    if compression == "zlib":
        import zlib

        def pack(b: bytes) -> bytes:
            return zlib.compress(b, ZLIB_LEVEL)
    else:
        import lzma

        pack = lzma.compress
    blocks = [pack(raw[i:i + BLOCK_BYTES]) for i in range(0, len(raw), BLOCK_BYTES)]
    header = np.array([len(blocks), BLOCK_BYTES, len(raw) % BLOCK_BYTES,
                       *(len(b) for b in blocks)], dtype=np.uint64)
    return header.tobytes() + b"".join(blocks)


def _collapsed_tetrahedra(cells: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Which rows of hexahedral cells (nc, 8) are tetrahedra drawn as collapsed hexahedra
    (``fe.tet4.DRAWN_AS``: nodes ``a, b, c, c, d, d, d, d``)."""
    same = np.all(cells == cells[:, _TET_CORNERS][:, tet4.DRAWN_AS], axis=1)
    return same & (cells[:, 2] != cells[:, 4])


def _write_mesh(
    path: PathLike,
    points: NDArray[np.float64],
    cell_type: str,
    cells: NDArray[np.int64],
    point_data: dict[str, NDArray],
    cell_data: dict[str, NDArray],
    compression: str | None,
) -> None:
    """An UnstructuredGrid of one cell type, every array in the appended data (raw bytes,
    little or big endian as the machine, UInt64 headers), written atomically."""
    if len(points) == 0 or len(cells) == 0:
        compression = None  # empty arrays: no blocks to compress (and meshio reads them so)
    nc, per = cells.shape
    connectivity, offsets = cells.ravel(), np.arange(per, per * nc + 1, per, dtype=np.int64)
    types = np.full(nc, _CELL_TYPES[cell_type], dtype=np.uint8)
    if cell_type == "hexahedron":
        tet = _collapsed_tetrahedra(cells)
        if tet.any():  # each as a VTK_TETRA of its four corners
            per_cell = np.where(tet, 4, 8)
            offsets = np.cumsum(per_cell).astype(np.int64)
            keep = np.ones(cells.shape, dtype=bool)
            keep[tet] = np.isin(np.arange(8), _TET_CORNERS)
            connectivity = cells[keep]
            types[tet] = VTK_TETRA
    arrays: list[tuple[str, NDArray]] = [
        ('NumberOfComponents="3"', points),
        ('Name="connectivity"', connectivity),
        ('Name="offsets"', offsets),
        ('Name="types"', types),
    ]
    for data in (point_data, cell_data):
        for name, a in data.items():
            k = f' NumberOfComponents="{a.shape[1]}"' if a.ndim == 2 else ""
            arrays.append((f"Name={quoteattr(name)}{k}", a))
    chunks, offsets, at = [], [], 0
    for _, a in arrays:
        chunks.append(_encoded(np.ascontiguousarray(a), compression))
        offsets.append(at)
        at += len(chunks[-1])
    tags = [f'<DataArray type="{_VTK_TYPES[a.dtype]}" {attrs} format="appended" '
            f'offset="{off}"/>' for (attrs, a), off in zip(arrays, offsets, strict=True)]
    n_pd = len(point_data)
    order = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
    comp = f' compressor="{_COMPRESSORS[compression]}"' if compression else ""
    head = "\n".join([
        '<?xml version="1.0"?>',
        (f'<VTKFile type="UnstructuredGrid" version="1.0" byte_order="{order}" '
         f'header_type="UInt64"{comp}>'),
        "<UnstructuredGrid>",
        f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{nc}">',
        "<Points>", tags[0], "</Points>",
        "<Cells>", *tags[1:4], "</Cells>",
        "<PointData>", *tags[4:4 + n_pd], "</PointData>",
        "<CellData>", *tags[4 + n_pd:], "</CellData>",
        "</Piece>",
        "</UnstructuredGrid>",
        '<AppendedData encoding="raw">',
        "_"])

    atomic_write(path, lambda tmp: _write_file(tmp, head.encode(), chunks))


def _write_file(tmp: str, head: bytes, chunks: list[bytes]) -> None:
    """The bytes of a .vtu: the XML up to the appended data's ``_``, the arrays, the end."""
    with open(tmp, "wb") as f:
        f.write(head)
        f.writelines(chunks)
        f.write(b"\n</AppendedData>\n</VTKFile>\n")


class VtuFile:
    """A .vtu file checked and ready to write: its arrays validated (module docstring,
    "Guarantees") and copied, so that the caller may change its own arrays before
    :meth:`write` runs (on another thread, say). Made by :func:`blocks_file` and
    :func:`points_file`."""

    def __init__(self, points: NDArray, cell_type: str, cells: NDArray,
                 point_data: dict[str, NDArray], cell_data: dict[str, NDArray],
                 compression: str | None):
        if compression not in (None, *_COMPRESSORS):
            raise ValueError(f"compression: zlib, lzma or None, got {compression!r}")
        self._args = (points.copy(), cell_type, cells.copy(),
                      {k: v.copy() for k, v in point_data.items()},
                      {k: v.copy() for k, v in cell_data.items()}, compression)

    def write(self, path: PathLike) -> None:
        """Encode the arrays and write the file ``path``, atomically."""
        _write_mesh(path, *self._args)


def blocks_file(
    points: ArrayLike,
    hexes: ArrayLike,
    point_data: Mapping[str, ArrayLike] | None = None,
    cell_data: Mapping[str, ArrayLike] | None = None,
    *,
    compression: str | None = "zlib",
) -> VtuFile:
    """Hexahedral blocks as a checked :class:`VtuFile` (arguments of :func:`write_blocks_vtu`;
    ValueError naming the field on a bad array)."""
    pts = _points_array(points)
    h = checked_array("hexes", hexes)
    if h.dtype.kind not in "iu" or h.ndim != 2 or h.shape[1] != 8:
        raise ValueError(f"hexes: integer array of shape (ne, 8) expected, got {h.dtype} {h.shape}")
    if h.size and (h.min() < 0 or h.max() >= len(pts)):
        raise ValueError(f"hexes: node indices must lie in [0, {len(pts)}), got {h.min()}..{h.max()}")
    pd = _data_arrays("point_data", point_data, len(pts), "one row per node")
    cd = _data_arrays("cell_data", cell_data, len(h), "one row per hexahedron")
    return VtuFile(pts, "hexahedron", h.astype(np.int64), pd, cd, compression)


def points_file(
    points: ArrayLike,
    point_data: Mapping[str, ArrayLike] | None = None,
    *,
    compression: str | None = "zlib",
) -> VtuFile:
    """A cloud of points as a checked :class:`VtuFile` (arguments of
    :func:`write_points_vtu`)."""
    pts = _points_array(points)
    pd = _data_arrays("point_data", point_data, len(pts), "one row per point")
    vertices = np.arange(len(pts), dtype=np.int64).reshape(-1, 1)
    return VtuFile(pts, "vertex", vertices, pd, {}, compression)


def write_blocks_vtu(
    path: PathLike,
    points: ArrayLike,
    hexes: ArrayLike,
    point_data: Mapping[str, ArrayLike] | None = None,
    cell_data: Mapping[str, ArrayLike] | None = None,
    *,
    compression: str | None = "zlib",
) -> None:
    """Write hexahedral blocks to ``path`` (.vtu), atomically.

    points: (n, 3) node coordinates, m (current or reference configuration, the caller's
    choice; give the displacement as point data so that ParaView's "Warp By Vector" works).
    hexes: (ne, 8) node indices in VTK_HEXAHEDRON order (that of ``fe.hex8``), 0-based.
    point_data: name -> (n,) or (n, k) arrays; cell_data: name -> (ne,) or (ne, k) arrays.
    compression: "zlib" (default), "lzma" or None.
    """
    blocks_file(points, hexes, point_data, cell_data, compression=compression).write(path)


def write_points_vtu(
    path: PathLike,
    points: ArrayLike,
    point_data: Mapping[str, ArrayLike] | None = None,
    *,
    compression: str | None = "zlib",
) -> None:
    """Write a cloud of points (one VTK_VERTEX cell each) to ``path`` (.vtu), atomically.

    points: (m, 3) coordinates, m. point_data: name -> (m,) or (m, k) arrays (e.g. d_coh,
    opening and slip in m, normal and shear tractions in Pa, status as integers).
    """
    points_file(points, point_data, compression=compression).write(path)


@lru_cache(maxsize=1 << 16)
def _pvd_line(t: float, name: str, part: int, parent: str) -> str:
    """One ``DataSet`` line of a collection in folder ``parent`` (absolute). Cached: a run
    writes its collection again at every output step with one more entry per file, and
    formatting every entry each time would make that quadratic in the number of entries."""
    if os.path.isabs(name):
        name = os.path.relpath(name, parent)
    # the XML by hand: one formatted line per entry, no tree built at every output step
    return (f'    <DataSet timestep="{t!r}" group="" part="{part}" '
            f'file={quoteattr(Path(name).as_posix())} />')


def write_pvd(path: PathLike, entries: Sequence[tuple[float, str] | tuple[float, str, int]]) -> None:
    """Write a ParaView collection ``path`` (.pvd) listing the entries, atomically.

    entries: ``(time, file)`` or ``(time, file, part)``; time in s (finite), file relative to
    the folder of ``path`` (an absolute file name is made relative to it, so the output folder
    can be moved), part a non-negative int (0 when omitted). The order is kept; ParaView sorts
    by time. Call it again with the grown list after each output step: the collection on disk
    is complete and valid at all times.
    """
    target = Path(path)
    parent = os.path.abspath(target.parent)
    lines = ['<?xml version="1.0" encoding="utf-8"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for i, entry in enumerate(entries):
        if len(entry) not in (2, 3):
            raise ValueError(f"entries[{i}]: (time, file) or (time, file, part) expected")
        time, file = entry[0], entry[1]
        part = entry[2] if len(entry) == 3 else 0
        t = float(time)
        if not np.isfinite(t):
            raise ValueError(f"entries[{i}]: time is {t}")
        if isinstance(part, bool) or not isinstance(part, int | np.integer) or part < 0:
            raise ValueError(f"entries[{i}]: part must be a non-negative int, got {part!r}")
        name = os.fspath(file)
        if not name:
            raise ValueError(f"entries[{i}]: empty file name")
        lines.append(_pvd_line(t, name, int(part), parent))
    lines += ["  </Collection>", "</VTKFile>", ""]
    text = "\n".join(lines)

    def write(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)

    atomic_write(target, write)
