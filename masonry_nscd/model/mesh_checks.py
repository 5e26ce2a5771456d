r"""Checks of a block assembly read from a mesh: inverted elements, overlapping blocks, blocks
that nothing holds. Kernels on plain arrays (m); :mod:`masonry_nscd.scenes.assembly` names the
blocks in its messages.

* **Inverted or flat element**: the Jacobian ``J = dx / dxi`` of the element's map
  (:mod:`masonry_nscd.fe.element`, VTK node order) at its corners,
  ``det J = (dx/dxi x dx/deta) . dx/dzeta``: at the eight corners of an 8-node hexahedron, at
  the four of a tetrahedron (``6 V`` for a 4-node one); an element whose smallest corner
  determinant is at most ``1e-12`` times its mean determinant, or times the cube of its
  largest extent, is inverted (nodes listed clockwise), flat (four corners in a plane) or
  tangled.
* **Overlap**: a point of block A strictly inside an element of block B. The points tried are
  A's nodes, the centres of its elements, of their faces and of their edges; "strictly inside"
  is more than ``tol`` (m) inside each of the face planes of B's element (planes through
  the face centres, normals from the face diagonals or a triangle's edges: exact for planar
  faces). Two blocks that
  only touch (a joint) have no point inside each other. Overlaps in which none of those points
  of either block lies inside the other (two long bars crossing mid-edge) are not seen.
* **Held**: the graph whose nodes are the blocks and whose edges are the joints found by the
  contact detection; a block in a connected part without a support floats (a block with no
  joint at all is the simplest case).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from masonry_nscd.fe.catalog import element_of
from masonry_nscd.model.faces import face_frame

#: An element whose smallest corner determinant is at most this times its mean is inverted.
FLAT_RATIO = 1e-12


def corner_jacobians(X: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """``det J`` (e, corners) of each element at its corners (m^3 per unit reference
    volume)."""
    el = element_of(conn)
    _, dN = el.shape_at(el.corners)  # (corners, nodes, 3)
    J = np.einsum("eai,gak->egik", X[conn], dN)
    return np.linalg.det(J)


def inverted_elements(X: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """Indices of the inverted, flat or tangled elements (module docstring)."""
    det = corner_jacobians(X, conn)
    extent = np.ptp(X[conn], axis=1).max(axis=1)
    scale = np.maximum(np.abs(det).mean(axis=1), extent ** 3)
    return np.flatnonzero(det.min(axis=1) <= FLAT_RATIO * scale)


def probe_points(X: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """The points of a block tried against the others (module docstring), (p, 3)."""
    el = element_of(conn)
    xe = X[conn]
    faces = xe[:, el.faces[:, :el.face_corners]].mean(axis=2).reshape(-1, 3)
    edges = xe[:, el.edges].mean(axis=2).reshape(-1, 3)
    return np.concatenate([X[np.unique(conn)], xe.mean(axis=1), faces, edges])


def _face_planes(X: np.ndarray, conn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Outward unit normals and centres (e, faces, 3) of the faces of each element."""
    el = element_of(conn)
    P = X[conn][:, el.faces[:, :el.face_corners]]  # (e, faces, corners, 3)
    return face_frame(P)


def points_inside(points: np.ndarray, X: np.ndarray, conn: np.ndarray,
                  tol: float) -> np.ndarray:
    """Whether each point (p, 3) lies more than ``tol`` (m) inside some element of the mesh
    ``(X, conn)``, (p,) bool."""
    if not len(points):
        return np.zeros(0, dtype=bool)
    n, c = _face_planes(X, conn)
    # signed distance of every point to every face plane: (p, e, 6), negative inside
    d = np.einsum("efk,pefk->pef", n, points[:, None, None, :] - c[None])
    return (d < -tol).all(axis=2).any(axis=1)


def overlapping_pairs(meshes: Sequence[tuple[np.ndarray, np.ndarray]],
                      tol: float) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, i < j, of blocks ``meshes[k] = (X, conn)`` that overlap (module
    docstring); only blocks whose bounding boxes overlap by more than ``tol`` are tried, found
    by the contact detection's grid search (:func:`~masonry_nscd.model.detection.candidate_pairs`
    on the boxes shrunk by ``tol / 2``: linear in the number of blocks)."""
    from masonry_nscd.model.detection import candidate_pairs

    if len(meshes) < 2:
        return []
    lo = np.array([X[np.unique(c)].min(axis=0) for X, c in meshes])
    hi = np.array([X[np.unique(c)].max(axis=0) for X, c in meshes])
    pairs = candidate_pairs(lo + 0.5 * tol, hi - 0.5 * tol)
    i, j = pairs[:, 0], pairs[:, 1]
    deep = np.all(np.minimum(hi[i], hi[j]) - np.maximum(lo[i], lo[j]) > tol, axis=1)
    probes: dict[int, np.ndarray] = {}

    def probe(k: int) -> np.ndarray:
        if k not in probes:
            probes[k] = probe_points(*meshes[k])
        return probes[k]

    return [(int(a), int(b)) for a, b in pairs[deep]
            if points_inside(probe(a), *meshes[b], tol).any()
            or points_inside(probe(b), *meshes[a], tol).any()]


def unheld_blocks(count: int, joints: Iterable[tuple[int, int]],
                  supports: Iterable[int]) -> tuple[list[int], list[int]]:
    """Blocks ``0..count-1`` joined by ``joints`` (pairs of blocks): those with no joint at
    all, and those (with joints) in a connected part that holds no support."""
    parent = list(range(count))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    touched = np.zeros(count, dtype=bool)
    for a, b in joints:
        touched[a] = touched[b] = True
        parent[root(a)] = root(b)
    held = {root(s) for s in supports}
    alone = [k for k in range(count) if not touched[k] and root(k) not in held]
    floating = [k for k in range(count) if touched[k] and root(k) not in held]
    return alone, floating
