"""The model: bodies, contact points, loads, as plain dataclasses of arrays.

Scene builders (``masonry_nscd.scenes``) create ``Block`` and ``RigidBody`` objects and contact
points; ``Model.build`` numbers the degrees of freedom and packs everything the kernels need
into flat arrays. Nothing here integrates in time.

Degrees of freedom: a deformable block has three translations per node (m); a rigid body has
``(u_x, u_y, u_z, rot_x, rot_y, rot_z)`` about its centre (m, rad, small rotations). Every
rigid dof is either free, or imposed (its velocity follows a history).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from masonry_nscd.fe import hex8

History = Callable[[float], float]


def at_rest(t: float) -> float:
    """The history of a dof held still: zero velocity at all times."""
    return 0.0

DOF_FREE = 0
DOF_IMPOSED = 1

MAT_ELASTIC = 0
MAT_ENDO3D = 1


@dataclass
class Block:
    """A deformable block: a structured hexahedral mesh of an axis-aligned box."""

    origin: np.ndarray  # m, lower corner
    size: np.ndarray  # m, edge lengths along x, y, z
    divisions: tuple[int, int, int]
    E: float  # Pa
    nu: float
    density: float  # kg/m^3
    material: int = MAT_ELASTIC
    label: str = ""
    X: np.ndarray = field(init=False)
    conn: np.ndarray = field(init=False)

    def __post_init__(self):
        self.origin = np.asarray(self.origin, dtype=float)
        self.size = np.asarray(self.size, dtype=float)
        self.X, self.conn = hex8.box_mesh(self.origin, self.size, self.divisions)

    @property
    def ndof(self) -> int:
        return 3 * len(self.X)

    def lumped_mass(self) -> np.ndarray:
        """Lumped mass per dof (3n,), kg."""
        return hex8.lumped_mass(self.X, self.conn, self.density)

    def node_id(self, i: int, j: int, k: int) -> int:
        nx, ny, _ = self.divisions
        return i + (nx + 1) * (j + (ny + 1) * k)

    def face_quads(self, axis: int, upper: bool):
        """Element faces on the side ``axis = min`` (upper False) or ``max`` of the box.

        Yields ``(nodes (4,), a1, a2, lo (2,), hi (2,))`` with ``a1 < a2`` the in-plane axes and
        the nodes ordered (lo,lo), (hi,lo), (hi,hi), (lo,hi) in (a1, a2).
        """
        div = self.divisions
        a1, a2 = [a for a in range(3) if a != axis]
        fixed = div[axis] if upper else 0
        edges = [np.linspace(self.origin[a], self.origin[a] + self.size[a], div[a] + 1)
                 for a in range(3)]
        for p in range(div[a1]):
            for q in range(div[a2]):
                nodes = []
                for (dp, dq) in ((0, 0), (1, 0), (1, 1), (0, 1)):
                    ijk = [0, 0, 0]
                    ijk[axis] = fixed
                    ijk[a1] = p + dp
                    ijk[a2] = q + dq
                    nodes.append(self.node_id(*ijk))
                lo = np.array([edges[a1][p], edges[a2][q]])
                hi = np.array([edges[a1][p + 1], edges[a2][q + 1]])
                yield np.array(nodes), a1, a2, lo, hi

    def locate(self, x: np.ndarray, axis: int, upper: bool):
        """The face quad of side (axis, upper) containing the projection of x, with (xi, eta)."""
        for nodes, a1, a2, lo, hi in self.face_quads(axis, upper):
            tol = 1e-9 * max(self.size)
            if lo[0] - tol <= x[a1] <= hi[0] + tol and lo[1] - tol <= x[a2] <= hi[1] + tol:
                xi = 2.0 * (x[a1] - lo[0]) / (hi[0] - lo[0]) - 1.0
                eta = 2.0 * (x[a2] - lo[1]) / (hi[1] - lo[1]) - 1.0
                return nodes, xi, eta
        return None


@dataclass
class RigidBody:
    """A rigid body (6 dofs about ``center``); each dof free or with an imposed velocity."""

    center: np.ndarray  # m
    mass: float  # kg
    inertia: np.ndarray  # kg m^2, principal moments about x, y, z
    dof_mode: np.ndarray = field(default_factory=lambda: np.zeros(6, dtype=np.int64))
    imposed_velocity: dict[int, History] = field(default_factory=dict)  # dof -> v(t) (m/s)
    label: str = ""

    def __post_init__(self):
        self.center = np.asarray(self.center, dtype=float)
        self.inertia = np.asarray(self.inertia, dtype=float)
        self.dof_mode = np.asarray(self.dof_mode, dtype=np.int64)
        for d in self.imposed_velocity:
            self.dof_mode[d] = DOF_IMPOSED

    @property
    def ndof(self) -> int:
        return 6

    @staticmethod
    def fixed(center, **kw) -> RigidBody:
        """A support: every dof imposed at zero velocity (its mass never enters)."""
        return RigidBody(center=center, mass=1.0, inertia=np.ones(3),
                         imposed_velocity=dict.fromkeys(range(6), at_rest), **kw)

    @staticmethod
    def box(origin, size, density: float, **kw) -> RigidBody:
        """A rigid box of uniform density (kg/m^3)."""
        size = np.asarray(size, dtype=float)
        m = density * float(np.prod(size))
        a, b, c = size
        inertia = m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        return RigidBody(center=np.asarray(origin) + 0.5 * size, mass=m, inertia=inertia, **kw)


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
    kind: int  # joint_law.KIND_*
    law: int  # row of the parameter table
    group: int  # scene label (e.g. bed joint, head joint, glue)
    bodies: tuple[int, int]  # body indices, -1 for none
    sides: list  # [(dofs (k,), coef (k, 3)), ...] velocity map per side


def deformable_side(dof0: int, nodes, xi: float, eta: float, frame, sign: float):
    """Velocity map of a point at (xi, eta) of a bilinear face quad of a block.

    ``v(x) = sum_i N_i(xi, eta) v_i`` with the quad's bilinear shape functions; the local
    relative velocity picks ``sign * frame @ v(x)``.
    """
    Nq = 0.25 * np.array([(1 - xi) * (1 - eta), (1 + xi) * (1 - eta),
                          (1 + xi) * (1 + eta), (1 - xi) * (1 + eta)])
    dofs = np.empty(12, dtype=np.int64)
    coef = np.empty((12, 3))
    for i, node in enumerate(nodes):
        for d in range(3):
            dofs[3 * i + d] = dof0 + 3 * node + d
            coef[3 * i + d] = sign * Nq[i] * frame[:, d]
    return dofs, coef


def rigid_side(dof0: int, body: RigidBody, x: np.ndarray, frame, sign: float):
    """Velocity map of a material point x of a rigid body: ``v = v_G + omega x (x - x_G)``."""
    r = np.asarray(x) - body.center
    dofs = dof0 + np.arange(6, dtype=np.int64)
    coef = np.empty((6, 3))
    for d in range(3):
        coef[d] = sign * frame[:, d]
        e = np.zeros(3)
        e[d] = 1.0
        coef[3 + d] = sign * frame @ np.cross(e, r)
    return dofs, coef


@dataclass
class Loads:
    """External loads: ``F(t) = sum_k history_k(t) * pattern_k`` (N)."""

    patterns: list[np.ndarray] = field(default_factory=list)
    histories: list[History] = field(default_factory=list)

    def add(self, pattern: np.ndarray, history: History) -> None:
        self.patterns.append(np.asarray(pattern, dtype=float))
        self.histories.append(history)

    def at(self, t: float, ndof: int) -> np.ndarray:
        F = np.zeros(ndof)
        for p, h in zip(self.patterns, self.histories):
            F += h(t) * p
        return F
