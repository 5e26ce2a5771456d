"""Small verification scenes: a block between plates, a block on a support, a column.

Each builder returns an ``Integrator`` ready to step and a dict of the indices the checks need.
Coordinates: x horizontal (along the wall), y vertical (up), z out of plane; SI units.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.contact import joint_law as jl
from masonry_nscd.contact.points import dof_offsets, face_contacts
from masonry_nscd.loading import Ramp
from masonry_nscd.model import Block, Loads, RigidBody, at_rest
from masonry_nscd.nscd.integrator import Integrator

X, Y, Z = 0, 1, 2


def face_pattern(block: Block, dof0: int, ndof: int, axis: int, upper: bool, comp: int,
                 total: float) -> np.ndarray:
    """Nodal forces (N) of a uniform traction on one face of a block, ``total`` N along comp.

    Consistent for bilinear quads: each quad gives a quarter of its share to its four nodes.
    """
    F = np.zeros(ndof)
    area = 0.0
    quads = list(block.face_quads(axis, upper))
    for nodes, _, _, lo, hi in quads:
        area += np.prod(hi - lo)
    for nodes, _, _, lo, hi in quads:
        share = total * np.prod(hi - lo) / area
        for n in nodes:
            F[dof0 + 3 * n + comp] += 0.25 * share
    return F


def block_between_plates(size=(0.2, 0.1, 0.15), divisions=(2, 2, 1), E=11.1e9, nu=0.2,
                         force=50e3, ramp=0.1, h=1e-3, tolerance=1e-8, plate_mass=100.0):
    """A block compressed by a force on a free rigid top plate, on a fixed bottom plate.

    Frictionless Signorini contacts (no spring), so the block is in uniaxial stress and the
    plate settles at ``force L / (E A)``. The plate mass matters to the Gauss-Seidel sweeps
    only: a plate much lighter than ``(theta h)^2 K`` of the block makes the Delassus blocks of
    its points nearly rank one, and the sweeps slow down accordingly.
    """
    block = Block(origin=(0, 0, 0), size=size, divisions=divisions, E=E, nu=nu, density=2000.0)
    bottom = RigidBody.fixed(center=(size[0] / 2, -0.05, size[2] / 2), label="bottom plate")
    top = RigidBody(center=(size[0] / 2, size[1] + 0.05, size[2] / 2), mass=plate_mass,
                    inertia=np.ones(3),
                    imposed_velocity={d: at_rest for d in (0, 2, 3, 4, 5)}, label="top plate")
    bodies = [block, bottom, top]
    dof0 = dof_offsets(bodies)
    P = jl.joint_params(law="coulomb", mu=0.0)
    kw = {"gap": 0.0, "tangent": (1, 0, 0), "kind": jl.KIND_JOINT, "law": 0, "group": 0}
    pts = face_contacts(bodies, dof0, 0, block, Y, False, [(1, None)], **kw)
    pts += face_contacts(bodies, dof0, 0, block, Y, True, [(2, None)], **kw)
    loads = Loads()
    F = np.zeros(dof0[-1])
    F[dof0[2] + Y] = -force
    loads.add(F, Ramp(1.0, 0.0, ramp))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=1.0, tolerance=tolerance,
                       max_iterations=20000, check_every=1)
    return integ, {"top_dof": int(dof0[2] + Y), "stiffness": E * size[0] * size[2] / size[1]}


def block_on_support(*, law: str = "coulomb", mu: float = 0.6, normal_force: float = 10e3,
                     shear_force: float = 0.0, rigid: bool = False, divisions=(2, 2, 1),
                     size=(0.3, 0.1, 0.15), h=1e-3, tolerance=1e-10, shear_start=0.1,
                     shear_ramp=0.1, shear_velocity: float | None = None, joint_kw=None):
    """A block on a fixed support, pressed by ``normal_force`` (N) and pushed sideways.

    The normal force is a uniform pressure on the top face ramped over [0, 0.05] s. The shear is
    either a horizontal force ``shear_force`` (N, distributed with the mass, like a horizontal
    acceleration, ramped from ``shear_start`` over ``shear_ramp``), or, for a rigid block
    (``shear_velocity``, m/s), an imposed horizontal velocity with the rotations blocked.
    """
    joint_kw = dict(joint_kw or {})
    P = jl.joint_params(law=law, mu=mu, **joint_kw)
    support = RigidBody.fixed(center=(size[0] / 2, -0.05, size[2] / 2), label="support")
    if rigid:
        imposed = {d: at_rest for d in (2, 3, 4, 5)}
        if shear_velocity is not None:
            imposed[0] = Ramp(shear_velocity, shear_start, shear_ramp)
        body = RigidBody.box((0, 0, 0), size, 2000.0, imposed_velocity=imposed, label="block")
        geom = Block(origin=(0, 0, 0), size=size, divisions=divisions, E=1.0, nu=0.0,
                     density=2000.0)
    else:
        body = geom = Block(origin=(0, 0, 0), size=size, divisions=divisions, E=11.1e9, nu=0.2,
                            density=2000.0)
    bodies = [body, support]
    dof0 = dof_offsets(bodies)
    n = int(dof0[-1])
    pts = face_contacts(bodies, dof0, 0, geom, Y, False, [(1, None)], gap=0.0,
                        tangent=(1, 0, 0), kind=jl.KIND_JOINT, law=0, group=0)
    loads = Loads()
    if rigid:
        Fn = np.zeros(n)
        Fn[Y] = -normal_force
        mass = body.mass
    else:
        Fn = face_pattern(body, 0, n, Y, True, Y, -normal_force)
        mass = body.density * float(np.prod(size))
    loads.add(Fn, Ramp(1.0, 0.0, 0.05))
    if shear_force:
        Fs = np.zeros(n)
        if rigid:
            Fs[X] = shear_force
        else:
            m = body.lumped_mass()
            Fs[X:body.ndof:3] = shear_force * m[X::3] / m[X::3].sum()
        loads.add(Fs, Ramp(1.0, shear_start, shear_ramp))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=1.0, tolerance=tolerance,
                       max_iterations=20000, check_every=1)
    return integ, {"mass": mass, "area": size[0] * size[2], "dofs_x": slice(X, body.ndof, 3)
                   if not rigid else slice(0, 1)}


def column(n_blocks: int = 3, size=(0.3, 0.1, 0.15), divisions=(2, 2, 1), joint=0.01,
           gravity=9.81, h=2e-3, tolerance=1e-8, joint_kw=None):
    """A column of blocks under gravity; joints with the joint law, the lowest glued to a support.
    """
    P = jl.joint_params(**dict(joint_kw or {}))
    blocks = [Block(origin=(0, i * (size[1] + joint), 0), size=size, divisions=divisions,
                    E=11.1e9, nu=0.2, density=2000.0, label=f"block {i}")
              for i in range(n_blocks)]
    support = RigidBody.fixed(center=(size[0] / 2, -0.05, size[2] / 2), label="support")
    bodies = [*blocks, support]
    dof0 = dof_offsets(bodies)
    pts = face_contacts(bodies, dof0, 0, blocks[0], Y, False, [(n_blocks, None)], gap=0.0,
                        tangent=(1, 0, 0), kind=jl.KIND_GLUED, law=0, group=1)
    for i in range(1, n_blocks):
        pts += face_contacts(bodies, dof0, i, blocks[i], Y, False, [(i - 1, blocks[i - 1])],
                             gap=joint, tangent=(1, 0, 0), kind=jl.KIND_JOINT, law=0, group=0)
    loads = Loads()
    G = np.zeros(dof0[-1])
    weight = 0.0
    for i, b in enumerate(blocks):
        m = b.lumped_mass()
        G[dof0[i] + Y:dof0[i + 1]:3] = -gravity * m[Y::3]
        weight += gravity * m[Y::3].sum()
    loads.add(G, Ramp(1.0, 0.0, 0.1))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=1.0, tolerance=tolerance,
                       max_iterations=20000, check_every=1)
    return integ, {"weight": weight}
