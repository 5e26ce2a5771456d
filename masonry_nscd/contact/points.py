"""Contact points between facing faces (detected once: small displacements, permanent contacts).

The points sit at the Gauss points (``n_gauss`` per direction, default 2, i.e. 2x2) of each
element face quad of the candidate face. Each carries the tributary area of its Gauss weight,
a frame (n, t, s) with ``n`` from the antagonist to the candidate and ``s = n x t``, the initial
gap, and the interpolation that maps the velocities of both bodies to its local relative
velocity: bilinear shape functions on a block's face quad, lever arms on a rigid body. The
antagonist point is the projection of the candidate point across the gap.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.model import Block, ContactPoint, RigidBody, deformable_side, rigid_side


def frame_from(normal, tangent) -> np.ndarray:
    """Orthonormal frame rows (n, t, s) with s = n x t."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    t = np.asarray(tangent, dtype=float)
    t = t - np.dot(t, n) * n
    t = t / np.linalg.norm(t)
    return np.array([n, t, np.cross(n, t)])


def dof_offsets(bodies) -> np.ndarray:
    """First global dof of each body, in the numbering of ``nscd.system.build_system``."""
    return np.concatenate([[0], np.cumsum([b.ndof for b in bodies])]).astype(np.int64)


def _side(bodies, dof0, i, geom: Block | None, x, frame, sign, axis, upper):
    body = bodies[i]
    if isinstance(body, RigidBody):
        return rigid_side(int(dof0[i]), body, x, frame, sign)
    found = geom.locate(x, axis, upper)
    if found is None:
        return None
    nodes, xi, eta = found
    return deformable_side(int(dof0[i]), nodes, xi, eta, frame, sign)


def face_contacts(
    bodies: list,
    dof0: np.ndarray,
    candidate: int,
    cand_geom: Block,
    axis: int,
    upper: bool,
    antagonists: list[tuple[int, Block | None]],
    *,
    gap: float,
    tangent,
    kind: int,
    law: int,
    group: int,
    n_gauss: int = 2,
) -> list[ContactPoint]:
    """Points on the face (axis, upper) of the candidate, each facing one of the antagonists.

    The candidate's face is ``axis = max`` when ``upper`` else ``axis = min``; the antagonist
    face is the opposite one, across ``gap`` (m). ``antagonists`` lists (body index, geometry or
    None for a rigid body without faces, e.g. a steel beam); each point goes to the first one
    whose face contains its projection. A point facing none is dropped (an open end).
    """
    normal = np.zeros(3)
    normal[axis] = 1.0 if upper else -1.0  # outward normal of the candidate face
    n_ant_to_cand = -normal
    frame = frame_from(n_ant_to_cand, tangent)
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    out = []
    for nodes, a1, a2, lo, hi in cand_geom.face_quads(axis, upper):
        half = 0.5 * (hi - lo)
        for p in range(n_gauss):
            for q in range(n_gauss):
                x = np.empty(3)
                x[axis] = cand_geom.origin[axis] + (cand_geom.size[axis] if upper else 0.0)
                x[a1] = lo[0] + half[0] * (1.0 + g[p])
                x[a2] = lo[1] + half[1] * (1.0 + g[q])
                area = w[p] * w[q] * half[0] * half[1]
                cand_side = _side(bodies, dof0, candidate, cand_geom, x, frame, 1.0, axis, upper)
                xa = x + gap * normal
                for ai, ageom in antagonists:
                    ant_side = _side(bodies, dof0, ai, ageom, xa, frame, -1.0, axis, not upper)
                    if ant_side is not None:
                        out.append(ContactPoint(
                            x=x, frame=frame, area=area, gap=gap, kind=kind, law=law,
                            group=group, bodies=(candidate, ai), sides=[cand_side, ant_side],
                        ))
                        break
    return out
