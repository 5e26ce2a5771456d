"""Rigid blocks of any convex polyhedral shape: exact mass properties from their vertices or
their flat-faced hexahedra, non-convex vertex sets refused, and a wedge on a tilting plane."""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.collapse import watch
from masonry_nscd.model import RigidBody
from masonry_nscd.scenes.small import tilting_block


def _prism(triangle, depth=0.15) -> list[list[float]]:
    """The six vertices (m) of the prism of a triangle of the x-y plane, ``depth`` along z."""
    return [[x, y, z] for z in (0.0, depth) for x, y in triangle]


def test_a_polyhedron_from_its_vertices_has_the_exact_mass_properties():
    """The hull of a right-triangular prism (legs b, h, depth d, right angle at the origin)
    has the prism's mass, centroid (b/3, h/3, d/2) and inertia about it (closed form); a
    vertex inside the hull of the others is refused as not convex, a flat set as flat."""
    b, h, d, rho = 0.2, 0.4, 0.15, 2000.0
    body = RigidBody.polyhedron(_prism([(0, 0), (b, 0), (0, h)], d), rho, name="wedge")
    m = rho * b * h * d / 2
    assert body.mass == pytest.approx(m, rel=1e-12)
    assert body.center == pytest.approx([b / 3, h / 3, d / 2], rel=1e-12)
    # the triangle's second moments about its centroid: b h^3/36, h b^3/36, -b^2 h^2/72
    A = b * h / 2
    Ixx_2d, Iyy_2d, Ixy_2d = b * h ** 3 / 36, h * b ** 3 / 36, -(b * h) ** 2 / 72
    expected = rho * d * np.array([
        [Ixx_2d + A * d * d / 12, -Ixy_2d, 0.0],
        [-Ixy_2d, Iyy_2d + A * d * d / 12, 0.0],
        [0.0, 0.0, Ixx_2d + Iyy_2d]])
    assert body.inertia == pytest.approx(expected, abs=1e-12 * m)
    cube = [[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    with pytest.raises(ValueError, match="block 'dent' is not convex: vertex 8"):
        RigidBody.polyhedron([*cube, [0.5, 0.5, 0.5]], rho, name="dent")
    with pytest.raises(ValueError, match="is flat"):
        RigidBody.polyhedron([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], rho)


def test_a_flat_faced_hexahedron_has_the_mass_properties_of_its_tetrahedra():
    """A distorted hexahedron with flat faces (a frustum, its top smaller and shifted) is its
    rigid body's exact shape: the mass, centre and inertia of its hexahedral mesh are those
    of the same solid cut into six tetrahedra (exact), to round-off."""
    bottom = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.6], [0.0, 0.0, 0.6]]
    top = [[0.2, 0.8, 0.1], [0.7, 0.8, 0.1], [0.7, 0.8, 0.4], [0.2, 0.8, 0.4]]
    X = np.array(bottom + top)
    X[:, [1, 2]] = X[:, [2, 1]]  # the frustum's axis along z, VTK order counter-clockwise
    hexa = RigidBody.from_mesh(X, np.arange(8)[None], 2000.0)
    tets = np.array([[0, 1, 3, 4], [1, 2, 3, 6], [1, 3, 4, 6], [1, 4, 5, 6], [3, 4, 6, 7]])
    vol = np.einsum("ij,ij->i", np.cross(X[tets[:, 1]] - X[tets[:, 0]],
                                         X[tets[:, 2]] - X[tets[:, 0]]),
                    X[tets[:, 3]] - X[tets[:, 0]])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    split = RigidBody.from_mesh(X, tets, 2000.0)
    assert hexa.mass == pytest.approx(split.mass, rel=1e-12)
    assert hexa.center == pytest.approx(split.center, rel=1e-12)
    assert hexa.inertia == pytest.approx(split.inertia, rel=1e-10, abs=1e-12 * hexa.mass)


@pytest.mark.parametrize("name, triangle, mu, expected", [
    ("topples about its toe, right angle at the heel", [(0, 0), (0.2, 0), (0, 0.4)], 1.5,
     2 * 0.2 / 0.4),
    ("topples about its toe, right angle at the toe", [(0, 0), (0.2, 0), (0.2, 0.4)], 1.5,
     0.2 / 0.4),
    ("slides", [(0, 0), (0.2, 0), (0.2, 0.4)], 0.3, 0.3)])
def test_a_tilting_wedge_slides_or_topples_at_its_closed_form_multiplier(name, triangle, mu,
                                                                       expected):
    """A rigid wedge (a right-triangular prism of base b = 0.2 m and height h = 0.4 m, from
    its vertices) on a fixed base under a horizontal multiplier lambda of its weight along +x:
    it topples about its toe when the weight's line leaves the base, at lambda = (b - x_c) /
    y_c (2b/h with the right angle at the heel, b/h at the toe), and slides at lambda = mu
    when mu is lower; the onset within 1 % (the load grows at 0.02 /s from 0.9 of it)."""
    scene = tilting_block(vertices=_prism(triangle), mu=mu, rate_per_s=0.02, rule="overlap",
                          multiplier=0.9 * expected, method="newton", end_s=30.0)
    out = watch(scene, 30.0)
    assert out["status"] == "collapse"
    assert out["collapse"]["loads_at_onset"]["lambda"] == pytest.approx(expected, rel=0.01)
    u = out["u"][0]  # about the centre of mass: ux, uy, uz, rx, ry, rz
    if name == "slides":
        assert abs(u[5]) < 1e-6 and u[0] > 0.005
    else:
        assert u[5] < -0.005 and u[1] > 0.0
