r"""A semi-smooth Newton solver for the Moreau-Jean step (primal form, same discrete equations).

The step of ``kernels.py`` is, with body velocities ``v`` at the end of the step as unknowns,

    R_v = M_hat (v - v_free) - sum_joints H_a r_a(v) - sum_glue H_g r_g = 0
    R_g = H_g^T v - w_g + eps r_g = 0    (glue: u_g,n+1 = 0, w_g = -(u_g,n + h (1 - theta) U_g,n) / (h theta))

where a joint point's impulse follows from its law, ``r_a = -h S_a T_a(u_a)``, with the relative
displacement ``u_a = u_a,n + h (1 - theta) U_a,n + h theta H_a^T v`` and ``T_a(u)`` the joint law
driven by its total relative displacement (the ``A = 0`` form of the law's ``solve``,
integrity consistent with the end of the step). These are exactly the equations that the
Gauss-Seidel sweeps solve in their dual form (impulses as unknowns); only the way to the
solution differs. Glue impulses stay unknowns (Lagrange multipliers), so the glue is exact.

Newton matrix, with ``K_a = dT_a/du_a`` the consistent tangent of the law (closed form per status
with the integrity frozen where it does not drop within the step; by differences of the implicit
law where it drops, since the frozen one misses the softening, by 100 % and in sign on opening
joints)::

    J = [[ M_hat + h^2 theta sum_a S_a H_a K_a H_a^T ,  -H_g ],
         [ H_g^T                                     ,   0   ]]

restricted to the dofs that are not imposed, with ``eps I`` (a glue compliance of 1e-9 of the
point's own Delassus diagonal) in the lower right block: glue points can outnumber the dofs they
hold, and the tiny compliance keeps the matrix non-singular. For ENDO3D blocks ``M_hat`` holds
their tangent stiffness (``Integrator._update_tangent``) and the residual a material correction.

Iterations:

* predictor: the solution (body velocities, glue impulses) extrapolated linearly from the last
  two steps;
* chord steps ``-J0^-1 F`` with the factorisation of an earlier iterate, accelerated by
  Anderson mixing of the last few steps (``_anderson``: GMRES preconditioned by J0 on a linear
  residual), and a backtracking line search on the residual norm, which stops the open/closed
  cycling of tiny loads; an accelerated step is tried whole, and where it does not decrease the
  norm the plain step's line search follows;
* the matrix is factorised again (sparse LU, in a fixed pattern and order: ``_Pattern``) when
  the residual fell by less than ``slow_rate`` in two iterations in a row, or when a direction
  from an older matrix does not decrease the residual; where even the direction of a fresh
  matrix finds no decrease (a kink of the piecewise-smooth residual) the full step is taken;
* where the directions of fresh matrices only creep (``_Stall``: three in a row cut short by the
  line search, each lowering the norm by less than 1 %), the next fresh direction is taken
  whole, the norm allowed to rise: the creeping steps stop just short of the kinks the
  Newton step would cross (gravity's first load on a large wall, its head joints at the kink
  between open and closed: without the whole step such a step creeps to its iteration cap and
  is made again as halves; docs/scaling.md).

The acceleration lowers both the iterations and the factorisations per step; what it gains on
the study's walls is in docs/performance.md.

Convergence: the relative change of the contact forces between iterates,
``sqrt(sum |S dT|^2) / sqrt(sum |S T|^2)``, and the momentum residual of the free dofs against
the contact impulses, ``|R_v| / (h sqrt(sum |S T|^2))``, both at most the tolerance. The
first alone is not enough at the friction limit, where ``T_t = mu N`` stops changing while the
slip rate is still wrong.

The tangent per status is the law's (``contact.laws.tangent_points``; for the FCZM,
``contact.laws.fczm.tangent``); a law with a spring in series has a finite ``T(u)`` (``fczm``,
``dry``).

Rigid contacts (``coulomb``: Signorini-Coulomb with no spring, ``laws.rigid_friction``) have no
``T(u)``: their impulses are unknowns, like the glue's, and their rows are the Alart-Curnier
function of the point in velocity units (``contact.alart_curnier``),
``F_c = Phi(u_c, r_c) / (h theta) + eps r_c``, with its generalised derivative in the matrix
(rows ``Gu H^T`` and ``Gr``), and the compliance ``eps`` of the glue (1e-9 of the point's
Delassus diagonal). A rigid block's contact points outnumber its six dofs, so their impulses are
not unique (only their resultant is): the change of the tractions between iterates is judged
at the points with a law and the glue only, and the rigid contacts by their rows: the impulse
that would meet each condition, ``|F_c / w| / (h sqrt(sum |S T|^2))`` (``w`` the mean diagonal of
the point's Delassus matrix), at most the tolerance.
"""

from __future__ import annotations

import contextlib
import copy
import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numba import njit

from masonry_nscd import timing
from masonry_nscd.contact import laws
from masonry_nscd.nscd import block_diagonal, mpi
from masonry_nscd.nscd import linear as linear_solvers
from masonry_nscd.nscd import pardiso as pardiso_solver
from masonry_nscd.nscd.block_diagonal import BlockDiagonal
from masonry_nscd.nscd.step_residual import Evaluation, Scales, StepResidual


@njit(cache=True, inline="always")
def _emit(k, row, col, val, rows, cols, vals, slot, data):
    """Entry ``k`` of the Newton matrix: a triplet, or (with ``slot``) added to the values of
    the fixed pattern. No bounds test here: ``_full`` checks the room a group needs before it
    is emitted (a test per entry would sit in the fill's innermost loop)."""
    if slot.shape[0] > 0:
        data[slot[k]] += val
    else:
        rows[k] = row
        cols[k] = col
        if vals.shape[0] > 0:  # none: the pattern's triplets alone (``jacobian_coo``)
            vals[k] = val
    return k + 1


@njit(cache=True, inline="always")
def _full(k, need, slot):
    """With a pattern (``slot``): whether ``need`` more entries after the ``k`` emitted would
    pass its end (the kernel then stops and returns ``slot.shape[0] + 1``)."""
    return slot.shape[0] > 0 and k + need > slot.shape[0]


@njit(cache=True, inline="always")
def _same_dofs(side_dofs, a):
    """Whether contact point ``a + 1`` acts on the same dofs as point ``a``."""
    for s in range(2):
        for j in range(side_dofs.shape[2]):
            if side_dofs[a + 1, s, j] != side_dofs[a, s, j]:
                return False
    return True


@njit(cache=True)
def _jacobian_entries(body_dof0, mhat_off, mhat, free_index, nfree, side_dofs, side_coef,
                      mult_of, area, K, Gu, Gr, full_block, h, theta, keep_zeros, eliminate,
                      part, k0, slot, rows, cols, vals, data):
    """The entries of the Newton matrix, in a fixed order (``jacobian_coo``): as triplets
    into ``rows, cols, vals`` when ``slot`` is empty, else summed into ``data[slot[k]]`` (every
    entry, zeros included; ``data`` zeroed first). Returns the number of entries, or
    ``slot.shape[0] + 1`` when they would not fit the pattern (nothing written past it).

    ``part``: 0 every entry; 1 the bodies' blocks only (the first entries); 2 the others only,
    numbered from ``k0`` (the count that part 1 returned) and summed onto ``data`` as given
    (not zeroed): parts 1 then 2 make the sums of part 0, in its order.

    ``eliminate``: the body system with the multipliers eliminated instead,
    ``S = A + B D^-1 C`` (free dofs only, ``linear.py``): a multiplier point adds
    ``coef_i . Gu[g] . coef_j`` between its dofs, the caller giving ``D^-1 Gu`` as ``Gu``
    (``D`` the point's block of the Newton matrix, ``NewtonSolver._multipliers``). There every
    point adds a block ``coef_i . X . coef_j`` between the same kind of unknowns, so the
    blocks of consecutive points on the same dofs (the Gauss points of one face, four in a
    row on the study's walls) are summed in a small dense buffer first and emitted once: a
    quarter of the triplets, each a scattered addition into ``data`` and a slot in the
    pattern (docs/scaling.md). The Newton matrix itself keeps its order of sums,
    and with it the direct solver's iterates bit for bit."""
    if slot.shape[0] > 0:
        if part != 2:
            data[:] = 0.0
        keep_zeros = True
    nb = body_dof0.shape[0] - 1 if part != 2 else 0
    npt = side_dofs.shape[0]
    ms = 2 * side_dofs.shape[2]
    k = k0
    for b in range(nb):
        d0 = body_dof0[b]
        n = body_dof0[b + 1] - d0
        mo = mhat_off[b]
        nf = 0
        for i in range(n):
            if free_index[d0 + i] >= 0:
                nf += 1
        if _full(k, nf * nf, slot):
            return slot.shape[0] + 1
        for i in range(n):
            fi = free_index[d0 + i]
            if fi < 0:
                continue
            for j in range(n):
                fj = free_index[d0 + j]
                if fj < 0:
                    continue
                val = mhat[mo + i * n + j]
                if val != 0.0 or keep_zeros:
                    k = _emit(k, fi, fj, val, rows, cols, vals, slot, data)
    if part == 1:
        return k
    dofs = np.empty(ms, dtype=np.int64)
    coef = np.empty((ms, 3))
    block = np.zeros((ms, ms))  # the body system's sum over a run of points on the same dofs
    for a in range(npt):
        m = 0
        for s in range(2):
            for j in range(side_dofs.shape[2]):
                d = side_dofs[a, s, j]
                if d < 0:
                    break
                if free_index[d] < 0:
                    continue
                dofs[m] = free_index[d]
                for c in range(3):
                    coef[m, c] = side_coef[a, s, j, c]
                m += 1
        g = mult_of[a]
        if eliminate:
            # X = D^-1 Gu (given as Gu) for a multiplier, h^2 theta S_a K_a for a joint; the
            # block's entries (coef_i . X) . coef_j, all of them: the pattern of S does not
            # depend on the values
            if g >= 0:
                X = Gu[g]
                w = 1.0
            else:
                X = K[a]
                w = h * h * theta * area[a]
            for i in range(m):
                x0 = coef[i, 0] * X[0, 0] + coef[i, 1] * X[1, 0] + coef[i, 2] * X[2, 0]
                x1 = coef[i, 0] * X[0, 1] + coef[i, 1] * X[1, 1] + coef[i, 2] * X[2, 1]
                x2 = coef[i, 0] * X[0, 2] + coef[i, 1] * X[1, 2] + coef[i, 2] * X[2, 2]
                for j in range(m):
                    block[i, j] += w * (x0 * coef[j, 0] + x1 * coef[j, 1] + x2 * coef[j, 2])
            if a + 1 < npt and _same_dofs(side_dofs, a):
                continue  # the next point adds to the same block
            if _full(k, m * m, slot):
                return slot.shape[0] + 1
            for i in range(m):
                for j in range(m):
                    k = _emit(k, dofs[i], dofs[j], block[i, j], rows, cols, vals, slot, data)
                    block[i, j] = 0.0
            continue
        if _full(k, m * m if g < 0 else 6 * m, slot):
            return slot.shape[0] + 1
        if g < 0:
            w = h * h * theta * area[a]
            for i in range(m):
                # row_i = coef_i . K
                k0 = coef[i, 0] * K[a, 0, 0] + coef[i, 1] * K[a, 1, 0] + coef[i, 2] * K[a, 2, 0]
                k1 = coef[i, 0] * K[a, 0, 1] + coef[i, 1] * K[a, 1, 1] + coef[i, 2] * K[a, 2, 1]
                k2 = coef[i, 0] * K[a, 0, 2] + coef[i, 1] * K[a, 1, 2] + coef[i, 2] * K[a, 2, 2]
                for j in range(m):
                    val = w * (k0 * coef[j, 0] + k1 * coef[j, 1] + k2 * coef[j, 2])
                    if val != 0.0 or keep_zeros:
                        k = _emit(k, dofs[i], dofs[j], val, rows, cols, vals, slot, data)
        else:
            row0 = nfree + 3 * g
            for i in range(m):
                for c in range(3):
                    val = Gu[g, c, 0] * coef[i, 0] + Gu[g, c, 1] * coef[i, 1] \
                        + Gu[g, c, 2] * coef[i, 2]
                    if coef[i, c] != 0.0 or keep_zeros:
                        k = _emit(k, dofs[i], row0 + c, -coef[i, c], rows, cols, vals, slot,
                                  data)
                    if val != 0.0 or keep_zeros:
                        k = _emit(k, row0 + c, dofs[i], val, rows, cols, vals, slot, data)
    for gi in range(0 if eliminate else Gr.shape[0]):
        if _full(k, 9 if full_block[gi] else 3, slot):
            return slot.shape[0] + 1
        for c in range(3):
            for d in range(3):
                if c == d or (full_block[gi] and (Gr[gi, c, d] != 0.0 or keep_zeros)):
                    k = _emit(k, nfree + 3 * gi + c, nfree + 3 * gi + d, Gr[gi, c, d], rows,
                              cols, vals, slot, data)
    return k


class _Stall:
    """Whether the Newton iterations creep (module docstring): counts the iterations in a
    row along a fresh matrix's direction that the line search cut short and that lowered the
    merit norm by less than ``decrease`` (a fraction); after ``run`` of them,
    :meth:`after` says to take the next fresh direction whole, and the count starts again."""

    def __init__(self, run: int = 3, decrease: float = 0.01):
        self.run, self.decrease = run, decrease
        self.count = 0

    def after(self, fresh: bool, alpha: float, norm: float, norm_next: float) -> bool:
        """Count the iteration that went from merit norm ``norm`` to ``norm_next`` with the
        step length ``alpha`` along a direction of a fresh matrix (``fresh``) or not; returns
        whether the next fresh direction is to be taken whole."""
        creeping = fresh and alpha < 1.0 and norm_next > (1.0 - self.decrease) * norm
        self.count = self.count + 1 if creeping else 0
        if self.count >= self.run:
            self.count = 0
            return True
        return False


CYCLE_VISITS = 3  # an iterate met this many times in one step closes a cycle (count)


class _Cycle:
    """Whether Newton's iterations cycle: an iterate met for the ``visits``-th time in one
    step, "the same" meaning the same merit norm and the same convergence measure within a
    relative ``rtol``. It happens at a kink of the residual: a fresh matrix's direction lowers
    the norm nowhere, the step is taken whole, far away, and the next iterations lead back,
    until the iteration cap. The iterates close in on a periodic orbit: the first pass through
    it differs from the later ones (the matrix's age, the counters), which agree with each
    other far below ``rtol``, so equality to the bit would not catch it. Such a step is given up at its
    ``CYCLE_VISITS``-th visit and made again as halves, as it would be after the cap."""

    def __init__(self, visits: int = CYCLE_VISITS, rtol: float = 1e-6):
        self.visits, self.rtol = visits, rtol
        self.seen: list[list[float]] = []  # [norm, measure, times met]

    def closed_by(self, norm: float, measure: float) -> bool:
        """Count the iterate of merit norm ``norm`` and convergence measure ``measure``;
        whether it closes a cycle."""
        r = self.rtol
        for entry in self.seen:
            if (abs(norm - entry[0]) <= r * abs(norm)
                    and abs(measure - entry[1]) <= r * abs(measure)):
                entry[2] += 1
                return entry[2] >= self.visits
        self.seen.append([norm, measure, 1.0])
        return False


_NO_SLOT = np.zeros(0, dtype=np.int32)
_NO_INT = np.zeros(0, dtype=np.int32)
_NO_FLOAT = np.zeros(0)


def index_type(largest: int) -> type:
    """The integer type of the indices of a sparse pattern whose indices, counts and places
    stay below ``largest``: 32 bits where they fit (half the memory of the triplets, the
    slots and the pattern's rows, which grow with the wall), else 64."""
    return np.int32 if largest < np.iinfo(np.int32).max else np.int64


def jacobian_coo(body_dof0, mhat_off, mhat, free_index, nfree, side_dofs, side_coef, mult_of,
                 area, K, Gu, Gr, full_block, h, theta, keep_zeros=False, eliminate=False,
                 values=True):
    """COO triplets of the Newton matrix (free dofs, then 3 impulses per multiplier point: glue
    and rigid contacts, rows ``Gu H^T`` and ``Gr``, of which only the diagonal unless
    ``full_block``): ``(rows, cols, vals)``, or ``(rows, cols)`` without ``values``.

    ``keep_zeros``: emit every entry that can be non-zero, zeros included, always in the same
    order; the triplets then fit the fixed pattern of ``NewtonSolver`` (``_Pattern``), and
    later matrices are summed straight into its values (``jacobian_values``). ``eliminate``:
    the body system ``S`` of the Krylov solver instead (``_jacobian_entries``). Without
    ``values`` the triplets are the pattern's alone: a third less memory while the pattern is
    sorted, the largest transient of a run on a large wall (docs/scaling.md)."""
    ms = 2 * side_dofs.shape[2]
    cap = int(np.sum(np.diff(body_dof0) ** 2)) + side_dofs.shape[0] * (ms * ms + 6 * ms) \
        + 9 * Gr.shape[0]
    kind = index_type(nfree + 3 * Gr.shape[0])  # of the rows and columns
    rows = np.empty(cap, dtype=kind)
    cols = np.empty(cap, dtype=kind)
    vals = np.empty(cap) if values else _NO_FLOAT
    k = _jacobian_entries(body_dof0, mhat_off, mhat, free_index, nfree, side_dofs, side_coef,
                          mult_of, area, K, Gu, Gr, full_block, h, theta, keep_zeros, eliminate,
                          0, 0, _NO_SLOT, rows, cols, vals, _NO_FLOAT)
    return (rows[:k], cols[:k], vals[:k]) if values else (rows[:k], cols[:k])


def bodies_values(slot, nnz, body_dof0, mhat_off, mhat, free_index, nfree, side_dofs,
                  side_coef, mult_of, area, K, Gu, Gr, full_block, h, theta
                  ) -> tuple[np.ndarray, int]:
    """The values (``nnz``) of the Newton matrix from the bodies' blocks alone and the count
    of their entries, for :func:`jacobian_values` of matrices with the same blocks."""
    data = np.empty(nnz)
    k = _jacobian_entries(body_dof0, mhat_off, mhat, free_index, nfree, side_dofs, side_coef,
                          mult_of, area, K, Gu, Gr, full_block, h, theta, True, False, 1, 0,
                          slot, _NO_INT, _NO_INT, _NO_FLOAT, data)
    return data, k


def jacobian_values(slot, nnz, body_dof0, mhat_off, mhat, free_index, nfree, side_dofs,
                    side_coef, mult_of, area, K, Gu, Gr, full_block, h, theta,
                    eliminate=False, bodies=None) -> np.ndarray:
    """The values (``nnz``) of the Newton matrix in a fixed pattern whose entry ``k`` of
    ``jacobian_coo(..., keep_zeros=True)`` sits at ``slot[k]``: the same sums, without the
    triplets (two indices and a value per entry). ``eliminate``: of
    the body system ``S``, in the pattern of ``jacobian_coo(..., True, True)``. ``bodies``:
    :func:`bodies_values` of these bodies' blocks, onto a copy of which only the other
    entries are summed (the same sums bit for bit)."""
    if bodies is None:
        data, part, k0 = np.empty(nnz), 0, 0
    else:
        data, part, k0 = bodies[0].copy(), 2, bodies[1]
    k = _jacobian_entries(body_dof0, mhat_off, mhat, free_index, nfree, side_dofs, side_coef,
                          mult_of, area, K, Gu, Gr, full_block, h, theta, True, eliminate, part,
                          k0, slot, _NO_INT, _NO_INT, _NO_FLOAT, data)
    if k > len(slot):
        raise RuntimeError(f"the Newton matrix has more entries than its pattern ({len(slot)})")
    if k < len(slot):
        raise RuntimeError(f"the Newton matrix has {k} entries, its pattern {len(slot)}")
    return data


@njit(cache=True)
def csc_slots(rows, cols, n, indptr):
    """The compressed-column pattern of the triplets ``(rows, cols)`` of an ``n x n`` matrix
    and the place of each triplet in it: returns ``(slot, indices)`` and fills ``indptr``
    (``n + 1``), the rows of each column sorted and unique, as ``np.unique`` of the keys
    ``cols n + rows`` gives them. The triplets are bucketed by column (a counting sort) and
    each column's rows sorted alone, where ``np.unique`` sorts all the keys at once: linear
    in the triplets but for the short sorts of the columns, against ``n log n`` of one sort.
    The triplets' places, the slots and the rows are of the type of ``rows`` (32 bits where
    the triplets and the rows fit in it: ``_Pattern``)."""
    ntrip = rows.shape[0]
    start = np.zeros(n + 1, dtype=np.int64)
    for k in range(ntrip):
        start[cols[k] + 1] += 1
    for j in range(n):
        start[j + 1] += start[j]
    order = np.empty(ntrip, dtype=rows.dtype)
    fill = start[:n].copy()
    for k in range(ntrip):
        c = cols[k]
        order[fill[c]] = k
        fill[c] += 1
    slot = np.empty(ntrip, dtype=rows.dtype)
    indices = np.empty(ntrip, dtype=rows.dtype)
    key = np.empty(ntrip, dtype=rows.dtype)  # the rows of the triplets in ``order``
    for q in range(ntrip):
        key[q] = rows[order[q]]
    nnz = 0
    for j in range(n):
        a, b = start[j], start[j + 1]
        # the column's triplets by row: a Shell sort (Knuth's gaps), written out because
        # numba's argsort takes seconds to compile, more than the sort of a small case
        gap = 1
        while gap < (b - a) // 3:
            gap = 3 * gap + 1
        while gap > 0:
            for i in range(a + gap, b):
                kv, ov = key[i], order[i]
                q = i
                while q - gap >= a and key[q - gap] > kv:
                    key[q] = key[q - gap]
                    order[q] = order[q - gap]
                    q -= gap
                key[q], order[q] = kv, ov
            gap //= 3
        indptr[j] = nnz
        last = -1
        for q in range(a, b):
            if key[q] != last:
                last = key[q]
                indices[nnz] = last
                nnz += 1
            slot[order[q]] = nnz - 1
    indptr[n] = nnz
    return slot, indices[:nnz].copy()


class _PermutedLU:
    """LU factors of ``P J P^T`` (``P x = x[order]``) that solve ``J x = b``."""

    def __init__(self, lu, order: np.ndarray):
        self.lu, self.order = lu, order

    def solve(self, b: np.ndarray) -> np.ndarray:
        x = np.empty_like(b)
        x[self.order] = self.lu.solve(b[self.order])
        return x


class _Pattern:
    """The fixed sparsity of the Newton matrix and a fill-reducing order, found once.

    ``pardiso``: factorise by PARDISO (``nscd/pardiso.py``), which finds its own order at its
    analysis of the pattern (once); otherwise by SuperLU, as follows.

    Every Newton matrix of a scene has the same pattern (the same bodies, points and free
    dofs; ``jacobian_coo(..., keep_zeros=True)`` emits the same triplets in the same order), so
    the place of each triplet in the CSC arrays is computed once and a matrix is summed
    straight into its values (``jacobian_values``) instead of a COO to CSC conversion. The symmetric minimum-degree
    order of SuperLU (``MMD_AT_PLUS_A``) is also computed once, at the first factorisation,
    and the later matrices are factorised already permuted, in their natural order: the same
    fill in L + U as an order computed for each matrix, without the conversion and the
    ordering at every factorisation.
    """

    #: triplets from which the pattern is sorted by the compiled kernel (``_slots``)
    KERNEL_TRIPLETS = 1_000_000

    def __init__(self, rows: np.ndarray, cols: np.ndarray, n: int, pardiso: bool = False):
        self.n = n
        self.slot = self._slots(rows, cols)
        self.order = None  # P x = x[order]; None until the first factorisation
        self._pardiso = pardiso_solver.Pardiso(self.indptr, self.indices, n) if pardiso else None
        if pardiso:
            self._rows = self._cols = None  # no reordering of the triplets: not needed

    def _slots(self, rows, cols) -> np.ndarray:
        """CSC arrays of the pattern of (rows, cols) and the slot of each triplet: by
        ``np.unique`` of the keys ``cols n + rows`` up to ``KERNEL_TRIPLETS`` triplets, by the
        compiled :func:`csc_slots` above (the same arrays; its compilation would add to a small
        case's first run more than it saves). The slots and the rows in 32 bits where the
        triplets and the rows fit (``index_type``): 4 bytes per triplet and per entry less
        than 64 bits, and PARDISO takes the rows as they are, without a copy of its own."""
        n = self.n
        kind = index_type(max(len(rows), n))
        rows, cols = np.asarray(rows, dtype=kind), np.asarray(cols, dtype=kind)
        self._rows, self._cols = rows, cols
        if len(rows) >= self.KERNEL_TRIPLETS:
            self.indptr = np.empty(n + 1, dtype=np.int64)
            slot, self.indices = csc_slots(rows, cols, n, self.indptr)
            return slot
        uniq, slot = np.unique(cols.astype(np.int64) * n + rows, return_inverse=True)
        self.indptr = np.searchsorted(uniq // n, np.arange(n + 1)).astype(np.int64)
        self.indices = (uniq % n).astype(kind)
        return slot.astype(kind)

    def sibling(self) -> _Pattern | None:
        """The same pattern with a PARDISO handle of its own (its own analysis and
        factorisation), for a solver of the same scene with another step size; None for a
        SuperLU pattern (its order and slots change at its first factorisation)."""
        if self._pardiso is None:
            return None
        other = copy.copy(self)  # the arrays shared, not copied
        other._pardiso = pardiso_solver.Pardiso(self.indptr, self.indices, self.n)
        return other

    def values(self, vals: np.ndarray) -> np.ndarray:
        """The CSC values of the matrix of the triplet values ``vals`` (in the current order),
        summed in the triplets' order as ``jacobian_values`` sums them."""
        return np.bincount(self.slot, weights=vals, minlength=len(self.indices))

    def matrix(self, data: np.ndarray) -> sp.csc_matrix:
        """The matrix of the CSC values ``data`` (in the current order)."""
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    def factorise(self, data: np.ndarray, pivoting: bool = False):
        """LU of the matrix of the CSC values ``data``: with diagonal pivots (SuperLU;
        RuntimeError on a zero pivot), by PARDISO for a ``pardiso`` pattern (its own pivoting;
        ``PardisoError``, a RuntimeError, when it fails), or with partial pivoting
        (``pivoting``: SuperLU, robust and slower, whatever the pattern)."""
        if pivoting:
            lu = spla.splu(self.matrix(data))
            return lu if self.order is None else _PermutedLU(lu, self.order)
        if self._pardiso is not None:
            return self._pardiso.factorise(data)
        opts = {"SymmetricMode": True}
        if self.order is None:
            lu = spla.splu(self.matrix(data), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options=opts)
            # J[r, c] is entry (place[r], place[c]) of P J P^T
            place = lu.perm_c.astype(np.int64)
            self.order = np.argsort(place)
            self.slot = self._slots(place[self._rows], place[self._cols])
            self._rows = self._cols = None  # not needed again (two indices per triplet)
            return lu
        lu = spla.splu(self.matrix(data), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                       options=opts)
        return _PermutedLU(lu, self.order)


class _ChordHistory:
    """The Anderson acceleration's memory (``NewtonSolver._anderson``): the last iterate and
    its chord step ``last``, the differences ``d_x``, ``d_f`` of both over the last steps
    with one matrix, and the weights of the unknowns in the least squares."""

    def __init__(self, weight: np.ndarray):
        self.weight = weight
        self.clear()

    def clear(self) -> None:
        """Forget the steps (a new matrix, or a step that was not a full one)."""
        self.last, self.d_x, self.d_f = None, [], []


class NewtonSolver:
    """Semi-smooth Newton (chord) solver of one step; keeps its factorisation between steps."""

    def __init__(self, sys, mhat_off, mhat, tolerance: float, max_iterations: int = 50,
                 params: np.ndarray | None = None, linear: str = "lu",
                 node_xyz: list[np.ndarray | None] | None = None):
        """``linear``: the solver of the Newton matrix (``linear.LINEAR_SOLVERS``; ``auto``
        picks by the number of unknowns); ``node_xyz``: each body's node coordinates (m; None
        for a rigid body), for the rigid-body modes of the Krylov solver's coarse space."""
        self.sys = sys
        self.mhat_off = mhat_off
        self.use_mhat(mhat)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        free = np.ones(sys.ndof, dtype=bool)
        free[sys.imposed_dofs] = False
        self.free = np.flatnonzero(free)
        self.free_index = np.full(sys.ndof, -1, dtype=np.int64)
        self.free_index[self.free] = np.arange(len(self.free))
        # Points whose impulses are unknowns ("multipliers"): the glue, and the joints of a
        # rigid Signorini-Coulomb law (friction coefficient ``mu``; -1 marks the glue)
        mu = np.full(sys.npt, np.nan)
        mu[sys.kind == laws.KIND_GLUED] = -1.0
        if params is not None:
            for row, P in enumerate(np.atleast_2d(params)):
                f = laws.rigid_friction(P)
                if f is not None:
                    mu[(sys.kind == laws.KIND_JOINT) & (sys.law == row)] = f
        self.mult = np.flatnonzero(~np.isnan(mu))
        self.mult_of = np.full(sys.npt, -1, dtype=np.int64)
        self.mult_of[self.mult] = np.arange(len(self.mult))
        self.mu = mu[self.mult]
        self.glue_rows = np.repeat(self.mu < 0.0, 3)
        self.rigid_rows = ~self.glue_rows
        self.has_rigid = bool(self.rigid_rows.any())
        # the mean diagonal of each point's Delassus matrix (1/kg), and rho = 1 / (theta h w)
        # of the Alart-Curnier function
        trace = np.trace(sys.W[self.mult], axis1=1, axis2=2)
        self.w = trace / 3.0
        self.rho = 1.0 / (sys.theta * sys.h * self.w)
        # Compliance of the multipliers (1/kg): 1e-9 of the point's own Delassus diagonal. It
        # makes the Newton matrix quasi-definite when glue points outnumber the dofs of the face
        # they hold (8 points on the 6 nodes of a 2 x 1 face quad pair), or rigid contacts those
        # of the bodies they hold (4 points on a face of a rigid block), and moves the glue or
        # the contact by 1e-9 of the relative displacement it resists.
        self.eps = 1e-9 * trace / 3.0
        self.scales = Scales(self)
        self.lu = None
        self.factorisations = 0
        # the linear solver, resolved by size; Krylov solves made again by LU, and why
        self.linear = linear_solvers.choose(linear, len(self.free) + 3 * len(self.mult),
                                            mpi.launched_processes())
        self.linear_fallbacks = 0
        self.linear_notes: list[str] = []
        self._krylov = None
        self._krylov_pattern: _Pattern | None = None
        if self.linear == "krylov":
            if node_xyz is None:
                raise ValueError("the krylov linear solver needs the bodies' node coordinates")
            modes = linear_solvers.rigid_body_modes(sys.body_dof0, sys.body_deformable,
                                                    node_xyz)[self.free]
            body_of = np.searchsorted(sys.body_dof0, self.free, side="right") - 1
            self._krylov = mpi.krylov_solver(body_of, modes)
        self._K_factorised = None
        # (blocks, pattern's slots, their values and count or None): ``_bodies_values``
        self._bodies_part: tuple | None = None
        # fixed pattern and order of the Newton matrix, found at the first factorisation
        self._pattern: _Pattern | None = None
        # called before refactorising when the iterations slow down or a direction fails (a
        # refresh of the material's part of the matrix)
        self.on_slow = None
        # a list to receive (iteration, residual, merit norm, step length, refactorised, index
        # and value of the largest residual entry, and the three parts of the residual: change
        # of the tractions, momentum, rigid contacts' rows) per iteration, for diagnosis; None
        # (the default) records nothing
        self.trace = None
        # refactorise when the residual falls by less than this per iteration, two in a row
        self.slow_rate = 0.6
        # depth of the Anderson acceleration of the chord iterations (0: plain chord steps)
        self.anderson = 5
        # the solutions of the last two steps, for the predictor of the next one: (end time s,
        # None when not given; body velocities, multipliers' impulses N s, step size s)
        self._solutions: list[tuple[float | None, np.ndarray, np.ndarray, float]] = []
        # steps given up because their iterations cycled (``_Cycle``)
        self.cycles = 0

    def use_mhat(self, mhat: np.ndarray | None) -> None:
        """Use the bodies' blocks ``mhat`` (flat at ``mhat_off``) in the residual and the
        matrix: at the start, and when the integrator's system makes them again after it let
        go of them (``Integrator.release``; None while it has, the matrices' values that the
        blocks make let go of too)."""
        self.mhat = mhat
        self.mhat_op = None if mhat is None else BlockDiagonal(self.sys.body_dof0,
                                                               self.mhat_off, mhat)
        self._mhat_without: tuple[tuple | None, BlockDiagonal | None] = (None, None)
        # the body blocks of the Newton matrix; the ENDO3D blocks' tangent may replace the
        # elastic one (``set_iteration_mhat``), the residual keeps the elastic decomposition
        self.mhat_jac = mhat
        self._bodies_part = None

    def mhat_without(self, bodies) -> BlockDiagonal | None:
        """The product by ``M_hat`` of every body but ``bodies`` (zero on their dofs), kept for
        the next calls with the same bodies; None when their blocks cannot be left out of the
        groups of ``M_hat`` (bodies of one size not all in ``bodies``, laid out between them)."""
        key = tuple(bodies)
        if self._mhat_without[0] != key:
            self._mhat_without = (key, block_diagonal.without(self.sys.body_dof0,
                                                              self.mhat_off, self.mhat, key))
        return self._mhat_without[1]

    @property
    def linear_iterations(self) -> int:
        """Krylov iterations of all the linear solves so far (0 with LU)."""
        return 0 if self._krylov is None else self._krylov.iterations

    @property
    def linear_engine(self) -> str:
        """What makes the Krylov solves on several processes (PETSc's KSP and preconditioner,
        ``petsc_solve.py``), after the first set-up; empty otherwise."""
        describe = getattr(self._krylov, "describe", None)
        return describe() if describe is not None and self.factorisations else ""

    def _linear_solve(self, b: np.ndarray) -> np.ndarray:
        """``J0^-1 b`` with the matrix in place; a Krylov solve that does not converge is made
        again by an LU factorisation of the same matrix (counted in ``linear_fallbacks``, the
        reason in ``linear_notes``)."""
        try:
            with timing.part("linear solve"):
                return self.lu.solve(b)
        except linear_solvers.KrylovFailure as exc:
            self.linear_fallbacks += 1
            self.linear_notes.append(f"{exc}: the Newton matrix factorised by LU instead")
            tangents, self._K_factorised = self._K_factorised, None
            self.lu = None
            self._factorise(tangents, direct=True)
            return self.lu.solve(b)

    def remembered(self) -> list:
        """The last steps' solutions that the predictor extrapolates (a copy of the list, for
        :meth:`remember`)."""
        return list(self._solutions)

    @staticmethod
    def extrapolates(solutions: list) -> bool:
        """Whether a step predicted from ``solutions`` (:meth:`remembered`) starts from their
        extrapolation (:meth:`_predict`) rather than from the free velocities."""
        return len(solutions) == 2

    def remember(self, solutions: list) -> None:
        """Predict the next step from ``solutions`` (:meth:`remembered` of a solver of the same
        scene, of any step size: the predictor extrapolates along the time); ``[]``: from the
        free velocities."""
        self._solutions = list(solutions)

    def adopt_solutions(self, other: NewtonSolver) -> None:
        """Predict from the last steps of ``other``, a solver of the same scene with another
        step size (the adaptive step size's integrators hand the run over to one another)."""
        self.remember(other.remembered())

    def share_pattern(self, other: NewtonSolver) -> None:
        """Use the patterns of ``other``, a solver of the same scene with another step size:
        they depend on the bodies, the points and the free dofs only, so the adaptive step's
        rungs and the halves need not make theirs (the time of making a pattern, and the slots'
        memory, 4 bytes per triplet, grow with the wall). A PARDISO pattern is shared
        with a handle of its own (``_Pattern.sibling``): a handle keeps one factorisation."""
        if not (np.array_equal(self.free, other.free) and np.array_equal(self.mult, other.mult)):
            return
        if self._krylov is not None and other._krylov is not None:
            self._krylov.share(other._krylov)
        if self._krylov is not None and other._krylov_pattern is not None:
            self._krylov_pattern = other._krylov_pattern
        if self._pattern is None and other._pattern is not None:
            self._pattern = other._pattern.sibling()

    def release(self) -> None:
        """Let go of the Krylov solver's matrix and preconditioner (the body system ``S``, the
        multipliers' blocks, the local inverses and the blocks they were made of, the coarse
        factor) while the run makes its steps with another step size: about 4.6 kB per
        contact point of the study's walls (docs/scaling.md). The next step of this solver
        starts with a new set-up at its first iterate, where it would have started with the
        matrix of its last step: other iterates, as after any refactorisation. Nothing with
        a direct solver (its factors in PARDISO's handle, and the shipped cases' iterates
        kept) or PETSc's (``petsc_solve.py``)."""
        if type(self._krylov) is not linear_solvers.KrylovSolver:
            return
        self.lu = None
        self._K_factorised = None
        self._krylov.release()

    def set_iteration_mhat(self, mhat_jac: np.ndarray) -> None:
        """Use other body blocks (same layout as ``mhat``) in the Newton matrix."""
        self.mhat_jac = mhat_jac
        self.lu = None

    def jacobian_args(self, tangents) -> tuple:
        """The arguments of ``jacobian_coo`` and, after the slot and the size, of
        ``jacobian_values`` for the Newton matrix with ``tangents = (K, Gu, Gr)``."""
        s = self.sys
        return (s.body_dof0, self.mhat_off, self.mhat_jac, self.free_index, len(self.free),
                s.side_dofs, s.side_coef, self.mult_of, s.area, *tangents, self.mu >= 0.0, s.h,
                s.theta)

    def _factorise(self, tangents, pivoting: bool = False, direct: bool = False):
        """Factorise the Newton matrix with the joint tangents and the multipliers' derivatives
        ``tangents = (K, Gu, Gr)`` (sparse LU), unless the factorisation in place is already of
        that matrix; ``pivoting``: partial pivoting (the robust, slower factorisation) instead
        of diagonal pivots; ``direct``: by LU whatever ``linear`` says (the Krylov solver's
        fallback)."""
        K, Gu, Gr = tangents
        if self.lu is not None and self._K_factorised is not None and \
                all(np.array_equal(x, y) for x, y in zip(tangents, self._K_factorised,
                                                          strict=True)):
            return  # the same matrix: refactorising would not help
        self._K_factorised = (K.copy(), Gu.copy(), Gr.copy())
        n = len(self.free) + 3 * len(self.mult)
        if self._krylov is not None and not (pivoting or direct):
            with timing.part("Krylov operator"):
                B, C, Dinv = self._multipliers(Gu, Gr)
            # the multipliers enter S as coef_i (D^-1 Gu) coef_j (``_jacobian_entries``)
            S = self._body_system(self.jacobian_args((K, Gu if Dinv is None else Dinv @ Gu,
                                                      Gr)))
            self.lu = self._krylov.factorise_system(
                S, B, C, None if Dinv is None else linear_solvers.block_diagonal(Dinv))
            self.factorisations += 1
            return
        args = self.jacobian_args(tangents)
        pat = self._pattern
        if pat is None:
            with timing.part("Newton matrix pattern"):
                r, c = jacobian_coo(*args, True, values=False)
                pat = self._pattern = _Pattern(r, c, n, pardiso=self.linear == "pardiso")
                del r, c
                data = jacobian_values(pat.slot, len(pat.indices), *args)
        else:
            with timing.part("Newton matrix"):
                data = jacobian_values(pat.slot, len(pat.indices), *args,
                                       bodies=self._bodies_values(pat, args))
        self.lu = None
        with timing.part("factorisation"):
            if not pivoting:
                # the pattern is symmetric and the diagonal dominant enough (mass, springs,
                # glue compliance): symmetric ordering, pivots on the diagonal, which gives
                # less fill than COLAMD and faster solves than partial pivoting
                with contextlib.suppress(RuntimeError):  # a zero pivot: pivot after all
                    self.lu = pat.factorise(data)
            if self.lu is None:
                self.lu = pat.factorise(data, pivoting=True)
        self.factorisations += 1

    def _bodies_values(self, pat: _Pattern, args) -> tuple[np.ndarray, int] | None:
        """The Newton matrix's values from the bodies' blocks alone (``bodies_values``), kept
        from the second matrix with the same blocks (``mhat_jac``) and pattern on: the elastic
        blocks' never change, and they are about half of a fill's entries on a wall. None at
        the first matrix of new blocks (the ENDO3D blocks have a new tangent at every
        refresh: their fills stay whole, with nothing kept)."""
        held = self._bodies_part  # keyed by the slots: SuperLU's first LU reorders them
        if held is None or held[0] is not self.mhat_jac or held[1] is not pat.slot:
            self._bodies_part = (self.mhat_jac, pat.slot, None)
            return None
        if held[2] is None:
            self._bodies_part = (held[0], held[1],
                                 bodies_values(pat.slot, len(pat.indices), *args))
        return self._bodies_part[2]

    def _body_system(self, args) -> sp.csr_matrix:
        """The Krylov solver's body system ``S = A + B D^-1 C`` (free dofs, CSR), summed
        straight into its own fixed pattern (``jacobian_values(..., eliminate=True)``; no
        Newton matrix is made); ``args``: ``jacobian_args`` with ``D^-1 Gu`` for ``Gu``."""
        nf = len(self.free)
        pat = self._krylov_pattern
        if pat is None:
            with timing.part("Newton matrix pattern"):
                r, c = jacobian_coo(*args, True, True, values=False)
                # the pattern of S^T in compressed columns: S in compressed rows
                pat = self._krylov_pattern = _Pattern(c, r, nf)
                pat._rows = pat._cols = None  # never reordered
                del r, c
                data = jacobian_values(pat.slot, len(pat.indices), *args, eliminate=True)
        else:
            with timing.part("Newton matrix"):
                data = jacobian_values(pat.slot, len(pat.indices), *args, eliminate=True)
        if self._krylov is not None and self._krylov.structure is None:
            # the coarse LU's pattern, analysed once
            self._krylov.structure = (pat.indptr, pat.indices)
        # the pattern holds every entry that can be non-zero (the bodies' blocks whole, the
        # open joints' zeros): without the zeros the products of GMRES are a third cheaper
        return linear_solvers.nonzero_csr(pat.indptr, pat.indices, data, nf)

    def _multipliers(self, Gu, Gr):
        """``(B, C, D^-1)`` of the multipliers (None when there are none): the blocks of the
        Newton matrix that the Krylov solver's elimination needs, ``B = -J[:nf, nf:]`` and
        ``C = J[nf:, :nf]`` (sparse), and the inverses ``(m, 3, 3)`` of the blocks of
        ``D = J[nf:, nf:]`` (``Gr``, or its diagonal unless the point is a rigid contact)."""
        m = len(self.mult)
        if m == 0:
            return None, None, None
        s = self.sys
        nf = len(self.free)
        d = s.side_dofs[self.mult]  # (m, 2, j); -1 past a side's last dof
        fi = np.where(d >= 0, self.free_index[np.maximum(d, 0)], -1)
        on = fi >= 0
        coef = s.side_coef[self.mult]  # (m, 2, j, 3)
        g = np.broadcast_to(np.arange(m)[:, None, None], d.shape)[on]
        rows = np.repeat(fi[on], 3)
        cols = (3 * g[:, None] + np.arange(3)).ravel()
        B = sp.csr_matrix((coef[on].ravel(), (rows, cols)), shape=(nf, 3 * m))
        # C[3 g + c, j] = Gu[g, c, :] . coef_j
        cv = np.einsum("gce,gsje->gsjc", Gu, coef)[on].ravel()
        C = sp.csr_matrix((cv, (cols, rows)), shape=(3 * m, nf))
        D = np.where(self.mu[:, None, None] >= 0.0, Gr, Gr * np.eye(3))
        return B, C, np.linalg.inv(D)

    def _refresh(self, K) -> None:
        """Factorise the matrix of the current iterate: the material's part refreshed
        (``on_slow``), the joints' tangents and the multipliers' derivatives ``K``."""
        if self.lu is not None and self.on_slow is not None:
            self.on_slow()
        self.lu = None
        self._factorise(K)

    def _line_search(self, residual: StepResidual, v, r_glue, dx, norm, fresh,
                     halve: bool = True):
        """Backtracking on the merit norm from ``(v, r_glue)`` along ``dx``: halve the step
        until the norm decreases (Armijo, 1e-4) or the step falls below 0.01 (``halve``
        False: the whole step only). Returns ``(alpha, descent, v, r_glue, evaluation)`` at
        the step taken.

        When no step decreases the norm along a direction from the matrix of this iterate
        (``fresh``), the full step is taken all the same: the residual is only piecewise
        smooth (a joint or an ENDO3D point at the kink between its elastic and softening
        branches, e.g. a crack about to open), the Newton direction of one branch is not one of
        descent across the kink, and short steps stall there, where the full step crosses the
        kink and the iterations converge on the other branch.
        """
        nf = len(self.free)
        alpha = 1.0
        first = None
        while True:
            v_try = v.copy()
            v_try[self.free] += alpha * dx[:nf]
            r_try = r_glue + alpha * dx[nf:]
            ev = residual(v_try, r_try)
            descent = ev.norm <= (1.0 - 1e-4 * alpha) * norm
            if descent:
                return alpha, True, v_try, r_try, ev
            if not halve:
                return alpha, False, v_try, r_try, ev
            if alpha < 0.01:
                if not fresh:
                    return alpha, False, v_try, r_try, ev
                # the full step, evaluated again so that the material's trial states are its own
                return 1.0, False, first[0], first[1], residual(first[0], first[1])
            if first is None:
                first = (v_try, r_try)
            alpha *= 0.5

    def _anderson(self, x, f, last, d_x, d_f, weight) -> np.ndarray:
        """The chord step ``f`` at ``x``, accelerated (Anderson, type II) with the history of
        the iterates ``x_i`` and their chord steps ``f_i = -J0^-1 F(x_i)`` (same matrix J0):

            gamma = argmin || W (f - dF gamma) ||_2,   step = f - (dX + dF) gamma

        with ``dX``, ``dF`` the differences of consecutive iterates and steps (the last
        ``anderson`` of them; ``d_x``, ``d_f`` are updated in place) and ``W`` the weights of
        the unknowns. For a linear residual this is GMRES preconditioned by J0; a stale
        factorisation whose plain steps shrink the residual by 0.5 per iteration (the
        reference wall) converges in about half the iterations.

        The least squares by the normal equations, ``G = (W dF)^T (W dF)`` (at most
        ``anderson`` x ``anderson``) diagonalised, its eigenvalues below 1e-14 of the largest
        left out (differences that the history repeats to 1e-7, where the rounding of ``G``
        would decide the mixture), instead of an SVD of the tall ``W dF`` (docs/choices.md).
        """
        d_x.append(x - last[0])
        d_f.append(f - last[1])
        if len(d_x) > self.anderson:
            del d_x[0], d_f[0]
        DF = np.column_stack(d_f)
        A = DF * weight[:, None]
        lam, Q = np.linalg.eigh(A.T @ A)
        keep = lam > 1e-14 * lam[-1]
        Q = Q[:, keep]
        gamma = Q @ ((Q.T @ (A.T @ (f * weight))) / lam[keep])
        return f - (np.column_stack(d_x) + DF) @ gamma

    def _predict(self, v_free, dv_guess, T, t_end):
        """The iterate Newton starts from: ``(v, r_glue)``, body velocities (m/s) and the
        multipliers' impulses (N s)."""
        s = self.sys
        h = s.h
        g = self.mult
        if self.extrapolates(self._solutions):
            # the solution of the step extrapolated linearly from the last two: in a slow,
            # smooth loading both change at a steady rate, so the extrapolation starts the
            # iterations closer to the solution than the last step's values do;
            # velocities and impulses per unit time, along the time when the sizes differ
            (t1, v1, r1, h1), (t2, v2, r2, h2) = self._solutions
            ratio = 1.0 if None in (t_end, t1, t2) else (t_end - t2) / (t2 - t1)
            if abs(ratio - 1.0) < 1e-9 and h1 == h2 == h:
                v = 2.0 * v2 - v1
                r_glue = 2.0 * r2 - r1
            else:
                v = v2 + ratio * (v2 - v1)
                r_glue = h * (r2 / h2 + ratio * (r2 / h2 - r1 / h1))
        else:
            v = v_free + dv_guess
            r_glue = (-h * s.area[g, None] * T[g]).ravel()
        v[s.imposed_dofs] = v_free[s.imposed_dofs]
        return v, r_glue

    def _move(self, residual: StepResidual, v, r_glue, ev: Evaluation, fresh: bool,
              history: _ChordHistory, whole: bool = False):
        """One iteration from ``(v, r_glue)`` with its evaluation ``ev``: the direction of the
        matrix in place (``fresh``: factorised at this iterate), accelerated, along which the
        line search steps (``whole``: a fresh direction taken whole, after the iterations
        crept). Returns ``(ev, alpha, fresh, v, r_glue, ev_next)``: the evaluation
        of this iterate (made again when the matrix had to be refreshed), the step length,
        whether the direction came from a fresh matrix, and the next iterate."""
        pivoted = False
        while True:
            dx = self._linear_solve(-ev.F)
            # one product instead of isfinite and all (one pass, no temporary array): NaN
            # or inf in dx make it NaN or inf (so would entries of some 1e154: as broken)
            finite = math.isfinite(float(dx @ dx))
            if not finite and not pivoted:
                # an unstable factorisation (diagonal pivots): refresh, with pivoting if the
                # matrix was fresh already
                if self.on_slow is not None and not fresh:
                    self.on_slow()
                self.lu = None
                pivoted = fresh
                self._factorise(residual.tangents(ev), pivoting=pivoted)
                fresh = True
                continue
            if not finite:  # singular even with pivoting: no step
                dx = np.zeros_like(dx)
            x = np.concatenate([v[self.free], r_glue])
            if fresh:
                history.clear()
            accelerated = history.last is not None and self.anderson > 0
            step = self._anderson(x, dx, history.last, history.d_x, history.d_f,
                                  history.weight) if accelerated else dx
            history.last = (x, dx)
            if whole and fresh:
                # the iterations crept (``_Stall``): the fresh direction whole, whatever the norm
                alpha, descent, v_try, r_try, ev_try = self._line_search(
                    residual, v, r_glue, dx, ev.norm, True, halve=False)
                return ev, alpha, fresh, v_try, r_try, ev_try
            # an accelerated step is taken whole or not at all: where it does not decrease the
            # norm, the plain step's line search follows (a shorter accelerated step was thrown
            # away for the plain one all the same)
            alpha, descent, v_try, r_try, ev_try = self._line_search(
                residual, v, r_glue, step, ev.norm, fresh and not accelerated,
                halve=not accelerated)
            if alpha != 1.0 or not descent:
                history.clear()
                if accelerated:
                    alpha, descent, v_try, r_try, ev_try = self._line_search(
                        residual, v, r_glue, dx, ev.norm, fresh)
            if descent or fresh:
                return ev, alpha, fresh, v_try, r_try, ev_try
            # a direction from an older matrix that does not decrease the residual: the
            # tangents moved (a joint or a material point began to soften); retry from the
            # same point with the matrix of this iterate (evaluated again: the material's
            # trial states must be those of this iterate, not of the last trial step)
            ev = residual(v, r_glue)
            self._refresh(residual.tangents(ev))
            fresh = True

    def solve(self, v_free, u_old, U_old, params, uc_old, beta_old, T, dv_guess,
              correction=None, t_end: float | None = None):
        """Solve the step. Returns (v, T, uc, beta, status, iterations, residual).

        ``t_end`` (s): the time the step ends at, for the predictor when the last steps had
        another size (None: they had this one).

        Each iteration: the law at every joint point and the residual
        (``step_residual.StepResidual``), a solve with the current factorisation
        (refactorised, with the joints' tangents at that iterate, when the iterations slow
        down), and a backtracking line search on the residual norm (glue rows scaled to
        impulse units), which stops the cycling between open and closed statuses that full
        steps show when the loads are tiny (the open joint is some 300 times softer than the
        closed one).

        ``correction``: a material correction of the body residual (N s), for blocks whose
        internal forces are not linear (ENDO3D), and the size of the internal impulses it
        corrects (``integrator.MaterialCorrection``; ``StepResidual`` says how it is called);
        its relative change between iterates joins the convergence test.
        """
        residual = StepResidual(self, v_free, u_old, U_old, params, uc_old, beta_old, T,
                                correction)
        v, r_glue = self._predict(v_free, dv_guess, T, t_end)
        ev = residual(v, r_glue)
        T_prev, c_prev = T, None
        res = math.inf
        prev = prev2 = math.inf
        it = 0
        # Anderson history: the last iterate and its chord step, and the differences of both
        # over the last full steps with this matrix, weighted to velocity units
        history = _ChordHistory(self.scales.weight)
        stall = _Stall()
        whole = False  # the next fresh direction taken whole (the iterations crept)
        cycle = _Cycle()
        for it in range(1, self.max_iterations + 1):
            res, num, den = residual.convergence(ev, T_prev, c_prev)
            if it > 1 and res <= self.tolerance:
                break
            if cycle.closed_by(ev.norm, res):  # given up, to be made again as halves
                self.cycles += 1
                break
            # refactorise only when two iterations in a row converged slower than slow_rate: an
            # LU of the wall costs about fifteen iterations, and the accelerated iterations do
            # not shrink the residual steadily (one slow iteration is no sign of a stale matrix)
            slow = it > 3 and res > self.slow_rate * prev and prev > self.slow_rate * prev2
            fresh = self.lu is None or slow
            if fresh:
                self._refresh(residual.tangents(ev))
            prev2, prev = prev, res
            T_prev, c_prev = ev.T, ev.correction
            ev, alpha, fresh, v, r_glue, ev_next = self._move(residual, v, r_glue, ev, fresh,
                                                               history, whole)
            # (kept until a fresh direction takes it)
            whole = stall.after(fresh, alpha, ev.norm, ev_next.norm) or (whole and not fresh)
            if self.trace is not None:
                worst = int(np.argmax(np.abs(ev.F)))
                self.trace.append((it, res, ev.norm, alpha, fresh, worst, float(ev.F[worst]),
                                   *residual.parts(ev, num, den)))
            ev = ev_next
        self._solutions = [*self._solutions[-1:], (t_end, v.copy(), r_glue.copy(), self.sys.h)]
        return v, ev.T, ev.uc, ev.beta, ev.status, it, res
