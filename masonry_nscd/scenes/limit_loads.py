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

* line loads (``loading.line_loads``), dead loads ramped with gravity: a force ``q`` (N/m) per
  metre along a segment from ``a`` to ``b`` (m) over named blocks, resultant ``q |b - a|``
  (:func:`line_load_pattern`);
* block loads (``loading.block_loads``), dead loads ramped with gravity: a force (N) on each
  named block, where the point load would act on it.

Each growing load is a :class:`~masonry_nscd.collapse.LoadFactor` whose value at collapse the
summary reports, and so is a settlement (``loading.settlement``: the builder moves its
supports; here its stage and its factor, the length of the supports' displacement, m); the
stages are ``gravity``, ``body force``, ``point load``, ``settlement``, the caller sorts them
by start time.

A force ``F`` at a point ``x`` of a block (:func:`add_force`): on a rigid block ``F`` and its
moment ``(x - x_ref) x F`` about the reference point; on a deformable block ``F`` shared
equally by the nodes nearest to ``x``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull

from masonry_nscd.loading import Loads, Ramp, at_rest
from masonry_nscd.loading.multiplier import GrowingMultiplier, SmoothMotion
from masonry_nscd.materials.point_driver import params_from_case
from masonry_nscd.model import MAT_ELASTIC, MAT_ENDO3D, Block, RigidBody, dof_offsets
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
        lam = GrowingMultiplier(bf.multiplier, bf.rate_per_s, bf.start_s, bf.ramp_s, bf.hold_s)
        gval = grav.value_m_s2
        loads.add(weight_pattern(bf.direction), lambda s, lam=lam, gval=gval: gval * lam(s))
        stages.append(Stage("body force", bf.start_s))
        factors.append(LoadFactor("lambda", "", lam, "body force multiplier (of g m)"))
    pl = ld.point_load
    if pl is not None:
        k = next(i for i, b in enumerate(bodies) if b.name == pl.block)
        F = np.zeros(ndof)
        add_force(F, bodies[k], int(dof0[k]), point_at(k), np.asarray(pl.direction, dtype=float))
        P = GrowingMultiplier(pl.force_N, pl.rate_N_s, pl.start_s, pl.ramp_s, pl.hold_s)
        loads.add(F, P)
        stages.append(Stage("point load", pl.start_s))
        factors.append(LoadFactor("point_load_N", "N", P, f"force on {pl.block}"))
    index = {b.name: i for i, b in enumerate(bodies) if b.name}
    dead = Ramp(1.0, grav.start_s, grav.ramp_s)  # the dead loads come with gravity
    for line in ld.line_loads:
        loads.add(line_load_pattern(bodies, [index[name] for name in line.blocks],
                                    line.force_N_m, line.from_m, line.to_m), dead)
    for each in ld.block_loads:
        F = np.zeros(ndof)
        for name in each.blocks:
            k = index[name]
            add_force(F, bodies[k], int(dof0[k]), point_at(k), np.asarray(each.force_N, float))
        loads.add(F, dead)
    settle = ld.settlement
    if settle is not None:
        stages.append(Stage("settlement", settle.start_s))
        motion = SmoothMotion(float(np.linalg.norm(settle.displacement_m)), settle.start_s,
                              settle.duration_s)
        factors.append(LoadFactor("settlement_m", "m", motion.displacement,
                                  f"settlement of {settle.label}"))
    return loads, stages, factors


def add_force(F: np.ndarray, body, d0: int, at, force: np.ndarray) -> None:
    """Add to ``F`` (N per dof) the force ``force`` (N) acting at the point ``at`` (m) of
    ``body``, whose dofs start at ``d0`` (module docstring)."""
    at = np.asarray(at, dtype=float)
    if isinstance(body, RigidBody):
        F[d0:d0 + 3] += force
        F[d0 + 3:d0 + 6] += np.cross(at - body.reference, force)
        return
    d2 = np.linalg.norm(body.X - at, axis=1)
    near = np.flatnonzero(d2 <= d2.min() + 1e-9 * (1.0 + d2.min()))
    for node in near:
        F[d0 + 3 * node:d0 + 3 * node + 3] += force / len(near)


#: A line load is cut into this many pieces of equal length, each carried whole by one block:
#: the share of each block is exact to a piece, 1/1000 of the segment
LINE_PIECES = 1000


def line_load_pattern(bodies: list, blocks: list[int], force_N_m, from_m, to_m) -> np.ndarray:
    r"""The load pattern (N per dof) of a force ``q`` = ``force_N_m`` (N/m) per metre along
    the segment from ``a`` = ``from_m`` to ``b`` = ``to_m`` (m), carried by the bodies
    ``blocks``.

    The segment is cut into :data:`LINE_PIECES` equal pieces; piece ``k`` carries
    ``q |b - a| / n`` at its middle ``x_k`` (the resultant of a uniform load on a piece acts
    there), so the pattern's resultant is ``q |b - a|`` whatever the split. The piece goes to
    the block under ``x_k``: among ``blocks``, those whose outline in plan (the convex hull of
    their nodes in x, z; y is up) holds ``(x_k, z_k)``, the one whose top (highest node) is
    highest, the load resting on it; where none holds it, the block whose outline is nearest
    in plan. The force acts on it at ``x_k`` itself (:func:`add_force`)."""
    a, b = np.asarray(from_m, dtype=float), np.asarray(to_m, dtype=float)
    q = np.asarray(force_N_m, dtype=float)
    n = LINE_PIECES
    mids = a + (b - a) * ((np.arange(n) + 0.5) / n)[:, None]
    plan = mids[:, [0, 2]]
    inside = np.zeros((n, len(blocks)), dtype=bool)
    distance = np.empty((n, len(blocks)))
    tops = np.empty(len(blocks))
    for j, k in enumerate(blocks):
        X = np.asarray(bodies[k].X, dtype=float)
        tops[j] = X[:, 1].max()
        hull = ConvexHull(X[:, [0, 2]])
        size = np.ptp(X[:, [0, 2]], axis=0).max()
        inside[:, j] = np.all(plan @ hull.equations[:, :2].T + hull.equations[:, 2]
                              <= 1e-9 * size, axis=1)
        corners = X[hull.vertices][:, [0, 2]]
        distance[:, j] = _distance_to_polygon(plan, corners)
    height = np.where(inside, tops, -np.inf)
    under = np.where(inside.any(axis=1), np.argmax(height, axis=1), np.argmin(distance, axis=1))
    dof0 = dof_offsets(bodies)
    F = np.zeros(int(dof0[-1]))
    piece = q * (np.linalg.norm(b - a) / n)
    for x, j in zip(mids, under):
        k = blocks[j]
        add_force(F, bodies[k], int(dof0[k]), x, piece)
    return F


def _distance_to_polygon(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """The distance (m) from each of ``points`` (p, 2) to the closed polygon ``corners``
    (c, 2): the nearest of its edges."""
    start, end = corners, np.roll(corners, -1, axis=0)
    edge = end - start
    rel = points[:, None, :] - start[None]
    s = np.clip(np.sum(rel * edge, axis=2) / np.maximum(np.sum(edge * edge, axis=1), 1e-300),
                0.0, 1.0)
    return np.linalg.norm(rel - s[..., None] * edge, axis=2).min(axis=1)


def until_collapse(case) -> str:
    """How long a limit-state run lasts, for ``masonry validate``: ``until collapse or 8 s,
    about 4000 steps of 0.002 s``."""
    return (f"until collapse or {case.collapse.end_time_s:g} s, about {case.step_count} steps "
            f"of {case.solver.time_step_s:g} s")


def structure_block(blocks, X: np.ndarray, conn: np.ndarray, name: str):
    """A block of the structure meshed by ``X`` (m) and ``conn``, as the case's ``blocks``
    section makes it: a rigid body (its mass, centre and inertia from the mesh) or a
    deformable block, linear elastic or ENDO3D."""
    if blocks.material == "rigid":
        return RigidBody.from_mesh(X, conn, blocks.density_kg_m3, name=name)
    return Block(X=X, conn=conn, E=blocks.E_Pa, nu=blocks.nu, density=blocks.density_kg_m3,
                 name=name, material=MAT_ENDO3D if blocks.material == "endo3d" else MAT_ELASTIC)


def support_motion(settle, moves: bool) -> dict:
    """The imposed velocities (dof -> history) of a fixed support: at rest, or, where it
    ``moves``, each component of the settlement's displacement (m) along its tanh ramp, its
    rotations held."""
    imposed = dict.fromkeys(range(6), at_rest)
    if moves:
        for d in range(3):
            if settle.displacement_m[d]:
                imposed[d] = SmoothMotion(settle.displacement_m[d], settle.start_s,
                                          settle.duration_s)
    return imposed


def limit_settings(case, factors: list[LoadFactor]) -> tuple[SolverSettings, CollapseRule]:
    """The solver settings of ``case.solver`` and the collapse rule of ``case.collapse``."""
    col = case.collapse
    endo = None
    if case.blocks.material == "endo3d":
        endo = params_from_case(case)
    solver = SolverSettings.from_case(case, endo)
    rule = CollapseRule(displacement_m=col.displacement_m, velocity_m_s=col.velocity_m_s,
                        onset_velocity_m_s=col.onset_velocity_m_s,
                        onset_kinetic_energy_J=col.onset_kinetic_energy_J,
                        hinge_opening_m=col.hinge_opening_m, after_s=col.after_s,
                        factors=factors)
    return solver, rule
