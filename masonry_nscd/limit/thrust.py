r"""The line of thrust of an arch: where the resultant force of each joint crosses it, in the
arch's plane (x, y).

An arch's joint ``j`` (between voussoirs ``j`` and ``j + 1``; 0 and ``n`` the springings) runs
in the arch's plane from its intrados point ``a_j`` to its extrados point ``b_j`` (the scene's
``arch`` information), direction ``d = (b_j - a_j) / |b_j - a_j|``, middle ``m_j``. The forces
``f_p`` of its interface points (N, global) have the resultant ``F = sum f_p`` and the moment
about the middle ``M = sum ((x_p - m_j) x f_p)_z`` (N m, about the axis normal to the plane).
The resultant crosses the joint's line at

    c_j = m_j + e_j d,    e_j = M / (d x F)_z                     (m)

the **eccentricity** ``e_j`` measured from the middle towards the extrados: the point where
one force ``F`` has the joints' moment. Without tension the resultant lies within the joint,
``|e_j| <= t_j / 2`` (``t_j = |b_j - a_j|``); at a hinge of the mechanism it reaches the face
the hinge turns about. The line through the points ``c_j`` is the line of thrust of the static
solution (the programme's joint forces; at collapse, with four hinges, the one admissible line
that touches the faces at the hinges). The normal force ``N_j`` (compression positive) and the
shear ``V_j`` are the resultant's components along the joint's normal and ``d``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from masonry_nscd.limit.statics import RigidModel

#: Columns of ``thrust_line.csv`` (and keys of each row of :func:`thrust_line`).
COLUMNS = ("joint", "angle_from_crown_deg", "x_m", "y_m", "eccentricity_m",
           "relative_eccentricity", "thickness_m", "N_N", "V_N")


def thrust_line(m: RigidModel, forces: np.ndarray, joints: list[dict[str, Any]],
                arch: Mapping[str, Any] | None) -> list[dict[str, Any]]:
    """One row per arch joint that carries a force, in the order of the joints (module
    docstring): ``joints`` as :func:`masonry_nscd.limit.mechanism.joints` finds them (their
    points and, for an arch, their joint numbers); ``forces`` (p, 3) N in the points' frames.
    ``relative_eccentricity`` is ``e_j / (t_j / 2)`` (1 at the extrados, -1 at the
    intrados). Empty when the scene is not an arch."""
    if arch is None:
        return []
    f_global = np.einsum("pk,pkj->pj", forces, m.frame)  # on the candidate
    rows = []
    for jt in joints:
        j = jt.get("joint")
        if j is None:
            continue
        idx = np.asarray(jt["points"])
        a = np.asarray(arch["joints_intrados_m"][j], float)[:2]
        b = np.asarray(arch["joints_extrados_m"][j], float)[:2]
        t = float(np.linalg.norm(b - a))
        d = (b - a) / t
        mid = 0.5 * (a + b)
        f = f_global[idx, :2].copy()
        # one sense for the whole joint: the force on the body of the higher number
        f *= _sense(m, idx, jt)[:, None]
        F = f.sum(axis=0)
        r = m.x[idx, :2] - mid
        M = float((r[:, 0] * f[:, 1] - r[:, 1] * f[:, 0]).sum())
        cross = float(d[0] * F[1] - d[1] * F[0])
        normal = np.array([d[1], -d[0]])  # in the plane, across the joint
        N = abs(float(F @ normal))
        if not np.any(f) or abs(cross) <= 1e-12 * max(float(np.linalg.norm(F)), 1e-300):
            continue
        e = M / cross
        c = mid + e * d
        place = jt.get("angle_from_crown_deg")
        rows.append({"joint": int(j), "angle_from_crown_deg": place,
                     "x_m": float(c[0]), "y_m": float(c[1]), "eccentricity_m": float(e),
                     "relative_eccentricity": float(e / (0.5 * t)), "thickness_m": t,
                     "N_N": N, "V_N": float(F @ d) * float(np.sign(F @ normal) or 1.0)})
    rows.sort(key=lambda r: r["joint"])
    return rows


def _sense(m: RigidModel, idx: np.ndarray, jt: dict[str, Any]) -> np.ndarray:
    """+1 for a point whose candidate is the joint's second body (by name order of
    ``jt['bodies']``), -1 otherwise: the points of one joint may name their bodies either
    way round."""
    second = jt["bodies"][1]
    return np.where(np.asarray([m.names[c] for c in m.pair[idx, 0]]) == second, 1.0, -1.0)
