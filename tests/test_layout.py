"""Course layouts (scenes/layout.py): pattern bonds, openings, lintels, and the errors of bad
layouts (exit code 2 naming the field)."""

import itertools

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.case.structures.wall import vertical_force_N
from masonry_nscd.cli import app
from masonry_nscd.scenes import check_case
from masonry_nscd.scenes.layout import unit_boxes

BRICK = "cases/brick_wall_pattern.yaml"
WINDOW = "cases/wall_window.yaml"


def _rows(boxes):
    courses = sorted({b.course for b in boxes})
    return [sorted((b for b in boxes if b.course == c), key=lambda b: b.x0) for c in courses]


def test_the_brick_pattern_alternates_its_two_courses():
    wall = load_case(BRICK).wall
    boxes = unit_boxes(wall)
    rows = _rows(boxes)
    assert len(rows) == 18
    for k, row in enumerate(rows):
        lengths = [b.length for b in row]
        assert lengths == ([0.21] * 4 + [0.11] if k % 2 == 0 else [0.11] + [0.21] * 4)
        for a, b in itertools.pairwise(row):  # 10 mm head joints
            assert b.x0 - (a.x0 + a.length) == pytest.approx(0.010, abs=1e-12)
        assert row[-1].x0 + row[-1].length == pytest.approx(0.99, abs=1e-12)
        assert row[0].y0 == pytest.approx(k * 0.062, abs=1e-12)
    assert (wall.wall_length_m, wall.wall_height_m) == pytest.approx((0.99, 18 * 0.052 + 17 * 0.010), abs=1e-12)
    assert vertical_force_N(load_case(BRICK)) == pytest.approx(0.30e6 * 0.99 * 0.10)


def test_a_pattern_course_may_have_its_own_height():
    case = load_case(BRICK, ["wall.courses=3", ("wall.pattern=[[0.21, 0.21], "
                             "{units: [0.1, 0.1, 0.21], height_m: 0.2}]")])
    levels = case.wall.course_levels()
    assert np.allclose(levels, [(0.0, 0.052), (0.062, 0.262), (0.272, 0.324)], atol=1e-12)
    rows = _rows(unit_boxes(case.wall))
    assert [len(r) for r in rows] == [2, 3, 2]
    assert {b.height for b in rows[1]} == {0.2}


def test_the_window_removes_and_cuts_units_and_adds_a_lintel():
    wall = load_case(WINDOW).wall
    boxes = unit_boxes(wall)
    study = unit_boxes(load_case("cases/wall_0.5MPa.yaml").wall)
    rows, before = _rows(boxes), _rows(study)
    for k in range(11):
        inside = [b for b in rows[k] if b.x0 < 1.23 - 1e-9 and b.x0 + b.length > 0.62 + 1e-9]
        if 3 <= k <= 6:  # courses 4 to 7: nothing between x = 0.62 and 1.23 m
            assert inside == []
        if k in (3, 5):  # even courses (1-based): the units across the edges are cut
            pieces = [b.length for b in rows[k] if b.length < 0.3 - 1e-9 and 0.3 < b.x0 < 1.5]
            assert pieces == pytest.approx([0.155, 0.155])
        if k in (0, 1, 2, 8, 9, 10):  # away from the window and the lintel: as the study's
            assert np.allclose([(b.x0, b.length) for b in rows[k]],
                               [(b.x0, b.length) for b in before[k]], atol=1e-12)
    lintel = [b for b in boxes if b.kind == "lintel"]
    assert len(lintel) == 1
    lt = lintel[0]
    assert (lt.x0, lt.length, lt.y0, lt.height) == pytest.approx((0.465, 0.92, 0.77, 0.10))
    # course 8 keeps its units beyond a joint of the lintel's ends
    ends = sorted(b.x0 + b.length for b in rows[7] if b.kind == "unit" and b.x0 < lt.x0)
    starts = sorted(b.x0 for b in rows[7] if b.kind == "unit" and b.x0 > lt.x0)
    assert lt.x0 - ends[-1] == pytest.approx(0.010)
    assert starts[0] - (lt.x0 + lt.length) == pytest.approx(0.010)
    # removed: 2 units in each of courses 5 and 7, 1 in each of courses 4 and 6 (their 2 others
    # cut), 3 in course 8 for the lintel
    assert len(boxes) == 71 - 2 * 2 - 2 * 1 - 3 + 1


BAD_LAYOUTS = {
    "courses of different lengths": (BRICK, ["wall.pattern=[[0.21, 0.21, 0.11], [0.21, 0.11]]"],
                                     ["wall.pattern[1]", "0.22 m", "shorter"]),
    "pattern without bond pattern": ("cases/smoke.yaml", ["wall.pattern=[[0.3]]"],
                                     ["wall.pattern", "bond 'running'"]),
    "bond pattern without pattern": ("cases/smoke.yaml", ["wall.bond=pattern"],
                                     ["wall.pattern", "missing"]),
    "an opening outside the wall": (WINDOW, [("wall.openings=[{x_m: 1.5, y_m: 0.32, width_m: 0.5, "
                                             "height_m: 0.44}]")],
                                    ["wall.openings[0]", "not inside the wall", "1.85"]),
    "overlapping openings": (WINDOW, [("wall.openings=[{x_m: 0.31, y_m: 0.32, width_m: 0.61, "
                                      "height_m: 0.22}, {x_m: 0.62, y_m: 0.21, width_m: 0.61, "
                                      "height_m: 0.22}]")],
                             ["wall.openings[1]", "overlaps openings[0]"]),
    "a unit cut shorter than a joint": (WINDOW, [("wall.openings=[{x_m: 0.625, y_m: 0.32, "
                                                 "width_m: 0.6, height_m: 0.44}]")],
                                        ["wall.openings[0]", "unit 3 of course 5", "0.005 m",
                                         "shorter than the joint"]),
    "an edge through a course": (WINDOW, [("wall.openings=[{x_m: 0.62, y_m: 0.35, width_m: 0.61, "
                                          "height_m: 0.41}]")],
                                 ["wall.openings[0].y_m", "cuts course 4", "bed joints"]),
    "a lintel that is not whole courses": (WINDOW, ["wall.openings[0].lintel.height_m=0.15"],
                                           ["wall.openings[0].lintel.height_m", "0.1, 0.21"]),
    "a lintel past the wall's end": (WINDOW, ["wall.openings[0].lintel.bearing_m=0.7"],
                                     ["wall.openings[0].lintel.bearing_m", "wall's ends"]),
    "a clamped course with an opening": (WINDOW, ["supports.clamped_courses=4"],
                                         ["wall.openings[0]", "clamped course"]),
}


@pytest.mark.parametrize("name", list(BAD_LAYOUTS))
def test_a_bad_layout_exits_2_naming_the_field(name):
    path, sets, words = BAD_LAYOUTS[name]
    with pytest.raises(CaseError) as info:  # the wall builder's check of its layout
        check_case(load_case(path, sets))
    text = str(info.value)
    for w in words:
        assert w in text, (name, text)
    args = [a for s in sets for a in ("--set", s)]
    res = CliRunner().invoke(app, ["validate", path, *args])
    assert res.exit_code == 2 and words[0] in res.output and "Traceback" not in res.output
