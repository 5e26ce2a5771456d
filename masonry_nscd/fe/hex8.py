r"""Eight-node hexahedra: shape functions, Gauss rules, stiffness, lumped mass, strains, forces.

Reference element ``[-1, 1]^3``, nodes in the usual order (bottom face ``zeta = -1``
counter-clockwise, then the top face)::

    N_i = (1 + xi xi_i)(1 + eta eta_i)(1 + zeta zeta_i) / 8

Voigt order ``[xx, yy, zz, yz, xz, xy]`` with ENGINEERING shear strains (``gamma = 2 eps``), so
that ``sigma = C eps`` and the strain energy is ``eps . sigma / 2``. Full 2x2x2 Gauss
integration. The mass is lumped by rows (``M_ii = sum_j M_ij``), which for the trilinear
hexahedron gives each node an eighth of the element mass on a parallelepiped; it keeps the
mass positive and diagonal (the free-velocity predictor then only needs ``M + (theta h)^2 K``).

Units: coordinates in m, E in Pa, density in kg/m^3, stiffness in N/m, mass in kg.
"""

from __future__ import annotations

import numpy as np
from numba import njit

NODE_SIGNS = np.array(
    [
        [-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1],
    ],
    dtype=np.float64,
)
_G = 1.0 / np.sqrt(3.0)
GAUSS_POINTS = NODE_SIGNS * _G  # 2x2x2 rule, unit weights, one point near each node


def elastic_matrix(E: float, nu: float) -> np.ndarray:
    """Isotropic elasticity C0 (6x6, Voigt, engineering shear), Pa."""
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    mu = E / (2.0 * (1.0 + nu))
    C = np.zeros((6, 6))
    C[:3, :3] = lam
    C[np.arange(3), np.arange(3)] += 2.0 * mu
    C[3:, 3:] = np.eye(3) * mu
    return C


@njit(cache=True)
def shape(xi: float, eta: float, zeta: float):
    """Shape functions N (8,) and their derivatives dN/dxi (8, 3) at a reference point."""
    N = np.empty(8)
    dN = np.empty((8, 3))
    for i in range(8):
        a = NODE_SIGNS[i, 0]
        b = NODE_SIGNS[i, 1]
        c = NODE_SIGNS[i, 2]
        N[i] = 0.125 * (1 + a * xi) * (1 + b * eta) * (1 + c * zeta)
        dN[i, 0] = 0.125 * a * (1 + b * eta) * (1 + c * zeta)
        dN[i, 1] = 0.125 * b * (1 + a * xi) * (1 + c * zeta)
        dN[i, 2] = 0.125 * c * (1 + a * xi) * (1 + b * eta)
    return N, dN


@njit(cache=True)
def b_matrix(xe: np.ndarray, xi: float, eta: float, zeta: float):
    """Strain-displacement matrix B (6, 24) and det J at a reference point of element ``xe``."""
    _, dN = shape(xi, eta, zeta)
    J = xe.T @ dN  # J[i, k] = dx_i / dxi_k
    detJ = np.linalg.det(J)
    dNdx = dN @ np.linalg.inv(J)  # (8, 3)
    B = np.zeros((6, 24))
    for i in range(8):
        dx = dNdx[i, 0]
        dy = dNdx[i, 1]
        dz = dNdx[i, 2]
        c = 3 * i
        B[0, c] = dx
        B[1, c + 1] = dy
        B[2, c + 2] = dz
        B[3, c + 1] = dz
        B[3, c + 2] = dy
        B[4, c] = dz
        B[4, c + 2] = dx
        B[5, c] = dy
        B[5, c + 1] = dx
    return B, detJ


@njit(cache=True)
def element_b_all(xe: np.ndarray):
    """B matrices (8, 6, 24) and integration weights det J (8,) at the 8 Gauss points."""
    Bs = np.empty((8, 6, 24))
    w = np.empty(8)
    for g in range(8):
        B, detJ = b_matrix(xe, GAUSS_POINTS[g, 0], GAUSS_POINTS[g, 1], GAUSS_POINTS[g, 2])
        if detJ <= 0.0:
            raise ValueError("hexahedron with a non-positive Jacobian (inverted element)")
        Bs[g] = B
        w[g] = detJ
    return Bs, w


@njit(cache=True)
def element_stiffness(xe: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element stiffness ``K_e = sum_g B^T C B det J`` (24, 24), N/m."""
    Bs, w = element_b_all(xe)
    K = np.zeros((24, 24))
    for g in range(8):
        K += w[g] * (Bs[g].T @ C @ Bs[g])
    return K


@njit(cache=True)
def element_lumped_mass(xe: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped nodal masses (8,), kg: ``m_i = sum_g rho N_i det J``."""
    m = np.zeros(8)
    for g in range(8):
        N, _ = shape(GAUSS_POINTS[g, 0], GAUSS_POINTS[g, 1], GAUSS_POINTS[g, 2])
        _, detJ = b_matrix(xe, GAUSS_POINTS[g, 0], GAUSS_POINTS[g, 1], GAUSS_POINTS[g, 2])
        m += rho * N * detJ
    return m


@njit(cache=True)
def lumped_mass(X: np.ndarray, conn: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped mass per dof (3n,) of one block mesh, kg (the mass of ``assemble_block``)."""
    m = np.zeros(3 * X.shape[0])
    xe = np.empty((8, 3))
    for e in range(conn.shape[0]):
        for i in range(8):
            xe[i] = X[conn[e, i]]
        me = element_lumped_mass(xe, rho)
        for i in range(8):
            for d in range(3):
                m[3 * conn[e, i] + d] += me[i]
    return m


@njit(cache=True)
def assemble_block(X: np.ndarray, conn: np.ndarray, C: np.ndarray, rho: float):
    """Dense stiffness (3n, 3n) and lumped mass per dof (3n,) of one block mesh."""
    n = X.shape[0]
    K = np.zeros((3 * n, 3 * n))
    m = np.zeros(3 * n)
    xe = np.empty((8, 3))
    for e in range(conn.shape[0]):
        for i in range(8):
            xe[i] = X[conn[e, i]]
        Ke = element_stiffness(xe, C)
        me = element_lumped_mass(xe, rho)
        for i in range(8):
            for di in range(3):
                I = 3 * conn[e, i] + di
                m[I] += me[i]
                for j in range(8):
                    for dj in range(3):
                        K[I, 3 * conn[e, j] + dj] += Ke[3 * i + di, 3 * j + dj]
    return K, m


@njit(cache=True)
def gauss_strains(X: np.ndarray, conn: np.ndarray, u: np.ndarray, eps: np.ndarray) -> None:
    """Strains (nel * 8, 6) at the Gauss points from nodal displacements u (3n,)."""
    ue = np.empty(24)
    xe = np.empty((8, 3))
    for e in range(conn.shape[0]):
        for i in range(8):
            xe[i] = X[conn[e, i]]
            for d in range(3):
                ue[3 * i + d] = u[3 * conn[e, i] + d]
        Bs, _ = element_b_all(xe)
        for g in range(8):
            eps[8 * e + g] = Bs[g] @ ue


@njit(cache=True)
def internal_forces(X: np.ndarray, conn: np.ndarray, sigma: np.ndarray, f: np.ndarray) -> None:
    """Nodal internal forces ``f = sum_e sum_g B^T sigma det J`` (3n,), N, from Gauss stresses."""
    f[:] = 0.0
    xe = np.empty((8, 3))
    for e in range(conn.shape[0]):
        for i in range(8):
            xe[i] = X[conn[e, i]]
        Bs, w = element_b_all(xe)
        fe = np.zeros(24)
        for g in range(8):
            fe += w[g] * (Bs[g].T @ sigma[8 * e + g])
        for i in range(8):
            for d in range(3):
                f[3 * conn[e, i] + d] += fe[3 * i + d]


@njit(cache=True)
def precompute_b(xe_all: np.ndarray):
    """B matrices (nel, 8, 6, 24) and weights det J (nel, 8) of many elements (nel, 8, 3)."""
    nel = xe_all.shape[0]
    B = np.empty((nel, 8, 6, 24))
    w = np.empty((nel, 8))
    for e in range(nel):
        Bs, we = element_b_all(xe_all[e])
        B[e] = Bs
        w[e] = we
    return B, w


@njit(cache=True)
def strains_from_b(B: np.ndarray, edofs: np.ndarray, u: np.ndarray, eps: np.ndarray) -> None:
    """Gauss-point strains (nel * 8, 6) from global displacements with precomputed B.

    ``edofs`` (nel, 24): the global dofs of each element's nodes (x, y, z per node).
    """
    ue = np.empty(24)
    for e in range(B.shape[0]):
        for i in range(24):
            ue[i] = u[edofs[e, i]]
        for g in range(8):
            for c in range(6):
                s = 0.0
                for i in range(24):
                    s += B[e, g, c, i] * ue[i]
                eps[8 * e + g, c] = s


@njit(cache=True)
def forces_from_b(B: np.ndarray, w: np.ndarray, edofs: np.ndarray, sigma: np.ndarray,
                  f: np.ndarray) -> None:
    """Add ``sum_g w B^T sigma`` of every element to the global force vector f (N)."""
    for e in range(B.shape[0]):
        for g in range(8):
            for i in range(24):
                s = 0.0
                for c in range(6):
                    s += B[e, g, c, i] * sigma[8 * e + g, c]
                f[edofs[e, i]] += w[e, g] * s


@njit(cache=True)
def stiffness_from_b(B: np.ndarray, w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element matrices ``K_e = sum_g w_g B_g^T C_g B_g`` (nel, 24, 24), N/m.

    ``C`` (nel * 8, 6, 6): a material matrix per Gauss point, ``C[p, i, j] = d sigma_i /
    d eps_j`` (Pa), not necessarily symmetric (a consistent tangent).
    """
    nel = B.shape[0]
    K = np.zeros((nel, 24, 24))
    CB = np.empty((6, 24))
    for e in range(nel):
        for g in range(8):
            p = 8 * e + g
            for i in range(6):
                for k in range(24):
                    s = 0.0
                    for j in range(6):
                        s += C[p, i, j] * B[e, g, j, k]
                    CB[i, k] = s
            for a in range(24):
                for k in range(24):
                    s = 0.0
                    for i in range(6):
                        s += B[e, g, i, a] * CB[i, k]
                    K[e, a, k] += w[e, g] * s
    return K


def box_mesh(origin, size, divisions):
    """Structured hexahedral mesh of the box ``[origin, origin + size]`` (m).

    Returns node coordinates X (n, 3) and connectivity conn (nel, 8), nodes numbered with x
    fastest, then y, then z; ``divisions = (nx, ny, nz)`` elements along x, y, z.
    """
    nx, ny, nz = divisions
    xs = [np.linspace(origin[k], origin[k] + size[k], (nx, ny, nz)[k] + 1) for k in range(3)]
    Z, Y, Xc = np.meshgrid(xs[2], xs[1], xs[0], indexing="ij")
    X = np.column_stack([Xc.ravel(), Y.ravel(), Z.ravel()])

    def nid(i, j, k):
        return i + (nx + 1) * (j + (ny + 1) * k)

    conn = []
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                conn.append(
                    [nid(i, j, k), nid(i + 1, j, k), nid(i + 1, j + 1, k), nid(i, j + 1, k),
                     nid(i, j, k + 1), nid(i + 1, j, k + 1), nid(i + 1, j + 1, k + 1),
                     nid(i, j + 1, k + 1)]
                )
    return X, np.asarray(conn, dtype=np.int64)
