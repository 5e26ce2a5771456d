r"""The arch: voussoirs on two abutments, a builder of the block assembly.

Coordinates: x horizontal from the middle of the span, y up from the springing line, z along
the arch's depth (``0 <= z <= depth``). SI units.

Geometry (:func:`arch_geometry`). ``R`` the radius of the centreline, ``t`` the thickness,
``R_i = R - t/2`` and ``R_e = R + t/2`` the radii of the intrados and of the extrados, ``L`` the
span between the centres of the springing joints, ``n`` voussoirs numbered from the left.

* Semicircular: centre ``(0, 0)``; joint ``j = 0..n`` on the radial line of angle
  ``theta_j = pi j / n`` from the left springing, direction ``u_j = (-cos theta_j, sin
  theta_j)``, from ``R_i u_j`` to ``R_e u_j``.
* Pointed: the left half is an arc of centre ``(c, 0)``, ``c = R - L/2``, from the left
  springing (angle 0) to the crown, where it meets the vertical ``x = 0`` at the angle
  ``phi_c = acos(c / R)`` of its centreline; its ``n/2`` voussoirs are bounded by the radial
  lines at ``phi_j = phi_c j / (n/2)``, ``j < n/2``, and by the vertical crown joint, from
  ``(0, sqrt(R_i^2 - c^2))`` to ``(0, sqrt(R_e^2 - c^2))``. The right half is its mirror image.

Voussoir ``k`` lies between joints ``k - 1`` and ``k``: a prism on the quadrilateral of the two
joint lines (its intrados and extrados are the chords), extruded along z; one hexahedron (a
rigid voussoir keeps it as its geometry: mass, centre and inertia of the prism) or
``elements_per_voussoir`` (along the ring, through the thickness, along z), mapped bilinearly.
Each joint's unit normal ``n_j = (sin theta_j, cos theta_j)`` points towards the higher
voussoirs' numbers; with a joint thickness ``g`` each face is moved back by ``g/2`` along it,
so the two faces of a joint stay parallel, ``g`` apart.

Abutments (``arch.abutments``): ``fixed`` - two fixed rigid boxes, ``abutment_width_m`` wide
(centred on the springing's centreline) and ``abutment_height_m`` tall, under the springing
joints; ``blocks`` - the abutments are rigid blocks of those sizes (the blocks' density) resting
on two fixed ground plates, through a joint of the joint law: they slide and overturn. The
fixed body under each side (the abutment, or the ground under a block abutment) is the support
whose force on the structure is reported, and the one that settles with
``loading.settlement``.

Joints are found by contact detection (:mod:`masonry_nscd.model.detection`: radial planes face
each other as a bed joint does) and named ``voussoir`` (between voussoirs), ``springing``
(springer on abutment) and ``base`` (block abutment on the ground), all of the case's joint
law.

Loads: gravity on every block (``loading.gravity``); the body force ``lambda(t) g m`` along
``loading.body_force.direction``; a force growing on one block at the middle of its extrados
face (``loading.point_load``); the settlement of a support. The curve's ``U_x``, ``U_y`` are
the displacements of the crown voussoir's reference point (the keystone, or the voussoir right
of the crown joint; a rigid voussoir's centre of mass, an elastic one's first node); ``F_x``,
``F_y`` the force of the left support on the arch, ``*_bottom`` of the right one. The run stops
at collapse or at ``collapse.end_time_s`` (:mod:`masonry_nscd.collapse`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from masonry_nscd.contact import laws
from masonry_nscd.fe import hex8
from masonry_nscd.model import RigidBody
from masonry_nscd.model.detection import find_joints, joint_points
from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.limit_loads import (
    limit_loads,
    limit_settings,
    structure_block,
    support_motion,
    until_collapse,
)
from masonry_nscd.scenes.scene import Scene

X, Y, Z = 0, 1, 2
#: Joint groups of an arch, in the order of their ids.
GROUPS = ("voussoir", "springing", "base", "ring")
GROUND_HEIGHT_FRACTION = 0.25  # a ground plate is this fraction of the abutment's height


@dataclass
class ArchGeometry:
    """The voussoirs' quadrilaterals and the joints of an arch (m)."""

    quads: np.ndarray  # (n, 4, 2): intrados low, intrados high, extrados high, extrados low
    joints_in: np.ndarray  # (n + 1, 2) intrados end of each joint line (before the gap)
    joints_out: np.ndarray  # (n + 1, 2) extrados end
    normals: np.ndarray  # (n + 1, 2) unit normal of each joint, towards higher voussoirs
    centres: np.ndarray  # (n + 1, 2) centre of the arc whose radius the joint lies on
    radius: float  # centreline radius R (m)
    span: float  # centreline span L (m)
    thickness: float  # m
    crown_joint: int | None  # index of the crown joint (None: a keystone)
    keystone: int  # index (0-based) of the crown voussoir

    @property
    def count(self) -> int:
        return len(self.quads)


def arch_geometry(shape: str, radius: float, span: float, thickness: float, n: int,
                  gap: float = 0.0) -> ArchGeometry:
    """The geometry of the module docstring."""
    r_i, r_e = radius - thickness / 2.0, radius + thickness / 2.0
    if shape == "semicircular":
        theta = np.pi * np.arange(n + 1) / n
        u = np.stack([-np.cos(theta), np.sin(theta)], axis=1)
        normals = np.stack([np.sin(theta), np.cos(theta)], axis=1)
        centres = np.zeros((n + 1, 2))
        j_in, j_out = r_i * u, r_e * u
        crown = n // 2 if n % 2 == 0 else None
        if crown is not None:  # exactly vertical (sin, cos of pi/2 are not exact)
            normals[crown] = (1.0, 0.0)
            j_in[crown], j_out[crown] = (0.0, r_i), (0.0, r_e)
    else:
        c = radius - span / 2.0
        m = n // 2
        phi_c = math.acos(c / radius)
        phi = phi_c * np.arange(m) / m
        u = np.stack([-np.cos(phi), np.sin(phi)], axis=1)
        left_in = np.array([c, 0.0]) + r_i * u
        left_out = np.array([c, 0.0]) + r_e * u
        left_n = np.stack([np.sin(phi), np.cos(phi)], axis=1)
        top_in = np.array([[0.0, math.sqrt(r_i ** 2 - c ** 2)]])
        top_out = np.array([[0.0, math.sqrt(r_e ** 2 - c ** 2)]])
        mirror = np.array([-1.0, 1.0])
        j_in = np.concatenate([left_in, top_in, (left_in * mirror)[::-1]])
        j_out = np.concatenate([left_out, top_out, (left_out * mirror)[::-1]])
        # the right half's normals point the other way round the arc (towards higher numbers)
        normals = np.concatenate([left_n, [[1.0, 0.0]], (left_n * np.array([1.0, -1.0]))[::-1]])
        centres = np.concatenate([np.tile([c, 0.0], (m, 1)), [[np.nan, np.nan]],
                                  np.tile([-c, 0.0], (m, 1))])
        crown = m
    quads = np.empty((n, 4, 2))
    for k in range(n):
        lo, hi = k, k + 1
        shift_lo, shift_hi = 0.5 * gap * normals[lo], -0.5 * gap * normals[hi]
        quads[k] = [j_in[lo] + shift_lo, j_in[hi] + shift_hi, j_out[hi] + shift_hi,
                    j_out[lo] + shift_lo]
    keystone = crown if crown is not None else n // 2
    return ArchGeometry(quads, j_in, j_out, normals, centres, radius, span, thickness, crown,
                        keystone)


def prism_mesh(quad: np.ndarray, depth: float, divisions=(1, 1, 1)
               ) -> tuple[np.ndarray, np.ndarray]:
    """Hexahedral mesh (nodes (k, 3), cells (e, 8)) of the prism on the quadrilateral ``quad``
    (4, 2), counter-clockwise, extruded from z = 0 to ``depth``; ``divisions`` along the edge
    0-1, along the edge 0-3 and along z, mapped bilinearly."""
    U, conn = hex8.box_mesh(np.zeros(3), np.ones(3), tuple(divisions))
    s, r = U[:, 0:1], U[:, 1:2]
    xy = ((1 - s) * (1 - r) * quad[0] + s * (1 - r) * quad[1] + s * r * quad[2]
          + (1 - s) * r * quad[3])
    return np.column_stack([xy, depth * U[:, 2]]), conn


@dataclass
class Voussoir:
    """One voussoir of an arch or of a vault: its name, its role, the quadrilaterals of its
    cross-section (one per piece along the ring, in order, counter-clockwise; an arch's
    voussoir has one, a vault's whole voussoir two halves) and its extent along z (m)."""

    name: str
    role: str
    quads: np.ndarray  # (p, 4, 2)
    z: tuple[float, float]
    place: dict = field(default_factory=dict)  # the builder's place keys (voussoir, ring)

    def extrados_middle(self) -> np.ndarray:
        """The middle of the extrados face (m): the middle of the extrados chord of the middle
        piece, or the extrados corner between the two middle pieces."""
        q, p = self.quads, len(self.quads)
        xy = 0.5 * (q[p // 2][2] + q[p // 2][3]) if p % 2 else q[p // 2][3]
        return np.array([*xy, 0.5 * (self.z[0] + self.z[1])])

    def mesh(self, divisions=(1, 1, 1)) -> tuple[np.ndarray, np.ndarray]:
        """Hexahedral mesh (nodes, cells) of the voussoir: :func:`prism_mesh` of each piece,
        the nodes the pieces share merged (they are computed from the same joint line)."""
        z0, z1 = self.z
        nodes, cells, count = [], [], 0
        for q in self.quads:
            Xp, cp = prism_mesh(q, z1 - z0, divisions)
            Xp[:, 2] += z0
            nodes.append(Xp)
            cells.append(cp + count)
            count += len(Xp)
        X = np.concatenate(nodes)
        if len(self.quads) == 1:
            return X, cells[0]
        _, first, inverse = np.unique(X.round(12), axis=0, return_index=True,
                                      return_inverse=True)
        order = np.argsort(first)  # keep the nodes in their first order
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        return X[first[order]], rank[inverse.ravel()][np.concatenate(cells)]


def describe(case) -> str:
    """One line on an arch case (``masonry validate``)."""
    a, ld = case.arch, case.loading
    loads = ["gravity"]
    bf = ld.body_force
    if bf.active:
        loads.append(f"body force lambda {bf.multiplier:g} + {bf.rate_per_s:g}/s along "
                     f"({', '.join(f'{v:.3g}' for v in bf.direction)})")
    if ld.point_load is not None:
        loads.append(f"a force on {ld.point_load.block}")
    if ld.settlement is not None:
        loads.append(f"settlement of the {ld.settlement.support} support")
    return (f"{case.name}: {a.shape} arch of {a.voussoirs} voussoirs, radius "
            f"{a.centreline_radius_m:.4g} m, span {a.centreline_span_m:.4g} m, thickness "
            f"{a.thickness_m:.4g} m (t/R = {a.thickness_m / a.centreline_radius_m:.4g}), "
            f"{a.abutments} abutments, blocks {case.blocks.material}, joints {case.joint.law}; "
            f"{', '.join(loads)}; {until_collapse(case)}")


def _box(lo, hi) -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(lo, dtype=float)
    return hex8.box_mesh(lo, np.asarray(hi, dtype=float) - lo, (1, 1, 1))


def arch_voussoirs(a, geo: ArchGeometry) -> list[Voussoir]:
    """The voussoirs of an arch: one prism each on its quadrilateral, over the whole depth."""
    n = geo.count
    return [Voussoir(f"voussoir {k + 1}",
                     "left springer" if k == 0 else "right springer" if k == n - 1 else
                     "keystone" if k == geo.keystone and geo.crown_joint is None else "",
                     geo.quads[k:k + 1], (0.0, a.depth_m), {"voussoir": k + 1})
            for k in range(n)]


def build_arch(case) -> Scene:
    """The scene of an arch case (module docstring)."""
    a = case.arch
    geo = arch_geometry(a.shape, a.centreline_radius_m, a.centreline_span_m, a.thickness_m,
                        a.voussoirs, a.joint_thickness_m)
    meta = {"shape": a.shape, "radius_m": geo.radius, "span_m": geo.span,
            "thickness_m": geo.thickness, "depth_m": a.depth_m, "voussoirs": geo.count,
            "abutments": a.abutments, "crown_voussoir": geo.keystone + 1,
            "joint_centres_m": [None if not np.isfinite(c).all() else [float(c[0]), float(c[1])]
                                for c in geo.centres],
            "joints_intrados_m": geo.joints_in.tolist(),
            "joints_extrados_m": geo.joints_out.tolist()}
    return voussoir_scene(case, a, arch_voussoirs(a, geo), geo.keystone, "arch", meta)


def voussoir_scene(case, a, voussoirs: list[Voussoir], driven: int, builder: str,
                   meta: dict) -> Scene:
    """The scene of voussoirs (an arch's, a vault's) on the two abutments of the section ``a``
    (an ``Arch``: abutments, depth, joint thickness, mesh and contact points): the supports,
    the joints, the loads and the collapse rule of the module docstring. ``driven`` is the
    voussoir whose reference point is the curve's; ``meta`` goes into ``scene.json`` under
    ``builder``, with the supports' outlines (``supports_xy_m``) added."""
    blk, ld = case.blocks, case.loading
    t, depth, g = a.thickness_m, a.depth_m, a.joint_thickness_m
    L = a.centreline_span_m
    bodies: list = []
    info = []
    for v in voussoirs:
        bodies.append(structure_block(blk, *v.mesh(a.elements_per_voussoir), v.name))
        info.append({"name": v.name, **v.place, "role": v.role})
    n_vous = len(bodies)

    # --- abutments ----------------------------------------------------------------------------
    width = a.abutment_width_m if a.abutment_width_m is not None else 2.0 * t
    height = a.abutment_height_m if a.abutment_height_m is not None else t
    top = -0.5 * g  # top of the abutments
    settle = ld.settlement
    supports = {}
    for side, xs in (("left", -L / 2.0), ("right", L / 2.0)):
        imposed = support_motion(settle, settle is not None and settle.support == side)
        if a.abutments == "fixed":
            Xa, ca = _box((xs - width / 2, top - height, 0.0), (xs + width / 2, top, depth))
            bodies.append(RigidBody(center=Xa.mean(axis=0), mass=1.0, inertia=np.ones(3),
                                    imposed_velocity=imposed, name=f"{side} abutment", X=Xa,
                                    conn=ca, support=True))
        else:
            block = RigidBody.box((xs - width / 2, top - height, 0.0), (width, height, depth),
                                  blk.density_kg_m3, name=f"{side} abutment")
            bodies.append(block)
            info.append({"name": block.name, "voussoir": None, "role": f"{side} abutment"})
            y_ground = top - height - g
            hg = GROUND_HEIGHT_FRACTION * height
            Xg, cg = _box((xs - width, y_ground - hg, 0.0), (xs + width, y_ground, depth))
            supports[side] = len(bodies)
            bodies.append(RigidBody(center=Xg.mean(axis=0), mass=1.0, inertia=np.ones(3),
                                    imposed_velocity=imposed, name=f"{side} ground", X=Xg,
                                    conn=cg, support=True))
            continue
        supports[side] = len(bodies) - 1
    structure = [i for i, b in enumerate(bodies) if not getattr(b, "support", False)]
    # body_info is in the order of ``structure``: the voussoirs, then the block abutments
    # (appended in the loop above in that same order)

    # --- joints -------------------------------------------------------------------------------
    fixed = set(supports.values())

    def classify(joint, antagonist):
        pair = {joint.candidate.body, antagonist.body}
        if pair & fixed and not pair & set(range(n_vous)):
            name = "base"
        elif pair <= set(range(n_vous)):
            name = "ring" if abs(joint.normal[Z]) > 0.5 else "voussoir"
        else:
            name = "springing"
        return GROUPS.index(name), laws.KIND_JOINT, 0

    detection = find_joints(bodies, max_gap=g)
    points = joint_points(bodies, detection.joints, classify, n_gauss=a.contact_points_per_face,
                          rule=case.contact_point_rule)
    params = np.atleast_2d(laws.params_from_case(case.joint))

    # --- loads --------------------------------------------------------------------------------
    loads, stages, factors = limit_loads(
        case, bodies, structure,
        lambda k: voussoirs[k].extrados_middle() if k < n_vous else
        np.array([bodies[k].X[:, 0].mean(), bodies[k].X[:, 1].max(), 0.5 * depth]))
    stages.sort(key=lambda st: st.start_s)
    solver, rule = limit_settings(case, factors)
    meta = {**meta, "supports_xy_m": [[*bodies[i].X[:, :2].min(axis=0).tolist(),
                                       *bodies[i].X[:, :2].max(axis=0).tolist()]
                                      for i in supports.values()]}
    return Scene(
        name=case.name, builder=builder, bodies=bodies, points=points, groups=GROUPS,
        params=params, loads=loads, solver=solver, structure=structure, body_info=info,
        driven=driven, reactions={"top": supports["left"], "bottom": supports["right"]},
        stages=stages, push_stage="gravity", target_m=None,
        expected_end_s=case.collapse.end_time_s, time_limit_s=case.collapse.end_time_s, history={"kind": "monotonic", "cycles": []},
        collapse=rule,
        meta={"contact_point_rule": case.contact_point_rule, "limit_state": True,
              builder: meta},
    )


BUILDER = Builder("arch", build_arch, describe)
