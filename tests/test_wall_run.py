"""The wall generator and `masonry run` on the smoke case: counts, outputs, equilibrium."""

import csv
import itertools

import h5py
import meshio
import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.run import CSV_COLUMNS
from masonry_nscd.scenes.layout import unit_boxes
from masonry_nscd.scenes.wall import GROUPS


def test_running_bond_of_the_reference_wall():
    wall = load_case("cases/wall_0.5MPa.yaml").wall
    boxes = unit_boxes(wall)
    per_course = [sum(1 for b in boxes if b.course == c) for c in range(11)]
    assert per_course == [6, 7] * 5 + [6]
    for c in range(11):
        row = sorted((b.x0, b.length) for b in boxes if b.course == c)
        # every course spans 1.85 m with 10 mm head joints between units
        assert row[-1][0] + row[-1][1] == pytest.approx(1.85, abs=1e-12)
        for (x0, l0), (x1, _) in itertools.pairwise(row):
            assert x1 - (x0 + l0) == pytest.approx(0.010, abs=1e-12)
        if c % 2:
            assert row[0][1] == row[-1][1] == pytest.approx(0.145)
    tops = {b.course: b.y0 for b in boxes}
    assert tops[10] + 0.1 == pytest.approx(1.20, abs=1e-12)  # 11 x 100 + 10 x 10 mm


def test_contact_points_of_the_reference_wall():
    from masonry_nscd.scenes.wall import build_wall

    case = load_case("cases/wall_0.5MPa_elastic.yaml", ["wall.refine=[]"])
    scene = build_wall(case)
    group = np.array([p.group for p in scene.points])
    count = {n: int((group == i).sum()) for i, n in enumerate(GROUPS) if (group == i).any()}
    # 2 x 2 element faces x 2 x 2 Gauss points = 8 points per bed face of a unit and per head
    # face. Bed joints: points on the bottom face of every unit above course 0 (5 courses of 7
    # units, 5 of 6); head joints: 5 per full course (6 courses), 6 per bonded one (5 courses).
    assert count == {"bed": 8 * (5 * 7 + 5 * 6), "head": 8 * (6 * 5 + 5 * 6),
                     "glue_bottom": 48, "glue_top": 48}
    # gaps measured on the geometry: the joint thickness, and none at the glue
    gaps = np.array([p.gap for p in scene.points])
    assert np.allclose(gaps[group < 2], 0.010, atol=1e-12)
    assert np.allclose(gaps[group >= 2], 0.0, atol=1e-12)
    area = np.array([p.area for p in scene.points])
    assert np.sum(area[group == 2]) == pytest.approx(1.8 * 0.15)
    # the case as shipped refines its four corner units to 4 x 4 x 1: their bed faces carry
    # 4 x 1 element faces x 4 Gauss points = 16 points. Glues: 4 units of 8 and 2 corners of 16
    # each; beds: the top course's two corners gain 8 each; heads: the points sit on the right
    # unit's face, so the right corners of courses 0 and 10 gain 8 each.
    refined = build_wall(load_case("cases/wall_0.5MPa_elastic.yaml"))
    group = np.array([p.group for p in refined.points])
    count = {n: int((group == i).sum()) for i, n in enumerate(GROUPS) if (group == i).any()}
    assert count == {"bed": 8 * (5 * 7 + 5 * 6) + 2 * 8, "head": 8 * (6 * 5 + 5 * 6) + 2 * 8,
                     "glue_bottom": 4 * 8 + 2 * 16, "glue_top": 4 * 8 + 2 * 16}
    area = np.array([p.area for p in refined.points])
    assert np.sum(area[group == 2]) == pytest.approx(1.8 * 0.15)


@pytest.fixture(scope="module")
def smoke_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("smoke") / "run"
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out)])
    assert res.exit_code == 0, res.output
    return out, res.output


def _curve(out):
    with open(out / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_smoke_run_writes_the_curve_with_units(smoke_run):
    out, text = smoke_run
    with open(out / "force_displacement.csv") as f:
        header = next(csv.reader(f))
    assert header == CSV_COLUMNS
    c = _curve(out)
    assert c["ux_mm"][-1] >= 0.5  # the target, 0.5 mm
    assert np.all(np.isfinite(np.column_stack(list(c.values()))))
    assert "done:" in text and "Ux" in text


def test_smoke_run_equilibrium(smoke_run):
    out, _ = smoke_run
    c = _curve(out)
    case = load_case("cases/smoke.yaml")
    sigma_force_kN = case.loading.vertical_stress.value_Pa * case.wall.wall_length_m * \
        case.wall.thickness_m / 1e3
    before = c["time_s"] < case.loading.horizontal.start_s
    # before the horizontal loading, no horizontal force (a converged contact solve)
    assert np.abs(c["fx_kN"][before]).max() < 0.01 * sigma_force_kN
    # the vertical load is carried: the beam pushes down with sigma_N x plan area
    settled = (c["time_s"] > 0.09) & before
    assert np.allclose(c["fy_kN"][settled], -sigma_force_kN, rtol=1e-2)
    # the bottom carries the load plus the weight of the wall
    units = unit_boxes(case.wall)
    weight_kN = sum(b.length * b.height * case.wall.thickness_m for b in units) * 2000 * 9.81 / 1e3
    assert np.allclose(c["fy_bottom_kN"][settled], sigma_force_kN + weight_kN, rtol=1e-2)
    # once loaded horizontally, the top force balances the bottom reaction
    last = c["fx_kN"][-1]
    assert abs(last) > 1.0
    assert c["fx_bottom_kN"][-1] == pytest.approx(-last, rel=1e-2)


def test_smoke_run_vtu_pvd_and_hdf5_read_back(smoke_run):
    out, _ = smoke_run
    import xml.etree.ElementTree as ET

    files = [d.get("file") for d in ET.parse(out / "wall.pvd").getroot().iter("DataSet")]
    assert files and all((out / f).exists() for f in files)
    blocks = meshio.read(out / [f for f in files if "blocks" in f][-1])
    assert blocks.cells[0].type == "hexahedron"
    assert "displacement_m" in blocks.point_data
    sig = blocks.cell_data["stress_Pa"][0]
    assert sig.shape[1] == 6 and np.all(np.isfinite(sig))
    # the wall is compressed: mean vertical stress of the elements about -(sigma_N + weight)
    assert -0.7e6 < float(np.mean(sig[:, 1])) < -0.3e6
    joints = meshio.read(out / [f for f in files if "joints" in f][-1])
    for name in ("d_coh", "opening_m", "slip_m", "T_n_Pa", "T_t_Pa", "status"):
        assert name in joints.point_data
    with h5py.File(out / "results.h5", "r") as f:
        assert "nodes_m" in f["mesh"] and len(f["steps"]) >= 10
        assert f["curve"]["ux_mm"][-1] >= 0.5
    assert load_case(out / "case.yaml").wall.courses == 3


def test_run_refuses_a_non_empty_output_folder(smoke_run, tmp_path):
    out, _ = smoke_run
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out)])
    assert res.exit_code == 2
    assert "--overwrite" in res.output


def test_point_joint_cli_writes_the_curve(tmp_path):
    out = tmp_path / "c.csv"
    res = CliRunner().invoke(app, ["point", "joint", "cases/smoke.yaml", "--path", "sliding",
                                   "--to", "2e-3", "--normal-stress", "-0.5e6", "-o", str(out)])
    assert res.exit_code == 0, res.output
    with open(out) as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["step", "u_n_m", "u_t_m", "T_n_Pa", "T_t_Pa", "d_coh"]
    peak = max(float(r["T_t_Pa"]) for r in rows)
    assert peak == pytest.approx(0.4586e6, rel=2e-3)


def test_sigterm_keeps_the_results_written_so_far(tmp_path):
    """A run ended by SIGTERM exits 130 and leaves a readable CSV and HDF5 file behind."""
    import os
    import signal
    import subprocess
    import sys
    import time

    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "masonry_nscd.cli", "run", "cases/smoke.yaml", "-o", str(out),
         "--set", "loading.horizontal.target_m=0.02"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 600  # a cold numba cache compiles for a minute or more
    while time.time() < deadline:
        csv_path = out / "force_displacement.csv"
        if csv_path.exists() and len(csv_path.read_text().splitlines()) > 30:
            break
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err
    rows = (out / "force_displacement.csv").read_text().splitlines()
    assert rows[0].startswith("step,time_s,ux_mm")
    assert len(rows) > 30 and all(len(r.split(",")) == len(rows[0].split(",")) for r in rows)
    with h5py.File(out / "results.h5", "r") as f:
        assert len(f["steps"]) >= 1
    assert os.path.exists(out / "wall.pvd")


def test_top_rotation_free_lets_the_beam_turn_and_softens_the_wall(tmp_path):
    """``supports.top_rotation``: fixed holds the upper beam level (model.md); free lets it turn
    in the wall's plane, and the wall, then a cantilever, is softer: on the smoke wall the
    horizontal force at the same imposed displacement is lower, and the beam has turned (its
    in-plane rotation dof is no longer imposed)."""
    from masonry_nscd.run import run_case
    from masonry_nscd.scenes import build_scene

    forces, turns = {}, {}
    for mode in ("fixed", "free"):
        case = load_case("cases/smoke.yaml", [f"supports.top_rotation={mode}",
                                              "loading.horizontal.target_m=0.2e-3"])
        scene = build_scene(case)
        integ = scene.integrator()
        top = integ.bodies[scene.driven]
        assert (5 in top.imposed_velocity) == (mode == "fixed")
        res = run_case(case, tmp_path / mode, echo=lambda m: None)
        forces[mode] = res.fx_kN
        with h5py.File(tmp_path / mode / "results.h5") as f:
            last = max(f["steps"])
            u = np.asarray(f["steps"][last]["u"])
        turns[mode] = abs(u[integ.sys.body_dof0[scene.driven] + 5])
    assert turns["fixed"] == 0.0 and turns["free"] > 0.0
    assert forces["free"] < 0.95 * forces["fixed"]
