"""Output files: VTU/PVD (read back with meshio and xml.etree) and the HDF5 results file.

Checks the round trips (names, shapes, values bit for bit), the refusal of NaN/inf, the atomic
replacement of VTU/PVD files, and that a results file stays readable by another process while
the writer runs and after the writer is killed without closing it.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

from masonry_nscd.io import vtu
from masonry_nscd.io.results_h5 import ResultsFile, _rewrite_column, read_results

REPO = Path(__file__).resolve().parents[1]


def two_hexes():
    """Two unit cubes side by side along x: 12 nodes, hex8/VTK node order."""
    x, y, z = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0], [0.0, 1.0], indexing="ij")
    pts = np.column_stack([x.ravel(), y.ravel(), z.ravel()])

    def node(i, j, k):
        return i * 4 + j * 2 + k

    hexes = np.array(
        [
            [node(i, 0, 0), node(i + 1, 0, 0), node(i + 1, 1, 0), node(i, 1, 0),
             node(i, 0, 1), node(i + 1, 0, 1), node(i + 1, 1, 1), node(i, 1, 1)]
            for i in range(2)
        ]
    )
    return pts, hexes


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# -- VTU / PVD ------------------------------------------------------------------------------
def test_blocks_vtu_round_trip(tmp_path):
    pts, hexes = two_hexes()
    rng = np.random.default_rng(0)
    u = rng.normal(size=(12, 3)) * 1e-4
    pd = {"displacement": u, "temperature": np.linspace(0.0, 1.0, 12)}
    cd = {
        "block": np.array([3, 7]),
        "damage_gauss": rng.uniform(size=(2, 8)),
        "broken": np.array([True, False]),
    }
    path = tmp_path / "vtu" / "blocks_000001.vtu"
    vtu.write_blocks_vtu(path, pts, hexes, pd, cd)

    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, pts)
    assert [c.type for c in m.cells] == ["hexahedron"]
    np.testing.assert_array_equal(m.cells[0].data, hexes)
    assert set(m.point_data) == set(pd)
    for k, v in pd.items():
        np.testing.assert_array_equal(m.point_data[k], v)
    assert set(m.cell_data) == set(cd)
    for k, v in cd.items():
        np.testing.assert_array_equal(m.cell_data[k][0], v)
    assert m.cell_data["broken"][0].dtype == np.uint8
    # VTK_HEXAHEDRON is cell type 12
    assert b'Name="types"' in path.read_bytes()
    assert leftovers(path.parent) == []


def test_hex_node_order_gives_positive_volume(tmp_path):
    """The order written is the VTK one: bottom face counter-clockwise (normal up), then top."""
    pts, hexes = two_hexes()
    vtu.write_blocks_vtu(tmp_path / "b.vtu", pts, hexes, {}, {})
    m = meshio.read(tmp_path / "b.vtu")
    c = m.points[m.cells[0].data[0]]
    bottom_normal = np.cross(c[1] - c[0], c[3] - c[0])
    assert np.dot(bottom_normal, c[4] - c[0]) > 0.0


def test_points_vtu_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    pts = rng.uniform(size=(5, 3))
    pd = {
        "d_coh": rng.uniform(size=5),
        "opening": rng.normal(size=5) * 1e-5,
        "slip": rng.normal(size=(5, 2)) * 1e-5,
        "traction_n": rng.normal(size=5) * 1e5,
        "traction_t": rng.normal(size=(5, 3)) * 1e5,
        "normal": np.tile([0.0, 0.0, 1.0], (5, 1)),
        "status": np.array([0, 1, 2, 1, 0], dtype=np.int8),
    }
    path = tmp_path / "joints.vtu"
    vtu.write_points_vtu(path, pts, pd)
    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, pts)
    assert [c.type for c in m.cells] == ["vertex"]
    np.testing.assert_array_equal(m.cells[0].data.ravel(), np.arange(5))
    assert set(m.point_data) == set(pd)
    for k, v in pd.items():
        np.testing.assert_array_equal(m.point_data[k], v)
        assert m.point_data[k].dtype == v.dtype


def test_pvd_lists_files_times_and_parts(tmp_path):
    entries = [
        (0.0, "vtu/blocks_000000.vtu", 0),
        (0.0, "vtu/joints_000000.vtu", 1),
        (0.1, "vtu/blocks_000001.vtu", 0),
        (0.1, str(tmp_path / "vtu" / "joints_000001.vtu"), 1),  # absolute: made relative
        (1e-5 + 0.2, "vtu/single.vtu"),  # part defaults to 0
    ]
    path = tmp_path / "run.pvd"
    vtu.write_pvd(path, entries)
    root = ET.parse(path).getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    rows = [
        (float(d.get("timestep")), d.get("file"), int(d.get("part")))
        for d in root.find("Collection").findall("DataSet")
    ]
    assert rows == [
        (0.0, "vtu/blocks_000000.vtu", 0),
        (0.0, "vtu/joints_000000.vtu", 1),
        (0.1, "vtu/blocks_000001.vtu", 0),
        (0.1, "vtu/joints_000001.vtu", 1),
        (1e-5 + 0.2, "vtu/single.vtu", 0),
    ]
    assert leftovers(tmp_path) == []


def test_pvd_refuses_bad_entries(tmp_path):
    path = tmp_path / "run.pvd"
    vtu.write_pvd(path, [(0.0, "a.vtu")])
    before = path.read_bytes()
    with pytest.raises(ValueError, match="time"):
        vtu.write_pvd(path, [(0.0, "a.vtu"), (float("nan"), "b.vtu")])
    with pytest.raises(ValueError, match="part"):
        vtu.write_pvd(path, [(0.0, "a.vtu", -1)])
    assert path.read_bytes() == before
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize(
    ("field", "where"),
    [("points", "points"), ("displacement", "point_data['displacement']"),
     ("damage", "cell_data['damage']")],
)
def test_nan_is_refused_and_previous_file_kept(tmp_path, field, where):
    pts, hexes = two_hexes()
    pd = {"displacement": np.zeros((12, 3))}
    cd = {"damage": np.zeros(2)}
    path = tmp_path / "blocks.vtu"
    vtu.write_blocks_vtu(path, pts, hexes, pd, cd)
    before = path.read_bytes()

    bad_pts = pts.copy()
    if field == "points":
        bad_pts[3, 1] = np.inf
    elif field == "displacement":
        pd["displacement"][5, 2] = np.nan
    else:
        cd["damage"][1] = np.nan
    with pytest.raises(ValueError) as info:
        vtu.write_blocks_vtu(path, bad_pts, hexes, pd, cd)
    assert where in str(info.value)
    assert path.read_bytes() == before
    assert leftovers(tmp_path) == []


def test_failure_during_write_keeps_previous_file(tmp_path, monkeypatch):
    """A writer that dies half way (disk full, interrupt) leaves the old file in place."""
    pts = np.zeros((3, 3))
    path = tmp_path / "joints.vtu"
    vtu.write_points_vtu(path, pts, {"d_coh": np.ones(3)})
    before = path.read_bytes()

    def broken_write(filename, head, chunks):
        Path(filename).write_bytes(head[: len(head) // 2])
        raise OSError("disk full")

    monkeypatch.setattr(vtu, "_write_file", broken_write)
    with pytest.raises(OSError, match="disk full"):
        vtu.write_points_vtu(path, pts, {"d_coh": np.zeros(3)})
    assert path.read_bytes() == before
    assert leftovers(tmp_path) == []


def test_shape_errors(tmp_path):
    pts, hexes = two_hexes()
    with pytest.raises(ValueError, match="hexes"):
        vtu.write_blocks_vtu(tmp_path / "a.vtu", pts, hexes[:, :4])
    with pytest.raises(ValueError, match="node indices"):
        vtu.write_blocks_vtu(tmp_path / "a.vtu", pts, hexes + 10)
    with pytest.raises(ValueError, match="temperature"):
        vtu.write_blocks_vtu(tmp_path / "a.vtu", pts, hexes, {"temperature": np.zeros(11)})
    with pytest.raises(ValueError, match="cell_data"):
        vtu.write_blocks_vtu(tmp_path / "a.vtu", pts, hexes, None, {"damage": np.zeros(12)})
    assert not (tmp_path / "a.vtu").exists()


def test_a_checked_vtu_file_keeps_the_values_it_was_given(tmp_path):
    # the recorder writes it later, on its background thread, while the run changes its arrays
    # (float64 arrays are converted, so copied, when checked; float32 and integers are not)
    pts, hexes = two_hexes()
    u = np.full((12, 3), 1e-3, dtype=np.float32)
    block = np.array([3, 7])
    f = vtu.blocks_file(pts, hexes, {"displacement": u}, {"block": block})
    hexes[:] = hexes[::-1]
    u[:] = 7.0
    block[:] = 0
    f.write(tmp_path / "later.vtu")
    m = meshio.read(tmp_path / "later.vtu")
    assert np.array_equal(m.cells[0].data, two_hexes()[1])
    assert np.array_equal(m.point_data["displacement"], np.full((12, 3), 1e-3, dtype=np.float32))
    assert np.array_equal(m.cell_data["block"][0], [3, 7])


def test_background_writer_writes_in_order_and_keeps_its_first_error(tmp_path):
    from masonry_nscd.errors import RunOutputError
    from masonry_nscd.io.background import BackgroundWriter

    made = []

    def write(path):
        made.append(Path(path).name)
        if Path(path).name == "b":
            raise PermissionError(13, "Permission denied", str(path))
        Path(path).write_text("x")

    w = BackgroundWriter()
    w.submit(write, tmp_path / "a")
    w.wait()
    assert (tmp_path / "a").read_text() == "x" and made == ["a"]
    w.submit(write, tmp_path / "b")
    for _ in range(3):  # raised at every call from now on, naming the file
        with pytest.raises(RunOutputError, match="cannot write .*b: Permission denied"):
            w.wait()
    with pytest.raises(RunOutputError):
        w.submit(write, tmp_path / "c")
    with pytest.raises(RunOutputError):
        w.close()
    assert made == ["a", "b"] and not (tmp_path / "c").exists()


# -- HDF5 -----------------------------------------------------------------------------------
CASE_YAML = "name: wall\nloading:\n  pressure_Pa: 0.5e6\n# ünïcode comment\n"


def make_mesh():
    pts, hexes = two_hexes()
    return {
        "nodes": pts,
        "hexes": hexes,
        "block_of_element": np.array([0, 1]),
        "contact_points": np.array([[1.0, 0.5, 0.5], [1.0, 0.25, 0.75]]),
        "contact_group": np.array([0, 0]),
    }


def step_fields(s: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(s)
    return {
        "displacement": rng.normal(size=(12, 3)),
        "d_coh": rng.uniform(size=2),
        "status": np.array([s % 3, 1], dtype=np.int8),
        "open": np.array([True, s % 2 == 0]),
    }


def test_curve_columns_are_rewritten_shrunk_and_replaced(tmp_path):
    """``write_curve`` rewrites a column whole: longer, shorter (a resumed run's curve), or
    replaced when its dtype changes or it cannot grow (a fixed-size dataset left by another
    writer)."""
    path = tmp_path / "results.h5"
    with ResultsFile(path, CASE_YAML, make_mesh()) as rf:
        rf.write_curve({"a": np.arange(5.0), "b": np.arange(5)})
        rf.write_curve({"a": np.array([7.0, 8.0]), "b": np.array([0.5, 1.5])})
        with h5py.File(path, "r+") as f:
            f["curve"].create_dataset("c", data=np.arange(3.0))  # fixed size
        rf.write_curve({"c": np.arange(4.0)})
        rf.write_curve({"a": np.zeros(0)})
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["curve/a"][()], np.zeros(0))
        np.testing.assert_array_equal(f["curve/b"][()], [0.5, 1.5])
        assert f["curve/b"].dtype == np.float64  # was int64: replaced
        np.testing.assert_array_equal(f["curve/c"][()], np.arange(4.0))
        assert all(f["curve"][k].maxshape == (None,) for k in "abc")
    with h5py.File(path, "r+") as f:  # a growable column of the same dtype: in place
        assert _rewrite_column(f["curve"], "c", np.arange(6.0))
        assert not _rewrite_column(f["curve"], "c", np.arange(6))
        assert not _rewrite_column(f["curve"], "missing", np.arange(6.0))
        np.testing.assert_array_equal(f["curve/c"][()], np.arange(6.0))


def test_a_staged_output_step_keeps_the_values_it_was_given(tmp_path):
    # the recorder stages a step and appends it on its background thread while the run
    # changes its arrays in place: the step written is the one given, checked when staged
    path = tmp_path / "results.h5"
    with ResultsFile(path, CASE_YAML, make_mesh()) as rf:
        u = np.arange(6.0)
        append = rf.staged_step(3, 0.25, {"u": u})
        u[:] = -1.0
        with pytest.raises(ValueError, match="already written"):
            rf.staged_step(3, 0.5, {"u": u})
        with pytest.raises(ValueError, match=r"fields\['u'\]"):
            rf.staged_step(4, 0.5, {"u": np.array([np.inf])})
        assert read_results(path)["steps"] == []
        append()
    (step,) = read_results(path)["steps"]
    assert step.step == 3 and step.time == 0.25
    np.testing.assert_array_equal(step.fields["u"], np.arange(6.0))


def test_results_round_trip(tmp_path):
    path = tmp_path / "out" / "results.h5"
    mesh = make_mesh()
    attrs = {"version": "0.1.0", "dt_s": 1e-4, "n_blocks": 2}
    with ResultsFile(path, CASE_YAML, mesh, attrs) as rf:
        for s in (0, 5, 10):
            rf.write_step(s, s * 1e-3, step_fields(s))
        rf.write_curve({"time_s": np.array([0.0, 1e-3]), "force_N": np.array([0.0, 2.5])})
        rf.write_curve({"time_s": np.array([0.0, 1e-3, 2e-3]),
                        "force_N": np.array([0.0, 2.5, 3.0])})
        rf.write_curve({"step": np.array([0, 5, 10])})
        with pytest.raises(ValueError, match="already written"):
            rf.write_step(5, 0.5, step_fields(5))
        with pytest.raises(ValueError, match=r"fields\['d_coh'\]"):
            rf.write_step(11, 0.011, {"d_coh": np.array([0.0, np.nan])})
        with pytest.raises(ValueError, match="time"):
            rf.write_step(12, float("inf"), {})
    assert rf.closed
    with pytest.raises(RuntimeError):
        rf.write_step(20, 0.02, {})

    r = read_results(path)
    assert r["case_yaml"] == CASE_YAML
    assert r["attrs"]["format"] == "masonry_nscd.results"
    assert r["attrs"]["version"] == "0.1.0"
    assert r["attrs"]["dt_s"] == 1e-4 and r["attrs"]["n_blocks"] == 2
    assert set(r["mesh"]) == set(mesh)
    for k, v in mesh.items():
        np.testing.assert_array_equal(r["mesh"][k], v)
    assert [(s.step, s.time) for s in r["steps"]] == [(0, 0.0), (5, 5e-3), (10, 1e-2)]
    for rec in r["steps"]:
        expected = step_fields(rec.step)
        assert set(rec.fields) == set(expected)
        for k, v in expected.items():
            np.testing.assert_array_equal(rec.fields[k], v)
            assert rec.fields[k].dtype == v.dtype
    np.testing.assert_array_equal(r["curve"]["time_s"], [0.0, 1e-3, 2e-3])
    np.testing.assert_array_equal(r["curve"]["force_N"], [0.0, 2.5, 3.0])
    np.testing.assert_array_equal(r["curve"]["step"], [0, 5, 10])
    with h5py.File(path, "r") as f:
        assert sorted(f["steps"]) == ["000000", "000005", "000010"]
        assert f["steps/000005"].attrs["step"] == 5


def test_results_refuse_nan_in_mesh_and_attrs(tmp_path):
    mesh = make_mesh()
    mesh["nodes"] = mesh["nodes"].copy()
    mesh["nodes"][0, 0] = np.nan
    with pytest.raises(ValueError, match=r"mesh\['nodes'\]"):
        ResultsFile(tmp_path / "r.h5", CASE_YAML, mesh)
    with pytest.raises(ValueError, match=r"attrs\['dt_s'\]"):
        ResultsFile(tmp_path / "r.h5", CASE_YAML, make_mesh(), {"dt_s": float("inf")})
    with (
        ResultsFile(tmp_path / "r.h5", CASE_YAML, make_mesh()) as rf,
        pytest.raises(ValueError, match=r"columns\['force_N'\]"),
    ):
        rf.write_curve({"force_N": np.array([1.0, -np.inf])})
    assert leftovers(tmp_path) == []


WRITER = textwrap.dedent(
    """
    import os, sys
    import numpy as np
    from masonry_nscd.io.results_h5 import ResultsFile

    def fields(s):
        return {"displacement": np.full((4, 3), float(s)), "d_coh": np.arange(3) * s}

    rf = ResultsFile(sys.argv[1], "name: killed\\n", {"nodes": np.zeros((4, 3))})
    for s in range(3):
        rf.write_step(s, 0.1 * s, fields(s))
        rf.write_curve({"step": np.arange(s + 1)})
    print("3", flush=True)
    sys.stdin.readline()
    rf.write_step(3, 0.3, fields(3))
    print("4", flush=True)
    sys.stdin.readline()
    os._exit(3)  # no close, no atexit, no finalizers
    """
)


def test_results_readable_while_running_and_after_kill(tmp_path):
    path = tmp_path / "results.h5"
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(
        [sys.executable, "-c", WRITER, str(path)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
    )
    try:
        assert proc.stdout.readline().strip() == "3"
        # another process reads while the writer is alive, between steps
        r = read_results(path)
        assert [s.step for s in r["steps"]] == [0, 1, 2]
        # a reader keeping the file open does not block the writer
        with h5py.File(path, "r") as held:
            assert len(held["steps"]) == 3
            proc.stdin.write("go\n")
            proc.stdin.flush()
            assert proc.stdout.readline().strip() == "4"
        proc.stdin.write("go\n")
        proc.stdin.flush()
        assert proc.wait(timeout=20) == 3
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()

    r = read_results(path, wait_s=0.0)
    assert r["case_yaml"] == "name: killed\n"
    assert [(s.step, s.time) for s in r["steps"]] == [(0, 0.0), (1, 0.1), (2, 0.2), (3, 0.3)]
    for rec in r["steps"]:
        np.testing.assert_array_equal(rec.fields["displacement"], np.full((4, 3), rec.step))
        np.testing.assert_array_equal(rec.fields["d_coh"], np.arange(3) * rec.step)
    np.testing.assert_array_equal(r["curve"]["step"], [0, 1, 2])
    with h5py.File(path, "r") as f:  # a plain reader, default options
        assert len(f["steps"]) == 4


def test_killed_during_a_write_is_refused_with_a_clear_message(tmp_path):
    """The documented limit: a writer killed inside a write leaves the 'open for write' flag."""
    path = tmp_path / "results.h5"
    with ResultsFile(path, "name: x\n", {"nodes": np.zeros((2, 3))}) as rf:
        rf.write_step(0, 0.0, {"u": np.ones(3)})
    code = (
        "import os, sys, h5py\n"
        "f = h5py.File(sys.argv[1], 'r+', libver='latest', locking=False)\n"
        "f['steps'].create_group('000001').create_dataset('u', data=[1.0, 2.0])\n"
        "os._exit(1)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(path)], check=False)
    assert proc.returncode == 1
    with pytest.raises(OSError, match="h5clear"):
        read_results(path, wait_s=0.05)


@pytest.mark.parametrize("compression", ["zlib", "lzma", None])
def test_vtu_arrays_of_many_blocks_round_trip(tmp_path, compression):
    """Arrays larger than one compressed block (64 KiB) come back exactly, in every encoding."""
    rng = np.random.default_rng(2)
    n = 20_000  # 480 kB of coordinates: 8 blocks
    pts = rng.normal(size=(n, 3))
    pd = {"opening_m": rng.normal(size=n) * 1e-5, "status": rng.integers(0, 4, n).astype(np.int8),
          "traction_Pa": rng.normal(size=(n, 3)) * 1e5, "flag": rng.uniform(size=n) > 0.5}
    path = tmp_path / "many.vtu"
    vtu.write_points_vtu(path, pts, pd, compression=compression)
    head = path.read_bytes()[:400]
    assert (b"compressor=" in head) == (compression is not None)
    m = meshio.read(path)
    np.testing.assert_array_equal(m.points, pts)
    np.testing.assert_array_equal(m.cells[0].data.ravel(), np.arange(n))
    for k, v in pd.items():
        np.testing.assert_array_equal(m.point_data[k], v.astype(np.uint8) if k == "flag" else v)
    with pytest.raises(ValueError, match="compression"):
        vtu.write_points_vtu(path, pts, pd, compression="gzip")


def test_repeated_arrays_are_compressed_once_into_the_same_bytes(tmp_path, monkeypatch):
    """The nodes and cells written at every output step: from their second file on, their
    compressed bytes are reused (``vtu._Repeats``), and every file is byte for byte the file
    written without reuse; the kept bytes stay within the budget, the oldest dropped first."""
    pts, hexes = two_hexes()
    rng = np.random.default_rng(3)
    fields = [{"u": rng.normal(size=(12, 3))} for _ in range(3)]
    monkeypatch.setattr(vtu, "_REPEATS", vtu._Repeats(budget=0))
    for i, pd in enumerate(fields):
        vtu.write_blocks_vtu(tmp_path / f"plain{i}.vtu", pts, hexes, pd)
    calls = []
    monkeypatch.setattr(vtu, "_REPEATS", vtu._Repeats())
    real = vtu._compressed
    monkeypatch.setattr(vtu, "_compressed", lambda raw, c: calls.append(len(raw)) or real(raw, c))
    for i, pd in enumerate(fields):
        vtu.write_blocks_vtu(tmp_path / f"kept{i}.vtu", pts, hexes, pd)
        assert (tmp_path / f"kept{i}.vtu").read_bytes() == (tmp_path / f"plain{i}.vtu").read_bytes()
    # 5 arrays per file (points, connectivity, offsets, types, u): all 5 compressed in the first
    # two files (the second sighting keeps them), then only u
    assert len(calls) == 5 + 5 + 1
    small = vtu._Repeats(budget=4 * 3000)
    for k in range(10):  # 1500 bytes each: 8 fit
        raw = bytes([k]) * 1000
        small.put(raw, "zlib", b"x" * 500)
        small.put(raw, "zlib", b"x" * 500)
        assert small.size <= small.budget
    assert small.get(bytes([9]) * 1000, "zlib") == b"x" * 500
    assert small.get(bytes([2]) * 1000, "zlib") == b"x" * 500
    assert small.get(bytes([1]) * 1000, "zlib") is None
