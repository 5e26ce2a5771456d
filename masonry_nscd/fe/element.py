r"""Isoparametric solid elements: the element descriptor, and what every element type shares
(B matrices, stiffness, lumped mass, strains, forces), on plain arrays.

An element type is one module (:mod:`~masonry_nscd.fe.hex8`, :mod:`~masonry_nscd.fe.tet4`,
:mod:`~masonry_nscd.fe.tet10`) that makes an :class:`Element`: its nodes, its Gauss rule, its
shape functions and their derivatives on the reference element, its faces in local node
order, its VTK cell type. Everything else is written once, here, for any descriptor:

    x(xi) = sum_a N_a(xi) x_a,   J = dx / dxi,   dN/dx = dN/dxi J^-1,
    K_e = sum_g w_g det J_g B_g^T C B_g          (N/m)
    eps = B u_e,   f_e = sum_g w_g det J_g B_g^T sigma_g      (N)

with ``B`` the strain-displacement matrix (Voigt ``[xx, yy, zz, yz, xz, xy]``, ENGINEERING
shear strains ``gamma = 2 eps``), ``w_g`` the rule's weights on the reference element. The
integration weights stored per element and point are ``w_g det J_g`` (m^3); for the
hexahedron the weights are 1 and they are ``det J`` itself.

The mass is lumped: by rows (``m_a = sum_g rho N_a(g) w_g det J_g``, positive for the
trilinear hexahedron and the linear tetrahedron), or, for an element whose row sums are not
all positive (the 10-node tetrahedron, whose corners would get ``-1/20`` of its mass), by
fixed fractions of the element mass (``Element.mass_fractions``: the diagonal of the
consistent mass scaled to the element mass, Hinton-Rock-Zienkiewicz).

What is computed once per block is vectorised NumPy; what runs at every step for ENDO3D blocks
(``forces_from_gradients``, ``stiffness_from_gradients``) is compiled, plain loops on the
gradients, for any number of nodes and Gauss points.

Units: coordinates in m, E in Pa, density in kg/m^3, stiffness in N/m, mass in kg.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numba import njit


@dataclass(frozen=True, eq=False)
class Element:
    """An element type (module docstring).

    ``shape_at(points (k, 3)) -> (N (k, nodes), dN/dxi (k, nodes, 3))`` on the reference
    element. ``faces`` (nf, face_nodes): the local nodes of each face, corners first, ordered so
    that the right-hand rule on its first three corners gives the outward normal; the
    midside nodes of a quadratic face follow its corners, edge (0, 1), (1, 2), (2, 0).
    ``corners``: reference coordinates (nc, 3) of the vertices, nodes ``0..nc-1``, where the
    mesh checks evaluate ``det J``; ``edges`` (ne, 2): corner pairs. ``mass_rule``: points and
    weights exact for the mass, first and second moments of an affine element (a rigid body's
    mass, centre and inertia). ``mass_fractions``: None for row-sum lumping, else the share of
    the element mass of each node. ``drawn_as``: the outputs (VTU, results.h5, plots) draw
    every element as an 8-node hexahedron, a tetrahedron as a collapsed one (corners
    ``0, 1, 2, 2, 3, 3, 3, 3``: its base, then its apex).
    """

    name: str
    nodes: int
    gauss_points: np.ndarray  # (ng, 3) reference coordinates
    gauss_weights: np.ndarray  # (ng,) reference weights (sum: the reference volume)
    shape_at: Callable
    faces: np.ndarray  # (nf, face_nodes) local node numbers
    face_corners: int  # 4: quadrilateral faces, 3: triangular
    corners: np.ndarray  # (nc, 3) reference coordinates of the vertices
    edges: np.ndarray  # (nedge, 2) corner pairs
    vtk_type: int
    meshio_type: str
    mass_rule: tuple[np.ndarray, np.ndarray]
    drawn_as: np.ndarray  # (8,) local nodes of the hexahedron the outputs draw it as
    mass_fractions: np.ndarray | None = None

    @property
    def ngauss(self) -> int:
        return len(self.gauss_weights)

    @property
    def ndof(self) -> int:
        return 3 * self.nodes

    @property
    def gauss_shape(self) -> tuple[np.ndarray, np.ndarray]:
        """N (ng, nodes) and dN/dxi (ng, nodes, 3) at the Gauss points (cached)."""
        cached = self.__dict__.get("_gauss_shape")
        if cached is None:
            cached = self.shape_at(self.gauss_points)
            object.__setattr__(self, "_gauss_shape", cached)
        return cached


def elastic_matrix(E: float, nu: float) -> np.ndarray:
    """Isotropic elasticity C0 (6x6, Voigt, engineering shear), Pa."""
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = E / (2.0 * (1.0 + nu))
    C = np.zeros((6, 6))
    C[:3, :3] = lam
    C[np.arange(3), np.arange(3)] += 2.0 * mu
    C[3:, 3:] = np.eye(3) * mu
    return C


def b_from_dndx(dNdx: np.ndarray) -> np.ndarray:
    """Strain-displacement matrices (..., 6, 3 nodes) from the shape-function gradients
    (..., nodes, 3): ``eps = B u`` with u ordered (x, y, z) per node, Voigt order, engineering
    shears."""
    n = dNdx.shape[-2]
    B = np.zeros((*dNdx.shape[:-2], 6, 3 * n))
    dx, dy, dz = dNdx[..., 0], dNdx[..., 1], dNdx[..., 2]
    B[..., 0, 0::3] = dx
    B[..., 1, 1::3] = dy
    B[..., 2, 2::3] = dz
    B[..., 3, 1::3] = dz
    B[..., 3, 2::3] = dy
    B[..., 4, 0::3] = dz
    B[..., 4, 2::3] = dx
    B[..., 5, 0::3] = dy
    B[..., 5, 1::3] = dx
    return B


def jacobians(xe_all: np.ndarray, dN: np.ndarray) -> np.ndarray:
    """``J[e, g, i, k] = dx_i / dxi_k = sum_a x[e, a, i] dN[g, a, k]`` (nel, ng, 3, 3)."""
    return np.einsum("eai,gak->egik", xe_all, dN)


def precompute_gradients(xe_all: np.ndarray, el: Element) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients ``dN/dx`` (nel, ng, nodes, 3; 1/m) and integration weights
    ``w_g det J`` (nel, ng; m^3) at the Gauss points of many elements ``xe_all`` (nel, nodes,
    3) of type ``el``. Raises ValueError for an element with a non-positive Jacobian (an
    inverted element)."""
    xe_all = np.asarray(xe_all, dtype=float)
    _, dN = el.gauss_shape
    J = jacobians(xe_all, dN)
    detJ = np.linalg.det(J)
    if np.any(detJ <= 0.0):
        raise ValueError(f"{el.name} element with a non-positive Jacobian (inverted element)")
    return np.einsum("gak,egkj->egaj", dN, np.linalg.inv(J)), detJ * el.gauss_weights


def precompute_b(xe_all: np.ndarray, el: Element) -> tuple[np.ndarray, np.ndarray]:
    """B matrices (nel, ng, 6, 3 nodes) and weights (nel, ng) of many elements, from
    :func:`precompute_gradients`."""
    dNdx, w = precompute_gradients(xe_all, el)
    return b_from_dndx(dNdx), w


def element_masses(w: np.ndarray, rho: float, el: Element) -> np.ndarray:
    """Lumped nodal masses (nel, nodes), kg, from the integration weights ``w`` (nel, ng):
    row sums ``m_a = sum_g rho N_a(g) w_g det J_g``, or the element's mass fractions of
    ``rho sum_g w_g det J_g`` (module docstring)."""
    if el.mass_fractions is not None:
        return rho * w.sum(axis=1)[:, None] * el.mass_fractions[None, :]
    return rho * w @ el.gauss_shape[0]


def element_dofs(conn: np.ndarray) -> np.ndarray:
    """The dofs of each element's nodes (nel, 3 nodes), x, y, z per node."""
    conn = np.asarray(conn, dtype=np.int64)
    return (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), 3 * conn.shape[1])


def lumped_mass(X: np.ndarray, conn: np.ndarray, rho: float, el: Element) -> np.ndarray:
    """Lumped mass per dof (3n,) of one block mesh, kg (the mass of ``assemble_block``)."""
    _, w = precompute_gradients(np.asarray(X, dtype=float)[conn], el)
    m = np.zeros(3 * X.shape[0])
    np.add.at(m, element_dofs(conn), np.repeat(element_masses(w, rho, el), 3, axis=1))
    return m


def assemble_block(X: np.ndarray, conn: np.ndarray, C: np.ndarray, rho: float, el: Element):
    """Dense stiffness (3n, 3n) and lumped mass per dof (3n,) of one block mesh."""
    B, w = precompute_b(np.asarray(X, dtype=float)[conn], el)
    Ke = np.einsum("eg,egia,ij,egjb->eab", w, B, C, B, optimize=True)
    edofs = element_dofs(conn)
    n = 3 * X.shape[0]
    K = np.zeros((n, n))
    np.add.at(K, (edofs[:, :, None], edofs[:, None, :]), Ke)
    m = np.zeros(n)
    np.add.at(m, edofs, np.repeat(element_masses(w, rho, el), 3, axis=1))
    return K, m


def gauss_strains(X: np.ndarray, conn: np.ndarray, u: np.ndarray, eps: np.ndarray,
                  el: Element) -> None:
    """Strains (nel * ng, 6) at the Gauss points from nodal displacements u (3n,)."""
    B, _ = precompute_b(np.asarray(X, dtype=float)[conn], el)
    ue = np.asarray(u)[element_dofs(conn)]
    eps[:] = np.einsum("egij,ej->egi", B, ue).reshape(-1, 6)


def mean_stress_map(X: np.ndarray, conn: np.ndarray, C: np.ndarray, el: Element) -> np.ndarray:
    """``S`` (6 nel, 3n): the mean stress over the Gauss points of each element (Pa, rows
    element by element in Voigt order) from the nodal displacements u (3n,) of a linear block,
    ``sigma_e = C (1/ng sum_g B_eg) u_e``."""
    B, _ = precompute_b(np.asarray(X, dtype=float)[conn], el)
    Se = C @ B.mean(axis=1)  # (nel, 6, 3 nodes)
    S = np.zeros((len(conn), 6, 3 * len(X)))
    edofs = element_dofs(conn)
    for e in range(len(conn)):
        S[e][:, edofs[e]] += Se[e]
    return S.reshape(-1, 3 * len(X))


def internal_forces(X: np.ndarray, conn: np.ndarray, sigma: np.ndarray, f: np.ndarray,
                    el: Element) -> None:
    """Nodal internal forces ``f = sum_e sum_g B^T sigma w_g det J`` (3n,), N, from the Gauss
    stresses (nel * ng, 6)."""
    B, w = precompute_b(np.asarray(X, dtype=float)[conn], el)
    fe = np.einsum("eg,egij,egi->ej", w, B, np.asarray(sigma).reshape(len(conn), el.ngauss, 6))
    f[:] = 0.0
    np.add.at(f, element_dofs(conn), fe)


@njit(cache=True)
def forces_from_gradients(dN: np.ndarray, w: np.ndarray, edofs: np.ndarray,
                          sigma: np.ndarray, f: np.ndarray) -> None:
    """Add ``sum_g w B^T sigma`` of every element to the global force vector f (N), ``B``
    given by the gradients that fill it, ``dN[e, g, a] = dN_a/dx`` (1/m, (nel, ng, nodes, 3);
    :func:`precompute_gradients`), ``sigma`` (nel * ng, 6): its nonzero terms in the order of
    its rows, so that the sums are the dense product's term for term."""
    ng = dN.shape[1]
    nn = dN.shape[2]
    for e in range(dN.shape[0]):
        for g in range(ng):
            s = sigma[ng * e + g]
            wg = w[e, g]
            for a in range(nn):
                gx = dN[e, g, a, 0]
                gy = dN[e, g, a, 1]
                gz = dN[e, g, a, 2]
                f[edofs[e, 3 * a]] += wg * (gx * s[0] + gz * s[4] + gy * s[5])
                f[edofs[e, 3 * a + 1]] += wg * (gy * s[1] + gz * s[3] + gx * s[5])
                f[edofs[e, 3 * a + 2]] += wg * (gz * s[2] + gy * s[3] + gx * s[4])


@njit(cache=True)
def stiffness_from_gradients(dN: np.ndarray, w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element matrices ``K_e = sum_g w_g B_g^T C_g B_g`` (nel, 3 nodes, 3 nodes), N/m, ``B``
    given by its gradients as in :func:`forces_from_gradients` (each column of ``B`` has three
    nonzero rows, each row of ``B^T``: ``C B`` and ``B^T (C B)`` take those only, in the order
    of the dense products).

    ``C`` (nel * ng, 6, 6): a material matrix per Gauss point, ``C[p, i, j] = d sigma_i /
    d eps_j`` (Pa), not necessarily symmetric (a consistent tangent).
    """
    nel = dN.shape[0]
    ng = dN.shape[1]
    nn = dN.shape[2]
    nd = 3 * nn
    K = np.zeros((nel, nd, nd))
    CB = np.empty((6, nd))
    for e in range(nel):
        for g in range(ng):
            p = ng * e + g
            Cp = C[p]
            for a in range(nn):
                gx = dN[e, g, a, 0]
                gy = dN[e, g, a, 1]
                gz = dN[e, g, a, 2]
                for i in range(6):
                    CB[i, 3 * a] = Cp[i, 0] * gx + Cp[i, 4] * gz + Cp[i, 5] * gy
                    CB[i, 3 * a + 1] = Cp[i, 1] * gy + Cp[i, 3] * gz + Cp[i, 5] * gx
                    CB[i, 3 * a + 2] = Cp[i, 2] * gz + Cp[i, 3] * gy + Cp[i, 4] * gx
            wg = w[e, g]
            for b in range(nn):
                gx = dN[e, g, b, 0]
                gy = dN[e, g, b, 1]
                gz = dN[e, g, b, 2]
                for k in range(nd):
                    K[e, 3 * b, k] += wg * (gx * CB[0, k] + gz * CB[4, k] + gy * CB[5, k])
                    K[e, 3 * b + 1, k] += wg * (gy * CB[1, k] + gz * CB[3, k] + gx * CB[5, k])
                    K[e, 3 * b + 2, k] += wg * (gz * CB[2, k] + gy * CB[3, k] + gx * CB[4, k])
    return K


def mass_properties(X: np.ndarray, conn: np.ndarray, density: float, el: Element
                    ) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass (kg), first moment (kg m, (3,)) and second moment ``int rho x x^T dV`` (kg m^2,
    (3, 3)) of a mesh of uniform density by the element's ``mass_rule``: the sums over the
    elements ``e`` and their points ``g`` of ``rho det J(e, g) w_g`` times 1, ``x`` and
    ``x x^T``."""
    X = np.asarray(X, dtype=float)
    points, weights = el.mass_rule
    N_all, dN_all = el.shape_at(points)
    xe = X[np.asarray(conn, dtype=np.int64)]  # (E, nn, 3)
    J = np.einsum("gna,enb->egab", dN_all, xe)  # the transpose of dx/dxi: the same det
    w = density * np.linalg.det(J) * np.asarray(weights)[None, :]  # (E, G), kg
    x = np.einsum("gn,enb->egb", N_all, xe)  # the points, m
    mass = float(w.sum())
    first = np.einsum("eg,egb->b", w, x)
    second = np.einsum("eg,ega,egb->ab", w, x, x)
    return mass, first, second
