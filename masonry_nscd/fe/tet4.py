r"""Four-node tetrahedra: the element descriptor ``TET4`` (linear shape functions, one Gauss
point: constant strain), and tetrahedral meshes from hexahedral ones.

Reference element: the corners ``(0,0,0), (1,0,0), (0,1,0), (0,0,1)`` (VTK and Gmsh order;
``(x_1 - x_0) x (x_2 - x_0) . (x_3 - x_0) > 0`` for a positive element), volume 1/6::

    N_0 = 1 - r - s - t,   N_1 = r,   N_2 = s,   N_3 = t

The strain is uniform over the element, so the one-point rule (the centroid, weight 1/6) is
exact for the stiffness; the lumped mass gives each node a quarter of the element mass. A
linear tetrahedron cannot bend (its strain is constant): a beam meshed with them is too stiff
in bending unless it has many elements through its depth (docs/architecture.md,
tests/test_tet.py). Its faces are triangles ordered counter-clockwise seen from outside.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.fe.element import Element

CORNERS = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
#: Local nodes of the four faces (the face opposite node 3, 2, 0, 1), outward by the right-hand rule
FACES = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]], dtype=np.int64)
EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]], dtype=np.int64)

#: The collapsed hexahedron the outputs draw a tetrahedron as
DRAWN_AS = np.array([0, 1, 2, 2, 3, 3, 3, 3], dtype=np.int64)

_A, _B = 0.5854101966249685, 0.1381966011250105  # (5 + 3 sqrt 5) / 20, (5 - sqrt 5) / 20
#: The four-point rule of degree 2 (weights 1/24): exact for quadratic integrands
DEGREE2_POINTS = np.array([[_B, _B, _B], [_A, _B, _B], [_B, _A, _B], [_B, _B, _A]])
DEGREE2_WEIGHTS = np.full(4, 1.0 / 24.0)


def barycentric(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The volume coordinates ``L`` (k, 4) of reference points (k, 3) and their constant
    derivatives ``dL/dxi`` (4, 3)."""
    p = np.atleast_2d(np.asarray(points, dtype=float))
    L = np.column_stack([1.0 - p.sum(axis=1), p])
    dL = np.array([[-1.0, -1.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    return L, dL


def shape_at(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (k, 4) and derivatives dN/dxi (k, 4, 3) at reference points (k, 3)."""
    L, dL = barycentric(points)
    return L, np.broadcast_to(dL, (len(L), 4, 3)).copy()


TET4 = Element(name="tet4", nodes=4, gauss_points=np.array([[0.25, 0.25, 0.25]]),
               gauss_weights=np.array([1.0 / 6.0]), shape_at=shape_at, faces=FACES,
               face_corners=3, corners=CORNERS, edges=EDGES, vtk_type=10, meshio_type="tetra",
               drawn_as=DRAWN_AS, mass_rule=(DEGREE2_POINTS, DEGREE2_WEIGHTS))

#: The six tetrahedra of a hexahedron (VTK order) along its diagonal 0-6 (Kuhn): one for
#: each order in which the path from corner 0 to corner 6 steps along x, y and z. The face
#: diagonals agree between neighbours of a structured mesh, so the tetrahedra are conforming.
KUHN = np.array([[0, 1, 2, 6], [0, 5, 1, 6], [0, 2, 3, 6], [0, 3, 7, 6], [0, 4, 5, 6],
                 [0, 7, 4, 6]], dtype=np.int64)


def split_hexahedra(X: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """The tetrahedra (6 nel, 4) of the Kuhn split of each hexahedron (``KUHN``), ordered to
    positive volume (two nodes swapped where the split gives a negative one)."""
    tets = np.asarray(hexes, dtype=np.int64)[:, KUHN].reshape(-1, 4)
    P = np.asarray(X, dtype=float)[tets]
    vol = np.einsum("ei,ei->e", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0])
    neg = vol < 0.0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return tets
