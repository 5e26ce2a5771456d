r"""Contact detection: the joints of a block assembly, found from the geometry of its bodies.

Two planar patches (:mod:`masonry_nscd.model.faces`) of two bodies form a **joint** when

* they are parallel and face each other: outward normals opposite within ``angle_tol`` (rad);
* the gap between them, measured along the normal, is within ``[-gap_tol, max_gap + gap_tol]``
  (m): ``max_gap`` is the joint thickness (the mortar and the unit-mortar interface are one
  contact interface with an initial gap equal to it);
* they overlap: at least one contact point of the candidate face projects, across the gap,
  inside the antagonist face.

Candidate and antagonist. The contact points sit on the candidate face. A support (a body
marked ``support``: the steel beams, the ground) is never the candidate of a joint with a body
that is not one. Otherwise the candidate is the body on the upper side of the joint: its
outward normal points down (``n_y < 0``), or, for a vertical joint, left (``n_x < 0``), or, for a
joint in the x-y plane, back (``n_z < 0``); the first component of the normal larger than
``1e-6`` decides. On a wall, the unit above a bed joint and the unit right of a head joint.

Contact points sit at the ``n_gauss x n_gauss`` points of a rule on each candidate face quad,
with the tributary area of their weight: Gauss-Legendre points inside the quad (``gauss``), or
Gauss-Lobatto points, the quad's corners among them (``lobatto``). A point that two quads of the
candidate face share (a corner, an edge point) is made once, with the sum of their areas; it
belongs to the first of them. Where a rigid block rocks on a face, it turns about its corner
points: at the edge of the face with ``lobatto``, at the outer Gauss point with ``gauss``
(``(1 - 1/sqrt(3)) / 2`` of a quad's width inside the edge). Each point projects along the
normal onto the antagonists: with ``gauss`` the first antagonist (in body order) whose face
contains the projection takes the point; with ``lobatto`` a point on the common edge of two
antagonists (a corner right above a head joint of the course below) is made for each of them,
its area shared equally. A point that faces none (an open end) is dropped. The point's gap is the distance to the
antagonist's plane along the normal, and its frame (n, t, s) has ``n`` from the antagonist to
the candidate (:func:`~masonry_nscd.model.points.joint_frame`).

With the rule ``overlap`` the points sit on the common area of each candidate quad and each
antagonist quad instead (:mod:`masonry_nscd.model.overlap`: the candidate quad clipped by the
antagonist quad projected on its plane): at the corners of the common area between two rigid
faces, with shares of the area that carry its area and centroid exactly, else at the degree-2
points of its triangles. Faces that meet in part (a face inside a larger one, a block on two
others, staggered voussoirs) then make a joint on exactly their common area, whichever face is
the larger, and a uniform traction gives the same force however the area is split.

Broad phase: the bounding boxes of the patches, enlarged by ``max_gap + gap_tol``, are hashed
into a grid of cells the size of the median patch; only patches that share a cell are compared,
so the cost grows with the number of patches, not with its square (a patch more than 32 cells
across, a ring's or the ground's face, is compared with every patch directly).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from masonry_nscd.model import overlap
from masonry_nscd.model.bodies import RigidBody
from masonry_nscd.model.faces import (
    Patch,
    corner_count,
    gauss_points,
    locate,
    locate_pairs,
    planar_patches,
    triangle_coordinates,
)
from masonry_nscd.model.points import (
    ContactPoint,
    deformable_side,
    dof_offsets,
    joint_frame,
    rigid_side,
)


@dataclass
class Joint:
    """Two facing patches: points on ``candidate``'s patch, projected on ``antagonist``'s."""

    candidate: Patch
    antagonists: list[Patch]  # in body order
    normal: np.ndarray  # (3,) from the antagonists to the candidate (minus its outward normal)


#: Two faces make a joint when their outward normals are opposite within this angle (rad)
JOINT_ANGLE_TOL = 1e-3
#: Faces of two bodies that touch at an angle up to this (rad) beyond the joints' tolerance
#: are reported as skewed (:attr:`Detection.skewed`): faces meant to meet that a mesh left
#: slightly turned. Blocks that meet on an edge, their faces opening at a larger angle (a
#: voussoir beside a pier), are not.
SKEW_REPORTED = np.radians(1.0)


@dataclass
class Detection:
    """The patches of every body and the joints between them; ``skewed``: the pairs of
    patches of two bodies that touch (a corner of one within the joint's gap of the other's
    plane) but face each other at an angle between the joints' tolerance and
    :data:`SKEW_REPORTED`, with that angle (rad): no joint is made there."""

    patches: list[Patch]
    joints: list[Joint]
    skewed: list[tuple[Patch, Patch, float]] = field(default_factory=list)


#: A box more than this many grid cells across is compared with every box directly
BIG_BOX_CELLS = 32


def candidate_pairs(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Pairs ``(i, j)``, i < j, of boxes ``[lo, hi]`` (n, 3) that overlap, sorted.

    The boxes are hashed into a uniform grid of cells the size of the median box (at least a
    100,000th of the whole extent, so that the cells' keys stay far inside 64-bit integers),
    and only boxes that share a cell are compared. A box more than ``BIG_BOX_CELLS`` cells
    across (the face of a ring or of the ground under many blocks) is compared with every box
    directly instead: a few large faces do not coarsen the grid for all the others."""
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    ext = (hi - lo).max(axis=1)
    domain = float((hi.max(axis=0) - lo.min(axis=0)).max())
    cell = max(float(np.median(ext)), domain * 1e-5) or 1.0
    big = ext > BIG_BOX_CELLS * cell
    small = np.flatnonzero(~big)
    found = [small[_grid_pairs(lo[small], hi[small], cell)]]
    for b in np.flatnonzero(big):
        other = np.flatnonzero(np.all((lo[b] <= hi) & (lo <= hi[b]), axis=1))
        other = other[other != b]
        found.append(np.stack([np.minimum(other, b), np.maximum(other, b)], axis=1))
    pairs = np.concatenate(found).reshape(-1, 2)
    return _unique_pairs(pairs, n)


def _unique_pairs(pairs: np.ndarray, n: int) -> np.ndarray:
    """The distinct rows of ``pairs`` (k, 2) of indices below ``n``, sorted by ``i`` then
    ``j``: as ``np.unique(pairs, axis=0)``, through the one integer ``i n + j`` per pair."""
    if not len(pairs):
        return pairs
    key = np.sort(pairs[:, 0] * np.int64(n) + pairs[:, 1])  # a sort: np.unique hashes first,
    key = key[np.r_[True, key[1:] != key[:-1]]]  # many times slower on millions of keys
    return np.stack([key // n, key % n], axis=1)


def _grid_pairs(lo: np.ndarray, hi: np.ndarray, cell: float) -> np.ndarray:
    """Pairs ``(i, j)``, i < j, of boxes that overlap, found through a grid of cells of
    ``cell`` (m) (:func:`candidate_pairs`)."""
    n = len(lo)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    origin = lo.min(axis=0)
    c0 = np.floor((lo - origin) / cell).astype(np.int64)
    c1 = np.floor((hi - origin) / cell).astype(np.int64)
    span = c1 - c0 + 1
    shape = c1.max(axis=0) + 1
    count = span.prod(axis=1)
    owner = np.repeat(np.arange(n), count)
    # the k-th cell of box i: offsets (a, b, c) within its span, x fastest
    k = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    sx, sy = span[owner, 0], span[owner, 1]
    cx = c0[owner, 0] + k % sx
    cy = c0[owner, 1] + (k // sx) % sy
    cz = c0[owner, 2] + k // (sx * sy)
    key = (cz * shape[1] + cy) * shape[0] + cx
    order = np.lexsort((owner, key))
    key, owner = key[order], owner[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    size = np.diff(np.r_[start, len(key)])
    group_start = np.repeat(start, size)
    pos = np.arange(len(key)) - group_start
    later = np.repeat(size, size) - pos - 1  # entries after this one in its cell
    first = np.repeat(np.arange(len(key)), later)
    offs = np.arange(len(first)) - np.repeat(np.cumsum(later) - later, later) + 1
    i, j = owner[first], owner[first + offs]
    # a pair of boxes shares every cell of their common box: keep it in one, the cell of the
    # common box's lowest corner, so that no pair comes twice
    cm = np.maximum(c0[i], c0[j])
    home = (cm[:, 2] * shape[1] + cm[:, 1]) * shape[0] + cm[:, 0] == key[first]
    i, j = i[home], j[home]
    ok = (i != j) & np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    a, b = np.minimum(i[ok], j[ok]), np.maximum(i[ok], j[ok])
    order = np.argsort(a * np.int64(n) + b)
    return np.stack([a[order], b[order]], axis=1)


def _is_candidate(a: Patch, b: Patch, bodies) -> bool:
    """Whether patch ``a`` (not ``b``) carries the points of their joint (module docstring)."""
    sa, sb = _support(bodies[a.body]), _support(bodies[b.body])
    if sa != sb:
        return sb
    for axis in (1, 0, 2):
        if abs(a.normal[axis]) > 1e-6:
            return a.normal[axis] < 0.0
    return a.body < b.body


def _support(body) -> bool:
    return isinstance(body, RigidBody) and body.support


def find_joints(bodies: Sequence, *, max_gap: float, gap_tol: float = 1e-6,
                angle_tol: float = JOINT_ANGLE_TOL) -> Detection:
    """The facing patches of ``bodies`` (module docstring), one :class:`Joint` per candidate
    patch, in body order, then from the bottom up (by the outward normal's ``n_y``, ``n_x``,
    ``n_z``: a unit's bed joint, then its head joints, then the glue on its top)."""
    patches = [p for i, b in enumerate(bodies) for p in planar_patches(i, b.X, b.conn)]
    if not patches:
        return Detection([], [])
    pad = max_gap + gap_tol
    lo = np.array([p.lo for p in patches]) - pad
    hi = np.array([p.hi for p in patches]) + pad
    cos_tol = np.cos(angle_tol)
    facing: dict[int, list[int]] = {}
    skewed = []
    pairs = candidate_pairs(lo, hi)
    # most pairs of boxes are faces of one body or faces that do not face each other: drop
    # them at once, with a margin, before the exact tests below
    body = np.array([p.body for p in patches])
    normal = np.array([p.normal for p in patches])
    dots = np.einsum("kd,kd->k", normal[pairs[:, 0]], normal[pairs[:, 1]])
    widest = min(cos_tol, np.cos(SKEW_REPORTED))
    pairs = pairs[(body[pairs[:, 0]] != body[pairs[:, 1]]) & (dots <= -widest + 1e-9)]
    for i, j in pairs:
        a, b = patches[i], patches[j]
        if a.body == b.body:
            continue
        if not a.normal @ b.normal <= -cos_tol:
            if a.normal @ b.normal <= -np.cos(SKEW_REPORTED):
                gaps = (bodies[b.body].X[b.quads].reshape(-1, 3) @ a.normal) - a.offset
                if np.any((gaps >= -gap_tol) & (gaps <= max_gap + gap_tol)):
                    skewed.append((a, b, float(np.arccos(min(1.0, -a.normal @ b.normal)))))
            continue
        if not _is_candidate(a, b, bodies):
            i, j, a, b = j, i, b, a
        # the antagonist's corners measured from the candidate's plane, along its normal
        gaps = (bodies[b.body].X[b.quads].reshape(-1, 3) @ a.normal) - a.offset
        if gaps.min() >= -gap_tol and gaps.max() <= max_gap + gap_tol:
            facing.setdefault(int(i), []).append(int(j))
    joints = []
    # a body's joints from the bottom up: by the candidate face's outward normal (n_y, n_x, n_z)
    for i in sorted(facing, key=lambda i: (patches[i].body, *patches[i].normal[[1, 0, 2]], i)):
        ants = sorted(facing[i], key=lambda j: (patches[j].body, j))
        joints.append(Joint(patches[i], [patches[j] for j in ants], -patches[i].normal))
    return Detection(patches, joints, skewed)


def joint_points(bodies: Sequence, joints: Sequence[Joint],
                 classify: Callable[[Joint, Patch], tuple[int, int, int] | None], *,
                 n_gauss: int = 2, rule: str = "gauss",
                 dof0: np.ndarray | None = None) -> list[ContactPoint]:
    """The contact points of ``joints`` (module docstring), ``n_gauss`` per direction of each
    face quad with the quadrature ``rule`` (``gauss`` or ``lobatto``), or on the common areas of
    the faces (``overlap``: :func:`_overlap_points`).

    ``classify(joint, antagonist_patch)`` gives the ``(group, kind, law)`` of the points that
    the antagonist takes, or None to make none there.
    """
    dof0 = dof_offsets(bodies) if dof0 is None else dof0
    if rule == "overlap":
        return _overlap_points(bodies, joints, classify, dof0)
    for jt in joints:
        for patch in (jt.candidate, *jt.antagonists):
            if corner_count(patch.faces) != 4:
                b = bodies[patch.body]
                raise ValueError(
                    f"body {patch.body}{f' ({b.name!r})' if b.name else ''} has triangular "
                    f"faces (a tetrahedral mesh): its joints take the contact-point rule "
                    f"'overlap', not {rule!r}")
    # first the points of every candidate face and their projections on its antagonists,
    # then every point located in every antagonist quad at once (locate_pairs)
    placed = []  # per joint: xs (nq, k, 3), areas (nq, k), ref (k, 2), [(gap, xa)] per antagonist
    pair_quads, pair_points = [], []
    for jt in joints:
        cand = jt.candidate
        n_out = cand.normal  # outward normal of the candidate face
        xs, areas, ref = gauss_points(bodies[cand.body].X[cand.quads], n_gauss, rule)
        projected = []
        for ant in jt.antagonists:
            # distance from each point to the antagonist's plane, along the candidate's normal
            gap = (ant.offset - xs @ ant.normal) / (n_out @ ant.normal)
            xa = xs + gap[..., None] * n_out
            projected.append((gap, xa))
            P = bodies[ant.body].X[ant.quads]  # (m, 4, 3)
            k = xa.shape[0] * xa.shape[1]
            pair_quads.append(np.broadcast_to(P, (k, *P.shape)).reshape(-1, 4, 3))
            pair_points.append(np.repeat(xa.reshape(-1, 3), len(P), axis=0))
        placed.append((xs, areas, ref, projected))
    xi_all, eta_all, inside_all = (locate_pairs(np.concatenate(pair_quads),
                                                np.concatenate(pair_points))
                                   if pair_quads else (None, None, None))
    out: list[ContactPoint] = []
    faces = 0  # element faces of the candidates, numbered joint after joint
    at = 0  # the next located pair
    for jt, (xs, areas, ref, projected) in zip(joints, placed, strict=True):
        cand = jt.candidate
        cb = bodies[cand.body]
        frame = joint_frame(jt.normal)
        taken = np.zeros(xs.shape[:2], dtype=bool)
        located = []
        for ant, (gap, xa) in zip(jt.antagonists, projected, strict=True):
            k, m = xs.shape[0] * xs.shape[1], len(ant.quads)
            sl = slice(at, at + k * m)
            located.append((gap, xa, xi_all[sl].reshape(k, m), eta_all[sl].reshape(k, m),
                            inside_all[sl].reshape(k, m)))
            at += k * m
        shares = np.ones(xs.shape[:2])
        if rule != "gauss":
            areas, taken = _merge_shared(xs, areas)
            # the antagonists each point faces: its area is shared between them
            faced = sum(loc[4].any(axis=1) for loc in located)
            shares = np.maximum(faced, 1).reshape(xs.shape[:2])
        for ant, (gap, xa, xi, eta, inside) in zip(jt.antagonists, located, strict=True):
            tag = classify(jt, ant)
            ab = bodies[ant.body]
            inside &= ~taken.reshape(-1)[:, None]
            hit = inside.any(axis=1)
            if rule == "gauss":  # the first antagonist takes the point
                taken |= hit.reshape(taken.shape)
            if tag is None:
                continue
            group, kind, law = tag
            for flat in np.flatnonzero(hit):
                q, k = divmod(int(flat), xs.shape[1])
                m = int(np.argmax(inside[flat]))
                x = xs[q, k]
                cand_side = _side(cb, int(dof0[cand.body]), cand.quads[q], x, frame, 1.0,
                                  ref[k])
                ant_side = _side(ab, int(dof0[ant.body]), ant.quads[m], xa[q, k], frame, -1.0,
                                 (xi[flat, m], eta[flat, m]))
                out.append(ContactPoint(
                    x=x, frame=frame, area=float(areas[q, k] / shares[q, k]),
                    gap=float(gap[q, k]), kind=kind,
                    law=law, group=group, bodies=(cand.body, ant.body),
                    sides=[cand_side, ant_side], face=faces + q))
        faces += len(cand.quads)
    return out


def _overlap_points(bodies: Sequence, joints: Sequence[Joint], classify, dof0: np.ndarray
                    ) -> list[ContactPoint]:
    """The contact points of ``joints`` on the common areas of their faces (rule ``overlap``,
    :mod:`masonry_nscd.model.overlap`): each candidate face clipped by each antagonist face in
    the candidate's plane (quadrilaterals or triangles, by their corners); on two rigid faces a
    point at each corner of the common area (the corners that adjacent common areas share made
    once, with the sum of their areas), else the degree-2 points of its triangles."""
    out: list[ContactPoint] = []
    faces = 0
    for jt in joints:
        cand = jt.candidate
        cb = bodies[cand.body]
        frame = joint_frame(jt.normal)
        n_out = cand.normal
        basis = overlap.plane_basis(n_out)
        Pc = cb.X[cand.corners]  # (nq, 4 or 3, 3)
        origin = Pc[0, 0]
        size = float(np.ptp(Pc.reshape(-1, 3), axis=0).max())
        for ant in jt.antagonists:
            tag = classify(jt, ant)
            if tag is None:
                continue
            group, kind, law = tag
            ab = bodies[ant.body]
            Pa = ab.X[ant.corners]
            rigid = isinstance(cb, RigidBody) and isinstance(ab, RigidBody)
            found = []  # (candidate quad, antagonist quad, points in the plane, areas)
            for q in range(len(Pc)):
                sub = (Pc[q] - origin) @ basis.T
                for m in range(len(Pa)):
                    common = overlap.clip(sub, (Pa[m] - origin) @ basis.T, 1e-9 * size)
                    if abs(overlap.signed_area(common)) <= 1e-12 * size * size:
                        continue
                    pts, areas = (overlap.vertex_points if rigid else
                                  overlap.triangle_points)(common)
                    found.append((q, m, pts, areas))
            if rigid and found:
                found = _merged_corners(found, 1e-9 * size)
            for q, m, pts, areas in found:
                for p2, area in zip(pts, areas, strict=True):
                    x = origin + p2 @ basis
                    gap = (ant.offset - x @ ant.normal) / (n_out @ ant.normal)
                    xa = x + gap * n_out
                    ref_c = None if isinstance(cb, RigidBody) else _reference(Pc[q], x)
                    ref_a = None if isinstance(ab, RigidBody) else _reference(Pa[m], xa)
                    out.append(ContactPoint(
                        x=x, frame=frame, area=float(area), gap=float(gap), kind=kind,
                        law=law, group=group, bodies=(cand.body, ant.body),
                        sides=[_side(cb, int(dof0[cand.body]), cand.quads[q], x, frame, 1.0,
                                     ref_c),
                               _side(ab, int(dof0[ant.body]), ant.quads[m], xa, frame, -1.0,
                                     ref_a)],
                        face=faces + q))
        faces += len(cand.quads)
    return out


def _merged_corners(found: list, tol: float) -> list:
    """The corners of the common areas of one rigid pair, the ones that several common areas
    share (within ``tol`` m) made once with the sum of their areas."""
    pts = np.concatenate([f[2] for f in found])
    areas = np.concatenate([f[3] for f in found])
    owner = np.concatenate([[i] * len(f[2]) for i, f in enumerate(found)])
    keys = np.round((pts - pts.min(axis=0)) / tol).astype(np.int64)
    first: dict[tuple[int, int], int] = {}  # a corner's key -> its first occurrence
    total: dict[tuple[int, int], float] = {}  # -> the sum of its areas, in order
    for i, key in enumerate(map(tuple, keys.tolist())):
        first.setdefault(key, i)
        total[key] = total.get(key, 0.0) + float(areas[i])
    return [(found[owner[first[key]]][0], found[owner[first[key]]][1],
             pts[first[key]:first[key] + 1], np.array([total[key]]))
            for key in sorted(first)]


def _reference(face: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """The reference coordinates of point ``x`` (3,) in the face with corners ``face`` (4 or
    3, 3): of the bilinear map of a quadrilateral, or of a triangle
    (:func:`~masonry_nscd.model.faces.triangle_coordinates`)."""
    if len(face) == 3:
        return triangle_coordinates(face, x)
    xi, eta, _ = locate(face[None], x[None])
    return float(xi[0, 0]), float(eta[0, 0])


def _merge_shared(xs: np.ndarray, areas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points of the quads of one face that coincide (within 1e-9 of the face's size): the
    areas (nq, k) with each first occurrence carrying the sum of its twins', and a mask
    (nq, k) of the later occurrences."""
    if len(xs) == 1:  # the points of one quad are distinct
        return areas, np.zeros(areas.shape, dtype=bool)
    flat = xs.reshape(-1, 3)
    size = float(np.ptp(flat, axis=0).max()) or 1.0
    keys = np.round((flat - flat.min(axis=0)) / (1e-9 * size)).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    total = np.bincount(inverse, weights=areas.reshape(-1))
    merged = np.zeros(flat.shape[0])
    merged[first] = total
    twin = np.ones(flat.shape[0], dtype=bool)
    twin[first] = False
    return merged.reshape(areas.shape), twin.reshape(areas.shape)


def _side(body, dof0: int, quad: np.ndarray, x: np.ndarray, frame: np.ndarray, sign: float,
          ref) -> tuple[np.ndarray, np.ndarray]:
    """Velocity map of point ``x`` of ``body``, at reference coordinates ``ref`` of its face
    ``quad`` (None on a rigid body, which needs none)."""
    if isinstance(body, RigidBody):
        return rigid_side(dof0, body, x, frame, sign)
    return deformable_side(dof0, quad, float(ref[0]), float(ref[1]), frame, sign)


def contact_points(bodies: Sequence, classify: Callable[[Joint, Patch], tuple[int, int, int] | None],
                   *, max_gap: float, n_gauss: int = 2, rule: str = "gauss",
                   gap_tol: float = 1e-6, angle_tol: float = JOINT_ANGLE_TOL
                   ) -> list[ContactPoint]:
    """The contact points of every joint of ``bodies``: :func:`find_joints`, then
    :func:`joint_points` with ``classify``."""
    found = find_joints(bodies, max_gap=max_gap, gap_tol=gap_tol, angle_tol=angle_tol)
    return joint_points(bodies, found.joints, classify, n_gauss=n_gauss, rule=rule)
