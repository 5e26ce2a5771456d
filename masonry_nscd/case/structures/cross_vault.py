"""A cross vault over a rectangular bay: a groin vault of stones in courses, on four supports."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Section, Whole
from masonry_nscd.case.structures import Structure
from masonry_nscd.case.structures.arch import LIMIT_STATE_OWNS, settlement_problems

#: The corners of the bay (north: +z, east: +x) and the sides, each the two corners on it
CORNERS = ("north-east", "north-west", "south-east", "south-west")
SIDES = {"north": ("north-east", "north-west"), "south": ("south-east", "south-west"),
         "east": ("north-east", "south-east"), "west": ("north-west", "south-west")}
#: The webs: east and west are the barrel across z (their stones run along x), north and south
#: the barrel across x
WEBS = ("east", "west", "north", "south")


class CrossVault(Section):
    """A cross vault (``masonry_nscd/scenes/cross_vault.py``; lengths in m), instead of a wall:
    two barrel vaults of the same rise that cross over a bay of ``span_x_m`` by ``span_z_m``
    between the centrelines of its supports, y up.

    The barrel across z (its arch spans ``span_z_m``; ``semicircular``, or ``pointed`` of
    ``radius_m``) gives the east and west webs, the barrel across x (the same arch scaled by
    ``span_x_m / span_z_m`` in plan) the north and south webs; they meet on the groins, the
    vertical planes of the bay's diagonals. Each web rises in ``courses`` courses from each
    springing to the crown, the courses along its barrel's axis, cut into stones about
    ``stone_length_m`` long from the groin to the web's end (staggered in every second course
    with ``stagger``). The lowest ``springer_courses`` courses of the two webs at a corner are
    one solid springer (tas-de-charge) down to the springing plane, on a fixed support. With
    ``transverse_ribs`` an arch of ``rib_width_m`` by ``rib_depth_m`` (its extrados the webs')
    closes each end of the east and west webs, on the same supports. With ``diagonal_ribs``
    the two groin stones of a course are one voussoir of a diagonal rib, deepened by
    ``diagonal_rib_depth_m`` below the webs' intrados and bonded into both webs; the top
    course's groin stones are the boss where the ribs cross. With ``piers`` each corner's
    springer (and rib feet) stands on a square pier of ``pier_drums`` drums, ``pier_height_m``
    high (square, ``pier_width_m`` wide and centred on the corner of the bay, or the plan of
    the springer's feet), whose lowest drum stands on the fixed support.
    """

    span_x_m: Real = Field(4.0, gt=0.0, le=200.0,
                           description="span of the bay along x, between support centrelines (m)")
    span_z_m: Real = Field(4.0, gt=0.0, le=200.0,
                           description="span of the bay along z, between support centrelines (m)")
    shape: Literal["semicircular", "pointed"] = Field(
        "semicircular", description="semicircular, or pointed (two arcs of radius_m)")
    radius_m: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="radius of the pointed arcs across z (m; null: span_z / 2, semicircular)")
    thickness_m: Real = Field(0.25, gt=0.0, le=50.0, description="thickness of the webs (m)")
    courses: Whole = Field(8, ge=2, le=200,
                           description="courses of a web from its springing to the crown "
                           "(count)")
    springer_courses: Whole = Field(
        2, ge=1, le=199, description="lowest courses made one solid springer at each corner "
        "(count)")
    stone_length_m: Real = Field(0.5, gt=0.0, le=100.0,
                                 description="length of a web's stones along its course (m)")
    stagger: bool = Field(True, description="joints of every second course offset by half a "
                          "stone")
    transverse_ribs: bool = Field(False, description="an arch under each end of the east and "
                                  "west webs")
    rib_width_m: Real = Field(0.3, gt=0.0, le=50.0, description="width of a rib along x (m)")
    rib_depth_m: Real = Field(0.45, gt=0.0, le=50.0,
                              description="depth of a rib from its extrados (m)")
    diagonal_ribs: bool = Field(False, description="the groin stones of each course one "
                                "voussoir of a diagonal rib, deepened below the intrados")
    diagonal_rib_depth_m: Real = Field(
        0.15, gt=0.0, le=50.0,
        description="depth of a diagonal rib below the webs' intrados (m)")
    support_height_m: Real = Field(0.5, gt=0.0, le=100.0,
                                   description="height of the fixed supports below the "
                                   "springing plane, or below the piers (drawn only, m)")
    piers: bool = Field(False, description="stand each corner on a pier of drums (blocks of "
                        "the structure) on its fixed support, instead of on the support")
    pier_height_m: Real = Field(3.0, gt=0.0, le=100.0,
                                description="height of the piers below the springing plane "
                                "(m; with piers)")
    pier_drums: Whole = Field(6, ge=1, le=500, description="drums of a pier (count; with piers)")
    pier_width_m: Real | None = Field(
        None, gt=0.0, le=100.0,
        description="side of a square pier centred on its corner of the bay (m; with piers; "
        "null: the plan of the springer's feet)")
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)")
    contact_point_rule: Literal["auto", "gauss", "lobatto", "overlap"] = Field(
        "overlap", description="overlap (on the common area of faces that meet in part: a "
        "staggered course on the one below), gauss, lobatto, or auto: lobatto")

    @property
    def arch_radius_m(self) -> float:
        """Radius of the centreline of the arch across z (m)."""
        return float(self.radius_m if self.radius_m is not None else self.span_z_m / 2.0)

    @property
    def offset_m(self) -> float:
        """How far beyond the bay's axis the arc's centre lies (m; 0: semicircular)."""
        return self.arch_radius_m - self.span_z_m / 2.0

    @property
    def rise_m(self) -> float:
        """Height of the centreline's crown above the springing plane (m)."""
        r, c = self.arch_radius_m, self.offset_m
        return math.sqrt(r * r - c * c)

    @model_validator(mode="after")
    def _check_geometry(self) -> CrossVault:
        problems: list[tuple[str, str]] = []
        half, t = self.span_z_m / 2.0, self.thickness_m
        if self.shape == "semicircular" and self.radius_m is not None and \
                abs(self.radius_m - half) > 1e-9 * half:
            problems.append(("radius_m", (
                f"got {self.radius_m:.6g} m with span_z_m = {self.span_z_m:.6g} m; a "
                "semicircular arch has radius = span / 2: leave radius_m out")))
        elif self.shape == "pointed" and not (self.radius_m is not None and
                                              self.radius_m > half):
            problems.append(("radius_m", (
                f"a pointed vault needs radius_m above span_z_m / 2 = {half:.6g} m")))
        elif not t < half:
            problems.append(("thickness_m", f"got {t:.6g} m; it must be below span_z_m / 2"))
        if not self.springer_courses < self.courses:
            problems.append(("springer_courses", (
                f"got {self.springer_courses}; it must be below courses = {self.courses}")))
        if self.transverse_ribs and not self.rib_depth_m >= t:
            problems.append(("rib_depth_m", (
                f"got {self.rib_depth_m:.6g} m; a rib is at least as deep as the webs "
                f"({t:.6g} m)")))
        raise_problems(problems)
        return self


def _cross_vault_problems(case) -> list[tuple[str, str]]:
    """A settlement of a support the bay does not have."""
    return settlement_problems(case, (*CORNERS, *SIDES))


STRUCTURE = Structure(
    name="cross_vault", model=CrossVault, article="a cross vault", order=50,
    limit_state=True, description="a cross vault over a rectangular bay instead of the wall "
    "(null: the wall)", owns=("cross_vault", *LIMIT_STATE_OWNS), checks=_cross_vault_problems)
