r"""Eight-node hexahedra: the element descriptor ``HEX8`` (shape functions, Gauss rule, faces),
and the hexahedron's shortcuts to :mod:`masonry_nscd.fe.element` (stiffness, lumped mass,
strains, forces), and structured box meshes.

What is computed once per block (B matrices, stiffness, mass) is vectorised NumPy over the
elements: compiled with numba its compilation would take most of a first run of a small case,
for work that takes milliseconds. What runs at every step for ENDO3D blocks (``forces_from_gradients``,
``stiffness_from_gradients``, and the strains inside ``materials.blocks.trial_forces``) stays
compiled: plain loops, quick to compile, on the shape functions' gradients rather than the
mostly zero B matrices (:mod:`masonry_nscd.fe.element`, for any element type).

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

from masonry_nscd.fe import element
from masonry_nscd.fe.element import (  # noqa: F401 (the hexahedron's API, as before the descriptor)
    Element,
    b_from_dndx,
    elastic_matrix,
    forces_from_gradients,
    jacobians,
    stiffness_from_gradients,
)

NODE_SIGNS = np.array(
    [
        [-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1],
    ],
    dtype=np.float64,
)
_G = 1.0 / np.sqrt(3.0)
GAUSS_POINTS = NODE_SIGNS * _G  # 2x2x2 rule, unit weights, one point near each node


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


#: Local node numbers of the six faces (VTK order), each ordered counter-clockwise seen from
#: outside: x-min, x-max, y-min, y-max, z-min, z-max.
FACES = np.array([[0, 4, 7, 3], [1, 2, 6, 5], [0, 1, 5, 4], [3, 7, 6, 2], [0, 3, 2, 1],
                  [4, 5, 6, 7]], dtype=np.int64)
EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4], [0, 4],
                  [1, 5], [2, 6], [3, 7]], dtype=np.int64)

#: The 3x3x3 Gauss rule (points, weights): exact for polynomials of degree 5 in each reference
#: coordinate, so for the mass, first and second moments of any trilinear hexahedron (its
#: ``det J`` is of degree 2 in each, ``x x^T det J`` of degree 4): a hexahedron with flat faces is
#: the trilinear image of the cube, so a rigid block's mass, centre and inertia are exact
_G3, _W3 = np.polynomial.legendre.leggauss(3)
MASS_POINTS = np.array([[a, b, c] for a in _G3 for b in _G3 for c in _G3])
MASS_WEIGHTS = np.array([a * b * c for a in _W3 for b in _W3 for c in _W3])

#: The 8-node hexahedron: 2x2x2 Gauss rule of unit weights, row-sum lumped mass, VTK type 12
HEX8 = Element(name="hex8", nodes=8, gauss_points=GAUSS_POINTS, gauss_weights=np.ones(8),
               shape_at=shape_at, faces=FACES, face_corners=4, corners=NODE_SIGNS,
               edges=EDGES, vtk_type=12, meshio_type="hexahedron",
               drawn_as=np.arange(8), mass_rule=(MASS_POINTS, MASS_WEIGHTS))

_N_GAUSS, _DN_GAUSS = shape_at(GAUSS_POINTS)
_b_from_dndx = b_from_dndx


def b_matrix(xe: np.ndarray, xi: float, eta: float, zeta: float):
    """Strain-displacement matrix B (6, 24) and det J at a reference point of element ``xe``."""
    _, dN = shape_at(np.array([[xi, eta, zeta]]))
    J = jacobians(np.asarray(xe, dtype=float)[None], dN)[0, 0]
    return b_from_dndx(dN[0] @ np.linalg.inv(J)), float(np.linalg.det(J))


def precompute_gradients(xe_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients ``dN/dx`` (nel, 8, 8, 3) and weights det J (nel, 8) of many
    hexahedra (nel, 8, 3): :func:`masonry_nscd.fe.element.precompute_gradients`."""
    return element.precompute_gradients(xe_all, HEX8)


def precompute_b(xe_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B matrices (nel, 8, 6, 24) and weights det J (nel, 8) of many hexahedra."""
    return element.precompute_b(xe_all, HEX8)


def element_b_all(xe: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """B matrices (8, 6, 24) and integration weights det J (8,) at the 8 Gauss points."""
    B, w = precompute_b(np.asarray(xe, dtype=float)[None])
    return B[0], w[0]


def element_stiffness(xe: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Element stiffness ``K_e = sum_g B^T C B det J`` (24, 24), N/m."""
    B, w = element_b_all(xe)
    return np.einsum("g,gia,ij,gjb->ab", w, B, C, B, optimize=True)


def element_lumped_mass(xe: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped nodal masses (8,), kg: ``m_i = sum_g rho N_i det J``."""
    return element.element_masses(element_b_all(xe)[1][None], rho, HEX8)[0]


def lumped_mass(X: np.ndarray, conn: np.ndarray, rho: float) -> np.ndarray:
    """Row-sum lumped mass per dof (3n,) of one hexahedral mesh, kg."""
    return element.lumped_mass(X, conn, rho, HEX8)


def assemble_block(X: np.ndarray, conn: np.ndarray, C: np.ndarray, rho: float):
    """Dense stiffness (3n, 3n) and lumped mass per dof (3n,) of one hexahedral mesh."""
    return element.assemble_block(X, conn, C, rho, HEX8)


def gauss_strains(X: np.ndarray, conn: np.ndarray, u: np.ndarray, eps: np.ndarray) -> None:
    """Strains (nel * 8, 6) at the Gauss points from nodal displacements u (3n,)."""
    element.gauss_strains(X, conn, u, eps, HEX8)


def mean_stress_map(X: np.ndarray, conn: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The mean stress over the 8 Gauss points of each hexahedron (Pa) as a map of the nodal
    displacements: :func:`masonry_nscd.fe.element.mean_stress_map`."""
    return element.mean_stress_map(X, conn, C, HEX8)


def internal_forces(X: np.ndarray, conn: np.ndarray, sigma: np.ndarray, f: np.ndarray) -> None:
    """Nodal internal forces ``f = sum_e sum_g B^T sigma det J`` (3n,), N, from Gauss stresses."""
    element.internal_forces(X, conn, sigma, f, HEX8)


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
