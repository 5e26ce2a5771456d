"""A dome of voussoirs in courses, on a fixed ring: hemispherical or pointed, with an oculus."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Section, Whole
from masonry_nscd.case.structures import Structure
from masonry_nscd.case.structures.arch import (
    LIMIT_STATE_OWNS,
    named_block_problems,
    settlement_problems,
)


class Dome(Section):
    """A dome of revolution about the vertical y axis (``masonry_nscd/scenes/dome.py``; lengths
    in m, angles in degrees), instead of a wall.

    Its meridian is the arc of the centreline, ``radius_m`` from a centre on the springing
    plane: for ``hemispherical`` the centre is on the axis (span = 2 radius); for ``pointed``
    it lies ``radius - span / 2`` beyond the axis, so that the arcs of opposite meridians meet
    at the apex, above ``span_m``. The ring is ``thickness_m`` thick about the centreline.
    From the springing to ``oculus_deg`` below the apex (in the angle of the meridian's arc),
    it is cut into ``courses`` courses of equal angle, each into ``voussoirs`` voussoirs of
    equal azimuth; with ``stagger`` the meridional joints of every second course fall in the
    middle of the voussoirs of its neighbours. Every voussoir is made of two halves of equal
    azimuth (one hexahedron each), so that a staggered voussoir rests on the halves of the two
    below it, face to face. The lowest course rests on a fixed ring; ``lantern_N`` is a
    vertical force on the top course, shared among its voussoirs, ramped with gravity.
    """

    shape: Literal["hemispherical", "pointed"] = Field(
        "hemispherical", description="hemispherical, or pointed (arcs meeting at the apex)")
    radius_m: Real = Field(5.0, gt=0.0, le=1000.0, description="radius of the centreline (m)")
    span_m: Real | None = Field(
        None, gt=0.0, le=2000.0,
        description="diameter of the centreline at the springing (m; null: 2 radius, "
        "hemispherical)")
    thickness_m: Real = Field(0.5, gt=0.0, le=100.0, description="thickness of the shell (m)")
    courses: Whole = Field(8, ge=1, le=200, description="courses from springing to oculus (count)")
    voussoirs: Whole = Field(16, ge=3, le=1000, description="voussoirs per course (count)")
    stagger: bool = Field(
        True, description="meridional joints of every second course offset by half a voussoir")
    oculus_deg: Real = Field(
        10.0, gt=0.0, lt=90.0,
        description="angle of the meridian's arc left open at the apex (degrees)")
    lantern_N: Real = Field(
        0.0, ge=0.0, le=1e12, description="vertical force on the top course (N; 0: none)")
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)")
    contact_point_rule: Literal["auto", "gauss", "lobatto", "overlap"] = Field(
        "auto", description="gauss, lobatto, overlap, or auto: lobatto (the faces' corners)")

    @property
    def centreline_span_m(self) -> float:
        """Diameter of the centreline at the springing (m)."""
        return float(self.span_m if self.span_m is not None else 2.0 * self.radius_m)

    @property
    def offset_m(self) -> float:
        """How far beyond the axis the meridian's centre lies (m; 0: hemispherical)."""
        return self.radius_m - self.centreline_span_m / 2.0

    @property
    def apex_deg(self) -> float:
        """The angle of the meridian's arc from the springing to the apex (degrees)."""
        return math.degrees(math.acos(self.offset_m / self.radius_m))

    @model_validator(mode="after")
    def _check_geometry(self) -> Dome:
        problems: list[tuple[str, str]] = []
        r, t = self.radius_m, self.thickness_m
        if self.shape == "hemispherical" and self.span_m is not None and \
                abs(self.span_m - 2.0 * r) > 1e-9 * self.span_m:
            problems.append(("span_m", (
                f"got {self.span_m:.6g} m with radius_m = {r:.6g} m; a hemispherical dome has "
                "span = 2 radius: leave span_m out")))
        elif self.shape == "pointed" and not (self.span_m is not None and r > self.span_m / 2):
            problems.append(("span_m", (
                "a pointed dome needs span_m below 2 radius_m (equal: hemispherical)")))
        elif not t < 2.0 * (r - self.offset_m):
            problems.append(("thickness_m", (
                f"got {t:.6g} m; the shell's inner face must stay clear of the axis: below "
                f"{2.0 * (r - self.offset_m):.6g} m")))
        if not problems and not self.oculus_deg < self.apex_deg:
            problems.append(("oculus_deg", (
                f"got {self.oculus_deg:g}; the meridian rises {self.apex_deg:.4g} degrees "
                "from the springing to the apex")))
        raise_problems(problems)
        return self

    def course_name(self, course: int) -> str:
        """``course 3`` (from 1 at the springing)."""
        return f"course {course}"

    def voussoir_names(self) -> list[str]:
        """The names of every voussoir, course by course from the springing."""
        return [f"course {i} voussoir {k}" for i in range(1, self.courses + 1)
                for k in range(1, self.voussoirs + 1)]


def _point_load_problems(case) -> list[tuple[str, str]]:
    """A point load on a block the dome does not have; a settlement (its ring is fixed)."""
    d = case.dome
    fixed = settlement_problems(case, ())
    return fixed + named_block_problems(case.loading, d.voussoir_names(), (
        f"the blocks are course 1 voussoir 1 to course {d.courses} voussoir {d.voussoirs} "
        "(from the springing; voussoir 1 at azimuth 0)"))


STRUCTURE = Structure(
    name="dome", model=Dome, article="a dome", order=40, limit_state=True,
    description="a dome of voussoirs instead of the wall (null: the wall)",
    owns=("dome", *LIMIT_STATE_OWNS), checks=_point_load_problems)
