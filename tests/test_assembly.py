"""Block assemblies read from mesh files: the reader, the checks, the mesh route.

References: the weights from the geometry of ``cases/make_pier_arches_mesh.py`` (rectangles
and the chord trapezoids of the voussoirs, ``(R_e^2 - R_i^2) sin(dtheta) / 2`` each), and the
limit analysis of ``tests/test_arch.py`` (its linear programme on the thrust line) for an arch
written into a mesh file.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, case_from_dict, load_case, read_yaml
from masonry_nscd.cli import app
from masonry_nscd.io.mesh_file import BlockMesh, read_block_mesh, write_block_mesh
from masonry_nscd.scenes import build_scene, check_case

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "pier_arches.yaml"
SCRIPT = ROOT / "cases" / "make_pier_arches_mesh.py"
DRY = {"law": "dry", "mu": 0.8, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11}


def _script():
    spec = importlib.util.spec_from_file_location("make_pier_arches_mesh", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _with_mesh(tmp_path: Path, mesh: BlockMesh, name: str = "m.msh") -> Path:
    """The shipped case reading ``mesh`` (written to tmp_path)."""
    write_block_mesh(tmp_path / name, mesh)
    text = CASE.read_text().replace("mesh_file: pier_arches.msh", f"mesh_file: {name}")
    path = tmp_path / "case.yaml"
    path.write_text(text)
    return path


def _validate(path: Path):
    return CliRunner().invoke(app, ["validate", str(path)])


def test_script_writes_what_the_reader_reads(tmp_path):
    """The script's mesh read back: 20 blocks named as written, 29 hexahedra, no element
    inverted; the shipped file is the script's."""
    mod = _script()
    mod.main(["-o", str(tmp_path / "p.msh")])
    mesh = read_block_mesh(tmp_path / "p.msh")
    shipped = read_block_mesh(ROOT / "cases" / "pier_arches.msh")
    assert len(mesh.hexes) == 29 and len(set(mesh.tags.tolist())) == 20
    assert mesh.names == shipped.names
    assert np.allclose(mesh.points, shipped.points) and (mesh.hexes == shipped.hexes).all()
    assert {mesh.block_name(t) for t in mesh.tags} >= {"pier 5", "left arch 6", "ground"}


def test_pier_and_arches_stand_on_their_supports(tmp_path):
    """The shipped case under its own weight stands; the supports carry the weight of the
    pier and of the 12 voussoirs, and no net horizontal force (the arches' thrusts balance
    on the pier)."""
    from masonry_nscd.run import run_case

    mod = _script()
    case = load_case(CASE, ["output.vtu=false", "loading.body_force.rate_per_s=0",
                            "collapse.end_time_s=0.3"])
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["status"] == "standing" and s["hinges"] == []
    r_i, r_e = mod.RADIUS - mod.THICKNESS / 2, mod.RADIUS + mod.THICKNESS / 2
    n = 6
    area = (2 * mod.PIER_HALF_WIDTH * mod.PIER_LEVELS[-1]
            + 2 * n * (r_e ** 2 - r_i ** 2) / 2 * math.sin(math.pi / 2 / n))
    weight = 2000.0 * 9.81 * 0.3 * area
    fx, fy = s["support_forces_last_kN"]["all supports"]
    assert fy == pytest.approx(1e-3 * weight, rel=1e-6)
    assert abs(fx) <= 1e-6 * 1e-3 * weight


def _arch_mesh(n: int, t: float, depth: float) -> BlockMesh:
    """A semicircular arch of n voussoirs (R = 1) on two fixed abutments, as a mesh."""
    from masonry_nscd.scenes.arch import Voussoir, arch_geometry

    geo = arch_geometry("semicircular", 1.0, 2.0, t, n)
    pts, hexes, tags, names = [], [], [], {}
    boxes = [np.array([[-1 - t, -t], [-1 + t, -t], [-1 + t, 0.0], [-1 - t, 0.0]]),
             np.array([[1 - t, -t], [1 + t, -t], [1 + t, 0.0], [1 - t, 0.0]])]
    quads = [*geo.quads, *boxes]
    for k, q in enumerate(quads):
        X, c = Voussoir("", "", q[None], (0.0, depth)).mesh()
        hexes.append(c + sum(len(p) for p in pts))
        pts.append(X)
        tags.append(k + 1)
        names[k + 1] = f"voussoir {k + 1}" if k < n else ("left", "right")[k - n]
    return BlockMesh(np.concatenate(pts), np.concatenate(hexes), np.array(tags), names)


def test_arch_from_a_mesh_file_collapses_at_the_limit_analysis_multiplier(tmp_path):
    """The shipped arch's 24 voussoirs written into a mesh file and run as an assembly under a
    growing horizontal body force: the multiplier at the onset within 2 % of limit analysis."""
    from test_arch import collapse_multiplier

    from masonry_nscd.run import run_case

    n, t, depth = 24, 0.15, 0.25
    write_block_mesh(tmp_path / "arch.msh", _arch_mesh(n, t, depth))
    data = read_yaml((ROOT / "cases" / "arch_semicircular.yaml").read_text())
    data.pop("arch")  # the same loads, joints, solver and collapse rule
    data["assembly"] = {"mesh_file": str(tmp_path / "arch.msh"),
                        "supports": [{"group": "left"}, {"group": "right"}]}
    data["output"]["vtu"] = False
    case = case_from_dict(data, check_files=True)
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["status"] == "collapse"
    lam = collapse_multiplier(n, t)
    assert s["collapse"]["loads_at_onset"]["lambda"] == pytest.approx(lam, rel=0.02)
    assert len(s["hinges"]) == 4


def _moved(mesh: BlockMesh, name: str, shift) -> BlockMesh:
    tag = next(t for t, nm in mesh.names.items() if nm == name)
    nodes = np.unique(mesh.hexes[mesh.tags == tag])
    points = mesh.points.copy()
    points[nodes] += shift
    return BlockMesh(points, mesh.hexes, mesh.tags, mesh.names)


def test_bad_meshes_exit_2_naming_the_block(tmp_path):
    mesh = _script().pier_arches_mesh()
    # an inverted element: pier 3's hexahedron with its bottom and top faces swapped
    hexes = mesh.hexes.copy()
    k = int(np.flatnonzero(mesh.tags == 4)[0])
    assert mesh.names[4] == "pier 3"
    hexes[k] = hexes[k][[4, 5, 6, 7, 0, 1, 2, 3]]
    res = _validate(_with_mesh(tmp_path, BlockMesh(mesh.points, hexes, mesh.tags, mesh.names)))
    assert res.exit_code == 2 and "'pier 3'" in res.output and "inverted" in res.output
    # two blocks overlapping: pier 5 pushed 5 cm down into pier 4
    res = _validate(_with_mesh(tmp_path, _moved(mesh, "pier 5", (0.0, -0.05, 0.0))))
    assert res.exit_code == 2 and "overlap" in res.output
    assert "'pier 4'" in res.output and "'pier 5'" in res.output
    # a block that nothing holds: pier 5 lifted by 0.5 m
    res = _validate(_with_mesh(tmp_path, _moved(mesh, "pier 5", (0.0, 0.5, 0.0))))
    assert res.exit_code == 2 and "'pier 5'" in res.output
    assert "no neighbour and no support" in res.output
    # faces that touch at an angle: pier 5 turned by half a degree about its bottom face's edge
    tag = next(t for t, nm in mesh.names.items() if nm == "pier 5")
    nodes = np.unique(mesh.hexes[mesh.tags == tag])
    P = mesh.points[nodes]
    pivot = P[np.argmin(P[:, 0] + 1e-3 * P[:, 1])]  # a corner of its bottom face, at x min
    c, s_ = math.cos(math.radians(0.5)), math.sin(math.radians(0.5))
    turned = mesh.points.copy()
    d = P - pivot
    turned[nodes, 0] = pivot[0] + c * d[:, 0] - s_ * d[:, 1]
    turned[nodes, 1] = pivot[1] + s_ * d[:, 0] + c * d[:, 1]
    res = _validate(_with_mesh(tmp_path, BlockMesh(turned, mesh.hexes, mesh.tags, mesh.names)))
    assert res.exit_code == 2 and "'pier 4' (tag 5) and block 'pier 5' (tag 6) touch on faces 0.5 degrees" in res.output
    # the run refuses it too, with the same exit code
    res = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "-o",
                                   str(tmp_path / "out")])
    assert res.exit_code == 2 and "'pier 5'" in res.output
    # crown joints whose faces do not meet corner to corner: a pier of four 0.4 m blocks, the
    # face of pier 4 (1.2 to 1.6 m) larger than the arches' crown faces (1.22 to 1.38 m)
    mod = _script()
    mod.PIER_LEVELS = (0.0, 0.4, 0.8, 1.2, 1.6)
    res = _validate(_with_mesh(tmp_path, mod.pier_arches_mesh()))
    assert res.exit_code == 2 and "face each other" in res.output
    assert "'pier 4'" in res.output and "'left arch 1'" in res.output
    assert "contact_point_rule: overlap" in res.output


def test_faces_that_meet_in_part_make_a_joint_on_their_common_area(tmp_path):
    """The pier of four 0.4 m blocks, its top block's face larger than the arches' crown faces
    (refused with the default rule, above): with the rule ``overlap`` each crown joint has its
    points on the crown face, their areas summing to it (0.16 x 0.3 m), and the structure
    stands under its weight."""
    mod = _script()
    mod.PIER_LEVELS = (0.0, 0.4, 0.8, 1.2, 1.6)
    path = _with_mesh(tmp_path, mod.pier_arches_mesh())
    sets = ["assembly.contact_point_rule=overlap", "assembly.driven_block=pier 4",
            "loading.body_force.rate_per_s=0", "collapse.end_time_s=0.4"]
    res = CliRunner().invoke(app, ["validate", str(path), *[a for s in sets for a in
                                                              ("--set", s)]])
    assert res.exit_code == 0, res.output
    scene = build_scene(load_case(path, sets))
    names = [b.name for b in scene.bodies]
    crown = [p for p in scene.points
             if {names[b] for b in p.bodies} == {"pier 4", "left arch 1"}]
    assert sum(p.area for p in crown) == pytest.approx(0.16 * 0.3, rel=1e-9)
    res = CliRunner().invoke(app, ["run", str(path), "-o", str(tmp_path / "run"),
                                   *[a for s in [*sets, "output.vtu=false"] for a in
                                     ("--set", s)]])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "standing"


def test_assembly_case_checks(tmp_path):
    mesh_path = ROOT / "cases" / "pier_arches.msh"
    base = {"assembly": {"mesh_file": str(mesh_path), "supports": [{"group": "ground"}]},
            "blocks": {"material": "rigid"}, "joint": DRY}
    # the mesh is read and its groups checked by the builder
    with pytest.raises(CaseError, match=r"assembly.supports\[0\].group: got 'floor'"):
        check_case(case_from_dict({**base, "assembly": {"mesh_file": str(mesh_path),
                                                        "supports": [{"group": "floor"}]}}))
    with pytest.raises(CaseError, match="assembly.supports"):
        case_from_dict({**base, "assembly": {"mesh_file": str(mesh_path), "supports": []}})
    with pytest.raises(CaseError, match="assembly.mesh_file: .*not found"):
        check_case(case_from_dict({**base, "assembly": {"mesh_file": str(tmp_path / "none.msh"),
                                                        "supports": [{"group": 1}]}}))
    with pytest.raises(CaseError, match="assembly: given with arch"):
        case_from_dict({**base, "arch": {}})
    with pytest.raises(CaseError, match="loading.settlement.support: got 'left'; an assembly"):
        case_from_dict({**base, "loading": {"settlement": {"support": "left",
                                                           "displacement_m": [0, 0, 0]}}})
    # a tag works as a name; a block's material from the table
    case = case_from_dict({**base, "assembly": {
        "mesh_file": str(mesh_path), "supports": [{"group": 1, "kind": "glued"},
                                                  {"group": "left abutment"},
                                                  {"group": "right abutment"}],
        "materials": [{"group": "pier 5", "density_kg_m3": 4000.0}]}})
    scene = build_scene(case)
    by_name = {b.name: b for b in scene.bodies}
    assert by_name["pier 5"].mass == pytest.approx(4000.0 * 0.4 * 0.22 * 0.3, rel=1e-12)
    assert by_name["pier 4"].mass == pytest.approx(2000.0 * 0.4 * 0.16 * 0.3, rel=1e-12)
    glued = [p for p in scene.points if scene.groups[p.group] == "glue"]
    assert {scene.bodies[b].name for p in glued for b in p.bodies} == {"ground", "pier 1"}


def test_a_mesh_made_by_gmsh_reads_and_stands(tmp_path):
    """``tests/data/meshes/gmsh_two_boxes.msh`` was written by Gmsh 4.15.2 itself (its Python
    API, format 4.1: two OCC boxes 1 x 0.5 x 0.3 m, one on the other, transfinite and recombined
    into 2 x 2 x 2 hexahedra each, physical volumes "box 1" and "box 2"). Read back: the names,
    16 hexahedra, none inverted; as an assembly with box 1 fixed, box 2 stands on it and the
    support carries its weight."""
    from masonry_nscd.model.mesh_checks import inverted_elements
    from masonry_nscd.run import run_case

    path = ROOT / "tests" / "data" / "meshes" / "gmsh_two_boxes.msh"
    mesh = read_block_mesh(path)
    assert sorted(mesh.names.values()) == ["box 1", "box 2"] and len(mesh.hexes) == 16
    assert len(inverted_elements(mesh.points, mesh.hexes)) == 0
    case = case_from_dict({
        "assembly": {"mesh_file": str(path), "supports": [{"group": "box 1"}]},
        "blocks": {"material": "rigid", "density_kg_m3": 2000.0}, "joint": DRY,
        "loading": {"gravity": {"ramp_s": 0.05}},
        "collapse": {"end_time_s": 0.2}, "output": {"vtu": False}}, check_files=True)
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["status"] == "standing"
    fx, fy = s["support_forces_last_kN"]["all supports"]
    assert fy == pytest.approx(1e-3 * 2000.0 * 9.81 * 1.0 * 0.5 * 0.3, rel=1e-6)
    assert abs(fx) < 1e-9


def test_the_driven_block_and_a_loaded_block_must_be_blocks_of_the_structure():
    """Named by the builder's check, before anything is built: a support is not one, nor a
    name the mesh does not have."""
    mesh_path = ROOT / "cases" / "pier_arches.msh"
    base = {"assembly": {"mesh_file": str(mesh_path), "supports": [{"group": "ground"}]},
            "blocks": {"material": "rigid"}, "joint": DRY}
    with pytest.raises(CaseError, match=r"assembly.driven_block: got 'ground'; the blocks of "
                                        r"the structure are 'pier 1'"):
        check_case(case_from_dict({**base, "assembly": {**base["assembly"],
                                                        "driven_block": "ground"}}))
    with pytest.raises(CaseError, match=r"loading.point_load.block: got 'pier 9'"):
        check_case(case_from_dict({**base, "loading": {"point_load": {"block": "pier 9"}}}))
    res = CliRunner().invoke(app, ["validate", str(CASE), "--set",
                                   "assembly.driven_block=left abutment"])
    assert res.exit_code == 2 and "assembly.driven_block" in res.output
