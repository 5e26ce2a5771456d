"""Past the peak: meshes refined where crushing localises, the crushing length that makes the
compressive softening independent of the element size, scattered joint properties, and the
failure mode named in the summary."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.cli import app
from masonry_nscd.contact.scatter import lognormal_factors
from masonry_nscd.io.results_h5 import read_fields
from masonry_nscd.io.runfolder import read_scene_info
from masonry_nscd.post.failure import failure_mode
from masonry_nscd.scenes import build_scene

STUDY = "cases/wall_0.5MPa_elastic.yaml"
CORNERS = "wall.refine=[{courses: [1, -1], units: [1, -1], elements_per_unit: [6, 6, 2]}]"


def _areas(scene):
    out = {}
    for p in scene.points:
        g = scene.groups[p.group]
        out[g] = out.get(g, 0.0) + p.area
    return out


def test_refined_corner_units_keep_every_joint_whole():
    """The four corner units meshed 6 x 6 x 2: more elements and points there, and the joints
    (non-conforming now) carry the same areas as on the uniform mesh."""
    plain = build_scene(load_case(STUDY))
    fine = build_scene(load_case(STUDY, [CORNERS]))
    sizes = [len(fine.bodies[i].conn) for i in fine.structure]
    assert sorted(sizes)[-4:] == [72] * 4 and sizes.count(4) == 71 - 4
    corners = [fine.body_info[k]["name"] for k, n in enumerate(sizes) if n == 72]
    assert corners == ["course 1 (bottom), unit 1 of 6 (left end)",
                       "course 1 (bottom), unit 6 of 6 (right end)",
                       "course 11 (top), unit 1 of 6 (left end)",
                       "course 11 (top), unit 6 of 6 (right end)"]
    assert len(fine.points) > len(plain.points)
    for g, a in _areas(plain).items():
        assert _areas(fine)[g] == pytest.approx(a, rel=1e-12), g


def test_the_last_refine_region_wins_and_null_units_mean_all():
    case = load_case(STUDY, [("wall.refine=[{courses: [2], elements_per_unit: [3, 1, 1]}, "
                              "{courses: [2], units: [-1], elements_per_unit: [1, 1, 1]}]")])
    scene = build_scene(case)
    course2 = [(s["position_in_course"], len(scene.bodies[s["body"]].conn))
               for s in scene.info()["structure"] if s["course"] == 2]
    assert course2 == [(k, 3) for k in range(1, 7)] + [(7, 1)]


def test_lognormal_factors_have_mean_one_and_the_cv():
    f = lognormal_factors(0.3, (200000,), np.random.default_rng(5))
    assert f.mean() == pytest.approx(1.0, abs=3 * 0.3 / np.sqrt(f.size))
    assert f.std() / f.mean() == pytest.approx(0.3, rel=0.01)
    assert np.all(f > 0.0)


@pytest.mark.parametrize("per", ["joint", "face"])
def test_scatter_draws_one_row_per_joint_or_face(per):
    sets = [f"joint.scatter={{cv: 0.25, seed: 7, per: {per}, fields: [sigma_II_e_Pa]}}"]
    scene = build_scene(load_case(STUDY, sets))
    again = build_scene(load_case(STUDY, sets))
    other = build_scene(load_case(STUDY, [sets[0].replace("seed: 7", "seed: 8")]))
    law = np.array([p.law for p in scene.points])
    glue = np.array([scene.groups[p.group].startswith("glue") for p in scene.points])
    assert np.all(law[glue] == 0) and np.all(law[~glue] > 0)
    key = [tuple(sorted(p.bodies)) if per == "joint" else (p.bodies[0], p.face)
           for p in scene.points]
    rows: dict = {}
    for k, r, g in zip(key, law, glue):
        if not g:
            assert rows.setdefault(k, r) == r  # one row per key
    assert len(set(rows.values())) == len(rows) == len(scene.params) - 1
    drawn = scene.point_fields["joint_sigma_II_e_Pa"]
    assert np.all(drawn[glue] == 0.27e6) and np.std(drawn[~glue]) > 0.1 * 0.27e6
    assert np.array_equal(drawn, again.point_fields["joint_sigma_II_e_Pa"])  # the seed decides
    assert not np.array_equal(drawn, other.point_fields["joint_sigma_II_e_Pa"])
    # only the scattered field moves in the rows
    assert np.all(scene.params[:, :8] == scene.params[0, :8])


def test_a_scattered_run_writes_its_draws(tmp_path):
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out), "--set",
                                   "joint.scatter={cv: 0.3, seed: 2}", "--set",
                                   "loading.horizontal.target_m=0.1e-3"])
    assert res.exit_code == 0, res.output
    import h5py
    import meshio

    with h5py.File(out / "results.h5") as f:
        drawn = np.asarray(f["mesh/contact_joint_G_fII_J_m2"])
    joints = meshio.read(max((out / "vtu").glob("joints_*.vtu")))
    assert np.allclose(joints.point_data["joint_G_fII_J_m2"], drawn)
    assert np.std(drawn) > 0.0
    case = load_case(out / "case.yaml")
    assert case.joint.scatter.cv == 0.3 and case.joint.scatter.seed == 2


def test_a_scatter_the_law_refuses_is_a_clear_input_error(tmp_path):
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(tmp_path / "r"),
                                   "--set", "joint.G_fI_J_m2=0.011", "--set",
                                   "joint.scatter={cv: 2.0, seed: 1, fields: [G_fI_J_m2]}"])
    assert res.exit_code == 2 and "joint.scatter" in res.output
    with pytest.raises(CaseError, match="joint.scatter.per"):
        load_case(STUDY, ["joint.scatter={per: unit}"])


@pytest.fixture(scope="module")
def smoke_fields(tmp_path_factory):
    out = tmp_path_factory.mktemp("fm") / "run"
    res = CliRunner().invoke(app, ["run", "cases/smoke.yaml", "-o", str(out), "--set",
                                   "output.vtu=false"])
    assert res.exit_code == 0, res.output
    return out


def test_the_failure_mode_is_named_from_the_damage(smoke_fields):
    out = smoke_fields
    scene = read_scene_info(out)
    f = read_fields(out / "results.h5")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["failure_mode"]["mode"] == "none"  # elastic, 0.5 mm: nothing broken
    assert "failure_mode_at_peak" in summary
    assert summary["failure_sequence"] == {"base_joint_80pct_lost_at_ux_mm": None,
                                           "middle_course_head_joint_cracked_at_ux_mm": None,
                                           "middle_course": 2}
    groups = scene["groups"]
    y = f.contact_points_m[:, 1]
    bed = f.contact_group == groups.index("bed")
    base = bed & (np.abs(y - y[bed].min()) < 1e-9)
    beta = f.joint_beta.copy()
    f.joint_beta[base] = 0.0  # the whole base bed joint loses its cohesion
    fm = failure_mode(f, scene, f.joint_u_m)
    assert fm["mode"] == "base sliding"
    levels = np.unique(np.round(y[bed], 6))
    assert [b["y_m"] for b in fm["bed_joints"]] == pytest.approx(levels, abs=1e-9)
    assert [b["cohesion_lost"] for b in fm["bed_joints"]] == [1.0] + [0.0] * (len(levels) - 1)
    u = np.zeros_like(f.joint_u_m)
    u[base, 1], u[base, 2] = 3e-4, 4e-4  # the base slides by 0.5 mm
    assert failure_mode(f, scene, u)["bed_joints"][0]["mean_slip_mm"] == pytest.approx(0.5)
    f.joint_beta[:] = beta
    second = bed & (np.abs(y - np.unique(y[bed])[1]) < 1e-9)  # the bed joint above the base
    f.joint_beta[second] = 0.0
    fm = failure_mode(f, scene, f.joint_u_m)
    assert fm["mode"] == "bed joint sliding"
    assert fm["sliding_bed_joints_y_m"] == [pytest.approx(y[second][0], abs=1e-6)]
    kept = second & (f.contact_points_m[:, 0] < 0.3)  # a third of it keeps its cohesion
    f.joint_beta[kept] = beta[kept]
    assert failure_mode(f, scene, f.joint_u_m)["mode"] == "none"  # 80 % of it or more, not less
    f.joint_beta[:] = beta
    u = np.zeros_like(f.joint_u_m)
    u[base & (f.contact_points_m[:, 0] < 0.3), 0] = 1e-3  # the heel end opens
    assert failure_mode(f, scene, u)["mode"] == "rocking"
    # a base that lost its bond slides only if its slip is a quarter of the top's displacement
    f.joint_beta[base] = 0.0
    u[base, 1] = 1e-3  # 1 mm of slip under a heel open by 1 mm
    assert failure_mode(f, scene, u, top_ux_m=10e-3)["mode"] == "rocking"  # 10 % of the top's
    assert failure_mode(f, scene, u, top_ux_m=3e-3)["mode"] == "base sliding + rocking"
    f.joint_beta[:] = beta
    head = f.contact_group == groups.index("head")
    middle = head & (np.abs(y - 0.16) < 0.06)  # the head joints of course 2, the middle one
    f.joint_beta[middle] = 0.0
    fm = failure_mode(f, scene, f.joint_u_m)
    assert fm["mode"] == "diagonal stair-step" and fm["courses_with_cracked_head_joints"] == [2]
    f.joint_beta[:] = beta
    toe = f.block_of_element == 2  # course 1, unit 3 of 3
    f.d_c[toe] = 0.9
    fm = failure_mode(f, scene, f.joint_u_m)
    assert fm["mode"] == "toe crushing"
    assert fm["crushed_units"] == ["course 1 (bottom), unit 3 of 3 (right end)"]
    f.d_c[toe] = 0.0
    # dry joints (no cohesion as built, integrity 1 throughout): read from their motion
    d0 = f.contact_initial_damage.copy()
    f.contact_initial_damage[:] = 1.0
    u = np.zeros_like(f.joint_u_m)
    u[base, 1] = 2e-4  # the whole base slides by 0.2 mm
    assert failure_mode(f, scene, u)["mode"] == "base sliding"
    u[base, 1] = 0.5e-4  # 0.05 mm: still stuck, as far as a name goes
    assert failure_mode(f, scene, u)["mode"] == "none"
    f.contact_initial_damage[:] = d0
    u[base, 1] = 2e-4  # a cohesive joint that slid is named from its integrity, not its motion
    assert failure_mode(f, scene, u)["mode"] == "none"


def test_a_crushing_length_makes_the_compressive_softening_mesh_objective():
    """ENDO3D in uniaxial compression: as specified (no crushing length) the post-peak stress is
    a function of the strain, whatever the element; with ``crushing_length_m = l_c`` it is a
    function of the post-peak shortening of the element: elements of 0.05, 0.025 and 0.0125 m
    give the same stress at the same shortening past the peak."""
    from masonry_nscd.materials.point_driver import drive_block_path, params_from_case

    def post_peak(l_c, h):
        case = load_case("cases/wall_0.5MPa.yaml",
                         [f"blocks.endo3d.crushing_length_m={l_c}"])
        eps = -np.linspace(0.0, 0.1, 801)
        out = drive_block_path(params_from_case(case), eps, h, "free")
        sig = -np.asarray(out["sigma_axial_Pa"])
        ip = int(np.argmax(sig))
        shortening = (-eps[ip:] + eps[ip]) * h  # m
        return lambda u: np.interp(u, shortening, sig[ip:])

    u = np.array([0.2e-3, 0.5e-3, 1.0e-3])
    ref = post_peak(0.05, 0.05)(u)
    assert np.all(ref < 0.99 * 9.46e6)  # softening
    for h in (0.025, 0.0125):
        assert np.allclose(post_peak(0.05, h)(u), ref, rtol=1e-6)
        # as specified: a given shortening is a larger strain in a smaller element, which has
        # softened further (its band dissipates less: no convergence with the mesh)
        assert np.all(post_peak(0.0, h)(u) < ref * 0.98)
    assert np.allclose(post_peak(0.0, 0.05)(u), ref, rtol=1e-9)  # l_c = h: the same law


def test_a_slip_is_weighed_against_the_largest_displacement_reached():
    """After a cycle the top is back near zero: the slip that makes a joint slide is a quarter
    of the amplitude reached, not of the displacement of the moment."""
    from masonry_nscd.report import _largest_ux_m

    curve = {"step": [1, 2, 3, 4, 5], "ux_mm": [0.0, 5.0, 0.0, -6.0, 0.5]}
    assert _largest_ux_m(curve, 5) == pytest.approx(6e-3)
    assert _largest_ux_m(curve, 2) == pytest.approx(5e-3)
    assert _largest_ux_m({"step": [], "ux_mm": []}, 3) is None
