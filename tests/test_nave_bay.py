"""The Gothic nave bay of ``cases/make_nave_bay_mesh.py`` and ``cases/nave_bay.yaml``, and the
settlement of an assembly's support blocks.

References: the counts of the bay's regular parts from its parameters (drums per pier, courses
per buttress, voussoirs per arch, courses per web); flatness and orientation of every
hexahedron from its own corners; the weight of a reduced bay's piers, buttresses and walls
from their outlines (boxes, and the wall's rectangle less the arcade's opening under the
intrados polygon), independent of how they are cut into blocks.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.io.mesh_file import read_block_mesh
from masonry_nscd.model.mesh_checks import corner_jacobians
from masonry_nscd.scenes import build_scene, check_case
from masonry_nscd.scenes.assembly import read_assembly

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "nave_bay.yaml"
SCRIPT = ROOT / "cases" / "make_nave_bay_mesh.py"
#: the faces of a hexahedron in the VTK order
FACES = ((0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))
NORTH_PIERS = ["foundation pier north-east", "foundation pier north-west"]


def _script():
    spec = importlib.util.spec_from_file_location("make_nave_bay_mesh", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def full_mesh(tmp_path_factory):
    path = tmp_path_factory.mktemp("nave") / "nave_bay.msh"
    _script().main(["-o", str(path)])
    return path


def _case(tmp_path: Path, mesh: Path, sets=(), parts=None):
    """The shipped case reading ``mesh``; with ``parts``, only the supports it has."""
    text = CASE.read_text().replace("mesh_file: nave_bay.msh", f"mesh_file: {mesh}")
    for part, support in (("buttresses", "foundation buttress"), ("flyers", "foundation flyer")):
        if parts is not None and part not in parts:
            text = "\n".join(line for line in text.splitlines() if support not in line)
    path = tmp_path / "case.yaml"
    path.write_text(text)
    return load_case(path, list(sets))


def test_the_script_writes_a_valid_mesh(full_mesh):
    """Every hexahedron turns the right way at each corner and has flat faces; one physical
    volume per block, each named; the regular parts count what the parameters say."""
    mod = _script()
    mesh = read_block_mesh(full_mesh)
    X, hexes = mesh.points, mesh.hexes
    assert len(mesh.others) == 0
    assert (corner_jacobians(X, hexes) > 0.0).all()
    size = np.ptp(X, axis=0).max()
    for face in FACES:
        P = X[hexes[:, face]]  # (e, 4, 3)
        n = np.cross(P[:, 1] - P[:, 0], P[:, 3] - P[:, 0])
        n /= np.linalg.norm(n, axis=1)[:, None]
        off = np.einsum("ei,ei->e", P[:, 2] - P[:, 0], n)
        assert np.abs(off).max() < 1e-9 * size
    tags = mesh.block_tags()
    assert sorted(mesh.names) == tags.tolist()
    names = [mesh.block_name(t) for t in tags]
    assert len(set(names)) == len(names)

    def count(prefix: str) -> int:
        return sum(nm.startswith(prefix) for nm in names)

    drums = round(mod.ARCADE_SPRING_M / mod.DRUM_M)
    upper = round((mod.VAULT_SPRING_M - mod.ARCADE_SPRING_M) / mod.DRUM_M)
    courses = round(mod.VAULT_SPRING_M / mod.BUTTRESS_COURSE_M)
    assert count("pier ") == 4 * drums and count("upper pier ") == 4 * upper
    assert count("buttress ") == 4 * courses and count("foundation ") == 12
    for side in ("north", "south"):
        assert count(f"{side} arcade ") == 2 * mod.ARCADE_VOUSSOIRS
    assert count("springer ") == 4 and count("boss") == 1
    assert sum(nm.startswith(("east rib ", "west rib ")) for nm in names) == \
        2 * 2 * mod.VAULT_COURSES
    ribs = mod.VAULT_COURSES - mod.SPRINGER_COURSES - 1  # the top course's are the boss's
    for corner in ("north-east", "north-west", "south-east", "south-west"):
        assert count(f"diagonal rib {corner} voussoir ") == ribs
    for web in ("east", "west", "north", "south"):
        assert count(f"{web} web ") >= 2 * (mod.VAULT_COURSES - mod.SPRINGER_COURSES)
    walls = sum(" wall course " in nm or " spandrel " in nm for nm in names)
    # a flying buttress: the upper buttress to the walls' top, the flyer, the flyer pier up to
    # the flyer's springing (its centre, the radius and the ring below the head's top), the
    # pinnacle
    above = round((mod.WALL_TOP_M - mod.VAULT_SPRING_M) / mod.BUTTRESS_COURSE_M)
    spring = mod.FLYER_HEAD_M - mod.FLYER_RADIUS_M - mod.FLYER_DEPTH_M
    flyer = (above + mod.FLYER_VOUSSOIRS + round(spring / mod.BUTTRESS_COURSE_M)
             + round(mod.PINNACLE_M / mod.BUTTRESS_COURSE_M))
    assert count("upper buttress ") == 4 * above and count("flyer pier ") == 4 * round(
        spring / mod.BUTTRESS_COURSE_M)
    assert sum(nm.startswith("flyer ") and " voussoir " in nm for nm in names) == \
        4 * mod.FLYER_VOUSSOIRS
    assert len(names) == (4 * (drums + upper + courses + flyer) + 12
                          + 4 * mod.ARCADE_VOUSSOIRS + 4 + 1
                          + 4 * mod.VAULT_COURSES + 4 * ribs
                          + count("east web ") + count("west web ")
                          + count("north web ") + count("south web ") + walls)


def test_the_bay_is_an_assembly_every_block_of_which_has_a_joint(full_mesh, tmp_path):
    """The assembly's checks pass (no inverted block, none overlapping, none unheld) and every
    block, foundation or not, is one of a pair of blocks with contact points."""
    case = _case(tmp_path, full_mesh)
    check_case(case)
    blocks = read_assembly(case.assembly)
    joined = {k for pair in blocks.pairs for k in pair}
    assert joined == set(range(len(blocks.names)))
    assert sum(s is not None for s in blocks.support) == 12


def test_a_settlement_moves_exactly_the_named_support_blocks(tmp_path):
    """``settlement.blocks`` moves the two north foundations outwards by the displacement
    and holds every other support; a block that is no support, or an arch's ``support``, is
    refused naming the field."""
    mesh = tmp_path / "small.msh"
    _script().main(["--scale", "0.3", "-o", str(mesh)])
    d = [0.0, 0.0, 0.03]
    case = _case(tmp_path, mesh, ["loading.settlement={blocks: [" + ", ".join(NORTH_PIERS)
                                  + "], displacement_m: [0, 0, 0.03], duration_s: 0.5}"])
    scene = build_scene(case)
    for b in scene.bodies:
        if not b.support:
            continue
        moved = [b.imposed_velocity[i].displacement(10.0)
                 if hasattr(b.imposed_velocity[i], "displacement") else 0.0 for i in range(3)]
        assert moved == (pytest.approx(d) if b.name in NORTH_PIERS else [0.0, 0.0, 0.0])
        assert all(b.imposed_velocity[i](0.55) == 0.0 for i in range(3, 6))
    factor = next(f for f in scene.collapse.factors if f.name == "settlement_m")
    assert factor.value(10.0) == pytest.approx(0.03)
    with pytest.raises(CaseError, match=r"loading.settlement.blocks\[0\]: got 'north wall"):
        check_case(_case(tmp_path, mesh, [("loading.settlement={blocks: ['north wall course "
                                            "20 block 1'], displacement_m: [0, 0, 0.01]}")]))
    with pytest.raises(CaseError, match="loading.settlement.support: got 'left'"):
        _case(tmp_path, mesh, ["loading.settlement={support: left, displacement_m: [0, 0, 1]}"])
    with pytest.raises(CaseError, match="loading.settlement.support: give support"):
        _case(tmp_path, mesh, ["loading.settlement={displacement_m: [0, 0, 1]}"])


def test_a_reduced_bay_stands_and_its_supports_carry_its_weight(tmp_path):
    """The bay at 0.3 of its size without its vault (piers, buttresses, arcades, walls) under
    its weight: it stands, and the supports carry the weight of the outlines (boxes, and the
    wall less the arcade's opening) to the solver's tolerance, with no net horizontal force
    (the bay is symmetric)."""
    from masonry_nscd.run import run_case

    mod = _script()
    mesh = tmp_path / "reduced.msh"
    parts = "piers,buttresses,walls"
    mod.main(["--scale", "0.3", "--parts", parts, "-o", str(mesh)])
    case = _case(tmp_path, mesh, ["output.vtu=false", "loading.body_force.rate_per_s=0",
                                  "collapse.end_time_s=0.4"], parts=parts)
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["status"] == "standing"
    bay = mod.Bay(0.3)
    pier = bay.pier_m ** 2 * bay.arcade_spring_m
    upper = (bay.bay_m / 2 + bay.pier_m / 2 - bay.upper_pier_x) * bay.pier_m * (
        bay.vault_spring_m - bay.arcade_spring_m)
    buttress = bay.buttress_width_m * bay.buttress_depth_m * bay.vault_spring_m
    intra, _ = mod.arcade_points(bay)
    x, y = intra[:, 0], intra[:, 1] - bay.arcade_spring_m
    opening = 2.0 * float(np.sum(0.5 * (y[1:] + y[:-1]) * (x[:-1] - x[1:])))
    # and the opening's strip between the intrados at the springing and the pier's face: none
    assert x[0] == pytest.approx(bay.arcade_inner_x)
    wall = (2 * bay.upper_pier_x * (bay.wall_top_m - bay.arcade_spring_m) - opening) \
        * bay.wall_thickness_m
    weight_kN = 2200.0 * 9.81 * (4 * (pier + upper + buttress) + 2 * wall) / 1e3
    fx, fy = s["support_forces_last_kN"]["all supports"]
    assert fy == pytest.approx(weight_kN, rel=1e-5)
    assert abs(fx) < 1e-6 * weight_kN
    assert math.isfinite(fx)


def _hexahedron_volumes(X: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """The volumes of hexahedra with flat faces (m^3): each cut into six tetrahedra about its
    diagonal from corner 0 to corner 6."""
    P = X[hexes]
    d = P[:, 6] - P[:, 0]
    total = np.zeros(len(hexes))
    for a, b in ((1, 2), (2, 3), (3, 7), (7, 4), (4, 5), (5, 1)):
        total += np.einsum("ei,ei->e", d, np.cross(P[:, a] - P[:, 0], P[:, b] - P[:, 0])) / 6.0
    return np.abs(total)


def test_a_nave_shares_its_lines_of_piers_and_stands(tmp_path):
    """``--bays 2`` (at 0.3 of the size, without the vault): three lines of piers, buttresses
    and flyers, each built once, the case it writes passes the assembly's checks (no block
    overlapping, none unheld), and the nave stands under its weight, the supports carrying the
    weight of the mesh's volume to the solver's tolerance."""
    from masonry_nscd.run import run_case

    mod = _script()
    parts = "piers,buttresses,walls,flyers"
    one, two = tmp_path / "one.msh", tmp_path / "two.msh"
    mod.main(["--scale", "0.3", "--parts", parts, "-o", str(one)])
    mod.main(["--scale", "0.3", "--parts", parts, "--bays", "2", "-o", str(two),
              "--case", str(tmp_path / "two.yaml")])
    names = {}
    for key, path in (("one", one), ("two", two)):
        mesh = read_block_mesh(path)
        names[key] = [mesh.block_name(t) for t in mesh.block_tags()]
    assert len(set(names["two"])) == len(names["two"])
    for prefix in ("pier ", "upper pier ", "buttress ", "upper buttress ", "flyer pier ",
                   "pinnacle ", "foundation "):
        per_corner = sum(n.startswith(prefix) for n in names["one"]) / 4
        assert sum(n.startswith(prefix) for n in names["two"]) == per_corner * 2 * 3, prefix
    for k in (1, 2):
        assert sum(n.startswith(f"bay {k} ") for n in names["two"]) == \
            sum(" wall " in n or " spandrel " in n or " arcade " in n for n in names["one"])
    case = load_case(tmp_path / "two.yaml", ["output.vtu=false", "loading.body_force.rate_per_s=0",
                                             "collapse.end_time_s=0.4"])
    assert len(case.assembly.supports) == 3 * 2 * 3
    check_case(case)
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["status"] == "standing"
    mesh = read_block_mesh(two)
    volumes = _hexahedron_volumes(mesh.points, mesh.hexes)
    fixed = {mesh.block_name(t) for t in mesh.block_tags()} & \
        {g.group for g in case.assembly.supports}
    weight_kN = 2200.0 * 9.81 * sum(
        v for v, t in zip(volumes, mesh.tags, strict=True) if mesh.block_name(t) not in fixed) / 1e3
    fx, fy = s["support_forces_last_kN"]["all supports"]
    assert fy == pytest.approx(weight_kN, rel=1e-5)
    assert abs(fx) < 1e-6 * weight_kN
