r"""Faces of block meshes: boundary faces, planar patches, points on and in faces.

The boundary of a mesh is the set of element faces that belong to one element only. Each face
is ordered so that the right-hand rule gives its outward normal (the element's ``faces``,
:mod:`masonry_nscd.fe.element`): quadrilaterals of hexahedra, triangles of 4-node tetrahedra,
six-node triangles (corners first) of 10-node tetrahedra. Boundary faces that lie in one plane
with the same outward normal form a **patch** (the six sides of a box; the joint faces of a
voussoir): contact detection pairs patches, and sits contact points on the faces of a patch.

A point of a triangle with corners ``P_0, P_1, P_2`` has the reference coordinates ``(r, s)``
of ``x = (1 - r - s) P_0 + r P_1 + s P_2``; its shape functions are the linear ones on a
three-node triangle, ``L_i (2 L_i - 1)`` at the corners and ``4 L_i L_j`` at the edge nodes of a
six-node one (``L = (1 - r - s, r, s)``, straight edges).

Bilinear map of a quad with nodes ``P_0..P_3``::

    x(xi, eta) = sum_i N_i(xi, eta) P_i,   N = (1 -+ xi)(1 -+ eta) / 4   in the quad's node order

(corners (-1,-1), (1,-1), (1,1), (-1,1)). Its area element is ``|dx/dxi x dx/deta|`` (m^2 per
unit of reference area). A point of the plane is located in a quad by inverting the map with
Newton's method on the in-plane coordinates (exact in one iteration on a parallelogram).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from masonry_nscd.fe import hex8
from masonry_nscd.fe.catalog import element_of

#: Local node numbers of the six faces of the 8-node hexahedron (``fe.hex8.FACES``)
HEX_FACES = hex8.FACES
_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def boundary_faces(conn: np.ndarray) -> np.ndarray:
    """Node numbers (nf, face nodes) of the element faces that belong to one element only,
    each ordered so that its outward normal follows the right-hand rule; in element order, then
    face order. The cells' element type is found by their node count."""
    local = element_of(conn).faces
    faces = conn[:, local].reshape(-1, local.shape[1])
    _, inverse, counts = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def boundary_quads(conn: np.ndarray) -> np.ndarray:
    """The boundary faces (nq, 4) of a hexahedral mesh (:func:`boundary_faces`)."""
    return boundary_faces(conn)


def corner_count(faces: np.ndarray) -> int:
    """The corners of faces (nf, face nodes): 4 for quadrilaterals, 3 for triangles (of 3 or
    6 nodes)."""
    return 4 if faces.shape[1] == 4 else 3


def face_shape(nodes: int, r: float, s: float) -> np.ndarray:
    """Shape functions (nodes,) of a face of ``nodes`` nodes at its reference coordinates:
    bilinear on a quadrilateral (``(r, s) = (xi, eta)`` in [-1, 1]^2), linear or quadratic on a
    triangle (module docstring)."""
    if nodes == 4:
        return shape4(r, s)
    L = np.array([1.0 - r - s, r, s])
    if nodes == 3:
        return L
    return np.concatenate([L * (2.0 * L - 1.0), 4.0 * L * L[[1, 2, 0]]])


def triangle_coordinates(P: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """The reference coordinates ``(r, s)`` of point ``x`` (3,) projected on the plane of the
    triangle with corners ``P`` (3, 3)."""
    a, b = P[1] - P[0], P[2] - P[0]
    G = np.array([[a @ a, a @ b], [a @ b, b @ b]])
    r, s = np.linalg.solve(G, np.array([a @ (x - P[0]), b @ (x - P[0])]))
    return float(r), float(s)


def face_frame(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit outward normal and centre of faces ``P`` (..., corners, 3): :func:`quad_frame` for
    quadrilaterals, ``(P_1 - P_0) x (P_2 - P_0)`` and the mean of the corners for triangles."""
    if P.shape[-2] == 4:
        return quad_frame(P)
    n = cross(P[..., 1, :] - P[..., 0, :], P[..., 2, :] - P[..., 0, :])
    return n / np.linalg.norm(n, axis=-1, keepdims=True), P.mean(axis=-2)


def shape4(xi, eta) -> np.ndarray:
    """Bilinear shape functions (..., 4) at reference points (xi, eta)."""
    xi, eta = np.asarray(xi, dtype=float), np.asarray(eta, dtype=float)
    return 0.25 * np.stack([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta),
                            (1 - xi) * (1 + eta)], axis=-1)


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a x b`` of vectors (..., 3), component by component: ``np.cross`` without its
    axis handling, which costs more than the product on the few vectors of one face."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def quad_frame(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normal (from the diagonals, right-hand rule) and centre of quads ``P`` (..., 4, 3)."""
    n = cross(P[..., 2, :] - P[..., 0, :], P[..., 3, :] - P[..., 1, :])
    return n / np.linalg.norm(n, axis=-1, keepdims=True), P.mean(axis=-2)


#: Gauss-Lobatto rules on [-1, 1] (points, weights) by number of points: the ends are points
LOBATTO = {
    2: (np.array([-1.0, 1.0]), np.array([1.0, 1.0])),
    3: (np.array([-1.0, 0.0, 1.0]), np.array([1.0, 4.0, 1.0]) / 3.0),
    4: (np.array([-1.0, -1.0 / np.sqrt(5.0), 1.0 / np.sqrt(5.0), 1.0]),
        np.array([1.0, 5.0, 5.0, 1.0]) / 6.0),
}


def gauss_points(P: np.ndarray, order: int, rule: str = "gauss"
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (nq, order^2, 3), tributary areas (nq, order^2) and reference coordinates
    (order^2, 2) of a rule of ``order`` points per direction on quads ``P`` (nq, 4, 3); points
    ordered with xi outer. ``rule``: ``gauss`` (Gauss-Legendre, inside the quad) or ``lobatto``
    (Gauss-Lobatto, ``order`` 2 to 4: the corners and, from 3, points on the edges among them;
    2 is the trapezoidal rule, a quarter of a parallelogram's area at each corner)."""
    if rule == "lobatto":
        if order not in LOBATTO:
            raise ValueError(f"the Gauss-Lobatto rule takes 2 to 4 points, got {order}")
        g, w = LOBATTO[order]
    elif rule == "gauss":
        g, w = np.polynomial.legendre.leggauss(order)
    else:
        raise ValueError(f"unknown quadrature rule {rule!r}: 'gauss' or 'lobatto'")
    xi, eta = np.repeat(g, order), np.tile(g, order)
    wt = np.repeat(w, order) * np.tile(w, order)
    N = shape4(xi, eta)  # (k, 4)
    x = np.einsum("ki,qid->qkd", N, P)
    dxi = 0.25 * np.stack([-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)], axis=-1)
    deta = 0.25 * np.stack([-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)], axis=-1)
    a = np.einsum("ki,qid->qkd", dxi, P)
    b = np.einsum("ki,qid->qkd", deta, P)
    return x, wt * np.linalg.norm(cross(a, b), axis=-1), np.stack([xi, eta], axis=1)


def locate(P: np.ndarray, x: np.ndarray, tol: float = 1e-9, iterations: int = 8):
    """Reference coordinates of points ``x`` (k, 3) in each of the quads ``P`` (m, 4, 3).

    Returns ``(xi, eta, inside)``, each (k, m): :func:`locate_pairs` of every point with
    every quad."""
    k, m = len(x), len(P)
    xi, eta, inside = locate_pairs(np.broadcast_to(P, (k, m, 4, 3)).reshape(-1, 4, 3),
                                   np.repeat(x, m, axis=0), tol, iterations)
    return xi.reshape(k, m), eta.reshape(k, m), inside.reshape(k, m)


def locate_pairs(P: np.ndarray, x: np.ndarray, tol: float = 1e-9, iterations: int = 8):
    """Reference coordinates of each point ``x[i]`` (n, 3) in its quad ``P[i]`` (n, 4, 3).

    Returns ``(xi, eta, inside)``, each (n,): the point is projected on the quad's plane and
    the bilinear map ``x(xi, eta) = c + xi a_1 + eta a_2 + xi eta a_3`` (in the plane)
    inverted by Newton's method, ``J = [a_1 + eta a_3, a_2 + xi a_3]``; ``inside`` where
    ``|xi|, |eta| <= 1 + tol``.
    """
    n, c = quad_frame(P)  # (n, 3)
    e1 = P[:, 1] - P[:, 0]
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = cross(n, e1)
    d = P - c[:, None, :]
    p = np.stack([np.einsum("nd,nid->ni", e1, d), np.einsum("nd,nid->ni", e2, d)], axis=-1)
    r0 = x - c
    x2 = np.stack([np.einsum("nd,nd->n", e1, r0), np.einsum("nd,nd->n", e2, r0)], axis=-1)
    a1 = 0.25 * (-p[:, 0] + p[:, 1] + p[:, 2] - p[:, 3])  # (n, 2), in the plane
    a2 = 0.25 * (-p[:, 0] - p[:, 1] + p[:, 2] + p[:, 3])
    a3 = 0.25 * (p[:, 0] - p[:, 1] + p[:, 2] - p[:, 3])
    c0 = 0.25 * p.sum(axis=1)
    xi = np.zeros(len(x))
    eta = np.zeros(len(x))
    for _ in range(iterations):
        ja = a1 + eta[:, None] * a3  # d x / d xi
        jb = a2 + xi[:, None] * a3  # d x / d eta
        r = c0 + xi[:, None] * a1 + eta[:, None] * a2 + (xi * eta)[:, None] * a3 - x2
        det = ja[:, 0] * jb[:, 1] - ja[:, 1] * jb[:, 0]
        d_xi = (jb[:, 1] * r[:, 0] - jb[:, 0] * r[:, 1]) / det
        d_eta = (ja[:, 0] * r[:, 1] - ja[:, 1] * r[:, 0]) / det
        xi = xi - d_xi
        eta = eta - d_eta
        if max(np.abs(d_xi).max(initial=0.0), np.abs(d_eta).max(initial=0.0)) < 1e-14:
            break
    inside = (np.abs(xi) <= 1.0 + tol) & (np.abs(eta) <= 1.0 + tol)
    return xi, eta, inside


@dataclass
class Patch:
    """A planar set of boundary faces of one body with one outward normal."""

    body: int
    normal: np.ndarray  # (3,) outward unit normal
    offset: float  # m, ``normal . x`` on the plane
    faces: np.ndarray  # (k, face nodes) node numbers of the body's mesh, corners first
    lo: np.ndarray  # (3,) bounding box, m
    hi: np.ndarray

    @property
    def quads(self) -> np.ndarray:
        """The faces (named for the quadrilaterals of hexahedral meshes)."""
        return self.faces

    @property
    def corners(self) -> np.ndarray:
        """The corner nodes of the faces (k, 4 or 3)."""
        return self.faces[:, :corner_count(self.faces)]


def planar_patches(body_index: int, X: np.ndarray, conn: np.ndarray, *,
                   angle_tol: float = 1e-6, dist_tol: float = 1e-9) -> list[Patch]:
    """The boundary faces of a mesh grouped by plane (outward normals within ``angle_tol``
    rad, plane offsets within ``dist_tol`` m); patches in order of their first face.

    Raises ValueError for a warped boundary face (a node more than ``1e-6`` of the face's size
    off its mean plane), which no planar joint can be built on.
    """
    if not len(conn):
        return []
    quads = boundary_faces(conn)
    nc = corner_count(quads)
    P = X[quads]
    n, c = face_frame(P[:, :nc])
    size = np.linalg.norm(P[:, 2] - P[:, 0], axis=-1) if nc == 4 else \
        np.linalg.norm(P[:, :nc] - P[:, [1, 2, 0]], axis=-1).max(axis=1)
    warp = np.abs(np.einsum("qid,qd->qi", P - c[:, None, :], n)).max(axis=1)
    if np.any(warp > 1e-6 * size):
        q = int(np.argmax(warp / size))
        raise ValueError(f"a boundary face of body {body_index} is not planar (a node "
                         f"{warp[q]:.3g} m off its plane)")
    offset = np.einsum("qd,qd->q", n, c)
    label = np.full(len(quads), -1)
    patches: list[Patch] = []
    cos_tol = np.cos(angle_tol)
    for q in range(len(quads)):
        if label[q] >= 0:
            continue
        same = (label < 0) & (n @ n[q] >= cos_tol) & (np.abs(offset - offset[q]) <= dist_tol)
        label[same] = len(patches)
        pts = P[same].reshape(-1, 3)
        patches.append(Patch(body_index, n[q], float(offset[q]), quads[same], pts.min(axis=0),
                             pts.max(axis=0)))
    return patches
