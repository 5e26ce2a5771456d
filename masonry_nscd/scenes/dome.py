r"""The dome: a builder of voussoirs in courses on a fixed ring (lengths in m, angles in rad).

Coordinates: y up along the dome's axis, the springing plane at y = 0, the azimuth ``phi``
from x towards z. The meridian is the arc of radius ``R`` (the centreline) about a centre on
the springing plane ``c = R - span / 2`` beyond the axis (0 for a hemisphere); a point of the
shell at ``rho`` from that centre (``R - t/2`` at the intrados, ``R + t/2`` at the extrados),
at the arc's angle ``alpha`` from the springing and at azimuth ``phi`` is

    r_h = rho cos(alpha) - c,     (x, y, z) = (r_h cos(phi), rho sin(alpha), r_h sin(phi)).

The courses cut ``alpha`` from 0 to the apex's angle less the oculus into equal parts; the
azimuth is cut into ``2 n`` equal half voussoirs (n voussoirs per course), and a voussoir is
two of them, the halves ``2k, 2k + 1`` in a course, ``2k + 1, 2k + 2`` in a staggered one.
Each half is a hexahedron on the eight points of its two angles, two radii and two azimuths:
its faces are flat (each a trapezoid symmetric about its middle, or a meridian plane), and a
bed face of a half is the top face of the half below it, so that every joint meets face to
face, a staggered voussoir on the halves of two voussoirs below. The ring under the lowest
course is one fixed body of ``2 n`` hexahedra, ``t`` deep below the springing plane.

Joint groups: ``bed`` between courses, ``head`` between the voussoirs of a course (the
meridional joints), ``base`` on the ring. Loads, solver and collapse rule are those of every
limit-state scene (:mod:`masonry_nscd.scenes.limit_loads`), plus the lantern: ``lantern_N``
downwards on the top course, an equal share at the middle of each voussoir's top face, ramped
with gravity.
"""

from __future__ import annotations

import math

import numpy as np

from masonry_nscd.contact import laws
from masonry_nscd.loading import Ramp, at_rest
from masonry_nscd.model import RigidBody, dof_offsets
from masonry_nscd.model.detection import find_joints, joint_points
from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.limit_loads import (
    limit_loads,
    limit_settings,
    structure_block,
    until_collapse,
)
from masonry_nscd.scenes.scene import Scene

GROUPS = ("bed", "head", "base")
#: The nodes of a half voussoir's hexahedron (VTK order), as (azimuth, radius, angle) indices
#: into its 2 x 2 x 2 corners: the azimuth, the radius and the angle increase along the
#: hexahedron's xi, eta and zeta (a right-handed frame: positive Jacobian)
_HEX_CORNERS = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
                (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1))


def shell_point(d, rho: float, alpha: float, phi: float) -> np.ndarray:
    """The point of dome section ``d`` at ``rho`` from the meridian's centre, at the arc's
    angle ``alpha`` and the azimuth ``phi`` (module docstring), m."""
    rh = rho * math.cos(alpha) - d.offset_m
    return np.array([rh * math.cos(phi), rho * math.sin(alpha), rh * math.sin(phi)])


def levels(d) -> np.ndarray:
    """The angles of the bed joints, from the springing to the oculus (courses + 1), rad."""
    top = math.radians(d.apex_deg - d.oculus_deg)
    return np.linspace(0.0, top, d.courses + 1)


def voussoir_mesh(d, alpha0: float, alpha1: float, halves: list[int]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The nodes (m) and hexahedra of the voussoir made of the half voussoirs ``halves``
    (consecutive, mod 2n) between the angles ``alpha0`` and ``alpha1``: one hexahedron per
    half, sharing the faces between them. The nodes run over azimuth, radius and angle, the
    angle fastest: the odd ones are the top face's."""
    radii = (d.radius_m - d.thickness_m / 2.0, d.radius_m + d.thickness_m / 2.0)
    phis = [math.pi * h / d.voussoirs for h in halves] + \
        [math.pi * (halves[-1] + 1) / d.voussoirs]
    X, index = [], {}
    for a, phi in enumerate(phis):
        for r, rho in enumerate(radii):
            for g, alpha in enumerate((alpha0, alpha1)):
                index[a, r, g] = len(X)
                X.append(shell_point(d, rho, alpha, phi))
    conn = [[index[a + da, dr, dg] for da, dr, dg in _HEX_CORNERS]
            for a in range(len(halves))]
    return np.array(X), np.array(conn, dtype=np.int64)


def base_ring(d) -> tuple[np.ndarray, np.ndarray]:
    """The fixed ring under the lowest course: ``2 n`` hexahedra whose top faces are the bed
    faces of the lowest course's halves, ``thickness`` deep (m). Neighbouring hexahedra share
    their nodes, so the faces between them are inside the ring: they are no faces of its
    boundary, where the detection would find them level with the head joints of the lowest
    course, and make joints along the springing line that hold its voussoirs sideways."""
    radii = (d.radius_m - d.thickness_m / 2.0, d.radius_m + d.thickness_m / 2.0)
    halves = 2 * d.voussoirs
    X, index = [], {}
    for h in range(halves):
        phi = math.pi * h / d.voussoirs
        for r, rho in enumerate(radii):
            top = shell_point(d, rho, 0.0, phi)
            for g, y in enumerate((-d.thickness_m, 0.0)):
                index[h, r, g] = len(X)
                X.append(np.array([top[0], y, top[2]]))
    conn = [[index[(h + a) % halves, r, g] for a, r, g in _HEX_CORNERS] for h in range(halves)]
    return np.array(X), np.array(conn, dtype=np.int64)


def course_halves(d, course: int, k: int) -> list[int]:
    """The half voussoirs (mod 2n) of voussoir ``k`` (from 0) of course ``course`` (from 1)."""
    shift = 1 if d.stagger and course % 2 == 0 else 0
    return [(2 * k + shift) % (2 * d.voussoirs), (2 * k + shift + 1) % (2 * d.voussoirs)]


def describe(case) -> str:
    """One line on a dome case (``masonry validate``)."""
    d = case.dome
    return (f"{case.name}: {d.shape} dome of {d.courses} courses x {d.voussoirs} voussoirs"
            f"{' (staggered)' if d.stagger and d.courses > 1 else ''}, radius "
            f"{d.radius_m:.4g} m, span {d.centreline_span_m:.4g} m, thickness "
            f"{d.thickness_m:.4g} m, oculus {d.oculus_deg:g} deg"
            + (f", lantern {d.lantern_N:g} N" if d.lantern_N else "")
            + f", blocks {case.blocks.material}, joints {case.joint.law}; "
            + until_collapse(case))


def build_dome(case) -> Scene:
    """The scene of a dome case (module docstring)."""
    d, blk = case.dome, case.blocks
    alphas = levels(d)
    bodies: list = []
    info = []
    for i in range(1, d.courses + 1):
        for k in range(d.voussoirs):
            X, conn = voussoir_mesh(d, alphas[i - 1], alphas[i], course_halves(d, i, k))
            name = f"course {i} voussoir {k + 1}"
            bodies.append(structure_block(blk, X, conn, name))
            info.append({"name": name, "course": i, "voussoir": k + 1})
    structure = list(range(len(bodies)))
    course_of = [place["course"] for place in info]
    Xb, cb = base_ring(d)
    base = len(bodies)
    bodies.append(RigidBody(center=Xb.mean(axis=0), mass=1.0, inertia=np.ones(3),
                            imposed_velocity=dict.fromkeys(range(6), at_rest), name="base",
                            X=Xb, conn=cb, support=True))

    def classify(joint, antagonist):
        a, b = joint.candidate.body, antagonist.body
        if base in (a, b):
            return GROUPS.index("base"), laws.KIND_JOINT, 0
        same = course_of[a] == course_of[b]
        return GROUPS.index("head" if same else "bed"), laws.KIND_JOINT, 0

    detection = find_joints(bodies, max_gap=0.0)
    points = joint_points(bodies, detection.joints, classify,
                          n_gauss=d.contact_points_per_face, rule=case.contact_point_rule)
    params = np.atleast_2d(laws.params_from_case(case.joint))

    def top_middle(k: int) -> np.ndarray:
        """The middle of the top face of voussoir ``k``: its nodes at the upper angle."""
        return bodies[k].X[1::2].mean(axis=0)

    loads, stages, factors = limit_loads(case, bodies, structure, top_middle)
    if d.lantern_N:
        top_course = [k for k in structure if course_of[k] == d.courses]
        loads.add(_lantern_pattern(bodies, top_course, top_middle, d.lantern_N),
                  Ramp(1.0, case.loading.gravity.start_s, case.loading.gravity.ramp_s))
    stages.sort(key=lambda st: st.start_s)
    solver, rule = limit_settings(case, factors)
    col = case.collapse
    driven = structure[-d.voussoirs]  # the top course's first voussoir
    meta = {"shape": d.shape, "radius_m": d.radius_m, "span_m": d.centreline_span_m,
            "thickness_m": d.thickness_m, "courses": d.courses, "voussoirs": d.voussoirs,
            "stagger": bool(d.stagger), "oculus_deg": d.oculus_deg, "lantern_N": d.lantern_N,
            "blocks": len(structure)}
    return Scene(
        name=case.name, builder="dome", bodies=bodies, points=points, groups=GROUPS,
        params=params, loads=loads, solver=solver, structure=structure, body_info=info,
        driven=driven, reactions={"bottom": base}, stages=stages, push_stage="gravity",
        target_m=None, expected_end_s=col.end_time_s, time_limit_s=col.end_time_s,
        history={"kind": "monotonic", "cycles": []}, collapse=rule,
        meta={"contact_point_rule": case.contact_point_rule, "limit_state": True,
              "reaction_names": ["base", "base"], "dome": meta},
    )


def _lantern_pattern(bodies: list, course: list[int], top_middle, force_N: float
                     ) -> np.ndarray:
    """The lantern's force (N) shared by the voussoirs ``course``, downwards at the middle
    of each one's top face (with its moment about a rigid body's reference point)."""
    dof0 = dof_offsets(bodies)
    F = np.zeros(int(dof0[-1]))
    share = np.array([0.0, -force_N / len(course), 0.0])
    for k in course:
        b, at = bodies[k], top_middle(k)
        if isinstance(b, RigidBody):
            F[dof0[k]:dof0[k] + 3] += share
            F[dof0[k] + 3:dof0[k] + 6] += np.cross(at - b.reference, share)
        else:
            d2 = np.linalg.norm(b.X - at, axis=1)
            near = np.flatnonzero(d2 <= d2.min() + 1e-9 * (1.0 + d2.min()))
            for node in near:
                F[dof0[k] + 3 * node:dof0[k] + 3 * node + 3] += share / len(near)
    return F


BUILDER = Builder("dome", build_dome, describe)
