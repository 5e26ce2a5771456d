"""The running-bond wall between two rigid steel beams (model.md section 1).

Courses are numbered from the bottom, 0-based here: course 0 (the study's first course) and
every other one are full courses of ``units_per_course`` whole units; courses 1, 3, ... start
and end with a half unit (running bond). Coordinates: x along the wall from its left end, y up
from the top of the lower beam, z through the thickness.

Contacts (all permanent):

* bed joint: the bottom face of every unit of course k >= 1 (candidate) against the units of
  course k - 1 below (antagonist), normal +y, initial gap = joint thickness;
* head joint: the left face of unit i + 1 (candidate) against unit i, normal +x;
* glue: the bottom face of course 0 on the lower beam (fixed), the top face of the last course
  on the upper beam; bilateral, no gap.

The upper beam: x driven (velocity ramp to the loading rate), y loaded by the vertical
stress times the wall's plan area (or held, ``supports.top_vertical: fixed``), z and rotations
blocked (the in-plane one free with ``supports.top_rotation: free``). The lower beam is fixed. Gravity acts on the units (lumped masses), not on the beams.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from masonry_nscd.contact import joint_law as jl
from masonry_nscd.contact.points import dof_offsets, face_contacts
from masonry_nscd.loading import Ramp
from masonry_nscd.model import MAT_ELASTIC, MAT_ENDO3D, Block, Loads, RigidBody, at_rest
from masonry_nscd.nscd.integrator import Integrator

X, Y, Z = 0, 1, 2
GROUP_BED, GROUP_HEAD, GROUP_GLUE_BOTTOM, GROUP_GLUE_TOP = 0, 1, 2, 3
GROUP_NAMES = ("bed", "head", "glue_bottom", "glue_top")


@dataclass
class WallScene:
    """The wall ready to step, and what the recorders need to read it."""

    integrator: Integrator
    units: list[Block]  # geometry of every unit (also for rigid units)
    course_of_unit: np.ndarray
    top_beam: int  # body index
    top_dof_x: int
    top_dof_y: int
    group: np.ndarray  # (npt,) GROUP_*
    material: str  # block material actually used


def unit_boxes(wall) -> list[tuple[int, float, float, float]]:
    """(course, x0, y0, length) of every unit, bottom course first, left to right (m)."""
    L, hgt, j = wall.unit_length_m, wall.unit_height_m, wall.joint_thickness_m
    out = []
    for k in range(wall.courses):
        y0 = k * (hgt + j)
        if wall.bond == "running" and k % 2 == 1:
            lengths = [wall.half_unit_length_m] + [L] * (wall.units_per_course - 1) + \
                      [wall.half_unit_length_m]
        else:
            lengths = [L] * wall.units_per_course
        x = 0.0
        for length in lengths:
            out.append((k, x, y0, length))
            x += length + j
    return out


def joint_params_from_case(case) -> np.ndarray:
    """The joint-law parameter vector of a case's ``joint`` section."""
    jt = case.joint
    return jl.joint_params(
        K_I_spring=jt.K_I_spring_Pa_m, K_II_spring=jt.K_II_spring_Pa_m, d_spring=jt.d_spring,
        sigma_I_e=jt.sigma_I_e_Pa, K_I_coh=jt.K_I_coh_Pa_m, G_fI=jt.G_fI_J_m2,
        sigma_II_e=jt.sigma_II_e_Pa, K_II_coh=jt.K_II_coh_Pa_m, G_fII=jt.G_fII_J_m2,
        d_coh_initial=jt.d_coh_initial, mu=jt.mu, p=jt.p, eta=jt.eta,
        compression_spring=jt.compression_spring, law=jt.law,
    )


def build_wall(case) -> WallScene:
    """Build bodies, contact points, loads and the integrator of a wall case."""
    w, blk, sol = case.wall, case.blocks, case.solver
    material = blk.material
    units = [
        Block(origin=(x0, y0, 0.0), size=(length, w.unit_height_m, w.thickness_m),
              divisions=tuple(w.elements_per_unit), E=blk.E_Pa, nu=blk.nu,
              density=blk.density_kg_m3, label=f"course {k} x {x0:.3f}",
              material=MAT_ENDO3D if material == "endo3d" else MAT_ELASTIC)
        for k, x0, y0, length in unit_boxes(w)
    ]
    course = np.array([k for k, *_ in unit_boxes(w)])
    if material == "rigid":
        bodies: list = [RigidBody.box(u.origin, u.size, blk.density_kg_m3, label=u.label)
                        for u in units]
    else:
        bodies = list(units)
    nu_ = len(units)
    width, height, t = w.wall_length_m, w.wall_height_m, w.thickness_m
    lower = RigidBody.fixed(center=(width / 2, -0.1, t / 2), label="lower beam")
    hz = case.loading.horizontal
    imposed = {X: Ramp(hz.rate_m_s, hz.start_s, hz.ramp_s), Z: at_rest, 3: at_rest, 4: at_rest,
               5: at_rest}
    if case.supports.top_vertical == "fixed":
        imposed[Y] = at_rest
    m_beam = case.supports.top_beam_mass_kg
    # in-plane rotational inertia of a beam as long as the wall and 0.2 m tall (kg m^2); the
    # other two rotations are held
    inertia = np.array([1.0, 1.0, m_beam * (width ** 2 + 0.2 ** 2) / 12.0])
    if case.supports.top_rotation == "free":
        del imposed[5]
    upper = RigidBody(center=(width / 2, height + 0.1, t / 2), mass=m_beam,
                      inertia=inertia, imposed_velocity=imposed, label="upper beam")
    bodies += [lower, upper]
    i_low, i_up = nu_, nu_ + 1
    dof0 = dof_offsets(bodies)
    ng = w.contact_points_per_face
    j = w.joint_thickness_m
    pts = []
    by_course = [[i for i in range(nu_) if course[i] == k] for k in range(w.courses)]
    for k, members in enumerate(by_course):
        for n, i in enumerate(members):
            if k == 0:
                pts += face_contacts(bodies, dof0, i, units[i], Y, False, [(i_low, None)],
                                     gap=0.0, tangent=(1, 0, 0), kind=jl.KIND_GLUED, law=0,
                                     group=GROUP_GLUE_BOTTOM, n_gauss=ng)
            else:
                below = [(b, units[b]) for b in by_course[k - 1]]
                pts += face_contacts(bodies, dof0, i, units[i], Y, False, below, gap=j,
                                     tangent=(1, 0, 0), kind=jl.KIND_JOINT, law=0,
                                     group=GROUP_BED, n_gauss=ng)
            if n > 0:
                left = members[n - 1]
                pts += face_contacts(bodies, dof0, i, units[i], X, False,
                                     [(left, units[left])], gap=j, tangent=(0, 1, 0),
                                     kind=jl.KIND_JOINT, law=0, group=GROUP_HEAD, n_gauss=ng)
            if k == w.courses - 1:
                pts += face_contacts(bodies, dof0, i, units[i], Y, True, [(i_up, None)],
                                     gap=0.0, tangent=(1, 0, 0), kind=jl.KIND_GLUED, law=0,
                                     group=GROUP_GLUE_TOP, n_gauss=ng)
    P = joint_params_from_case(case)
    loads = Loads()
    ndof = int(dof0[-1])
    G = np.zeros(ndof)
    for i, b in enumerate(bodies[:nu_]):
        if isinstance(b, RigidBody):
            G[dof0[i] + Y] = -b.mass
        else:
            G[dof0[i] + Y:dof0[i + 1]:3] = -b.lumped_mass()[Y::3]
    g = case.loading.gravity
    loads.add(G, Ramp(g.value_m_s2, g.start_s, g.ramp_s))
    if case.supports.top_vertical == "load":
        vs = case.loading.vertical_stress
        Fv = np.zeros(ndof)
        Fv[dof0[i_up] + Y] = -vs.value_Pa * width * t
        loads.add(Fv, Ramp(1.0, vs.start_s, vs.ramp_s))
    endo = None
    if material == "endo3d":
        from masonry_nscd.materials.point_driver import params_from_case

        endo = params_from_case(case)
    integ = Integrator(bodies, pts, P, loads, h=sol.time_step_s, theta=sol.theta,
                       tolerance=sol.tolerance, max_iterations=sol.max_iterations,
                       check_every=sol.check_every, method=sol.method, endo3d_params=endo,
                       endo3d_tau=case.blocks.endo3d.relaxation_time_s,
                       max_halvings=sol.max_step_halvings)
    return WallScene(
        integrator=integ, units=units, course_of_unit=course, top_beam=i_up,
        top_dof_x=int(dof0[i_up] + X), top_dof_y=int(dof0[i_up] + Y),
        group=np.array([p.group for p in pts], dtype=np.int64),
        material=material,
    )
