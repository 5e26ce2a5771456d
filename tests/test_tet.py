"""Tetrahedral blocks: the 4- and 10-node elements against uniform strain and beam theory, rigid
bodies from tetrahedral meshes, inverted tetrahedra refused, and a wall of rigid blocks meshed
with hexahedra and with tetrahedra collapsing at the same multiplier.

References: a linear displacement field (the patch test: every element reproduces its strain
exactly, and no force acts on the inner nodes); Timoshenko's cantilever ``P L^3 / (3 E I) +
P L / (kappa G A)``; the trilinear hexahedron's parasitic shear in bending (an element of
length ``a`` and depth ``b`` bent by ``u = kappa x y`` stores ``E b^2 / 3 + G a^2 / 3`` for the
beam's ``E b^2 / 3``: at ``nu = 0`` the element's own bending is ``1 + a^2 / (2 b^2)`` times too
stiff, 1.5 for cubes; with ``n`` elements through the depth that bending is ``1 / n^2`` of the
beam's, the rest being stretching of whole elements, which they carry exactly); the
box's closed-form mass, centre and inertia; the overturning multiplier ``b / h`` of a rigid
column of width ``b`` and height ``h`` on a fixed base.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from typer.testing import CliRunner

from masonry_nscd.case import case_from_dict, read_yaml
from masonry_nscd.cli import app
from masonry_nscd.fe import element as solid
from masonry_nscd.fe import hex8, tet4, tet10
from masonry_nscd.io.mesh_file import BlockMesh, read_block_mesh, write_block_mesh
from masonry_nscd.model import RigidBody
from masonry_nscd.model.mesh_checks import inverted_elements

ROOT = Path(__file__).resolve().parents[1]


def _box(origin, size, divisions, kind: str):
    """A box meshed with hexahedra, their Kuhn split into 4-node tetrahedra, or those made
    quadratic: ``(X, conn, element)``."""
    X, conn = hex8.box_mesh(np.asarray(origin, float), np.asarray(size, float), divisions)
    if kind == "hex8":
        return X, conn, hex8.HEX8
    tets = tet4.split_hexahedra(X, conn)
    if kind == "tet4":
        return X, tets, tet4.TET4
    X10, c10 = tet10.quadratic(X, tets)
    return X10, c10, tet10.TET10


@pytest.mark.parametrize("kind", ["hex8", "tet4", "tet10"])
def test_uniform_strain_is_reproduced_exactly(kind):
    """Patch test: nodes moved off the grid inside a box (the edge nodes of the 10-node mesh at
    the middle of their edges), a linear displacement ``u = A x``: the strain at every Gauss
    point is ``A``'s (engineering shears), and the elastic forces on the inner nodes vanish."""
    X, conn, el = _box((0, 0, 0), (1.0, 0.8, 0.6), (3, 3, 3), "hex8")
    rng = np.random.default_rng(3)
    inner = np.all((X > 1e-9) & (X < np.array([1.0, 0.8, 0.6]) - 1e-9), axis=1)
    X[inner] += rng.uniform(-0.05, 0.05, (inner.sum(), 3))
    if kind != "hex8":
        conn = tet4.split_hexahedra(X, conn)
        el = tet4.TET4
        if kind == "tet10":
            X, conn = tet10.quadratic(X, conn)
            el = tet10.TET10
    assert not len(inverted_elements(X, conn))
    A = np.array([[1.0, 0.3, -0.2], [0.1, -0.5, 0.4], [0.25, -0.15, 0.7]]) * 1e-3
    u = (X @ A.T).ravel()
    eps = np.zeros((len(conn) * el.ngauss, 6))
    solid.gauss_strains(X, conn, u, eps, el)
    expected = [A[0, 0], A[1, 1], A[2, 2], A[1, 2] + A[2, 1], A[0, 2] + A[2, 0],
                A[0, 1] + A[1, 0]]
    assert np.abs(eps - expected).max() <= 1e-12
    K, m = solid.assemble_block(X, conn, solid.elastic_matrix(30e9, 0.2), 2000.0, el)
    f = (K @ u).reshape(-1, 3)
    boundary = np.any((np.abs(X) < 1e-9) | (np.abs(X - [1.0, 0.8, 0.6]) < 1e-9), axis=1)
    assert np.abs(f[~boundary]).max() <= 1e-9 * np.abs(f).max()
    assert m.sum() / 3 == pytest.approx(2000.0 * 0.48, rel=1e-12)  # the box's mass, kg
    assert m.min() > 0.0


def _cantilever_stiffness(kind: str, L=1.0, h=0.1, E=1e9) -> float:
    """Tip force over the mean tip deflection (N/m) of a square cantilever ``L x h x h``, 20 x 2
    x 2 cubes (or their tetrahedra), clamped at x = 0, a transverse force spread equally over
    the nodes of the free end; ``nu = 0`` (the clamp adds no lateral constraint)."""
    X, conn, el = _box((0, 0, 0), (L, h, h), (20, 2, 2), kind)
    K, _ = solid.assemble_block(X, conn, solid.elastic_matrix(E, 0.0), 1.0, el)
    free = np.repeat(X[:, 0] > 1e-9, 3)
    tip = np.flatnonzero(np.abs(X[:, 0] - L) < 1e-9)
    f = np.zeros(3 * len(X))
    f[3 * tip + 1] = 1.0 / len(tip)
    u = np.zeros_like(f)
    u[free] = scipy.linalg.solve(K[np.ix_(free, free)], f[free], assume_a="pos")
    return 1.0 / u[3 * tip + 1].mean()


def test_cantilever_stiffness_against_beam_theory():
    """Timoshenko's tip stiffness (nu = 0, G = E / 2, kappa = 5/6) against the meshes: the
    10-node tetrahedra within 2 % (quadratic displacements bend), the hexahedra too stiff by
    their parasitic shear, ``1 + 0.5 / 2^2`` in bending for cubes two through the depth
    (module docstring; the shear deflection, 0.6 % of the total, is not stiffened), the 4-node
    tetrahedra (constant strain) stiffer still."""
    L, h, E = 1.0, 0.1, 1e9
    I, A, G = h ** 4 / 12, h * h, E / 2
    bending, shear = L ** 3 / (3 * E * I), L / (5 / 6 * G * A)
    k_beam = 1.0 / (bending + shear)
    ratio = {k: _cantilever_stiffness(k, L, h, E) / k_beam for k in ("hex8", "tet4", "tet10")}
    print("stiffness / Timoshenko:", {k: round(v, 3) for k, v in ratio.items()})
    assert ratio["tet10"] == pytest.approx(1.0, abs=0.02)
    hex_predicted = 1.0 / (bending / (1 + 0.5 / 2 ** 2) + shear) / k_beam
    assert ratio["hex8"] == pytest.approx(hex_predicted, rel=0.01)
    assert ratio["tet4"] > ratio["hex8"]


@pytest.mark.parametrize("kind", ["tet4", "tet10"])
def test_a_rigid_body_from_tetrahedra_has_the_box_mass_and_inertia(kind):
    """A box of tetrahedra: mass, centre of mass and inertia tensor those of the box, to
    round-off (the degree-2 rule is exact on each tetrahedron)."""
    size = np.array([0.4, 0.25, 0.15])
    X, conn, _ = _box((1.0, 2.0, -0.5), size, (2, 2, 1), kind)
    body = RigidBody.from_mesh(X, conn, 1800.0)
    m = 1800.0 * size.prod()
    a, b, c = size
    assert body.mass == pytest.approx(m, rel=1e-12)
    assert np.allclose(body.center, np.array([1.0, 2.0, -0.5]) + size / 2, rtol=0, atol=1e-12)
    expected = m / 12 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    assert np.allclose(body.inertia, expected, rtol=0, atol=1e-12 * expected.max())


def test_inverted_and_flat_tetrahedra_are_found():
    """A tetrahedron with two nodes swapped is inverted; one with its apex in its base's plane
    is flat; the positive ones are not."""
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.3, 0.3, 0.0]], dtype=float)
    conn = np.array([[0, 1, 2, 3], [0, 2, 1, 3], [0, 1, 2, 4]])
    assert inverted_elements(X, conn).tolist() == [1, 2]
    X10, c10 = tet10.quadratic(X, conn)
    assert inverted_elements(X10, c10).tolist() == [1, 2]


def _wall_mesh(kind: str) -> BlockMesh:
    """Two columns of two blocks (0.2 m cubes) on a base slab, each block meshed with one
    hexahedron or its six tetrahedra (of 4 or 10 nodes); the slab with a hexahedron."""
    types = ("hexahedron", "tetra", "tetra10")
    pts, names = [], {}
    sets: dict[str, list] = {t: [] for t in types}
    tags: dict[str, list] = {t: [] for t in types}
    boxes = [((-0.1, -0.1, 0.0), (0.6, 0.1, 0.2), "base")]
    boxes += [((0.2 * i, 0.2 * j, 0.0), (0.2, 0.2, 0.2), f"block {i} {j}")
              for j in range(2) for i in range(2)]
    for k, (o, s, name) in enumerate(boxes):
        X, c = hex8.box_mesh(np.array(o), np.array(s), (1, 1, 1))
        t = "hexahedron"
        if kind != "hex8" and name != "base":
            c, t = tet4.split_hexahedra(X, c), "tetra"
            if kind == "tet10":
                X, c = tet10.quadratic(X, c)
                t = "tetra10"
        n0 = sum(len(p) for p in pts)
        pts.append(X)
        sets[t].append(c + n0)
        tags[t].append(np.full(len(c), k + 1))
        names[k + 1] = name
    return BlockMesh(np.concatenate(pts), np.concatenate(sets["hexahedron"]),
                     np.concatenate(tags["hexahedron"]), names,
                     {t: (np.concatenate(sets[t]), np.concatenate(tags[t]))
                      for t in types[1:] if sets[t]})


def test_mixed_mesh_files_read_back(tmp_path):
    """A file with hexahedral and tetrahedral blocks: each block's cells of its own type."""
    write_block_mesh(tmp_path / "w.msh", _wall_mesh("tet4"))
    mesh = read_block_mesh(tmp_path / "w.msh")
    assert mesh.block_tags().tolist() == [1, 2, 3, 4, 5]
    assert mesh.block_cells(1).shape == (1, 8)
    assert all(mesh.block_cells(t).shape == (6, 4) for t in (2, 3, 4, 5))


def _wall_case(tmp_path: Path, kind: str):
    write_block_mesh(tmp_path / f"{kind}.msh", _wall_mesh(kind))
    data = read_yaml((ROOT / "cases" / "pier_arches.yaml").read_text())
    data["assembly"] = {"mesh_file": str(tmp_path / f"{kind}.msh"),
                        "supports": [{"group": "base"}], "contact_point_rule": "overlap"}
    if kind != "hex8":  # auto: overlap for tetrahedral blocks
        del data["assembly"]["contact_point_rule"]
    data["loading"]["body_force"].update(rate_per_s=0.5)
    data["collapse"]["end_time_s"] = 1.6
    data["output"]["vtu"] = False
    return data


def test_an_inverted_tetrahedron_exits_2_naming_its_block(tmp_path):
    mesh = _wall_mesh("tet4")
    cells, tags = mesh.others["tetra"]
    cells = cells.copy()
    first = np.flatnonzero(tags == 3)[0]
    cells[first, [1, 2]] = cells[first, [2, 1]]
    mesh.others["tetra"] = (cells, tags)
    write_block_mesh(tmp_path / "tet4.msh", mesh)
    data = _wall_case(tmp_path, "tet4")
    write_block_mesh(tmp_path / "tet4.msh", mesh)
    (tmp_path / "case.yaml").write_text(json.dumps(data))
    res = CliRunner().invoke(app, ["validate", str(tmp_path / "case.yaml")])
    assert res.exit_code == 2
    assert "'block 1 0'" in res.output and "tetrahedra inverted" in res.output


def test_triangular_faces_take_the_overlap_rule_only(tmp_path):
    """A tetrahedral block with ``contact_point_rule: lobatto``: exit 2 naming the blocks and
    the field."""
    data = _wall_case(tmp_path, "tet4")
    data["assembly"]["contact_point_rule"] = "lobatto"
    (tmp_path / "case.yaml").write_text(json.dumps(data))
    res = CliRunner().invoke(app, ["validate", str(tmp_path / "case.yaml")])
    assert res.exit_code == 2
    assert "contact_point_rule" in res.output and "'block 0 0'" in res.output


def test_a_wall_of_rigid_blocks_collapses_at_the_same_multiplier_with_tetrahedra(tmp_path):
    """The wall of ``_wall_mesh`` with rigid blocks under a horizontal body force that grows
    at 0.5 / s: meshed with hexahedra or tetrahedra (the same geometry, joints on the
    common areas of the faces), the multiplier at the onset of collapse is the same within the
    step of the multiplier over one output interval, and near ``b / h = 0.5`` of a column of
    two cubes rocking on its toe (the dynamic onset lags the static value)."""
    from masonry_nscd.run import run_case

    lam = {}
    for kind in ("hex8", "tet4"):
        case = case_from_dict(_wall_case(tmp_path, kind), check_files=True)
        run_case(case, tmp_path / kind, echo=lambda _m: None)
        s = json.loads((tmp_path / kind / "summary.json").read_text())
        assert s["status"] == "collapse", kind
        lam[kind] = s["collapse"]["loads_at_onset"]["lambda"]
    print("collapse multipliers:", lam)
    step = 0.5 * 25 * 0.002  # rate x output interval
    assert lam["tet4"] == pytest.approx(lam["hex8"], abs=step)
    assert lam["hex8"] == pytest.approx(0.5, rel=0.1)


def test_an_endo3d_tetrahedral_block_softens_as_a_hexahedral_one():
    """A 0.1 m cube of ENDO3D as one hexahedron and as its six tetrahedra, side by side in one
    batch (two runs of element types), stretched along x (uniform strain, the lateral
    contraction of a uniaxial stress): the force on the x = 0.1 m face over its area peaks at
    the tensile strength R_t and softens the same way for both (each tetrahedron spans the cube
    along x, so the Hillerborg length is the cube's side for both)."""
    from masonry_nscd.materials.blocks import Endo3dBlocks
    from masonry_nscd.materials.endo3d import endo3d_params
    from masonry_nscd.model import MAT_ENDO3D, Block

    E, nu, R_t = 11.1e9, 0.2, 1.0e6
    prm = endo3d_params(E=E, nu=nu, R_t=R_t, eps_pic_t=R_t / E, G_ft=60.0, R_c=9.46e6,
                        eps_pic_c=0.13e-1, delta=0.4, beta=0.2, eps_kdc=0.18e-1, DCPK=1.0,
                        REF=0.3e6, GFR=4.5)
    blocks = []
    for kind in ("hex8", "tet4"):
        X, conn, _ = _box((0, 0, 0), (0.1, 0.1, 0.1), (1, 1, 1), kind)
        blocks.append(Block(X=X, conn=conn, E=E, nu=nu, density=2000.0, material=MAT_ENDO3D))
    dof0 = np.cumsum([0] + [b.ndof for b in blocks])
    mat = Endo3dBlocks(blocks, dof0, prm)
    assert len(mat.runs) == 2
    stress = {0: [], 1: []}
    fint = np.zeros(dof0[-1])
    for eps in np.linspace(0.0, 3.0, 61)[1:] * R_t / E:
        u = np.concatenate([(b.X * [eps, -nu * eps, -nu * eps]).ravel() for b in blocks])
        mat.internal_forces(u, fint)
        assert mat.failures == 0
        mat.commit()
        for k, b in enumerate(blocks):
            face = np.flatnonzero(np.abs(b.X[:, 0] - 0.1) < 1e-12)
            stress[k].append(fint[dof0[k] + 3 * face].sum() / 0.01)
    hexa, tets = np.array(stress[0]), np.array(stress[1])
    print(f"peak stress: hexahedron {hexa.max():.4g} Pa, tetrahedra {tets.max():.4g} Pa")
    assert hexa.max() == pytest.approx(R_t, rel=0.02)
    assert tets.max() == pytest.approx(hexa.max(), rel=1e-3)
    assert tets[-1] < 0.9 * tets.max()  # softened
    assert np.allclose(tets, hexa, rtol=0, atol=1e-3 * R_t)
    K = mat.tangent_stiffness()
    assert [k.shape for k in K] == [(24, 24), (24, 24)]


def _column_compliance(kind: str, divisions) -> float:
    """Static top displacement (m) per N of horizontal body force of one column of the wall
    (0.2 x 0.4 x 0.2 m, E = 1e8 Pa, nu = 0, clamped at its base, the force spread as the lumped
    masses), at the node the wall's curve measures (0, 0.2, 0)."""
    X, conn, el = _box((0, 0, 0), (0.2, 0.4, 0.2), divisions, kind)
    K, m = solid.assemble_block(X, conn, solid.elastic_matrix(1e8, 0.0), 2000.0, el)
    f = np.zeros(3 * len(X))
    f[0::3] = m[0::3] / m[0::3].sum()
    free = np.repeat(X[:, 1] > 1e-9, 3)
    u = np.zeros_like(f)
    u[free] = scipy.linalg.solve(K[np.ix_(free, free)], f[free], assume_a="pos")
    return u[3 * np.flatnonzero(np.all(np.abs(X - [0.0, 0.2, 0.0]) < 1e-9, axis=1))[0]]


def test_an_elastic_wall_has_the_stiffness_its_elements_predict(tmp_path):
    """The wall of ``_wall_mesh`` with elastic blocks (E = 1e8 Pa, nu = 0: the blocks, not the
    stiff joints, deform), pushed by a horizontal body force growing slowly to 0.1 g: the
    compliance ``d U_x / d F_x`` of each mesh is that of a static solve of one of its columns
    with the same elements (the dry head joint carries no shear without compression, so the
    columns bend side by side, each with half the force) within 5 %. Against the converged
    column (10-node tetrahedra, 4 x 8 x 4 cubes), one hexahedron per block is 1.5 times too
    stiff (its parasitic shear in bending, one element through the depth: the module
    docstring's ``1 + a^2 / (2 b^2)``), six 10-node tetrahedra per block within 10 %, six
    4-node ones stiffer than the hexahedron."""
    from masonry_nscd.run import run_case

    run, static = {}, {}
    converged = _column_compliance("tet10", (4, 8, 4))
    for kind in ("hex8", "tet4", "tet10"):
        data = _wall_case(tmp_path, kind)
        data["blocks"] = {"material": "elastic", "density_kg_m3": 2000.0, "E_Pa": 1e8,
                          "nu": 0.0}
        data["collapse"]["end_time_s"] = 0.45
        run_case(case_from_dict(data, check_files=True), tmp_path / kind,
                 echo=lambda _m: None)
        rows = np.genfromtxt(tmp_path / kind / "force_displacement.csv", delimiter=",",
                             names=True)
        late = rows["time_s"] >= 0.3 - 1e-9  # the push, past the load's ramp
        slope = np.polyfit(-rows["fx_kN"][late] * 1e3, rows["ux_mm"][late] * 1e-3, 1)[0]
        run[kind] = slope
        static[kind] = _column_compliance(kind, (1, 2, 1)) / 2  # two columns share the force
        assert run[kind] == pytest.approx(static[kind], rel=0.05), kind
    print("wall stiffness over the converged column's:",
          {k: round(converged / 2 / v, 3) for k, v in run.items()})
    assert converged / 2 / run["hex8"] == pytest.approx(1.5, rel=0.05)
    assert converged / 2 / run["tet10"] == pytest.approx(1.0, abs=0.1)
    assert run["tet4"] < run["hex8"]


def test_tetrahedra_are_written_to_vtu_as_tetrahedra(tmp_path):
    """Drawn as collapsed hexahedra, tetrahedra are read back from the blocks' VTU (by meshio)
    as VTK tetrahedra of their four corners, the hexahedra as they were."""
    import meshio

    from masonry_nscd.io.vtu import write_blocks_vtu

    X, hexes = hex8.box_mesh(np.zeros(3), np.ones(3), (1, 1, 1))
    tets = tet4.split_hexahedra(X, hexes)
    write_blocks_vtu(tmp_path / "b.vtu", X, np.concatenate([hexes, tets[:, tet4.DRAWN_AS]]),
                     cell_data={"id": np.arange(7.0)})
    m = meshio.read(tmp_path / "b.vtu")
    assert [b.type for b in m.cells] == ["hexahedron", "tetra"]
    assert (m.cells[0].data == hexes).all() and (m.cells[1].data == tets).all()

