"""Small verification scenes: a block between plates, a block on a support, a column.

Each builder returns an ``Integrator`` ready to step and a dict of the indices the checks need.
Coordinates: x horizontal (along the wall), y vertical (up), z out of plane; SI units. The
joints are found by contact detection (:mod:`masonry_nscd.model.detection`), as in a wall.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.contact.laws import KIND_GLUED, KIND_JOINT, fczm
from masonry_nscd.fe import hex8
from masonry_nscd.loading import Loads, Ramp, RampedVelocity, at_rest, smooth_step
from masonry_nscd.loading.ground_motion import GroundMotion
from masonry_nscd.loading.multiplier import GrowingMultiplier
from masonry_nscd.model import Block, RigidBody, dof_offsets
from masonry_nscd.model.detection import contact_points
from masonry_nscd.model.faces import boundary_quads, quad_frame
from masonry_nscd.nscd import kernels
from masonry_nscd.nscd.integrator import Integrator
from masonry_nscd.scenes.scene import CollapseRule, LoadFactor, Scene, SolverSettings, Stage

X, Y, Z = 0, 1, 2


def _plate(center, size, **kw) -> RigidBody:
    """A rigid plate (a support: the blocks carry the points) of box geometry ``size`` (m)."""
    c, size = np.asarray(center, float), np.asarray(size, float)
    X_, conn = hex8.box_mesh(c - 0.5 * size, size, (1, 1, 1))
    return RigidBody(center=c, X=X_, conn=conn, support=True, **kw)


def _fixed_plate(center, size) -> RigidBody:
    c, size = np.asarray(center, float), np.asarray(size, float)
    X_, conn = hex8.box_mesh(c - 0.5 * size, size, (1, 1, 1))
    return RigidBody.fixed(center=c, X=X_, conn=conn)


def face_pattern(block: Block, dof0: int, ndof: int, normal, comp: int,
                 total: float) -> np.ndarray:
    """Nodal forces (N) of a uniform traction on the faces of a block of outward ``normal``,
    ``total`` N along ``comp``.

    Consistent for parallelogram quads: each quad gives a quarter of its share to its four nodes.
    """
    quads = boundary_quads(block.conn)
    n, _ = quad_frame(block.X[quads])
    quads = quads[n @ np.asarray(normal, float) > 1.0 - 1e-9]
    P = block.X[quads]
    areas = 0.5 * np.linalg.norm(np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1]), axis=-1)
    F = np.zeros(ndof)
    for nodes, a in zip(quads, areas):
        for node in nodes:
            F[dof0 + 3 * node + comp] += 0.25 * total * a / areas.sum()
    return F


def _all_joints(kind=KIND_JOINT):
    return lambda joint, antagonist: (0, kind, 0)


def block_between_plates(size=(0.2, 0.1, 0.15), divisions=(2, 2, 1), E=11.1e9, nu=0.2,
                         force=50e3, ramp=0.1, h=1e-3, tolerance=1e-8, plate_mass=100.0):
    """A block compressed by a force on a free rigid top plate, on a fixed bottom plate.

    Frictionless Signorini contacts (no spring), so the block is in uniaxial stress and the
    plate settles at ``force L / (E A)``. The plate mass matters to the Gauss-Seidel sweeps
    only: a plate much lighter than ``(theta h)^2 K`` of the block makes the Delassus blocks of
    its points nearly rank one, and the sweeps slow down accordingly.
    """
    block = Block.box((0, 0, 0), size, divisions, E=E, nu=nu, density=2000.0)
    plate = (size[0], 0.1, size[2])
    bottom = _fixed_plate((size[0] / 2, -0.05, size[2] / 2), plate)
    top = _plate((size[0] / 2, size[1] + 0.05, size[2] / 2), plate, mass=plate_mass,
                 inertia=np.ones(3), imposed_velocity={d: at_rest for d in (0, 2, 3, 4, 5)},
                 name="top plate")
    bodies = [block, bottom, top]
    dof0 = dof_offsets(bodies)
    pts = contact_points(bodies, _all_joints(), max_gap=0.0)
    loads = Loads()
    F = np.zeros(dof0[-1])
    F[dof0[2] + Y] = -force
    loads.add(F, Ramp(1.0, 0.0, ramp))
    integ = Integrator(bodies, pts, fczm.joint_params(law="coulomb", mu=0.0), loads, h=h,
                       theta=1.0, tolerance=tolerance, max_iterations=20000, check_every=1)
    return integ, {"top_dof": int(dof0[2] + Y), "stiffness": E * size[0] * size[2] / size[1]}


def block_on_support(*, law: str = "coulomb", mu: float = 0.6, normal_force: float = 10e3,
                     shear_force: float = 0.0, rigid: bool = False, divisions=(2, 2, 1),
                     size=(0.3, 0.1, 0.15), h=1e-3, tolerance=1e-10, shear_start=0.1,
                     shear_ramp=0.1, shear_velocity: float | None = None, joint_kw=None,
                     method: str = "nlgs"):
    """A block on a fixed support, pressed by ``normal_force`` (N) and pushed sideways.

    The normal force is a uniform pressure on the top face ramped over [0, 0.05] s. The shear is
    either a horizontal force ``shear_force`` (N, distributed with the mass, like a horizontal
    acceleration, ramped from ``shear_start`` over ``shear_ramp``), or, for a rigid block
    (``shear_velocity``, m/s), an imposed horizontal velocity with the rotations blocked.
    """
    P = fczm.joint_params(law=law, mu=mu, **dict(joint_kw or {}))
    support = _fixed_plate((size[0] / 2, -0.05, size[2] / 2), (size[0], 0.1, size[2]))
    if rigid:
        imposed = {d: at_rest for d in (2, 3, 4, 5)}
        if shear_velocity is not None:
            imposed[0] = RampedVelocity(shear_velocity, shear_start, shear_ramp)
        body = RigidBody.box((0, 0, 0), size, 2000.0, divisions, imposed_velocity=imposed,
                             name="block")
    else:
        body = Block.box((0, 0, 0), size, divisions, E=11.1e9, nu=0.2, density=2000.0)
    bodies = [body, support]
    dof0 = dof_offsets(bodies)
    n = int(dof0[-1])
    pts = contact_points(bodies, _all_joints(), max_gap=0.0)
    loads = Loads()
    if rigid:
        Fn = np.zeros(n)
        Fn[Y] = -normal_force
        mass = body.mass
    else:
        Fn = face_pattern(body, 0, n, (0, 1, 0), Y, -normal_force)
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
                       max_iterations=20000, check_every=1, method=method)
    return integ, {"mass": mass, "area": size[0] * size[2], "dofs_x": slice(X, body.ndof, 3)
                   if not rigid else slice(0, 1)}


def column(n_blocks: int = 3, size=(0.3, 0.1, 0.15), divisions=(2, 2, 1), joint=0.01,
           gravity=9.81, h=2e-3, tolerance=1e-8, joint_kw=None):
    """A column of blocks under gravity; joints with the joint law (group 0), the lowest block
    glued to a support (group 1)."""
    P = fczm.joint_params(**dict(joint_kw or {}))
    blocks = [Block.box((0, i * (size[1] + joint), 0), size, divisions, E=11.1e9, nu=0.2,
                        density=2000.0, name=f"block {i}") for i in range(n_blocks)]
    support = _fixed_plate((size[0] / 2, -0.05, size[2] / 2), (size[0], 0.1, size[2]))
    bodies = [*blocks, support]
    dof0 = dof_offsets(bodies)

    def classify(jt, antagonist):
        return (1, KIND_GLUED, 0) if antagonist.body == n_blocks else (0, KIND_JOINT, 0)

    pts = contact_points(bodies, classify, max_gap=joint)
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


def _rotation_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def block_on_incline(angle_deg: float, *, law: str = "coulomb", mu: float = 0.6,
                     size=(0.3, 0.1, 0.15), divisions=(2, 1, 1), h=1e-3, tolerance=1e-10,
                     gravity=9.81, ramp=0.05, method: str = "nlgs", joint_kw=None):
    """A rigid block (2000 kg/m^3) on a fixed plane inclined by ``angle_deg`` about z, free in its
    six dofs, under gravity ``-gravity`` along y ramped over ``ramp`` s.

    The plane rises towards +x; the block's bottom face lies on it, its points at the Gauss
    points of that face. ``info["slope"]`` is the unit vector up the slope: a sliding block
    accelerates along ``-slope`` at ``g (sin a - mu cos a)``.
    """
    a = np.radians(angle_deg)
    Q = _rotation_z(a)
    P = fczm.joint_params(law=law, mu=mu, **dict(joint_kw or {}))
    Xp, cp = hex8.box_mesh((-0.5, -0.1, -0.1), (1.0 + size[0], 0.1, 0.2 + size[2]), (1, 1, 1))
    Xb, cb = hex8.box_mesh((0.0, 0.0, 0.0), size, divisions)
    plane = RigidBody.fixed(center=Q @ Xp.mean(axis=0), X=Xp @ Q.T, conn=cp)
    block = RigidBody.from_mesh(Xb @ Q.T, cb, 2000.0, name="block")
    bodies = [block, plane]
    n = int(dof_offsets(bodies)[-1])
    pts = contact_points(bodies, _all_joints(), max_gap=0.0)
    loads = Loads()
    G = np.zeros(n)
    G[:6] = block.weight_load(np.array([0.0, -gravity, 0.0]))
    loads.add(G, Ramp(1.0, 0.0, ramp))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=1.0, tolerance=tolerance,
                       max_iterations=20000, check_every=1, method=method)
    return integ, {"mass": block.mass, "slope": Q[:, 0]}


def slender_block_pushed(*, width=0.1, height=0.4, depth=0.15, normal_force=2e3, mu=0.6,
                         law: str = "coulomb", push_velocity=2e-3, push_start=0.1,
                         push_ramp=0.02, gravity=9.81, h=1e-3, divisions=(2, 4, 1),
                         tolerance=1e-10, method: str = "nlgs", joint_kw=None,
                         rule: str = "lobatto"):
    """A slender rigid block (2000 kg/m^3; ``width`` along x, ``height`` along y) on a fixed
    support, under its weight and a vertical force ``normal_force`` (N) through its centre (both
    ramped over [0, 0.05] s), pushed along +x at the middle of its top face at a horizontal
    velocity ``push_velocity`` (m/s, ramped from ``push_start`` over ``push_ramp``).

    The block's dofs move that top point (``reference``); its horizontal dof is imposed, its
    vertical translation and its rotation about z are free, the others held. It tips about its
    toe when the push reaches ``(W + N) width / (2 height)``, if friction holds that much
    (``width / (2 height) < mu``), and if its contact points sit at the corners of its base
    (``rule`` ``lobatto``, :mod:`masonry_nscd.model.detection`).
    """
    P = fczm.joint_params(law=law, mu=mu, **dict(joint_kw or {}))
    size = (width, height, depth)
    support = _fixed_plate((width / 2, -0.05, depth / 2), (3 * width, 0.1, depth))
    imposed = {d: at_rest for d in (2, 3, 4)}
    imposed[0] = RampedVelocity(push_velocity, push_start, push_ramp)
    top = np.array([width / 2, height, depth / 2])
    block = RigidBody.box((0, 0, 0), size, 2000.0, divisions, imposed_velocity=imposed,
                          reference=top, name="block")
    bodies = [block, support]
    n = int(dof_offsets(bodies)[-1])
    pts = contact_points(bodies, _all_joints(), max_gap=0.0, rule=rule)
    loads = Loads()
    W = block.mass * gravity
    F = np.zeros(n)
    F[:6] = block.weight_load(np.array([0.0, -(W + normal_force) / block.mass, 0.0]))
    loads.add(F, Ramp(1.0, 0.0, 0.05))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=1.0, tolerance=tolerance,
                       max_iterations=20000, check_every=1, method=method)
    return integ, {"weight": W, "rotation_dof": 5}


def block_launched(*, size=(0.3, 0.1, 0.15), divisions=(2, 2, 1), E=1e8, nu=0.2,
                   density=2000.0, mu=0.3, lift=2.5, push=1.0, pulse=(0.0, 0.04),
                   ramp=0.01, gravity=9.81, h=5e-4, tolerance=1e-8, theta=1.0,
                   method: str = "nlgs", rigid: bool = False, max_halvings: int = 0):
    """A block on a fixed support (rigid contact, law ``coulomb``, friction ``mu``) under its
    weight from the start, launched by a force pulse: ``lift`` times its weight upwards and
    ``push`` times its weight along +x, spread with its mass, from ``pulse[0]`` to
    ``pulse[1]`` s with tanh ramps of ``ramp`` s at both ends. It flies, lands on the support
    (an impact), bounces on its elastic modes and slides until friction stops it: every term
    of the energy balance is exercised (``nscd/energy.py``). A soft block (``E``) so that its
    strain energy and vibrations are resolved by the step."""
    P = fczm.joint_params(law="coulomb", mu=mu)
    support = _fixed_plate((size[0] / 2, -0.05, size[2] / 2), (4 * size[0], 0.1, size[2]))
    if rigid:
        body = RigidBody.box((0, 0, 0), size, density, divisions,
                             imposed_velocity={d: at_rest for d in (2, 3, 4)}, name="block")
    else:
        body = Block.box((0, 0, 0), size, divisions, E=E, nu=nu, density=density, name="block")
    bodies = [body, support]
    n = int(dof_offsets(bodies)[-1])
    pts = contact_points(bodies, _all_joints(), max_gap=0.0,
                         rule="lobatto" if rigid else "gauss")
    if rigid:
        m = np.zeros(n)
        m[:3] = body.mass
        mass = body.mass
    else:
        m = np.zeros(n)
        m[:body.ndof] = body.lumped_mass()
        mass = float(m[0::3].sum())
    loads = Loads()
    G = np.zeros(n)
    G[Y:body.ndof:3] = -gravity * m[Y:body.ndof:3]
    loads.add(G, lambda t: 1.0)
    Fp = np.zeros(n)
    Fp[Y:body.ndof:3] = lift * gravity * m[Y:body.ndof:3]
    Fp[X:body.ndof:3] = push * gravity * m[X:body.ndof:3]
    if rigid:
        Fp[3:6] = 0.0
    t0, t1 = pulse
    loads.add(Fp, lambda t: smooth_step(t, t0, ramp) - smooth_step(t, t1 - ramp, ramp))
    integ = Integrator(bodies, pts, P, loads, h=h, theta=theta, tolerance=tolerance,
                       max_iterations=20000, check_every=1, method=method,
                       max_halvings=max_halvings)
    return integ, {"mass": mass, "weight": mass * gravity}


def rocking_block(*, width=0.2, height=0.8, depth=0.15, mu=0.8, record=None, tilt=0.0,
                  gravity=9.81, h=1e-3, tolerance=1e-10, divisions=(1, 1, 1),
                  method: str = "nlgs", theta: float = 1.0):
    """A rigid block (2000 kg/m^3; ``width`` along x, ``height`` along y) standing on a rigid
    base, rigid contact (law ``coulomb``, friction ``mu``) at the Gauss-Lobatto points of its
    bottom face (its corners), under its weight from the start. The block is free in x, y and
    the in-plane rotation (small rotations about its centre, ``info["rotation_dof"]``), its
    other dofs held.

    ``record``: an acceleration record ``(time_s, acceleration_m_s2)`` of the base along x
    (:class:`masonry_nscd.loading.ground_motion.GroundMotion`, time 0 at t = 0): the base moves
    with it. ``tilt`` (rad): the block starts rotated by ``tilt`` about its left bottom corner
    (``tilt > 0`` lifts the right one), at rest, the relative displacements of the contact
    points set to match. Housner's block: it rocks when the base acceleration exceeds
    ``g b / h`` (``b``, ``h`` its half width and half height), and each impact multiplies the
    angular velocity by ``1 - 1.5 sin^2(alpha)``, ``tan(alpha) = b / h``.
    """
    P = fczm.joint_params(law="coulomb", mu=mu)
    base_geom = (6 * width, 0.1, depth)
    c = np.array([width / 2, -0.05, depth / 2])
    Xb, cb = hex8.box_mesh(c - 0.5 * np.asarray(base_geom), np.asarray(base_geom), (1, 1, 1))
    motion = dict.fromkeys(range(6), at_rest)
    ground = None
    if record is not None:
        ground = GroundMotion(*record)
        motion[X] = ground
    base = RigidBody(center=c, mass=1.0, inertia=np.ones(3), imposed_velocity=motion,
                     X=Xb, conn=cb, support=True, name="base")
    block = RigidBody.box((0, 0, 0), (width, height, depth), 2000.0, divisions,
                          imposed_velocity={d: at_rest for d in (2, 3, 4)}, name="block")
    bodies = [block, base]
    n = int(dof_offsets(bodies)[-1])
    pts = contact_points(bodies, _all_joints(), max_gap=0.0, rule="lobatto")
    loads = Loads()
    G = np.zeros(n)
    G[:6] = block.weight_load(np.array([0.0, -gravity, 0.0]))
    loads.add(G, lambda t: 1.0)
    integ = Integrator(bodies, pts, P, loads, h=h, theta=theta, tolerance=tolerance,
                       max_iterations=20000, check_every=1, method=method)
    if tilt:
        # rotation about the left bottom corner A: q_xy = -tilt z x (A - c)
        hb, hh = width / 2, height / 2
        integ.u[0], integ.u[1], integ.u[5] = -tilt * hh, tilt * hb, tilt
        kernels.local_velocities(integ.sys.side_dofs, integ.sys.side_coef, integ.u,
                                 integ.joints.u)
    b, hh = width / 2, height / 2
    return integ, {"mass": block.mass, "rotation_dof": 5, "ground": ground,
                   "threshold_m_s2": gravity * b / hh,
                   "housner_factor": 1.0 - 1.5 * b * b / (b * b + hh * hh)}


def tilting_block(*, width=0.1, height=0.4, depth=0.15, mu=0.6, rate_per_s=0.05,
                  multiplier=0.0, start_s=0.1, ramp_s=0.1, gravity=9.81, h=2e-3,
                  law: str = "coulomb", method: str = "nlgs", tolerance=1e-8,
                  rule: str = "lobatto", displacement_m=0.01, onset_velocity_m_s=1e-4,
                  end_s=10.0, joint_kw=None, vertices=None, walls: bool = False,
                  direction=(1.0, 0.0, 0.0)):
    """A rigid block (2000 kg/m^3; ``width`` along x, ``height`` along y) free on a fixed base,
    under gravity (ramped over [0, 0.05] s) and a horizontal body force ``lambda(t) g m``
    along +x that rises to ``multiplier`` and grows at ``rate_per_s``
    (:class:`masonry_nscd.loading.multiplier.GrowingMultiplier`): the tilting table, a base
    tilted by ``atan(lambda)``. A limit-state scene (:mod:`masonry_nscd.collapse`): it topples
    about its toe at ``lambda = width / height`` if ``mu`` is larger, and slides at
    ``lambda = mu`` otherwise, with its contact points at the corners of its base (``rule``
    ``lobatto``). With ``vertices`` (k, 3) the block is the convex polyhedron of those
    vertices instead (:meth:`RigidBody.polyhedron`, standing on ``y = 0``; ``rule`` must then
    be ``overlap``, the rule of triangular faces). With ``walls`` the box is wedged between two
    fixed walls, one on each face normal to x, touching them without pressure (the joints'
    ``side`` group); ``direction`` is the body force's (a unit vector; along z it pushes the
    block along the walls). Returns the :class:`~masonry_nscd.scenes.scene.Scene`."""
    P = np.atleast_2d(fczm.joint_params(law=law, mu=mu, **dict(joint_kw or {})))
    base = _fixed_plate((width / 2, -0.05, depth / 2), (4 * width, 0.1, 2 * depth))
    base.name = "base"
    block = (RigidBody.box((0, 0, 0), (width, height, depth), 2000.0, (1, 1, 1), name="block")
             if vertices is None else RigidBody.polyhedron(vertices, 2000.0, name="block"))
    bodies = [block, base]
    groups: tuple[str, ...] = ("base",)
    if walls:
        for x in (-0.05, width + 0.05):
            wall = _fixed_plate((x, height / 2, depth / 2), (0.1, height, 2 * depth))
            wall.name = "wall"
            bodies.append(wall)
        groups = ("base", "side")
    n = int(dof_offsets(bodies)[-1])

    def group(joint, antagonist):
        pair = (bodies[joint.candidate.body], bodies[antagonist.body])
        if all(b.support for b in pair):  # a wall on the base: no joint
            return None
        return (1 if any(b.name == "wall" for b in pair) else 0), KIND_JOINT, 0

    pts = contact_points(bodies, group, max_gap=0.0, rule=rule)
    loads = Loads()
    G = np.zeros(n)
    G[:6] = block.weight_load(np.array([0.0, -1.0, 0.0]))
    loads.add(G, Ramp(gravity, 0.0, 0.05))
    lam = GrowingMultiplier(multiplier, rate_per_s, start_s, ramp_s)
    B = np.zeros(n)
    B[:6] = block.weight_load(np.asarray(direction, float))
    loads.add(B, lambda t: gravity * lam(t))
    rule_ = CollapseRule(displacement_m=displacement_m, onset_velocity_m_s=onset_velocity_m_s,
                         factors=[LoadFactor("lambda", "", lam, "body force multiplier")])
    solver = SolverSettings(h=h, tolerance=tolerance, max_iterations=20000, check_every=1,
                            method=method)
    return Scene(name="tilting block", bodies=bodies, points=pts, groups=groups, params=P,
                 loads=loads, solver=solver, structure=[0], body_info=[{"name": "block"}],
                 driven=0, reactions={"top": 1, "bottom": 1},
                 stages=[Stage("gravity", 0.0), Stage("body force", start_s)],
                 push_stage="gravity", target_m=None, expected_end_s=end_s,
                 time_limit_s=end_s, builder="small", collapse=rule_)
