"""The wall: its units, joints, bond, openings and mesh, and the test rig that holds it."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import ElementCount, Real, Section, Whole
from masonry_nscd.case.structures import Structure


def row_length(units: list[float], joint: float) -> float:
    """Length of a course of ``units`` (m): the units and the head joints between them."""
    return sum(units) + (len(units) - 1) * joint


#: Tolerance of the running-bond length identity (m).
BOND_TOLERANCE_M = 1e-9


class PatternCourse(Section):
    """One course of a pattern bond with its own unit height (lengths in m)."""

    units: list[Annotated[Real, Field(ge=0.005, le=10.0)]] = Field(
        min_length=1, max_length=500, description="unit lengths, left to right (m)"
    )
    height_m: Real | None = Field(
        None, ge=0.01, le=10.0, description="unit height of this course (m; null: unit_height_m)"
    )


class Lintel(Section):
    """A lintel over an opening: one linear elastic unit (the blocks' E, nu and density; rigid
    in a wall of rigid blocks) spanning the opening and bearing on the units beside it."""

    height_m: Real = Field(
        gt=0.0, le=10.0, description="height of the lintel (m): that of whole courses above "
        "the opening"
    )
    bearing_m: Real = Field(
        gt=0.0, le=10.0, description="length the lintel rests on beyond each side (m)"
    )


class Opening(Section):
    """A rectangular opening (window, door), measured from the wall's lower left corner (m).
    Its bottom and top edges lie in bed joints, or at the bottom or top of the wall."""

    x_m: Real = Field(ge=0.0, le=1000.0, description="left edge (m)")
    y_m: Real = Field(ge=0.0, le=1000.0, description="bottom edge (m)")
    width_m: Real = Field(gt=0.0, le=1000.0, description="width (m)")
    height_m: Real = Field(gt=0.0, le=1000.0, description="height (m)")
    lintel: Lintel | None = Field(None, description="a lintel over the opening (null: none)")


class RefineRegion(Section):
    """Units meshed with other ``elements_per_unit``: the units ``units`` (positions in their
    course from the left end) of the courses ``courses`` (from the bottom), both counted from 1,
    negative from the other end (-1: the top course, the right end unit); ``units`` null: every
    unit of those courses. Example, the two end units of the first and last courses:
    ``{courses: [1, -1], units: [1, -1], elements_per_unit: [6, 6, 2]}``."""

    courses: list[Annotated[Whole, Field(ge=-200, le=200)]] = Field(
        min_length=1, max_length=200, description="courses (index: from 1 at the bottom, -1: the top)"
    )
    units: list[Annotated[Whole, Field(ge=-500, le=500)]] | None = Field(
        None, max_length=500,
        description="positions in the course (index: from 1 at the left end, -1: the right "
        "end); null: all",
    )
    elements_per_unit: tuple[ElementCount, ElementCount, ElementCount] = Field(
        description="hexahedra per unit along length, height, thickness (counts, 1..16 each)"
    )


class Wall(Section):
    """Geometry of the wall: units, joints, bond, openings and mesh (lengths in m).

    The wall lies in the x-y plane (x along the wall, y up, z through the thickness). Courses are
    counted from the bottom, the first (bottom) course is odd. Between two units, along a course
    (head joint) and between courses (bed joint), there is a joint of ``joint_thickness_m``; the
    mortar and the unit-mortar interface are one contact interface with an initial gap equal to
    the joint thickness.

    Bond (the layouts are built in ``masonry_nscd/scenes/layout.py``):

    - ``stack``: every course has ``units_per_course`` whole units, head joints aligned.
    - ``running``: odd courses (1st, 3rd, ...) have ``units_per_course`` whole units; even courses
      (2nd, 4th, ...) have ``units_per_course - 1`` whole units and one half unit at each end.
      Both courses must have the same length::

          2 half + (n - 1) length + n joint = n length + (n - 1) joint
          =>  half = (length - joint) / 2        (0.145 m for 0.300 m units and 10 mm joints)

    - ``pattern``: the courses of ``pattern``, each a list of unit lengths left to right or a
      mapping ``{units: [...], height_m: ...}`` for another unit height, repeated up the wall
      to ``courses`` courses; every course as long as the first.

    ``openings``: rectangles ``{x_m, y_m, width_m, height_m}`` from the lower left corner, each
    with an optional ``lintel: {height_m, bearing_m}``; units inside are removed, units across
    an edge cut at it.

    Overall size (running, stack): ``wall_length_m = n length + (n - 1) joint`` (1.85 m by
    default), ``wall_height_m = courses height + (courses - 1) joint`` (1.20 m by default).
    """

    unit_length_m: Real = Field(
        0.300, ge=0.01, le=10.0, description="length of one whole unit along the wall (m)"
    )
    unit_height_m: Real = Field(0.100, ge=0.01, le=10.0, description="height of one unit (m)")
    thickness_m: Real = Field(
        0.150, ge=0.01, le=10.0, description="thickness of the wall and of the units (m)"
    )
    joint_thickness_m: Real = Field(
        0.010,
        ge=0.0,
        le=0.5,
        description="thickness of the bed and head joints = initial contact gap (m)",
    )
    courses: Whole = Field(11, ge=1, le=200, description="number of courses (count)")
    units_per_course: Whole = Field(
        6, ge=1, le=500, description="number of whole units in a full (odd) course (count; "
        "running and stack bonds)"
    )
    bond: Literal["running", "stack", "pattern"] = Field(
        "running", description="running: even courses offset by half a unit; stack: aligned; "
        "pattern: the courses of wall.pattern"
    )
    half_unit_length_m: Real = Field(
        0.145,
        ge=0.005,
        le=10.0,
        description="length of the half units at both ends of even courses, running bond (m)",
    )
    pattern: list[list[Annotated[Real, Field(ge=0.005, le=10.0)]] | PatternCourse] | None = Field(
        None, min_length=1, max_length=200,
        description="bond pattern: courses of unit lengths (m), left to right, repeated up the "
        "wall; a course may be {units: [...], height_m: ...} (null unless bond is pattern)",
    )
    openings: list[Opening] = Field(
        default_factory=list, max_length=100,
        description="rectangular openings {x_m, y_m, width_m, height_m, lintel}, from the lower "
        "left corner (m)",
    )
    elements_per_unit: tuple[ElementCount, ElementCount, ElementCount] = Field(
        (2, 2, 1),
        description="hexahedra per unit along length, height, thickness (counts, 1..16 each)",
    )
    refine: list[RefineRegion] = Field(
        default_factory=list, max_length=100,
        description="units meshed otherwise: {courses, units, elements_per_unit} (the last "
        "region that names a unit wins)",
    )
    contact_points_per_face: Whole = Field(
        2,
        ge=1,
        le=4,
        description="contact points per direction on each element face in contact (count; "
        "2 to 4 with contact_point_rule lobatto)",
    )
    contact_point_rule: Literal["auto", "gauss", "lobatto"] = Field(
        "auto",
        description="where the contact points sit on a face: gauss (Gauss-Legendre points "
        "inside each element face, the study's), lobatto (Gauss-Lobatto points, the corners "
        "among them: rigid blocks rock about the edges of their faces; shared points made "
        "once), or auto: lobatto for rigid contacts (joint law coulomb) with 2 or more points, "
        "gauss otherwise",
    )

    def course_rows(self) -> list[tuple[float, list[float]]]:
        """``(unit height, [unit lengths])`` of every course, bottom first (m), by ``bond``."""
        L, half, n = self.unit_length_m, self.half_unit_length_m, self.units_per_course
        rows = []
        for k in range(self.courses):
            if self.bond == "pattern":
                entry = self.pattern[k % len(self.pattern)]
                units = list(entry.units) if hasattr(entry, "units") else list(entry)
                rows.append((getattr(entry, "height_m", None) or self.unit_height_m, units))
            elif self.bond == "running" and k % 2 == 1:
                rows.append((self.unit_height_m, [half] + [L] * (n - 1) + [half]))
            else:
                rows.append((self.unit_height_m, [L] * n))
        return rows

    def course_levels(self) -> list[tuple[float, float]]:
        """``(bottom, top)`` of every course (m)."""
        out, y = [], 0.0
        for height, _ in self.course_rows():
            out.append((y, y + height))
            y += height + self.joint_thickness_m
        return out

    @property
    def wall_length_m(self) -> float:
        """Length of the wall along x (m): its first course's units and head joints,
        ``n * unit_length + (n - 1) * joint`` in running and stack bond."""
        return row_length(self.course_rows()[0][1], self.joint_thickness_m)

    @property
    def wall_height_m(self) -> float:
        """Height of the wall, without the steel beams (m)."""
        return self.course_levels()[-1][1]

    @model_validator(mode="after")
    def _check_bond(self) -> Wall:
        problems: list[tuple[str, str]] = []
        if self.contact_point_rule == "lobatto" and self.contact_points_per_face < 2:
            problems.append(("contact_points_per_face", (
                f"got {self.contact_points_per_face}; the lobatto rule takes 2 to 4 points per "
                "direction (the corners, then points on the edges)")))
        if self.bond == "running":
            half, joint = self.half_unit_length_m, self.joint_thickness_m
            expected = (self.unit_length_m - joint) / 2.0
            if not half > joint:
                problems.append(
                    (
                        "half_unit_length_m",
                        (
                            f"got {half:.9g} m; a half unit must be longer than the joint, "
                            f"joint_thickness_m = {joint:.9g} m"
                        ),
                    )
                )
            if abs(half - expected) > BOND_TOLERANCE_M:
                problems.append(
                    (
                        "half_unit_length_m",
                        (
                            f"got {half:.9g} m; with a running bond the even courses "
                            "(2 half units, units_per_course - 1 whole units, units_per_course "
                            "head joints) must be as long as the odd ones, so "
                            "half_unit_length_m must be "
                            f"(unit_length_m - joint_thickness_m) / 2 = {expected:.9g} m"
                        ),
                    )
                )
        if self.bond == "pattern" and self.pattern is None:
            problems.append(("pattern", ("missing; bond 'pattern' needs the list of courses, "
                             "e.g. [[0.21, 0.21, 0.11], [0.11, 0.21, 0.21]] (unit lengths, m)")))
        if self.bond != "pattern" and self.pattern is not None:
            problems.append(("pattern", (f"given with bond {self.bond!r}; set bond: pattern to "
                             "use it, or remove it")))
        raise_problems(problems)
        return self


class Supports(Section):
    """Boundary conditions: the test rig. The wall stands on a clamped steel beam and carries a
    rigid steel beam above, glued to them or on joints of the joint law (or its outer courses
    clamped in them); the top beam's out-of-plane displacement and rotations are blocked, its
    x motion is driven by the horizontal stage.

    ``top_vertical``: ``load`` - the top beam is free in y and carries the vertical stress of
    ``loading.vertical_stress`` (the study); ``fixed`` - the top beam is held in y (then the
    vertical stress must be 0); ``load_then_fixed`` - the vertical stress is applied, then the
    beam is held at the height it has reached when the horizontal stage starts (the vertical
    reaction varies as the wall dilates or rocks).

    ``top_rotation``: ``fixed`` - the top beam stays level (the wall bends in double
    curvature, the usual shear test); ``free`` - it may rotate in the wall's plane (about z),
    the wall then works as a cantilever. model.md blocks the rotations (the default);
    docs/validation.md shows how much the initial stiffness depends on it.

    ``load_height_m``: the height above the wall's top of the point whose horizontal
    displacement is imposed and recorded as U_x (the shear span of a cantilever test is the
    wall's height plus this; with a level top beam it changes nothing). 0.1 m is the centre of
    the 0.2 m tall beam.

    ``clamped_courses``: the courses at the bottom and at the top of the wall embedded in the
    steel beams (0: none, as in the study; 1: the outer course at each end). A clamped course
    moves with its beam (its weight is the beam's), and the bed joint between it and the wall
    is as ``beam_joints`` says.

    ``beam_joints``: how the wall meets the beams (or the clamped courses in them): ``glue``,
    bilateral glue that never opens nor slides (the study's epoxy), or ``joint_law``, joints of
    the case's joint law (``bed_bottom`` and ``bed_top``) on which the wall can rock and slide
    as a wall built on its foundation with a mortar bed (or dry) does. Left out, it is
    ``glue`` without clamped courses and ``joint_law`` with them.

    ``top_beam``: ``present`` (the rig), or ``absent``: no top beam, the wall stands free on
    its base, for ``loading.ground_motion`` only (no vertical stress then, and no clamped
    courses). Under ground motion a present top beam is free in x, carries the vertical stress
    in y (``top_vertical: load``) and its mass, and rotates as ``top_rotation`` says.
    """

    top_vertical: Literal["load", "fixed", "load_then_fixed"] = Field(
        "load", description="top beam in y: load (free, carries sigma_N), fixed (held) or "
        "load_then_fixed (held from the start of the horizontal stage)"
    )
    top_rotation: Literal["fixed", "free"] = Field(
        "fixed", description="in-plane rotation of the top beam: fixed (level) or free"
    )
    top_beam_mass_kg: Real = Field(
        500.0, ge=1.0, le=1e7, description="mass of the rigid top steel beam (kg)"
    )
    load_height_m: Real = Field(
        0.1, ge=0.0, le=100.0,
        description="height above the wall's top where U_x is imposed (m; 0.1: the beam's "
        "centre)",
    )
    clamped_courses: Whole = Field(
        0, ge=0, le=10,
        description="courses embedded in each steel beam, bottom and top (count; 0: none)",
    )
    beam_joints: Literal["glue", "joint_law"] = Field(
        "glue", description="joints between the wall and the beams: glue (never open) or "
        "joint_law (the case's joint law); left out: glue without clamped courses, joint_law "
        "with them"
    )
    top_beam: Literal["present", "absent"] = Field(
        "present", description="the top steel beam: present (the rig), or absent (a "
        "free-standing wall under loading.ground_motion)"
    )

    @model_validator(mode="before")
    @classmethod
    def _beam_joints_default(cls, data):
        """``beam_joints`` left out: the joint law where courses are clamped, glue otherwise."""
        if isinstance(data, dict) and "beam_joints" not in data:
            clamped = data.get("clamped_courses", 0)
            try:
                on_law = int(clamped) > 0
            except (TypeError, ValueError):
                on_law = False  # the field's own check names the bad value
            data = {**data, "beam_joints": "joint_law" if on_law else "glue"}
        return data


def vertical_force_N(case) -> float:
    """The vertical force on the top beam (N): sigma_N times the wall's length and thickness."""
    w = case.wall
    return case.loading.vertical_stress.value_Pa * w.wall_length_m * w.thickness_m


STRUCTURE = Structure(
    name="wall", model=Wall, article="a wall", order=0, limit_state=False,
    description="geometry, bond and mesh",
    owns=("wall", "supports", "loading.vertical_stress", "loading.horizontal", "joint.regions"))
