"""``joint.regions``: wall joints with properties of their own (a weaker base joint, say).

The points a region holds are checked against the geometry (the heights of the bed joints, the
courses' heights), not against the builder's own bookkeeping."""

import numpy as np
import pytest

from masonry_nscd.case import CaseError, case_to_yaml, load_case
from masonry_nscd.contact import laws
from masonry_nscd.scenes import build_scene, check_case

STUDY = "cases/wall_0.5MPa_elastic.yaml"
COURSE_M = 0.11  # unit height 0.1 m + bed joint 0.01 m
BASE = ("joint.regions=[{joints: bed, courses: [1], sigma_I_e_Pa: 2.0e4, G_fI_J_m2: 0.48, "
        "sigma_II_e_Pa: 1.08e5, G_fII_J_m2: 32.96}]")


def _groups(scene):
    return np.array([scene.groups[p.group] for p in scene.points])


def _y(scene):
    return np.array([p.x[1] for p in scene.points])


def test_the_base_region_holds_the_lowest_bed_joint_and_nothing_else():
    case = load_case(STUDY, [BASE])
    scene = build_scene(case)
    g, y = _groups(scene), _y(scene)
    law = np.array([p.law for p in scene.points])
    # the bed joint between courses 1 and 2: its points lie on one of its faces, y 0.10 or 0.11
    base = (g == "bed") & (y < COURSE_M + 1e-6)
    assert base.sum() > 0 and np.all(law[base] == 1) and np.all(law[~base] == 0)
    weak = case.joint.with_values({"sigma_I_e_Pa": 2.0e4, "G_fI_J_m2": 0.48,
                                   "sigma_II_e_Pa": 1.08e5, "G_fII_J_m2": 32.96})
    assert np.array_equal(scene.params[1], laws.params_from_case(weak))
    assert np.array_equal(scene.params[0], laws.params_from_case(case.joint))
    # the base is 1.79 m long (six head joints of the second course) and 0.15 m deep
    assert sum(p.area for p, b in zip(scene.points, base) if b) == pytest.approx(1.79 * 0.15)
    # the values a region sets go out with the points (HDF5, VTU), the case's elsewhere
    s2 = scene.point_fields["joint_sigma_II_e_Pa"]
    assert np.all(s2[base] == 1.08e5) and np.all(s2[~base] == 0.27e6)
    assert set(scene.point_fields) == {f"joint_{f}" for f in
                                       ("sigma_I_e_Pa", "G_fI_J_m2", "sigma_II_e_Pa",
                                        "G_fII_J_m2")}


def test_a_region_on_the_top_course_holds_the_joint_under_the_top_beam():
    """With the wall on joints of the joint law at its beams, the bed joint on the top course
    is the one under the top beam (``bed_top``), which a region can name."""
    case = load_case(STUDY, ["supports.beam_joints=joint_law",
                             "joint.regions=[{joints: bed, courses: [-1], mu: 0.5}]"])
    check_case(case)
    scene = build_scene(case)
    law = np.array([p.law for p in scene.points])
    top = _groups(scene) == "bed_top"
    assert top.sum() > 0 and np.all(law[top] == 1) and np.all(law[~top] == 0)


def test_head_regions_take_their_course_and_the_last_region_wins():
    scene = build_scene(load_case(STUDY, [
        "joint.regions=[{joints: head, mu: 0.5}, {joints: head, courses: [2, -2], mu: 0.6}]"]))
    g, y = _groups(scene), _y(scene)
    mu = scene.point_fields["joint_mu"]
    course = np.floor(y / COURSE_M).astype(int) + 1  # a head joint's points lie inside its course
    head = g == "head"
    assert np.all(mu[head & np.isin(course, [2, 10])] == 0.6)
    assert np.all(mu[head & ~np.isin(course, [2, 10])] == 0.5)
    assert np.all(mu[~head] == 0.7)
    assert len(scene.params) == 3  # the case's row and one per region


def test_scatter_draws_around_the_region_with_the_same_draws():
    scatter = "joint.scatter={cv: 0.3, seed: 4, fields: [sigma_II_e_Pa]}"
    alone = build_scene(load_case(STUDY, [scatter]))
    both = build_scene(load_case(STUDY, [scatter, BASE]))
    g, y = _groups(both), _y(both)
    base = (g == "bed") & (y < COURSE_M + 1e-6)
    a = alone.point_fields["joint_sigma_II_e_Pa"]
    b = both.point_fields["joint_sigma_II_e_Pa"]
    assert np.array_equal(a[~base], b[~base])  # a region does not move the other draws
    assert np.allclose(b[base] / a[base], 1.08e5 / 0.27e6, rtol=1e-12)
    assert np.std(b[base]) > 0.0


def test_a_region_is_written_back_and_reads_back_equal(tmp_path):
    case = load_case(STUDY, [BASE])
    text = case_to_yaml(case)
    assert "G_fII_J_m2: 32.96}" in text and "mu: null" not in text
    path = tmp_path / "case.yaml"
    path.write_text(text)
    assert load_case(path) == case


@pytest.mark.parametrize(("sets", "message"), [
    (["joint.regions=[{joints: bed, courses: [1]}]"], r"joint.regions\[0\]: sets no field"),
    (["joint.regions=[{joints: bed, mu: 2.5}]"], r"joint.regions\[0\].mu: got 2.5; out of range"),
    (["joint.regions=[{joints: head, G_fII_J_m2: 0.01}]"],
     r"joint.regions\[0\].G_fII_J_m2: got 0.01 J/m\^2; it must exceed the elastic energy"),
    (["joint.regions=[{joints: bed, courses: [12], mu: 0.5}]"],
     r"joint.regions\[0\].courses: got 12; there are 11 courses"),
    (["joint.regions=[{joints: bed, courses: [-1], mu: 0.5}]"],
     r"course 11 has no bed joint of the joint law .* allowed courses 1 to 10"),
    (["supports.clamped_courses=1", "joint.regions=[{joints: head, courses: [1], mu: 0.5}]"],
     r"course 1 has no head joint of the joint law .* allowed courses 2 to 10"),
    (["supports.clamped_courses=1", "supports.beam_joints=glue",
      "joint.regions=[{joints: bed, courses: [1], mu: 0.5}]"],
     r"course 1 has no bed joint of the joint law .* allowed courses 2 to 9"),
    (["joint.regions=[{joints: mortar, mu: 0.5}]"], r"joint.regions\[0\].joints: got 'mortar'"),
    (["joint.law=coulomb", "joint.regions=[{joints: bed, mu: 0.5}]"],
     r"joint.regions: given with law coulomb"),
])
def test_a_region_the_wall_cannot_have_is_named(sets, message):
    with pytest.raises(CaseError, match=message):
        check_case(load_case(STUDY, sets))


def test_a_region_an_opening_empties_is_a_clear_error():
    # a window through courses 4 to 7 over the whole length leaves no head joint in course 5
    sets = ["wall.openings=[{x_m: 0.0, y_m: 0.33, width_m: 1.85, height_m: 0.44}]",
            "joint.regions=[{joints: head, courses: [5], mu: 0.5}]"]
    with pytest.raises(ValueError, match=r"joint.regions\[0\]: no head joint"):
        build_scene(load_case(STUDY, sets))


def test_an_arch_refuses_the_wall_regions():
    with pytest.raises(CaseError, match=r"joint.regions: given with an arch case"):
        load_case("cases/arch_semicircular.yaml",
                  ["joint.law=fczm", "joint.regions=[{joints: bed, mu: 0.5}]"])
