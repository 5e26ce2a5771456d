r"""The cross vault: a groin vault of stones in courses over a rectangular bay, on four supports
(lengths in m, angles in rad, y up, north +z, east +x).

The bay spans ``a = span_x`` by ``b = span_z`` between the centrelines of its supports. The arch
of the barrel across z is the arc of radius ``R`` (``b / 2`` for a semicircular vault) about a
centre on the springing plane ``c = R - b / 2`` beyond the bay's axis. A point of that arch at
``rho`` from its centre (``R -+ t/2`` at the intrados and the extrados) has the horizontal
distance ``r = rho cos(alpha) - c`` from the axis and the height ``y = rho sin(alpha)``; the
courses cut ``alpha`` from 0 to ``acos(c / rho)`` (where ``r = 0``, the crown) into equal parts
at each of the two radii, so that the crown joint is the vertical plane of the axis. With
``w = r / (b / 2)``, the barrel across z (the east and west webs) has its points at
``z = +- (b / 2) w`` and the barrel across x (north and south) at ``x = +- (a / 2) w``: the same
arch scaled by ``a / b`` in plan, of the same rise. At a height both barrels meet where
``|x| / a = |z| / b``: the groins are the vertical planes of the bay's diagonals, and a web's
stone reaches its groin at ``(a / 2) w`` along x (east) or ``(b / 2) w`` along z (north).

A web's course lies between two levels of the arch and runs along its barrel's axis, from the
groin to the web's end (``a / 2`` or ``b / 2``), cut into stones by planes across it. Every
face of a stone is flat: its beds hold lines along the axis, its intrados and extrados two
parallel lines, its ends are planes across the axis or the groin's plane; the groin stones of
two webs in the same course share their groin face. The lowest ``springer_courses`` courses at a
corner are the springer, one body of two hexahedra: under the bed of the first free course of
each web, down to the springing plane, meeting on the groin. With ``transverse_ribs``, an arch
of the same levels, ``rib_depth`` deep below the webs' extrados and ``rib_width`` wide, stands
against each end of the east and west webs; its voussoirs spring from the same supports. With
``diagonal_ribs``, the two groin stones of a course at a corner are one block, a voussoir of the
diagonal rib: its intrados ``diagonal_rib_depth`` further on each bed's line (so that the bed
stays one plane), bonded into both webs; the top course's eight groin stones are the boss where
the ribs cross, and the springers' tops are deepened the same way. Each support is a fixed box
under the springer (and the transverse ribs' feet) of its corner; with ``piers`` the box stands
``pier_height`` lower, and a pier of drums (``pier <corner> drum k``, k from 1 at the bottom,
boxes of the feet's plan) fills the height between it and the springing plane.

Joint groups: ``bed`` (courses of a web), ``head`` (stones of a course), ``crown`` (the two
halves of a web), ``groin`` (two webs), ``springer`` (a web on its springer), ``rib`` (the
ribs' own joints, the boss's included), ``rib side`` (a web or springer against a rib), ``pier``
(the drums, and the springers and ribs on them), ``base`` (on the supports).
Loads, solver and collapse rule are those of every limit-state scene
(:mod:`masonry_nscd.scenes.limit_loads`); ``loading.settlement`` moves the supports of a corner
or a side (the spreading of the bay).
"""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np

from masonry_nscd.case.structures.arch import named_block_problems
from masonry_nscd.case.structures.cross_vault import CORNERS, SIDES, WEBS
from masonry_nscd.contact import laws
from masonry_nscd.model import RigidBody
from masonry_nscd.model.detection import find_joints, joint_points
from masonry_nscd.scenes import Builder
from masonry_nscd.scenes.limit_loads import (
    limit_loads,
    limit_settings,
    structure_block,
    support_motion,
    until_collapse,
)
from masonry_nscd.scenes.scene import Scene

GROUPS = ("bed", "head", "crown", "groin", "springer", "rib", "rib side", "pier", "base")
#: Per web: the horizontal axis its courses run along (0: x, 2: z) and its side of the bay
_WEB_AXIS = {"east": (0, 1.0), "west": (0, -1.0), "north": (2, 1.0), "south": (2, -1.0)}
#: Per web: the names of its two halves (the sign of the coordinate across its courses)
_HALVES = {"east": ("north", "south"), "west": ("north", "south"),
           "north": ("east", "west"), "south": ("east", "west")}
_SIGN = {"north": 1.0, "south": -1.0, "east": 1.0, "west": -1.0}


class ArchSection:
    """The arch across z of a cross vault ``v`` (module docstring): the horizontal distance
    ``w`` (in half spans) and the height ``y`` (m) of its level ``j`` (0 at the springing,
    ``courses`` at the crown) at the radius ``rho`` (m)."""

    def __init__(self, v):
        self.v = v
        self.R, self.c = v.arch_radius_m, v.offset_m

    def point(self, j: int, rho: float) -> tuple[float, float]:
        """``(w, y)`` of level ``j`` at ``rho``."""
        top = math.acos(min(1.0, self.c / rho))
        alpha = top * j / self.v.courses
        r = 0.0 if j == self.v.courses else rho * math.cos(alpha) - self.c
        return r / (self.v.span_z_m / 2.0), rho * math.sin(alpha)

    @property
    def radii(self) -> tuple[float, float]:
        """The intrados and extrados radii of the webs (m)."""
        t = self.v.thickness_m
        return self.R - t / 2.0, self.R + t / 2.0

    def level(self, j: int, s: int, deep: bool = False) -> tuple[float, float]:
        """``(w, y)`` of level ``j`` at the intrados (``s = 0``) or the extrados (1); with
        ``deep`` the intrados point moves ``diagonal_rib_depth_m`` further on the bed's line
        from the extrados through the intrados, so that a deepened bed stays one plane."""
        if not (deep and s == 0):
            return self.point(j, self.radii[s])
        (wi, yi), (we, ye) = (self.point(j, r) for r in self.radii)
        half = self.v.span_z_m / 2.0
        d = np.array([(wi - we) * half, yi - ye])
        r, y = np.array([wi * half, yi]) + d * self.v.diagonal_rib_depth_m / np.hypot(*d)
        return float(r / half), float(y)


def web_point(v, web: str, half: str, w: float, y: float, along: float) -> np.ndarray:
    """The point of web ``web`` (its ``half``) at ``w`` half spans across its courses, height
    ``y`` and ``along`` m from the bay's centre along its courses (m)."""
    axis, sign = _WEB_AXIS[web]
    across = 2 - axis
    half_across = (v.span_z_m if across == 2 else v.span_x_m) / 2.0
    p = np.zeros(3)
    p[axis] = sign * along
    p[across] = _SIGN[half] * half_across * w
    p[1] = y
    return p


def half_along(v, web: str) -> float:
    """How far a web runs from the bay's centre along its courses: half its bay (m)."""
    return (v.span_x_m if _WEB_AXIS[web][0] == 0 else v.span_z_m) / 2.0


def hexahedron(corners: dict) -> tuple[np.ndarray, np.ndarray]:
    """The nodes (8, 3) and connectivity (1, 8) of the hexahedron of ``corners[e, s, l]``
    (along, radius, level, each 0 or 1), in the VTK order with a positive Jacobian (the
    ``along`` index reversed where the three directions turn the other way)."""
    order = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1),
             (0, 1, 1))
    X = np.array([corners[k] for k in order])
    d_e = X[[1, 2, 5, 6]].mean(axis=0) - X[[0, 3, 4, 7]].mean(axis=0)
    d_s = X[[2, 3, 6, 7]].mean(axis=0) - X[[0, 1, 4, 5]].mean(axis=0)
    d_l = X[4:].mean(axis=0) - X[:4].mean(axis=0)
    if np.dot(np.cross(d_e, d_s), d_l) < 0.0:
        X = np.array([corners[(1 - e, s, lv)] for e, s, lv in order])
    return X, np.arange(8, dtype=np.int64)[None, :]


def merged(meshes: list[tuple[np.ndarray, np.ndarray]], tol: float
           ) -> tuple[np.ndarray, np.ndarray]:
    """One mesh of several, their nodes within ``tol`` (m) of each other made one."""
    X: list[np.ndarray] = []
    conn = []
    for Xm, cm in meshes:
        index = []
        for p in Xm:
            near = [i for i, q in enumerate(X) if np.linalg.norm(p - q) <= tol]
            if near:
                index.append(near[0])
            else:
                index.append(len(X))
                X.append(p)
        conn.extend(np.asarray(index)[cm])
    return np.array(X), np.array(conn, dtype=np.int64)


def stone_cuts(v, start: float, low: float, end: float, staggered: bool) -> list[float]:
    """The positions (m along the course) of the planes that cut a course from its groin to
    its end ``end`` into stones about ``stone_length`` long: from ``start`` (the middle of
    the groin face), a half stone later where ``staggered``; none within a quarter stone of
    ``low`` (the groin's farthest corner) or of the end."""
    length = end - start
    n = max(1, round(length / v.stone_length_m))
    step = length / n
    cuts = [start + (m - 0.5 if staggered else m) * step
            for m in range(1, n + (1 if staggered else 0))]
    return [p for p in cuts if low + 0.25 * step < p < end - 0.25 * step]


def course_stones(v, sec: ArchSection, web: str, half: str, j: int
                  ) -> list[tuple[np.ndarray, np.ndarray]]:
    """The stones (nodes, hexahedron) of course ``j`` (from 1) of a web's half, from the
    groin to the web's end; with ``diagonal_ribs`` the first, at the groin, deepened below
    the intrados (the web's half of a diagonal rib's voussoir)."""
    wy = {(s, lv): sec.level(j - 1 + lv, s) for s in (0, 1) for lv in (0, 1)}
    end = half_along(v, web)
    groin = {k: end * w for k, (w, _) in wy.items()}
    start = float(np.mean(list(groin.values())))
    staggered = v.stagger and (j - v.springer_courses) % 2 == 0
    cuts = stone_cuts(v, start, max(groin.values()), end, staggered)
    ends = [None, *cuts, end]  # None: the groin
    stones = []
    for a, b in pairwise(ends):
        deep = v.diagonal_ribs and a is None
        corners = {}
        for s, lv in wy:
            w, y = sec.level(j - 1 + lv, s, deep)
            for e, at in ((0, a), (1, b)):
                along = end * w if at is None else at
                corners[e, s, lv] = web_point(v, web, half, w, y, along)
        stones.append(hexahedron(corners))
    return stones


def springer_mesh(v, sec: ArchSection, corner: str) -> tuple[np.ndarray, np.ndarray]:
    """The springer of a corner: under the bed of the first free course of its two webs (the
    level ``springer_courses``; deepened like the ribs' with ``diagonal_ribs``), down to the
    springing plane, one hexahedron per web (m)."""
    ns, ew = corner.split("-")
    k = v.springer_courses
    meshes = []
    for web, half in ((ew, ns), (ns, ew)):
        end = half_along(v, web)
        corners = {}
        for s in (0, 1):
            w, y = sec.level(k, s, v.diagonal_ribs)
            for e, along in ((0, end * w), (1, end)):
                top = web_point(v, web, half, w, y, along)
                corners[e, s, 1] = top
                corners[e, s, 0] = np.array([top[0], 0.0, top[2]])
        meshes.append(hexahedron(corners))
    return merged(meshes, 1e-9 * max(v.span_x_m, v.span_z_m))


def rib_voussoir(v, sec: ArchSection, end: str, half: str, j: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Voussoir ``j`` (from 1 at the springing) of the transverse rib at the ``end`` (east or
    west) of the bay, in its ``half``: its extrados the webs', ``rib_depth`` deep, from the
    webs' end to ``rib_width`` beyond (m)."""
    out = sec.radii[1]
    rho = (out - v.rib_depth_m, out)
    x0 = v.span_x_m / 2.0
    corners = {}
    for s in (0, 1):
        for lv in (0, 1):
            w, y = sec.point(j - 1 + lv, rho[s])
            for e, along in ((0, x0), (1, x0 + v.rib_width_m)):
                corners[e, s, lv] = web_point(v, end, half, w, y, along)
    return hexahedron(corners)


def geometry_problems(case) -> list[tuple[str, str]]:
    """What of a valid cross vault cannot be built: a springer too low for its webs' stones
    to clear the bay's corner, a rib deeper than its arch, a pier narrower than its
    springer's feet."""
    v = case.cross_vault
    sec = ArchSection(v)
    problems = []
    w_out, _ = sec.point(v.springer_courses, sec.radii[1])
    if not w_out < 1.0:
        need = next((k for k in range(v.springer_courses, v.courses)
                     if sec.point(k, sec.radii[1])[0] < 1.0), None)
        problems.append(("cross_vault.springer_courses", (
            f"got {v.springer_courses}; the extrados of the first free course must lie inside "
            "the bay's corner, so that its stones have a length: "
            + (f"at least {need}" if need else "raise courses or thin the webs"))))
    if v.transverse_ribs and not sec.R + v.thickness_m / 2.0 - v.rib_depth_m > sec.c:
        problems.append(("cross_vault.rib_depth_m", (
            f"got {v.rib_depth_m:.6g} m; the rib's intrados must stay above the arch's centre: "
            f"below {sec.R + v.thickness_m / 2.0 - sec.c:.6g} m")))
    deep = sec.R - v.thickness_m / 2.0 - v.diagonal_rib_depth_m
    if v.diagonal_ribs and not deep > sec.c:
        problems.append(("cross_vault.diagonal_rib_depth_m", (
            f"got {v.diagonal_rib_depth_m:.6g} m; the ribs' intrados must stay above the "
            f"arch's centre: below {sec.R - v.thickness_m / 2.0 - sec.c:.6g} m")))
    if not problems and v.piers and v.pier_width_m is not None:
        need = _pier_width_needed(v, sec)
        if v.pier_width_m < need:
            problems.append(("cross_vault.pier_width_m", (
                f"got {v.pier_width_m:.6g} m; a pier must hold its springer's feet: at least "
                f"{need:.4g} m")))
    if not problems:
        problems += named_block_problems(case.loading, block_names(v), (
            f"the blocks are named like 'east web north course {v.springer_courses + 1} "
            "stone 2', 'springer north-east', 'east rib north voussoir 1', 'diagonal rib "
            "north-east voussoir 1', 'boss'"))
    return problems


def block_names(v) -> list[str]:
    """The names of the blocks of the vault (its supports aside)."""
    sec = ArchSection(v)
    names = [name for name, _, _ in stone_meshes(v, sec)]
    names += [f"springer {c}" for c in CORNERS]
    if v.transverse_ribs:
        names += [name for name, _ in rib_meshes(v, sec)]
    if v.piers:
        names += [f"pier {c} drum {k + 1}" for c in CORNERS for k in range(v.pier_drums)]
    return names


def corner_of(web: str, half: str) -> str:
    """The corner (``north-east``, ...) where a web's half meets its groin."""
    return f"{half}-{web}" if web in ("east", "west") else f"{web}-{half}"


def stone_meshes(v, sec: ArchSection):
    """``(name, (nodes, hexahedra), place)`` of every web stone, web by web, half by half,
    course by course from the springer, stone by stone from the groin; with
    ``diagonal_ribs`` the groin stones of a course at a corner come after them as one
    ``diagonal rib <corner> voussoir i`` (i from 1 above the springer), and the top course's
    eight as the ``boss``."""
    k = v.springer_courses
    ribs: dict[tuple[str, int], list] = {}
    for web in WEBS:
        for half in _HALVES[web]:
            for j in range(k + 1, v.courses + 1):
                for m, mesh in enumerate(course_stones(v, sec, web, half, j)):
                    if v.diagonal_ribs and m == 0:
                        corner = "boss" if j == v.courses else corner_of(web, half)
                        ribs.setdefault((corner, j), []).append(mesh)
                        continue
                    yield (f"{web} web {half} course {j} stone {m + 1}", mesh,
                           {"role": "web", "web": web, "half": half, "course": j})
    tol = 1e-9 * max(v.span_x_m, v.span_z_m)
    for (corner, j), meshes in sorted(ribs.items(), key=lambda item: (item[0][0] == "boss",
                                                                        item[0])):
        name = "boss" if corner == "boss" else f"diagonal rib {corner} voussoir {j - k}"
        yield name, merged(meshes, tol), {"role": "rib", "corner": corner, "course": j}


def rib_meshes(v, sec: ArchSection):
    """``(name, (nodes, hexahedron))`` of every rib voussoir."""
    for end in ("east", "west"):
        for half in ("north", "south"):
            for j in range(1, v.courses + 1):
                yield f"{end} rib {half} voussoir {j}", rib_voussoir(v, sec, end, half, j)


def describe(case) -> str:
    """One line on a cross vault case (``masonry validate``)."""
    v = case.cross_vault
    return (f"{case.name}: {v.shape} cross vault over {v.span_x_m:.4g} x {v.span_z_m:.4g} m, "
            f"rise {v.rise_m:.4g} m, webs {v.thickness_m:.4g} m thick in {v.courses} courses "
            f"({v.springer_courses} in the springers) of stones {v.stone_length_m:.4g} m"
            + (" staggered" if v.stagger else "")
            + (f", transverse ribs {v.rib_width_m:.4g} x {v.rib_depth_m:.4g} m"
               if v.transverse_ribs else "")
            + (f", diagonal ribs {v.diagonal_rib_depth_m:.4g} m below the webs"
               if v.diagonal_ribs else "")
            + (f", on piers {v.pier_height_m:.4g} m high in {v.pier_drums} drums"
               if v.piers else "")
            + f", blocks {case.blocks.material}, joints {case.joint.law}; "
            + until_collapse(case))


def build_cross_vault(case) -> Scene:
    """The scene of a cross vault case (module docstring)."""
    v, blk = case.cross_vault, case.blocks
    sec = ArchSection(v)
    bodies: list = []
    info: list[dict] = []

    def add(name: str, mesh, place: dict) -> None:
        bodies.append(structure_block(blk, *mesh, name))
        info.append({"name": name, **place})

    for name, mesh, place in stone_meshes(v, sec):
        add(name, mesh, place)
    for corner in CORNERS:
        add(f"springer {corner}", springer_mesh(v, sec, corner),
            {"role": "springer", "corner": corner})
    if v.transverse_ribs:
        for name, mesh in rib_meshes(v, sec):
            add(name, mesh, {"role": "rib", "end": name.split()[0]})
    plans = feet_plans(v, sec)
    if v.piers and v.pier_width_m is not None:
        plans = {corner: _pier_plan(v, corner) for corner in CORNERS}
    base_y = 0.0
    if v.piers:
        base_y = -v.pier_height_m
        levels = np.linspace(base_y, 0.0, v.pier_drums + 1)
        for corner in CORNERS:
            for k, (y0, y1) in enumerate(pairwise(levels)):
                add(f"pier {corner} drum {k + 1}", _box(*plans[corner], y0, y1),
                    {"role": "pier", "corner": corner, "drum": k + 1})
    structure = list(range(len(bodies)))

    # --- supports: a fixed box under each corner's feet (or pier), moved by a settlement
    settle = case.loading.settlement
    moving = () if settle is None else SIDES.get(settle.support, (settle.support,))
    supports = {}
    for corner in CORNERS:
        lo, hi = plans[corner]
        imposed = support_motion(settle, corner in moving)
        X, conn = _box(lo, hi, base_y - v.support_height_m, base_y)
        supports[corner] = len(bodies)
        bodies.append(RigidBody(center=X.mean(axis=0), mass=1.0, inertia=np.ones(3),
                                imposed_velocity=imposed, name=f"support {corner}", X=X,
                                conn=conn, support=True))
    role = [place["role"] for place in info] + ["support"] * len(CORNERS)

    def classify(joint, antagonist):
        a, b = joint.candidate.body, antagonist.body
        roles = {role[a], role[b]}
        if "support" in roles:
            name = "base"
        elif "pier" in roles:
            name = "pier"
        elif roles == {"rib"}:
            name = "rib"
        elif "rib" in roles:
            name = "rib side"
        elif "springer" in roles:
            name = "springer"
        else:
            pa, pb = info[a], info[b]
            if pa["web"] != pb["web"]:
                name = "groin"
            elif pa["half"] != pb["half"]:
                name = "crown"
            else:
                name = "head" if pa["course"] == pb["course"] else "bed"
        return GROUPS.index(name), laws.KIND_JOINT, 0

    detection = find_joints(bodies, max_gap=0.0)
    points = joint_points(bodies, detection.joints, classify,
                          n_gauss=v.contact_points_per_face, rule=case.contact_point_rule)
    params = np.atleast_2d(laws.params_from_case(case.joint))

    def top_middle(k: int) -> np.ndarray:
        """The middle of body ``k``'s highest face: the mean of its highest nodes, m."""
        X = bodies[k].X
        return X[X[:, 1] >= X[:, 1].max() - 1e-9 * v.rise_m].mean(axis=0)

    loads, stages, factors = limit_loads(case, bodies, structure, top_middle)
    stages.sort(key=lambda st: st.start_s)
    solver, rule = limit_settings(case, factors)
    col = case.collapse
    driven = next(i for i, place in enumerate(info)
                  if place["role"] == "web" and place["course"] == v.courses)
    meta = {"span_x_m": v.span_x_m, "span_z_m": v.span_z_m, "shape": v.shape,
            "radius_m": sec.R, "rise_m": v.rise_m, "thickness_m": v.thickness_m,
            "courses": v.courses, "springer_courses": v.springer_courses,
            "transverse_ribs": bool(v.transverse_ribs),
            "diagonal_ribs": bool(v.diagonal_ribs), "piers": bool(v.piers),
            "blocks": len(structure),
            "supports": {c: bodies[i].name for c, i in supports.items()}}
    return Scene(
        name=case.name, builder="cross_vault", bodies=bodies, points=points, groups=GROUPS,
        params=params, loads=loads, solver=solver, structure=structure, body_info=info,
        driven=driven, reactions={"top": tuple(supports.values()),
                                  "bottom": supports["north-east"]},
        stages=stages, push_stage="gravity", target_m=None, expected_end_s=col.end_time_s,
        time_limit_s=col.end_time_s, history={"kind": "monotonic", "cycles": []},
        collapse=rule,
        meta={"contact_point_rule": case.contact_point_rule, "limit_state": True,
              "reaction_names": ["all supports", "support north-east"],
              "cross_vault": meta},
    )


def _box(lo: np.ndarray, hi: np.ndarray, y0: float, y1: float) -> tuple[np.ndarray, np.ndarray]:
    """The hexahedron of the plan ``lo`` .. ``hi`` (their x and z, m) between heights ``y0`` and
    ``y1`` (m)."""
    return hexahedron({(e, s, lv): np.array([(lo, hi)[e][0], (y0, y1)[lv], (lo, hi)[s][2]])
                       for e in (0, 1) for s in (0, 1) for lv in (0, 1)})


def feet_plans(v, sec: ArchSection) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per corner, the plan ``(lo, hi)`` (m; their y is 0) of the springer's and the
    transverse ribs' feet on the springing plane, widened by a tenth of the webs' thickness:
    the support's plan."""
    ribs = list(rib_meshes(v, sec)) if v.transverse_ribs else []
    plans = {}
    for corner in CORNERS:
        meshes = [springer_mesh(v, sec, corner)[0]] + [X for _, (X, _) in ribs
                                                       if _near_corner(X, corner)]
        feet = np.concatenate([X[np.abs(X[:, 1]) <= 1e-9 * v.rise_m] for X in meshes])
        margin = 0.1 * v.thickness_m
        plans[corner] = (feet.min(axis=0) - margin, feet.max(axis=0) + margin)
    return plans


def _corner_centre(v, corner: str) -> np.ndarray:
    """The corner of the bay (m; y = 0): where its supports' centrelines meet."""
    ns, ew = corner.split("-")
    return np.array([_SIGN[ew] * v.span_x_m / 2.0, 0.0, _SIGN[ns] * v.span_z_m / 2.0])


def _pier_plan(v, corner: str) -> tuple[np.ndarray, np.ndarray]:
    """The plan of ``corner``'s pier: ``pier_width`` square, centred on the corner of the
    bay."""
    c = _corner_centre(v, corner)
    return c - v.pier_width_m / 2.0, c + v.pier_width_m / 2.0


def _pier_width_needed(v, sec: ArchSection) -> float:
    """The least side (m) of a square pier centred on its corner that holds the feet."""
    return max(2.0 * float(np.abs(np.stack([lo, hi]) - _corner_centre(v, corner))[:, [0, 2]].max())
               for corner, (lo, hi) in feet_plans(v, sec).items())


def _near_corner(X: np.ndarray, corner: str) -> bool:
    """Whether nodes ``X`` lie in the quarter of the bay of ``corner`` (by their mean)."""
    ns, ew = corner.split("-")
    m = X.mean(axis=0)
    return m[0] * _SIGN[ew] > 0.0 and m[2] * _SIGN[ns] > 0.0


BUILDER = Builder("cross_vault", build_cross_vault, describe, geometry_problems)
