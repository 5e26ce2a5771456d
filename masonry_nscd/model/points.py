"""Contact points: where a joint is sampled, and how the bodies' velocities reach it.

A contact point sits on the candidate face of a joint. It carries a tributary area (m^2), a frame
(n, t, s) with ``n`` from the antagonist to the candidate (so that ``u_n > 0`` opens the joint)
and ``s = n x t``, the initial gap (m), the kind and law row of the joint and its group, and per
side the map from the body's dof velocities to the point's local relative velocity: bilinear
shape functions of the face (quadrilateral or triangle) on a block, lever arms on a rigid
body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from masonry_nscd.model.bodies import RigidBody
from masonry_nscd.model.faces import cross, face_shape


@dataclass
class ContactPoint:
    """One contact point between a candidate side (body 0) and an antagonist side (body 1).

    ``frame`` rows are (n, t, s), ``n`` pointing from the antagonist to the candidate, so that
    ``u_n > 0`` opens the joint. ``sides`` holds, per side, the global dofs and the matrix that
    maps their velocities to the point's local relative velocity (sign included).
    """

    x: np.ndarray  # m, position on the candidate face
    frame: np.ndarray  # (3, 3)
    area: float  # m^2, tributary area
    gap: float  # m, initial gap
    kind: int  # contact.laws.KIND_*
    law: int  # row of the parameter table
    group: int  # joint group id (the scene names them)
    bodies: tuple[int, int]  # body indices
    sides: list  # [(dofs (k,), coef (k, 3)), ...] velocity map per side
    face: int = -1  # the candidate's element face that carries the point (numbered by joint)


def frame_from(normal, tangent) -> np.ndarray:
    """Orthonormal frame rows (n, t, s) with s = n x t; ``tangent`` is projected on the plane."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    t = np.asarray(tangent, dtype=float)
    t = t - np.dot(t, n) * n
    t = t / np.linalg.norm(t)
    return np.array([n, t, cross(n, t)])


def joint_frame(normal) -> np.ndarray:
    """The frame of a joint of normal ``normal``: ``t`` along x, or along y when the normal is
    closer to x than 45 degrees (bed joints: t = x; head joints: t = y)."""
    n = np.asarray(normal, dtype=float)
    axis = (0.0, 1.0, 0.0) if abs(n[0]) > np.sqrt(0.5) * np.linalg.norm(n) else (1.0, 0.0, 0.0)
    return frame_from(n, axis)


def dof_offsets(bodies) -> np.ndarray:
    """First global dof of each body (and the total), in the numbering of
    ``nscd.system.build_system``."""
    return np.concatenate([[0], np.cumsum([b.ndof for b in bodies])]).astype(np.int64)


def deformable_side(dof0: int, nodes, xi: float, eta: float, frame, sign: float):
    """Velocity map of a point at reference coordinates (xi, eta) of a face of a block.

    ``v(x) = sum_i N_i(xi, eta) v_i`` with the face's shape functions (nodes in the face's
    order): bilinear on a four-node quadrilateral, linear or quadratic on a three- or six-node
    triangle (:func:`masonry_nscd.model.faces.face_shape`); the local relative velocity picks
    ``sign * frame @ v(x)``.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) == 4:
        Nq = 0.25 * np.array([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta),
                              (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
    else:
        Nq = face_shape(len(nodes), xi, eta)
    dofs = (dof0 + 3 * nodes[:, None] + np.arange(3)).ravel()
    coef = sign * (Nq[:, None, None] * np.asarray(frame).T[None, :, :]).reshape(3 * len(nodes), 3)
    return dofs, coef


def rigid_side(dof0: int, body: RigidBody, x: np.ndarray, frame, sign: float):
    """Velocity map of a material point x of a rigid body: ``v = v_0 + omega x (x - x_ref)``."""
    r0, r1, r2 = np.asarray(x) - body.reference
    dofs = dof0 + np.arange(6, dtype=np.int64)
    coef = np.empty((6, 3))
    coef[:3] = sign * frame.T
    # e_d x r for the unit vectors e_0, e_1, e_2
    for d, arm in enumerate(((0.0, -r2, r1), (r2, 0.0, -r0), (-r1, r0, 0.0))):
        coef[3 + d] = sign * frame @ np.array(arm)
    return dofs, coef
