"""Contact detection (model/detection.py) on shapes other than axis-aligned boxes, its broad
phase against brute force, and what each contact point must satisfy on the study's walls."""

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from masonry_nscd.case import load_case
from masonry_nscd.cli import app
from masonry_nscd.contact.laws import KIND_JOINT
from masonry_nscd.fe.hex8 import box_mesh
from masonry_nscd.model import Block, RigidBody
from masonry_nscd.model.detection import candidate_pairs, contact_points, find_joints
from masonry_nscd.model.faces import locate
from masonry_nscd.scenes import build_scene

JOINT = lambda joint, antagonist: (0, KIND_JOINT, 0)


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _block(X, conn, name=""):
    return Block(X=X, conn=conn, E=1e10, nu=0.2, density=2000.0, name=name)


@pytest.mark.parametrize("angle", [0.0, 0.3, 1.1])
def test_a_rotated_stack_has_one_bed_joint_at_the_joint_thickness(angle):
    """Two 0.3 x 0.1 x 0.15 m units 10 mm apart, turned about z: one joint, its 2 x 2 x 4
    points on the upper unit, the normal and the gap turned with them, the area the face's."""
    R = _rotation(angle)
    bodies = []
    for y0 in (0.0, 0.11):
        X, conn = box_mesh(np.array([0.0, y0, 0.0]), np.array([0.3, 0.1, 0.15]), (2, 1, 1))
        bodies.append(_block(X @ R.T, conn))
    pts = contact_points(bodies, JOINT, max_gap=0.01)
    assert len(pts) == 2 * 4
    normal = R @ np.array([0.0, 1.0, 0.0])
    n_up = 1 if normal[1] > 0 or (abs(normal[1]) < 1e-6 and normal[0] > 0) else 0
    for p in pts:
        assert p.bodies == (n_up, 1 - n_up)
        assert np.allclose(p.frame[0], normal if n_up == 1 else -normal, atol=1e-12)
        assert p.gap == pytest.approx(0.01, abs=1e-12)
    assert sum(p.area for p in pts) == pytest.approx(0.3 * 0.15, rel=1e-12)


@pytest.mark.parametrize(("order", "count"), [(2, 3 * 2), (3, 5 * 3), (4, 7 * 4)])
def test_lobatto_points_sit_on_the_corners_once_each(order, count):
    """The Gauss-Lobatto rule on a 2 x 1 quad face of 0.3 x 0.15 m: the points shared by the two
    quads are made once (order 2: the 3 x 2 nodes), the outer ones on the face's edges, and the
    areas add up to the face's, the shared points' counted from both quads."""
    bodies = []
    for y0 in (0.0, 0.11):
        X, conn = box_mesh(np.array([0.0, y0, 0.0]), np.array([0.3, 0.1, 0.15]), (2, 1, 1))
        bodies.append(_block(X, conn))
    pts = contact_points(bodies, JOINT, max_gap=0.01, n_gauss=order, rule="lobatto")
    assert len(pts) == count
    x = np.array([p.x for p in pts])
    assert x[:, 0].min() == pytest.approx(0.0, abs=1e-12)
    assert x[:, 0].max() == pytest.approx(0.3, abs=1e-12)
    assert x[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    assert x[:, 2].max() == pytest.approx(0.15, abs=1e-12)
    assert sum(p.area for p in pts) == pytest.approx(0.3 * 0.15, rel=1e-12)
    assert len({tuple(np.round(xi, 9)) for xi in x}) == count  # no twins
    if order == 2:  # trapezoidal rule: a quarter of a quad at a corner, a half on the middle
        areas = sorted(p.area for p in pts)
        assert areas == pytest.approx([0.15 * 0.15 / 4] * 4 + [0.15 * 0.15 / 2] * 2)


def test_a_lobatto_point_over_a_head_joint_is_shared_by_both_units_below():
    """A 0.3 m unit (two quads along x) on two 0.15 m units that meet under its middle node:
    that node's point is made for each unit below, with half its area each, so that both carry
    it; with Gauss points none sits on that edge."""
    X, conn = box_mesh(np.array([0.0, 0.1, 0.0]), np.array([0.3, 0.1, 0.15]), (2, 1, 1))
    bodies = [_block(X, conn)]
    for x0 in (0.0, 0.15):
        X, conn = box_mesh(np.array([x0, 0.0, 0.0]), np.array([0.15, 0.1, 0.15]), (1, 1, 1))
        bodies.append(_block(X, conn))
    pts = [p for p in contact_points(bodies, JOINT, max_gap=0.0, rule="lobatto")
           if p.bodies[0] == 0]  # the bed joint (the units below also meet at a head joint)
    middle = [p for p in pts if abs(p.x[0] - 0.15) < 1e-12]
    assert sorted(p.bodies[1] for p in middle) == [1, 1, 2, 2]
    assert all(p.area == pytest.approx(0.15 * 0.15 / 4) for p in middle)
    for below in (1, 2):
        assert sum(p.area for p in pts if p.bodies[1] == below) == pytest.approx(0.15 * 0.15)
    assert sum(p.bodies[0] == 0 for p in contact_points(bodies, JOINT, max_gap=0.0)) == 8


def test_voussoirs_meet_on_their_inclined_joint():
    """Two wedge-shaped voussoirs (hexahedra that are not boxes) of an arch, their joint a
    radial plane: detected, points on the joint's plane, the normal along the arch."""
    R0, R1, t = 1.0, 1.2, 0.2
    def voussoir(a0, a1, gap_angle=0.0):
        a0 += gap_angle
        corners = []
        for z in (0.0, t):
            for r, a in ((R0, a0), (R0, a1), (R1, a1), (R1, a0)):
                corners.append((r * np.cos(a), r * np.sin(a), z))
        # hex8 order: bottom face (z = 0) counter-clockwise seen from +z, then the top face
        X = np.array(corners)
        return _block(X, np.array([[0, 1, 2, 3, 4, 5, 6, 7]]))
    a = voussoir(np.pi / 2, np.pi / 3)  # counter-clockwise in a descending angle: flip order
    a.X = a.X[[1, 0, 3, 2, 5, 4, 7, 6]]
    b = voussoir(np.pi / 3, np.pi / 6)
    b.X = b.X[[1, 0, 3, 2, 5, 4, 7, 6]]
    pts = contact_points([a, b], JOINT, max_gap=0.0)
    assert len(pts) == 4
    radial = np.array([np.cos(np.pi / 3), np.sin(np.pi / 3), 0.0])
    normal = np.cross(radial, (0.0, 0.0, 1.0))
    for p in pts:
        assert abs(p.x @ normal) < 1e-12  # on the joint's plane
        assert abs(abs(p.frame[0] @ normal) - 1.0) < 1e-12
    assert sum(p.area for p in pts) == pytest.approx((R1 - R0) * t, rel=1e-12)


@pytest.mark.parametrize("case, n", [
    ("apart beyond the joint", 0),         # 12 mm apart, joint of 10 mm
    ("side by side", 0),                    # faces in line, not facing
    ("offset, not overlapping", 0),         # facing planes, no overlap
    ("half overlapping", 4),                # half the upper face over the lower one
])
def test_what_is_not_a_joint(case, n):
    lower = box_mesh(np.array([0.0, 0.0, 0.0]), np.array([0.3, 0.1, 0.15]), (2, 1, 1))
    origin = {"apart beyond the joint": (0.0, 0.112, 0.0), "side by side": (0.31, 0.0, 0.0),
              "offset, not overlapping": (0.31, 0.11, 0.0),
              "half overlapping": (0.15, 0.11, 0.0)}[case]
    upper = box_mesh(np.array(origin), np.array([0.3, 0.1, 0.15]), (2, 1, 1))
    bodies = [_block(*lower), _block(*upper)]
    pts = contact_points(bodies, lambda j, a: (0, KIND_JOINT, 0), max_gap=0.01)
    if case == "side by side":  # the facing end faces form a head joint, no bed joint
        assert all(abs(p.frame[0][1]) < 1e-12 for p in pts)
        return
    assert len(pts) == n


@settings(max_examples=50, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 10), st.floats(0, 10), st.floats(0, 10),
                          st.floats(0, 3), st.floats(0, 3), st.floats(0, 0.5)),
                min_size=0, max_size=40))
def test_the_grid_broad_phase_finds_every_overlapping_pair(boxes):
    _check_broad_phase(boxes)


def _check_broad_phase(boxes):
    lo = np.array([b[:3] for b in boxes]).reshape(-1, 3)
    hi = lo + np.array([b[3:] for b in boxes]).reshape(-1, 3)
    got = {tuple(p) for p in candidate_pairs(lo, hi)}
    want = {(i, j) for i in range(len(lo)) for j in range(i + 1, len(lo))
            if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i])}
    assert got == want


@pytest.mark.parametrize("boxes", [
    # flat boxes: a median extent of 1e-12 made the 0.5 m box span 5e11 cells (3.6 TiB)
    [(0, 0, 0, 0, 0, 0), (0, 0, 0, 0, 0, 0.5), (0, 0, 0, 0, 0, 1e-12)],
    # points far apart: the cells' keys must not overflow
    [(0, 0, 0, 0, 0, 0), (1e9, 1e9, 1e9, 0, 0, 0), (1e9, 1e9, 1e9, 0, 0, 0)],
])
def test_the_grid_broad_phase_on_degenerate_boxes(boxes):
    _check_broad_phase(boxes)


@pytest.mark.parametrize("material", ["elastic", "rigid"])
def test_every_point_faces_its_antagonist(material):
    """On the study's wall, each contact point projected across its gap lies on a boundary
    face of its antagonist, rigid units included (a point tied to a unit it does not face
    would carry forces across empty space)."""
    scene = build_scene(load_case("cases/wall_0.5MPa_elastic.yaml",
                                  [f"blocks.material={material}"]))
    bodies = scene.bodies
    for p in scene.points:
        ant = bodies[p.bodies[1]]
        xa = p.x - p.gap * p.frame[0]
        lo, hi = ant.X.min(axis=0), ant.X.max(axis=0)
        assert np.all(xa >= lo - 1e-9) and np.all(xa <= hi + 1e-9), (p.x, p.bodies)
    # 1096 points at 2 x 2 x 1 (tests/test_wall_run.py); the four corner units at 4 x 4 x 1
    # carry 16 points per bed and head face instead of 8: +16 on each glue, +16 on the bed
    # faces of the top course's two corners, +16 on the head faces of the two right corners
    assert len(scene.points) == 1096 + 4 * 16


def test_rigid_smoke_wall_is_symmetric_under_the_vertical_load(tmp_path):
    """Rigid units on a symmetric wall: no horizontal force before the horizontal stage."""
    from masonry_nscd.io.runfolder import read_curve_csv
    from masonry_nscd.run import run_case

    case = load_case("cases/smoke.yaml", ["blocks.material=rigid", "output.vtu=false",
                                          "output.hdf5=false"])
    run_case(case, tmp_path / "r", echo=lambda m: None)
    c = read_curve_csv(tmp_path / "r" / "force_displacement.csv")
    before = c["time_s"] < case.loading.horizontal.start_s
    assert np.abs(c["fx_kN"][before]).max() < 1e-6 * np.abs(c["fy_kN"][before]).max()


def test_a_rigid_body_from_a_mesh_has_the_box_mass_properties():
    X, conn = box_mesh(np.array([0.1, 0.2, 0.3]), np.array([0.3, 0.1, 0.15]), (3, 2, 1))
    a = RigidBody.from_mesh(X @ _rotation(0.0).T, conn, 2000.0)
    b = RigidBody.box((0.1, 0.2, 0.3), (0.3, 0.1, 0.15), 2000.0)
    assert a.mass == pytest.approx(b.mass, rel=1e-12)
    assert np.allclose(a.center, b.center, atol=1e-14)
    scale = np.abs(b.inertia).max()  # the second moment less m c c^T: round-off of 1e-14
    assert np.allclose(a.inertia, b.inertia, rtol=0.0, atol=1e-12 * scale)
    turned = RigidBody.from_mesh(X @ _rotation(0.4).T, conn, 2000.0)
    R = _rotation(0.4)
    assert np.allclose(turned.inertia, R @ b.inertia @ R.T, rtol=0.0, atol=1e-12 * scale)


def test_a_point_is_located_in_a_general_quad():
    P = np.array([[[0.0, 0.0, 0.0], [2.0, 0.2, 0.0], [2.5, 1.5, 0.0], [-0.2, 1.0, 0.0]]])
    xi, eta = np.array([-0.3, 0.7, 0.9]), np.array([0.5, -0.8, 0.95])
    N = 0.25 * np.stack([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta),
                         (1 - xi) * (1 + eta)], axis=-1)
    x = N @ P[0]
    gx, ge, inside = locate(P, x)
    assert np.allclose(gx[:, 0], xi, atol=1e-12) and np.allclose(ge[:, 0], eta, atol=1e-12)
    assert inside.all()
    assert not locate(P, np.array([[3.0, 3.0, 0.0]]))[2].any()


def test_find_joints_names_one_joint_per_candidate_face():
    scene_bodies = build_scene(load_case("cases/smoke.yaml")).bodies
    found = find_joints(scene_bodies, max_gap=0.01)
    # smoke wall: 3 + 4 + 3 units; bed faces of courses 2-3 (7), head faces (2 + 3 + 2),
    # glue under course 1 (3) and over course 3 (3)
    assert len(found.joints) == 7 + 7 + 3 + 3


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("gap", "rule"), [(0.0, "gauss"), (0.01, "gauss"), (0.01, "lobatto")])
def test_detection_does_not_depend_on_the_orientation(seed, gap, rule):
    """A stack-bonded 2 x 3 assembly turned by a random rotation in 3D (its joints' normals
    with components along every axis, as an arch's radial joints or a vault's) and moved: the
    same points, areas and gaps as the assembly as built; the frames turned with it. (Not
    with Lobatto points and no gap: a unit's corner on the edge between two units of the other
    course is shared between them, and which corners those are depends on which unit of a
    joint carries the points, the upper one.)"""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = q * np.sign(np.linalg.det(q))  # a proper rotation

    def assembly(R, shift):
        bodies = []
        for i in range(3):
            for k in range(2):
                X, conn = box_mesh(np.array([k * (0.3 + gap), i * (0.1 + gap), 0.0]),
                                   np.array([0.3, 0.1, 0.15]), (2, 2, 1))
                bodies.append(_block(X @ R.T + shift, conn))
        return bodies

    shift = rng.normal(size=3)
    built = contact_points(assembly(np.eye(3), np.zeros(3)), JOINT, max_gap=gap, rule=rule)
    turned = contact_points(assembly(Q, shift), JOINT, max_gap=gap, rule=rule)
    assert len(turned) == len(built)

    def key(p, x, n):  # the joint's bodies and the point moved to the joint's middle plane
        return tuple(sorted(p.bodies)), tuple(np.round(x - 0.5 * p.gap * n, 9) + 0.0)

    # which of two bodies carries the points depends on the orientation (the upper one)
    by_key = {key(p, p.x, p.frame[0]): p for p in built}
    for p in turned:
        b = by_key[key(p, Q.T @ (p.x - shift), Q.T @ p.frame[0])]
        assert p.area == pytest.approx(b.area, rel=1e-12)
        assert p.gap == pytest.approx(b.gap, abs=1e-12)
        assert abs(p.frame[0] @ (Q @ b.frame[0])) == pytest.approx(1.0, abs=1e-12)



def test_bench_detection_counts_the_scenes_joints_and_points():
    """``masonry bench-detection`` finds again the joints and points that the builder made."""
    case_file = Path(__file__).resolve().parents[1] / "cases" / "dome_hemispherical.yaml"
    sets = ["dome.courses=3", "dome.voussoirs=8", "dome.contact_point_rule=overlap"]
    res = CliRunner().invoke(app, ["bench-detection", str(case_file), "--repeats", "1",
                                   *[a for s in sets for a in ("--set", s)]])
    assert res.exit_code == 0, res.output
    scene = build_scene(load_case(case_file, sets))
    assert "blocks 24, joints" in res.output
    assert f"contact points {len(scene.points)}" in res.output
