r"""The common area of two facing flat faces: polygon clipping, and contact points on it.

Two faces of a joint (element quads of two blocks) are flat convex polygons in nearly the same
plane, facing each other across the joint's gap. Their common area is the candidate face cut
by the antagonist face projected on the candidate's plane: a convex polygon, found by clipping
(Sutherland-Hodgman: the candidate polygon cut in turn by the line of each edge of the
antagonist, in two coordinates of the candidate's plane, m). It is empty where the faces do not
overlap, the whole candidate face where the antagonist covers it, and a part of either where
the joint is staggered (a voussoir on two voussoirs of the course below).

Contact points on the common area, each with its share of the area (m^2):

* ``vertices``: the polygon's corners. The polygon is cut into a fan of triangles from one
  corner and each triangle gives a third of its area to each of its corners, and the shares
  are averaged over the fans from every corner, so the points carry the area ``A`` and its
  first moment ``A x_c`` exactly, whichever corner comes first: a uniform traction gives
  the force and the moment of the common area, however the area is split (two blocks rock
  about the corners of their common area). For two rigid faces.
* ``triangles``: the three points of the degree-2 rule of each triangle of the fan, at the
  barycentric coordinates ``(2/3, 1/6, 1/6)`` and their permutations, each with a third of the
  triangle's area: exact for tractions that vary linearly over the area (a deformable face).

A polygon is a (k, 2) array of corners in counter-clockwise order.
"""

from __future__ import annotations

import numpy as np

#: Barycentric coordinates of the degree-2 points of a triangle (each of weight 1/3)
TRIANGLE_POINTS = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


def signed_area(P: np.ndarray) -> float:
    """Area of polygon ``P`` (k, 2), positive when its corners turn counter-clockwise (m^2)."""
    if len(P) < 3:
        return 0.0
    x, y = P[:, 0], P[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def counter_clockwise(P: np.ndarray) -> np.ndarray:
    """``P`` with its corners in counter-clockwise order."""
    return P if signed_area(P) >= 0.0 else P[::-1]


def clip(subject: np.ndarray, clipper: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """The part of convex polygon ``subject`` inside convex polygon ``clipper`` (both (k, 2),
    any orientation): a counter-clockwise polygon, (0, 2) when they do not overlap. A corner
    closer than ``tol`` (m) to an edge line counts as on it."""
    out = counter_clockwise(np.asarray(subject, dtype=float))
    C = counter_clockwise(np.asarray(clipper, dtype=float))
    for a, b in zip(C, np.roll(C, -1, axis=0), strict=True):
        if len(out) == 0:
            break
        edge = b - a
        length = float(np.hypot(*edge))
        if length == 0.0:
            continue
        # signed distance of each corner to the edge line, positive inside (on the left)
        d = (edge[0] * (out[:, 1] - a[1]) - edge[1] * (out[:, 0] - a[0])) / length
        kept = []
        for i in range(len(out)):
            p, q, dp, dq = out[i], out[(i + 1) % len(out)], d[i], d[(i + 1) % len(out)]
            if dp >= -tol:
                kept.append(p)
            if (dp > tol and dq < -tol) or (dp < -tol and dq > tol):
                kept.append(p + (q - p) * (dp / (dp - dq)))
        out = np.array(kept).reshape(-1, 2)
    return _without_repeats(out, tol)


def _without_repeats(P: np.ndarray, tol: float) -> np.ndarray:
    """``P`` without corners that repeat the one before them (within ``tol`` m, and at least a
    1e-12 of the polygon's size)."""
    if len(P) < 2:
        return P
    size = float(np.ptp(P, axis=0).max())
    eps = max(tol, 1e-12 * size)
    keep = np.linalg.norm(P - np.roll(P, 1, axis=0), axis=1) > eps
    return P[keep] if keep.any() else P[:1]


def fan(P: np.ndarray) -> np.ndarray:
    """The triangles (k - 2, 3) of the fan of polygon ``P`` from its first corner (indices)."""
    k = len(P)
    return np.stack([np.zeros(k - 2, dtype=np.int64), np.arange(1, k - 1),
                     np.arange(2, k)], axis=1) if k >= 3 else np.zeros((0, 3), dtype=np.int64)


def vertex_points(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The corners of polygon ``P`` and their shares of its area (module docstring), averaged
    over the fans from each of its corners, so that they do not depend on which corner comes
    first (a rectangle's four corners a quarter each): ``(points (k, 2), areas (k,))``, the
    areas summing to the polygon's."""
    k = len(P)
    if k < 3:
        return P.copy(), np.zeros(k)
    # the triangles (a, b, c) of the fans from every corner a: b = a + i, c = a + i + 1 (mod k)
    a = np.repeat(np.arange(k), k - 2)
    b = (a + np.tile(np.arange(1, k - 1), k)) % k
    c = (b + 1) % k
    u, v = P[b] - P[a], P[c] - P[a]
    share = np.abs(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]) / (6.0 * k)  # a third of each area
    areas = np.bincount(np.concatenate([a, b, c]), weights=np.tile(share, 3), minlength=k)
    return P.copy(), areas


def triangle_points(P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The degree-2 points of the triangles of the fan of ``P`` and their areas (module
    docstring): ``(points (3 (k - 2), 2), areas)``."""
    tris = fan(P)
    if not len(tris):
        return np.zeros((0, 2)), np.zeros(0)
    corners = P[tris]  # (t, 3, 2)
    pts = np.einsum("pc,tcd->tpd", TRIANGLE_POINTS, corners).reshape(-1, 2)
    areas = np.repeat([abs(signed_area(c)) / 3.0 for c in corners], 3)
    return pts, areas


def plane_basis(normal: np.ndarray) -> np.ndarray:
    """Two unit vectors (2, 3) that span the plane of unit ``normal`` (right-handed with it)."""
    n0, n1, n2 = (float(v) for v in normal)
    k = int(np.argmin(np.abs([n0, n1, n2])))
    # e1 = helper x n, the helper the unit vector along the normal's smallest component
    e1 = np.array([(0.0, -n2, n1), (n2, 0.0, -n0), (-n1, n0, 0.0)][k])
    e1 /= np.linalg.norm(e1)
    e2 = np.array([n1 * e1[2] - n2 * e1[1], n2 * e1[0] - n0 * e1[2], n0 * e1[1] - n1 * e1[0]])
    return np.stack([e1, e2])
