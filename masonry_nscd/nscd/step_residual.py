r"""The residual of one Moreau-Jean step at an iterate of the Newton solver (``nscd/newton.py``).

At body velocities ``v`` (m/s, every dof) and glue or rigid-contact impulses ``r`` (N s), with
the step's data fixed (free velocities, the joints' displacements and states at its start):

    R_v = M_hat (v - v_free) - sum_joints H_a r_a(v) - sum_mult H_m r_m [+ c(v)]     (N s)
    F   = [ R_v on the free dofs ; the multipliers' rows ]

where a joint point's impulse follows from its law, ``r_a = -h S_a T_a(u_a)``, at
``u_a = u_a,n + h (1 - theta) U_a,n + h theta H_a^T v``, and ``c(v)`` is the material correction
of blocks whose internal forces are not linear (ENDO3D). On those blocks' dofs
``M_hat (v - v_free) + c(v)`` is computed as ``M v + h theta F_int(u) + b``, the same function
(``integrator.MaterialCorrection``) without a product by their dense ``M_hat`` per evaluation
nor their free velocity (the integrator's ``blocks_apart``: it is then ``v_n`` there).
An evaluation also gives the multipliers' derivatives ``Gu``, ``Gr`` that the Newton matrix
needs, the laws' tangents ``K`` when asked (:meth:`StepResidual.tangents`: the line search's
trial points need none), and the merit norm of the line search, ``|F|`` with the glue rows
scaled to impulse units and the rigid contacts' rows as impulses (``F / w``, N s).

Convergence (:meth:`StepResidual.convergence`): the relative change of the contact forces
between iterates, ``sqrt(sum |S dT|^2) / sqrt(sum |S T|^2)`` (the points with a law and the
glue), the momentum residual ``|R_v| / (h sqrt(sum |S T|^2))``, the rigid contacts' rows as
the impulses that would meet them, and the relative change of the material correction; the
largest of them.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np
from numba import njit

from masonry_nscd import threads, timing
from masonry_nscd.contact import alart_curnier, laws
from masonry_nscd.nscd import kernels


def evaluate_joints(u_pred, Hv, h, theta, mult_of, law, params, uc_old, beta_old,
                    T, uc, beta, status):
    """The law at every joint point with a spring (``mult_of < 0``) for
    ``u = u_pred + h theta H^T v`` (Hv = H^T v), by the kernel ``contact.laws.solve_points``:
    tractions ``T`` (Pa), cohesive displacements ``uc`` (m), integrities and statuses."""
    laws.solve_points(u_pred, Hv, h * theta, mult_of, law, params, uc_old, beta_old, T, uc,
                      beta, status)


def joint_tangents(u_pred, Hv, h, theta, mult_of, law, params, uc_old, beta_old, T, beta,
                   status, K):
    """Consistent tangents ``K`` (npt, 3, 3; Pa/m) of the joint points at the solution
    (``T``, ``beta``, ``status``) that :func:`evaluate_joints` found for the same ``Hv``, by
    the kernel ``contact.laws.tangent_points``; the rows of the other points are left as they
    are."""
    laws.tangent_points(u_pred, Hv, h * theta, mult_of, law, params, uc_old, beta_old, T, beta,
                        status, K)


@njit(cache=True)
def evaluate_multipliers(u_pred, Hv, h, theta, mult, mu, rho, eps, uc_old, r, area, F, Gu, Gr,
                         T, uc, status):
    """Rows of the points whose impulses ``r`` (N s) are unknowns: glue (``mu < 0``) and rigid
    Signorini-Coulomb contacts, at ``u = u_pred + h theta H^T v`` (Hv = H^T v), in velocity
    units: ``F = Phi / (h theta) + eps r`` with ``Phi = u`` for the glue and the Alart-Curnier
    function (``contact.alart_curnier``, with ``rho`` in N s/m) for a contact; ``Gu``, ``Gr``
    the derivatives of ``F`` along ``H^T v`` and ``r``. The tractions ``T = -r / (h S)`` (Pa),
    the cohesive displacements and the statuses of these points are written too."""
    phi = np.empty(3)
    u = np.empty(3)
    gu = np.empty((3, 3))
    gr = np.empty((3, 3))
    c = np.empty(3)
    ht = h * theta
    for m in range(mult.shape[0]):
        a = mult[m]
        e = eps[m]
        if mu[m] < 0.0:
            for i in range(3):
                F[3 * m + i] = Hv[a, i] + u_pred[a, i] / ht + e * r[3 * m + i]
                for j in range(3):
                    Gu[m, i, j] = 1.0 if i == j else 0.0
                    Gr[m, i, j] = e if i == j else 0.0
                uc[a, i] = 0.0
            status[a] = laws.ST_GLUED
        else:
            for i in range(3):
                u[i] = u_pred[a, i] + ht * Hv[a, i]
            status[a] = alart_curnier.residual(u, r[3 * m:3 * m + 3], uc_old[a], mu[m], rho[m],
                                               phi, gu, gr, c)
            for i in range(3):
                F[3 * m + i] = phi[i] / ht + e * r[3 * m + i]
                for j in range(3):
                    Gu[m, i, j] = gu[i, j]
                    Gr[m, i, j] = gr[i, j] / ht + (e if i == j else 0.0)
                uc[a, i] = c[i]
        for i in range(3):
            T[a, i] = -r[3 * m + i] / (h * area[a])


@njit(cache=True)
def subtract_impulses(side_dofs, side_coef, mult_of, area, T, r_mult, h, R):
    """``R -= H r``: the contact impulses (N s) of every point taken from the residual, the
    points with a law from their tractions (``r = -h S T``), the multipliers' from ``r_mult``."""
    for a in range(side_dofs.shape[0]):
        g = mult_of[a]
        if g < 0:
            f = -h * area[a]
            r0 = f * T[a, 0]
            r1 = f * T[a, 1]
            r2 = f * T[a, 2]
        else:
            r0 = r_mult[3 * g]
            r1 = r_mult[3 * g + 1]
            r2 = r_mult[3 * g + 2]
        for s in range(2):
            for j in range(side_dofs.shape[2]):
                d = side_dofs[a, s, j]
                if d < 0:
                    break
                R[d] -= side_coef[a, s, j, 0] * r0 + side_coef[a, s, j, 1] * r1 \
                    + side_coef[a, s, j, 2] * r2


_NO_DOFS = np.zeros(0, dtype=np.int64)
_NO_VALUES = np.zeros(0)


@njit(cache=True)
def momentum_rows(R, free, blocks, mass, v, b, hth, f_trial, F, glue_scale):
    """The end of the residual: on the ENDO3D blocks' dofs ``blocks`` (none when empty)
    ``R += M v + b + hth f_trial`` (``mass`` and ``b`` per entry of ``blocks``, ``hth`` = h
    theta), then ``F[:nf] = R[free]``. Returns ``(sum of F[:nf]^2, that plus glue_scale^2 times
    the sum of the other rows' squares)`` (N^2 s^2): the merit norm squared when every other row
    is the glue's (already written, m/s; ``glue_scale`` in kg); with rigid contacts the caller
    gives 0 and adds their rows and the glue's itself."""
    for i in range(blocks.shape[0]):
        d = blocks[i]
        R[d] += mass[i] * v[d] + b[i] + hth * f_trial[d]
    nf = free.shape[0]
    momentum = 0.0
    for i in range(nf):
        x = R[free[i]]
        F[i] = x
        momentum += x * x
    rest = 0.0
    for i in range(nf, F.shape[0]):
        rest += F[i] * F[i]
    return momentum, momentum + glue_scale * glue_scale * rest


@njit(cache=True)
def traction_change(area, T, T_prev, lawful):
    """``(sum over the points with lawful[a] of |S (T - T_prev)|^2, sum over every point of
    |S T|^2)`` (N^2): the change of the contact forces between iterates and their size."""
    num = 0.0
    den = 0.0
    for a in range(T.shape[0]):
        for i in range(3):
            x = area[a] * T[a, i]
            den += x * x
            if lawful[a]:
                y = area[a] * (T[a, i] - T_prev[a, i])
                num += y * y
    return num, den


@njit(cache=True)
def change_norm(x, y):
    """``|x - y|`` (2-norm)."""
    s = 0.0
    for i in range(x.shape[0]):
        d = x[i] - y[i]
        s += d * d
    return math.sqrt(s)


class Evaluation(NamedTuple):
    """The residual at one iterate and what comes with it."""

    F: np.ndarray  # residual (free dofs, N s; then 3 rows per multiplier point, m/s)
    norm: float  # merit norm (N s)
    T: np.ndarray  # tractions of every point (npt, 3), Pa
    uc: np.ndarray  # cohesive displacements (npt, 3), m
    beta: np.ndarray  # integrities (npt,)
    status: np.ndarray  # statuses (npt,)
    Hv: np.ndarray  # the points' relative velocities H^T v (npt, 3), m/s
    Gu: np.ndarray  # the multipliers' derivatives along H^T v (m, 3, 3)
    Gr: np.ndarray  # and along their impulses (m, 3, 3)
    correction: np.ndarray | None  # material correction c(v) (ndof), N s; None without
    correction_scale: float  # the size of the internal impulses it corrects, N s
    K: list  # [the joints' tangents (npt, 3, 3), Pa/m], once StepResidual.tangents made them
    momentum_sq: float  # sum of F[:nf]^2 (N^2 s^2), for the convergence measure


class Scales:
    """How the residual's rows are weighed, fixed for a solver (built once by it): the glue
    rows scaled to impulse units by ``glue_scale`` (10 times the mean entry of ``M_hat``,
    kg), the rigid contacts' rows divided by ``w`` (the mean diagonal of their Delassus
    matrices, 1/kg), and the points whose tractions' change is judged (``lawful``: all but
    the rigid contacts, whose impulse can shift between redundant points at no cost)."""

    def __init__(self, solver):
        s = solver.sys
        nf = len(solver.free)
        self.glue_scale = float(np.mean(np.abs(solver.mhat))) * 10.0 if len(solver.mhat) else 1.0
        # the rows of the rigid contacts in impulse units (N s): F / w
        self.rigid_w = np.repeat(solver.w, 3)[solver.rigid_rows]
        self.glue_rows = nf + np.flatnonzero(solver.glue_rows)
        self.rigid_rows = nf + np.flatnonzero(solver.rigid_rows)
        self.lawful = np.ones(s.npt, dtype=bool)
        if solver.has_rigid:
            self.lawful[solver.mult[solver.mu >= 0.0]] = False
        # the unknowns (free velocities, then the multipliers' impulses) in velocity units:
        # 1, 1 / glue_scale for the glue, w for rigid contacts (Anderson's least squares)
        self.weight = np.concatenate([np.ones(nf), np.where(solver.glue_rows,
                                                            1.0 / self.glue_scale,
                                                            np.repeat(solver.w, 3))])

    def rigid_sq(self, F: np.ndarray) -> float:
        """Sum of squares of the rigid contacts' rows as impulses (F / w, N s)."""
        return np.sum((F[self.rigid_rows] / self.rigid_w) ** 2)


class StepResidual:
    """The residual of one step as a function of the iterate (``__call__``), for the solver
    ``solver`` (a ``NewtonSolver``: the system, the multipliers, their ``scales``).

    ``correction``: the material correction (None: linear blocks), whose ``batch(v)`` gives
    the kernel that computes it, as a batch for ``threads.run_together`` run in the same
    hand-over as the joint law, and what turns the batch's results into ``(c, scale)``: the
    correction (N s) and the size of the internal impulses it corrects
    (``integrator.MaterialCorrection``).
    """

    def __init__(self, solver, v_free, u_old, U_old, params, uc_old, beta_old, T,
                 correction=None):
        s = solver.sys
        self.solver = solver
        self.sys = s
        self.scales = solver.scales
        self.v_free = v_free
        self.params = params
        self.uc_old = uc_old
        self.beta_old = beta_old
        self.T_old = T
        self.correction = correction
        self._f_trial = _NO_VALUES if correction is None else correction.f_trial
        self.u_pred = u_old + s.h * (1.0 - s.theta) * U_old
        self.nf = len(solver.free)
        self._R = np.empty(s.ndof)
        self._p_free: float | None = None  # |M_hat v_free| (N s), when asked for
        # the product by M_hat (v - v_free): of every body, or of all but the ENDO3D blocks,
        # whose rows are then M v + h theta F_int(u) + b (integrator.MaterialCorrection)
        self._mhat_op = solver.mhat_op
        self._blocks = (_NO_DOFS, _NO_VALUES, _NO_VALUES)  # (their dofs, M there, b there)
        if correction is not None and correction.apart:
            d = np.asarray(correction.dofs, dtype=np.int64)
            self._mhat_op = solver.mhat_without(correction.bodies)
            self._blocks = (d, s.mass[d], correction.constant_impulses())

    def __call__(self, v: np.ndarray, r_glue: np.ndarray) -> Evaluation:
        """The residual at body velocities ``v`` (m/s) and multipliers' impulses ``r_glue``
        (N s)."""
        sv, s = self.solver, self.sys
        h, th, npt, nf = s.h, s.theta, s.npt, self.nf
        g = sv.mult
        u_pred, uc_old, beta_old, params = self.u_pred, self.uc_old, self.beta_old, self.params
        R = self._R
        Hv = np.empty((npt, 3))  # kept by the evaluation, for its tangents
        out_T = self.T_old.copy()
        out_uc = np.zeros((npt, 3))
        out_beta = beta_old.copy()
        out_status = np.full(npt, laws.ST_GLUED, dtype=np.int64)
        Gu = np.empty((len(g), 3, 3))
        Gr = np.empty((len(g), 3, 3))
        F = np.empty(nf + 3 * len(g))
        kernels.local_velocities(s.side_dofs, s.side_coef, v, Hv)
        mo = sv.mult_of

        def joints(lo, hi):
            evaluate_joints(u_pred[lo:hi], Hv[lo:hi], h, th, mo[lo:hi], s.law[lo:hi], params,
                            uc_old[lo:hi], beta_old[lo:hi], out_T[lo:hi], out_uc[lo:hi],
                            out_beta[lo:hi], out_status[lo:hi])

        busy = [0.0, 0.0]  # the calling thread's time in ``meanwhile`` and in its product (s)

        def meanwhile():
            # what needs none of the joints' tractions, while the threads finish: the glue's
            # and the rigid contacts' rows, and R_v = M_hat (v - v_free) over all dofs
            t0 = time.perf_counter()
            with timing.part("glue and rigid contacts"):
                evaluate_multipliers(u_pred, Hv, h, th, g, sv.mu, sv.rho, sv.eps, uc_old,
                                     r_glue, s.area, F[nf:], Gu, Gr, out_T, out_uc, out_status)
            t1 = time.perf_counter()
            self._mhat_op.matvec(v - self.v_free, R)
            t2 = time.perf_counter()
            busy[:] = t2 - t0, t2 - t1

        # the joint law and the ENDO3D trial (the material correction c(v)) in one hand-over
        jobs = [(joints, npt, None)]
        if self.correction is not None:
            kernel, n, min_size, finish = self.correction.batch(v)
            jobs.append((kernel, n, min_size))
        t0 = time.perf_counter()
        results = threads.run_together(jobs, meanwhile)
        cvec, cscale = (None, 0.0) if self.correction is None else finish(results[1])
        timing.record("joint law" if self.correction is None else "joint law and ENDO3D trial",
                      time.perf_counter() - t0 - busy[0])
        t1 = time.perf_counter()
        # R_v -= H r: the joints' and the multipliers' impulses
        subtract_impulses(s.side_dofs, s.side_coef, mo, s.area, out_T, r_glue, h, R)
        timing.record("bodies' residual", busy[1] + time.perf_counter() - t1)
        d, m, b = self._blocks
        if cvec is not None and not len(d):
            R[:] += cvec
        sc = self.scales
        gs = sc.glue_scale
        if sv.has_rigid:
            momentum, _ = momentum_rows(R, sv.free, d, m, v, b, h * th, self._f_trial, F, 0.0)
            norm = math.sqrt(momentum + gs ** 2 * np.sum(F[sc.glue_rows] ** 2)
                             + sc.rigid_sq(F))
        else:
            momentum, norm2 = momentum_rows(R, sv.free, d, m, v, b, h * th, self._f_trial, F, gs)
            norm = math.sqrt(norm2)
        return Evaluation(F, norm, out_T, out_uc, out_beta, out_status, Hv, Gu, Gr, cvec, cscale,
                          [None], momentum)

    def tangents(self, ev: Evaluation) -> tuple:
        """``(K, Gu, Gr)`` at the iterate of ``ev`` for the Newton matrix: the joints'
        tangents (:func:`joint_tangents`, made at the first call and kept in ``ev``) and the
        multipliers' derivatives."""
        if ev.K[0] is None:
            s, sv = self.sys, self.solver
            K = np.zeros((s.npt, 3, 3))
            u_pred, uc_old, beta_old, params = self.u_pred, self.uc_old, self.beta_old, self.params
            mo = sv.mult_of

            def joints(lo, hi):
                joint_tangents(u_pred[lo:hi], ev.Hv[lo:hi], s.h, s.theta, mo[lo:hi], s.law[lo:hi],
                               params, uc_old[lo:hi], beta_old[lo:hi], ev.T[lo:hi],
                               ev.beta[lo:hi], ev.status[lo:hi], K[lo:hi])

            with timing.part("joint tangents"):
                threads.run_ranges(joints, s.npt)
            ev.K[0] = K
        return ev.K[0], ev.Gu, ev.Gr

    def convergence(self, ev: Evaluation, T_prev: np.ndarray,
                    c_prev: np.ndarray | None) -> tuple[float, float, float]:
        """The convergence measure at ``ev`` against the tractions ``T_prev`` (Pa) and the
        material correction ``c_prev`` of the iterate before (module docstring). Returns
        ``(measure, num, den)``: ``num`` and ``den`` the sums of squares of the traction
        change and of the tractions (N^2), for :meth:`parts`."""
        s, h, F = self.sys, self.sys.h, ev.F
        # the change of the tractions of the points with a law (a rigid contact's impulse
        # can shift between redundant points at no cost: its rows below judge it)
        num, den = traction_change(s.area, ev.T, T_prev, self.scales.lawful)
        res = math.sqrt(num / den) if den > 0 else (0.0 if num == 0 else math.inf)
        if den > 0:
            # and the momentum balance against the contact impulses: at the friction limit
            # the tractions (mu N) stop changing before the velocities are right
            res = max(res, math.sqrt(ev.momentum_sq / den) / h)
            if self.solver.has_rigid:
                # and the rigid contacts' conditions, as the impulses that would meet them
                res = max(res, math.sqrt(self.scales.rigid_sq(F) / den) / h)
        else:
            # no point carries a force (every body in free flight: a block left alone after
            # the removal of its neighbours): the momentum balance alone tells, against the
            # momentum of the free velocities. Without it the predictor, an extrapolation of
            # the steps before, passed for the solution, and a block that had just lost its
            # last contact went on accelerating upwards
            res = max(res, math.sqrt(ev.momentum_sq) / self._free_momentum())
        cvec, cscale = ev.correction, ev.correction_scale
        if cvec is not None and c_prev is not None:
            dc = change_norm(cvec, c_prev)
            res = max(res, dc / cscale if cscale > 0 else (0.0 if dc == 0 else math.inf))
        return res, num, den

    def _free_momentum(self) -> float:
        """``|M_hat v_free|`` over the free dofs (N s; 1e-300 at least), made once."""
        if self._p_free is None:
            p = np.empty(self.sys.ndof)
            self.solver.mhat_op.matvec(self.v_free, p)
            self._p_free = max(float(np.linalg.norm(p[self.solver.free])), 1e-300)
        return self._p_free

    def parts(self, ev: Evaluation, num: float, den: float) -> tuple[float, float, float]:
        """The three parts of the measure (change of the tractions, momentum, rigid
        contacts' rows), for the solver's trace."""
        d = den if den > 0 else math.inf
        h, F = self.sys.h, ev.F
        return (math.sqrt(num / d), math.sqrt(ev.momentum_sq / d) / h,
                math.sqrt(self.scales.rigid_sq(F) / d) / h)
