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

import math

import numpy as np
from numba import njit

#: Barycentric coordinates of the degree-2 points of a triangle (each of weight 1/3)
TRIANGLE_POINTS = np.array([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]])


def signed_area(P: np.ndarray) -> float:
    """Area of polygon ``P`` (k, 2), positive when its corners turn counter-clockwise (m^2)."""
    return _signed_area(np.ascontiguousarray(P, dtype=float))


@njit(cache=True)
def _signed_area(P):
    k = P.shape[0]
    if k < 3:
        return 0.0
    s = 0.0
    for i in range(k):
        j = (i + 1) % k
        s += P[i, 0] * P[j, 1] - P[j, 0] * P[i, 1]
    return 0.5 * s


def counter_clockwise(P: np.ndarray) -> np.ndarray:
    """``P`` with its corners in counter-clockwise order."""
    return P if signed_area(P) >= 0.0 else P[::-1]


def clip(subject: np.ndarray, clipper: np.ndarray, tol: float = 0.0) -> np.ndarray:
    """The part of convex polygon ``subject`` inside convex polygon ``clipper`` (both (k, 2),
    any orientation): a counter-clockwise polygon, (0, 2) when they do not overlap. A corner
    closer than ``tol`` (m) to an edge line counts as on it."""
    out = _clip(np.ascontiguousarray(counter_clockwise(np.asarray(subject, dtype=float))),
                np.ascontiguousarray(counter_clockwise(np.asarray(clipper, dtype=float))),
                float(tol))
    return _without_repeats(out, float(tol))


@njit(cache=True)
def _clip(S, C, tol):
    """Sutherland-Hodgman on counter-clockwise ``S`` and ``C`` (module docstring)."""
    out = S.copy()
    m = C.shape[0]
    for e in range(m):
        n = out.shape[0]
        if n == 0:
            break
        a0, a1 = C[e, 0], C[e, 1]
        e0, e1 = C[(e + 1) % m, 0] - a0, C[(e + 1) % m, 1] - a1
        length = math.hypot(e0, e1)
        if length == 0.0:
            continue
        # signed distance of each corner to the edge line, positive inside (on the left)
        d = np.empty(n)
        for i in range(n):
            d[i] = (e0 * (out[i, 1] - a1) - e1 * (out[i, 0] - a0)) / length
        kept = np.empty((2 * n, 2))  # a corner and a crossing per edge at most
        k = 0
        for i in range(n):
            j = (i + 1) % n
            dp, dq = d[i], d[j]
            if dp >= -tol:
                kept[k, 0], kept[k, 1] = out[i, 0], out[i, 1]
                k += 1
            if (dp > tol and dq < -tol) or (dp < -tol and dq > tol):
                t = dp / (dp - dq)
                kept[k, 0] = out[i, 0] + (out[j, 0] - out[i, 0]) * t
                kept[k, 1] = out[i, 1] + (out[j, 1] - out[i, 1]) * t
                k += 1
        out = kept[:k].copy()
    return out


@njit(cache=True)
def _without_repeats(P, tol):
    """``P`` without corners that repeat the one before them (within ``tol`` m, and at least a
    1e-12 of the polygon's size)."""
    k = P.shape[0]
    if k < 2:
        return P
    size = max(P[:, 0].max() - P[:, 0].min(), P[:, 1].max() - P[:, 1].min())
    eps = max(tol, 1e-12 * size)
    keep = np.empty(k, dtype=np.bool_)
    for i in range(k):
        dx, dy = P[i, 0] - P[i - 1, 0], P[i, 1] - P[i - 1, 1]
        keep[i] = math.sqrt(dx * dx + dy * dy) > eps
    return P[keep] if keep.any() else P[:1].copy()


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
