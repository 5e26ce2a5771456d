r"""The scene: a block assembly with its loads, supports and stages, ready to step.

A builder (:mod:`masonry_nscd.scenes.wall`, the small scenes) declares everything the run loop,
the recorders, the summary and the plots need, so that none of them knows what was built:

* the bodies and the contact points, each point in a named joint group (``bed``, ``head``,
  ``glue_bottom``...);
* the structure: the bodies drawn and reported (the units), each with a name and the builder's
  place keys (``course``, ``position_in_course``, ...);
* the driven body, whose reference point's displacement is the curve's ``U_x``, ``U_y`` unless
  the builder says what else is measured (``measured``: weighted sums of dofs, e.g. under
  ground motion the drift, the top beam's point or the top course's centre of mass relative
  to the moving base), and the bodies whose forces on the structure are reported as ``F_x``,
  ``F_y`` (``top``; none when there is no top beam: zero) and ``F_x,bottom``, ``F_y,bottom``
  (``bottom``);
* the load stages (name, start time) and the stage whose force-displacement curve the summary
  reads; dofs held from a time on (``Hold``: the top beam held in y once the vertical load is
  on); the stop rule (:meth:`Scene.finished`): the driven displacement reaching ``target_m``
  (a monotonic push), or the time reaching ``time_limit_s`` (the end of a cyclic or tabulated
  history, where ``target_m`` is None; a guard for a push); the driven history (kind, end,
  cycles: what the summary needs to cut the curve into cycles);
* the solver settings, and per-point data to write out (the drawn joint properties of
  ``joint.scatter``).

A held dof changes the system (its velocity becomes imposed), and so does the removal of blocks
(``removal``, :mod:`masonry_nscd.scenes.removal`), so :meth:`Scene.integrator` builds the
integrator of the phase a step starts in; the run loop moves the state into a new one when a
hold or the removal begins (:meth:`Scene.next_integrator`). :meth:`Scene.info` is what the run folder keeps of the
scene (``scene.json``) for the summary and the plots.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from masonry_nscd.contact.laws import KIND_JOINT
from masonry_nscd.loading import Loads, at_rest
from masonry_nscd.model import ContactPoint, RigidBody
from masonry_nscd.nscd.checkpoint import integrator_state, restore_integrator
from masonry_nscd.nscd.integrator import Integrator
from masonry_nscd.scenes.removal import Removal

DOF_NAMES = ("x", "y", "z", "rot_x", "rot_y", "rot_z")
SCENE_FORMAT = "masonry_nscd.scene"


@dataclass(frozen=True)
class Stage:
    """A load stage: its name and start time (s)."""

    name: str
    start_s: float


@dataclass(frozen=True)
class Hold:
    """A dof of a rigid body held still (imposed zero velocity) for every step that ends after
    ``from_s`` (s)."""

    body: int
    dof: int
    from_s: float


@dataclass(frozen=True)
class SolverSettings:
    """How the steps are solved (``nscd.integrator.Integrator``'s arguments)."""

    h: float  # s
    theta: float = 1.0
    tolerance: float = 1e-6
    max_iterations: int = 20000
    check_every: int = 5
    method: str = "newton"
    max_halvings: int = 0
    halve_after_failure: int = 0
    endo3d_params: np.ndarray | None = None
    endo3d_tau: float = 0.0  # s
    energy: bool = True  # keep the energy balance (nscd/energy.py)
    max_growth: int = 0  # adaptive step size: steps up to h 2^max_growth (nscd/step_size.py)
    grow_after: int = 2
    easy_iterations: int = 4
    easy_damage: float = 0.02
    linear: str = "lu"  # the Newton matrix's solver: auto, lu, krylov (nscd/linear.py)
    kinetic_damping: bool = False  # velocities to zero after a step whose kinetic energy fell

    @classmethod
    def from_case(cls, case, endo3d_params: np.ndarray | None = None) -> SolverSettings:
        """The settings of ``case`` (its ``solver`` section, the contact solver it resolves to,
        the ENDO3D relaxation time and whether the energy balance is kept)."""
        sol = case.solver
        return cls(h=sol.time_step_s, theta=sol.theta, tolerance=sol.tolerance,
                   max_iterations=sol.max_iterations, check_every=sol.check_every,
                   method=case.contact_solver, max_halvings=sol.max_step_halvings,
                   halve_after_failure=sol.halved_steps_after_failure,
                   endo3d_params=endo3d_params,
                   endo3d_tau=case.blocks.endo3d.relaxation_time_s,
                   energy=case.output.energy, max_growth=case.step_growth,
                   grow_after=sol.grow_after_steps, easy_iterations=sol.easy_iterations,
                   easy_damage=sol.easy_damage, linear=sol.linear,
                   kinetic_damping=sol.kinetic_damping)


@dataclass(frozen=True)
class LoadFactor:
    """A load whose value at collapse is reported: ``name`` (a CSV column and a key of the
    summary), its unit, ``value(t)`` and what it is."""

    name: str
    unit: str
    value: Callable[[float], float]
    description: str = ""


@dataclass
class CollapseRule:
    """What a scene calls a collapse (module docstring; ``collapse`` section of the case)."""

    displacement_m: float
    velocity_m_s: float | None = None
    onset_velocity_m_s: float = 1e-3
    onset_kinetic_energy_J: float | None = None
    hinge_opening_m: float = 1e-4
    after_s: float = 0.0
    factors: list[LoadFactor] = field(default_factory=list)

    def info(self) -> dict[str, Any]:
        return {"displacement_m": self.displacement_m, "velocity_m_s": self.velocity_m_s,
                "onset_velocity_m_s": self.onset_velocity_m_s,
                "onset_kinetic_energy_J": self.onset_kinetic_energy_J,
                "hinge_opening_m": self.hinge_opening_m, "after_s": self.after_s,
                "load_factors": [{"name": f.name, "unit": f.unit, "description": f.description}
                                 for f in self.factors]}


@dataclass
class Scene:
    """A block assembly ready to step, and what the recorders and the post read of it."""

    name: str
    bodies: list
    points: list[ContactPoint]
    groups: tuple[str, ...]  # joint group id -> name
    params: np.ndarray  # joint-law parameter table, one row per law
    loads: Loads
    solver: SolverSettings
    structure: list[int]  # bodies drawn and reported, in output order
    body_info: list[dict[str, Any]]  # per structure body: "name" and the builder's place keys
    driven: int  # body whose reference point moves by (U_x, U_y)
    # "top", "bottom" -> body (or bodies: their sum) whose force on the others is reported
    reactions: dict[str, int | tuple[int, ...]]
    stages: list[Stage]
    push_stage: str  # the stage whose F_x - U_x curve is summarised
    target_m: float | None  # the run stops when U_x reaches it (m; None: on time only)
    expected_end_s: float  # when the target should be reached (s; progress and step count)
    time_limit_s: float  # the run stops at this time in any case (s)
    holds: list[Hold] = field(default_factory=list)
    history: dict[str, Any] = field(default_factory=lambda: {"kind": "monotonic"})
    # windows (start, end) (s) in which the driven velocity turns (a cyclic or tabulated
    # path's corners): adaptive steps are of h there (``step_limit_s``)
    turns_s: tuple[tuple[float, float], ...] = ()
    builder: str = ""
    # what the run log's first line says of the scene after its blocks' material (the wall:
    # its vertical stress; "": the builder's name)
    label: str = ""
    point_fields: dict[str, np.ndarray] = field(default_factory=dict)  # per point, written out
    meta: dict[str, Any] = field(default_factory=dict)  # builder's values for the summary
    # (dofs, weights) of U_x and of U_y, global dofs (None: the driven body's reference point)
    measured: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None = None
    collapse: CollapseRule | None = None  # a limit-state scene's (None: no watch)
    removal: Removal | None = None  # blocks taken out, each group at its time (scenes/removal.py)

    # --- what changes with time -----------------------------------------------------------
    def stage_at(self, t: float) -> str:
        """Name of the load stage at time ``t`` (s): the last one started at or before it."""
        name = self.stages[0].name
        for st in self.stages:
            if t >= st.start_s:
                name = st.name
        return name

    def finished(self, ux: float, t: float) -> bool:
        """The stop rule after a step ending at ``t`` (s) with the driven displacement ``ux``
        (m): ``ux >= target_m`` when there is a target (within a billionth of it: the driven
        point is on its path to round-off, and its path reaches the target at the expected
        end), or ``t >= time_limit_s`` (within a millionth of a step, for the time summed step
        by step)."""
        if self.target_m is not None and ux >= self.target_m - 1e-9 * abs(self.target_m):
            return True
        return t >= self.time_limit_s - 1e-6 * self.solver.h

    def holds_at(self, t: float) -> tuple[Hold, ...]:
        """The holds active in a step that starts at ``t`` (s) (it ends after ``from_s``)."""
        h = self.solver.h
        return tuple(hd for hd in self.holds if t + h > hd.from_s + 1e-12 * h)

    def holds_change(self, t_before: float, t_after: float) -> bool:
        """Whether the step starting at ``t_after`` has other holds than the one at
        ``t_before``."""
        return self.holds_at(t_before) != self.holds_at(t_after)

    def removed_at(self, t: float) -> int:
        """How many of the removal's groups are out in a step that starts at ``t`` (s): 0
        before the first one's time (or without a removal), then the first ones."""
        return 0 if self.removal is None else self.removal.out_at(t, self.solver.h)

    def removed_bodies(self, t: float) -> tuple[int, ...]:
        """The bodies out of the model in a step that starts at ``t`` (s)."""
        return () if self.removal is None else self.removal.bodies_at(t, self.solver.h)

    def phase_at(self, t: float) -> tuple:
        """What makes the system of a step starting at ``t`` (s): its holds and how many groups
        of removed blocks are out. A step in another phase than the last one needs a new
        integrator (:meth:`next_integrator`)."""
        return self.holds_at(t), self.removed_at(t)

    def next_integrator(self, integ):
        """The integrator of the step starting at ``integ.t``: ``integ`` itself, or, when a
        hold or the removal begins there, a new one (:meth:`integrator`) with the state of
        ``integ`` moved into it (:meth:`settle`)."""
        if getattr(integ, "phase", None) == self.phase_at(integ.t):
            return integ
        new = self.integrator(integ.t)
        restore_integrator(new, integrator_state(integ))
        new.set_step_memory(integ.step_memory())
        self.settle(new)
        return new

    def settle(self, integ) -> None:
        """The state of ``integ`` (an integrator of this scene with a state put in) as the
        removals leave it, when removed blocks are out at its time (``Removal.settle``;
        nothing before, and nothing new for a group already out)."""
        if self.removed_at(integ.t):
            self.removal.settle(integ, self.points, self.solver.h)

    def step_limit_s(self, t: float) -> float:
        """The latest time (s) a step starting at ``t`` may end at (the adaptive step size's
        bound): the start of the first step that holds a dof not held at ``t``, and the
        expected end of the loading (the time limit once past it). A push that stops on its
        displacement (``target_m``) reaches it exactly at the expected end (the driven point
        is on its path at the end of every step, ``loading.step_velocity``), so its last step
        ends there, or within one ``h`` past it where that end is not on the grid of ``h``."""
        h = self.solver.h
        limit = self.expected_end_s if t < self.expected_end_s - 1e-9 * h else self.time_limit_s
        for hd in self.holds:
            if hd not in self.holds_at(t):
                limit = min(limit, math.floor(hd.from_s / h + 1e-9) * h)
        leaves = None if self.removal is None else self.removal.next_at_s(t, h)
        if leaves is not None:
            limit = min(limit, leaves)
        if self.turns_s and self.solver.max_growth:
            limit = min(limit, self._turn_limit_s(t))
        return limit

    def _turn_limit_s(self, t: float) -> float:
        """The bound that ``turns_s`` puts on a step starting at ``t``: ``t + h`` inside a
        window, the window's start (on the grid of h) before it. A large step across a turn
        ends where it ends, and the run's largest displacement in a cycle stops short of the
        amplitude (docs/performance.md)."""
        h = self.solver.h
        i = bisect.bisect_right(self._turn_ends, t + 1e-9 * h)  # the first window not over
        if i == len(self.turns_s):
            return math.inf
        return self._steps_of_h_from(self.turns_s[i][0], t)

    def _steps_of_h_from(self, a: float, t: float) -> float:
        """The bound on a step starting at ``t`` where every step from ``a`` (s) on is of
        ``h``: ``t + h`` once there, before it the last time of the grid of ``h`` at or
        before ``a`` (at least ``t + h``)."""
        h = self.solver.h
        if t >= a - 1e-9 * h:
            return t + h
        return max(math.floor(a / h + 1e-9) * h, t + h)

    @functools.cached_property
    def _turn_ends(self) -> list[float]:
        return [end for _, end in self.turns_s]

    def integrator(self, t: float = 0.0):
        """A new integrator of the scene for a step starting at ``t`` (s), with the holds active
        then (its state is the initial one: restore a state into it to continue a run)."""
        bodies = list(self.bodies)
        for hd in self.holds_at(t):
            b = bodies[hd.body]
            bodies[hd.body] = dataclasses.replace(
                b, imposed_velocity={**b.imposed_velocity, hd.dof: at_rest},
                dof_mode=b.dof_mode.copy())
        points, loads = self.points, self.loads
        if self.removed_at(t):
            bodies, points, loads = self.removal.apply(bodies, points, loads, t, self.solver.h)
        s = self.solver
        integ = Integrator(bodies, points, self.params, loads, h=s.h, theta=s.theta,
                          tolerance=s.tolerance, max_iterations=s.max_iterations,
                          check_every=s.check_every, method=s.method,
                          endo3d_params=s.endo3d_params, endo3d_tau=s.endo3d_tau,
                          max_halvings=s.max_halvings,
                          halve_after_failure=s.halve_after_failure, energy=s.energy,
                          max_growth=s.max_growth, grow_after=s.grow_after,
                          easy_iterations=s.easy_iterations, easy_damage=s.easy_damage,
                          step_limit=self.step_limit_s, linear=s.linear,
                          kinetic_damping=s.kinetic_damping)
        integ.phase = self.phase_at(t)  # what it was built for (``next_integrator``)
        return integ

    # --- read-outs ------------------------------------------------------------------------
    def driven_dofs(self, body_dof0: np.ndarray) -> tuple[int, int]:
        """Global dofs of the driven body's reference point, x and y."""
        d0 = int(body_dof0[self.driven])
        return d0, d0 + 1

    def measured_dofs(self, body_dof0: np.ndarray):
        """``((dofs, weights), (dofs, weights))``: ``U_x = weights . u[dofs]`` and ``U_y``
        (``measured``, or the driven body's reference point)."""
        if self.measured is not None:
            return self.measured
        ux, uy = self.driven_dofs(body_dof0)
        one = np.ones(1)
        return (np.array([ux]), one), (np.array([uy]), one)

    def reaction_weights(self, side_body: np.ndarray) -> dict[str, np.ndarray]:
        """Per reaction, the weight (+1, -1, 0) of each point's force on its candidate body in
        the force of that body (of those bodies) on the others: +1 where it is the antagonist,
        -1 where it is the candidate (0 between two of the bodies)."""
        return {k: np.isin(side_body[:, 1], b).astype(float) - np.isin(side_body[:, 0], b)
                for k, b in self.reactions.items()}

    @property
    def joint_groups(self) -> tuple[str, ...]:
        """The groups whose points follow a joint law (not the glue)."""
        used = {p.group for p in self.points if p.kind == KIND_JOINT}
        return tuple(g for i, g in enumerate(self.groups) if i in used)

    def info(self) -> dict[str, Any]:
        """What the run folder keeps of the scene (``scene.json``; SI units)."""
        def name(i: int) -> str:
            b = self.bodies[i]
            return b.name or f"body {i}"

        return {
            "format": SCENE_FORMAT, "version": 1, "name": self.name, "builder": self.builder,
            "groups": list(self.groups), "joint_groups": list(self.joint_groups),
            "stages": [{"name": s.name, "start_s": s.start_s} for s in self.stages],
            "push_stage": self.push_stage, "target_m": self.target_m,
            "expected_end_s": self.expected_end_s, "time_limit_s": self.time_limit_s,
            "history": self.history,
            "contact_solver": self.solver.method,
            "driven": {"body": name(self.driven),
                       "reference_m": [float(v) for v in getattr(  # a block: its first node
                           self.bodies[self.driven], "reference", self.bodies[self.driven].X[0])]},
            "reactions": {k: name(b) if isinstance(b, int | np.integer)
                          else " + ".join(name(i) for i in b)
                          for k, b in self.reactions.items()},
            "holds": [{"body": name(hd.body), "dof": DOF_NAMES[hd.dof], "from_s": hd.from_s}
                      for hd in self.holds],
            "bodies": [name(i) for i in range(len(self.bodies))],
            "structure": [{"body": i, "kind": "rigid" if isinstance(self.bodies[i], RigidBody)
                           else "block", **info}
                          for i, info in zip(self.structure, self.body_info)],
            **({"collapse": self.collapse.info()} if self.collapse is not None else {}),
            **({"removal": self.removal.info(self.solver.h)} if self.removal is not None
               else {}),
            **self.meta,
        }
