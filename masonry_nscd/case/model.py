"""The case: one simulation, its sections validated together."""

from __future__ import annotations

import math

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from masonry_nscd.case.blocks import Blocks
from masonry_nscd.case.collapse import Collapse
from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Section, given
from masonry_nscd.case.joint import Joint
from masonry_nscd.case.loading import Loading
from masonry_nscd.case.output import Output
from masonry_nscd.case.solver import Solver
from masonry_nscd.case.structures.arch import Arch
from masonry_nscd.case.structures.assembly import Assembly
from masonry_nscd.case.structures.vault import Vault
from masonry_nscd.case.structures.wall import Supports, Wall

WALL_ONLY = ("wall", "supports", "loading.vertical_stress", "loading.horizontal",
             "joint.regions")
ARCH_ONLY = ("arch", "vault", "assembly", "collapse", "loading.body_force", "loading.point_load",
             "loading.settlement")


class Case(Section):
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
        raise_problems(problems)
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
                    for path in (WALL_ONLY if arch else ARCH_ONLY) if given(self, path)]
        named = [k for k in ("arch", "vault", "assembly") if getattr(self, k) is not None]
        if len(named) > 1:
            problems.append((named[1], (f"given with {named[0]}; a case builds one structure: "
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
