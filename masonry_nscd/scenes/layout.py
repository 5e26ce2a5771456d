r"""Course layouts: where every unit of a wall is, before any mesh (lengths in m).

The wall lies in the x-y plane, x along the wall from its left end, y up from its bottom.
Courses are counted from the bottom (0-based here, 1-based in messages). A course is a row of
units of one height, left to right, with a joint of ``joint_thickness_m`` between two units
(head joint) and between two courses (bed joint).

Rows, by ``wall.bond``:

* ``stack``: every course ``units_per_course`` whole units, head joints aligned;
* ``running``: courses 1, 3, ... (1-based) ``units_per_course`` whole units; courses 2, 4, ...
  a half unit at each end and ``units_per_course - 1`` whole units between;
* ``pattern``: the courses of ``wall.pattern`` (unit lengths left to right; a course may give
  its own unit height), repeated up the wall until there are ``courses`` of them. Every course
  must be as long as the first one: ``sum(lengths) + (n - 1) joint``.

Openings (``wall.openings``) are rectangles ``[x, x + width] x [y, y + height]``. Their bottom
and top edges lie in bed joints (or at the bottom or top of the wall), so that a course is
either wholly beside an opening or not at all; in the courses beside it, units inside the
opening are removed and units across a vertical edge are cut at it. A piece shorter than the
joint is refused (it would be a sliver of mortar size). A lintel (``{height_m, bearing_m}``)
is one unit spanning ``[x - bearing, x + width + bearing]`` whose bottom is the bottom of the
course above the opening and whose height is that of whole courses; the units of those courses
within a joint of it are removed or cut, as for an opening.

The mesh of each unit (:func:`unit_divisions`): ``elements_per_unit`` hexahedra, a lintel as
many per metre as a whole unit, and the regions of ``wall.refine`` over that (the last region
that names a unit wins).

The courses' rows and levels are the wall section's own (``case/structures/wall.py``); the
wall builder checks a layout with :func:`unit_boxes` and :func:`unit_divisions` before it
builds it. Problems raise :class:`LayoutError` naming the field (relative to ``wall``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from masonry_nscd.case.structures.wall import row_length

#: Geometric tolerance of the layout (m): lengths that agree to this are equal.
TOL_M = 1e-9


class LayoutError(ValueError):
    """A layout that cannot be built: ``field`` (relative to the ``wall`` section) and why."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field, self.message = field, message


@dataclass(frozen=True)
class UnitBox:
    """One unit: its course (0-based), position in the course (0-based, after cuts), lower left
    corner and size in the wall's plane (m), and what it is (``unit`` or ``lintel``)."""

    course: int
    index: int
    x0: float
    y0: float
    length: float
    height: float
    kind: str = "unit"
    opening: int = -1  # the opening a lintel spans


def check_pattern(wall) -> None:
    """Every course of a pattern as long as the first (LayoutError naming the course)."""
    j = wall.joint_thickness_m
    lengths = []
    for entry in wall.pattern:
        units = list(entry.units) if hasattr(entry, "units") else list(entry)
        lengths.append(row_length(units, j))
    for i, length in enumerate(lengths[1:], start=1):
        diff = length - lengths[0]
        if abs(diff) > 1e-6:
            raise LayoutError(
                f"pattern[{i}]", f"the course is {length:.6g} m long, {abs(diff):.6g} m "
                f"{'longer' if diff > 0 else 'shorter'} than course pattern[0] ({lengths[0]:.6g} "
                f"m; with joints of {j:g} m): every course must be as long as the first")


def _course_span(levels, y0: float, y1: float, where: str, wall_height: float) -> range:
    """The courses between two heights that lie in bed joints (or at the wall's ends)."""
    def edge(y: float, which: str) -> int:
        """Index of the first course above the joint at height y."""
        if y <= TOL_M:
            return 0
        if y >= wall_height - TOL_M:
            return len(levels)
        for k in range(1, len(levels)):
            if levels[k - 1][1] - TOL_M <= y <= levels[k][0] + TOL_M:
                return k
        k = next(k for k, (b, t) in enumerate(levels) if b < y < t)
        joints = (levels[k - 1][1] if k else 0.0, levels[k][1])
        raise LayoutError(where + ("y_m" if which == "bottom" else "height_m"),
                          f"the {which} edge at y = {y:.6g} m cuts course {k + 1} (from "
                          f"{levels[k][0]:.6g} to {levels[k][1]:.6g} m); an opening's edges "
                          f"must lie in bed joints: for example at {joints[0]:.6g} or "
                          f"{joints[1]:.6g} m")
    return range(edge(y0, "bottom"), edge(y1, "top"))


def unit_boxes(wall) -> list[UnitBox]:
    """Every unit of the wall, bottom course first, left to right (module docstring)."""
    if wall.bond == "pattern":
        check_pattern(wall)
    j = wall.joint_thickness_m
    rows = wall.course_rows()
    levels = wall.course_levels()
    length, height = wall.wall_length_m, wall.wall_height_m
    cuts: list[list[tuple[float, float, str]]] = [[] for _ in rows]  # per course
    lintels: list[UnitBox] = []
    boxes_xy: list[tuple[float, float, float, float, str]] = []  # for the overlap check
    for i, op in enumerate(wall.openings):
        where = f"openings[{i}]."
        x0, x1, y0, y1 = op.x_m, op.x_m + op.width_m, op.y_m, op.y_m + op.height_m
        if x1 > length + TOL_M or y1 > height + TOL_M:
            raise LayoutError(f"openings[{i}]", f"the opening [{x0:.6g}, {x1:.6g}] x [{y0:.6g}, "
                              f"{y1:.6g}] m is not inside the wall ({length:.6g} x {height:.6g} m, "
                              "measured from its lower left corner)")
        span = _course_span(levels, y0, y1, where, height)
        boxes_xy.append((x0, x1, y0, y1, f"openings[{i}]"))
        for k in span:
            cuts[k].append((x0, x1, f"openings[{i}]"))
        if op.lintel is None:
            continue
        lt = op.lintel
        first = span.stop
        if first >= len(levels):
            raise LayoutError(where + "lintel", "the opening reaches the top of the wall: no "
                              "course above it to carry a lintel")
        tops = [levels[k][1] - levels[first][0] for k in range(first, len(levels))]
        n = next((m for m, top in enumerate(tops, start=1) if abs(top - lt.height_m) <= 1e-6),
                 None)
        if n is None:
            allowed = ", ".join(f"{t:.6g}" for t in tops[:4])
            raise LayoutError(where + "lintel.height_m",
                              f"got {lt.height_m:.6g} m; a lintel is as tall as whole courses "
                              f"above the opening: {allowed} m ...")
        lx0, lx1 = x0 - lt.bearing_m, x1 + lt.bearing_m
        if lx0 < -TOL_M or lx1 > length + TOL_M:
            raise LayoutError(where + "lintel.bearing_m",
                              f"got {lt.bearing_m:.6g} m; the lintel [{lx0:.6g}, {lx1:.6g}] m "
                              f"runs past the wall's ends (0 and {length:.6g} m)")
        ly0 = levels[first][0]
        boxes_xy.append((lx0, lx1, ly0, ly0 + lt.height_m, f"openings[{i}].lintel"))
        for k in range(first, first + n):
            cuts[k].append((lx0 - j, lx1 + j, f"openings[{i}].lintel"))
        lintels.append(UnitBox(first, -1, lx0, ly0, lx1 - lx0, lt.height_m, "lintel", i))
    for a in range(len(boxes_xy)):
        for b in range(a + 1, len(boxes_xy)):
            p, q = boxes_xy[a], boxes_xy[b]
            if p[0] < q[1] - TOL_M and q[0] < p[1] - TOL_M and p[2] < q[3] - TOL_M \
                    and q[2] < p[3] - TOL_M:
                raise LayoutError(q[4].split(".")[0], f"{q[4]} overlaps {p[4]}")
    out: list[UnitBox] = []
    for k, (h, units) in enumerate(rows):
        pieces: list[tuple[float, float]] = []
        x = 0.0
        for u, unit_len in enumerate(units):
            cut = _cut(x, x + unit_len, cuts[k], j, k, u)
            pieces += [(x, unit_len)] if cut == [(x, x + unit_len)] else \
                [(a, b - a) for a, b in cut]
            x += unit_len + j
        row = [(x0, ln, "unit", -1, h) for x0, ln in pieces]
        row += [(lt.x0, lt.length, "lintel", lt.opening, lt.height) for lt in lintels
                if lt.course == k]
        for n, (x0, ln, kind, op, hh) in enumerate(sorted(row)):
            out.append(UnitBox(k, n, x0, levels[k][0], ln, hh, kind, op))
    return out


def _cut(a: float, b: float, cuts: list[tuple[float, float, str]], joint: float, course: int,
         unit: int) -> list[tuple[float, float]]:
    """The pieces of the unit ``[a, b]`` outside the intervals ``cuts`` (m)."""
    pieces = [(a, b)]
    for c0, c1, what in cuts:
        nxt = []
        for p0, p1 in pieces:
            for q0, q1 in ((p0, min(p1, c0)), (max(p0, c1), p1)):
                size = q1 - q0
                if size <= TOL_M:
                    continue
                if q1 - q0 < joint - TOL_M:
                    raise LayoutError(what.split(".")[0], (
                        f"{what} cuts unit {unit + 1} of course {course + 1} (from {a:.6g} to "
                        f"{b:.6g} m) into a piece of {size:.6g} m, shorter than the joint "
                        f"({joint:g} m): move the edge onto a head joint or away from it"))
                nxt.append((q0, q1))
        pieces = nxt
    return pieces


def count_index(k: int, count: int, what: str, field: str) -> int:
    """0-based index of a 1-based (negative: from the end) ``k`` among ``count`` items."""
    if not (1 <= k <= count or -count <= k <= -1):
        raise LayoutError(field, f"got {k}; there are {count} {what}: allowed 1 to {count} "
                          f"(or -1 to -{count} from the other end)")
    return k - 1 if k > 0 else count + k


def unit_divisions(wall, boxes: list[UnitBox]) -> list[tuple[int, int, int]]:
    """Hexahedra per unit (along its length, height, thickness) of every box of ``boxes``
    (module docstring); LayoutError for a region naming a course or unit that is not there."""
    nx, ny, nz = wall.elements_per_unit
    out = []
    for b in boxes:
        if b.kind == "lintel":
            out.append((max(nx, math.ceil(nx * b.length / wall.unit_length_m - 1e-9)),
                        max(ny, math.ceil(ny * b.height / wall.unit_height_m - 1e-9)), nz))
        else:
            out.append((nx, ny, nz))
    count = {}
    for b in boxes:
        count[b.course] = count.get(b.course, 0) + 1
    for r, region in enumerate(getattr(wall, "refine", None) or []):
        courses = {count_index(k, wall.courses, "courses", f"refine[{r}].courses")
                   for k in region.courses}
        for c in sorted(courses):
            n = count.get(c, 0)
            units = None if region.units is None else {
                count_index(u, n, f"units in course {c + 1}", f"refine[{r}].units")
                for u in region.units}
            for i, b in enumerate(boxes):
                if b.course == c and (units is None or b.index in units):
                    out[i] = tuple(region.elements_per_unit)
    return out
