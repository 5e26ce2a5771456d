r"""The collapse mechanism read joint by joint, named as the NSCD summary names it.

A **joint** is the set of interface points between one pair of bodies. From the mechanism's
relative velocities ``u = (u_n, u_t, u_s)`` of its points (:func:`.statics.point_velocities`;
normalised: the fastest node moves at 1), with the tolerance ``tol`` (relative to that 1):

* **closed**: every ``|u| <= tol``;
* **sliding**: a point slips, ``|(u_t, u_s)| > tol`` (with associative friction a sliding
  joint also opens by ``mu`` times its slip: it counts as sliding);
* **hinge**: no slip, some points open (``u_n > tol``) and some not: the bodies turn about the
  points that stay closed, the **pivot** (their mean position);
* **open**: no slip, every point opens (the bodies separate).

The names, the arch's joint numbers, faces and angles from the crown, and the mechanism's name
(``four-hinge``, ``sliding``, ``hinges and sliding``...) are those of the NSCD summary
(:mod:`masonry_nscd.post.limit`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from masonry_nscd.limit.statics import RigidModel
from masonry_nscd.post.limit import arch_place, mechanism_name

#: Relative velocity below which a point neither opens nor slips (of the fastest node's 1).
TOLERANCE = 1e-5


def joints(m: RigidModel, u: np.ndarray, scene_info: dict[str, Any],
           tol: float = TOLERANCE) -> list[dict[str, Any]]:
    """Every joint of the model (module docstring), in the order of their first point: the
    bodies' names, group, ``kind``, the largest opening and slip rates, the pivot (m, hinges),
    the centre (m), and for an arch its joint number, face and angle."""
    groups = list(scene_info["groups"])
    arch = scene_info.get("arch")
    pairs: dict[tuple[int, int], list[int]] = {}
    for p, (a, b) in enumerate(m.pair):
        if not m.glued[p]:
            pairs.setdefault((int(min(a, b)), int(max(a, b))), []).append(p)
    out = []
    for (b0, b1), members in pairs.items():
        idx = np.asarray(members)
        un = u[idx, 0]
        slip = np.linalg.norm(u[idx, 1:], axis=1)
        opens = un > tol
        if slip.max() > tol:
            kind = "sliding"
        elif opens.all():
            kind = "open"
        elif opens.any():
            kind = "hinge"
        else:
            kind = "closed"
        pivot = m.x[idx[~opens]].mean(axis=0) if kind == "hinge" else None
        entry: dict[str, Any] = {
            "bodies": [m.names[b0], m.names[b1]], "group": groups[int(m.group[idx[0]])],
            "kind": kind, "max_opening_rate": float(max(un.max(), 0.0)),
            "max_slip_rate": float(slip.max()),
            "pivot_m": None if pivot is None else [float(v) for v in pivot],
            "centre_m": [float(v) for v in m.x[idx].mean(axis=0)],
            "points": [int(i) for i in idx]}
        if arch is not None:
            entry.update(arch_place(arch, m.names[b0], m.names[b1], pivot))
        out.append(entry)
    return out


def summary(found: list[dict[str, Any]]) -> dict[str, Any]:
    """The mechanism's name and its hinges, sliding and open joints (the point lists
    dropped)."""
    def public(j):
        return {k: v for k, v in j.items() if k != "points"}

    return {"mechanism": mechanism_name(found),
            "hinges": [public(j) for j in found if j["kind"] == "hinge"],
            "sliding_joints": [public(j) for j in found if j["kind"] == "sliding"],
            "open_joints": [public(j) for j in found if j["kind"] == "open"]}
