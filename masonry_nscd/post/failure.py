r"""The failure mode of a wall, named from its joint and block damage at one output step.

A joint point has lost its cohesion when its integrity ``beta`` is below 0.01
(``COHESION_LOST_BETA``, which the summary's counts use too); a joint built with none (a dry
joint: initial damage 1) counts as lost where it is open by more than 0.1 mm or has slid by more
than 0.1 mm (``OPEN_M``, ``SLIP_M``), since its integrity says nothing. Fractions are fractions
of the tributary area. The mechanisms, read from the scene's joint groups and the places of its units
(``scene.json``):

``base sliding``
    the base bed joint (the lowest joint of a ``bed`` group, the glue left out) has lost its
    cohesion over at least 80 % of its area and, where the top's largest horizontal
    displacement so far ``U`` is given, slipped by at least a quarter of it (area-weighted mean ``|u_t|``): a
    joint that lost its bond under a rocking wall, its heel open and its toe pressed, has
    not made the wall slide;
``rocking``
    the base bed joint is open (normal relative displacement above 0.1 mm) over at least 20 %
    of its area: the wall turns about its toe (with or without base sliding);
``bed joint sliding``
    a bed joint above the base (the points of a bed group at one height) has lost its cohesion
    over at least 80 % of its area and slipped by a quarter of ``U``: the wall slides along
    it;
``diagonal stair-step``
    in at least half of the courses between the bottom and the top ones a head joint has lost
    its cohesion over at least half of its area (a crack that steps through the courses);
``toe crushing``
    a unit of the bottom or the top course has an element with a post-peak compressive damage
    ``d_c`` of 0.5 or more.

The name is the mechanisms found, joined by `` + `` in that order, or ``none``; with it come
the numbers that decide each, and the joints and units that make it, and every bed joint's
height, cohesion lost, opening and mean slip (``bed_joints``: where a wall slides, and how the
slip shares out between its bed joints). A scene without bed and head groups or without
courses (not a wall) gives ``n/a``.

The order of events (:func:`failure_sequence`), over the output steps: the displacement at which
the base bed joint has lost its cohesion over 80 % of its area, and the one at which a head
joint of the middle course (the diagonal crack crossing mid-height) has lost it over half of
its area.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from masonry_nscd.io.results_h5 import read_mesh_arrays, read_step_field

#: A joint point whose integrity ``beta`` is below this has lost its cohesion.
COHESION_LOST_BETA = 0.01
BASE_LOST_FRACTION = 0.8
BASE_OPEN_FRACTION = 0.2
#: A bed joint slides when its mean slip is at least this share of the top's displacement.
SLIDING_SHARE = 0.25
OPEN_M = 1e-4
SLIP_M = 1e-4
HEAD_LOST_FRACTION = 0.5
COURSES_FRACTION = 0.5
CRUSHED_D_C = 0.5


def _bed_levels(fields, groups: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The points of the bed groups (mask), and every point's height y rounded to a micrometre,
    which the points of one bed joint share (m)."""
    bed = np.isin(fields.contact_group, [i for i, g in enumerate(groups) if g.startswith("bed")])
    return bed, np.round(fields.contact_points_m[:, 1], 6)


def _base_points(fields, groups: list[str]) -> np.ndarray:
    """The contact points of the base bed joint (the lowest joint of a bed group)."""
    bed, level = _bed_levels(fields, groups)
    return bed & (level == level[bed].min()) if bed.any() else bed


def _bed_joints(fields, groups: list[str], lost: np.ndarray, joint_u_m: np.ndarray | None
                ) -> list[dict[str, float | None]]:
    """Every bed joint (the points of the bed groups at one height), lowest first: its height
    ``y_m``, the fractions of its area whose cohesion is lost (``cohesion_lost``) and that is
    open by more than 0.1 mm (``open``), and its area-weighted mean slip ``mean_slip_mm``
    (``|u_t|``; None, like ``open``, without the relative displacements)."""
    bed, level = _bed_levels(fields, groups)
    area = fields.contact_area_m2
    out = []
    for lv in np.unique(level[bed]):
        sel = bed & (level == lv)
        a = area[sel].sum()
        row: dict[str, float | None] = {"y_m": float(lv),
                                        "cohesion_lost": float(area[sel & lost].sum() / a),
                                        "open": None, "mean_slip_mm": None}
        if joint_u_m is not None:
            row["open"] = float(area[sel & (joint_u_m[:, 0] > OPEN_M)].sum() / a)
            slip = np.hypot(joint_u_m[sel, 1], joint_u_m[sel, 2])
            row["mean_slip_mm"] = float((area[sel] * slip).sum() / a * 1e3)
        out.append(row)
    return out


def _head_joints(fields, groups: list[str]) -> list[tuple[int, int, np.ndarray]]:
    """(antagonist, candidate, point mask) of every head joint."""
    head = fields.contact_group == groups.index("head")
    out = []
    for cand, ant in sorted({tuple(int(b) for b in pb) for pb in fields.contact_bodies[head]}):
        sel = head & (fields.contact_bodies[:, 0] == cand) & (fields.contact_bodies[:, 1] == ant)
        out.append((ant, cand, sel))
    return out


def _cracked(joints, area: np.ndarray, lost: np.ndarray) -> list[tuple[int, int]]:
    """The joints of ``joints`` that lost their cohesion over half of their area or more."""
    return [(ant, cand) for ant, cand, sel in joints
            if area[sel & lost].sum() >= HEAD_LOST_FRACTION * area[sel].sum()]


def failure_sequence(h5_path, scene: Mapping[str, Any], ux_by_step: Mapping[int, float]
                     ) -> dict[str, float | None]:
    """``U_x`` (mm) of the first output step at which the base bed joint has lost its cohesion
    over 80 % of its area, and of the first at which a head joint of the middle course has lost
    it over half of its area (None: never). Reads the integrities of every output step."""
    from types import SimpleNamespace

    groups = list(scene["groups"])
    structure = scene["structure"]
    if "head" not in groups or not all("course" in s for s in structure):
        return {}
    courses = sorted({s["course"] for s in structure})
    middle = courses[len(courses) // 2]
    body_course = {s["body"]: s["course"] for s in structure}
    out: dict[str, float | None] = {"base_joint_80pct_lost_at_ux_mm": None,
                                    "middle_course_head_joint_cracked_at_ux_mm": None,
                                    "middle_course": middle}
    mesh = SimpleNamespace(**read_mesh_arrays(h5_path, (
        "contact_group", "contact_points_m", "contact_area_m2", "contact_bodies")))
    base = _base_points(mesh, groups)
    joints = [jt for jt in _head_joints(mesh, groups) if body_course.get(jt[1]) == middle]
    area = mesh.contact_area_m2
    for step, beta in read_step_field(h5_path, "joint_beta"):
        lost = beta < COHESION_LOST_BETA
        ux = ux_by_step.get(step)
        if out["base_joint_80pct_lost_at_ux_mm"] is None and base.any() and \
                area[base & lost].sum() >= BASE_LOST_FRACTION * area[base].sum():
            out["base_joint_80pct_lost_at_ux_mm"] = ux
        if out["middle_course_head_joint_cracked_at_ux_mm"] is None and \
                _cracked(joints, area, lost):
            out["middle_course_head_joint_cracked_at_ux_mm"] = ux
    return out


def failure_mode(fields, scene: Mapping[str, Any], joint_u_m: np.ndarray | None,
                 top_ux_m: float | None = None) -> dict[str, Any]:
    """The failure mode at the output step of ``fields``
    (:class:`~masonry_nscd.io.results_h5.RunFields`); ``joint_u_m``: the relative
    displacements of the contact points (n, t, s) at that step, m; ``top_ux_m``: the top's
    largest horizontal displacement up to then, m (None: a joint that lost its cohesion is
    taken to slide, whatever its slip)."""
    groups = list(scene["groups"])
    structure = scene["structure"]
    if "head" not in groups or not any(g.startswith("bed") for g in groups) \
            or not all("course" in s for s in structure):
        return {"mode": "n/a"}
    lost = fields.joint_beta < COHESION_LOST_BETA
    if joint_u_m is not None:
        # joints with no cohesion as built (dry): open or slid
        dry = np.asarray(fields.contact_initial_damage) >= 1.0
        moved = (joint_u_m[:, 0] > OPEN_M) | (np.hypot(joint_u_m[:, 1], joint_u_m[:, 2]) > SLIP_M)
        lost = lost | (dry & moved)
    area = fields.contact_area_m2
    out: dict[str, Any] = {}
    modes = []

    # --- the bed joints, the base (the lowest) first --------------------------------------------
    beds = _bed_joints(fields, groups, lost, joint_u_m)
    base = beds[0] if beds else {"y_m": None, "cohesion_lost": 0.0, "open": None}
    lost_base, open_base = base["cohesion_lost"], base["open"] or 0.0
    out["base_joint_y_m"] = base["y_m"]
    out["base_joint_cohesion_lost"] = lost_base
    out["base_joint_open"] = open_base
    slip_needed_mm = None if top_ux_m is None else SLIDING_SHARE * abs(top_ux_m) * 1e3
    out["sliding_slip_needed_mm"] = slip_needed_mm

    def slides(b) -> bool:
        if b["cohesion_lost"] < BASE_LOST_FRACTION:
            return False
        return slip_needed_mm is None or b["mean_slip_mm"] is None \
            or b["mean_slip_mm"] >= slip_needed_mm

    if beds and slides(base):
        modes.append("base sliding")
    if open_base >= BASE_OPEN_FRACTION:
        modes.append("rocking")
    sliding = [b["y_m"] for b in beds[1:] if slides(b)]
    out["sliding_bed_joints_y_m"] = sliding
    if sliding:
        modes.append("bed joint sliding")
    out["bed_joints"] = beds

    # --- head joints through the courses ------------------------------------------------------
    body_course = {s["body"]: s["course"] for s in structure}
    courses = sorted(set(body_course.values()))
    inner = courses[1:-1]
    cracked: dict[int, list[tuple[int, int]]] = {}
    for ant, cand in _cracked(_head_joints(fields, groups), area, lost):
        c = body_course.get(cand)
        if c is not None:
            cracked.setdefault(c, []).append((ant, cand))
    crossed = [c for c in inner if c in cracked]
    out["courses_with_cracked_head_joints"] = sorted(cracked)
    if inner and len(crossed) >= COURSES_FRACTION * len(inner):
        modes.append("diagonal stair-step")

    # --- crushing at the toes -----------------------------------------------------------------
    names = dict(enumerate(scene["bodies"]))
    ends = {courses[0], courses[-1]}
    end_d_c = {k: float(fields.d_c[fields.block_of_element == k].max(initial=0.0))
               for k, s in enumerate(structure) if s["course"] in ends}
    crushed = [names[structure[k]["body"]] for k, d in end_d_c.items() if d >= CRUSHED_D_C]
    out["crushed_units"] = crushed
    out["largest_d_c_end_courses"] = max(end_d_c.values(), default=0.0)
    if crushed:
        modes.append("toe crushing")
    out["mode"] = " + ".join(modes) if modes else "none"
    return {"mode": out.pop("mode"), **out}
