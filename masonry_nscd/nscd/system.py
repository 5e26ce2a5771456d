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

What does not depend on h (the numbering, the blocks' K and masses, the points' sides) is a
:class:`DofLayout`, made once per scene and shared by the systems of the adaptive step's sizes
and of the halved steps, so that a new step size builds only what depends on h.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from masonry_nscd.fe import element as solid
from masonry_nscd.model import DOF_IMPOSED, Block, ContactPoint, RigidBody
from masonry_nscd.nscd.block_diagonal import BlockDiagonal, grouped_offsets

#: The dofs of a side of a contact point: 12 for a bilinear face (4 nodes) or a rigid body (6);
#: a point on a six-node triangle (a 10-node tetrahedron's face) widens the arrays to 18
MAX_SIDE_DOFS = 12


@dataclass
class DofLayout:
    """What the systems of one scene share whatever their step: the dofs' numbering, each
    block's stiffness ``K`` (N/m) and every body's lumped mass, the contact points' sides. The
    integrators of the adaptive step's sizes and of the halved steps build their
    :class:`System` from one layout (:func:`build_system`; a system is a layout too)."""

    bodies: list
    ndof: int
    body_dof0: np.ndarray  # (nb + 1,)
    body_deformable: np.ndarray  # (nb,) bool
    minv_off: np.ndarray  # (nb,) offsets of the bodies' dense blocks (grouped by size)
    k_off: np.ndarray  # (nb,) offsets into k (-1 for rigid bodies)
    k: np.ndarray  # flat, dense K per deformable block (N/m)
    mass: np.ndarray  # (ndof,) lumped mass (translations kg, rotations kg m^2)
    imposed_dofs: np.ndarray  # (ni,)
    # contact points
    kind: np.ndarray  # (npt,)
    law: np.ndarray  # (npt,)
    area: np.ndarray  # (npt,) m^2
    frame: np.ndarray  # (npt, 3, 3)
    side_dofs: np.ndarray  # (npt, 2, MAX_SIDE_DOFS or more), -1 padded
    side_coef: np.ndarray  # (npt, 2, MAX_SIDE_DOFS or more, 3)
    side_body: np.ndarray  # (npt, 2), -1 for none

    @property
    def npt(self) -> int:
        return len(self.area)

    @classmethod
    def of(cls, bodies, points: list[ContactPoint]) -> DofLayout:
        nb = len(bodies)
        body_dof0 = np.zeros(nb + 1, dtype=np.int64)
        for i, b in enumerate(bodies):
            body_dof0[i + 1] = body_dof0[i] + b.ndof
        sizes = np.diff(body_dof0)
        deformable = np.array([isinstance(b, Block) for b in bodies], dtype=bool)
        # the blocks of one size one after the other (block_diagonal.grouped_offsets)
        minv_off = grouped_offsets(sizes)
        k_off = grouped_offsets(sizes, deformable)
        k = np.zeros(int(np.sum(sizes[deformable] ** 2)))
        mass = np.zeros(int(body_dof0[-1]))
        imposed = []
        for i, b in enumerate(bodies):
            if isinstance(b, Block):
                K, m = solid.assemble_block(b.X, b.conn, solid.elastic_matrix(b.E, b.nu),
                                            b.density, b.element)
                k[k_off[i]:k_off[i] + K.size] = K.ravel()
            else:
                assert isinstance(b, RigidBody)
                m = np.diag(b.mass_matrix()).copy()
                imposed += [body_dof0[i] + d for d in range(6) if b.dof_mode[d] == DOF_IMPOSED]
            mass[body_dof0[i]:body_dof0[i + 1]] = m
        npt = len(points)
        width = max([MAX_SIDE_DOFS] + [len(d) for p in points for d, _ in p.sides])
        side_dofs = np.full((npt, 2, width), -1, dtype=np.int64)
        side_coef = np.zeros((npt, 2, width, 3))
        side_body = np.full((npt, 2), -1, dtype=np.int64)
        for a, p in enumerate(points):
            for s, ((dofs, coef), bi) in enumerate(zip(p.sides, p.bodies)):
                side_dofs[a, s, :len(dofs)] = dofs
                side_coef[a, s, :len(dofs)] = coef
                side_body[a, s] = bi
        return cls(bodies=bodies, ndof=int(body_dof0[-1]), body_dof0=body_dof0,
                   body_deformable=deformable, minv_off=minv_off, k_off=k_off, k=k, mass=mass,
                   imposed_dofs=np.array(imposed, dtype=np.int64),
                   kind=np.array([p.kind for p in points], dtype=np.int64),
                   law=np.array([p.law for p in points], dtype=np.int64),
                   area=np.array([p.area for p in points], dtype=float),
                   frame=np.array([p.frame for p in points], dtype=float).reshape(npt, 3, 3),
                   side_dofs=side_dofs, side_coef=side_coef, side_body=side_body)


@dataclass
class System(DofLayout):
    """A layout and what steps of ``h`` add to it: flat arrays shared by the kernels
    (read-only during a step)."""

    minv: np.ndarray | None  # flat, dense M_hat^-1 per body (row-major, at minv_off)
    mhat: np.ndarray | None  # flat, dense M_hat per body (same offsets as minv); both None
    # while released (``release``)
    W: np.ndarray  # (npt, 3, 3)
    h: float
    theta: float

    def __post_init__(self):
        # the products by M_hat^-1 and K of the free velocity and the internal forces (views
        # of the flat arrays above); the Newton solver makes its own by the M_hat it is given
        self.minv_op = BlockDiagonal(self.body_dof0, self.minv_off, self.minv)
        self.k_op = BlockDiagonal(self.body_dof0, self.k_off, self.k)
        self._velocity_maps: tuple[np.ndarray, np.ndarray] | None = None

    def release(self) -> None:
        """Let go of ``M_hat``, ``M_hat^-1`` and the velocity maps (two dense blocks per body:
        3 kB per contact point on the study's walls) while the run steps with another step
        size; :meth:`restore` makes them again."""
        self.minv = self.mhat = self.minv_op = None
        self._velocity_maps = None

    @property
    def released(self) -> bool:
        return self.minv is None

    def restore(self) -> None:
        """Make again what :meth:`release` let go of (``body_blocks``: the same bits)."""
        if self.minv is None:
            self.mhat, self.minv = body_blocks(self, self.h, self.theta)
            self.minv_op = BlockDiagonal(self.body_dof0, self.minv_off, self.minv)

    def velocity_maps(self) -> tuple[np.ndarray, np.ndarray]:
        """``(y_off, y)``: the blocks ``Y_aB`` (ndof_B, 3) of every side that can move, laid
        end to end in the order of the points and their sides (``y``, flat), and each side's
        offset into ``y`` (``y_off``, (npt, 2), -1 where the side cannot move).

        Only the Gauss-Seidel sweeps use them (``kernels.nlgs``): made at the first call and
        kept, so that a system stepped by Newton alone never holds them (6 ndof_B floats per
        point and side: 2.6 kB per point on the study's walls, for each step size)."""
        if self._velocity_maps is None:
            npt = len(self.area)
            sizes = np.diff(self.body_dof0)
            maps = list(_side_maps(self, self.minv))
            moving = np.zeros((npt, 2), dtype=bool)
            for a, s, Y in maps:
                moving[a, s] = True
            y_size = np.where(moving, 3 * sizes[np.maximum(self.side_body, 0)], 0)
            y_off = np.where(moving, np.cumsum(y_size.ravel()).reshape(npt, 2) - y_size, -1)
            y = np.empty(int(y_size.sum()))
            for a, s, Y in maps:
                if len(a):
                    y[y_off[a, s][:, None] + np.arange(Y[0].size)] = Y.reshape(len(a), -1)
            self._velocity_maps = (y_off, y)
        return self._velocity_maps


def _rigid_inverse(body: RigidBody) -> tuple[np.ndarray, np.ndarray]:
    """``(M_hat, M_hat^-1)`` of a rigid body (6, 6): its mass matrix, and the inverse of its
    free block with zero rows and columns at the imposed dofs."""
    Mhat = body.mass_matrix()
    m = np.diag(Mhat)
    free = body.dof_mode != DOF_IMPOSED
    if not (np.all(m[free] > 0.0) and np.isfinite(Mhat).all()):
        # a free dof without mass: its row of M_hat^-1 (and the Delassus blocks W of its
        # contact points, which both solvers divide by) would be a division by zero
        raise ValueError(
            f"body {body.name or '(unnamed)'!r}: mass {body.mass:.6g} kg, inertia diagonal "
            f"{', '.join(f'{v:.6g}' for v in np.diag(body.inertia))} kg m^2; a free rigid "
            "body needs a positive mass and inertia (a block of zero volume or density?)")
    minv = np.zeros((6, 6))
    if np.count_nonzero(Mhat - np.diag(m)):  # reference point off the centre of mass
        minv[np.ix_(free, free)] = np.linalg.inv(Mhat[np.ix_(free, free)])
    else:
        minv[free, free] = 1.0 / m[free]
    return Mhat, minv


def body_blocks(lay: DofLayout, h: float, theta: float) -> tuple[np.ndarray, np.ndarray]:
    """``(M_hat, M_hat^-1)`` of every body for steps of ``h``, flat at ``lay.minv_off``: the
    blocks' ``M_hat = diag(m) + (theta h)^2 K`` inverted by size group (numpy's stacked
    LAPACK call, the same per block whatever the batch), a rigid body's its mass matrix and
    the inverse of its free block (``_rigid_inverse``). The same bits at every call."""
    body_dof0, sizes = lay.body_dof0, np.diff(lay.body_dof0)
    minv_off = lay.minv_off
    minv = np.zeros(int(np.sum(sizes ** 2)))
    mhat_flat = np.zeros_like(minv)
    c = (theta * h) ** 2
    # the blocks' M_hat = diag(m) + (theta h)^2 K, inverted by size group
    for n in np.unique(sizes[lay.body_deformable]):
        group = np.flatnonzero(lay.body_deformable & (sizes == n))
        o0 = minv_off[group[0]]
        ko = lay.k_off[group[0]]
        Mhat = c * lay.k[ko:ko + len(group) * n * n].reshape(len(group), n, n)
        dofs = body_dof0[group][:, None] + np.arange(n)
        Mhat[:, np.arange(n), np.arange(n)] += lay.mass[dofs]
        mhat_flat[o0:o0 + Mhat.size] = Mhat.ravel()
        minv[o0:o0 + Mhat.size] = np.linalg.inv(Mhat).ravel()
    for i in np.flatnonzero(~lay.body_deformable):
        Mhat, minv_b = _rigid_inverse(lay.bodies[i])
        mhat_flat[minv_off[i]:minv_off[i] + 36] = Mhat.ravel()
        minv[minv_off[i]:minv_off[i] + 36] = minv_b.ravel()
    return mhat_flat, minv


def build_system(bodies, points: list[ContactPoint], h: float, theta: float,
                 layout: DofLayout | None = None) -> System:
    """The system of steps ``h``: each body's ``M_hat`` and its inverse, and the Delassus
    blocks of the contact points (module docstring), from ``layout`` (made from ``bodies``
    and ``points`` when None; another step's system will do). The products are those of a
    body and a point at a time, batched per body (numpy's stacked LAPACK and BLAS calls, the
    same per block)."""
    lay = DofLayout.of(bodies, points) if layout is None else layout
    mhat_flat, minv = body_blocks(lay, h, theta)
    # W_aa = sum of H^T Y over the point's sides, Y = M_hat^-1 H made body by body and let go
    # (``System.velocity_maps`` makes them again for the Gauss-Seidel sweeps)
    npt = len(lay.area)
    W = np.zeros((npt, 3, 3))
    HtY_of = [(a, s, np.matmul(H.transpose(0, 2, 1), Y))
              for a, s, Y, H in _side_maps(lay, minv, with_h=True)]
    for side in (0, 1):  # W = (0 + side 0) + side 1, as the sum point by point
        for a, s, HtY in HtY_of:
            on = s == side
            W[a[on]] += HtY[on]
    del HtY_of
    # A direction along which no free body can move (an imposed dof of a rigid body, say) has a
    # zero row in W_aa: the relative motion there is kinematic and the point carries no traction
    # in it. Give it a finite compliance in the local problem (the predictor along it is zero,
    # so the traction comes out zero); the velocity maps Y are untouched.
    dmax = np.abs(np.diagonal(W, axis1=1, axis2=2)).max(axis=1) if npt else np.zeros(0)
    for i in range(3):
        stuck = np.flatnonzero(W[:, i, i] <= 1e-12 * dmax)
        W[stuck, i, :] = 0.0
        W[stuck, :, i] = 0.0
        W[stuck, i, i] = np.where(dmax[stuck] > 0, dmax[stuck], 1.0)
    return System(**{f.name: getattr(lay, f.name) for f in fields(DofLayout)}, minv=minv,
                  mhat=mhat_flat, W=W, h=h, theta=theta)


def _side_maps(lay: DofLayout, minv: np.ndarray, with_h: bool = False):
    """Per body that a contact point's side lies on (in increasing order), the sides that can
    move: their points ``a`` and sides ``s`` and ``Y = M_hat^-1 H`` of each ``(k, n_B, 3)``
    (``with_h``: and their ``H``, the same shape), one body at a time. A fixed body (impulses
    do not move it, ``Y = 0``) gives no side."""
    body_dof0, sizes, minv_off = lay.body_dof0, np.diff(lay.body_dof0), lay.minv_off
    side_body = lay.side_body
    for b in np.unique(side_body[side_body >= 0]):
        a, s = np.nonzero(side_body == b)
        d0, nB = body_dof0[b], sizes[b]
        H = np.zeros((len(a), nB, 3))
        sd = lay.side_dofs[a, s]
        i, j = np.nonzero(sd >= 0)
        H[i, sd[i, j] - d0] = lay.side_coef[a, s][i, j]
        Y = np.matmul(minv[minv_off[b]:minv_off[b] + nB * nB].reshape(nB, nB), H)
        nz = np.any(Y, axis=(1, 2))  # a fixed body: impulses do not move it
        if with_h:
            yield a[nz], s[nz], Y[nz], H[nz]
        else:
            yield a[nz], s[nz], Y[nz]
