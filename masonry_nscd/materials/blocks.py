r"""ENDO3D in the blocks of a scene: Gauss-point states, internal forces, outputs.

Every deformable block with ``material = MAT_ENDO3D`` carries an ENDO3D state at each Gauss
point of each of its elements (8 per hexahedron, 1 per 4-node and 4 per 10-node tetrahedron:
:mod:`masonry_nscd.fe.catalog`). For a trial displacement ``u`` of the step the strains
are computed at the Gauss points, ENDO3D updates the states from those committed at the end of
the last step (the committed states are never modified by a trial), and the internal forces
are ``F_int = sum_e sum_g B^T sigma w_g det J`` (N): one kernel per element (``trial_forces``),
the elements shared between threads. ``commit`` makes the last trial the state of the step.

In the step, the theta-method's internal-force term is ``theta F_int(u_n+1) + (1 - theta)
F_int(u_n)``; the free velocities hold the elastic part ``K0 (u_n+1 - u_n)``, so the residual
needs the correction

    c(u_n+1) = h theta [ F_int(u_n+1) - F_int(u_n) - K0 (u_n+1 - u_n) ]          (N s)
             = h theta sum_e sum_g B^T [ sigma - sigma_n - C0 (eps - eps_n) ] det J

(``K0 = sum B^T C0 B det J``, the blocks' elastic stiffness), summed element by element with
the forces, which is zero for linear elastic blocks, and the Newton matrix the tangent stiffness
(``tangent_stiffness``: consistent, by differences of the kernel). Blocks that are linear
elastic never call ENDO3D.

**Viscous regularisation** (optional, relaxation time ``tau`` in s, 0 = none): the stress of a
Gauss point relaxes towards the ENDO3D stress (Duvaut-Lions),

    d sigma / dt = C0 d eps / dt - (sigma - sigma_endo3d) / tau,

with the internal variables (damages, plastic strains, crack openings) those of ENDO3D. Over a
step in which ``eps`` and ``sigma_endo3d`` go linearly from their values at the start (``_n``)
to those at the end (``_n+1``), the overstress ``x = sigma - sigma_endo3d`` obeys
``dx/dt = (C0 d eps - d sigma_endo3d) / h - x / tau``, whose exact solution gives, with
``r = h / tau``,

    sigma_n+1 = sigma_endo3d,n+1 + exp(-r) (sigma_n - sigma_endo3d,n)
                + phi (C0 (eps_n+1 - eps_n) - (sigma_endo3d,n+1 - sigma_endo3d,n)),
    phi = (1 - exp(-r)) / r.

An overstress left by a crack that opens within a step decays as ``exp(-t / tau)`` whatever
the step. The implicit Euler rule, ``[sigma_n + C0 d eps + r sigma_endo3d,n+1] / (1 + r)``,
would decay it by ``1 / (1 + r)`` a step, as if ``tau`` were ``h / ln(1 + r)`` (2.5 tau at
``h = 4 tau``), and so move the post-peak events with the step (docs/choices.md); the two
agree on a steady strain rate (overstress ``E tau d eps / dt``).
The tangent becomes ``phi C0 + (1 - phi) C_endo3d``: positive for a softening slope ``-S``
when ``S / E < phi / (1 - phi)`` (``> 1 / r``). Where two Gauss points soften together (the two
layers of a block one element thick, cracking in its plane), a negative tangent lets the
iterations jump between the symmetric solution and the one where one layer cracks alone, and
the step does not converge; the relaxation picks the symmetric one. As ``tau -> 0`` the
rate-independent law returns.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from masonry_nscd import threads, timing
from masonry_nscd.fe import element as solid
from masonry_nscd.materials import endo3d
from masonry_nscd.model import MAT_ENDO3D, Block

_NO_DOFS = np.zeros(0, dtype=np.int64)


@njit(cache=True, nogil=True)
def trial_forces(dN, w, edofs, u, state_in, params, xe, relax, C0, sigma_c, eps_c,
                 sigma_endo_c, eps, state_out, sigma_endo, sigma, f_e, c_e):
    """A trial of the elements of the batch (arrays sliced to them, all of one element type;
    Gauss point ``ng e + g``)
    at the displacements ``u`` (m, every dof): the strains ``eps = B u_e``; the ENDO3D update
    from ``state_in`` (``state_out``, ``sigma_endo``, Pa); the stress ``sigma``, relaxed
    towards ``sigma_endo`` from ``sigma_c`` and the committed ENDO3D stress ``sigma_endo_c`` when
    ``relax = h / tau > 0`` (module docstring) or equal to it;
    the element forces ``f_e = sum_g w B^T sigma`` (N) and their departure from the linear
    forces of the step's start, ``c_e = sum_g w B^T (sigma - sigma_c - C0 (eps - eps_c))``
    (N), both (nel, 3 nodes). Returns the number of points whose return mapping did not
    converge.

    ``B`` is read through the shape functions' gradients ``dN[e, g, a] = dN_a/dx`` (1/m,
    (nel, ng, nodes, 3)) that fill it (``fe.element.b_from_dndx``): its nonzero terms only, in
    the order of its rows and columns, so that the sums are those of the dense product term for
    term.
    """
    nfail = 0
    decay = np.exp(-relax)  # exp(-r) and phi of the module docstring
    phi = -np.expm1(-relax) / relax if relax > 0.0 else 1.0
    wk = np.empty((endo3d.N_WORK, 3, 3))
    ng = dN.shape[1]
    nn = dN.shape[2]
    nd = 3 * nn
    ue = np.empty(nd)
    d = np.empty(6)
    for e in range(dN.shape[0]):
        for i in range(nd):
            ue[i] = u[edofs[e, i]]
            f_e[e, i] = 0.0
            c_e[e, i] = 0.0
        for g in range(ng):
            p = ng * e + g
            G = dN[e, g]
            exx = 0.0
            eyy = 0.0
            ezz = 0.0
            gyz = 0.0
            gxz = 0.0
            gxy = 0.0
            for a in range(nn):
                ux = ue[3 * a]
                uy = ue[3 * a + 1]
                uz = ue[3 * a + 2]
                exx += G[a, 0] * ux
                eyy += G[a, 1] * uy
                ezz += G[a, 2] * uz
                gyz += G[a, 2] * uy
                gyz += G[a, 1] * uz
                gxz += G[a, 2] * ux
                gxz += G[a, 0] * uz
                gxy += G[a, 1] * ux
                gxy += G[a, 0] * uy
            eps[p, 0] = exx
            eps[p, 1] = eyy
            eps[p, 2] = ezz
            eps[p, 3] = gyz
            eps[p, 4] = gxz
            eps[p, 5] = gxy
            if endo3d.update_point(eps[p], state_in[p], params, xe[e], state_out[p],
                                   sigma_endo[p], wk) != 0:
                nfail += 1
            for i in range(6):
                lin = 0.0
                for j in range(6):
                    lin += C0[p, i, j] * (eps[p, j] - eps_c[p, j])
                if relax > 0.0:
                    sigma[p, i] = (sigma_endo[p, i] + decay * (sigma_c[p, i] - sigma_endo_c[p, i])
                                   + phi * (lin - sigma_endo[p, i] + sigma_endo_c[p, i]))
                else:
                    sigma[p, i] = sigma_endo[p, i]
                d[i] = sigma[p, i] - sigma_c[p, i] - lin
            s = sigma[p]
            wg = w[e, g]
            for a in range(nn):
                gx = G[a, 0]
                gy = G[a, 1]
                gz = G[a, 2]
                f_e[e, 3 * a] += wg * (gx * s[0] + gz * s[4] + gy * s[5])
                f_e[e, 3 * a + 1] += wg * (gy * s[1] + gz * s[3] + gx * s[5])
                f_e[e, 3 * a + 2] += wg * (gz * s[2] + gy * s[3] + gx * s[4])
                c_e[e, 3 * a] += wg * (gx * d[0] + gz * d[4] + gy * d[5])
                c_e[e, 3 * a + 1] += wg * (gy * d[1] + gz * d[3] + gx * d[5])
                c_e[e, 3 * a + 2] += wg * (gz * d[2] + gy * d[3] + gx * d[4])
    return nfail


@njit(cache=True)
def gather_element_vectors(edofs, dofs, f_e, f, c_e, c, scale):
    """``f`` and ``c`` zeroed at ``dofs`` (the elements' dofs), then ``f[edofs[e, i]] +=
    f_e[e, i]`` and ``c[edofs[e, i]] += c_e[e, i]`` element by element (N), and ``c`` there
    times ``scale`` (h theta for the material correction, N s); both are left as they are
    elsewhere."""
    for i in range(dofs.shape[0]):
        f[dofs[i]] = 0.0
        c[dofs[i]] = 0.0
    for e in range(edofs.shape[0]):
        for i in range(edofs.shape[1]):
            f[edofs[e, i]] += f_e[e, i]
            c[edofs[e, i]] += c_e[e, i]
    for i in range(dofs.shape[0]):
        c[dofs[i]] *= scale


class _Run:
    """Consecutive ENDO3D blocks of one element type: their elements ``e0`` to ``e1 - 1`` and
    Gauss points ``p0`` to ``p1 - 1`` of the batch, with the shape functions' gradients
    ``dN`` (1/m, (nel, ng, nodes, 3)), integration weights ``w`` (m^3, (nel, ng)), dofs
    ``edofs`` (nel, 3 nodes) and node coordinates ``xe`` (m, (nel, nodes, 3))."""

    def __init__(self, el, blocks, dofs0, e0: int, p0: int):
        self.el = el
        xe = np.concatenate([b.X[b.conn] for b in blocks])
        self.edofs = np.concatenate([
            (d0 + 3 * b.conn[:, :, None] + np.arange(3)).reshape(len(b.conn), el.ndof)
            for d0, b in zip(dofs0, blocks, strict=True)]).astype(np.int64)
        self.dN, self.w = solid.precompute_gradients(np.ascontiguousarray(xe), el)
        self.xe = np.ascontiguousarray(xe)
        self.e0, self.e1 = e0, e0 + len(xe)
        self.ng = el.ngauss
        self.p0, self.p1 = p0, p0 + self.ng * len(xe)
        self.elem_of_point = np.repeat(np.arange(len(xe)), self.ng).astype(np.int64)


class Endo3dBlocks:
    """The ENDO3D blocks of a scene (body indices ``index``) and their Gauss-point states.

    All ENDO3D elements are handled in one batch: their shape functions' gradients are
    computed once, and a trial evaluation is one kernel (``trial_forces``) over ranges of
    elements on the threads of ``masonry_nscd.threads``, whatever the number of blocks.
    Per-block views (``state``, ``trial``) index into the batch. Blocks of different element
    types (hexahedra, tetrahedra) are runs of the batch (consecutive blocks of one type, in
    the order of ``index``), each with its own gradients; a range of elements may span runs.
    """

    def __init__(self, bodies: list, body_dof0: np.ndarray, params: np.ndarray, *,
                 tau: float = 0.0, h: float = 1.0):
        self.params = np.ascontiguousarray(params, dtype=float)
        # h / tau of the viscous regularisation (0: none)
        self.relax = h / tau if tau > 0.0 else 0.0
        self.index = [i for i, b in enumerate(bodies)
                      if isinstance(b, Block) and b.material == MAT_ENDO3D]
        self.blocks = [bodies[i] for i in self.index]
        self.dofs = [np.arange(body_dof0[i], body_dof0[i + 1]) for i in self.index]
        if not self.blocks:
            return
        self.runs: list[_Run] = []
        start = 0
        for k in range(1, len(self.blocks) + 1):
            if k == len(self.blocks) or self.blocks[k].element is not self.blocks[start].element:
                run = self.runs[-1] if self.runs else None
                self.runs.append(_Run(self.blocks[start].element, self.blocks[start:k],
                                      [body_dof0[i] for i in self.index[start:k]],
                                      run.e1 if run else 0, run.p1 if run else 0))
                start = k
        self.all_dofs = np.unique(np.concatenate([r.edofs.ravel() for r in self.runs]))
        self.nel = self.runs[-1].e1
        npts = self.runs[-1].p1
        #: integration weight of each Gauss point (m^3, (points,)), w_g det J
        self.w = np.concatenate([r.w.ravel() for r in self.runs])
        self.state_all = np.tile(endo3d.endo3d_initial_state(), (npts, 1))
        self.trial_all = self.state_all.copy()
        self.sigma_all = np.zeros((npts, 6))
        self.sigma_committed_all = self.sigma_all.copy()
        self._eps = np.zeros((npts, 6))
        self._sigma_endo3d = np.zeros((npts, 6))
        # the ENDO3D stress at the end of the last step, where the relaxation starts from
        self.sigma_endo3d_committed_all = np.zeros((npts, 6))
        self.eps_committed_all = np.zeros((npts, 6))
        # where each entry of the element stiffnesses (nel, 3 nodes, 3 nodes) goes in the
        # blocks' dense stiffnesses, laid end to end (block k at _k_off[k], row-major
        # (3n_k, 3n_k))
        sizes = [3 * len(b.X) for b in self.blocks]
        self._k_off = np.cumsum([0] + [n * n for n in sizes])
        self._k_slot = np.concatenate([
            (self._k_off[k] + loc[:, :, None] * n + loc[:, None, :]).ravel()
            for k, (b, n) in enumerate(zip(self.blocks, sizes))
            for loc in [solid.element_dofs(b.conn)]])
        self.C0 = np.concatenate([
            np.broadcast_to(solid.elastic_matrix(b.E, b.nu), (b.element.ngauss * len(b.conn),
                                                               6, 6))
            for b in self.blocks])
        ends = np.cumsum([0] + [b.element.ngauss * len(b.conn) for b in self.blocks])
        self.state = [self.state_all[ends[k]:ends[k + 1]] for k in range(len(self.blocks))]
        self.trial = [self.trial_all[ends[k]:ends[k + 1]] for k in range(len(self.blocks))]
        self.failures = 0

    def __bool__(self) -> bool:
        return bool(self.blocks)

    def internal_forces(self, u: np.ndarray, fint: np.ndarray, *, trial: bool = True,
                        departure: np.ndarray | None = None) -> None:
        """Write the ENDO3D internal forces of the blocks at displacement u into fint (N).

        ``trial``: update trial states from the committed ones (inside a step); otherwise the
        committed stresses are used as they are (forces at the start of the step).
        ``departure`` (trial only): also write there the forces' departure from the linear
        forces of the step's start, ``F_int(u) - F_int(u_n) - K0 (u - u_n)`` (N, module
        docstring). Both are zero at the dofs of other bodies.
        """
        if not trial:
            fint[self.all_dofs] = 0.0
            for r in self.runs:
                solid.forces_from_gradients(r.dN, r.w, r.edofs,
                                            self.sigma_committed_all[r.p0:r.p1], fint)
            return
        batch, n, min_size, finish = self.trial_batch(u, fint, departure)
        with timing.part("ENDO3D trial"):
            finish(threads.run_ranges(batch, n, min_size=min_size))

    def trial_batch(self, u: np.ndarray, fint: np.ndarray,
                    departure: np.ndarray | None = None, scale: float = 1.0) -> tuple:
        """The trial of :meth:`internal_forces` as a batch for ``threads``: ``(batch, n,
        min_size, finish)``, with ``batch(lo, hi)`` the elements ``lo`` to ``hi - 1`` (their
        Gauss points updated from the committed states, their element vectors computed; it
        returns the count of return mappings that failed), ``n`` the elements and ``finish``
        to call with the batch's results once every range is done: it records the failures
        and sums the element vectors into ``fint`` (and ``departure``, times ``scale``)."""
        f_e = [np.empty((len(r.dN), r.el.ndof)) for r in self.runs]
        c_e = [np.empty((len(r.dN), r.el.ndof)) for r in self.runs]
        rx = self.relax
        sig_endo = self._trial_endo3d_stress

        def batch(lo, hi):
            nfail = 0
            for k, r in enumerate(self.runs):
                a, b = max(lo, r.e0) - r.e0, min(hi, r.e1) - r.e0  # the run's own elements
                if a >= b:
                    continue
                p0, p1 = r.p0 + r.ng * a, r.p0 + r.ng * b
                nfail += trial_forces(
                    r.dN[a:b], r.w[a:b], r.edofs[a:b], u, self.state_all[p0:p1], self.params,
                    r.xe[a:b], rx, self.C0[p0:p1], self.sigma_committed_all[p0:p1],
                    self.eps_committed_all[p0:p1], self.sigma_endo3d_committed_all[p0:p1],
                    self._eps[p0:p1], self.trial_all[p0:p1], sig_endo[p0:p1],
                    self.sigma_all[p0:p1], f_e[k][a:b], c_e[k][a:b])
            return nfail

        def finish(failures: list[int]) -> None:
            self.failures = sum(failures)
            c = np.zeros_like(fint) if departure is None else departure
            if len(self.runs) == 1:
                gather_element_vectors(self.runs[0].edofs, self.all_dofs, f_e[0], fint, c_e[0],
                                       c, scale)
                return
            fint[self.all_dofs] = 0.0
            c[self.all_dofs] = 0.0
            for r, f_r, c_r in zip(self.runs, f_e, c_e, strict=True):
                gather_element_vectors(r.edofs, _NO_DOFS, f_r, fint, c_r, c, 1.0)
            c[self.all_dofs] *= scale

        # a range of elements holds as many Gauss points as a range of points elsewhere
        return batch, self.nel, threads.MIN_POINTS // max(r.ng for r in self.runs), finish

    @property
    def _trial_endo3d_stress(self) -> np.ndarray:
        """Where a trial writes ENDO3D's stress (Pa, one row per Gauss point): its own array
        with the relaxation, else ``sigma_all``, the stress being ENDO3D's."""
        return self._sigma_endo3d if self.relax > 0.0 else self.sigma_all

    def failed_points(self) -> np.ndarray:
        """Gauss points (indices into the batch) whose return mapping did not converge at the
        last trial. The batch kernel only counts them (``failures``); this runs the kernel again
        point by point, so call it before ``commit`` and only when ``failures`` > 0."""
        out = np.empty(endo3d.N_STATE)
        sig = np.empty(6)
        bad = [p for r in self.runs for p in range(r.p0, r.p1)
               if endo3d.endo3d_update(self._eps[p], self.state_all[p], self.params,
                                       r.xe[r.elem_of_point[p - r.p0]], out, sig) != 0]
        return np.array(bad, dtype=np.int64)

    def point_centre(self, p: int) -> np.ndarray:
        """Centre (m, reference coordinates: the mean of its nodes) of the element of Gauss
        point ``p``."""
        r = next(r for r in self.runs if r.p0 <= p < r.p1)
        return r.xe[r.elem_of_point[p - r.p0]].mean(axis=0)

    def damages(self, state: np.ndarray | None = None) -> np.ndarray:
        """The largest tensile and the compressive damage (``d_t``, ``d_c``) of every Gauss point
        (ngp, 2) of ``state`` (the committed states by default)."""
        st = self.state_all if state is None else state
        return st[:, [endo3d.S_D_T, endo3d.S_D_C]]

    def commit(self) -> None:
        """The last trial becomes the state at the end of the step."""
        self.state_all[:] = self.trial_all
        self.sigma_committed_all[:] = self.sigma_all
        self.eps_committed_all[:] = self._eps
        self.sigma_endo3d_committed_all[:] = self._trial_endo3d_stress

    def tangent_stiffness(self, delta: float = 1e-8) -> list[np.ndarray]:
        """Consistent tangent stiffness (3n, 3n) of each block at the last trial strains, N/m.

        ``C_p = d sigma / d eps`` at each Gauss point by forward differences of the ENDO3D
        update from the committed state (strain steps ``delta``, engineering shear for the
        shear components), ``C_p[:, j] = (sigma(eps + delta e_j) - sigma(eps)) / delta``,
        assembled as ``K_e = sum_p w_p B_p^T C_p B_p``. It is the derivative of the step's
        internal forces with respect to the end-of-step displacements: Newton converges
        quadratically where the law is smooth, softening included (a negative stiffness along
        a crack's normal). Not symmetric in general; six kernel calls per Gauss point (the
        unperturbed stress is the last trial's).
        """
        with timing.part("ENDO3D tangent"):
            return self._tangent_stiffness(delta)

    def _tangent_stiffness(self, delta: float) -> list[np.ndarray]:
        # C[p, i, j] = d sigma_i / d eps_j, from the ENDO3D stresses of the last trial
        C = np.empty((len(self._eps), 6, 6))
        for r in self.runs:
            eps, state = self._eps[r.p0:r.p1], self.state_all[r.p0:r.p1]
            sigma, Cr = self._trial_endo3d_stress[r.p0:r.p1], C[r.p0:r.p1]

            def tangent(lo, hi, r=r, eps=eps, state=state, sigma=sigma, Cr=Cr):
                endo3d.endo3d_tangent_elements(eps[lo:hi], state[lo:hi], self.params, r.xe,
                                               r.elem_of_point[lo:hi], sigma[lo:hi], delta,
                                               Cr[lo:hi])

            threads.run_ranges(tangent, len(eps))
        if self.relax > 0.0:
            phi = -np.expm1(-self.relax) / self.relax  # module docstring
            C = np.ascontiguousarray(phi * self.C0 + (1.0 - phi) * C)
        Ke = [solid.stiffness_from_gradients(r.dN, r.w, np.ascontiguousarray(C[r.p0:r.p1]))
              for r in self.runs]
        # the element matrices summed into each block's (entries in element order, as a
        # scatter-add per block would sum them)
        K = np.bincount(self._k_slot, weights=np.concatenate([k.ravel() for k in Ke]),
                        minlength=self._k_off[-1])
        return [K[self._k_off[k]:self._k_off[k + 1]].reshape(3 * len(b.X), 3 * len(b.X))
                for k, b in enumerate(self.blocks)]

    def element_fields(self) -> dict[str, np.ndarray]:
        """Per element, over its Gauss points: max d_c, max d_cpp, max d_t, max crack opening
        (m), and the mean apparent stress (nel, 6), Pa. Blocks in the order of ``index``."""
        d_c, d_cpp, d_t, w = endo3d.endo3d_outputs(self.state_all)

        def per_element(x, reduce):
            return np.concatenate([reduce(x[r.p0:r.p1].reshape(r.e1 - r.e0, r.ng, *x.shape[1:]))
                                   for r in self.runs])

        def largest(a):
            return a.max(axis=1)

        def mean(a):
            return a.mean(axis=1)

        return {"d_c": per_element(d_c, largest), "d_cpp": per_element(d_cpp, largest),
                "d_t": per_element(d_t, largest), "crack_opening_m": per_element(w, largest),
                "stress_Pa": per_element(self.sigma_committed_all, mean)}
