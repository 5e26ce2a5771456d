r"""Ten-node tetrahedra: the element descriptor ``TET10`` (quadratic shape functions, the
four-point rule of degree 2, six-node triangular faces), and quadratic meshes from linear ones.

Reference element and volume coordinates ``L`` of :mod:`masonry_nscd.fe.tet4`; nodes in VTK
order (meshio gives Gmsh's in it): the corners 0-3, then the midpoints of the edges (0, 1),
(1, 2), (2, 0), (0, 3), (1, 3), (2, 3)::

    N_i = L_i (2 L_i - 1) (corners),    N_ab = 4 L_a L_b (edges)

The strain is linear over the element: it bends, and the four-point rule of degree 2 integrates
the stiffness of a straight-edged element exactly. Row-sum lumping would give the corners
``-1/20`` of the element mass each; the mass is lumped by the diagonal of the consistent mass
scaled to the element mass (Hinton-Rock-Zienkiewicz), for a straight-edged element
``int N_i^2 dV``: ``V/70`` at a corner and ``8 V/105`` at an edge node, that is ``1/36`` of the
mass at each corner and ``4/27`` at each edge node.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.fe.element import Element
from masonry_nscd.fe.tet4 import (
    CORNERS,
    DEGREE2_POINTS,
    DEGREE2_WEIGHTS,
    DRAWN_AS,
    EDGES,
    barycentric,
)

#: Corner pairs of the six edge nodes 4-9, in VTK order
EDGE_NODES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]], dtype=np.int64)
#: The four faces: corners as in tet4.FACES, then their edge nodes (edges 01, 12, 20 of the face)
FACES = np.array([[0, 2, 1, 6, 5, 4], [0, 1, 3, 4, 8, 7], [1, 2, 3, 5, 9, 8],
                  [0, 3, 2, 7, 9, 6]], dtype=np.int64)


def shape_at(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (k, 10) and derivatives dN/dxi (k, 10, 3) at reference points (k, 3)."""
    L, dL = barycentric(points)
    a, b = EDGE_NODES[:, 0], EDGE_NODES[:, 1]
    N = np.concatenate([L * (2.0 * L - 1.0), 4.0 * L[:, a] * L[:, b]], axis=1)
    dN = np.concatenate([(4.0 * L - 1.0)[:, :, None] * dL[None],
                         4.0 * (L[:, a, None] * dL[None, b] + L[:, b, None] * dL[None, a])],
                        axis=1)
    return N, dN


TET10 = Element(name="tet10", nodes=10, gauss_points=DEGREE2_POINTS,
                gauss_weights=DEGREE2_WEIGHTS, shape_at=shape_at, faces=FACES, face_corners=3,
                corners=CORNERS, edges=EDGES, vtk_type=24, meshio_type="tetra10",
                drawn_as=DRAWN_AS, mass_rule=(DEGREE2_POINTS, DEGREE2_WEIGHTS),
                mass_fractions=np.array([1 / 36] * 4 + [4 / 27] * 6))


def quadratic(X: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 10-node mesh of a 4-node one: a node at the middle of each edge, shared by the
    tetrahedra around it. Returns the nodes (n + edges, 3) and cells (nel, 10)."""
    tets = np.asarray(tets, dtype=np.int64)
    pairs = np.sort(tets[:, EDGE_NODES].reshape(-1, 2), axis=1)
    edges, inverse = np.unique(pairs, axis=0, return_inverse=True)
    X = np.asarray(X, dtype=float)
    mid = 0.5 * (X[edges[:, 0]] + X[edges[:, 1]])
    cells = np.concatenate([tets, len(X) + inverse.reshape(len(tets), 6)], axis=1)
    return np.concatenate([X, mid]), cells
