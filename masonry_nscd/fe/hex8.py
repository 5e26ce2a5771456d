r"""Eight-node hexahedra: shape functions, Gauss rules, stiffness, lumped mass, strains, forces.

What is computed once per block (B matrices, stiffness, mass) is vectorised NumPy over the
elements: compiled with numba it cost 8 of the 14 s of a first run of the smoke case, for work
that takes milliseconds. What runs at every step for ENDO3D blocks (``forces_from_gradients``,
``stiffness_from_gradients``, and the strains inside ``materials.blocks.trial_forces``) stays
compiled: plain loops, quick to compile, on the shape functions' gradients rather than the
mostly zero B matrices.

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


def shape_at(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (ng, 8) and their derivatives dN/dxi (ng, 8, 3) at reference points
    ``points`` (ng, 3)::

        N_i = (1 + xi xi_i)(1 + eta eta_i)(1 + zeta zeta_i) / 8
    """
    p = np.atleast_2d(np.asarray(points, dtype=float))
    f = 1.0 + p[:, None, :] * NODE_SIGNS[None, :, :]  # (ng, 8, 3): the three factors
    N = 0.125 * f.prod(axis=2)
    dN = np.empty((len(p), 8, 3))
    dN[..., 0] = 0.125 * NODE_SIGNS[:, 0] * f[..., 1] * f[..., 2]
    dN[..., 1] = 0.125 * NODE_SIGNS[:, 1] * f[..., 0] * f[..., 2]
    dN[..., 2] = 0.125 * NODE_SIGNS[:, 2] * f[..., 0] * f[..., 1]
    return N, dN


def shape(xi: float, eta: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions N (8,) and their derivatives dN/dxi (8, 3) at one reference point."""
    N, dN = shape_at(np.array([[xi, eta, zeta]]))
    return N[0], dN[0]


_N_GAUSS, _DN_GAUSS = shape_at(GAUSS_POINTS)


def _b_from_dndx(dNdx: np.ndarray) -> np.ndarray:
    """Strain-displacement matrices (..., 6, 24) from the shape-function gradients (..., 8, 3):
    ``eps = B u`` with u ordered (x, y, z) per node, Voigt order, engineering shears."""
    B = np.zeros((*dNdx.shape[:-2], 6, 24))
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


def _jacobians(xe_all: np.ndarray, dN: np.ndarray) -> np.ndarray:
    """``J[e, g, i, k] = dx_i / dxi_k = sum_a x[e, a, i] dN[g, a, k]`` (nel, ng, 3, 3)."""
    return np.einsum("eai,gak->egik", xe_all, dN)


def b_matrix(xe: np.ndarray, xi: float, eta: float, zeta: float):
    """Strain-displacement matrix B (6, 24) and det J at a reference point of element ``xe``."""
    _, dN = shape_at(np.array([[xi, eta, zeta]]))
    J = _jacobians(np.asarray(xe, dtype=float)[None], dN)[0, 0]
    return _b_from_dndx(dN[0] @ np.linalg.inv(J)), float(np.linalg.det(J))


def precompute_gradients(xe_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients ``dN/dx`` (nel, 8, 8, 3; Gauss point, node, direction; 1/m)
    and weights det J (nel, 8) at the 2x2x2 Gauss points of many elements (nel, 8, 3):
    ``dN/dx = dN/dxi J^-1``, unit Gauss weights. Raises ValueError for an element with a
    non-positive Jacobian (an inverted element)."""
    xe_all = np.asarray(xe_all, dtype=float)
    J = _jacobians(xe_all, _DN_GAUSS)
    w = np.linalg.det(J)
    if np.any(w <= 0.0):
        raise ValueError("hexahedron with a non-positive Jacobian (inverted element)")
    return np.einsum("gak,egkj->egaj", _DN_GAUSS, np.linalg.inv(J)), w


def precompute_b(xe_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B matrices (nel, 8, 6, 24) and weights det J (nel, 8) at the 2x2x2 Gauss points of many
    elements (nel, 8, 3), from :func:`precompute_gradients`."""
    dNdx, w = precompute_gradients(xe_all)
    return _b_from_dndx(dNdx), w


def element_b_all(xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B matrices (8, 6, 24) and integration weights det J (8,) at the 8 Gauss points."""
    B, w = precompute_b(np.asarray(xe, dtype=float)[None])
    return B[0], w[0]


def element_stiffness(xe: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element stiffness ``K_e = sum_g B^T C B det J`` (24, 24), N/m."""
    B, w = element_b_all(xe)
    return np.einsum("g,gia,ij,gjb->ab", w, B, C, B, optimize=True)


def _element_masses(w: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped nodal masses (nel, 8), kg: ``m_a = sum_g rho N_a(g) det J(g)``."""
    return rho * w @ _N_GAUSS


def element_lumped_mass(xe: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped nodal masses (8,), kg: ``m_i = sum_g rho N_i det J``."""
    return _element_masses(element_b_all(xe)[1][None], rho)[0]


def _element_dofs(conn: np.ndarray) -> np.ndarray:
    """The dofs of each element's nodes (nel, 24), x, y, z per node."""
    return (3 * np.asarray(conn, dtype=np.int64)[:, :, None] + np.arange(3)).reshape(-1, 24)


def lumped_mass(X: np.ndarray, conn: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped mass per dof (3n,) of one block mesh, kg (the mass of ``assemble_block``)."""
    _, w = precompute_gradients(np.asarray(X, dtype=float)[conn])
    m = np.zeros(3 * X.shape[0])
    np.add.at(m, _element_dofs(conn), np.repeat(_element_masses(w, rho), 3, axis=1))
    return m


def assemble_block(X: np.ndarray, conn: np.ndarray, C: np.ndarray, rho: float):
    """Dense stiffness (3n, 3n) and lumped mass per dof (3n,) of one block mesh."""
    B, w = precompute_b(np.asarray(X, dtype=float)[conn])
    Ke = np.einsum("eg,egia,ij,egjb->eab", w, B, C, B, optimize=True)
    edofs = _element_dofs(conn)
    n = 3 * X.shape[0]
    K = np.zeros((n, n))
    np.add.at(K, (edofs[:, :, None], edofs[:, None, :]), Ke)
    m = np.zeros(n)
    np.add.at(m, edofs, np.repeat(_element_masses(w, rho), 3, axis=1))
    return K, m


def gauss_strains(X: np.ndarray, conn: np.ndarray, u: np.ndarray, eps: np.ndarray) -> None:
    """Strains (nel * 8, 6) at the Gauss points from nodal displacements u (3n,)."""
    B, _ = precompute_b(np.asarray(X, dtype=float)[conn])
    ue = np.asarray(u)[_element_dofs(conn)]  # (nel, 24)
    eps[:] = np.einsum("egij,ej->egi", B, ue).reshape(-1, 6)


def mean_stress_map(X: np.ndarray, conn: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``S`` (6 nel, 3n): the mean stress over the 8 Gauss points of each element (Pa, rows
    element by element in Voigt order) from the nodal displacements u (3n,) of a linear block,
    ``sigma_e = C (1/8 sum_g B_eg) u_e``."""
    B, _ = precompute_b(np.asarray(X, dtype=float)[conn])
    Se = C @ B.mean(axis=1)  # (nel, 6, 24)
    S = np.zeros((len(conn), 6, 3 * len(X)))
    edofs = _element_dofs(conn)
    for e in range(len(conn)):
        S[e][:, edofs[e]] += Se[e]
    return S.reshape(-1, 3 * len(X))


def internal_forces(X: np.ndarray, conn: np.ndarray, sigma: np.ndarray, f: np.ndarray) -> None:
    """Nodal internal forces ``f = sum_e sum_g B^T sigma det J`` (3n,), N, from Gauss stresses."""
    B, w = precompute_b(np.asarray(X, dtype=float)[conn])
    fe = np.einsum("eg,egij,egi->ej", w, B, np.asarray(sigma).reshape(len(conn), 8, 6))
    f[:] = 0.0
    np.add.at(f, _element_dofs(conn), fe)


@njit(cache=True)
def forces_from_gradients(dN: np.ndarray, w: np.ndarray, edofs: np.ndarray,
                          sigma: np.ndarray, f: np.ndarray) -> None:
    """Add ``sum_g w B^T sigma`` of every element to the global force vector f (N), ``B``
    given by the gradients that fill it, ``dN[e, g, a] = dN_a/dx`` (1/m, (nel, 8, 8, 3);
    :func:`precompute_gradients`): its nonzero terms in the order of its rows, so that the
    sums are the dense product's term for term."""
    for e in range(dN.shape[0]):
        for g in range(8):
            s = sigma[8 * e + g]
            wg = w[e, g]
            for a in range(8):
                gx = dN[e, g, a, 0]
                gy = dN[e, g, a, 1]
                gz = dN[e, g, a, 2]
                f[edofs[e, 3 * a]] += wg * (gx * s[0] + gz * s[4] + gy * s[5])
                f[edofs[e, 3 * a + 1]] += wg * (gy * s[1] + gz * s[3] + gx * s[5])
                f[edofs[e, 3 * a + 2]] += wg * (gz * s[2] + gy * s[3] + gx * s[4])


@njit(cache=True)
def stiffness_from_gradients(dN: np.ndarray, w: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element matrices ``K_e = sum_g w_g B_g^T C_g B_g`` (nel, 24, 24), N/m, ``B`` given by
    its gradients as in :func:`forces_from_gradients` (each column of ``B`` has three nonzero
    rows, each row of ``B^T``: ``C B`` and ``B^T (C B)`` take those only, in the order of the
    dense products).

    ``C`` (nel * 8, 6, 6): a material matrix per Gauss point, ``C[p, i, j] = d sigma_i /
    d eps_j`` (Pa), not necessarily symmetric (a consistent tangent).
    """
    nel = dN.shape[0]
    K = np.zeros((nel, 24, 24))
    CB = np.empty((6, 24))
    for e in range(nel):
        for g in range(8):
            p = 8 * e + g
            Cp = C[p]
            for a in range(8):
                gx = dN[e, g, a, 0]
                gy = dN[e, g, a, 1]
                gz = dN[e, g, a, 2]
                for i in range(6):
                    CB[i, 3 * a] = Cp[i, 0] * gx + Cp[i, 4] * gz + Cp[i, 5] * gy
                    CB[i, 3 * a + 1] = Cp[i, 1] * gy + Cp[i, 3] * gz + Cp[i, 5] * gx
                    CB[i, 3 * a + 2] = Cp[i, 2] * gz + Cp[i, 3] * gy + Cp[i, 4] * gx
            wg = w[e, g]
            for b in range(8):
                gx = dN[e, g, b, 0]
                gy = dN[e, g, b, 1]
                gz = dN[e, g, b, 2]
                for k in range(24):
                    K[e, 3 * b, k] += wg * (gx * CB[0, k] + gz * CB[4, k] + gy * CB[5, k])
                    K[e, 3 * b + 1, k] += wg * (gy * CB[1, k] + gz * CB[3, k] + gx * CB[5, k])
                    K[e, 3 * b + 2, k] += wg * (gz * CB[2, k] + gy * CB[3, k] + gx * CB[4, k])
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
