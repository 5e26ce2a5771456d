r"""The statics of a scene taken as rigid blocks: bodies, interface points, loads, and the
equilibrium matrix that links them.

Every body is rigid. A rigid body of the scene keeps its reference point ``x_b`` (m) and its
six dofs; a deformable block becomes the rigid body of its mesh
(:meth:`masonry_nscd.model.RigidBody.from_mesh`: mass, centre of mass, inertia), whose reference
point is its centre of mass. A body is a **support** (fixed) when all its dofs are imposed; an
imposed dof of another body (or a dof held by the scene) has no equilibrium row (its reaction
is free). The scene's mark ``support`` says only on which side of a joint its points sit: a
beam so marked whose vertical displacement and rotation are free (the dry stone wall's top
beam) keeps their equilibrium rows.

Interface points are the scene's contact points (:mod:`masonry_nscd.model.points`): position
``x_p`` (m), frame ``(n, t, s)`` with ``n`` from the antagonist (body ``a``) to the candidate
(body ``c``), tributary area ``A_p`` (m^2), friction coefficient ``mu_p`` and, from the joint
law's parameter row, the tensile strength ``f_t`` and the cohesion ``c`` of the joint as built
(Pa: the cohesive law's elastic limits times its initial integrity; zero for a dry joint).
A glued point carries any force. The joint's springs (the normal compliance in compression
and the tangential one, m/Pa; zero for a ``coulomb`` joint) weigh its points in the state of
least complementary energy that starts the non-associative iteration (:mod:`.lp`).

The unknown force of point ``p`` is ``f_p = N_p n + T_p t + S_p s`` (N) on the candidate
(``N > 0`` compression), ``-f_p`` on the antagonist. Equilibrium of a free body ``b``:

    sum_p  +-[ f_p ; (x_p - x_b) x f_p ]  +  F_dead,b  +  lambda F_live,b  =  0      (N, N m)

six rows per body (forces, moments about ``x_b``). The loads are the scene's
(:attr:`Scene.loads`): ``F(t) = F_dead + v(t) F_live`` where ``v(t)`` is the first growing load
factor of the scene (``lambda``, the body-force multiplier; ``point_load_N``, a force in N)
once every ramp is over, so ``F_live`` is the load per unit of that factor and ``F_dead`` the
rest (self-weight and the other loads); a deformable block's nodal loads are reduced to their
resultant and moment about its reference point. A scene with no growing factor (a factor of
rate zero) has only dead loads, unless it is a **push**: its driven body's x dof imposed and
some other dof free (a wall sheared by its top beam). The push's growing load is then a
horizontal force (``push_force_N``, N) on the driven body at its reference point, its x dof
freed: the force the wall carries when the beam is pushed, the NSCD curve's ``F_x``.

Blocks removed at a time (``Scene.removal``, ``loading.removal``) are out of the model whatever
the time: no equilibrium rows, no interface points, no loads; the analysis is that of the
structure with the hole.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from masonry_nscd.contact.laws import KIND_GLUED
from masonry_nscd.contact.laws.fczm import P_B, P_CN_C, P_CT, P_D1, P_D2, P_KI, P_KII, P_MU
from masonry_nscd.model import RigidBody, dof_offsets
from masonry_nscd.model.bodies import DOF_IMPOSED


@dataclass
class RigidModel:
    """A scene as rigid blocks (module docstring); arrays per body ``b`` and per point ``p``."""

    names: list[str]  # per body
    reference: np.ndarray  # (b, 3) m, the point the body's dofs and moments refer to
    support: np.ndarray  # (b,) bool
    free: np.ndarray  # (6 b,) bool: the dofs with an equilibrium row
    x: np.ndarray  # (p, 3) m
    frame: np.ndarray  # (p, 3, 3) rows n, t, s
    pair: np.ndarray  # (p, 2) candidate, antagonist
    area: np.ndarray  # (p,) m^2
    mu: np.ndarray  # (p,)
    tensile_Pa: np.ndarray  # (p,)
    cohesion_Pa: np.ndarray  # (p,)
    glued: np.ndarray  # (p,) bool
    group: np.ndarray  # (p,) joint group id
    compliance_n: np.ndarray  # (p,) m/Pa, the joint's normal spring in compression (0: rigid)
    compliance_t: np.ndarray  # (p,) m/Pa, its tangential spring
    dead: np.ndarray  # (6 b,) N, N m
    live: np.ndarray  # (6 b,) N, N m per unit of the factor
    factor: str | None  # the growing load's name (None: dead loads only)
    factor_unit: str
    meshes: list[tuple[np.ndarray, np.ndarray]]  # per body, nodes (k, 3) m and hexahedra

    @property
    def bodies(self) -> int:
        return len(self.names)

    @property
    def points(self) -> int:
        return len(self.x)


def _as_rigid(body) -> tuple[np.ndarray, bool, np.ndarray]:
    """Reference point, support flag and imposed-dof mask (6,) of a body taken as rigid."""
    if isinstance(body, RigidBody):
        imposed = np.asarray(body.dof_mode) == DOF_IMPOSED
        return np.asarray(body.reference, float), bool(imposed.all()), imposed
    rigid = RigidBody.from_mesh(body.X, body.conn, body.density)
    return rigid.center, False, np.zeros(6, bool)


def _reduce(scene, F: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """A load vector of the scene's dofs (N; N m for a rigid body's rotations) as a rigid
    load (6 per body) about each body's reference point."""
    dof0 = dof_offsets(scene.bodies)
    out = np.zeros(6 * len(scene.bodies))
    for i, body in enumerate(scene.bodies):
        f = F[dof0[i]:dof0[i + 1]]
        if isinstance(body, RigidBody):
            out[6 * i:6 * i + 6] = f
        else:
            nodal = f.reshape(-1, 3)
            out[6 * i:6 * i + 3] = nodal.sum(axis=0)
            out[6 * i + 3:6 * i + 6] = np.cross(body.X - reference[i], nodal).sum(axis=0)
    return out


def split_loads(scene) -> tuple[np.ndarray, np.ndarray, str | None, str]:
    """``(F_dead, F_live, factor name, unit)`` of the scene's dofs (module docstring): the
    loads read at two times after every stage and ramp, ``F_live = dF / dv``."""
    ndof = int(dof_offsets(scene.bodies)[-1])
    factors = list(scene.collapse.factors) if scene.collapse is not None else []
    last = max([st.start_s for st in scene.stages] + [scene.time_limit_s, 1.0])
    t1, t2 = 10.0 * last, 20.0 * last
    loads = scene.loads
    if scene.removal is not None:  # the removed blocks' loads are gone
        loads = loads.without(scene.removal.dofs(scene.bodies))
    F1, F2 = loads.at(t1, ndof), loads.at(t2, ndof)
    for fa in factors:
        v1, v2 = float(fa.value(t1)), float(fa.value(t2))
        if v2 != v1:
            live = (F2 - F1) / (v2 - v1)
            return F1 - v1 * live, live, fa.name, fa.unit
    return F1, np.zeros(ndof), None, ""


#: The growing load of a scene driven by a displacement (a push), by name and unit.
PUSH_FACTOR = ("push_force_N", "N")


def _push(scene, free: np.ndarray, live: np.ndarray) -> tuple[str | None, str]:
    """Where a scene has no growing load but its driven body is pushed along x (its x dof
    imposed, others free: the dry stone wall's top beam), the push as a growing force: the
    dof is freed and a unit force along +x at the body's reference point is the live load
    (``live`` and ``free`` changed in place). Returns the factor's name and unit, or
    ``(None, "")`` when there is no such push."""
    d = getattr(scene, "driven", None)
    if d is None or scene.removal is not None and d in scene.removal.bodies:
        return None, ""
    body = scene.bodies[d]
    if not isinstance(body, RigidBody):
        return None, ""
    imposed = np.asarray(body.dof_mode) == DOF_IMPOSED
    if not imposed[0] or imposed.all() or any(h.body == d and h.dof == 0 for h in scene.holds):
        return None, ""
    free[6 * d] = True
    live[6 * d] = 1.0
    return PUSH_FACTOR


def rigid_model(scene) -> RigidModel:
    """The scene as rigid blocks (module docstring)."""
    nb = len(scene.bodies)
    ref = np.zeros((nb, 3))
    support = np.zeros(nb, bool)
    free = np.ones(6 * nb, bool)
    meshes = []
    for i, body in enumerate(scene.bodies):
        ref[i], support[i], imposed = _as_rigid(body)
        free[6 * i:6 * i + 6] = ~imposed & ~support[i]
        meshes.append((np.asarray(body.X, float), np.asarray(body.conn, np.int64)))
    for hd in scene.holds:
        free[6 * hd.body + hd.dof] = False
    pts = scene.points
    if scene.removal is not None:  # the structure once they are out: no dofs, no points
        out = set(scene.removal.bodies)
        for i in out:
            free[6 * i:6 * i + 6] = False
        pts = [p for p in pts if not out & set(p.bodies)]
    law = np.array([p.law for p in pts], dtype=np.int64)
    P = np.asarray(scene.params)[law] if len(pts) else np.zeros((0, 16))
    dead, live, factor, unit = split_loads(scene)
    live = _reduce(scene, live, ref)
    if factor is None:  # a push: the driven dof's force grows (module docstring)
        factor, unit = _push(scene, free, live)
    return RigidModel(
        names=[b.name or f"body {i}" for i, b in enumerate(scene.bodies)],
        reference=ref, support=support, free=free,
        x=np.array([p.x for p in pts], float).reshape(-1, 3),
        frame=np.array([p.frame for p in pts], float).reshape(-1, 3, 3),
        pair=np.array([p.bodies for p in pts], np.int64).reshape(-1, 2),
        area=np.array([p.area for p in pts], float),
        mu=P[:, P_MU].copy(),
        tensile_Pa=P[:, P_B] * P[:, P_KI] * P[:, P_D1],
        cohesion_Pa=P[:, P_B] * P[:, P_KII] * P[:, P_D2],
        glued=np.array([p.kind == KIND_GLUED for p in pts], bool),
        group=np.array([p.group for p in pts], np.int64),
        compliance_n=P[:, P_CN_C].copy(), compliance_t=P[:, P_CT].copy(),
        dead=_reduce(scene, dead, ref), live=live,
        factor=factor, factor_unit=unit, meshes=meshes)


def equilibrium_matrix(m: RigidModel) -> sp.csr_matrix:
    """``B`` (6 b, 3 p): column ``3 p + k`` is the generalised force on every body of a unit
    force along row ``k`` of point ``p``'s frame (+ on the candidate, - on the antagonist),
    forces and moments about each body's reference point."""
    npt = m.points
    rows, cols, vals = [], [], []
    for side, sign in ((0, 1.0), (1, -1.0)):
        b = m.pair[:, side]
        r = m.x - m.reference[b]
        for k in range(3):
            d = m.frame[:, k, :]  # (p, 3) the direction of component k
            mom = np.cross(r, d)
            col = 3 * np.arange(npt) + k
            for j in range(3):
                rows += [6 * b + j, 6 * b + 3 + j]
                cols += [col, col]
                vals += [sign * d[:, j], sign * mom[:, j]]
    if not npt:
        return sp.csr_matrix((6 * m.bodies, 0))
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(6 * m.bodies, 3 * npt))


#: The compliance (m/Pa) of every joint's springs when no joint of the scene has any: the
#: stiffness 1e11 Pa/m of the shipped dry joints.
STIFF_COMPLIANCE = 1e-11


def spring_compliances(m: RigidModel) -> tuple[np.ndarray, np.ndarray]:
    """The points' normal and tangential compliances (m/Pa), a joint without springs (zero
    compliance, a ``coulomb`` joint) as stiff as the others (in shear as in compression, and
    :data:`STIFF_COMPLIANCE`, if none has one)."""
    out = []
    for c in (m.compliance_n, m.compliance_t):
        c = np.asarray(c, float).copy()
        soft = c > 0.0
        c[~soft] = c[soft].mean() if soft.any() else STIFF_COMPLIANCE
        out.append(c)
    return out[0], out[1]


def point_velocities(m: RigidModel, velocity: np.ndarray) -> np.ndarray:
    """The relative velocity (p, 3) of each point's candidate to its antagonist in the
    point's frame (n, t, s), for the rigid velocities ``velocity`` (b, 6) (v of the reference
    point, omega): ``u_n > 0`` opens the joint."""
    def at(side: int) -> np.ndarray:
        b = m.pair[:, side]
        return velocity[b, :3] + np.cross(velocity[b, 3:], m.x - m.reference[b])

    rel = at(0) - at(1)
    return np.einsum("pkj,pj->pk", m.frame, rel)
