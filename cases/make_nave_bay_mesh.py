"""Write the mesh of cases/nave_bay.yaml: a Gothic nave bay of stones (Gmsh .msh).

    python cases/make_nave_bay_mesh.py               # writes cases/nave_bay.msh
    python cases/make_nave_bay_mesh.py --scale 0.5 -o small.msh
    python cases/make_nave_bay_mesh.py --bays 20 -o nave.msh --case nave.yaml   # a nave

y is up, the nave's axis along x, z across the nave; the bay is centred on the origin, its
floor at y = 0. Lengths in m. Every block is one physical volume of 8-node hexahedra (several
for the blocks whose shape needs them, nodes shared inside the block), every face flat; blocks
meet face to face or in part (the case's ``contact_point_rule: overlap`` makes a joint on the
common area). The parameters are the module's constants below; ``--scale`` scales every
length and divides the block counts accordingly (a small bay for the tests).

The bay (``BAY_M`` between the piers' centres along x, ``NAVE_M`` between the inner faces of
the clerestory walls), side by side (``north``: +z, ``south``: -z; ``east``: +x, ``west``: -x):

* ``pier <side>-<end> drum k``: four square piers ``PIER_M`` wide, centred on the walls'
  middle planes at x = +-BAY/2, drums ``DRUM_M`` high from the floor to the arcade's springing
  ``ARCADE_SPRING_M``; ``upper pier <side>-<end> k``: the pier above it, from the arcade arch's
  springing bed outwards, up to the vault's springing ``VAULT_SPRING_M``.
* ``foundation ...``: a fixed block under every pier, buttress and flyer pier (the supports).
* ``<side> arcade voussoir k``: a pointed arch between the two piers of a side, in the wall's
  thickness, springing on the piers' tops flush with their inner faces (``ARCADE_*``).
* ``<side> wall course m block k``: the spandrels and the clerestory wall, between the upper
  piers, from the arcade's extrados up to ``WALL_TOP_M``, in courses of ``WALL_COURSE_M`` with
  staggered head joints. Over the arch a course's block is a run of columns, each standing on
  the chord of one voussoir's extrados (one hexahedron per column).
* ``buttress <side>-<end> course k``: an attached buttress against each pier's outer face, from
  the floor to ``VAULT_SPRING_M``.
* The flying buttresses (``FLYER_*``): ``upper buttress <side>-<end> course k`` on the upper pier
  and the attached buttress, from ``VAULT_SPRING_M`` to the walls' top, against the wall's end;
  ``flyer <side>-<end> voussoir k`` (k from 1 at the head), a quarter circle whose head is a
  vertical joint against the upper buttress's outer face, its top at ``FLYER_HEAD_M``, and
  whose foot is a horizontal bed on ``flyer pier <side>-<end> course k``, a pier standing
  ``FLYER_RADIUS_M`` out from the attached buttress; ``pinnacle <side>-<end> course k`` on the
  flyer pier beyond the flyer's foot.
* The vault, a quadripartite rib vault over the bay: the webs are a pointed groin vault of
  stones in courses (two barrels meeting on the diagonal planes, the geometry of
  ``masonry_nscd/scenes/cross_vault.py``), ``<web> web <half> course j stone k`` (k from 2:
  the course's first stone, at the groin, is the rib's); the diagonal ribs are the webs' groin
  stones deepened by ``DIAGONAL_RIB_DEPTH_M`` below the intrados, the two groin stones of a
  course on either side of a groin one block, ``diagonal rib <corner> voussoir i`` (a rib
  bonded into its webs; separate groin stones are wedges that drop); ``boss`` the keystone
  where the ribs cross: the top course's eight groin stones as one block;
  ``<end> rib <half> voussoir j`` the transverse arches against the east and west ends of the
  webs; ``springer <corner>`` the solid lowest courses at a corner, on the upper pier. The
  north and south webs' ends bear on the clerestory walls' inner faces up to the walls' top;
  above it their ends are free (the windows' wall ribs are left out).

Simplifications: square piers and buttresses, one flyer per pier, no roof, the webs as a
groin vault whose groin stones are the diagonal ribs, the bay alone (the next bays' thrusts
along x are not there).

``--bays N`` writes a nave of N such bays along x instead (:func:`nave_blocks`: the lines of
piers shared, one transverse rib on each line), and ``--case FILE`` a case for it: the
shipped bay's case with this mesh and every foundation fixed.
"""

from __future__ import annotations

import argparse
import math
from itertools import pairwise
from pathlib import Path

import numpy as np

# --- the bay (m) -----------------------------------------------------------------------------
BAY_M = 7.0  # between the piers' centres along the nave
NAVE_M = 12.0  # between the clerestory walls' inner faces
WALL_THICKNESS_M = 0.8
PIER_M = 2.0  # the piers' square side
DRUM_M = 0.3  # height of a pier's drum
ARCADE_SPRING_M = 6.0  # the arcade arches spring from the piers' tops
ARCADE_THICKNESS_M = 0.5  # the arcade arch's ring
ARCADE_RADIUS_FACTOR = 0.8  # its radius / its span (0.5: semicircular)
ARCADE_VOUSSOIRS = 12  # per half arch
VAULT_SPRING_M = 11.0  # the vault springs from the upper piers' tops
WALL_TOP_M = 14.0
WALL_COURSE_M = 0.3
WALL_BLOCK_M = 0.3  # length of a wall block
BUTTRESS_WIDTH_M = 1.2  # along x
BUTTRESS_DEPTH_M = 1.6  # along z, out from the pier
BUTTRESS_COURSE_M = 0.3
FOUNDATION_DEPTH_M = 0.5
# --- the flying buttresses ------------------------------------------------------------------
FLYER_RADIUS_M = 3.5  # of the flyer's intrados, a quarter circle
FLYER_DEPTH_M = 0.6  # of its ring
FLYER_HEAD_M = 13.7  # the top of its head, against the upper buttress
FLYER_VOUSSOIRS = 10
FLYER_PIER_DEPTH_M = 2.0  # along z, out from the flyer's springing
PINNACLE_M = 1.8  # on the flyer pier, beyond the flyer's foot
# --- the vault -------------------------------------------------------------------------------
VAULT_RADIUS_M = 7.5  # of the webs' centreline, across the nave (> NAVE_M / 2: pointed)
VAULT_THICKNESS_M = 0.3
VAULT_COURSES = 26  # from each springing to the crown
SPRINGER_COURSES = 7
STONE_M = 0.2  # length of a web stone
DIAGONAL_RIB_DEPTH_M = 0.25
TRANSVERSE_RIB_WIDTH_M = 0.5
TRANSVERSE_RIB_DEPTH_M = 0.6

_SIGN = {"north": 1.0, "south": -1.0, "east": 1.0, "west": -1.0}
_WEB_AXIS = {"east": (0, 1.0), "west": (0, -1.0), "north": (2, 1.0), "south": (2, -1.0)}
_HALVES = {"east": ("north", "south"), "west": ("north", "south"),
           "north": ("east", "west"), "south": ("east", "west")}
CORNERS = ("north-east", "north-west", "south-east", "south-west")


class Bay:
    """The parameters of a bay: the module's constants, every length times ``scale``, the
    blocks' lengths (drums, courses, stones) times ``sqrt(scale)`` where it is below 1 (fewer
    blocks), the vault's courses as they are."""

    def __init__(self, scale: float = 1.0):
        g = globals()
        for name, value in g.items():
            if name.endswith("_M") and isinstance(value, float):
                setattr(self, name.lower(), value * scale)
        self.arcade_radius_factor = ARCADE_RADIUS_FACTOR
        self.arcade_voussoirs = max(2, round(ARCADE_VOUSSOIRS * min(1.0, scale ** 0.5)))
        self.flyer_voussoirs = max(2, round(FLYER_VOUSSOIRS * min(1.0, scale ** 0.5)))
        self.vault_courses = VAULT_COURSES  # the springers' tops, and so their feet on the
        # upper piers, stay where they are in the full bay
        self.springer_courses = SPRINGER_COURSES
        # lengths of blocks scale less than the bay, so that a small bay has fewer blocks
        grow = 1.0 / math.sqrt(scale) if scale < 1.0 else 1.0
        for name in ("drum_m", "wall_course_m", "wall_block_m", "buttress_course_m",
                     "stone_m"):
            setattr(self, name, getattr(self, name) * grow)

    # derived positions
    @property
    def wall_z(self) -> tuple[float, float]:
        """The north wall's inner and outer faces (z)."""
        return self.nave_m / 2.0, self.nave_m / 2.0 + self.wall_thickness_m

    @property
    def pier_z(self) -> tuple[float, float]:
        """The north piers' faces (z), centred on the wall."""
        mid = self.nave_m / 2.0 + self.wall_thickness_m / 2.0
        return mid - self.pier_m / 2.0, mid + self.pier_m / 2.0

    @property
    def arcade_inner_x(self) -> float:
        """The east pier's inner face (x): the arcade's intrados springs there."""
        return self.bay_m / 2.0 - self.pier_m / 2.0

    @property
    def upper_pier_x(self) -> float:
        """The east upper pier's inner face (x): the arcade's springing bed ends there."""
        return self.arcade_inner_x + self.arcade_thickness_m


# --- hexahedra and blocks --------------------------------------------------------------------

def hexahedron(X: np.ndarray) -> np.ndarray:
    """The 8 corners ``X`` of a hexahedron (bottom face, then top face) in the VTK order with a
    positive Jacobian: the faces' order reversed where the corners turn the other way."""
    X = np.asarray(X, dtype=float)
    d1 = X[[1, 2, 5, 6]].mean(axis=0) - X[[0, 3, 4, 7]].mean(axis=0)
    d2 = X[[2, 3, 6, 7]].mean(axis=0) - X[[0, 1, 4, 5]].mean(axis=0)
    d3 = X[4:].mean(axis=0) - X[:4].mean(axis=0)
    if np.dot(np.cross(d1, d2), d3) < 0.0:
        X = X[[1, 0, 3, 2, 5, 4, 7, 6]]
    return X


def box(lo, hi) -> np.ndarray:
    """The hexahedron of the box ``lo`` .. ``hi`` (3 each)."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return hexahedron([[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1],
                       [x0, y1, z0], [x1, y1, z0], [x1, y1, z1], [x0, y1, z1]])


def prism_xy(quad, z0: float, z1: float) -> np.ndarray:
    """The hexahedron of the quadrilateral ``quad`` (4, 2) in the x-y plane between z0 and z1."""
    q = np.asarray(quad, dtype=float)
    return hexahedron([[*q[i], z0] for i in range(4)] + [[*q[i], z1] for i in range(4)])


def mirror(hexes: list[np.ndarray], axis: int) -> list[np.ndarray]:
    """The hexahedra mirrored in the plane ``axis = 0``."""
    out = []
    for X in hexes:
        Y = X.copy()
        Y[:, axis] *= -1.0
        out.append(hexahedron(Y))
    return out


# --- the vault (the geometry of scenes/cross_vault.py, standalone) ---------------------------

class Vault:
    """The webs' arch across z: its level ``j`` at radius ``rho`` is ``(w, y)``, ``w`` the
    horizontal distance from the bay's axis in half spans, ``y`` above the springing; the
    courses cut the angle from 0 to the crown into equal parts at each radius (the crown joint
    is the vertical plane of the axis)."""

    def __init__(self, bay: Bay, span_m: float | None = None):
        self.bay = bay
        self.a, self.b = bay.bay_m if span_m is None else span_m, bay.nave_m
        self.R = bay.vault_radius_m
        self.c = self.R - self.b / 2.0
        self.t = bay.vault_thickness_m
        self.n = bay.vault_courses
        self.k = bay.springer_courses

    def point(self, j: int, rho: float) -> tuple[float, float]:
        top = math.acos(min(1.0, self.c / rho))
        alpha = top * j / self.n
        r = 0.0 if j == self.n else rho * math.cos(alpha) - self.c
        return r / (self.b / 2.0), rho * math.sin(alpha)

    @property
    def radii(self) -> tuple[float, float]:
        return self.R - self.t / 2.0, self.R + self.t / 2.0

    def deep_point(self, j: int) -> tuple[float, float]:
        """``(w, y)`` of level ``j`` ``DIAGONAL_RIB_DEPTH_M`` below the intrados, on the line
        of the bed from the extrados through the intrados (the bed stays one plane)."""
        (wi, yi), (we, ye) = (self.point(j, r) for r in self.radii)
        half = self.b / 2.0
        d = np.array([(wi - we) * half, yi - ye])
        r, y = np.array([wi * half, yi]) + d * self.bay.diagonal_rib_depth_m / np.hypot(*d)
        return r / half, y

    def level(self, j: int, s: int, deep: bool) -> tuple[float, float]:
        """``(w, y)`` of level ``j`` at the intrados (``s = 0``; deepened if ``deep``) or the
        extrados (1)."""
        return self.deep_point(j) if deep and s == 0 else self.point(j, self.radii[s])

    def half_along(self, web: str) -> float:
        return (self.a if _WEB_AXIS[web][0] == 0 else self.b) / 2.0

    def web_point(self, web: str, half: str, w: float, y: float, along: float) -> np.ndarray:
        axis, sign = _WEB_AXIS[web]
        across = 2 - axis
        p = np.zeros(3)
        p[axis] = sign * along
        p[across] = _SIGN[half] * (self.b if across == 2 else self.a) / 2.0 * w
        p[1] = self.bay.vault_spring_m + y
        return p

    def block(self, corners: dict) -> np.ndarray:
        """The hexahedron of ``corners[e, s, l]`` (along, radius, level)."""
        order = ((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1),
                 (0, 1, 1))
        return hexahedron([corners[key] for key in order])

    def stone_cuts(self, start: float, low: float, end: float, staggered: bool) -> list[float]:
        length = end - start
        n = max(1, round(length / self.bay.stone_m))
        step = length / n
        cuts = [start + (m - 0.5 if staggered else m) * step
                for m in range(1, n + (1 if staggered else 0))]
        return [p for p in cuts if low + 0.25 * step < p < end - 0.25 * step]

    def course(self, web: str, half: str, j: int) -> list[np.ndarray]:
        """The stones of course ``j`` of a web's half from the groin; the first, the groin
        stone, deepened below the intrados: a voussoir of the diagonal rib."""
        rho = self.radii
        end = self.half_along(web)
        wy = {(s, lv): self.point(j - 1 + lv, rho[s]) for s in (0, 1) for lv in (0, 1)}
        groin = {key: end * w for key, (w, _) in wy.items()}
        start = float(np.mean(list(groin.values())))
        staggered = (j - self.k) % 2 == 0
        cuts = self.stone_cuts(start, max(groin.values()), end, staggered)
        stones = []
        for m, (lo, hi) in enumerate(pairwise([None, *cuts, end])):
            corners = {}
            for s in (0, 1):
                for lv in (0, 1):
                    w, y = self.level(j - 1 + lv, s, m == 0)
                    for e, at in ((0, lo), (1, hi)):
                        along = end * w if at is None else at
                        corners[e, s, lv] = self.web_point(web, half, w, y, along)
            stones.append(self.block(corners))
        return stones

    def springer(self, corner: str) -> list[np.ndarray]:
        """Under the bed of the first free course of its two webs, down to the springing
        plane: one hexahedron per web, the groin's deepened like the ribs'."""
        ns, ew = corner.split("-")
        out = []
        for web, half in ((ew, ns), (ns, ew)):
            end = self.half_along(web)
            corners = {}
            for s in (0, 1):
                w, y = self.level(self.k, s, True)
                for e, along in ((0, end * w), (1, end)):
                    top = self.web_point(web, half, w, y, along)
                    corners[e, s, 1] = top
                    corners[e, s, 0] = np.array([top[0], self.bay.vault_spring_m, top[2]])
            out.append(self.block(corners))
        return out

    def rib_voussoir(self, end: str, half: str, j: int) -> np.ndarray:
        out = self.radii[1]
        rho = (out - self.bay.transverse_rib_depth_m, out)
        x0 = self.a / 2.0
        corners = {}
        for s in (0, 1):
            for lv in (0, 1):
                w, y = self.point(j - 1 + lv, rho[s])
                for e, along in ((0, x0), (1, x0 + self.bay.transverse_rib_width_m)):
                    corners[e, s, lv] = self.web_point(end, half, w, y, along)
        return self.block(corners)


def vault_blocks(bay: Bay, span_m: float | None = None) -> list[tuple[str, list[np.ndarray]]]:
    """The vault's blocks; ``span_m``: the webs' length along x (default the bay's, the
    transverse ribs beyond the webs' ends; in a nave the bay less a rib's width, each rib
    straddling the line between two bays)."""
    v = Vault(bay, span_m)
    out = []
    boss = []
    ribs: dict[tuple[str, int], list[np.ndarray]] = {}
    for web in ("east", "west", "north", "south"):
        for half in _HALVES[web]:
            corner = f"{half}-{web}" if web in ("east", "west") else f"{web}-{half}"
            for j in range(v.k + 1, v.n + 1):
                for m, X in enumerate(v.course(web, half, j)):
                    if m == 0 and j == v.n:
                        boss.append(X)
                    elif m == 0:
                        ribs.setdefault((corner, j), []).append(X)
                    else:
                        out.append((f"{web} web {half} course {j} stone {m + 1}", [X]))
    for (corner, j), hexes in sorted(ribs.items()):
        out.append((f"diagonal rib {corner} voussoir {j - v.k}", hexes))
    out.append(("boss", boss))
    for corner in CORNERS:
        out.append((f"springer {corner}", v.springer(corner)))
    for end in ("east", "west"):
        for half in ("north", "south"):
            for j in range(1, v.n + 1):
                out.append((f"{end} rib {half} voussoir {j}", [v.rib_voussoir(end, half, j)]))
    return out


# --- arcade, spandrels and clerestory wall ---------------------------------------------------

def arcade_points(bay: Bay) -> tuple[np.ndarray, np.ndarray]:
    """The east half of a side's arcade arch in the x-y plane: its intrados and extrados
    points (n + 1, 2) from the springing to the crown (x = 0)."""
    t = bay.arcade_thickness_m
    span = 2.0 * bay.arcade_inner_x + t  # between the centres of the springing beds
    R = bay.arcade_radius_factor * span
    c = R - span / 2.0  # the east half's centre lies at x = -c
    n = bay.arcade_voussoirs
    out = []
    for rho in (R - t / 2.0, R + t / 2.0):
        top = math.acos(min(1.0, c / rho))
        pts = []
        for i in range(n + 1):
            a = top * i / n
            x = 0.0 if i == n else rho * math.cos(a) - c
            pts.append((x, bay.arcade_spring_m + rho * math.sin(a)))
        out.append(np.array(pts))
    return out[0], out[1]


def wall_side(bay: Bay) -> list[tuple[str, list[np.ndarray]]]:
    """The arcade and the wall of the north side (z of the wall): the arch's voussoirs, then
    the courses of the spandrels and the clerestory (blocks of columns on the extrados)."""
    z0, z1 = bay.wall_z
    intra, extra = arcade_points(bay)
    n = len(intra) - 1
    blocks = []
    for half, sign in (("east", 1.0), ("west", -1.0)):
        for i in range(n):
            q = np.array([intra[i], intra[i + 1], extra[i + 1], extra[i]])
            q[:, 0] *= sign
            blocks.append((f"arcade {half} voussoir {i + 1}", [prism_xy(q, z0, z1)]))
    # columns over the extrados chords, x increasing from the west springing to the east one
    xe = extra[:, 0]
    chords = [(extra[i + 1], extra[i]) for i in range(n)][::-1]  # east half, crown first
    cols = [((-b[0], b[1]), (-a[0], a[1])) for a, b in chords[::-1]] + chords
    # levels of the courses
    levels = list(np.arange(bay.arcade_spring_m, bay.wall_top_m - 0.5 * bay.wall_course_m,
                            bay.wall_course_m)) + [bay.wall_top_m]
    assert abs(xe[0] - bay.upper_pier_x) < 1e-9  # the wall ends on the upper piers' faces
    # each column's first course level: the first level a course height above its chord's top
    first = []
    for (p, q) in cols:
        top = max(p[1], q[1]) + 0.5 * bay.wall_course_m
        first.append(next(m for m, y in enumerate(levels) if y >= top))
    # bottom pieces: runs of neighbouring columns at least half a block long (a steep chord
    # near the springing makes a narrow column), each from its chord up to the run's highest
    # first level
    for side_cols in (range(n), range(n, 2 * n)):
        run: list[int] = []
        for i in side_cols:
            run.append(i)
            if cols[i][1][0] - cols[run[0]][0][0] >= 0.5 * bay.wall_block_m or \
                    i == side_cols[-1]:
                top = max(first[r] for r in run)
                for r in run:
                    first[r] = top
                blocks.append(_bottom_block(cols, run, levels[top], z0, z1, len(blocks)))
                run = []
    # courses: in course m, the columns whose first level is at or below it; cut into blocks
    # about wall_block_m long at column boundaries, staggered every other course
    for m in range(min(first), len(levels) - 1):
        y0, y1 = levels[m], levels[m + 1]
        present = [i for i in range(2 * n) if first[i] <= m]
        for seg in _runs(present):  # a run of neighbouring columns: one, or two at the piers
            edges = [cols[seg[0]][0][0]] + [cols[i][1][0] for i in seg]
            for xa, xb in pairwise(_cuts(edges, bay.wall_block_m, m % 2 == 1)):
                hexes = [box((xl, y0, z0), (xr, y1, z1))
                         for xl, xr in pairwise([e for e in edges if xa - 1e-9 <= e <= xb + 1e-9])]
                blocks.append((f"wall course {m + 1} block {len(blocks)}", hexes))
    return blocks


def _runs(idx: list[int]) -> list[list[int]]:
    out: list[list[int]] = []
    for i in idx:
        if out and out[-1][-1] == i - 1:
            out[-1].append(i)
        else:
            out.append([i])
    return out


def _cuts(edges: list[float], length: float, staggered: bool) -> list[float]:
    """Block boundaries among the column edges ``edges`` (increasing): the ends, and the edges
    nearest to a grid of ``length`` (shifted by half of it where ``staggered``)."""
    lo, hi = edges[0], edges[-1]
    n = max(1, round((hi - lo) / length))
    step = (hi - lo) / n
    targets = [lo + (m - 0.5 if staggered else m) * step
               for m in range(1, n + (1 if staggered else 0))]
    chosen = {lo, hi}
    for t in targets:
        e = min(edges[1:-1], key=lambda x: abs(x - t), default=None)
        if e is not None and abs(e - t) < 0.5 * step:
            chosen.add(e)
    return sorted(chosen)


def _bottom_block(cols, run, y_top, z0, z1, count):
    """One block of the columns ``run`` from their chords up to ``y_top``."""
    hexes = []
    for i in run:
        (xa, ya), (xb, yb) = cols[i]
        hexes.append(prism_xy([(xa, ya), (xb, yb), (xb, y_top), (xa, y_top)], z0, z1))
    return (f"spandrel block {count}", hexes)


# --- the bay -------------------------------------------------------------------------------

PARTS = ("piers", "buttresses", "walls", "vault", "flyers")


def nave_bay_blocks(bay: Bay, parts=PARTS
                    ) -> tuple[list[tuple[str, list[np.ndarray]]], list[str]]:
    """The blocks ``(name, hexahedra)`` of the bay's ``parts`` (of ``PARTS``; the piers'
    foundations with the piers, the buttresses' with the buttresses, the flyer piers' with the
    flyers, which stand on the piers and buttresses), and the names of its fixed supports."""
    blocks: list[tuple[str, list[np.ndarray]]] = []
    supports: list[str] = []
    for side in ("north", "south"):
        s = _SIGN[side]
        # the wall, the arcade and the spandrels (built for the north side, mirrored)
        for name, hexes in wall_side(bay) if "walls" in parts else ():
            if s < 0:
                hexes = mirror(hexes, 2)
            blocks.append((f"{side} {name}", hexes))
        for end in ("east", "west"):
            e = _SIGN[end]
            corner = f"{side}-{end}"

            def place(lo, hi, s=s, e=e):
                """A box given for the north-east corner, placed at this corner."""
                X = box(lo, hi)
                X[:, 0] *= e
                X[:, 2] *= s
                return hexahedron(X)

            if "piers" in parts:
                _pier(blocks, supports, bay, corner, place)
            if "buttresses" in parts:
                _buttress(blocks, supports, bay, corner, place)
            if "flyers" in parts:
                _flyer(blocks, supports, bay, corner, place, e, s)
    if "vault" in parts:
        blocks += vault_blocks(bay)
    return blocks, supports


def nave_blocks(bay: Bay, bays: int, parts=PARTS
                ) -> tuple[list[tuple[str, list[np.ndarray]]], list[str]]:
    """The blocks and the fixed supports of a nave of ``bays`` bays along x, centred on the
    origin (one bay: :func:`nave_bay_blocks`, the shipped bay). Two neighbouring bays share
    the line of piers between them: its piers, attached buttresses, flyers and flyer piers
    are built once, the upper piers and upper buttresses and the flyers' heads from one
    bay's arcade springing bed to the other's (the nave's two ends as in a bay); each bay has
    its arcades, walls and vault, the webs shortened by a transverse rib's width so that one
    rib straddles each line (``bay K ...``; the piers' lines ``... <side> line I ...``, I
    from 0 at the west end)."""
    if bays == 1:
        return nave_bay_blocks(bay, parts)
    h = bay.bay_m / 2.0

    def centre(k: int) -> float:
        return (k - (bays - 1) / 2.0) * bay.bay_m

    blocks: list[tuple[str, list[np.ndarray]]] = []
    supports: list[str] = []
    own = list(nave_bay_blocks(bay, ("walls",) if "walls" in parts else ())[0])
    if "vault" in parts:
        own += vault_blocks(bay, bay.bay_m - bay.transverse_rib_width_m)
    for k in range(bays):
        for name, hexes in own:
            if name.startswith("west rib") and k > 0:
                continue  # the rib on this line is the bay before's east rib
            moved = []
            for X in hexes:
                Y = X.copy()
                Y[:, 0] += centre(k)
                moved.append(Y)
            blocks.append((f"bay {k + 1} {name}", moved))
    for i in range(bays + 1):
        # a line as the east end of the bay before it (the west end: as the first bay's west)
        e = -1.0 if i == 0 else 1.0
        dx = centre(0) if i == 0 else centre(i - 1)
        far = None if i in (0, bays) else 2.0 * h - bay.upper_pier_x
        for side in ("north", "south"):
            s = _SIGN[side]
            corner = f"{side} line {i}"

            def place(lo, hi, s=s, e=e, dx=dx):
                """A box given for the north-east corner of a bay centred on the origin,
                placed at this line and side."""
                X = box(lo, hi)
                X[:, 0] = X[:, 0] * e + dx
                X[:, 2] *= s
                return hexahedron(X)

            if "piers" in parts:
                _pier(blocks, supports, bay, corner, place, far)
            if "buttresses" in parts:
                _buttress(blocks, supports, bay, corner, place)
            if "flyers" in parts:
                _flyer(blocks, supports, bay, corner, place, e, s, far, dx)
    return blocks, supports


def _pier(blocks, supports, bay, corner, place, far=None):
    """A pier of drums, its upper pier (from the arcade's springing bed to ``far``, by default
    the pier's outer face) and its foundation."""
    pz0, pz1 = bay.pier_z
    h, p = bay.bay_m / 2.0, bay.pier_m / 2.0
    levels = _levels(0.0, bay.arcade_spring_m, bay.drum_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"pier {corner} drum {k + 1}",
                       [place((h - p, y0, pz0), (h + p, y1, pz1))]))
    levels = _levels(bay.arcade_spring_m, bay.vault_spring_m, bay.drum_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"upper pier {corner} {k + 1}",
                       [place((bay.upper_pier_x, y0, pz0), (h + p if far is None else far,
                                                           y1, pz1))]))
    m = 0.1 * p
    blocks.append((f"foundation pier {corner}",
                   [place((h - p - m, -bay.foundation_depth_m, pz0 - m), (h + p + m, 0.0, pz1))]))
    supports.append(f"foundation pier {corner}")


def _buttress(blocks, supports, bay, corner, place):
    """An attached buttress against a pier's outer face, and its foundation."""
    _, pz1 = bay.pier_z
    h, m = bay.bay_m / 2.0, 0.05 * bay.pier_m
    bw, bd = bay.buttress_width_m / 2.0, bay.buttress_depth_m
    levels = _levels(0.0, bay.vault_spring_m, bay.buttress_course_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"buttress {corner} course {k + 1}",
                       [place((h - bw, y0, pz1), (h + bw, y1, pz1 + bd))]))
    blocks.append((f"foundation buttress {corner}",
                   [place((h - bw - m, -bay.foundation_depth_m, pz1),
                          (h + bw + m, 0.0, pz1 + bd + m))]))
    supports.append(f"foundation buttress {corner}")


def _flyer(blocks, supports, bay, corner, place, e, s, far=None, dx=0.0):
    """A flying buttress: the upper buttress above the upper pier and the attached buttress, up
    to the walls' top against the wall's end; the flyer, a quarter circle of voussoirs from its
    head (a vertical joint against the upper buttress's outer face) down to its springing (a
    horizontal bed on the flyer pier); the flyer pier with its pinnacle beyond the flyer's
    foot, and its foundation. ``far``: the x of the upper buttress's and the flyer's far face
    (by default the attached buttress's); ``dx``: the bay's centre along x."""
    h, bw = bay.bay_m / 2.0, bay.buttress_width_m / 2.0
    _, pz1 = bay.pier_z
    z_out = pz1 + bay.buttress_depth_m  # the attached buttress's outer face
    z_in = bay.wall_z[0] + 0.25 * bay.wall_thickness_m  # clear of the transverse rib's foot
    x0, x1 = bay.upper_pier_x, h + bw if far is None else far
    levels = _levels(bay.vault_spring_m, bay.wall_top_m, bay.buttress_course_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"upper buttress {corner} course {k + 1}",
                       [place((x0, y0, z_in), (x1, y1, z_out))]))
    ri, ro = bay.flyer_radius_m, bay.flyer_radius_m + bay.flyer_depth_m
    yc = bay.flyer_head_m - ro  # the flyer's centre, on the upper buttress's face
    angles = np.linspace(0.0, 0.5 * math.pi, bay.flyer_voussoirs + 1)
    for k, (a0, a1) in enumerate(pairwise(angles)):
        X = np.array([[x, yc + r * math.cos(a), z_out + r * math.sin(a)]
                      for x, r, a in ((x0, ri, a0), (x1, ri, a0), (x1, ri, a1), (x0, ri, a1),
                                      (x0, ro, a0), (x1, ro, a0), (x1, ro, a1), (x0, ro, a1))])
        X[:, 0] = X[:, 0] * e + dx
        X[:, 2] *= s
        blocks.append((f"flyer {corner} voussoir {k + 1}", [hexahedron(X)]))
    zf0, zf1 = z_out + ri, z_out + ri + bay.flyer_pier_depth_m
    fx0, fx1 = h - bw, h + bw
    levels = _levels(0.0, yc, bay.buttress_course_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"flyer pier {corner} course {k + 1}",
                       [place((fx0, y0, zf0), (fx1, y1, zf1))]))
    levels = _levels(yc, yc + bay.pinnacle_m, bay.buttress_course_m)
    for k, (y0, y1) in enumerate(pairwise(levels)):
        blocks.append((f"pinnacle {corner} course {k + 1}",
                       [place((fx0, y0, z_out + ro), (fx1, y1, zf1))]))
    m = 0.05 * bay.pier_m
    blocks.append((f"foundation flyer pier {corner}",
                   [place((fx0 - m, -bay.foundation_depth_m, zf0 - m),
                          (fx1 + m, 0.0, zf1 + m))]))
    supports.append(f"foundation flyer pier {corner}")


def _levels(y0: float, y1: float, step: float) -> list[float]:
    n = max(1, round((y1 - y0) / step))
    return list(np.linspace(y0, y1, n + 1))


def block_mesh(blocks: list[tuple[str, list[np.ndarray]]], tol: float):
    """Points, hexahedra and tags of the blocks (tags from 1 in their order), the nodes of a
    block within ``tol`` of each other made one."""
    points, cells, tags = [], [], []
    for tag, (_, hexes) in enumerate(blocks, start=1):
        X = np.concatenate(hexes)
        key = np.round(X / tol).astype(np.int64)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        base = sum(len(q) for q in points)
        points.append(X[first])
        conn = inverse.reshape(-1, 8) + base
        cells.append(conn)
        tags += [tag] * len(conn)
    return np.concatenate(points), np.concatenate(cells), np.array(tags, dtype=np.int64)


def write_mesh(path: Path, blocks, tol: float = 1e-7) -> tuple[int, int]:
    """Write the blocks as a Gmsh 2.2 file, one physical volume per block (meshio)."""
    import meshio

    points, cells, tags = block_mesh(blocks, tol)
    mesh = meshio.Mesh(points, [("hexahedron", cells)],
                       cell_data={"gmsh:physical": [tags], "gmsh:geometrical": [tags]},
                       field_data={name: np.array([tag, 3])
                                   for tag, (name, _) in enumerate(blocks, start=1)})
    meshio.write(path, mesh, file_format="gmsh22", binary=False)
    return len(blocks), len(cells)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scale", type=float, default=1.0,
                        help="factor on every length (a smaller bay has fewer blocks)")
    parser.add_argument("--parts", default=",".join(PARTS),
                        help=f"comma-separated parts to write (of {', '.join(PARTS)})")
    parser.add_argument("--bays", type=int, default=1,
                        help="bays along the nave (1: the bay alone, the shipped mesh)")
    parser.add_argument("-o", "--output", type=Path,
                        default=Path(__file__).with_name("nave_bay.msh"))
    parser.add_argument("--case", type=Path, default=None,
                        help="also write a case of this mesh: the shipped bay's, its "
                             "supports every foundation")
    args = parser.parse_args(argv)
    if not 0.05 <= args.scale <= 4.0:
        parser.error("--scale must be between 0.05 and 4")
    if not 1 <= args.bays <= 200:
        parser.error("--bays must be between 1 and 200")
    parts = tuple(args.parts.split(","))
    if not set(parts) <= set(PARTS):
        parser.error(f"--parts takes {', '.join(PARTS)}")
    bay = Bay(args.scale)
    blocks, supports = nave_blocks(bay, args.bays, parts)
    n_blocks, n_hex = write_mesh(args.output, blocks)
    print(f"wrote {args.output}: {n_blocks} blocks ({len(supports)} fixed foundations), "
          f"{n_hex} hexahedra")
    if args.case is not None:
        write_case(args.case, args.output, supports, args.bays)
        print(f"wrote {args.case}")


def write_case(path: Path, mesh: Path, supports: list[str], bays: int) -> None:
    """The shipped bay's case (``nave_bay.yaml`` beside this script) on ``mesh``, every
    foundation in ``supports`` fixed."""
    import os

    import yaml

    case = yaml.safe_load(Path(__file__).with_name("nave_bay.yaml").read_text())
    case["name"] = path.stem
    case["description"] = (f"Gothic nave of {bays} bays from a mesh file, growing horizontal "
                           "body force across the nave to collapse")
    case["assembly"]["mesh_file"] = os.path.relpath(mesh.resolve(), path.resolve().parent)
    case["assembly"]["supports"] = [{"group": g, "kind": "fixed"} for g in supports]
    path.write_text(f"# written by cases/{Path(__file__).name} --bays {bays}\n"
                    + yaml.safe_dump(case, sort_keys=False, width=100))


if __name__ == "__main__":
    main()
