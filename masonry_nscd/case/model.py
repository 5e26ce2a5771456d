"""The case: one simulation, its sections validated together.

The case model is made from its common sections and the sections of the structures a case can
build (``structures/``), in a fixed order: ``name``, ``description``, the default structure's
section (``wall``), ``blocks``, ``joint``, ``supports``, ``loading``, ``solver``, ``output``,
the other structures' sections (``arch``, ``vault``, ``assembly``, by their order), ``collapse``.
That order is the order of the case written back (``case_to_yaml``) and of the keys listed in
messages. Every section has defaults (the reference study), so ``{}`` is a valid case: the
default structure's section is always there, the others are null unless given.
"""

from __future__ import annotations

import math
from typing import Any

from pydantic import Field, create_model, field_validator, model_validator
from pydantic_core import PydanticCustomError

from masonry_nscd.case import solver as policy
from masonry_nscd.case.blocks import Blocks
from masonry_nscd.case.collapse import Collapse
from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Section, given
from masonry_nscd.case.joint import Joint
from masonry_nscd.case.loading import Loading
from masonry_nscd.case.output import Output
from masonry_nscd.case.solver import Solver
from masonry_nscd.case.structures import Structure, structures
from masonry_nscd.case.structures.wall import Supports


class CaseBase(Section):
    """One simulation: a structure (a wall by default), its materials, supports, loading,
    solver settings and outputs; the properties and checks of :data:`Case`, whose fields are
    made in ``_case_fields``."""

    @property
    def structure(self) -> Structure:
        """The structure the case builds: the first (by order) whose section is given, the
        default one (the wall) when none is."""
        for s in structures()[1:]:
            if getattr(self, s.name) is not None:
                return s
        return structures()[0]

    @property
    def structure_section(self) -> Any:
        """The section of the case's structure (``case.wall``, ``case.arch``, ...)."""
        return getattr(self, self.structure.name)

    @property
    def limit_state(self) -> Any:
        """The section of a limit-state case's structure (an arch, a vault, an assembly);
        None for a wall."""
        return self.structure_section if self.structure.limit_state else None

    @field_validator("name", check_fields=False)
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
    def contact_solver(self) -> str:
        """The contact solver the run uses (``case/solver.py``, :func:`contact_solver`)."""
        return policy.contact_solver(self)

    @property
    def contact_point_rule(self) -> str:
        """Where the run puts the contact points (``case/solver.py``,
        :func:`contact_point_rule`)."""
        return policy.contact_point_rule(self)

    @property
    def step_growth(self) -> int:
        """``k`` of the largest adaptive step (``case/solver.py``, :func:`step_growth`)."""
        return policy.step_growth(self)

    @property
    def step_growth_note(self) -> str | None:
        """Why the adaptive step stops short of ``solver.max_time_step_s``, or None
        (``case/solver.py``, :func:`step_growth_note`)."""
        return policy.step_growth_note(self)

    @property
    def step_count(self) -> int:
        """Expected number of time steps, ``ceil(end_time_s / time_step_s)`` (a limit state:
        ``collapse.end_time_s``)."""
        end = self.collapse.end_time_s if self.structure.limit_state \
            else self.loading.end_time_s
        return max(1, math.ceil(end / self.solver.time_step_s - 1e-9))

    @model_validator(mode="after")
    def _check_case(self) -> CaseBase:
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
        problems += self._ground_motion_problems()
        problems += self._structure_problems()
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

    def _structure_problems(self) -> list[tuple[str, str]]:
        """The parts of the case owned by other structures that are given (``structures/``),
        the sections of two structures, and the problems of the case's own structure."""
        own = self.structure
        others = [s for s in structures() if s is not own]
        chosen = {s.name for s in structures()[1:]}  # given, they name the structure: below
        problems = []
        for path in dict.fromkeys(p for s in others for p in s.owns if p not in own.owns):
            if path in chosen or not given(self, path):
                continue
            owner = next(s for s in others if path in s.owns)
            problems.append((path, (
                f"given with {own.article} case; it belongs to "
                f"{'the wall' if owner.default else owner.article} (leave it out"
                + (f", or give {owner.article}: section" if own.default else "") + ")")))
        named = [s.name for s in structures()[1:] if getattr(self, s.name) is not None]
        if len(named) > 1:
            problems.append((named[1], (
                f"given with {named[0]}; a case builds one structure: give one of "
                + ", ".join(s.name for s in structures()[1:]))))
            return problems
        return problems + own.checks(self)

    def unused_sections(self) -> tuple[str, ...]:
        """The dotted paths of the case that its structure does not read (left out of the case
        written back): those owned by the other structures only."""
        own = self.structure
        return tuple(dict.fromkeys(p for s in structures() if s is not own for p in s.owns
                                   if p not in own.owns))


def _case_fields() -> dict[str, tuple[Any, Any]]:
    """The fields of :data:`Case`, in the order of the module docstring."""
    default, *others = structures()
    common = {
        "name": (str, Field("case", min_length=1, max_length=200, description="name of the run, "
                            "used for the output folder (default: the file's stem)")),
        "description": (str, Field("", max_length=10_000, description="free text")),
        default.name: (default.model, Field(default_factory=default.model,
                                            description=default.description)),
        "blocks": (Blocks, Field(default_factory=Blocks, description="block material")),
        "joint": (Joint, Field(default_factory=Joint, description="joint law")),
        "supports": (Supports, Field(default_factory=Supports,
                                     description="supports of the top beam")),
        "loading": (Loading, Field(default_factory=Loading, description="load stages")),
        "solver": (Solver, Field(default_factory=Solver,
                                 description="time step and contact solver")),
        "output": (Output, Field(default_factory=Output, description="outputs")),
    }
    for s in others:
        common[s.name] = (s.model | None, Field(None, description=s.description))
    common["collapse"] = (Collapse, Field(default_factory=Collapse,
                                          description="limit states: when the run has collapsed"))
    return common


#: The case model: :class:`CaseBase` with the fields of ``_case_fields``.
Case = create_model("Case", __base__=CaseBase, __module__=__name__, **_case_fields())
Case.__doc__ = CaseBase.__doc__
