r"""Faces of hexahedral meshes: boundary quads, planar patches, points on and in quads.

The boundary of a mesh is the set of element faces that belong to one element only. Each face
quad is ordered so that the right-hand rule gives its outward normal (``HEX_FACES``). Boundary
quads that lie in one plane with the same outward normal form a **patch** (the six sides of a
box; the joint faces of a voussoir): contact detection pairs patches, and sits contact points on
the quads of a patch.

Bilinear map of a quad with nodes ``P_0..P_3``::

    x(xi, eta) = sum_i N_i(xi, eta) P_i,   N = (1 -+ xi)(1 -+ eta) / 4   in the quad's node order

(corners (-1,-1), (1,-1), (1,1), (-1,1)). Its area element is ``|dx/dxi x dx/deta|`` (m^2 per
unit of reference area). A point of the plane is located in a quad by inverting the map with
Newton's method on the in-plane coordinates (exact in one iteration on a parallelogram).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Local node numbers of the six faces of the 8-node hexahedron (VTK order), each ordered
#: counter-clockwise seen from outside: x-min, x-max, y-min, y-max, z-min, z-max.
HEX_FACES = np.array([[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1],
                      [4, 5, 6, 7]], dtype=np.int64)
_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def boundary_quads(conn: np.ndarray) -> np.ndarray:
    """Node numbers (nq, 4) of the element faces that belong to one element only, each ordered
    so that its outward normal follows the right-hand rule; in element order, then face order."""
    faces = conn[:, HEX_FACES].reshape(-1, 4)
    _, inverse, counts = np.unique(np.sort(faces, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    return faces[counts[inverse.ravel()] == 1]


def shape4(xi, eta) -> np.ndarray:
    """Bilinear shape functions (..., 4) at reference points (xi, eta)."""
    xi, eta = np.asarray(xi, dtype=float), np.asarray(eta, dtype=float)
    return 0.25 * np.stack([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta), (1 + xi) * (1 + eta),
                            (1 - xi) * (1 + eta)], axis=-1)


def quad_frame(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normal (from the diagonals, right-hand rule) and centre of quads ``P`` (..., 4, 3)."""
    n = np.cross(P[..., 2, :] - P[..., 0, :], P[..., 3, :] - P[..., 1, :])
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
    return x, wt * np.linalg.norm(np.cross(a, b), axis=-1), np.stack([xi, eta], axis=1)


def locate(P: np.ndarray, x: np.ndarray, tol: float = 1e-9, iterations: int = 8):
    """Reference coordinates of points ``x`` (k, 3) in each of the quads ``P`` (m, 4, 3).

    Returns ``(xi, eta, inside)``, each (k, m): the points are projected on each quad's plane
    and the bilinear map inverted; ``inside`` where ``|xi|, |eta| <= 1 + tol``.
    """
    n, c = quad_frame(P)  # (m, 3)
    e1 = P[:, 1] - P[:, 0]
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(n, e1)
    basis = np.stack([e1, e2], axis=1)  # (m, 2, 3)
    p2 = np.einsum("mjd,mid->mij", basis, P - c[:, None, :])  # (m, 4, 2) corners in plane
    x2 = np.einsum("mjd,kmd->kmj", basis, x[:, None, :] - c[None, :, :])  # (k, m, 2)
    ref = np.zeros(x2.shape)
    for _ in range(iterations):
        xi, eta = ref[..., 0], ref[..., 1]
        N = shape4(xi, eta)  # (k, m, 4)
        r = np.einsum("kmi,mij->kmj", N, p2) - x2
        dxi = 0.25 * np.stack([-(1 - eta), (1 - eta), (1 + eta), -(1 + eta)], axis=-1)
        deta = 0.25 * np.stack([-(1 - xi), -(1 + xi), (1 + xi), (1 - xi)], axis=-1)
        J = np.stack([np.einsum("kmi,mij->kmj", dxi, p2),
                      np.einsum("kmi,mij->kmj", deta, p2)], axis=-1)  # (k, m, 2, 2)
        step = np.linalg.solve(J, r[..., None])[..., 0]
        ref = ref - step
        if np.abs(step).max(initial=0.0) < 1e-14:
            break
    xi, eta = ref[..., 0], ref[..., 1]
    inside = (np.abs(xi) <= 1.0 + tol) & (np.abs(eta) <= 1.0 + tol)
    return xi, eta, inside


@dataclass
class Patch:
    """A planar set of boundary quads of one body with one outward normal."""

    body: int
    normal: np.ndarray  # (3,) outward unit normal
    offset: float  # m, ``normal . x`` on the plane
    quads: np.ndarray  # (k, 4) node numbers of the body's mesh
    lo: np.ndarray  # (3,) bounding box, m
    hi: np.ndarray


def planar_patches(body_index: int, X: np.ndarray, conn: np.ndarray, *,
                   angle_tol: float = 1e-6, dist_tol: float = 1e-9) -> list[Patch]:
    """The boundary quads of a mesh grouped by plane (outward normals within ``angle_tol``
    rad, plane offsets within ``dist_tol`` m); patches in order of their first quad.

    Raises ValueError for a warped boundary quad (a corner more than ``1e-6`` of the quad's size
    off its mean plane), which no planar joint can be built on.
    """
    if not len(conn):
        return []
    quads = boundary_quads(conn)
    P = X[quads]
    n, c = quad_frame(P)
    size = np.linalg.norm(P[:, 2] - P[:, 0], axis=-1)
    warp = np.abs(np.einsum("qid,qd->qi", P - c[:, None, :], n)).max(axis=1)
    if np.any(warp > 1e-6 * size):
        q = int(np.argmax(warp / size))
        raise ValueError(f"a boundary face of body {body_index} is not planar (a corner "
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
