"""Joints wherever two faces overlap (contact-point rule ``overlap``, ``model/overlap.py``):
the common area of two facing faces by polygon clipping, points on it with their shares of the
area, and the statics those points give."""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.contact import laws
from masonry_nscd.contact.laws import fczm
from masonry_nscd.fe.hex8 import box_mesh
from masonry_nscd.loading import Loads, Ramp, RampedVelocity, at_rest
from masonry_nscd.model import RigidBody, dof_offsets
from masonry_nscd.model import overlap as ov
from masonry_nscd.model.detection import contact_points
from masonry_nscd.nscd.integrator import Integrator

G = 9.81
RHO = 2000.0


def test_the_common_area_of_two_squares_is_their_intersection():
    a = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    b = a + [1.0, 0.5]
    common = ov.clip(a, b[::-1])  # the clipper in either orientation
    assert ov.signed_area(common) == pytest.approx(1.0 * 1.5)
    assert {tuple(p) for p in common} == {(1.0, 0.5), (2.0, 0.5), (2.0, 2.0), (1.0, 2.0)}
    assert len(ov.clip(a, a + [3.0, 0.0])) == 0  # apart: nothing
    inner = np.array([[0.5, 0.5], [1.0, 0.5], [1.0, 1.0], [0.5, 1.0]])
    assert ov.signed_area(ov.clip(a, inner)) == pytest.approx(0.25)  # a face inside another
    assert ov.signed_area(ov.clip(inner, a)) == pytest.approx(0.25)


def test_the_corner_points_carry_the_area_and_its_first_moment():
    """A pentagon: the corners' shares sum to its area and put its centroid where it is; the
    triangles' points integrate a linear field exactly."""
    P = np.array([[0.0, 0.0], [3.0, 0.0], [4.0, 2.0], [1.5, 3.5], [-0.5, 2.0]])
    area = ov.signed_area(P)
    tris = ov.fan(P)
    centroid = sum(ov.signed_area(P[t]) * P[t].mean(axis=0) for t in tris) / area
    pts, w = ov.vertex_points(P)
    assert w.sum() == pytest.approx(area) and (w > 0).all()
    assert (w @ pts) / w.sum() == pytest.approx(centroid)
    pts, w = ov.triangle_points(P)
    f = lambda x: 2.0 + 0.3 * x[:, 0] - 1.1 * x[:, 1]
    assert w @ f(pts) == pytest.approx(area * f(centroid[None])[0])


def _settle(bodies, params, steps=400, h=2e-3):
    """Bodies under their weight (ramped over 0.1 s) on the overlap rule's joints, stepped to
    rest: the integrator and the contact points."""
    pts = contact_points(bodies, lambda jt, ant: (0, laws.KIND_JOINT, 0), max_gap=0.0,
                         rule="overlap")
    dof0 = dof_offsets(bodies)
    Gv = np.zeros(int(dof0[-1]))
    for i, b in enumerate(bodies):
        if not b.support:
            Gv[dof0[i]:dof0[i] + 6] = b.weight_load(np.array([0.0, -G, 0.0]))
    loads = Loads()
    loads.add(Gv, Ramp(1.0, 0.0, 0.1))
    integ = Integrator(bodies, pts, params, loads, h=h, theta=1.0, tolerance=1e-10,
                       max_iterations=200, method="newton", max_halvings=3)
    for _ in range(steps):
        assert integ.step().converged
    return integ, pts


DRY = fczm.joint_params(law="dry", mu=0.8, K_n=1e11, K_t=1e11)


@pytest.mark.parametrize("small_on_top", [True, False])
def test_a_face_inside_a_larger_one_carries_the_weight(small_on_top):
    """A 0.2 x 0.1 m face on a 1 x 0.4 m one (the small block on the large, or the large on
    the small): the points lie on the small face, their areas sum to it, and the lower block
    carries the upper one's weight."""
    if small_on_top:
        upper = RigidBody.box((0.3, 0.2, 0.1), (0.2, 0.1, 0.1), RHO, name="small")
        lower = RigidBody.fixed(center=(0.5, 0.1, 0.2), name="large", **_box_geometry(
            (0.0, 0.0, 0.0), (1.0, 0.2, 0.4)))
    else:
        upper = RigidBody.box((0.0, 0.1, 0.0), (1.0, 0.2, 0.4), RHO, name="large")
        lower = RigidBody.fixed(center=(0.4, 0.05, 0.15), name="small", **_box_geometry(
            (0.3, 0.0, 0.1), (0.2, 0.1, 0.1)))
    integ, pts = _settle([upper, lower], DRY)
    assert sum(p.area for p in pts) == pytest.approx(0.2 * 0.1, rel=1e-12)
    for p in pts:
        assert 0.3 - 1e-12 <= p.x[0] <= 0.5 + 1e-12 and 0.1 - 1e-12 <= p.x[2] <= 0.2 + 1e-12
    carried = integ.point_forces()[:, 1].sum()  # the points' force on the upper block
    assert carried == pytest.approx(upper.mass * G, rel=1e-6)


def _box_geometry(origin, size, divisions=(1, 1, 1)):
    """The hexahedra of a box, as the geometry of a rigid body."""
    X, conn = box_mesh(np.asarray(origin, float), np.asarray(size, float), divisions)
    return {"X": X, "conn": conn}


def test_a_block_bridging_two_others_splits_its_weight_by_statics():
    """A 2 m beam on two supports, 0.1 m and 0.2 m wide, off its centre. On the joints' springs
    (``K_n`` times each point's share of the area, ``k_i``) the beam sinks by ``w0`` and turns by
    ``theta_z``, ``theta_x``: force and moment balance, ``sum k_i w(x_i) (1, x_i, z_i) = W (1,
    x_g, z_g)`` with ``w(x) = w0 + theta_z x + theta_x z``, give each support's share, and
    those the run must give. The beam turns, so each support's centre of pressure lies a little off its centroid
    (by ``theta a^2 / (4 w)``, about 1 mm here, the same for any stiffness): the lever rule on
    the centroids ``x1``, ``x2``, ``W (x2 - xg) / (x2 - x1)``, holds to 0.19 %."""
    beam = RigidBody.box((0.0, 0.2, 0.0), (2.0, 0.1, 0.2), RHO, name="beam")
    left = RigidBody.fixed(center=(0.05, 0.1, 0.1), name="left",
                           **_box_geometry((0.0, 0.0, 0.0), (0.1, 0.2, 0.2)))
    right = RigidBody.fixed(center=(1.6, 0.1, 0.1), name="right",
                            **_box_geometry((1.5, 0.0, 0.0), (0.2, 0.2, 0.2)))
    integ, pts = _settle([beam, left, right], DRY)
    F = integ.point_forces()[:, 1]
    on = {b: sum(F[k] for k, p in enumerate(pts) if b in p.bodies) for b in (1, 2)}
    W, x1, x2, xg = beam.mass * G, 0.05, 1.6, 1.0
    k = np.array([1e11 * p.area for p in pts])
    x, z = np.array([p.x[0] for p in pts]), np.array([p.x[2] for p in pts])
    A = np.stack([np.ones_like(x), x, z])  # the beam sinks, turns about z and about x
    w = np.linalg.solve((A * k) @ A.T, [W, W * xg, W * 0.1])
    for b in (1, 2):
        mine = np.array([b in p.bodies for p in pts])
        assert on[b] == pytest.approx(float(k[mine] @ (w @ A[:, mine])), rel=1e-6)
    assert on[1] == pytest.approx(W * (x2 - xg) / (x2 - x1), rel=3e-3)
    assert on[2] == pytest.approx(W * (xg - x1) / (x2 - x1), rel=3e-3)


@pytest.mark.parametrize("divisions", [(1, 1, 1), (3, 1, 2)])
def test_a_cohesive_joint_over_a_partial_overlap_opens_at_its_strength_times_the_area(
        divisions):
    """A rigid block pulled up off a larger fixed one through a virgin cohesive joint (the
    FCZM with no initial damage): the largest pull is ``sigma_I^e`` times the common area
    (0.05 MPa x 0.02 m^2 = 1 kN), whether the block's face is one quad or six (the common area
    split in six, its points and their shares other)."""
    block = RigidBody(center=(0.4, 0.25, 0.15), mass=1.0, inertia=np.ones(3),
                      imposed_velocity={0: at_rest, 1: RampedVelocity(1e-4, 0.0, 0.01),
                                        2: at_rest, 3: at_rest, 4: at_rest, 5: at_rest},
                      name="block", **_box_geometry((0.3, 0.2, 0.1), (0.2, 0.1, 0.1),
                                                    divisions))
    base = RigidBody.fixed(center=(0.5, 0.1, 0.2), name="base",
                           **_box_geometry((0.0, 0.0, 0.0), (1.0, 0.2, 0.4)))
    bodies = [block, base]
    pts = contact_points(bodies, lambda jt, ant: (0, laws.KIND_JOINT, 0), max_gap=0.0,
                         rule="overlap")
    P = fczm.joint_params(d_coh_initial=0.0)
    integ = Integrator(bodies, pts, P, Loads(), h=1e-3, theta=1.0, tolerance=1e-10,
                       max_iterations=200, method="newton", max_halvings=3)
    pull = []
    for _ in range(150):  # to 1.5e-5 m of opening, past the peak at 2.9e-6 m
        integ.step()
        pull.append(-integ.point_forces()[:, 1].sum())
    assert max(pull) == pytest.approx(0.05e6 * 0.2 * 0.1, rel=1e-3)
