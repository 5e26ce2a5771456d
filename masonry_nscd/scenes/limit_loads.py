r"""The loads, solver settings and collapse rule of a limit-state scene (an arch, a vault, an
assembly from a mesh file), from the case's ``loading``, ``solver`` and ``collapse`` sections.

Loads on the structure's blocks (SI units):

* gravity ``g(t) m`` downwards (``loading.gravity``, along -y), ``m`` a rigid block's mass at
  its centre of mass or an elastic block's lumped nodal masses;
* the body force ``lambda(t) g m`` along ``loading.body_force.direction`` (``g`` the gravity's
  value; :class:`~masonry_nscd.loading.multiplier.GrowingMultiplier`);
* a force ``P(t)`` along ``loading.point_load.direction`` at a point of one block (the
  builder's: the middle of a voussoir's extrados); on a rigid block the force and its moment
  about the reference point ``(x - x_ref) x F``, on an elastic block shared by the nodes
  nearest to the point.

Each growing load is a :class:`~masonry_nscd.collapse.LoadFactor` whose value at collapse the
summary reports; the stages are ``gravity``, ``body force``, ``point load`` by start time.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from masonry_nscd.loading import Loads, Ramp
from masonry_nscd.loading.multiplier import GrowingMultiplier
from masonry_nscd.materials.point_driver import params_from_case
from masonry_nscd.model import RigidBody, dof_offsets
from masonry_nscd.scenes.scene import CollapseRule, LoadFactor, SolverSettings, Stage


def limit_loads(case, bodies: list, structure: list[int],
                point_at: Callable[[int], np.ndarray]
                ) -> tuple[Loads, list[Stage], list[LoadFactor]]:
    """The loads of the module docstring on ``bodies[structure]``; ``point_at(k)`` is where
    the point load acts on body ``k`` (m)."""
    ld = case.loading
    dof0 = dof_offsets(bodies)
    ndof = int(dof0[-1])
    loads = Loads()

    def weight_pattern(direction) -> np.ndarray:
        """Per unit of acceleration along ``direction``: m * direction on every block."""
        F = np.zeros(ndof)
        for i in structure:
            b = bodies[i]
            if isinstance(b, RigidBody):
                F[dof0[i]:dof0[i + 1]] = b.weight_load(direction)
            else:
                m = b.lumped_mass()
                for d in range(3):
                    F[dof0[i] + d:dof0[i + 1]:3] = direction[d] * m[d::3]
        return F

    grav = ld.gravity
    loads.add(weight_pattern((0.0, -1.0, 0.0)), Ramp(grav.value_m_s2, grav.start_s, grav.ramp_s))
    stages = [Stage("gravity", 0.0)]
    factors = []
    bf = ld.body_force
    if bf.active:
        lam = GrowingMultiplier(bf.multiplier, bf.rate_per_s, bf.start_s, bf.ramp_s)
        gval = grav.value_m_s2
        loads.add(weight_pattern(bf.direction), lambda s, lam=lam, gval=gval: gval * lam(s))
        stages.append(Stage("body force", bf.start_s))
        factors.append(LoadFactor("lambda", "", lam, "body force multiplier (of g m)"))
    pl = ld.point_load
    if pl is not None:
        k = next(i for i, b in enumerate(bodies) if b.name == pl.block)
        b = bodies[k]
        at = np.asarray(point_at(k), dtype=float)
        F = np.zeros(ndof)
        force = np.asarray(pl.direction, dtype=float)
        if isinstance(b, RigidBody):
            F[dof0[k]:dof0[k] + 3] = force
            F[dof0[k] + 3:dof0[k] + 6] = np.cross(at - b.reference, force)
        else:  # the nodes of the top face nearest to the point share it
            d2 = np.linalg.norm(b.X - at, axis=1)
            near = np.flatnonzero(d2 <= d2.min() + 1e-9 * (1.0 + d2.min()))
            for node in near:
                F[dof0[k] + 3 * node:dof0[k] + 3 * node + 3] = force / len(near)
        P = GrowingMultiplier(pl.force_N, pl.rate_N_s, pl.start_s, pl.ramp_s)
        loads.add(F, P)
        stages.append(Stage("point load", pl.start_s))
        factors.append(LoadFactor("point_load_N", "N", P, f"force on {pl.block}"))
    return loads, stages, factors


def limit_settings(case, factors: list[LoadFactor]) -> tuple[SolverSettings, CollapseRule]:
    """The solver settings of ``case.solver`` and the collapse rule of ``case.collapse``."""
    col = case.collapse
    endo = None
    if case.blocks.material == "endo3d":
        endo = params_from_case(case)
    solver = SolverSettings.from_case(case, endo)
    rule = CollapseRule(displacement_m=col.displacement_m, velocity_m_s=col.velocity_m_s,
                        onset_velocity_m_s=col.onset_velocity_m_s,
                        hinge_opening_m=col.hinge_opening_m, after_s=col.after_s,
                        factors=factors)
    return solver, rule
