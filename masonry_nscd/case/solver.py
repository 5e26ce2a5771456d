"""The time step and the contact and linear solvers."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from masonry_nscd.case.errors import raise_problems
from masonry_nscd.case.fields import Real, Section, Whole


class Solver(Section):
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
    petsc_options: str = Field(
        "",
        max_length=2000,
        description="PETSc's options for the Krylov solve on several processes (masonry run "
        "--processes P), over the defaults, e.g. '-pc_type asm -sub_pc_type ilu'; the command "
        "line's --petsc-options go over these; unused on one process (docs/guide/solvers.md)",
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
    kinetic_damping: bool = Field(
        False,
        description="Cundall's kinetic damping: every free velocity set to zero after a step "
        "in which the blocks' kinetic energy fell; the run then asks which loads the structure "
        "carries at rest, without the momentum a dynamic run builds (a static solution by "
        "dynamic relaxation). On an assembly of many loose stones every rattle that ends resets "
        "a mechanism too: read the summary's creep_at_end before calling a held run standing "
        "(docs/guide/limit_states.md)",
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
        raise_problems(problems)
        return self


# The solver policy: what the run uses where the case leaves the choice to it (``auto``), and
# how far the adaptive step grows. Functions of the whole case, read by ``Case``'s properties.


def contact_solver(case) -> str:
    """The contact solver the run uses: ``solver.method``, or for ``auto`` the faster one
    measured for the case's blocks and joints (docs/performance.md, "Which solver"):
    Gauss-Seidel (``nlgs``) when every block is rigid and every joint rigid Signorini-Coulomb
    (``coulomb``), whose Delassus blocks are small and whose impulses are the unknowns of both
    solvers; Newton otherwise (a spring in series, deformable blocks; ENDO3D blocks need
    it)."""
    if case.solver.method != "auto":
        return case.solver.method
    if case.blocks.material == "rigid" and case.joint.law == "coulomb":
        return "nlgs"
    return "newton"


def contact_point_rule(case) -> str:
    """Where the run puts the contact points: the structure's ``contact_point_rule``, or for
    ``auto`` Gauss-Lobatto points when the joints are rigid contacts (``coulomb``) and a face
    has 2 or more per direction, Gauss points otherwise. On deformable blocks Lobatto points,
    made once where quads share them, are the face's nodes: one point per node, so the normal
    impulses that hold a face are unique, where 2 x 2 Gauss points per quad outnumber the
    nodes and let Newton's contact statuses cycle among equivalent impulses; on rigid blocks
    they put the rocking on the corners (docs/choices.md). A limit-state structure (an arch, a
    vault, an assembly) takes Lobatto points for every law: its joints hinge at their edges,
    and Gauss points would make a voussoir of one element 0.577 of its thickness thick."""
    w = case.structure_section
    if w.contact_point_rule != "auto":
        return w.contact_point_rule
    if case.structure.limit_state:  # blocks hinge about the edges of their faces, any law
        return "lobatto" if w.contact_points_per_face >= 2 else "gauss"
    if case.joint.law == "coulomb" and w.contact_points_per_face >= 2:
        return "lobatto"
    return "gauss"


def step_growth(case) -> int:
    """``k`` of the largest adaptive step ``time_step_s 2^k``: ``solver.max_growth``, lowered
    until ``2^k`` divides ``output.every_steps`` (the fields are written at the end of a step:
    a step of ``2^k h`` starts on a multiple of ``2^k h`` and never crosses one)."""
    k = case.solver.max_growth
    while case.output.every_steps % (1 << k):
        k -= 1
    return k


def step_growth_note(case) -> str | None:
    """Why the adaptive step stops short of ``solver.max_time_step_s`` (:func:`step_growth`
    below ``solver.max_growth``), for the run's log and ``masonry validate``; None when it
    does not."""
    k, asked = step_growth(case), case.solver.max_growth
    if k == asked:
        return None
    h, every = case.solver.time_step_s, case.output.every_steps
    grows = f"steps grow to {h * (1 << k):g} s only" if k else "every step is time_step_s"
    return (f"solver.max_time_step_s = {case.solver.max_time_step_s:g} s: {grows}, "
            f"because output.every_steps = {every} is not a multiple of {1 << (k + 1)} "
            f"(a multiple of {1 << asked} lets the steps grow to {h * (1 << asked):g} s)")
