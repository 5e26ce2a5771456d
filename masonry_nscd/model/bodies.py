r"""Bodies of a block assembly: deformable blocks and rigid bodies, each with a mesh.

A **block** (:class:`Block`) is a mesh of one element type (8-node hexahedra, 4- or 10-node
tetrahedra: :mod:`masonry_nscd.fe.catalog`, found by the cells' node count; the elements are
isoparametric), with a material (linear elastic or ENDO3D), E, nu and density. Its degrees of
freedom are three translations per node (m).

A **rigid body** (:class:`RigidBody`) has six degrees of freedom ``(u_x, u_y, u_z, rot_x, rot_y,
rot_z)`` (m, rad; small rotations) about its reference point ``reference`` (m). Its mesh, if it
has one, is geometry only: the faces that contact detection sees and the cells that the outputs
draw. A box or any body meshed with hexahedra or tetrahedra (a wedge, a voussoir, a stone of
any polyhedral shape) has its mass, centre of mass and inertia tensor from its mesh
(:meth:`RigidBody.from_mesh`: exact for hexahedra with flat faces and for tetrahedra), from the
hull of its vertices (:meth:`RigidBody.polyhedron`) or in closed form
(:meth:`RigidBody.box`). With the centre of mass ``c`` and ``d = c - reference``, the velocity of
a material point is ``v = v_0 + omega x (x - reference)`` and the mass matrix

    M = [[ m I        , -m [d]x           ],
         [ m [d]x     ,  I_c - m [d]x [d]x ]]          (kg, kg m, kg m^2)

with ``[d]x`` the cross-product matrix and ``I_c`` the inertia tensor about the centre of mass
(kg m^2); it is diagonal when the reference point is the centre of mass and the axes are
principal. A dof of a rigid body is free, or imposed: its velocity follows a history (m/s or
rad/s). A rigid body marked ``support`` (a steel beam, the ground) never carries the contact
points of a joint with a body that is not a support (:mod:`masonry_nscd.model.detection`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from masonry_nscd.fe import element as solid
from masonry_nscd.fe import hex8
from masonry_nscd.fe.catalog import element_of
from masonry_nscd.loading import History, at_rest

DOF_FREE = 0
DOF_IMPOSED = 1

MAT_ELASTIC = 0
MAT_ENDO3D = 1

_NO_NODES = np.zeros((0, 3))
_NO_CELLS = np.zeros((0, 8), dtype=np.int64)


def cross_matrix(d: np.ndarray) -> np.ndarray:
    """``[d]x`` with ``[d]x a = d x a``."""
    return np.array([[0.0, -d[2], d[1]], [d[2], 0.0, -d[0]], [-d[1], d[0], 0.0]])


@dataclass
class Block:
    """A deformable block: a mesh of one element type (nodes ``X`` (n, 3) m, cells ``conn``
    (ne, nodes): 8 for hexahedra, 4 or 10 for tetrahedra)."""

    X: np.ndarray
    conn: np.ndarray
    E: float  # Pa
    nu: float
    density: float  # kg/m^3
    material: int = MAT_ELASTIC
    name: str = ""

    def __post_init__(self):
        self.X = np.ascontiguousarray(self.X, dtype=float)
        self.conn = np.ascontiguousarray(self.conn, dtype=np.int64)

    @classmethod
    def box(cls, origin, size, divisions, **kw) -> Block:
        """A block meshed as the box ``[origin, origin + size]`` (m) with ``divisions`` =
        (nx, ny, nz) hexahedra."""
        X, conn = hex8.box_mesh(np.asarray(origin, float), np.asarray(size, float),
                                tuple(divisions))
        return cls(X=X, conn=conn, **kw)

    @property
    def ndof(self) -> int:
        return 3 * len(self.X)

    @property
    def element(self) -> solid.Element:
        """The element type of the block's cells."""
        return element_of(self.conn)

    def lumped_mass(self) -> np.ndarray:
        """Lumped mass per dof (3n,), kg."""
        return solid.lumped_mass(self.X, self.conn, self.density, self.element)


@dataclass
class RigidBody:
    """A rigid body: 6 dofs about ``reference``; each dof free or with an imposed velocity.

    ``center``: centre of mass (m); ``inertia``: about the centre of mass, principal moments
    about x, y, z (3,) or the tensor (3, 3) (kg m^2); ``reference`` defaults to ``center``.
    """

    center: np.ndarray  # m
    mass: float  # kg
    inertia: np.ndarray  # kg m^2
    dof_mode: np.ndarray = field(default_factory=lambda: np.zeros(6, dtype=np.int64))
    imposed_velocity: dict[int, History] = field(default_factory=dict)  # dof -> v(t)
    name: str = ""
    X: np.ndarray = field(default_factory=lambda: _NO_NODES)  # geometry only
    conn: np.ndarray = field(default_factory=lambda: _NO_CELLS)
    reference: np.ndarray | None = None  # m, the point the dofs move
    support: bool = False

    def __post_init__(self):
        self.center = np.asarray(self.center, dtype=float)
        inertia = np.asarray(self.inertia, dtype=float)
        self.inertia = np.diag(inertia) if inertia.shape == (3,) else inertia
        self.reference = self.center.copy() if self.reference is None else \
            np.asarray(self.reference, dtype=float)
        self.dof_mode = np.array(self.dof_mode, dtype=np.int64)
        for d in self.imposed_velocity:
            self.dof_mode[d] = DOF_IMPOSED
        self.X = np.ascontiguousarray(self.X, dtype=float)
        self.conn = np.ascontiguousarray(self.conn, dtype=np.int64)

    @property
    def ndof(self) -> int:
        return 6

    def mass_matrix(self) -> np.ndarray:
        """The 6x6 mass matrix about the reference point (module docstring)."""
        d = self.center - self.reference
        D = cross_matrix(d)
        M = np.zeros((6, 6))
        M[:3, :3] = self.mass * np.eye(3)
        M[:3, 3:] = -self.mass * D
        M[3:, :3] = self.mass * D
        M[3:, 3:] = self.inertia - self.mass * D @ D
        return M

    def weight_load(self, g: np.ndarray) -> np.ndarray:
        """Generalised force (6,) of the weight ``m g`` (g in m/s^2) acting at the centre of mass:
        the force and its moment about the reference point (N, N m)."""
        f = self.mass * np.asarray(g, dtype=float)
        return np.concatenate([f, np.cross(self.center - self.reference, f)])

    def displacement_of(self, q: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Displacement (m) of material points ``x`` (k, 3) for the dofs ``q`` (6,)."""
        return q[:3] + np.cross(q[3:], np.asarray(x) - self.reference)

    @staticmethod
    def fixed(center, **kw) -> RigidBody:
        """A support: every dof imposed at zero velocity (its mass never enters)."""
        kw.setdefault("support", True)
        return RigidBody(center=center, mass=1.0, inertia=np.ones(3),
                         imposed_velocity=dict.fromkeys(range(6), at_rest), **kw)

    @staticmethod
    def box(origin, size, density: float, divisions=(1, 1, 1), **kw) -> RigidBody:
        """A rigid box of uniform density (kg/m^3), meshed by ``divisions`` for its geometry."""
        size = np.asarray(size, dtype=float)
        m = density * float(np.prod(size))
        a, b, c = size
        inertia = m / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        X, conn = hex8.box_mesh(np.asarray(origin, float), size, tuple(divisions))
        return RigidBody(center=np.asarray(origin) + 0.5 * size, mass=m, inertia=inertia,
                         X=X, conn=conn, **kw)

    @staticmethod
    def from_mesh(X, conn, density: float, **kw) -> RigidBody:
        """A rigid body of uniform density (kg/m^3) with the shape of a mesh of hexahedra or
        tetrahedra: mass, centre of mass and inertia tensor by the element's ``mass_rule``
        (:func:`masonry_nscd.fe.element.mass_properties`: the 3x3x3 Gauss rule of hexahedra,
        exact for any hexahedron with flat faces; the degree-2 rule of tetrahedra, exact for
        any tetrahedral mesh with straight edges, the sum over its tetrahedra)."""
        X = np.asarray(X, dtype=float)
        conn = np.asarray(conn, dtype=np.int64)
        mass, first, second = solid.mass_properties(X, conn, density, element_of(conn))
        if not mass > 0.0:
            raise ValueError("a rigid body's mesh has no volume")
        c = first / mass
        S = second - mass * np.outer(c, c)  # second moment about the centre of mass
        inertia = np.trace(S) * np.eye(3) - S
        return RigidBody(center=c, mass=mass, inertia=inertia, X=X, conn=conn, **kw)

    @staticmethod
    def polyhedron(vertices, density: float, **kw) -> RigidBody:
        """A rigid convex polyhedron of uniform density (kg/m^3) from its vertices (m): the
        tetrahedra of its hull (:func:`convex_hull_mesh`), so its mass, centre and inertia are
        exact; ValueError if it is flat or not convex."""
        X, conn = convex_hull_mesh(vertices, kw.get("name", ""))
        return RigidBody.from_mesh(X, conn, density, **kw)


def convex_hull_mesh(vertices, name: str = "", tol: float = 1e-9
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The tetrahedra of the convex polyhedron of ``vertices`` (k, 3) (m): one per triangle of
    its hull, to the mean of the hull's vertices (inside a convex body); nodes: the vertices,
    then that mean. Faces of the hull that lie in one plane make one planar patch for contact
    detection, whatever their triangles.

    Raises ValueError naming the body when the polyhedron is flat or not convex: a vertex
    farther than ``tol`` times the body's size inside the hull of the others (split such a
    stone into convex blocks, or mesh it)."""
    V = np.asarray(vertices, dtype=float)
    label = f"block {name!r}" if name else "a polyhedral block"
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 4:
        raise ValueError(f"{label}: a polyhedron needs at least 4 vertices (k, 3), got "
                         f"{V.shape}")
    size = float(np.ptp(V, axis=0).max())
    try:
        hull = ConvexHull(V)
    except QhullError:
        raise ValueError(f"{label} is flat: its vertices lie in one plane") from None
    # a vertex that is not the hull's: how far inside the hull's planes it lies
    depth = -(hull.equations[:, :3] @ V.T + hull.equations[:, 3:]).max(axis=0)
    inside = [k for k in range(len(V)) if k not in set(hull.vertices)
              and depth[k] > tol * size]
    if inside:
        k = inside[0]
        raise ValueError(f"{label} is not convex: vertex {k} lies {depth[k]:.3g} m inside the "
                         "hull of the others (split it into convex blocks, or mesh it)")
    used = np.unique(hull.simplices)
    center = V[used].mean(axis=0)
    X = np.vstack([V, center])
    conn = np.column_stack([hull.simplices, np.full(len(hull.simplices), len(V))])
    # the right-hand rule of each base seen from its apex: positive volumes
    a, b, c, d = (X[conn[:, i]] for i in range(4))
    negative = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) < 0.0
    conn[negative, 1], conn[negative, 2] = conn[negative, 2], conn[negative, 1].copy()
    return X, conn


def body_mass(body) -> float:
    """Mass of a body (kg)."""
    return float(body.mass) if isinstance(body, RigidBody) else float(body.lumped_mass()[0::3].sum())


def body_momentum(body, v: np.ndarray) -> np.ndarray:
    """Linear momentum (3,) of a body for its dof velocities ``v`` (N s)."""
    if isinstance(body, RigidBody):
        return body.mass * (v[:3] + np.cross(v[3:], body.center - body.reference))
    m = body.lumped_mass()
    return (m * v).reshape(-1, 3).sum(axis=0)
