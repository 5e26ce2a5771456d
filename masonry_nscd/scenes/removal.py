r"""The removal of blocks at given times: holes opened in a vault (``loading.removal``).

A removal is one or several groups of blocks (:class:`RemovalGroup`), each with its time; a
block belongs to one group. The blocks of a group leave the model at the start of a step: the
first step that ends after its ``time_s`` (s), so at ``time_s`` itself when it is on the grid of
the step ``h``, else at the start of the step in which it falls (:meth:`RemovalGroup.at_s`;
the adaptive step size ends a step there, ``Scene.step_limit_s``). The groups out in a step are
those whose time has come (:meth:`Removal.out_at`), and each new group out makes a new system
(``Scene.phase_at``). It is a change of the system's activity, not of its size: the bodies,
the contact points and the state keep their numbering, so the checkpoints and the outputs of a
run keep their shapes across the removals.

From then on (:meth:`Removal.apply`, :meth:`Removal.settle`):

* **the contact points** of a removed block (with the structure, with a support) are detached:
  both sides lose their dofs (``H = 0``), so the points neither see the bodies' motion nor act
  on them, and their state is set to a joint at rest with no displacement,
  ``u = U = u_c = 0``, ``T = 0``, status open. Every law gives no traction at ``u = 0`` (the
  initial gap is already subtracted from ``u``): a joint law's spring and cohesion carry
  ``T = K u = 0``, the rigid contact's Alart-Curnier row and the glue's row with their
  compliance ``eps`` give ``eps r = 0``; ``u`` stays 0 since ``U = H^T v = 0``. So no impulse,
  no cohesion, no force in the reactions. The integrity ``beta`` is left as it was;
* **their loads stop**: the load patterns are zero on their dofs (gravity, the body force, the
  point and line loads on them; ``Loads.without``);
* **a removed rigid block is held at rest** where it was (its six dofs imposed at zero velocity,
  its velocity set to zero), so that it neither falls through the structure nor loads it. A
  deformable block has no imposed dofs: it moves on freely, with no contact and no load;
* **the collapse watch** leaves them out (``collapse.CollapseMonitor``), the outputs flag their
  cells ``removed`` (VTU, from the output step after their time on), ``scene.json`` and the
  summary list each group: its blocks, the time asked for and the time they left.

The energy balance does not follow the blocks out: the elastic energy of their joints at the
removal and the kinetic energy of a removed rigid block leave the account (the imbalance grows
by as much).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from masonry_nscd.contact import laws
from masonry_nscd.loading import Loads, at_rest
from masonry_nscd.model import RigidBody, dof_offsets

#: A step that ends within this fraction of ``h`` of the removal time is still a step before it
#: (the run's time is a sum of steps: it comes to ``k h`` within round-off only)
TIME_TOLERANCE = 1e-6


@dataclass(frozen=True)
class RemovalGroup:
    """The bodies (scene indices) removed at ``time_s`` (s), and their names."""

    bodies: tuple[int, ...]
    time_s: float
    names: tuple[str, ...] = ()

    def active(self, t: float, h: float) -> bool:
        """Whether the bodies are out in the step of ``h`` (s) starting at ``t`` (s): it ends
        after ``time_s`` (module docstring)."""
        return t + h > self.time_s + TIME_TOLERANCE * h

    def at_s(self, h: float) -> float:
        """The time (s) at which the bodies leave: the start of the first step of ``h`` that
        ends after ``time_s``."""
        return math.floor(self.time_s / h + TIME_TOLERANCE) * h

    def info(self, h: float) -> dict:
        """What ``scene.json`` keeps of it (``h``: the scene's step, s)."""
        return {"blocks": list(self.names), "time_s": self.time_s, "at_s": self.at_s(h)}


@dataclass(frozen=True)
class Removal:
    """The groups of bodies removed, each at its time, in the order of their times."""

    groups: tuple[RemovalGroup, ...]

    def __post_init__(self):
        object.__setattr__(self, "groups", tuple(sorted(self.groups, key=lambda g: g.time_s)))

    @property
    def bodies(self) -> tuple[int, ...]:
        """Every removed body, whatever its time (the structure with every hole:
        ``masonry limit``)."""
        return tuple(i for g in self.groups for i in g.bodies)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(n for g in self.groups for n in g.names)

    def out_at(self, t: float, h: float) -> int:
        """How many groups are out in the step of ``h`` (s) starting at ``t`` (s): the first
        ones (the groups are in the order of their times)."""
        return sum(g.active(t, h) for g in self.groups)

    def bodies_at(self, t: float, h: float) -> tuple[int, ...]:
        """The bodies out in the step of ``h`` starting at ``t``."""
        return tuple(i for g in self.groups[:self.out_at(t, h)] for i in g.bodies)

    def next_at_s(self, t: float, h: float) -> float | None:
        """When the next group leaves after a step starting at ``t`` (s; None: none left)."""
        k = self.out_at(t, h)
        return self.groups[k].at_s(h) if k < len(self.groups) else None

    def apply(self, bodies: list, points: list, loads: Loads, t: float, h: float
              ) -> tuple[list, list, Loads]:
        """The bodies, points and loads of the integrator of a step of ``h`` starting at ``t``
        (s), with the groups out then: the removed rigid bodies held at rest, their points
        detached, their loads zero."""
        out = set(self.bodies_at(t, h))
        bodies = list(bodies)
        for i in out:
            b = bodies[i]
            if isinstance(b, RigidBody):
                bodies[i] = dataclasses.replace(
                    b, imposed_velocity=dict.fromkeys(range(6), at_rest),
                    dof_mode=np.zeros(6, dtype=np.int64))
        nothing = (np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
        points = [dataclasses.replace(p, bodies=(-1, -1), sides=[nothing, nothing])
                  if out & set(p.bodies) else p for p in points]
        return bodies, points, loads.without(self.dofs(bodies, sorted(out)))

    def dofs(self, bodies: list, which=None) -> np.ndarray:
        """The global dofs of the removed bodies (``which``: of those only; None: every
        removed body, whatever its time)."""
        dof0 = dof_offsets(bodies)
        which = self.bodies if which is None else which
        return np.concatenate([np.arange(dof0[i], dof0[i + 1]) for i in which]
                              or [np.zeros(0, dtype=np.int64)])

    def points(self, points: list, which) -> np.ndarray:
        """The contact points (indices) of the bodies ``which``."""
        out = set(which)
        return np.array([a for a, p in enumerate(points) if out & set(p.bodies)],
                        dtype=np.int64)

    def settle(self, integ, points: list, h: float) -> None:
        """Put the state of ``integ``, an integrator built with :meth:`apply` (``points``: the
        scene's, before it; ``h`` the scene's step, s), as the removals out at its time leave
        it: the removed points' joints at rest with no displacement, the held bodies'
        velocities zero, the loads at the step's start without theirs. Changes nothing for the
        groups already settled (a run resumed after a removal, a second group leaving
        later)."""
        out = self.bodies_at(integ.t, h)
        gone = self.points(points, out)
        j = integ.joints
        for name in ("u", "U", "uc", "T"):
            getattr(j, name)[gone] = 0.0
        j.status[gone] = laws.ST_OPEN
        d0 = integ.sys.body_dof0
        for i in out:
            if isinstance(integ.bodies[i], RigidBody):
                integ.v[d0[i]:d0[i + 1]] = 0.0
        integ._F0 = integ.loads.at(integ.t, integ.sys.ndof)

    def info(self, h: float) -> list[dict]:
        """What ``scene.json`` keeps of it (``h``: the scene's step, s): each group, in the
        order of their times."""
        return [g.info(h) for g in self.groups]


def removal_of(case, bodies: list) -> Removal | None:
    """The removal of ``case.loading.removal`` on the scene's ``bodies``, found by name (the
    builders' checks have refused a name they do not have); None without one, or for a case
    whose structure has no limit state (a wall: the schema refuses the field)."""
    loading = case.loading
    if getattr(loading, "removal", None) is None:
        return None
    index = {b.name: i for i, b in enumerate(bodies) if b.name}
    groups = []
    for path, spec in loading.removal_groups():
        missing = [name for name in spec.blocks if name not in index]
        if missing:
            raise ValueError(f"{path}.blocks: no block named {', '.join(map(repr, missing))}")
        groups.append(RemovalGroup(tuple(index[name] for name in spec.blocks),
                                   float(spec.time_s), tuple(spec.blocks)))
    return Removal(tuple(groups))
