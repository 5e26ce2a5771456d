r"""What a limit-state run ended in: its status, its collapse, its hinges and sliding joints.

The status and the collapse come from ``limit.json`` (:mod:`masonry_nscd.collapse`, read by
:func:`masonry_nscd.io.limit_files.read_limit`); the state of the joints from the last output
step of ``results.h5``.

A joint (the contact points between two bodies) at one output step, from the normal opening
``u_n`` (m) of its points (positive: open) and their slip:

* the opening is fitted by a plane over the face, ``u_n(x) = a + g . (x - x_c)`` (least squares,
  ``g`` in the face's plane, m/m: the joint's relative rotation), and read along ``g`` over the
  extent of the points ``[s_min, s_max]``;
* the **open fraction** is the part of that extent where the fitted opening passes
  ``hinge_opening_m`` (the ``collapse`` section of the case);
* a **hinge**: open over at least half of the face (``HINGE_FRACTION``) and closed at one edge
  (the fitted opening at ``s_min`` at most ``hinge_opening_m``): the two bodies turn about that
  edge, the **pivot**. With Gauss-Lobatto points (an arch's default) the points span the face;
* **open**: open everywhere (the bodies have separated);
* **sliding**: closed, and a point has slid by more than ``hinge_opening_m`` (tangential
  relative displacement).

An arch's joints are numbered from 0 (the left springing) to ``n`` (the right one), joint ``j``
between voussoirs ``j`` and ``j + 1``; the pivot is on the ``intrados`` or the ``extrados``
(whichever end of the joint line is nearer), and ``angle_from_crown_deg`` is the angle of the
joint's line from the vertical through the centre of its arc (the crown joint of a pointed arch
has none).

The mechanism is named from the count: ``four-hinge`` (a fixed arch's one degree of freedom),
``three-hinge``, ``five-hinge`` (the symmetric mechanism of a symmetric arch and load), ...,
``sliding``, or ``hinges and sliding``; ``none`` when no joint has moved.

Every output step of a limit-state run marks the state of each contact point's joint in the
field ``joint_state`` of the joints' VTU files (``vtu/joints_*.vtu``; :data:`STATE_CODES`: 1
closed, 2 partly open, 3 open, 4 sliding, 5 hinge; 0 off the joint groups), computed by the
same :func:`classify_joints` from the step's relative displacements.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.io.limit_files import read_limit, read_limit_table
from masonry_nscd.io.runfolder import LIMIT_CSV, SUMMARY

#: A hinge is open over at least this fraction of its face.
HINGE_FRACTION = 0.5
_COUNT_NAMES = {1: "one-hinge", 2: "two-hinge", 3: "three-hinge", 4: "four-hinge",
                5: "five-hinge", 6: "six-hinge"}


#: The code of each joint state in the ``joint_state`` field of the contact points (VTU output
#: of a limit-state run, results.h5): 0 for a point of no joint group (the glue).
STATE_CODES = {"closed": 1, "partly open": 2, "open": 3, "sliding": 4, "hinge": 5}


def classify_joints(x: np.ndarray, normal: np.ndarray, bodies: np.ndarray, group: np.ndarray,
                    joint_ids, u: np.ndarray, opening_m: float) -> list[dict[str, Any]]:
    """The joints (the points of one pair of bodies in the groups ``joint_ids``) and their
    state (module docstring), in the order of their first point; plain arrays per contact
    point: positions ``x`` (p, 3) m, joint normals (p, 3), bodies (p, 2), group ids (p,),
    relative displacements ``u`` (p, 3) m (n, t, s). Each joint: ``members`` (its points),
    ``pair``, ``kind``, ``open_fraction``, ``max_opening_m``, ``rotation_rad``, ``slip_m``,
    ``pivot`` (m), ``centre`` (m)."""
    idx = np.flatnonzero(np.isin(group, list(joint_ids)))
    pairs: dict[tuple[int, int], list[int]] = {}
    for a in idx:
        cand, ant = (int(b) for b in bodies[a])
        pairs.setdefault((min(cand, ant), max(cand, ant)), []).append(int(a))
    out = []
    for pair, members in pairs.items():
        pts = np.asarray(members)
        xp = x[pts]
        n = normal[pts[0]]
        un = u[pts, 0]
        slip = float(np.linalg.norm(u[pts, 1:], axis=1).max())
        xc = xp.mean(axis=0)
        d = xp - xc
        d = d - np.outer(d @ n, n)  # in the face's plane
        # least squares u_n = a + g . d, g in the plane (the normal component has no data)
        A = np.column_stack([np.ones(len(pts)), d])
        coef, *_ = np.linalg.lstsq(A, un, rcond=None)
        a0, g = float(coef[0]), coef[1:] - (coef[1:] @ n) * n
        gnorm = float(np.linalg.norm(g))
        if gnorm > 0.0:
            e = g / gnorm
            sp = d @ e
            s_lo, s_hi = float(sp.min()), float(sp.max())
        else:
            e, s_lo, s_hi = np.zeros(3), 0.0, 0.0
        low, high = a0 + gnorm * s_lo, a0 + gnorm * s_hi
        if high <= opening_m:
            fraction = 0.0
        elif low > opening_m:
            fraction = 1.0
        else:
            fraction = (high - opening_m) / (high - low) if high > low else 0.0
        if fraction >= HINGE_FRACTION and low <= opening_m:
            kind = "hinge"
        elif fraction >= 1.0:
            kind = "open"
        elif fraction == 0.0 and slip > opening_m:
            kind = "sliding"
        elif fraction > 0.0:
            kind = "partly open"
        else:
            kind = "closed"
        out.append({"members": pts, "pair": pair, "kind": kind, "open_fraction": fraction,
                    "max_opening_m": float(max(high, un.max())), "rotation_rad": gnorm,
                    "slip_m": slip, "pivot": xc + s_lo * e, "centre": xc})
    return out


def state_codes(joints: list[dict[str, Any]], count: int) -> np.ndarray:
    """Per contact point (``count``), the code (:data:`STATE_CODES`) of its joint's state."""
    codes = np.zeros(count)
    for j in joints:
        codes[j["members"]] = STATE_CODES[j["kind"]]
    return codes


def joint_states(fields, scene: Mapping[str, Any], opening_m: float) -> list[dict[str, Any]]:
    """Every joint of the scene's joint groups at the output step of ``fields`` (module
    docstring), in the order of their first point."""
    groups = list(scene["groups"])
    joint_ids = [groups.index(g) for g in scene["joint_groups"]]
    names = dict(enumerate(scene["bodies"]))
    u = fields.joint_u_m
    if u is None:
        return []
    arch = scene.get("arch")
    out = []
    for j in classify_joints(fields.contact_points_m, fields.contact_frame[:, 0],
                             fields.contact_bodies, fields.contact_group, joint_ids, u,
                             opening_m):
        b0, b1 = j["pair"]
        kind, pivot = j["kind"], j["pivot"]
        entry: dict[str, Any] = {
            "bodies": [names[b0], names[b1]],
            "group": groups[int(fields.contact_group[j["members"][0]])],
            "kind": kind, "open_fraction": j["open_fraction"],
            "max_opening_m": j["max_opening_m"], "rotation_rad": j["rotation_rad"],
            "slip_m": j["slip_m"],
            "pivot_m": [float(v) for v in pivot] if kind == "hinge" else None,
            "centre_m": [float(v) for v in j["centre"]]}
        if arch is not None:
            entry.update(arch_place(arch, names[b0], names[b1], pivot if kind == "hinge"
                                     else None))
        out.append(entry)
    return out


def arch_place(arch: Mapping[str, Any], name0: str, name1: str,
                pivot: np.ndarray | None) -> dict[str, Any]:
    """The joint number of an arch's joint, the angle of its line from the crown, and on which
    face its pivot is."""
    n = int(arch["voussoirs"])

    def number(name: str) -> int | None:
        if name.startswith("voussoir "):
            return int(name.split()[1])
        return None

    k0, k1 = number(name0), number(name1)
    if k0 is not None and k1 is not None:
        j = min(k0, k1)
    elif (k0 or k1) is not None:
        j = 0 if (k0 or k1) == 1 else n
    else:
        return {"joint": None}
    p_in = np.asarray(arch["joints_intrados_m"][j])
    p_out = np.asarray(arch["joints_extrados_m"][j])
    centre = arch["joint_centres_m"][j]
    mid = 0.5 * (p_in + p_out)
    angle = None if centre is None else \
        math.degrees(math.atan2(abs(mid[0] - centre[0]), mid[1] - centre[1]))
    side = None
    if pivot is not None:
        side = "intrados" if np.linalg.norm(pivot[:2] - p_in) < np.linalg.norm(pivot[:2] - p_out) \
            else "extrados"
    return {"joint": j, "angle_from_crown_deg": angle, "side": side}


#: Hinges a report names (the run log's summary line, ``masonry limit``'s); the others are in
#: ``summary.json`` or ``limit.json``
HINGES_SHOWN = 12


def describe_hinge(h: dict[str, Any]) -> str:
    """One hinge as the reports name it: ``joint 3 (intrados, 67.5 deg from the crown)`` for
    an arch, else the two bodies."""
    if h.get("joint") is not None:
        angle = h.get("angle_from_crown_deg")
        return f"joint {h['joint']} ({h.get('side')}" + (
            f", {angle:.1f} deg from the crown)" if angle is not None else ")")
    return f"{h['bodies'][0]} / {h['bodies'][1]}"


def describe_hinges(hinges: list[dict[str, Any]], listed_in: str) -> str:
    """The first :data:`HINGES_SHOWN` hinges, ``; ``-separated (:func:`describe_hinge`), and how
    many more the file ``listed_in`` lists: a vault's thousand hinges are read there, not in a
    report's line."""
    named = "; ".join(describe_hinge(h) for h in hinges[:HINGES_SHOWN])
    more = len(hinges) - HINGES_SHOWN
    return named + (f"; {more} more ({listed_in} lists every hinge)" if more > 0 else "")


def mechanism_line(mechanism: str, hinges: list[dict[str, Any]], sliding: list[Any],
                   listed_in: str) -> str:
    """The reports' line of a mechanism: its name, its hinges (:func:`describe_hinges`, the
    others in the file ``listed_in``) and how many joints slide."""
    return (f"mechanism: {mechanism}"
            + (f"; hinges at {describe_hinges(hinges, listed_in)}" if hinges else "")
            + (f"; {len(sliding)} joints sliding" if sliding else ""))


def mechanism_name(joints: list[dict[str, Any]]) -> str:
    """``four-hinge``, ``sliding``, ``hinges and sliding``, ``none``... (module docstring)."""
    hinges = sum(1 for j in joints if j["kind"] == "hinge")
    sliding = sum(1 for j in joints if j["kind"] == "sliding")
    if hinges and sliding:
        return "hinges and sliding"
    if sliding:
        return "sliding"
    if hinges:
        return _COUNT_NAMES.get(hinges, f"{hinges}-hinge")
    return "none" if not any(j["kind"] in ("open", "partly open") for j in joints) \
        else "joints opening"


def removal_groups(info) -> list[dict]:
    """The groups of a run folder's ``removal`` (``scene.json``, the summary), a list of
    ``{blocks, time_s, at_s}`` in the order of their times; one group given alone (a mapping)
    is a list of one, none is ``[]``."""
    if not info:
        return []
    return [info] if isinstance(info, dict) else list(info)


def limit_summary(outdir: Path | str, scene: Mapping[str, Any], fields) -> dict[str, Any]:
    """The limit-state part of ``summary.json``: ``status`` (``collapse``, ``standing``,
    ``failed``, ``interrupted``, or ``running`` when no status was written), ``collapse``
    (loads and time at the onset and at the detection, the blocks that moved most; None if
    it stands), ``hinges`` (the hinges and sliding joints at the last output step),
    ``mechanism``, and ``moving_at_end`` (standing, but a block point faster than
    ``collapse.onset_velocity_m_s`` at the end: a mechanism too slow to pass the displacement
    bound in the time of the run), and ``removal`` (each group of blocks taken out, in the order
    of their times: its ``blocks``, the time asked for, ``time_s``, and the time they left,
    ``at_s``: the start of the step in which it falls; None without one), and
    ``creep_at_end`` (:func:`creep_at_end`)."""
    record = read_limit(outdir) or {}
    rule = scene.get("collapse") or {}
    opening = float(rule.get("hinge_opening_m", 1e-4))
    joints = joint_states(fields, scene, opening) if fields is not None else []
    moved = [j for j in joints if j["kind"] in ("hinge", "sliding", "open")]
    out: dict[str, Any] = {
        "status": record.get("status", "running"),
        "collapse": record.get("collapse"),
        "mechanism": mechanism_name(joints) if fields is not None else None,
        "hinges": [j for j in moved if j["kind"] == "hinge"],
        "sliding_joints": [j for j in moved if j["kind"] == "sliding"],
        "open_joints": [j for j in moved if j["kind"] == "open"],
        "joints_step": fields.step if fields is not None else None,
        "load_factors": rule.get("load_factors", []),
        "last_loads": (record.get("last") or {}).get("loads"),
        "removal": removal_groups(scene.get("removal")) or None,
    }
    last_speed = (record.get("last") or {}).get("max_speed_m_s")
    # standing by the rule, but still in motion at the end: a slow mechanism may be forming
    out["moving_at_end"] = bool(out["status"] == "standing" and last_speed is not None
                                and last_speed > float(rule.get("onset_velocity_m_s", 0.0)))
    out["creep_at_end"] = creep_at_end(read_limit_table(outdir)) \
        if (Path(outdir) / LIMIT_CSV).exists() else None
    if record.get("message"):
        out["status_message"] = record["message"]
    return out


#: The share of a run's time over which :func:`creep_at_end` reads the growth at its end.
CREEP_WINDOW_SHARE = 0.1
#: A growth at the end smaller than this is reported as none (m): a micron.
CREEP_NONE_M = 1e-6


def creep_at_end(table: Mapping[str, np.ndarray]) -> dict[str, float] | None:
    """How far the largest displacement of a block point grew over the last tenth of the run
    (``limit.csv``'s ``max_displacement_m`` at its last row less at the last row at or before
    ``t_end - window``): ``window_s`` (s), ``growth_m`` (m) and ``rate_m_s = growth_m /
    window_s`` (m/s). A structure at rest grows by nothing; one that stands by the rule but
    creeps (stones that slide a little after every rattle) says how fast, where the speed at
    the last step (``moving_at_end``) reads one instant. None with fewer than two rows."""
    t = np.asarray(table.get("time_s", ()), dtype=float)
    d = np.asarray(table.get("max_displacement_m", ()), dtype=float)
    if len(t) < 2:
        return None
    start = (1.0 - CREEP_WINDOW_SHARE) * t[-1] * (1.0 + 1e-12)  # a row at the start counts
    k = max(int(np.searchsorted(t, start, side="right")) - 1, 0)
    window = float(t[-1] - t[k])
    growth = float(d[-1] - d[k])
    return {"window_s": window, "growth_m": growth,
            "rate_m_s": growth / window if window > 0.0 else 0.0}


def _creep_words(creep: Mapping[str, float] | None) -> str:
    """The report's words for :func:`creep_at_end` (empty without it)."""
    if not creep:
        return ""
    if abs(creep["growth_m"]) < CREEP_NONE_M:
        return (f"; the largest displacement steady over the last {creep['window_s']:.3g} s "
                f"(within {1e3 * CREEP_NONE_M:g} mm)")
    return (f"; the largest displacement grew by {1e3 * creep['growth_m']:.3g} mm over the "
            f"last {creep['window_s']:.3g} s ({1e3 * creep['rate_m_s']:.3g} mm/s)")


def format_limit(s: Mapping[str, Any]) -> list[str]:
    """The lines of the short report of a limit-state summary."""
    lines = [f"status: {s['status']}" + (f" ({s['status_message']})"
                                         if s.get("status_message") else "")]
    for group in removal_groups(s.get("removal")):
        lines.append(f"removed at t = {group['at_s']:.4f} s: " + ", ".join(group["blocks"]))
    c = s.get("collapse")
    if c:
        loads = c.get("loads_at_onset") or c.get("loads_at_detection") or {}
        when = c.get("onset_time_s")
        lines.append("collapse: " + (", ".join(f"{k} = {v:.5g}" for k, v in loads.items())
                                     + " at the onset" if loads else "the mechanism started")
                     + (f", t = {when:.4f} s" if when is not None else "")
                     + f" (detected by its {c['detected_by']} at t = "
                     f"{c['detected_time_s']:.4f} s)")
        if c.get("moved_most"):
            lines.append("collapse: moved most: " + ", ".join(
                f"{m['body']} ({1e3 * m['displacement_m']:.3g} mm)" for m in c["moved_most"][:3]))
    elif s.get("last_loads"):
        lines.append("standing at " + ", ".join(f"{k} = {v:.5g}"
                                                for k, v in s["last_loads"].items())
                     + _creep_words(s.get("creep_at_end")))
    if s.get("moving_at_end"):
        lines.append("standing, but still moving at the end: a slow mechanism may be forming "
                     "(a later collapse.end_time_s tells)")
    if s.get("mechanism") is not None:
        lines.append(mechanism_line(s["mechanism"], s.get("hinges") or [],
                                    s.get("sliding_joints") or [], SUMMARY))
    return lines
