r"""The removal of blocks at a time: a hole opened in a vault (``loading.removal``).

The removed blocks leave the model at the start of a step: the first step that ends after
``time_s`` (s), so at ``time_s`` itself when it is on the grid of the step ``h``, else at the
start of the step in which it falls (:attr:`Removal.at_s`; the adaptive step size ends a step
there, ``Scene.step_limit_s``). It is a change of the system's activity, not of its size: the
bodies, the contact points and the state keep their numbering, so the checkpoints and the
outputs of a run keep their shapes across the removal.

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
  cells ``removed`` (VTU), ``scene.json`` and the summary name them and the time.

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
class Removal:
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

    def apply(self, bodies: list, points: list, loads: Loads) -> tuple[list, list, Loads]:
        """The bodies, points and loads of the integrator once the bodies are out: the removed
        rigid bodies held at rest, their points detached, their loads zero."""
        out = set(self.bodies)
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
        return bodies, points, loads.without(self.dofs(bodies))

    def dofs(self, bodies: list) -> np.ndarray:
        """The global dofs of the removed bodies."""
        dof0 = dof_offsets(bodies)
        return np.concatenate([np.arange(dof0[i], dof0[i + 1]) for i in self.bodies])

    def points(self, points: list) -> np.ndarray:
        """The contact points (indices) of the removed bodies."""
        out = set(self.bodies)
        return np.array([a for a, p in enumerate(points) if out & set(p.bodies)],
                        dtype=np.int64)

    def settle(self, integ, points: list) -> None:
        """Put the state of ``integ``, an integrator built with :meth:`apply` (``points``: the
        scene's, before it), as the removal leaves it: the removed points' joints at rest with
        no displacement, the held bodies' velocities zero, the loads at the step's start
        without theirs. Changes nothing the second time (a run resumed after the removal)."""
        gone = self.points(points)
        j = integ.joints
        for name in ("u", "U", "uc", "T"):
            getattr(j, name)[gone] = 0.0
        j.status[gone] = laws.ST_OPEN
        d0 = integ.sys.body_dof0
        for i in self.bodies:
            if isinstance(integ.bodies[i], RigidBody):
                integ.v[d0[i]:d0[i + 1]] = 0.0
        integ._F0 = integ.loads.at(integ.t, integ.sys.ndof)

    def info(self, h: float) -> dict:
        """What ``scene.json`` keeps of it (``h``: the scene's step, s)."""
        return {"blocks": list(self.names), "time_s": self.time_s, "at_s": self.at_s(h)}


def removal_of(case, bodies: list) -> Removal | None:
    """The removal of ``case.loading.removal`` on the scene's ``bodies``, found by name (the
    builders' checks have refused a name they do not have); None without one, or for a case
    whose structure has no limit state (a wall: the schema refuses the field)."""
    spec = getattr(case.loading, "removal", None)
    if spec is None:
        return None
    index = {b.name: i for i, b in enumerate(bodies) if b.name}
    missing = [name for name in spec.blocks if name not in index]
    if missing:
        raise ValueError(f"loading.removal.blocks: no block named {', '.join(map(repr, missing))}")
    return Removal(tuple(index[name] for name in spec.blocks), float(spec.time_s),
                   tuple(spec.blocks))
