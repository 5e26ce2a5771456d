r"""Pack bodies and contact points into the flat arrays of the NSCD kernels.

For each body the iteration matrix of the theta-method is

    M_hat = M + (theta h)^2 K          (kg; K the elastic tangent of a block, 0 for rigid bodies)

and its inverse is stored densely per body (blocks have a few tens of dofs). Imposed dofs of a
rigid body get zero rows and columns in ``M_hat^-1`` (the inverse of its free block):
impulses do not change their velocity.

For each contact point ``a`` and each of its two sides (body B) the kernels use

    H_aB   (k, 3)         local relative velocity U_a = sum_B H_aB^T v_B   (sparse: k dofs)
    Y_aB = M_hat_B^-1 H_aB (ndof_B, 3)  velocity change of body B per unit local impulse
    W_aa = sum_B H_aB^T Y_aB  (3, 3)     diagonal block of the Delassus operator (1/kg)

so that a change ``dr`` of the local impulse of ``a`` changes the velocities of its bodies by
``Y_aB dr`` and nothing else. The Delassus operator is never assembled beyond its diagonal
blocks: the off-diagonal coupling is carried by the body velocities (cost per point and sweep
~ 2 ndof_B, memory linear in the number of points).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from masonry_nscd.fe import hex8
from masonry_nscd.model import DOF_IMPOSED, Block, ContactPoint, RigidBody
from masonry_nscd.nscd.block_diagonal import BlockDiagonal, grouped_offsets

MAX_SIDE_DOFS = 12


@dataclass
class System:
    """Flat arrays shared by the kernels (read-only during a step)."""

    ndof: int
    body_dof0: np.ndarray  # (nb + 1,)
    body_deformable: np.ndarray  # (nb,) bool
    minv_off: np.ndarray  # (nb,) offsets into minv (the blocks grouped by size)
    minv: np.ndarray  # flat, dense M_hat^-1 per body (row-major)
    mhat: np.ndarray  # flat, dense M_hat per body (same offsets as minv)
    k_off: np.ndarray  # (nb,) offsets into k (-1 for rigid bodies)
    k: np.ndarray  # flat, dense K per deformable block
    mass: np.ndarray  # (ndof,) lumped mass (translations kg, rotations kg m^2)
    imposed_dofs: np.ndarray  # (ni,)
    # contact points
    kind: np.ndarray  # (npt,)
    law: np.ndarray  # (npt,)
    area: np.ndarray  # (npt,) m^2
    frame: np.ndarray  # (npt, 3, 3)
    side_dofs: np.ndarray  # (npt, 2, 12), -1 padded
    side_coef: np.ndarray  # (npt, 2, 12, 3)
    side_body: np.ndarray  # (npt, 2), -1 for none
    y_off: np.ndarray  # (npt, 2) offsets into y, -1 where the side cannot move
    y: np.ndarray  # flat Y_aB blocks (ndof_B, 3)
    W: np.ndarray  # (npt, 3, 3)
    h: float
    theta: float

    def __post_init__(self):
        # the products by M_hat^-1 and K of the free velocity and the internal forces (views
        # of the flat arrays above); the Newton solver makes its own by the M_hat it is given
        self.minv_op = BlockDiagonal(self.body_dof0, self.minv_off, self.minv)
        self.k_op = BlockDiagonal(self.body_dof0, self.k_off, self.k)

    @property
    def npt(self) -> int:
        return len(self.area)


def body_matrices(body, h: float, theta: float, with_mhat: bool = False):
    """Stiffness K (or None), lumped mass per dof, and M_hat^-1 (and M_hat) of one body."""
    if isinstance(body, Block):
        C = hex8.elastic_matrix(body.E, body.nu)
        K, m = hex8.assemble_block(body.X, body.conn, C, body.density)
        Mhat = np.diag(m) + (theta * h) ** 2 * K
        out = K, m, np.linalg.inv(Mhat)
    else:
        assert isinstance(body, RigidBody)
        Mhat = body.mass_matrix()
        m = np.diag(Mhat).copy()
        free = body.dof_mode != DOF_IMPOSED
        minv = np.zeros((6, 6))
        if np.count_nonzero(Mhat - np.diag(m)):  # reference point off the centre of mass
            minv[np.ix_(free, free)] = np.linalg.inv(Mhat[np.ix_(free, free)])
        else:
            minv[free, free] = 1.0 / m[free]
        out = None, m, minv
    return (*out, Mhat) if with_mhat else out


def build_system(bodies, points: list[ContactPoint], h: float, theta: float) -> System:
    """Number the dofs, factor each body and precompute the Delassus blocks."""
    nb = len(bodies)
    body_dof0 = np.zeros(nb + 1, dtype=np.int64)
    for i, b in enumerate(bodies):
        body_dof0[i + 1] = body_dof0[i] + b.ndof
    ndof = int(body_dof0[-1])
    sizes = np.diff(body_dof0)
    deformable = np.array([isinstance(b, Block) for b in bodies], dtype=bool)
    # the blocks of one size one after the other (block_diagonal.grouped_offsets)
    minv_off = grouped_offsets(sizes)
    k_off = grouped_offsets(sizes, deformable)
    minv = np.zeros(int(np.sum(sizes ** 2)))
    mhat_flat = np.zeros_like(minv)
    k = np.zeros(int(np.sum(sizes[deformable] ** 2)))
    mass = np.zeros(ndof)
    imposed = []
    for i, b in enumerate(bodies):
        K, m, minv_b, mhat_b = body_matrices(b, h, theta, with_mhat=True)
        o, n2 = minv_off[i], minv_b.size
        mhat_flat[o:o + n2] = mhat_b.ravel()
        minv[o:o + n2] = minv_b.ravel()
        mass[body_dof0[i]:body_dof0[i + 1]] = m
        if K is not None:
            k[k_off[i]:k_off[i] + K.size] = K.ravel()
        if isinstance(b, RigidBody):
            imposed += [body_dof0[i] + d for d in range(6) if b.dof_mode[d] == DOF_IMPOSED]
    npt = len(points)
    side_dofs = np.full((npt, 2, MAX_SIDE_DOFS), -1, dtype=np.int64)
    side_coef = np.zeros((npt, 2, MAX_SIDE_DOFS, 3))
    side_body = np.full((npt, 2), -1, dtype=np.int64)
    y_off = np.full((npt, 2), -1, dtype=np.int64)
    W = np.zeros((npt, 3, 3))
    ys = []
    yo = 0
    for a, p in enumerate(points):
        for s, ((dofs, coef), bi) in enumerate(zip(p.sides, p.bodies)):
            n = len(dofs)
            side_dofs[a, s, :n] = dofs
            side_coef[a, s, :n] = coef
            side_body[a, s] = bi
            d0, d1 = body_dof0[bi], body_dof0[bi + 1]
            nB = d1 - d0
            o = minv_off[bi]
            H = np.zeros((nB, 3))
            H[dofs - d0] = coef
            Y = minv[o:o + nB * nB].reshape(nB, nB) @ H
            if not np.any(Y):
                continue  # a fixed body: impulses do not move it
            y_off[a, s] = yo
            yo += Y.size
            ys.append(Y.ravel())
            W[a] += H.T @ Y
    # A direction along which no free body can move (an imposed dof of a rigid body, say) has a
    # zero row in W_aa: the relative motion there is kinematic and the point carries no traction
    # in it. Give it a finite compliance in the local problem (the predictor along it is zero,
    # so the traction comes out zero); the velocity maps Y are untouched.
    for a in range(npt):
        dmax = np.abs(np.diag(W[a])).max()
        for i in range(3):
            if W[a, i, i] <= 1e-12 * dmax:
                W[a, i, :] = 0.0
                W[a, :, i] = 0.0
                W[a, i, i] = dmax if dmax > 0 else 1.0
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros(0)
    return System(
        ndof=ndof, body_dof0=body_dof0,
        body_deformable=deformable,
        minv_off=minv_off, minv=minv, mhat=mhat_flat, k_off=k_off, k=k, mass=mass,
        imposed_dofs=np.array(imposed, dtype=np.int64),
        kind=np.array([p.kind for p in points], dtype=np.int64),
        law=np.array([p.law for p in points], dtype=np.int64),
        area=np.array([p.area for p in points], dtype=float),
        frame=np.array([p.frame for p in points], dtype=float).reshape(npt, 3, 3),
        side_dofs=side_dofs, side_coef=side_coef, side_body=side_body, y_off=y_off,
        y=cat(ys), W=W, h=h, theta=theta,
    )
