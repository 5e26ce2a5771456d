"""The case file: what one simulation of a masonry wall is, validated, with SI units.

A case file is a YAML mapping with the sections below; every value is in SI units (m, Pa, N, J,
s, kg) and every section and field is optional (the defaults are the reference study: Venzal's
1.85 x 1.20 x 0.15 m limestone wall, 11 courses in running bond, ENDO3D blocks, frictional
cohesive joints, 0.5 MPa of vertical stress, 10 mm of imposed horizontal displacement; see
``docs/model.md`` section 1 of the shared documentation)::

    name: wall_0.5MPa            # default: the file's stem
    description: ...
    wall:     geometry of the units, the joints, the bond and the mesh     -> Wall
    blocks:   material of the units (elastic | endo3d | rigid)             -> Blocks, Endo3d
    joint:    joint law (frictional cohesive zone + spring, or Coulomb)    -> Joint
    supports: boundary conditions of the top steel beam                    -> Supports
    loading:  gravity, vertical stress, horizontal displacement stages     -> Loading
    solver:   time step, theta, NLGS tolerance                             -> Solver
    output:   what is written and how often                                -> Output
    arch:     an arch of voussoirs instead of the wall (issue 18)          -> Arch
    vault:    a barrel vault: the arch in staggered rings along z          -> Vault
    assembly: blocks of hexahedra read from a mesh file                    -> Assembly
    collapse: when an arch run has collapsed                               -> Collapse

An arch case has ``arch:`` and its loads (``loading.body_force``, ``point_load``,
``settlement``); the wall's sections (``wall``, ``supports``, ``loading.vertical_stress``,
``loading.horizontal``) are then refused, and the arch's in a wall case (:data:`WALL_ONLY`,
:data:`ARCH_ONLY`); the case written back has the sections of its builder only.

Units are in the field names (``_m``, ``_Pa``, ``_Pa_m`` = Pa/m, ``_J_m2`` = J/m^2, ``_kg_m3``,
``_kg``, ``_s``, ``_m_s`` = m/s, ``_m_s2`` = m/s^2) or, for dimensionless numbers and counts, in
the field's description.

Reading YAML. PyYAML implements YAML 1.1, where ``1e5`` and ``0.3e6`` are *strings* (a 1.1 float
needs a dot and a signed exponent), ``010`` is 8 and ``no``/``on`` are booleans. Case files are
read with a loader that implements the YAML 1.2 core schema instead: ``1e5``, ``0.3e6``,
``-2.5E-3``, ``.5`` are floats; ``10``, ``0x1f``, ``0o17`` are integers; only
``true``/``false`` (any case style) are booleans; ``null``, ``~`` and an empty value are null;
everything else is text. Duplicate keys in a mapping are an error (PyYAML silently keeps the last
one). Numbers given as quoted text ("0.3e6") are still converted by the (lax) validation; true and
false are *not* accepted where a number is expected.

Errors. Every problem in a case file - missing file, YAML syntax, wrong type, out-of-range value,
unknown field, inconsistent geometry, bad ``--set`` override - raises :class:`CaseError`, whose
``messages`` are one readable line each, naming the field path (``joint.d_spring``), the value
given and what is allowed.

Public API: :class:`Case` (and its sections), :func:`load_case`, :func:`case_from_dict`,
:func:`case_to_yaml`, :func:`read_yaml`, :class:`CaseError`.
"""

from __future__ import annotations

import copy
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import UnionType
from typing import Annotated, Any, ClassVar, Literal, Union, get_args, get_origin

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

__all__ = [
    "Arch",
    "Assembly",
    "AssemblyMaterial",
    "AssemblySupport",
    "Blocks",
    "BodyForce",
    "Case",
    "CaseError",
    "Collapse",
    "Endo3d",
    "GravityStage",
    "HorizontalStage",
    "Joint",
    "JointScatter",
    "Lintel",
    "Loading",
    "Opening",
    "Output",
    "PatternCourse",
    "PointLoad",
    "RefineRegion",
    "Settlement",
    "Solver",
    "StressStage",
    "Supports",
    "Vault",
    "Wall",
    "case_from_dict",
    "case_to_yaml",
    "load_case",
    "read_yaml",
]

#: Tolerance of the running-bond length identity (m).
BOND_TOLERANCE_M = 1e-9


# ---------------------------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------------------------


class CaseError(Exception):
    """An invalid case file or override.

    ``messages`` holds one readable line per problem, each starting with the field path
    (``joint.d_spring: got 1.2; ...``) or with the file when the problem is the file itself.
    ``str(error)`` is the messages joined by newlines.
    """

    def __init__(self, messages: str | Sequence[str]):
        if isinstance(messages, str):
            messages = [messages]
        self.messages: list[str] = [str(m) for m in messages] or ["invalid case"]
        super().__init__("\n".join(self.messages))


# ---------------------------------------------------------------------------------------------
# Field types
# ---------------------------------------------------------------------------------------------


def _reject_bool(value: Any) -> Any:
    """Refuse ``true``/``false`` where a number is expected (pydantic would read them as 1/0)."""
    if isinstance(value, bool):
        raise PydanticCustomError("number_type", "a number is expected, not true/false")
    return value


#: A real number (lax: ints and numeric text are converted; booleans are refused).
Real = Annotated[float, BeforeValidator(_reject_bool)]
#: A whole number (lax: 3.0 and "3" are converted; 3.5 and booleans are refused).
Whole = Annotated[int, BeforeValidator(_reject_bool)]
#: Number of hexahedra of one unit along one direction.
ElementCount = Annotated[int, BeforeValidator(_reject_bool), Field(ge=1, le=8)]

_SQRT3 = math.sqrt(3.0)


class _Section(BaseModel):
    """Common configuration: unknown keys are errors, assignments are validated, no inf/nan.

    An assignment that breaks a field's own bounds is refused (pydantic ``ValidationError``) and
    leaves the model unchanged; one that breaks a cross-field check of the section (e.g. the
    running-bond identity) raises too, but pydantic has already stored the value. To change
    several related values, build a new case: ``case_from_dict(case.model_dump() | {...})``.
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=True, allow_inf_nan=False)


def _problems(problems: list[tuple[str, str]]) -> None:
    """Raise the consistency problems of one section as one pydantic error.

    Each problem is ``(field, text)``, the field relative to the section; the formatter of
    :class:`CaseError` turns each into a message with the full path.
    """
    if problems:
        summary = "; ".join(f"{field}: {text}" for field, text in problems)
        raise PydanticCustomError(
            "case_consistency", "{summary}", {"summary": summary, "problems": problems}
        )


# ---------------------------------------------------------------------------------------------
# Wall
# ---------------------------------------------------------------------------------------------


class PatternCourse(_Section):
    """One course of a pattern bond with its own unit height (lengths in m)."""

    units: list[Annotated[Real, Field(ge=0.005, le=10.0)]] = Field(
        min_length=1, max_length=500, description="unit lengths, left to right (m)"
    )
    height_m: Real | None = Field(
        None, ge=0.01, le=10.0, description="unit height of this course (m; null: unit_height_m)"
    )


class Lintel(_Section):
    """A lintel over an opening: one linear elastic unit (the blocks' E, nu and density; rigid
    in a wall of rigid blocks) spanning the opening and bearing on the units beside it."""

    height_m: Real = Field(
        gt=0.0, le=10.0, description="height of the lintel (m): that of whole courses above "
        "the opening"
    )
    bearing_m: Real = Field(
        gt=0.0, le=10.0, description="length the lintel rests on beyond each side (m)"
    )


class Opening(_Section):
    """A rectangular opening (window, door), measured from the wall's lower left corner (m).
    Its bottom and top edges lie in bed joints, or at the bottom or top of the wall."""

    x_m: Real = Field(ge=0.0, le=1000.0, description="left edge (m)")
    y_m: Real = Field(ge=0.0, le=1000.0, description="bottom edge (m)")
    width_m: Real = Field(gt=0.0, le=1000.0, description="width (m)")
    height_m: Real = Field(gt=0.0, le=1000.0, description="height (m)")
    lintel: Lintel | None = Field(None, description="a lintel over the opening (null: none)")


class RefineRegion(_Section):
    """Units meshed with other ``elements_per_unit``: the units ``units`` (positions in their
    course from the left end) of the courses ``courses`` (from the bottom), both counted from 1,
    negative from the other end (-1: the top course, the right end unit); ``units`` null: every
    unit of those courses. Example, the two end units of the first and last courses:
    ``{courses: [1, -1], units: [1, -1], elements_per_unit: [6, 6, 2]}``."""

    courses: list[Annotated[Whole, Field(ge=-200, le=200)]] = Field(
        min_length=1, max_length=200, description="courses, from 1 at the bottom (-1: the top)"
    )
    units: list[Annotated[Whole, Field(ge=-500, le=500)]] | None = Field(
        None, max_length=500,
        description="positions in the course, from 1 at the left end (-1: the right end); "
        "null: all",
    )
    elements_per_unit: tuple[ElementCount, ElementCount, ElementCount] = Field(
        description="hexahedra per unit along length, height, thickness (counts, 1..8 each)"
    )


class Wall(_Section):
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
        description="hexahedra per unit along length, height, thickness (counts, 1..8 each)",
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

    @property
    def wall_length_m(self) -> float:
        """Length of the wall along x (m): ``n * unit_length + (n - 1) * joint`` (running,
        stack), the length of the first course (pattern)."""
        if self.bond == "pattern":
            from masonry_nscd.scenes.layout import wall_size

            return wall_size(self)[0]
        n = self.units_per_course
        return n * self.unit_length_m + (n - 1) * self.joint_thickness_m

    @property
    def wall_height_m(self) -> float:
        """Height of the wall, without the steel beams (m)."""
        from masonry_nscd.scenes.layout import wall_size

        return wall_size(self)[1]

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
        if not problems:
            from masonry_nscd.scenes.layout import LayoutError, unit_boxes, unit_divisions

            try:
                unit_divisions(self, unit_boxes(self))
            except LayoutError as exc:
                problems.append((exc.field, exc.message))
        _problems(problems)
        return self


# ---------------------------------------------------------------------------------------------
# Blocks
# ---------------------------------------------------------------------------------------------


class Endo3d(_Section):
    """Parameters of the ENDO3D damage-plasticity law of the stone (docs/model.md section 3).

    Strengths in Pa, strains dimensionless, fracture energies in J/m^2. ``eps_pic_t`` is the
    study's peak tensile strain; the law of model.md reaches its tensile peak at ``R_t / E``
    (9.009e-5 with the defaults, the same number), so the value is kept for the record.
    """

    R_t_Pa: Real = Field(
        1.0e6, ge=1e3, le=1e9, description="tensile strength R_t (Pa), Rankine criterion"
    )
    eps_pic_t: Real = Field(
        0.9009e-4, gt=0.0, lt=1.0, description="strain at the tensile peak (dimensionless)"
    )
    G_ft_J_m2: Real = Field(
        60.0, ge=1e-3, le=1e6, description="tensile fracture energy G_ft (J/m^2), Hillerborg"
    )
    R_c_Pa: Real = Field(9.46e6, ge=1e3, le=1e10, description="compressive strength R_c (Pa)")
    eps_pic_c: Real = Field(
        0.13e-1, gt=0.0, lt=1.0, description="strain at the compressive peak (dimensionless)"
    )
    delta: Real = Field(
        0.4,
        ge=0.0,
        lt=_SQRT3,
        description="Drucker-Prager confinement coefficient (dimensionless, < sqrt 3)",
    )
    beta: Real = Field(
        0.2,
        ge=0.0,
        lt=_SQRT3,
        description="Drucker-Prager dilatancy coefficient (dimensionless, 0 <= beta <= delta)",
    )
    eps_kdc: Real = Field(
        0.18e-1,
        gt=0.0,
        lt=1.0,
        description="post-peak compressive damage strain scale (dimensionless)",
    )
    crushing_length_m: Real = Field(
        0.0, ge=0.0, le=10.0,
        description="length of an element whose post-peak strain scale is eps_kdc (m; 0: the "
        "law as specified, eps_kdc a strain whatever the mesh; > 0: regularised by the element "
        "size)",
    )
    DCPK: Real = Field(
        1.0, ge=0.0, le=1.0, description="cap on the pre-peak compressive damage (dimensionless)"
    )
    REF_Pa: Real = Field(0.3e6, ge=1e2, le=1e9, description="crack reclosure stress REF (Pa)")
    GFR_J_m2: Real = Field(4.5, ge=1e-3, le=1e6, description="crack reclosure energy GFR (J/m^2)")
    relaxation_time_s: Real = Field(
        1e-3, ge=0.0, le=1.0,
        description="Duvaut-Lions relaxation time tau of the viscous regularisation (s); "
        "0 = the rate-independent law (materials/blocks.py)",
    )

    @model_validator(mode="after")
    def _check_strengths(self) -> Endo3d:
        """``R_t < R_c``; ``beta <= delta``: the Drucker-Prager flow dissipates
        ``dlambda (C + (delta - beta) p)`` (J/m^3), negative at pressures
        ``p > C/(beta - delta)`` when ``beta > delta``: the law then creates energy (issue 7:
        a shear cycle with beta = 1.5, delta = 0 ratchets the effective pressure up to
        100 R_c). ``materials.endo3d.endo3d_params`` only warns, for studies of the kernel."""
        problems: list[tuple[str, str]] = []
        if not self.beta <= self.delta:
            problems.append(
                (
                    "beta",
                    (
                        f"got {self.beta:.6g}; allowed: 0 <= beta <= delta = {self.delta:.6g} "
                        "(with beta > delta the Drucker-Prager flow dissipates a negative "
                        "energy dlambda (C + (delta - beta) p) at pressures p > C/(beta - delta))"
                    ),
                )
            )
        if not self.R_t_Pa < self.R_c_Pa:
            problems.append(
                (
                    "R_t_Pa",
                    (
                        f"got {self.R_t_Pa:.9g} Pa; the tensile strength must be lower than the "
                        f"compressive strength R_c_Pa = {self.R_c_Pa:.9g} Pa"
                    ),
                )
            )
        _problems(problems)
        return self


class Blocks(_Section):
    """The units (blocks): material model, density, elasticity.

    ``material``: ``endo3d`` (damage-plasticity, the study), ``elastic`` (linear elastic, the
    study's counter-example, same E and nu) or ``rigid`` (rigid bodies, for fast studies where
    block deformation does not matter; E and nu unused). The ``endo3d`` section is used only
    with ``material: endo3d``.
    """

    material: Literal["elastic", "endo3d", "rigid"] = Field(
        "endo3d", description="block material model: elastic, endo3d or rigid"
    )
    density_kg_m3: Real = Field(2000.0, ge=100.0, le=1e5, description="density (kg/m^3)")
    E_Pa: Real = Field(11.1e9, ge=1e6, le=1e13, description="Young's modulus E (Pa)")
    nu: Real = Field(
        0.2, gt=-1.0, lt=0.5, description="Poisson's ratio (dimensionless, -1 < nu < 0.5)"
    )
    endo3d: Endo3d = Field(
        default_factory=Endo3d, description="ENDO3D parameters (used when material is endo3d)"
    )

    @model_validator(mode="after")
    def _check_endo3d_with_E(self) -> Blocks:
        """For ENDO3D blocks, the checks of ``materials.endo3d.endo3d_params`` that involve E:
        ``R_t < R_c,eff`` and ``R_t delta <= R_c,eff (1/sqrt3 - delta/3)``, with the effective
        compressive strength ``R_c,eff`` of that function (kept equal to it by
        tests/test_case.py; not imported here, it would load numba)."""
        if self.material != "endo3d":
            return self
        e, E = self.endo3d, self.E_Pa
        if e.DCPK > 0.0 and e.eps_pic_c > e.R_c_Pa / E:
            cap_free = e.DCPK >= 1.0 - e.R_c_Pa / (E * e.eps_pic_c)
            rc_eff = E * e.eps_pic_c if cap_free else e.R_c_Pa / (1.0 - e.DCPK)
        else:
            rc_eff = e.R_c_Pa
        problems: list[tuple[str, str]] = []
        if not e.R_t_Pa < rc_eff:
            problems.append(("endo3d.R_t_Pa", (
                f"got {e.R_t_Pa:.6g} Pa; it must be lower than the effective compressive "
                f"strength R_c,eff = {rc_eff:.6g} Pa (from R_c_Pa, eps_pic_c, DCPK and E_Pa)")))
        elif not e.R_t_Pa * e.delta <= rc_eff * (1.0 / _SQRT3 - e.delta / 3.0):
            problems.append(("endo3d.delta", (
                f"got {e.delta:.6g}; the initial cohesion R_t delta = {e.R_t_Pa * e.delta:.6g} "
                f"Pa exceeds the peak cohesion R_c,eff (1/sqrt3 - delta/3) = "
                f"{rc_eff * (1.0 / _SQRT3 - e.delta / 3.0):.6g} Pa: lower delta or R_t_Pa")))
        _problems(problems)
        return self


# ---------------------------------------------------------------------------------------------
# Joint
# ---------------------------------------------------------------------------------------------


class JointScatter(_Section):
    """Scatter of the joint properties (masonry_nscd/contact/scatter.py): each of ``fields``
    drawn independently from a lognormal law whose mean is the case's value and whose
    coefficient of variation is ``cv``, once per joint (``per: joint``, the interface between
    two units) or per element face of the joint (``per: face``), with the random ``seed``. The
    glue is not scattered."""

    cv: Real = Field(0.2, gt=0.0, le=2.0, description="coefficient of variation (dimensionless)")
    seed: Whole = Field(1, ge=0, le=2**63 - 1, description="seed of the random draws (integer)")
    fields: list[Literal["sigma_I_e_Pa", "sigma_II_e_Pa", "G_fI_J_m2", "G_fII_J_m2"]] = Field(
        default_factory=lambda: ["sigma_I_e_Pa", "sigma_II_e_Pa", "G_fI_J_m2", "G_fII_J_m2"],
        min_length=1, max_length=4, description="joint fields drawn",
    )
    per: Literal["joint", "face"] = Field(
        "joint", description="one draw per joint (two units) or per element face of a joint"
    )


#: The numbers of the fczm law a joint region may set; the law itself, the spring convention in
#: compression and the scatter are the case's.
REGION_FIELDS = ("K_I_spring_Pa_m", "K_II_spring_Pa_m", "d_spring", "sigma_I_e_Pa",
                 "K_I_coh_Pa_m", "G_fI_J_m2", "sigma_II_e_Pa", "K_II_coh_Pa_m", "G_fII_J_m2",
                 "d_coh_initial", "mu", "p", "eta")


class JointRegion(_Section):
    """Joints of a wall with properties of their own (``joint.regions``): the bed joints on
    top of the courses ``courses`` (``joints: bed``; course 1: the joint between the first and
    the second course, the study's base joint) or the head joints within them (``joints:
    head``). Courses count from 1 at the bottom, negative from the top (-1: the top course);
    null: every course. Each field given replaces the case's value for those joints (bounds and
    fracture-energy checks as in ``joint``); the others are the case's. Example, a base joint
    with 0.3 times the others' strengths (the energies times 0.3^2 keep the shape of the
    law)::

        {joints: bed, courses: [1], sigma_I_e_Pa: 1.5e4, G_fI_J_m2: 0.27,
         sigma_II_e_Pa: 8.1e4, G_fII_J_m2: 18.54}
    """

    #: Fields left out of the case written back when null (the case's value).
    OMIT_NULL: ClassVar[tuple[str, ...]] = REGION_FIELDS

    joints: Literal["bed", "head"] = Field(
        description="bed: the bed joints on top of the courses; head: the head joints in them"
    )
    courses: list[Annotated[Whole, Field(ge=-200, le=200)]] | None = Field(
        None, min_length=1, max_length=200,
        description="courses, from 1 at the bottom (-1: the top); null: every course",
    )
    K_I_spring_Pa_m: Real | None = Field(None, description="as joint.K_I_spring_Pa_m (Pa/m)")
    K_II_spring_Pa_m: Real | None = Field(None, description="as joint.K_II_spring_Pa_m (Pa/m)")
    d_spring: Real | None = Field(None, description="as joint.d_spring (dimensionless)")
    sigma_I_e_Pa: Real | None = Field(None, description="as joint.sigma_I_e_Pa (Pa)")
    K_I_coh_Pa_m: Real | None = Field(None, description="as joint.K_I_coh_Pa_m (Pa/m)")
    G_fI_J_m2: Real | None = Field(None, description="as joint.G_fI_J_m2 (J/m^2)")
    sigma_II_e_Pa: Real | None = Field(None, description="as joint.sigma_II_e_Pa (Pa)")
    K_II_coh_Pa_m: Real | None = Field(None, description="as joint.K_II_coh_Pa_m (Pa/m)")
    G_fII_J_m2: Real | None = Field(None, description="as joint.G_fII_J_m2 (J/m^2)")
    d_coh_initial: Real | None = Field(None, description="as joint.d_coh_initial (dimensionless)")
    mu: Real | None = Field(None, description="as joint.mu (dimensionless)")
    p: Real | None = Field(None, description="as joint.p (dimensionless)")
    eta: Real | None = Field(None, description="as joint.eta (dimensionless)")

    def values(self) -> dict[str, float]:
        """The fields this region sets: ``{name: value}``."""
        return {f: float(getattr(self, f)) for f in REGION_FIELDS if getattr(self, f) is not None}


class Joint(_Section):
    """The joint law, per unit area of interface (docs/model.md section 2).

    ``law``:

    - ``fczm``: frictional cohesive zone in series with an elastic spring (the study). Spring
      ``T = (1 - d_spring) K^spring u_s``; cohesion with one integrity shared by both modes,
      initial integrity ``1 - d_coh_initial``, exponential softening to ``eta``; Coulomb
      friction in compression with ``mu_eff = mu (1 - beta b)^p``.
    - ``coulomb``: dry Signorini-Coulomb contact with friction ``mu``; no cohesion, no spring
      (the spring and cohesive parameters are then unused).
    - ``dry``: a dry joint, Signorini-Coulomb contact with friction ``mu`` in series with
      interface stiffnesses ``K_n_Pa_m``, ``K_t_Pa_m`` (the closure of rough dry joints), no
      cohesion: ``T_n = K_n <u_n>_-``, ``|T_t| <= mu |T_n|``. Only ``mu`` and the two
      stiffnesses are used.

    Stiffnesses in Pa/m (traction per opening), stresses in Pa, fracture energies in J/m^2.
    Mode I is normal opening, mode II tangential sliding. The softening slope
    ``phi = sigma_e / (G - sigma_e^2 / (2 K_coh))`` needs ``G_f > sigma_e^2 / (2 K_coh)`` in each
    mode; it is checked here for the pure modes and for mixed modes.
    """

    law: Literal["fczm", "coulomb", "dry"] = Field(
        "fczm",
        description=(
            "fczm: cohesive zone + friction + spring; coulomb: dry friction only (rigid contact); "
            "dry: dry friction in series with the interface stiffnesses K_n_Pa_m, K_t_Pa_m"
        ),
    )
    K_n_Pa_m: Real | None = Field(
        None, gt=0, le=1e16,
        description="dry law: normal stiffness of the joint's closure (Pa/m; needed with law dry)",
    )
    K_t_Pa_m: Real | None = Field(
        None, gt=0, le=1e16,
        description="dry law: tangential stiffness of the joint (Pa/m; needed with law dry)",
    )
    K_I_spring_Pa_m: Real = Field(
        4.3e11, ge=1e6, le=1e16, description="normal stiffness of the series spring (Pa/m)"
    )
    K_II_spring_Pa_m: Real = Field(
        1.8e11, ge=1e6, le=1e16, description="tangential stiffness of the series spring (Pa/m)"
    )
    d_spring: Real = Field(
        0.953, ge=0.0, lt=1.0, description="constant damage of the spring (dimensionless)"
    )
    sigma_I_e_Pa: Real = Field(
        0.05e6, ge=1.0, le=1e9, description="mode I elastic limit (tensile strength) (Pa)"
    )
    K_I_coh_Pa_m: Real = Field(
        1.21e11, ge=1e6, le=1e16, description="mode I cohesive stiffness (Pa/m)"
    )
    G_fI_J_m2: Real = Field(3.0, ge=1e-3, le=1e6, description="mode I fracture energy (J/m^2)")
    sigma_II_e_Pa: Real = Field(
        0.27e6, ge=1.0, le=1e9, description="mode II elastic limit (shear strength) (Pa)"
    )
    K_II_coh_Pa_m: Real = Field(
        2.8e11, ge=1e6, le=1e16, description="mode II cohesive stiffness (Pa/m)"
    )
    G_fII_J_m2: Real = Field(206.0, ge=1e-3, le=1e6, description="mode II fracture energy (J/m^2)")
    d_coh_initial: Real = Field(
        0.99944,
        ge=0.0,
        lt=1.0,
        description="initial cohesive damage, b = 1 - d_coh_initial (dimensionless)",
    )
    mu: Real = Field(0.7, ge=0.0, le=2.0, description="friction coefficient (dimensionless)")
    p: Real = Field(
        1.0,
        gt=0.0,
        le=100.0,
        description="friction growth exponent in mu (1 - beta b)^p (dimensionless)",
    )
    eta: Real = Field(
        1e-4,
        ge=1e-12,
        lt=0.5,
        description="residual integrity at which the joint is fully broken (dimensionless)",
    )
    compression_spring: Literal["damaged", "undamaged"] = Field(
        "damaged",
        description="normal spring in compression: damaged (the study) or undamaged (LMGC90)",
    )
    scatter: JointScatter | None = Field(
        None, description="lognormal scatter of the joint strengths and energies (null: none)"
    )
    regions: list[JointRegion] = Field(
        default_factory=list, max_length=100,
        description="wall joints with properties of their own (the last region naming a "
        "joint wins; the scatter draws around each region's values)",
    )

    def with_values(self, values: dict[str, float]) -> Joint:
        """This joint with ``values`` in place of its own, no regions (validated: ValueError
        naming the first field the law refuses)."""
        data = {**self.model_dump(), **values, "regions": []}
        return type(self).model_validate(data)

    @model_validator(mode="after")
    def _check_dry(self) -> Joint:
        if self.law == "dry":
            _problems([(f, "the dry law needs it (Pa/m, > 0)") for f in ("K_n_Pa_m", "K_t_Pa_m")
                       if getattr(self, f) is None])
        if self.law != "fczm" and self.scatter is not None:
            _problems([("scatter", (f"the {self.law} law has no cohesion to scatter: "
                                    "remove joint.scatter or use law fczm"))])
        if self.law != "fczm" and self.regions:
            _problems([("regions", (f"given with law {self.law}; the regions set numbers of "
                                    "the fczm law: remove joint.regions or use law fczm"))])
        return self

    @model_validator(mode="after")
    def _check_regions(self) -> Joint:
        problems: list[tuple[str, str]] = []
        for i, region in enumerate(self.regions):
            values = region.values()
            if not values:
                problems.append((f"regions[{i}]", (
                    "sets no field; give one or more of " + ", ".join(REGION_FIELDS))))
                continue
            try:
                self.with_values(values)
            except ValidationError as exc:
                for message in _messages(exc, ("joint",)):  # "joint.<field>: <text>"
                    where, _, text = message.partition(": ")
                    field = where.removeprefix("joint").lstrip(".")
                    problems.append((f"regions[{i}]" + (f".{field}" if field else ""), text))
        _problems(problems)
        return self

    @model_validator(mode="after")
    def _check_fracture_energies(self) -> Joint:
        if self.law != "fczm":
            return self
        problems: list[tuple[str, str]] = []
        modes = (
            ("G_fI_J_m2", self.G_fI_J_m2, "sigma_I_e_Pa", self.sigma_I_e_Pa,
             "K_I_coh_Pa_m", self.K_I_coh_Pa_m),
            ("G_fII_J_m2", self.G_fII_J_m2, "sigma_II_e_Pa", self.sigma_II_e_Pa,
             "K_II_coh_Pa_m", self.K_II_coh_Pa_m),
        )  # fmt: skip
        for g_name, g, s_name, s, k_name, k in modes:
            elastic = s * s / (2.0 * k)
            if not g > elastic:
                problems.append(
                    (
                        g_name,
                        (
                            f"got {g:.6g} J/m^2; it must exceed the elastic energy "
                            f"{s_name}^2 / (2 {k_name}) = {elastic:.6g} J/m^2, else the softening "
                            f"slope is undefined (raise {g_name} or {k_name}, or lower {s_name})"
                        ),
                    )
                )
        if not problems:
            m_bad = self._worst_mixed_mode()
            if m_bad is not None:
                problems.append(
                    (
                        "G_fII_J_m2",
                        (
                            f"with G_fI_J_m2 = {self.G_fI_J_m2:.6g} and G_fII_J_m2 = "
                            f"{self.G_fII_J_m2:.6g} J/m^2 the mixed-mode fracture energy is below "
                            f"the mixed-mode elastic energy at mode mixity m = {m_bad:.3g} (the "
                            "softening slope is undefined there): raise G_fI_J_m2 or G_fII_J_m2"
                        ),
                    )
                )
        _problems(problems)
        return self

    def _worst_mixed_mode(self) -> float | None:
        """Mode mixity m where G(m) <= sigma_e(m) delta_e(m) / 2, or None if there is none."""
        d1 = self.sigma_I_e_Pa / self.K_I_coh_Pa_m
        d2 = self.sigma_II_e_Pa / self.K_II_coh_Pa_m
        k1, k2 = self.K_I_coh_Pa_m, self.K_II_coh_Pa_m
        for i in range(-120, 121):
            m = 10.0 ** (i / 10.0)
            w1, w2 = d2 * d2, m * d1 * d1
            g = (w1 * self.G_fI_J_m2 + w2 * self.G_fII_J_m2) / (w1 + w2)
            delta_e_sq = d1 * d1 * d2 * d2 * (1.0 + m) / (w1 + w2)
            k = math.sqrt((k1 * k1 + m * k2 * k2) / (1.0 + m))
            if not g > 0.5 * k * delta_e_sq:
                return m
        return None


# ---------------------------------------------------------------------------------------------
# Arches and limit states (issue 18): the arch builder, the growing loads, the collapse rule
# ---------------------------------------------------------------------------------------------


Vector3 = tuple[Real, Real, Real]


def _unit(value: tuple[float, float, float]) -> tuple[float, float, float]:
    """A direction (3 components, not all zero) made a unit vector."""
    norm = math.sqrt(sum(v * v for v in value))
    if not norm > 0.0:
        raise PydanticCustomError("direction_zero", "a direction needs a non-zero component")
    return tuple(v / norm for v in value)  # type: ignore[return-value]


Direction = Annotated[Vector3, AfterValidator(_unit)]


class Arch(_Section):
    """An arch of voussoirs on two abutments (``masonry_nscd/scenes/arch.py``), instead of a
    wall (lengths in m).

    The arch lies in the x-y plane: x horizontal from the middle of the span, y up from the
    springing line, z along its depth. ``radius_m`` is the radius of the arch's centreline
    (the middle of the ring), ``span_m`` the distance between the centres of its two springing
    joints. ``semicircular``: give one of them (span = 2 radius). ``pointed``: two arcs of
    ``radius_m`` whose centres lie on the springing line, ``radius - span / 2`` from the middle
    of the span on the other side, meeting at a vertical crown joint; give both, ``radius_m >
    span_m / 2``, and an even number of voussoirs.

    The joints between voussoirs are radial planes (a pointed arch's crown joint is vertical),
    equally spaced in angle; each voussoir is a prism on the chords of its intrados and
    extrados (one hexahedron, or ``elements_per_voussoir``). ``joint_thickness_m`` is the
    initial gap of every joint (0: dry voussoirs in contact). Abutments: ``fixed`` - the
    springers rest on two fixed rigid abutments; ``blocks`` - the abutments are rigid blocks
    (piers) of ``abutment_width_m`` x ``abutment_height_m`` resting on fixed ground through a
    joint of the joint law, free to slide and overturn.
    """

    shape: Literal["semicircular", "pointed"] = Field(
        "semicircular", description="semicircular, or pointed (two arcs meeting at the crown)"
    )
    radius_m: Real | None = Field(
        1.0, gt=0.0, le=1000.0,
        description="radius of the centreline (m; null: from span_m, semicircular arch)",
    )
    span_m: Real | None = Field(
        None, gt=0.0, le=2000.0,
        description="distance between the centres of the springing joints (m; null: 2 radius, "
        "semicircular arch)",
    )
    thickness_m: Real = Field(
        0.15, gt=0.0, le=100.0, description="thickness of the ring, intrados to extrados (m)"
    )
    depth_m: Real = Field(0.25, gt=0.0, le=100.0, description="depth of the arch along z (m)")
    voussoirs: Whole = Field(24, ge=3, le=500, description="number of voussoirs (count)")
    joint_thickness_m: Real = Field(
        0.0, ge=0.0, le=0.5, description="initial gap of every joint (m; 0: dry contact)"
    )
    elements_per_voussoir: tuple[ElementCount, ElementCount, ElementCount] = Field(
        (1, 1, 1),
        description="hexahedra per voussoir along the ring, through the thickness, along the "
        "depth (counts, 1..8 each)",
    )
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)",
    )
    contact_point_rule: Literal["auto", "gauss", "lobatto"] = Field(
        "auto",
        description="gauss, lobatto (the corners among them: voussoirs hinge about the edges "
        "of their faces) or auto: lobatto with 2 or more points, whatever the joint law",
    )
    abutments: Literal["fixed", "blocks"] = Field(
        "fixed", description="fixed (rigid supports) or blocks (rigid piers on fixed ground)"
    )
    abutment_width_m: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="width of each abutment along x, centred on its springing (m; null: 2 "
        "thickness)",
    )
    abutment_height_m: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="height of each abutment (m; null: the thickness)",
    )

    @property
    def centreline_radius_m(self) -> float:
        """Radius of the centreline (m)."""
        return float(self.radius_m if self.radius_m is not None else self.span_m / 2.0)

    @property
    def centreline_span_m(self) -> float:
        """Distance between the centres of the springing joints (m)."""
        return float(self.span_m if self.span_m is not None else 2.0 * self.radius_m)

    @model_validator(mode="after")
    def _check_geometry(self) -> Arch:
        problems: list[tuple[str, str]] = []
        if self.radius_m is None and self.span_m is None:
            problems.append(("radius_m", "give radius_m or span_m"))
        elif self.shape == "semicircular":
            if self.radius_m is not None and self.span_m is not None and \
                    abs(self.span_m - 2.0 * self.radius_m) > 1e-9 * self.span_m:
                problems.append(("span_m", (
                    f"got {self.span_m:.6g} m with radius_m = {self.radius_m:.6g} m; a "
                    "semicircular arch has span = 2 radius: give one of them")))
        else:
            if self.radius_m is None or self.span_m is None:
                problems.append(("span_m" if self.span_m is None else "radius_m",
                                 "a pointed arch needs both radius_m and span_m"))
            elif not self.radius_m > self.span_m / 2.0:
                problems.append(("radius_m", (
                    f"got {self.radius_m:.6g} m; a pointed arch needs radius_m > span_m / 2 = "
                    f"{self.span_m / 2.0:.6g} m (equal: semicircular)")))
            if self.voussoirs % 2:
                problems.append(("voussoirs", (
                    f"got {self.voussoirs}; a pointed arch needs an even number (its crown "
                    "is a joint)")))
        if not problems:
            r, t = self.centreline_radius_m, self.thickness_m
            c = r - self.centreline_span_m / 2.0
            if not r - t / 2.0 > c:
                problems.append(("thickness_m", (
                    f"got {t:.6g} m; the intrados radius (radius - thickness / 2) must exceed "
                    f"{'the offset of the centres ' if c > 0 else ''}{c:.6g} m: at most "
                    f"{2.0 * (r - c):.6g} m")))
            width = self.abutment_width_m
            if width is not None and width < t:
                problems.append(("abutment_width_m", (
                    f"got {width:.6g} m; an abutment must be at least as wide as the "
                    f"springing joint, the thickness {t:.6g} m")))
        _problems(problems)
        return self


class Vault(Arch):
    """A barrel vault (``masonry_nscd/scenes/vault.py``): the arch of the same fields extruded
    along z over ``depth_m``, in ``rings`` rings of voussoirs side by side, each
    ``depth_m / rings`` deep, instead of a wall or an arch.

    With ``stagger`` the radial joints of every second ring fall in the middle of the voussoirs
    of its neighbours (running bond along the ring): that ring has ``voussoirs - 1`` whole
    voussoirs and a half voussoir at each springing. The joints between rings are planes
    ``z = const``; every joint is a dry contact (``joint_thickness_m`` must be 0). The
    abutments run along the whole depth. A voussoir is made of two half voussoirs (one at a
    staggered ring's springings), each meshed with ``elements_per_voussoir`` hexahedra.
    """

    depth_m: Real = Field(1.0, gt=0.0, le=100.0, description="length of the vault along z (m)")
    rings: Whole = Field(4, ge=1, le=100, description="rings of voussoirs along z (count)")
    stagger: bool = Field(
        True, description="radial joints of every second ring offset by half a voussoir"
    )

    @model_validator(mode="after")
    def _check_vault(self) -> Vault:
        problems: list[tuple[str, str]] = []
        if self.joint_thickness_m != 0.0:
            problems.append(("joint_thickness_m", (
                f"got {self.joint_thickness_m:.6g} m; a vault's joints are dry contacts: 0 (the "
                "corners of a staggered ring would fall into a gap of its neighbour)")))
        _problems(problems)
        return self


GroupRef = Annotated[Whole | str, Field(union_mode="left_to_right")]


class AssemblySupport(_Section):
    """A block of the mesh that is a support: fixed (it does not move), its joints with the
    structure of the joint law (``fixed``) or glued (``glued``: no opening, no slip)."""

    group: GroupRef = Field(..., description="the block: its physical name or its tag")
    kind: Literal["fixed", "glued"] = Field(
        "fixed", description="fixed (joints of the joint law) or glued (glued joints)"
    )


class AssemblyMaterial(_Section):
    """The material of one block of the mesh (null fields: those of ``blocks``)."""

    group: GroupRef = Field(..., description="the block: its physical name or its tag")
    material: Literal["rigid", "elastic"] = Field("rigid", description="rigid or elastic")
    density_kg_m3: Real | None = Field(
        None, ge=100.0, le=1e5, description="density (kg/m^3; null: blocks.density_kg_m3)"
    )
    E_Pa: Real | None = Field(
        None, ge=1e6, le=1e13, description="Young's modulus (Pa; null: blocks.E_Pa)"
    )
    nu: Real | None = Field(
        None, gt=-1.0, lt=0.5, description="Poisson's ratio (null: blocks.nu)"
    )


class Assembly(_Section):
    """A block assembly read from a mesh file (``masonry_nscd/scenes/assembly.py``), instead
    of a wall, an arch or a vault.

    ``mesh_file``: a mesh of 8-node hexahedra (Gmsh ``.msh``, or any format meshio reads; a
    relative path is relative to the case file); the hexahedra of one tag (``tag_field``:
    Gmsh's physical group) are one block, named by its physical name (or ``block <tag>``).
    ``supports`` name the blocks that are fixed supports (at least one); ``materials`` give a
    block's material by its name or tag, the others take ``blocks``. Joints are found by the
    generic contact detection between facing faces at most ``joint_thickness_m`` apart (groups
    ``joint``, ``support``, ``glue``) and follow ``joint``. y is up (gravity along -y).
    """

    mesh_file: str = Field(
        ..., min_length=1, max_length=4096,
        description="mesh file of hexahedra (relative to the case file)",
    )
    tag_field: str = Field(
        "gmsh:physical", min_length=1, max_length=200,
        description="cell data of the block tag of each hexahedron",
    )
    supports: list[AssemblySupport] = Field(
        ..., min_length=1, max_length=1000, description="the blocks that are supports"
    )
    materials: list[AssemblyMaterial] = Field(
        default_factory=list, max_length=100_000,
        description="material of a block by name or tag (the others: blocks)",
    )
    driven_block: str | None = Field(
        None, max_length=200,
        description="block whose displacement is the curve's ux, uy (null: the highest)",
    )
    joint_thickness_m: Real = Field(
        0.0, ge=0.0, le=0.5, description="largest gap between two faces of a joint (m)"
    )
    contact_points_per_face: Whole = Field(
        2, ge=1, le=4,
        description="contact points per direction on each element face in contact (count)",
    )
    contact_point_rule: Literal["auto", "gauss", "lobatto"] = Field(
        "auto", description="gauss, lobatto or auto: lobatto with 2 or more points"
    )

    @field_validator("mesh_file")
    @classmethod
    def _resolve_file(cls, value: str, info: ValidationInfo) -> str:
        """A relative path is made absolute from the case file's folder, as
        ``loading.ground_motion.file``."""
        base = (info.context or {}).get("case_dir")
        if base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_mesh(self, info: ValidationInfo) -> Assembly:
        problems: list[tuple[str, str]] = []
        seen: dict[str, str] = {}
        for table in ("supports", "materials"):
            for i, entry in enumerate(getattr(self, table)):
                key = str(entry.group)
                if key in seen and (table == "supports" or seen[key] == table):
                    problems.append((f"{table}[{i}].group", (
                        f"got {entry.group!r} again; a block is named once in {table}"
                        + (" and once in materials" if table == "supports" else ""))))
                seen.setdefault(key, table)
        if not problems and (info.context or {}).get("check_files"):
            from masonry_nscd.scenes.assembly import AssemblyError, read_assembly

            try:  # read and checked only: nothing is kept in the case
                read_assembly(self)
            except AssemblyError as exc:
                problems += exc.problems
        _problems(problems)
        return self


class BodyForce(_Section):
    """A body force ``lambda(t) g m`` on every block along ``direction`` (``g`` the gravity
    of ``loading.gravity``, ``m`` the block's mass): the pseudo-static seismic or tilting-table
    load, whose multiplier at collapse is the result. ``lambda`` rises to ``multiplier`` over
    the tanh ramp ``ramp_s`` from ``start_s``, and grows at ``rate_per_s`` from there on, its
    growth starting along the same ramp::

        lambda(t) = multiplier s(t) + rate_per_s ramp_s S((t - start_s) / ramp_s)

    (``s`` the ramp, ``S`` its integral, :mod:`masonry_nscd.loading.multiplier`). A horizontal
    body force of ``lambda`` with gravity is a base tilted by ``atan(lambda)``.
    """

    direction: Direction = Field(
        (1.0, 0.0, 0.0), description="direction of the body force (made a unit vector)"
    )
    multiplier: Real = Field(
        0.0, ge=-100.0, le=100.0,
        description="constant part of lambda, reached at start_s + ramp_s (dimensionless)",
    )
    rate_per_s: Real = Field(
        0.0, ge=0.0, le=1000.0, description="growth of lambda after the ramp (1/s; 0: none)"
    )
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.1, gt=0.0, le=1e6, description="duration of the ramp (s)")

    @property
    def active(self) -> bool:
        return self.multiplier != 0.0 or self.rate_per_s > 0.0


class PointLoad(_Section):
    """A force on one block (``block``: its name, e.g. ``voussoir 7``) at the middle of its
    extrados face, ``force_N`` reached over the tanh ramp ``ramp_s`` from ``start_s`` and
    growing at ``rate_N_s`` from there on (as ``lambda`` of ``body_force``)."""

    block: str = Field(..., min_length=1, max_length=200, description="name of the block")
    direction: Direction = Field(
        (0.0, -1.0, 0.0), description="direction of the force (made a unit vector)"
    )
    force_N: Real = Field(0.0, ge=0.0, le=1e12, description="constant part of the force (N)")
    rate_N_s: Real = Field(0.0, ge=0.0, le=1e12, description="growth of the force (N/s)")
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.1, gt=0.0, le=1e6, description="duration of the ramp (s)")


class Settlement(_Section):
    """A support that moves: the fixed body under one springing (the abutment, or the ground
    under a block abutment) moves by ``displacement_m`` along a tanh ramp of ``duration_s``
    from ``start_s``."""

    support: Literal["left", "right"] = Field(..., description="the support that moves")
    displacement_m: Vector3 = Field(..., description="its displacement (m): x, y, z")
    start_s: Real = Field(0.3, ge=0.0, le=1e6, description="time at which it starts (s)")
    duration_s: Real = Field(1.0, gt=0.0, le=1e6, description="duration of the motion (s)")


class Collapse(_Section):
    """When a limit-state run (an arch) has collapsed, and what is read of it
    (``masonry_nscd/post/limit.py``).

    A mechanism: the largest displacement of a point of a block passes ``displacement_m``, or,
    if it is given, the largest speed passes ``velocity_m_s``. The run then goes on for
    ``after_s`` and stops, with status ``collapse``; the loads at collapse are read at the
    onset of the mechanism, the last step before it at which every block was slower than
    ``onset_velocity_m_s``. A run that reaches ``end_time_s`` stands (status ``standing``). A
    hinge is a joint open by more than ``hinge_opening_m`` over most of its face and closed at
    one edge.
    """

    displacement_m: Real = Field(
        0.01, gt=0.0, le=100.0, description="a block point moved this far: collapse (m)"
    )
    velocity_m_s: Real | None = Field(
        None, gt=0.0, le=1000.0,
        description="a block point this fast: collapse (m/s; null: displacement only)",
    )
    onset_velocity_m_s: Real = Field(
        1e-3, gt=0.0, le=1000.0,
        description="slower than this, every block is at rest: the onset of the mechanism is "
        "the last such step (m/s)",
    )
    hinge_opening_m: Real = Field(
        1e-4, gt=0.0, le=10.0, description="a joint point opened by this much is open (m)"
    )
    end_time_s: Real = Field(
        2.0, gt=0.0, le=1e7, description="the run stops here if it has not collapsed (s)"
    )
    after_s: Real = Field(
        0.0, ge=0.0, le=1e6, description="time run on after the collapse is detected (s)"
    )


#: Sections of a case that belong to the wall builder and to the arch builder (the other's
#: are refused when given, and left out of the case written back).
WALL_ONLY = ("wall", "supports", "loading.vertical_stress", "loading.horizontal",
             "joint.regions")
ARCH_ONLY = ("arch", "vault", "assembly", "collapse", "loading.body_force", "loading.point_load",
             "loading.settlement")


def _given(model: BaseModel, path: str) -> bool:
    """Whether the dotted ``path`` was given in the case (not a default)."""
    *parents, last = path.split(".")
    for part in parents:
        if part not in model.model_fields_set:
            return False
        model = getattr(model, part)
    return last in model.model_fields_set and getattr(model, last) is not None


# ---------------------------------------------------------------------------------------------
# Supports and loading
# ---------------------------------------------------------------------------------------------


class Supports(_Section):
    """Boundary conditions: the test rig. The wall is glued to a clamped steel beam below and
    to a rigid steel beam above (or its outer courses are clamped in them); the top beam's
    out-of-plane displacement and rotations are blocked, its x motion is driven by the
    horizontal stage.

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
    steel beams (0: none, the wall glued to the beams as in the study; 1: the outer course at
    each end). A clamped course moves with its beam (its weight is the beam's), and the bed
    joint between it and the wall is a mortar joint of the joint law.

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
        description="courses embedded in each steel beam, bottom and top (count; 0: glued)",
    )
    top_beam: Literal["present", "absent"] = Field(
        "present", description="the top steel beam: present (the rig), or absent (a "
        "free-standing wall under loading.ground_motion)"
    )


class GravityStage(_Section):
    """Gravity, ramped from 0 to ``value_m_s2`` (acceleration, m/s^2, acting in -y)."""

    value_m_s2: Real = Field(
        9.81, ge=0.0, le=1000.0, description="gravitational acceleration, downwards (m/s^2)"
    )
    start_s: Real = Field(0.0, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.05, gt=0.0, le=1e6, description="duration of the ramp (s)")


class StressStage(_Section):
    """Vertical compressive stress sigma_N on the top beam, ramped from 0 to ``value_Pa``.

    ``value_Pa`` is a magnitude (>= 0): the force pushing the top beam down is
    ``value_Pa * wall_length_m * thickness_m`` (138.75 kN for 0.5 MPa over 1.85 x 0.15 m).
    """

    value_Pa: Real = Field(
        0.5e6,
        ge=0.0,
        le=1e9,
        description="compressive stress sigma_N over wall length x thickness, magnitude (Pa)",
    )
    start_s: Real = Field(0.05, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(0.15, gt=0.0, le=1e6, description="duration of the ramp (s)")


class HorizontalStage(_Section):
    """Imposed horizontal displacement U_x of the top beam, along one of three histories
    (``history``; the equations are in :mod:`masonry_nscd.loading.histories`). The beam is
    driven through its velocity, each change of velocity a tanh ramp of ``ramp_s``.

    ``monotonic`` (the default, the study): the velocity ramps from 0 to ``rate_m_s`` over
    ``ramp_s`` from ``start_s``, then stays at ``rate_m_s``; the displacement therefore lags the
    ideal ``rate * (t - start)`` by ``rate_m_s * ramp_s / 2`` once the ramp is over. The run
    stops when U_x reaches ``target_m``, at ``start_s + ramp_s / 2 + target_m / rate_m_s``
    (:attr:`Loading.end_time_s`).

    ``cyclic``: for each amplitude A of ``amplitudes_m`` in turn, ``cycles_per_amplitude``
    cycles 0 -> +A -> -A -> 0 at the speed ``rate_m_s``, from ``start_s``; each reversal turns
    the velocity from +rate to -rate (or back) over ``ramp_s`` and stops exactly at +-A; the
    run ends when the beam is back at rest at 0 after the last cycle. Every amplitude must be
    at least ``rate_m_s * ramp_s`` (so that two ramps do not overlap). ``target_m`` is not
    used.

    ``table``: the displacement of the CSV file ``file`` (header ``time_s,displacement_m``,
    first row ``0,0``, times increasing; a relative path is relative to the case file's
    folder, and is written back resolved), linear between the rows, each row a corner rounded
    over ``ramp_s``; the table's time 0 is ``start_s + ramp_s / 2``; the run ends when the beam
    is at rest after the last row. ``target_m`` and ``rate_m_s`` are not used.

    ``none``: no horizontal push (the top beam is free in x); required with, and only with,
    ``loading.ground_motion``. The other fields are not used.
    """

    history: Literal["monotonic", "cyclic", "table", "none"] = Field(
        "monotonic", description="displacement history: monotonic (push to target_m), cyclic "
        "(amplitudes_m, cycles_per_amplitude), table (file), or none (no push: "
        "loading.ground_motion moves the base)"
    )
    target_m: Real = Field(
        0.010, gt=0.0, le=10.0,
        description="horizontal displacement at which the run stops (m; monotonic only)"
    )
    rate_m_s: Real = Field(
        0.002, gt=0.0, le=100.0,
        description="horizontal velocity after the ramp (m/s; monotonic and cyclic)"
    )
    start_s: Real = Field(0.25, ge=0.0, le=1e6, description="time at which the ramp starts (s)")
    ramp_s: Real = Field(
        0.05, gt=0.0, le=1e6,
        description="duration of each velocity ramp: start, reversals, corners (s)"
    )
    amplitudes_m: list[Annotated[Real, Field(gt=0.0, le=10.0)]] | None = Field(
        None, min_length=1, max_length=1000,
        description="cyclic: amplitudes of the cycles, in order (m; null otherwise)",
    )
    cycles_per_amplitude: Whole = Field(
        1, ge=1, le=100, description="cyclic: cycles at each amplitude (count)"
    )
    file: str | None = Field(
        None, min_length=1, max_length=4096,
        description="table: CSV file of time_s,displacement_m (relative to the case file; "
        "null otherwise)",
    )

    @field_validator("file")
    @classmethod
    def _resolve_file(cls, value: str | None, info: ValidationInfo) -> str | None:
        """A relative path is made absolute from the case file's folder (validation context
        ``case_dir``), so that the case written back in the run folder still finds it."""
        base = (info.context or {}).get("case_dir")
        if value is None or base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_history(self, info: ValidationInfo) -> HorizontalStage:
        problems: list[tuple[str, str]] = []
        kind = self.history
        if kind != "cyclic" and self.amplitudes_m is not None:
            problems.append(("amplitudes_m", (
                f"given with history '{kind}'; amplitudes are for history 'cyclic' (set "
                "history: cyclic, or leave amplitudes_m out)")))
        if kind != "table" and self.file is not None:
            problems.append(("file", (
                f"given with history '{kind}'; a file is for history 'table' (set "
                "history: table, or leave file out)")))
        if kind == "cyclic":
            if self.amplitudes_m is None:
                problems.append(("amplitudes_m", (
                    "missing; history 'cyclic' needs the list of amplitudes (m), e.g. "
                    "[0.001, 0.002, 0.004]")))
            elif min(self.amplitudes_m) < self.rate_m_s * self.ramp_s:
                problems.append(("amplitudes_m", (
                    f"got {min(self.amplitudes_m):.6g} m; every amplitude must be at least "
                    f"rate_m_s x ramp_s = {self.rate_m_s * self.ramp_s:.6g} m (a reversal "
                    "takes ramp_s): lower ramp_s or rate_m_s")))
        if kind == "table":
            if self.file is None:
                problems.append(("file", (
                    "missing; history 'table' needs a CSV file of time_s,displacement_m")))
            elif (info.context or {}).get("check_files"):
                from masonry_nscd.loading.histories import read_displacement_table

                try:
                    self._table = read_displacement_table(self.file)
                except ValueError as exc:
                    problems.append(("file", str(exc)))
        _problems(problems)
        return self

    _table: Any = PrivateAttr(None)

    def displacement_history(self):
        """The history (:class:`masonry_nscd.loading.histories.DisplacementHistory`): the
        beam's velocity, the end of the motion, the cycles. A table is read from ``file``
        (ValueError naming the file and line if it cannot be). None for ``none``."""
        from masonry_nscd.loading import histories as hs

        if self.history == "cyclic":
            return hs.cyclic(self.amplitudes_m, self.cycles_per_amplitude, self.rate_m_s,
                             self.start_s, self.ramp_s)
        if self.history == "table":
            if self._table is None:
                self._table = hs.read_displacement_table(self.file)
            return hs.table(*self._table, self.start_s, self.ramp_s)
        if self.history == "none":
            return None
        return hs.monotonic(self.rate_m_s, self.start_s, self.ramp_s)


class GroundMotionStage(_Section):
    """An acceleration record applied to the base (:mod:`masonry_nscd.loading.ground_motion`):
    the lower beam moves along ``direction`` with the record times ``scale`` integrated to its
    velocity and displacement (piecewise-linear acceleration between the rows), the record's
    time 0 at ``start_s``. ``file``: a CSV file with the header ``time_s,acceleration_m_s2``
    (s, m/s^2), first time 0, times increasing; a relative path is relative to the case file's
    folder and is written back resolved. The run ends at the record's last row (give the
    record a quiet tail for the wall to come to rest: the residual drift is read at the end).
    With a ground motion, ``loading.horizontal.history`` must be ``none``.
    """

    file: str = Field(
        min_length=1, max_length=4096,
        description="CSV file of time_s,acceleration_m_s2 (relative to the case file)",
    )
    scale: Real = Field(
        1.0, gt=0.0, le=100.0, description="factor on the record's accelerations (dimensionless)"
    )
    direction: Literal["x", "y"] = Field(
        "x", description="direction of the base motion: x (horizontal, in the wall's plane) or "
        "y (vertical)"
    )
    start_s: Real = Field(
        0.25, ge=0.0, le=1e6, description="run time of the record's time 0 (s)"
    )

    @field_validator("file")
    @classmethod
    def _resolve_file(cls, value: str, info: ValidationInfo) -> str:
        """A relative path is made absolute from the case file's folder (validation context
        ``case_dir``), as ``loading.horizontal.file``."""
        base = (info.context or {}).get("case_dir")
        if base is None or Path(value).is_absolute():
            return value
        return str((Path(base) / value).resolve())

    @model_validator(mode="after")
    def _check_file(self, info: ValidationInfo) -> GroundMotionStage:
        if (info.context or {}).get("check_files"):
            from masonry_nscd.loading.ground_motion import read_acceleration_record

            try:  # read to check it only: nothing kept, so the case compares equal to a
                # copy read without its files
                read_acceleration_record(self.file)
            except ValueError as exc:
                _problems([("file", str(exc))])
        return self

    def history(self):
        """The base's motion (:class:`masonry_nscd.loading.ground_motion.GroundMotion`),
        scaled; the record read from ``file`` at each call (ValueError naming the file and
        line if it cannot be)."""
        from masonry_nscd.loading.ground_motion import GroundMotion, read_acceleration_record

        t, a = read_acceleration_record(self.file)
        return GroundMotion(t, self.scale * a, self.start_s)


class Loading(_Section):
    """The three load stages, each ramped smoothly: gravity, then the vertical stress, then the
    horizontal displacement (the stages may overlap; the study applies them one after the other).
    """

    gravity: GravityStage = Field(default_factory=GravityStage, description="gravity stage")
    vertical_stress: StressStage = Field(
        default_factory=StressStage, description="vertical compressive stress on the top beam"
    )
    horizontal: HorizontalStage = Field(
        default_factory=HorizontalStage, description="imposed horizontal displacement"
    )
    ground_motion: GroundMotionStage | None = Field(
        None, description="acceleration record applied to the base (null: none)"
    )
    # arches (issue 18): the loads of limit-state runs, declared below with the arch
    body_force: BodyForce = Field(
        default_factory=BodyForce,
        description="arch: body force lambda(t) g m along a direction (the collapse multiplier)",
    )
    point_load: PointLoad | None = Field(
        None, description="arch: a growing force on one block (null: none)"
    )
    settlement: Settlement | None = Field(
        None, description="arch: the settlement of a support (null: none)"
    )

    @property
    def end_time_s(self) -> float:
        """Expected end of the run (s). Monotonic: ``start + ramp / 2 + target / rate`` of the
        horizontal stage, when U_x reaches ``target_m`` (the velocity ramps to ``rate_m_s``
        over ``ramp_s``, so the displacement lags the sharp path by ``rate ramp / 2``; exact
        when ``target_m`` is reached after the ramp, ``loading.RampedVelocity``). Cyclic and
        table: the end of the motion, when the run stops. Ground motion: the end of the
        record."""
        if self.ground_motion is not None:
            return float(self.ground_motion.history().end_s)
        h = self.horizontal
        if h.history == "none":
            return h.start_s
        if h.history != "monotonic":
            return float(h.displacement_history().end_s)
        return h.start_s + h.ramp_s / 2.0 + h.target_m / h.rate_m_s


# ---------------------------------------------------------------------------------------------
# Solver and output
# ---------------------------------------------------------------------------------------------


class Solver(_Section):
    """Time integration (Moreau-Jean theta scheme) and the contact solver.

    ``tolerance`` bounds the relative change of the contact impulses between two Newton
    iterations (and Newton's momentum residual against the contact impulses), or between two
    convergence checks of the non-linear Gauss-Seidel (NLGS), made every ``check_every``
    sweeps. It matters for NLGS: a loose tolerance lowers the apparent initial stiffness of
    the wall (docs/model.md section 4); Newton's curve is the same from 1e-5 to 1e-9 on the
    elastic wall (docs/performance.md).

    The defaults (h = 4e-3 s, 3e-5) are those of the study's ENDO3D cases, on the Pareto front
    of ``masonry bench`` (docs/choices.md); the elastic case takes 1e-4 and the adaptive step
    size (``cases/wall_0.5MPa_elastic.yaml``).
    """

    time_step_s: Real = Field(4e-3, ge=1e-6, le=1.0, description="time step h (s)")
    theta: Real = Field(
        1.0, ge=0.5, le=1.0, description="theta of the theta-method (dimensionless, 0.5..1)"
    )
    method: Literal["auto", "newton", "nlgs"] = Field(
        "auto",
        description="contact solver: newton (semi-smooth Newton, sparse LU), nlgs (non-linear "
        "Gauss-Seidel), or auto: the faster for the case's blocks and joints (nlgs when every "
        "block is rigid and every joint rigid Signorini-Coulomb, newton otherwise)",
    )
    linear: Literal["auto", "lu", "pardiso", "krylov"] = Field(
        "auto",
        description="solver of the Newton matrix: lu (sparse LU, SuperLU), pardiso (sparse LU, "
        "Intel MKL's PARDISO: the same solutions, faster; needs the mkl package), krylov (GMRES "
        "with a two-level preconditioner over the blocks: each block's own matrix and the blocks "
        "as rigid bodies; docs/scaling.md), or auto: pardiso (lu without MKL) below 100,000 "
        "unknowns, krylov from there",
    )
    tolerance: Real = Field(
        3e-5,
        ge=1e-14,
        lt=1.0,
        description="convergence: relative change of the contact forces, and for newton the "
        "momentum residual against the contact impulses (dimensionless)",
    )
    max_iterations: Whole = Field(
        20000, ge=1, le=1_000_000_000,
        description="maximum iterations per step (count; Newton stops at 50, then the step is "
        "halved, and NLGS sweeps finish it at the smallest step size)",
    )
    check_every: Whole = Field(
        5, ge=1, le=1_000_000, description="NLGS sweeps between convergence checks (count)"
    )
    max_step_halvings: Whole = Field(
        3, ge=0, le=10,
        description="a step that does not converge is made again as two of h/2, nested at most "
        "this many times (count; 0: never, the step is kept as it is)",
    )
    halved_steps_after_failure: Whole = Field(
        0, ge=0, le=64,
        description="after a step made again as halves, the next this many steps are made as "
        "halves at once, without the attempt at h, twice as many each time the attempt after "
        "them fails again (count; 0: every step tries h first)",
    )
    max_time_step_s: Real | None = Field(
        None, gt=0.0, le=1.0,
        description="adaptive step size: the largest step (s); steps are time_step_s times 1, "
        "2, 4, ... up to it (at most 256), doubled after grow_after_steps easy steps and made "
        "again smaller when they fail (null: every step is time_step_s; docs/choices.md)",
    )
    grow_after_steps: Whole = Field(
        2, ge=1, le=1000,
        description="adaptive step size: easy steps in a row before the step doubles (count)",
    )
    easy_iterations: Whole = Field(
        4, ge=1, le=50,
        description="adaptive step size: a step is easy when Newton converged within this many "
        "iterations; one that needs more than twice as many halves the next (count)",
    )
    easy_damage: Real = Field(
        0.02, gt=0.0, le=1.0,
        description="adaptive step size: a step is easy only if no joint lost more than this of "
        "its integrity and no ENDO3D Gauss point gained more than this of damage in it; twice "
        "as much halves the next step (dimensionless)",
    )

    @property
    def max_growth(self) -> int:
        """``k`` of the largest step ``time_step_s 2^k`` not above ``max_time_step_s`` (0: no
        adaptive step size)."""
        if self.max_time_step_s is None:
            return 0
        return min(8, max(0, math.floor(math.log2(self.max_time_step_s / self.time_step_s)
                                        + 1e-9)))

    @model_validator(mode="after")
    def _check_iterations(self) -> Solver:
        problems: list[tuple[str, str]] = []
        if self.max_time_step_s is not None and \
                self.max_time_step_s < self.time_step_s * (1.0 - 1e-9):
            problems.append(("max_time_step_s", (
                f"got {self.max_time_step_s:g}; the largest step cannot be smaller than "
                f"time_step_s = {self.time_step_s:g} s")))
        if self.linear == "pardiso":
            from masonry_nscd.nscd import pardiso

            if not pardiso.available():
                problems.append(("linear", f"got pardiso; {pardiso.MISSING}"))
        if self.check_every > self.max_iterations:
            problems.append(
                (
                    "check_every",
                    (
                        f"got {self.check_every}; convergence would never be checked: it must not "
                        f"exceed max_iterations = {self.max_iterations}"
                    ),
                )
            )
        _problems(problems)
        return self


class Output(_Section):
    """What the run writes (the force-displacement CSV is always written, every step)."""

    every_steps: Whole = Field(
        5, ge=1, le=1_000_000_000, description="write fields every this many steps of "
        "solver.time_step_s (count; with adaptive steps, the largest step divides it)"
    )
    vtu: bool = Field(True, description="write VTU/PVD fields for ParaView (true/false)")
    hdf5: bool = Field(True, description="write results.h5 (true/false)")
    energy: bool = Field(
        True, description="compute the energy balance and write energy.csv (true/false)"
    )


# ---------------------------------------------------------------------------------------------
# Case
# ---------------------------------------------------------------------------------------------


class Case(_Section):
    """One simulation: a wall, its materials, supports, loading, solver settings and outputs.

    Every section has defaults (the reference study), so ``{}`` is a valid case.
    """

    name: str = Field(
        "case",
        min_length=1,
        max_length=200,
        description="name of the run, used for the output folder (default: the file's stem)",
    )
    description: str = Field("", max_length=10_000, description="free text")
    wall: Wall = Field(default_factory=Wall, description="geometry, bond and mesh")
    blocks: Blocks = Field(default_factory=Blocks, description="block material")
    joint: Joint = Field(default_factory=Joint, description="joint law")
    supports: Supports = Field(default_factory=Supports, description="supports of the top beam")
    loading: Loading = Field(default_factory=Loading, description="load stages")
    solver: Solver = Field(default_factory=Solver, description="time step and contact solver")
    output: Output = Field(default_factory=Output, description="outputs")
    arch: Arch | None = Field(
        None, description="an arch of voussoirs instead of the wall (null: the wall)"
    )
    vault: Vault | None = Field(
        None, description="a barrel vault instead of the wall (null: the wall or the arch)"
    )
    assembly: Assembly | None = Field(
        None, description="blocks from a mesh file instead of the wall (null: the wall)"
    )
    collapse: Collapse = Field(
        default_factory=Collapse, description="arch: when the run has collapsed"
    )

    @property
    def limit_state(self) -> Arch | Assembly | None:
        """The section of a limit-state case's builder: ``arch``, ``vault`` or ``assembly``
        (None: a wall)."""
        return self.arch_section if self.arch_section is not None else self.assembly

    @property
    def arch_section(self) -> Arch | None:
        """The arch of a limit-state case: ``arch``, or the section of a ``vault`` (None: a
        wall)."""
        return self.arch if self.arch is not None else self.vault

    @field_validator("name")
    @classmethod
    def _check_name(cls, value: str) -> str:
        if any(c in value for c in "/\\\x00") or value.strip() != value or value in (".", ".."):
            raise PydanticCustomError(
                "name_text",
                "a name is used as a folder name: no '/', '\\' or NUL character, no leading "
                "or trailing spaces, not '.' or '..'",
            )
        return value

    @property
    def vertical_force_N(self) -> float:
        """Vertical force on the top beam (N): sigma_N x wall length x thickness."""
        return (
            self.loading.vertical_stress.value_Pa
            * self.wall.wall_length_m
            * (self.wall.thickness_m)
        )

    @property
    def contact_solver(self) -> str:
        """The contact solver the run uses: ``solver.method``, or for ``auto`` the faster one
        measured for the case's blocks and joints (docs/performance.md, "Which solver"):
        Gauss-Seidel (``nlgs``) when every block is rigid and every joint rigid
        Signorini-Coulomb (``coulomb``), whose Delassus blocks are small and whose impulses
        are the unknowns of both solvers; Newton otherwise (a spring in series, deformable
        blocks; ENDO3D blocks need it)."""
        if self.solver.method != "auto":
            return self.solver.method
        if self.blocks.material == "rigid" and self.joint.law == "coulomb":
            return "nlgs"
        return "newton"

    @property
    def contact_point_rule(self) -> str:
        """Where the run puts the contact points: ``wall.contact_point_rule``, or for ``auto``
        Gauss-Lobatto points when the joints are rigid contacts (``coulomb``) and a face has 2
        or more per direction, Gauss points otherwise. On deformable blocks Lobatto points,
        made once where quads share them, are the face's nodes: one point per node, so the
        normal impulses that hold a face are unique, where 2 x 2 Gauss points per quad
        outnumber the nodes and let Newton's contact statuses cycle among equivalent
        impulses; on rigid blocks they put the rocking on the corners (docs/choices.md). An
        arch takes Lobatto points for every law: its joints hinge at their edges, and Gauss
        points would make a voussoir of one element 0.577 of its thickness thick."""
        w = self.limit_state if self.limit_state is not None else self.wall
        if w.contact_point_rule != "auto":
            return w.contact_point_rule
        if self.limit_state is not None:  # voussoirs hinge about the edges of their faces, any law
            return "lobatto" if w.contact_points_per_face >= 2 else "gauss"
        if self.joint.law == "coulomb" and w.contact_points_per_face >= 2:
            return "lobatto"
        return "gauss"

    @property
    def step_growth(self) -> int:
        """``k`` of the largest adaptive step ``time_step_s 2^k``: ``solver.max_growth``, lowered
        until ``2^k`` divides ``output.every_steps`` (the fields are written at the end of a
        step: a step of ``2^k h`` starts on a multiple of ``2^k h`` and never crosses one)."""
        k = self.solver.max_growth
        while self.output.every_steps % (1 << k):
            k -= 1
        return k

    @property
    def step_growth_note(self) -> str | None:
        """Why the adaptive step stops short of ``solver.max_time_step_s`` (:attr:`step_growth`
        below ``solver.max_growth``), for the run's log and ``masonry validate``; None when it
        does not."""
        k, asked = self.step_growth, self.solver.max_growth
        if k == asked:
            return None
        h, every = self.solver.time_step_s, self.output.every_steps
        grows = f"steps grow to {h * (1 << k):g} s only" if k else "every step is time_step_s"
        return (f"solver.max_time_step_s = {self.solver.max_time_step_s:g} s: {grows}, "
                f"because output.every_steps = {every} is not a multiple of {1 << (k + 1)} "
                f"(a multiple of {1 << asked} lets the steps grow to {h * (1 << asked):g} s)")

    @property
    def step_count(self) -> int:
        """Expected number of time steps, ``ceil(end_time_s / time_step_s)`` (an arch:
        ``collapse.end_time_s``)."""
        end = self.collapse.end_time_s if self.limit_state is not None \
            else self.loading.end_time_s
        return max(1, math.ceil(end / self.solver.time_step_s - 1e-9))

    @model_validator(mode="after")
    def _check_supports(self) -> Case:
        problems: list[tuple[str, str]] = []
        stress = self.loading.vertical_stress.value_Pa
        if self.solver.method == "nlgs" and self.blocks.material == "endo3d":
            problems.append(
                (
                    "solver.method",
                    (
                        "got 'nlgs' with blocks.material = 'endo3d'; ENDO3D enters the residual "
                        "of the Newton solver only: use method 'newton'"
                    ),
                )
            )
        clamped = self.supports.clamped_courses
        if clamped and 2 * clamped >= self.wall.courses:
            problems.append(("supports.clamped_courses", (
                f"got {clamped}; with {self.wall.courses} courses no course would be left "
                f"between the beams: at most {(self.wall.courses - 1) // 2}")))
        elif clamped:
            from masonry_nscd.scenes.layout import course_levels

            levels = course_levels(self.wall)
            free = (levels[clamped - 1][1], levels[-clamped][0])
            for i, op in enumerate(self.wall.openings):
                if op.y_m < free[0] - 1e-9 or op.y_m + op.height_m > free[1] + 1e-9:
                    problems.append((f"wall.openings[{i}]", (
                        f"reaches into a clamped course (the wall between the beams spans y = "
                        f"{free[0]:.6g} to {free[1]:.6g} m)")))
        problems += self._ground_motion_problems()
        problems += self._builder_problems()
        problems += self._joint_region_problems()
        if self.supports.top_vertical == "fixed" and stress != 0.0:
            problems.append(
                (
                    "supports.top_vertical",
                    (
                        f"got 'fixed' with loading.vertical_stress.value_Pa = {stress:.6g} "
                        "Pa; a top beam held in y cannot carry a vertical stress: use "
                        "top_vertical 'load' or set loading.vertical_stress.value_Pa to 0"
                    ),
                )
            )
        _problems(problems)
        return self


    def _joint_region_problems(self) -> list[tuple[str, str]]:
        """The courses of ``joint.regions`` against the wall's: each must have joints of the
        joint law of that kind (a bed joint on top of it, head joints in it) between the
        beams, not the glue and not inside a clamped course."""
        if self.limit_state is not None:
            return []  # an arch's case: the regions are refused as the wall's
        from masonry_nscd.scenes.layout import LayoutError, count_index

        n, k = self.wall.courses, self.supports.clamped_courses
        spans = {"bed": (k - 1 if k else 0, n - 1 - k if k else n - 2), "head": (k, n - 1 - k)}
        problems = []
        for i, region in enumerate(self.joint.regions):
            lo, hi = spans[region.joints]
            field = f"joint.regions[{i}].courses"
            for c in region.courses or []:
                try:
                    course = count_index(c, n, "courses", field)
                except LayoutError as exc:
                    problems.append((exc.field, exc.message))
                    continue
                if not lo <= course <= hi:
                    problems.append((field, (
                        f"got {c}; course {course + 1} has no {region.joints} joint of the "
                        f"joint law (glued or clamped): allowed courses {lo + 1} to {hi + 1}")))
        return problems

    def _ground_motion_problems(self) -> list[tuple[str, str]]:
        """The ground motion against the push, the top beam and the supports."""
        problems: list[tuple[str, str]] = []
        gm, hz, sup = self.loading.ground_motion, self.loading.horizontal, self.supports
        if gm is not None and hz.history != "none":
            problems.append(("loading.horizontal.history", (
                f"got '{hz.history}' with loading.ground_motion; under ground motion the base "
                "moves and the top beam is free in x, there is no horizontal push: set "
                "history: none")))
        if gm is None and hz.history == "none":
            problems.append(("loading.horizontal.history", (
                "got 'none' without loading.ground_motion; 'none' (no push) is for a ground "
                "motion: give loading.ground_motion, or a history monotonic, cyclic or table")))
        if sup.top_beam == "absent":
            if gm is None:
                problems.append(("supports.top_beam", (
                    "got 'absent' without loading.ground_motion; the push needs the top beam: "
                    "a wall without it is for a ground motion")))
            if self.loading.vertical_stress.value_Pa != 0.0:
                problems.append(("loading.vertical_stress.value_Pa", (
                    f"got {self.loading.vertical_stress.value_Pa:.6g} Pa with "
                    "supports.top_beam = 'absent'; no beam carries it: set 0")))
            if sup.clamped_courses:
                problems.append(("supports.clamped_courses", (
                    f"got {sup.clamped_courses} with supports.top_beam = 'absent'; must be 0 "
                    "(the wall stands glued on its base)")))
        elif gm is not None and sup.top_vertical != "load":
            problems.append(("supports.top_vertical", (
                f"got '{sup.top_vertical}' with loading.ground_motion; under ground motion the "
                "top beam carries the vertical stress and is otherwise free: use 'load' (or "
                "supports.top_beam: absent)")))
        return problems

    def _builder_problems(self) -> list[tuple[str, str]]:
        """The sections of the other builder given in the case (:data:`WALL_ONLY`,
        :data:`ARCH_ONLY`), both ``arch`` and ``vault``, and a point load on a block the arch
        or the vault does not have."""
        a = self.arch_section
        arch = self.limit_state is not None
        kind = ("a vault" if self.vault is not None else "an arch" if self.arch is not None
                else "an assembly")
        problems = [(path, f"given with {kind if arch else 'a wall'} case; it belongs to "
                     f"{'the wall' if arch else 'an arch'} (leave it out"
                     + ("" if arch else ", or give an arch: section") + ")")
                    for path in (WALL_ONLY if arch else ARCH_ONLY) if _given(self, path)]
        given = [k for k in ("arch", "vault", "assembly") if getattr(self, k) is not None]
        if len(given) > 1:
            problems.append((given[1], (f"given with {given[0]}; a case builds one structure: "
                                        "give one of arch, vault, assembly")))
            return problems
        if self.assembly is not None and self.loading.settlement is not None:
            problems.append(("loading.settlement", (
                "given with an assembly case; the settlement of a support is the arch's and "
                "the vault's (an assembly's supports are fixed)")))
        load = self.loading.point_load
        if a is not None and load is not None:
            if self.vault is not None:
                from masonry_nscd.scenes.vault import voussoir_names

                names = voussoir_names(self.vault)
                where = (f"ring 1 voussoir 1 to ring {self.vault.rings} voussoir "
                         f"{len(voussoir_names(self.vault, self.vault.rings))}")
            else:
                names = [f"voussoir {k}" for k in range(1, a.voussoirs + 1)]
                where = f"voussoir 1 to voussoir {a.voussoirs}"
            extra = a.abutments == "blocks"
            if extra:
                names += ["left abutment", "right abutment"]
            if load.block not in names:
                problems.append(("loading.point_load.block", (
                    f"got {load.block!r}; the blocks are {where} (from the left springing)"
                    + (", left abutment, right abutment" if extra else ""))))
        return problems

    def unused_sections(self) -> tuple[str, ...]:
        """The dotted paths of the sections the case's builder does not read (left out of the
        case written back)."""
        others = [k for k in ("arch", "vault", "assembly") if getattr(self, k) is None]
        return (*WALL_ONLY, *others) if self.limit_state is not None else ARCH_ONLY


# ---------------------------------------------------------------------------------------------
# YAML: a YAML 1.2 core-schema loader on top of PyYAML
# ---------------------------------------------------------------------------------------------

_TAG = "tag:yaml.org,2002:"

_RESOLVERS_1_2: list[tuple[str, re.Pattern[str], list[str | None]]] = [
    (_TAG + "null", re.compile(r"^(?:~|null|Null|NULL|)$"), ["~", "n", "N", ""]),
    (_TAG + "bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")),
    (
        _TAG + "int",
        re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"),
        list("-+0123456789"),
    ),
    (
        _TAG + "float",
        re.compile(
            r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
            r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
        ),
        list("-+0123456789."),
    ),
    (_TAG + "merge", re.compile(r"^(?:<<)$"), ["<"]),
]


class _CaseLoader(yaml.SafeLoader):
    """PyYAML's safe loader with the YAML 1.2 core schema for plain scalars and with duplicate
    keys refused."""

    yaml_implicit_resolvers: ClassVar[dict] = {}  # filled below, not inherited (YAML 1.1)

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, yaml.Node] = {}
            for key_node, _ in node.value:
                if key_node.tag == _TAG + "merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    hash(key)
                except TypeError:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping",
                        node.start_mark,
                        "found a key that is not a scalar (a list or a mapping)",
                        key_node.start_mark,
                    ) from None
                if key in seen:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping",
                        node.start_mark,
                        f"found duplicate key {key!r}",
                        key_node.start_mark,
                    )
                seen[key] = key_node
        return super().construct_mapping(node, deep=deep)


def _clip(text: str, size: int = 40) -> str:
    return repr(text) if len(text) <= size else repr(text[: size - 3] + "...")


def _construct_int(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> int:
    text = str(loader.construct_scalar(node)).strip()
    try:
        if text.lower().startswith("0o"):
            return int(text, 0)
        if text.lower().startswith("0x"):
            return int(text, 0)
        return int(text, 10)
    except ValueError:
        raise yaml.constructor.ConstructorError(
            None, None, f"{_clip(text)} is not an integer", node.start_mark
        ) from None


def _construct_float(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> float:
    text = str(loader.construct_scalar(node)).strip()
    low = text.lower()
    if low in (".inf", "+.inf"):
        return math.inf
    if low == "-.inf":
        return -math.inf
    if low == ".nan":
        return math.nan
    try:
        return float(text)
    except ValueError:
        raise yaml.constructor.ConstructorError(
            None, None, f"{_clip(text)} is not a number", node.start_mark
        ) from None


def _construct_bool(loader: yaml.SafeLoader, node: yaml.ScalarNode) -> bool:
    text = str(loader.construct_scalar(node)).strip().lower()
    if text in ("true", "false"):
        return text == "true"
    raise yaml.constructor.ConstructorError(
        None, None, f"{_clip(text)} is not true or false", node.start_mark
    )


for _tag, _regexp, _first in _RESOLVERS_1_2:
    _CaseLoader.add_implicit_resolver(_tag, _regexp, _first)
_CaseLoader.add_constructor(_TAG + "int", _construct_int)
_CaseLoader.add_constructor(_TAG + "float", _construct_float)
_CaseLoader.add_constructor(_TAG + "bool", _construct_bool)


class _CaseDumper(yaml.SafeDumper):
    """A dumper that quotes every string that either YAML 1.1 or YAML 1.2 would read as
    something else than a string, so that the output reads back the same with both."""

    yaml_implicit_resolvers: ClassVar[dict] = {}


for _first_char, _resolvers in yaml.SafeDumper.yaml_implicit_resolvers.items():
    _CaseDumper.yaml_implicit_resolvers[_first_char] = list(_resolvers)
for _tag, _regexp, _first in _RESOLVERS_1_2:
    _CaseDumper.add_implicit_resolver(_tag, _regexp, _first)


def read_yaml(text: str, source: str = "<text>") -> Any:
    """Parse YAML text as case files are read (YAML 1.2 core schema: ``0.3e6`` is a float,
    duplicate keys refused). Any problem becomes a :class:`CaseError` naming ``source`` and,
    for syntax errors, the line and column."""
    try:
        return yaml.load(text, Loader=_CaseLoader)  # a SafeLoader subclass
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        kind = "error" if isinstance(exc, yaml.constructor.ConstructorError) else "syntax error"
        what = str(exc.problem or exc.context or "invalid YAML")
        if exc.problem and exc.context:
            cmark = exc.context_mark
            what += f" ({exc.context}" + (f" at line {cmark.line + 1})" if cmark else ")")
        raise CaseError(f"{source}: YAML {kind}{where}: {what}") from None
    except yaml.YAMLError as exc:
        raise CaseError(f"{source}: cannot read the YAML: {exc}") from None
    except RecursionError:
        raise CaseError(f"{source}: the YAML is nested too deeply") from None
    except (ValueError, TypeError, AttributeError, OverflowError) as exc:
        # PyYAML's own constructors (e.g. !!timestamp with a bad value) can raise these
        raise CaseError(f"{source}: cannot read the YAML: {exc}") from None


# ---------------------------------------------------------------------------------------------
# Schema helpers (for messages and overrides)
# ---------------------------------------------------------------------------------------------

_UNIT_SUFFIXES = (
    ("_kg_m3", "kg/m^3"),
    ("_J_m2", "J/m^2"),
    ("_m_s2", "m/s^2"),
    ("_Pa_m", "Pa/m"),
    ("_m_s", "m/s"),
    ("_Pa", "Pa"),
    ("_kg", "kg"),
    ("_s", "s"),
    ("_m", "m"),
)


def _unit_of(name: str) -> str | None:
    for suffix, unit in _UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return None


def _is_model(annotation: Any) -> bool:
    return isinstance(annotation, type) and issubclass(annotation, BaseModel)


def _split_annotated(annotation: Any) -> tuple[Any, list[Any]]:
    """``Annotated[T, FieldInfo(...), ...]`` -> ``(T, metadata of the FieldInfo parts)``."""
    metadata: list[Any] = []
    if get_origin(annotation) is Annotated:
        base, *extras = get_args(annotation)
        for extra in extras:
            metadata.extend(getattr(extra, "metadata", [extra]))
        return base, metadata
    return annotation, metadata


def _fmt_bound(value: Any) -> str:
    if isinstance(value, float) and value == _SQRT3:
        return "sqrt(3)"
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


def _describe(annotation: Any, metadata: Sequence[Any], name: str = "") -> str:
    """What a field accepts, in words: 'a number, 0 <= value < 1', "one of 'a', 'b'", ..."""
    annotation, extra = _split_annotated(annotation)
    metadata = list(metadata) + extra
    if get_origin(annotation) is Literal:
        return "one of " + ", ".join(repr(a) for a in get_args(annotation))
    if annotation is bool:
        return "true or false"
    if annotation is str:
        return "text"
    if _is_model(annotation):
        return "a mapping with the keys " + ", ".join(annotation.model_fields)
    if get_origin(annotation) is tuple:
        args = get_args(annotation)
        return f"a list of {len(args)} items, each " + _describe(args[0], [])
    if annotation in (int, float):
        low = high = ""
        for m in metadata:
            if getattr(m, "gt", None) is not None:
                low = f"{_fmt_bound(m.gt)} < "
            if getattr(m, "ge", None) is not None:
                low = f"{_fmt_bound(m.ge)} <= "
            if getattr(m, "lt", None) is not None:
                high = f" < {_fmt_bound(m.lt)}"
            if getattr(m, "le", None) is not None:
                high = f" <= {_fmt_bound(m.le)}"
        text = "a whole number" if annotation is int else "a number"
        if low or high:
            text += f", {low}value{high}"
        unit = _unit_of(name)
        if unit:
            text += f" (in {unit})"
        return text
    return str(annotation)


def _lookup(loc: Sequence[Any]) -> tuple[Any, list[Any], str] | None:
    """The annotation, constraints and name of the schema node at ``loc`` (None if unknown)."""
    annotation: Any = Case
    metadata: list[Any] = []
    name = ""
    for part in loc:
        annotation, _ = _split_annotated(annotation)
        if _is_model(annotation):
            if not isinstance(part, str) or part not in annotation.model_fields:
                return None
            info = annotation.model_fields[part]
            annotation, metadata, name = info.annotation, list(info.metadata), part
        elif get_origin(annotation) is tuple and isinstance(part, int):
            args = get_args(annotation)
            if not 0 <= part < len(args):
                return None
            annotation, metadata = args[part], []
        else:
            return None
    return annotation, metadata, name


def _path(loc: Sequence[Any]) -> str:
    text = ""
    for part in loc:
        if isinstance(part, int) and not isinstance(part, bool):
            text += f"[{part}]"
        else:
            text += ("." if text else "") + str(part)
    return text


def _show(value: Any) -> str:
    """A short rendering of a value given by the user."""
    text = repr(value)
    if len(text) > 60:
        text = text[:57] + "..."
    if value is None:
        return "null (no value)"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, Mapping):
        return "a mapping " + text
    if isinstance(value, (list, tuple)):
        return "a list " + text
    return text


def _allowed_keys(loc: Sequence[Any]) -> list[str]:
    node = _lookup(loc)
    if node is None:
        return []
    annotation, _ = _split_annotated(node[0])
    return list(annotation.model_fields) if _is_model(annotation) else []


def _suggest(key: Any, allowed: Sequence[str]) -> str:
    close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


_RANGE_ERRORS = frozenset(
    {"greater_than", "greater_than_equal", "less_than", "less_than_equal", "finite_number"}
)


def _messages(error: ValidationError, prefix: Sequence[Any] = ()) -> list[str]:
    """Readable messages from a pydantic error: field path, value given, what is allowed."""
    messages: list[str] = []
    for err in error.errors():
        loc = tuple(prefix) + tuple(err.get("loc", ()))
        kind = err.get("type", "")
        value = err.get("input")
        ctx = err.get("ctx") or {}
        if kind == "case_consistency":
            for field, text in ctx.get("problems", []):
                messages.append(f"{_path(loc + (field,))}: {text}")
            continue
        if kind in ("extra_forbidden", "invalid_key"):
            parent, key = loc[:-1], (loc[-1] if loc else "?")
            allowed = _allowed_keys(parent)
            where = _path(parent) or "the top level"
            if kind == "extra_forbidden":
                what, shown = "unknown field", _path(loc)
            else:
                what, shown = (
                    "a key must be text",
                    ".".join(filter(None, [_path(parent), repr(value)])),
                )
            messages.append(
                f"{shown}: {what}{_suggest(key, allowed)}; the keys allowed in {where} "
                f"are: {', '.join(allowed)}"
            )
            continue
        node = _lookup(loc)
        allowed = _describe(*node) if node is not None else ""
        if kind in _RANGE_ERRORS and allowed:
            reason = "out of range"
        elif kind == "literal_error" and allowed:
            reason = "not a valid choice"
        else:
            reason = str(err.get("msg", "invalid value"))
            reason = reason[:1].lower() + reason[1:]
        text = f"{_path(loc) or 'the case'}: got {_show(value)}; {reason}"
        if allowed:
            text += f"; allowed: {allowed}"
        messages.append(text)
    return messages or [str(error)]


# ---------------------------------------------------------------------------------------------
# Public functions
# ---------------------------------------------------------------------------------------------


def case_from_dict(data: Any, *, case_dir: str | Path | None = None,
                   check_files: bool = False) -> Case:
    """Validate a mapping (as read from a case file) into a :class:`Case`.

    ``case_dir``: the folder relative paths of the case (``loading.horizontal.file``) are
    read from, and made absolute with (None: left as they are, i.e. relative to the working
    folder). ``check_files``: read the files the case names and refuse one that cannot be
    used. Raises :class:`CaseError` with one message per problem.
    """
    if not isinstance(data, Mapping):
        raise CaseError(
            f"the case: got {_show(data)}; a case must be a mapping with the keys "
            + ", ".join(Case.model_fields)
        )
    try:
        return Case.model_validate(dict(data), context={"case_dir": case_dir,
                                                        "check_files": check_files})
    except ValidationError as exc:
        raise CaseError(_messages(exc)) from None
    except RecursionError:
        raise CaseError(
            "the case: the data is nested too deeply (a recursive YAML alias?)"
        ) from None


_PART = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


def _list_item(annotation: Any) -> Any | None:
    """The item type of a list field (``list[T]``, ``list[T] | None``), or None."""
    annotation, _ = _split_annotated(annotation)
    options = get_args(annotation) if get_origin(annotation) in (Union, UnionType) \
        else (annotation,)
    for option in options:
        option, _ = _split_annotated(option)
        if get_origin(option) is list:
            return get_args(option)[0]
    return None


def _as_model(annotation: Any) -> Any:
    """A section type, or the section among the options of a union (``list[float] | Course``)."""
    annotation, _ = _split_annotated(annotation)
    if get_origin(annotation) in (Union, UnionType):
        models = [a for a in get_args(annotation) if _is_model(_split_annotated(a)[0])]
        if models:
            return _split_annotated(models[0])[0]
    return annotation


def _apply_override(data: dict, override: str) -> None:
    """Apply one ``dotted.path=value`` override to raw case data (in place); a part may index a
    list (``wall.openings[0].x_m``)."""
    if not isinstance(override, str) or "=" not in override:
        raise CaseError(
            f"--set {override}: an override must be PATH=VALUE, e.g. joint.mu=0.5 or "
            "wall.elements_per_unit=[1,1,1]"
        )
    path_text, value_text = override.split("=", 1)
    parts = [p.strip() for p in path_text.strip().split(".")]
    if not path_text.strip() or any(not p for p in parts):
        raise CaseError(f"--set {override}: the path before '=' is empty or has an empty part")
    steps: list[tuple[str, int | None]] = []
    annotation: Any = Case
    for i, part in enumerate(parts):
        annotation = _as_model(annotation)
        here = ".".join(parts[:i]) or "the top level"
        if not _is_model(annotation):
            raise CaseError(
                f"--set {override}: {'.'.join(parts[:i])} is a value, not a section; it has "
                f"no key '{part}'"
            )
        m = _PART.match(part)
        key, index = (m.group(1), m.group(2)) if m else (part, None)
        fields = annotation.model_fields
        if key not in fields:
            raise CaseError(
                f"--set {override}: unknown path {'.'.join(parts[: i + 1])}"
                f"{_suggest(key, list(fields))}; the keys allowed in {here} are: "
                + ", ".join(fields)
            )
        annotation = fields[key].annotation
        if index is not None:
            item = _list_item(annotation)
            if item is None:
                raise CaseError(f"--set {override}: {'.'.join(parts[:i] + [key])} is not a "
                                "list: it takes no [index]")
            annotation = item
        steps.append((key, None if index is None else int(index)))
    if annotation is str:
        value: Any = value_text  # text fields take the text as given
    else:
        value = read_yaml(value_text, f"--set {override}")
    target: Any = data
    for i, (key, index) in enumerate(steps):
        last = i == len(steps) - 1
        where = ".".join(parts[: i + 1])
        if index is None:
            if last:
                target[key] = value
                return
            child = target.get(key)
            if child is None:
                child = target[key] = {}
        else:
            items = target.get(key)
            if not isinstance(items, list) or not index < len(items):
                count = len(items) if isinstance(items, list) else 0
                raise CaseError(f"--set {override}: {'.'.join(parts[:i] + [key])} has {count} "
                                f"item{'s' if count != 1 else ''} in the case file: no [{index}]")
            if last:
                items[index] = value
                return
            child = items[index]
        if not isinstance(child, dict):
            raise CaseError(
                f"--set {override}: {where} in the case file is {_show(child)}, not a mapping"
            )
        target = child


def load_case(path: str | Path, overrides: Sequence[str] = (), *,
              check_files: bool = True) -> Case:
    """Read, override and validate a case file.

    A relative path in the case (``loading.horizontal.file``) is relative to the case file's
    folder and made absolute; with ``check_files`` (the default) the file is read and checked
    (the summary and the plots of a run folder pass False: they do not need it).

    ``overrides`` are ``dotted.path=value`` strings (the CLI's ``--set``), applied in order; the
    value is parsed as YAML (``0.3e6`` is a float, ``[2,2,1]`` a list, ``true`` a boolean; a
    text field such as ``name`` takes the text as given) and the path must exist in the schema.
    ``name`` defaults to the file's stem. Raises :class:`CaseError` for every problem.
    """
    path = Path(path)
    source = str(path)
    if not path.exists():
        raise CaseError(f"{source}: case file not found")
    if path.is_dir():
        raise CaseError(f"{source}: is a directory, not a case file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise CaseError(
            f"{source}: not a UTF-8 text file ({exc.reason} at byte {exc.start})"
        ) from None
    except OSError as exc:
        raise CaseError(f"{source}: cannot read the file: {exc.strerror or exc}") from None
    data = read_yaml(text, source)
    if data is None:
        raise CaseError(
            f"{source}: the file is empty; a case file is a mapping (use '{{}}' for all defaults)"
        )
    if not isinstance(data, dict):
        raise CaseError(
            f"{source}: the top level must be a mapping with the keys "
            f"{', '.join(Case.model_fields)}; got {_show(data)}"
        )
    data = copy.deepcopy(data) if overrides else data
    for override in overrides:
        _apply_override(data, override)
    data.setdefault("name", path.stem)
    return case_from_dict(data, case_dir=path.parent, check_files=check_files)


# ---------------------------------------------------------------------------------------------
# Writing
# ---------------------------------------------------------------------------------------------


def _format_float(x: float) -> str:
    """The shortest text that reads back as the same float in YAML 1.1 and 1.2."""
    if math.isnan(x):
        return ".nan"
    if math.isinf(x):
        return ".inf" if x > 0 else "-.inf"
    if x == 0.0 or 1e-3 <= abs(x) < 1e4:
        text = repr(x)
        if "e" not in text:
            return text
    for digits in range(18):
        text = f"{x:.{digits}e}"
        if float(text) == x:
            break
    mantissa, exponent = text.split("e")
    if "." not in mantissa:
        mantissa += ".0"
    sign = exponent[0]
    return f"{mantissa}e{sign}{exponent[1:].lstrip('0') or '0'}"


def _reads_back(text: str, value: Any) -> bool:
    """Whether ``text`` reads back as ``value`` with this module's reader and with PyYAML's."""
    try:
        return read_yaml(text) == value and yaml.safe_load(text) == value
    except (CaseError, yaml.YAMLError):
        return False


def _format_scalar(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return _format_float(value)
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_format_scalar(v) for v in value) + "]"
    if isinstance(value, BaseModel):  # in a list (openings, pattern courses): a flow mapping
        quiet = getattr(type(value), "OMIT_NULL", ())  # null there: "the case's", left out
        return "{" + ", ".join(f"{k}: {_format_scalar(getattr(value, k))}"
                               for k in type(value).model_fields
                               if not (k in quiet and getattr(value, k) is None)) + "}"
    text = yaml.dump(
        value, Dumper=_CaseDumper, width=float("inf"), allow_unicode=True, explicit_end=False
    )
    text = text.removesuffix("\n").removesuffix("\n...").removesuffix("...")
    if "\n" in text or not _reads_back(text, value):
        text = yaml.dump(
            value, Dumper=_CaseDumper, width=float("inf"), allow_unicode=True, default_style='"'
        ).strip()
    return text


def _emit(model: BaseModel, indent: int, lines: list[str], comments: bool,
          skip: Sequence[str] = (), prefix: str = "") -> None:
    pad = "  " * indent
    for name, info in type(model).model_fields.items():
        if f"{prefix}{name}" in skip:
            continue
        value = getattr(model, name)
        comment = f"  # {info.description}" if comments and info.description else ""
        if isinstance(value, BaseModel):
            lines.append(f"{pad}{name}:{comment}")
            _emit(value, indent + 1, lines, comments, skip, f"{prefix}{name}.")
        else:
            lines.append(f"{pad}{name}: {_format_scalar(value)}{comment}")


def case_to_yaml(case: Case, *, comments: bool = True) -> str:
    """The full case as YAML, every default filled in, in schema order.

    Floats are written so that they read back as floats with any YAML reader (``1.1e+10``,
    ``0.3``); with ``comments`` each line carries the field's description and unit.
    ``load_case`` of the text gives back an equal :class:`Case`.
    """
    lines = ["# masonry_nscd case file; SI units (m, Pa, N, J, s, kg)"] if comments else []
    _emit(case, 0, lines, comments, case.unused_sections())
    return "\n".join(lines) + "\n"
