r"""Linear solves of the Newton matrix: sparse LU, or GMRES with a two-level block preconditioner.

The Newton matrix of a step (``newton.py``) has the body part and the rows of the points whose
impulses are unknowns (glue, rigid contacts), ``m`` of them with three rows each::

    J = [[ A , -B ],      A = M_hat + h^2 theta sum_a S_a H_a K_a H_a^T   (kg, free dofs)
         [ C ,  D ]]      B = H_g,  C = H_g^T (glue) or Gu H_g^T,  D = eps I (glue) or Gr

``D`` is block diagonal (3 x 3 per point, never singular: the compliance ``eps``). Both
solvers answer ``J x = b`` for the matrix last given to ``factorise``; the Newton iterations
call ``solve`` on whatever ``factorise`` returned and do not care which one it is.

``lu``: SuperLU in a fixed order (``newton._Pattern``): exact, its fill (and so its memory and
time) growing faster than the matrix.

``krylov``: the multipliers are eliminated exactly (``D`` is block diagonal), which leaves the
body system

    S v = b_v + B D^-1 b_g,   S = A + B D^-1 C,   then r = D^-1 (b_g - C v)

(the glue as the penalty ``1 / eps`` it is; the Newton solver sums ``S`` straight into a
fixed pattern, ``newton.jacobian_values(..., eliminate=True)``, and gives it with ``B``, ``C``
and ``D^-1`` to ``factorise_system``: no Newton matrix is made and sliced, which on a large wall would cost
a large share of a step in scipy's slicing and products), solved by restarted GMRES with a two-level
multiplicative preconditioner over the bodies, the coarse level first::

    y = R S_0^-1 R^T b,   P^-1 b = y + S_loc^-1 (b - S y)

``S_loc``: the diagonal blocks of ``S``, one per body (its own ``M_hat``, the springs of its
joints and its glue), inverted densely; ``R`` (dofs x 6 bodies): the six rigid-body motions of
every body (``rigid_body_modes``); ``S_0 = R^T S R``: the wall as rigid blocks on the joints'
springs, 6 unknowns per body, factorised by sparse LU. The local solves take the deformation
inside each block, the coarse one the motion of the blocks against one another, which a
one-level (block-Jacobi) method would need about as many iterations as there are blocks across
the wall to carry. Each iteration costs two products with ``S`` (GMRES's and this one's), one
with ``S_loc^-1`` and one coarse solve: all linear in the bodies for a wall (the coarse LU has
6 unknowns per block and the two-dimensional connectivity of a wall). A second coarse
correction after the local one (``z + R S_0^-1 R^T (b - S z)``) saves a few iterations but
costs a third product and a second coarse solve in each (docs/scaling.md). The local inverses
are kept as dense blocks grouped by size and applied by one stacked product per size, not as a
sparse matrix, and only the blocks that moved by more than ``block_tolerance`` (1e-3 of their
Frobenius norm) since their inverse was made are inverted again: the joints' cohesive damage
moves most blocks a little at every set-up, and an inverse good to 1e-3 is as good a
preconditioner (docs/scaling.md). The setup (``factorise``) is redone only where the LU would
be refactorised: a preconditioner of an earlier matrix is a poor one for the new matrix, as the
joints' springs change by orders of magnitude when they open or close (docs/scaling.md). The
solution of the previous solve (the iteration or the step before) starts GMRES when
its residual is below that of zero. A solve whose relative residual ``|rhs - S v| / |rhs|``
stays above ``rtol`` after ``max_iterations`` is reported (``KrylovFailure``): the Newton
solver then factorises the same matrix by LU and says so.

``pardiso``: the sparse LU of Intel MKL (``nscd/pardiso.py``), in the same fixed pattern as
``lu``: the same solutions to round-off, faster factorisations (docs/performance.md).

``auto`` picks ``pardiso`` (``lu`` where MKL is not installed) below ``KRYLOV_MIN_UNKNOWNS``
unknowns, ``krylov`` from there. The environment variable ``MASONRY_DIRECT_SOLVER`` (``lu`` or
``pardiso``) names the direct solver that ``auto`` picks instead: the way to run a whole test
suite or study with the other one; a case that names its solver keeps it.
"""

from __future__ import annotations

import copy
import math
import os

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numba import njit

from masonry_nscd import threads, timing
from masonry_nscd.nscd import pardiso

LINEAR_SOLVERS = ("auto", "lu", "pardiso", "krylov")
#: ``auto`` picks krylov from this many unknowns of the Newton matrix (free dofs and three per
#: multiplier point); below, pardiso where MKL is installed, else lu (docs/scaling.md)
KRYLOV_MIN_UNKNOWNS = 100_000
#: the environment variable that names the direct solver ``auto`` picks (module docstring)
DIRECT_SOLVER_VARIABLE = "MASONRY_DIRECT_SOLVER"
#: ``KrylovSolver.block_tolerance`` by default
BLOCK_TOLERANCE = 1e-3


def choose(linear: str, unknowns: int, processes: int = 1) -> str:
    """The linear solver ``linear`` (``auto``, ``lu``, ``pardiso``, ``krylov``) resolved for a
    Newton matrix of ``unknowns`` rows, on ``processes`` processes (``mpi.py``: only
    ``krylov`` uses more than one, and ``auto`` takes it there). ``pardiso`` where MKL is
    missing, a direct solver on several processes, or another value of
    ``MASONRY_DIRECT_SOLVER`` than ``lu`` or ``pardiso``, is a ValueError."""
    if linear not in LINEAR_SOLVERS:
        raise ValueError(f"linear solver must be one of {', '.join(LINEAR_SOLVERS)}, got "
                         f"{linear!r}")
    if processes > 1:
        if linear not in ("auto", "krylov"):
            raise ValueError(f"solver.linear: {linear} runs on one process; on {processes} "
                             f"processes give krylov or auto")
        return "krylov"
    if linear == "auto":
        if unknowns >= KRYLOV_MIN_UNKNOWNS:
            return "krylov"
        direct = os.environ.get(DIRECT_SOLVER_VARIABLE, "").strip()
        if direct not in ("", "lu", "pardiso"):
            raise ValueError(f"{DIRECT_SOLVER_VARIABLE} must be lu or pardiso, got {direct!r}")
        linear = direct or ("pardiso" if pardiso.available() else "lu")
    if linear == "pardiso" and not pardiso.available():
        raise ValueError(pardiso.MISSING)
    return linear


def rigid_body_modes(body_dof0: np.ndarray, deformable: np.ndarray,
                     node_xyz: list[np.ndarray | None]) -> np.ndarray:
    """The six rigid-body motions of every body as columns, one row per dof (``(ndof, 6)``).

    For a block with nodes ``x_i`` (m, three dofs per node, x y z) the translations ``e_k``
    and the rotations ``omega_k x (x_i - x_c)`` about its centroid ``x_c`` (m per rad); for a
    rigid body (three translations, then three rotations as its dofs) the identity."""
    modes = np.zeros((int(body_dof0[-1]), 6))
    for b in range(len(body_dof0) - 1):
        d0, d1 = int(body_dof0[b]), int(body_dof0[b + 1])
        if not deformable[b]:
            modes[d0:d1] = np.eye(d1 - d0, 6)
            continue
        x = np.asarray(node_xyz[b], dtype=float)
        x = x - x.mean(axis=0)
        block = modes[d0:d1].reshape(len(x), 3, 6)
        for k in range(3):
            block[:, k, k] = 1.0
        # omega_x: (0, -z, y); omega_y: (z, 0, -x); omega_z: (-y, x, 0)
        block[:, 1, 3], block[:, 2, 3] = -x[:, 2], x[:, 1]
        block[:, 0, 4], block[:, 2, 4] = x[:, 2], -x[:, 0]
        block[:, 0, 5], block[:, 1, 5] = -x[:, 1], x[:, 0]
    return modes


def _mode_entries(body_of: np.ndarray, modes: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The non-zero entries of the rigid-body ``modes`` (``(nf, 6)``): their free dof, their
    coarse unknown ``6 b + k`` (the mode ``k`` of the dof's body ``b``) and their value."""
    m = np.asarray(modes, dtype=float).ravel()
    rows = np.repeat(np.arange(len(body_of)), 6)
    cols = (6 * np.asarray(body_of, dtype=np.int64)[:, None] + np.arange(6)).ravel()
    on = m != 0.0
    return rows[on], cols[on], m[on]


def coarse_columns(body_of: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """The coarse unknowns some free dof moves, ``6 b + k`` for the mode ``k`` of body ``b``
    (sorted): the columns of :func:`coarse_space`, the modes of imposed motions dropped."""
    return np.unique(_mode_entries(body_of, modes)[1])


def coarse_space(body_of: np.ndarray, modes: np.ndarray) -> sp.csc_matrix:
    """``R`` (free dofs x coarse unknowns, CSC): the rigid-body modes ``modes`` (``(nf, 6)``)
    of the bodies ``body_of`` (sorted) as six columns per body in the order of the bodies, the
    empty columns (imposed motions) dropped (``coarse_columns``)."""
    rows, cols, values = _mode_entries(body_of, modes)
    used = np.unique(cols)
    return sp.csc_matrix((values, (rows, np.searchsorted(used, cols))),
                         shape=(len(body_of), len(used)))


class KrylovFailure(RuntimeError):
    """A Krylov solve that did not reach its tolerance: ``iterations``, ``residual`` (the body
    system's ``|rhs - S v| / |rhs|``)."""

    def __init__(self, iterations: int, residual: float, rtol: float):
        super().__init__(f"GMRES not converged: relative residual {residual:.2e} > {rtol:.0e} "
                         f"after {iterations} iterations")
        self.iterations, self.residual = iterations, residual


class KrylovSolver:
    """GMRES with the two-level block preconditioner of the module docstring.

    ``body_of``: the body of each free dof (``(nf,)``, sorted: a body's dofs are contiguous);
    ``modes``: the rigid-body modes of the free dofs (``(nf, 6)``); ``rtol``: relative
    residual of a solve; ``max_iterations``: GMRES iterations before a solve is failed.

    ``rtol`` is the forcing term of an inexact Newton method: the Newton iterations judge
    their own convergence on the residual of the step, so a direction good to 1 % is enough
    (docs/scaling.md)."""

    def __init__(self, body_of: np.ndarray, modes: np.ndarray, rtol: float = 1e-2,
                 max_iterations: int = 300, restart: int = 40):
        body_of = np.asarray(body_of, dtype=np.int64)
        self.nf = nf = len(body_of)
        self.rtol, self.max_iterations, self.restart = rtol, max_iterations, restart
        self.iterations = 0  # GMRES iterations of all solves so far
        self.last_iterations = 0
        self.last_residual = 0.0
        self._x = None  # the last solution: the start of the next solve
        self.body_of = body_of
        self.modes = np.ascontiguousarray(modes, dtype=float)
        self.R = coarse_space(body_of, modes)
        #: the coarse unknowns (``coarse_columns``) and the bodies they number
        self.coarse_columns = coarse_columns(body_of, modes)
        self.n_bodies = int(body_of.max()) + 1 if nf else 0
        self.RT = self.R.T.tocsr()
        # the bodies' dof ranges in the free numbering, grouped by size for batched inverses
        starts = np.flatnonzero(np.r_[True, body_of[1:] != body_of[:-1]]) if nf else \
            np.zeros(0, dtype=np.int64)
        sizes = np.diff(np.r_[starts, nf])
        # the bodies' dense diagonal blocks laid end to end, grouped by size: group (k,
        # starts) at _group_off, its body i's block at _group_off + i k^2, row-major
        self.groups = [(int(k), starts[sizes == k]) for k in np.unique(sizes)]
        self._group_off = np.cumsum([0] + [len(st) * k * k for k, st in self.groups])
        block_off = np.empty(len(starts), dtype=np.int64)  # per body, in the order of starts
        for (k, st), off in zip(self.groups, self._group_off[:-1], strict=True):
            block_off[np.searchsorted(starts, st)] = off + k * k * np.arange(len(st))
        # per free dof: its body's block, its place in the body, its body's size
        self._block_of = np.repeat(block_off, sizes)
        self._local = (np.arange(nf) - np.repeat(starts, sizes)).astype(np.int64)
        self._size_of = np.repeat(sizes, sizes).astype(np.int64)
        # the coarse matrix's analysed pattern (``_CoarsePattern``)
        self._coarse_pattern: _CoarsePattern | None = None
        # a solver of the same free dofs and bodies whose parts this one shares (``share``)
        self._like: KrylovSolver | None = None
        self.coarse_analyses = 0  # analyses of the coarse pattern so far
        #: every entry the body system can have, ``(indptr, indices)`` of a CSR pattern with
        #: its zeros (the Newton solver's fixed pattern), when known: the coarse pattern is
        #: then analysed once, on ``|R|^T P |R|``
        self.structure = None
        self._coarse_seed = None
        # the blocks the inverses were made of (laid out as above) and the inverses, per
        # group; blocks inverted again since the first set-up
        self._last_blocks = None
        self.blocks_inverted = 0
        #: a body's block is inverted again when it moved by more than this fraction of its
        #: Frobenius norm since its inverse was made (0: at any change)
        self.block_tolerance = BLOCK_TOLERANCE

    #: what depends on the free dofs and their bodies alone (``share``)
    SHARED = ("body_of", "modes", "R", "RT", "coarse_columns", "groups", "_group_off",
              "_block_of", "_local", "_size_of")

    def share(self, other: KrylovSolver) -> None:
        """Take the parts of ``other``, a solver of the same free dofs, bodies and modes (the
        Newton solver of another step size of the scene), that depend on nothing else: the
        coarse space and its transpose, the modes, the numbering of the bodies' blocks
        (``SHARED``), and later the coarse seed and its analysed pattern, with a PARDISO
        handle of its own (``_CoarsePattern.sibling``: a handle keeps one factorisation).
        About 1 kB per contact point that each step size's solver no longer makes again
        (docs/scaling.md). Nothing when the two differ or are not of this class (PETSc's,
        ``petsc_solve.py``, keeps its own)."""
        if type(self) is not KrylovSolver or type(other) is not KrylovSolver or \
                not (np.array_equal(self.body_of, other.body_of)
                     and np.array_equal(self.modes, other.modes)):
            return
        for name in self.SHARED:
            setattr(self, name, getattr(other, name))
        self._like = other

    def release(self) -> None:
        """Let go of what the local level keeps from one set-up to the next: the blocks its
        inverses were made of and the inverses (two arrays of every body's dense block). The
        solver of a step size the run has left (``NewtonSolver.release``); its next set-up
        inverts every block, as the first one did."""
        self._last_blocks = None

    def factorise(self, J: sp.spmatrix) -> KrylovOperator:
        """The preconditioner of ``J`` (free dofs first, then three rows per multiplier
        point) and the object whose ``solve`` answers ``J x = b``."""
        with timing.part("Krylov operator"):
            S, B, C, Dinv = self._body_system(J)
        return self.factorise_system(S, B, C, Dinv)

    def factorise_system(self, S: sp.csr_matrix, B, C, Dinv) -> KrylovOperator:
        """As :meth:`factorise`, from the body system ``S = A + B D^-1 C`` (CSR) and the
        blocks ``B = -J[:nf, nf:]``, ``C = J[nf:, :nf]``, ``D^-1`` (None without
        multipliers) instead of ``J``."""
        with timing.part("preconditioner set-up"):
            preconditioner = self._preconditioner(S)
        return KrylovOperator(self, S, B, C, Dinv, preconditioner)

    def _body_system(self, J: sp.spmatrix):
        """``(S, B, C, D^-1)``: the body system ``S = A + B D^-1 C`` of ``J`` and the blocks
        that eliminate the multipliers (None without multipliers)."""
        nf = self.nf
        J = sp.csr_matrix(J)
        A = J[:nf, :nf]
        m = (J.shape[0] - nf) // 3
        if m:
            B = (-J[:nf, nf:]).tocsr()
            C = J[nf:, :nf].tocsr()
            Dinv = block_diagonal(np.linalg.inv(_diagonal_blocks(J[nf:, nf:], m)))
            S = (A + B @ (Dinv @ C)).tocsr()
        else:
            B = C = Dinv = None
            S = A.tocsr()
        return S, B, C, Dinv

    def _preconditioner(self, S: sp.csr_matrix) -> Preconditioner:
        """The two-level preconditioner of ``S``."""
        groups = self.local_inverses(S, self.body_of)
        return Preconditioner(self, S, groups, self._coarse_factor(S))

    def _coarse_factor(self, S: sp.csr_matrix):
        """The LU of the coarse matrix ``S_0 = R^T S R``: summed straight into the seed's
        analysed pattern (``coarse_on_seed``) once the seed is known, else by scipy's
        products (``_coarse_lu``)."""
        seed = self.coarse_seed()
        if seed is not None:
            lu = self.coarse_on_seed(seed, S, 0, self.body_of, self.modes, self.coarse_columns,
                                     self.n_bodies)
            if lu is not None:
                return lu
        return self._coarse_lu((self.RT @ S @ self.R).tocsc(), seed)

    def coarse_on_seed(self, seed: sp.csc_matrix, rows: sp.csr_matrix, row0: int,
                       body_of: np.ndarray, modes: np.ndarray, columns: np.ndarray,
                       n_bodies: int, total=None):
        """The LU of ``S_0 = R^T S R`` summed by ``coarse_entries`` straight into the analysed
        pattern of ``seed`` (``coarse_seed``), rather than by scipy's two products and the
        laying of their result on the pattern, half of a set-up at 8x (docs/scaling.md).
        ``rows``: rows of ``S`` from dof ``row0`` on, its columns the dofs of ``body_of`` and
        ``modes`` (all the free dofs), ``columns`` and ``n_bodies`` their coarse unknowns
        (``coarse_columns``) and bodies; ``total``: sums the processes' parts of an array in
        place (each process gives its own rows), None on one process. None when PARDISO is
        not installed or a term found no entry in the pattern (the caller then sums by
        scipy's products)."""
        if not pardiso.available():
            return None
        if self._coarse_pattern is None:
            like = self._like
            if like is not None and like._coarse_seed is seed and \
                    like._coarse_pattern is not None and like._coarse_pattern.seeded:
                # the same seed's analysed pattern, shared with a handle of its own
                self._coarse_pattern = like._coarse_pattern.sibling()
                self.coarse_analyses += 1
            else:
                self._analyse(_ones(seed.indptr, seed.indices, seed.shape)).seeded = True
        kept = self._coarse_pattern
        data = np.zeros(len(kept.keys) + 1)  # the last: the terms that found no entry
        data[-1] = coarse_entries(rows.indptr, rows.indices, rows.data, row0, body_of, modes,
                                  n_bodies, *kept.pairs(columns, n_bodies), data[:-1])
        if total is not None:
            total(data)
        if data[-1] != 0.0:
            return None
        return kept.handle.factorise(data[:-1])

    def local_inverses(self, S: sp.csr_matrix, body_of: np.ndarray) -> list:
        """The inverses of the bodies' dense diagonal blocks of ``S`` by size, ``[(dofs (g,
        k), inverses (g, k, k))]``. A block is inverted again only where it moved from the
        block its inverse was made of by more than ``block_tolerance`` of its Frobenius norm,
        ``|A - A_inv| > block_tolerance |A_inv|``; the others keep their inverse. ``S``: this
        solver's rows (CSR), its columns numbered by ``body_of`` (the body of each column;
        columns of other bodies, such as another process's, marked -1)."""
        flat = np.zeros(self._group_off[-1])
        diagonal_blocks(S.indptr, S.indices, S.data, body_of, self._block_of,
                        self._local, self._size_of, flat)
        groups = []
        if self._last_blocks is None:
            # the blocks the inverses are of, laid out as ``flat`` (``flat`` itself: it is
            # this set-up's, and only the blocks inverted again write into it later)
            self._last_blocks = (flat, [None] * len(self.groups))
        made_of, inverses = self._last_blocks
        for n, ((k, starts), off) in enumerate(zip(self.groups, self._group_off[:-1],
                                                    strict=True)):
            shape = (len(starts), k, k)
            span = slice(off, off + len(starts) * k * k)
            blocks = flat[span].reshape(shape)
            idx = starts[:, None] + np.arange(k)[None, :]  # (g, k) dofs of each body
            if inverses[n] is None:
                inv = _inverses(blocks)
            else:
                old = made_of[span].reshape(shape)
                moved = moved_blocks(blocks.reshape(len(starts), k * k),
                                     old.reshape(len(starts), k * k), self.block_tolerance)
                changed = np.flatnonzero(moved)
                # in place: a preconditioner serves until the next set-up (a copy of every
                # inverse would cost a large share of the local level's set-up); a few hundred
                # blocks at a time, so that the blocks taken out and their inverses are not a
                # second and third copy of every block of a large wall
                inv = inverses[n]
                for lo in range(0, len(changed), REINVERTED_AT_ONCE):
                    some = changed[lo:lo + REINVERTED_AT_ONCE]
                    taken = blocks[some]
                    inv[some] = _inverses(taken)
                    old[some] = taken
                self.blocks_inverted += len(changed)
            inverses[n] = inv
            groups.append((idx, inv))
        return groups

    def coarse_seed(self) -> sp.csc_matrix | None:
        """Every entry the coarse matrix can have, ``|R|^T P |R|`` with ``P`` the ones of
        ``structure`` (CSC; None while ``structure`` is not known), made once."""
        like = self._like
        if self._coarse_seed is None and like is not None and like._coarse_seed is not None \
                and like.structure is not None and self.structure is not None \
                and like.structure[1] is self.structure[1]:
            self._coarse_seed = like._coarse_seed  # the same pattern's: the same seed
        if self._coarse_seed is None and self.structure is not None:
            indptr, indices = self.structure
            P = sp.csr_matrix((np.ones(len(indices)), indices, indptr), shape=(self.nf, self.nf))
            absR = abs(self.R)
            self._coarse_seed = (absR.T @ P @ absR).tocsc()
        return self._coarse_seed

    def _coarse_lu(self, S0: sp.csc_matrix, seed: sp.csc_matrix | None = None):
        """The LU of the coarse matrix: PARDISO where MKL is installed, else SuperLU; ``seed``:
        the pattern to analyse at the first call (``coarse_seed``), else ``S0``'s.

        PARDISO's analysis is kept for a pattern that grows to the union of the patterns met,
        the entries of joints that opened kept as zeros: the pattern changes at most set-ups
        as joints open and close, and an analysis costs several factorisations
        (docs/scaling.md). Ordered by nested dissection: the bodies' 6 x 6 blocks make a
        graph like the wall's, where it halves the fill of the minimum degree order. In MKL's
        reproducible mode, as every PARDISO handle (``nscd/pardiso.py``)."""
        if not pardiso.available():
            return spla.splu(S0)
        S0.sort_indices()
        kept = self._coarse_pattern
        base = seed
        if kept is not None:
            data = _on_pattern(kept.keys, S0)
            if data is not None:
                return kept.handle.factorise(data)
            # an entry outside the kept pattern: analyse the union of the two, so that the
            # entries that come and go as joints open and close stay in it (as zeros)
            base = _ones(kept.indptr, kept.indices, S0.shape)
        union = S0 if base is None else base + _ones(S0.indptr, S0.indices, S0.shape)
        kept = self._analyse(union)
        return kept.handle.factorise(_on_pattern(kept.keys, S0))

    def _analyse(self, pattern: sp.csc_matrix) -> _CoarsePattern:
        """Analyse the coarse ``pattern`` (its entries' values unused) and keep it."""
        pattern.sort_indices()
        self._coarse_pattern = _CoarsePattern(pattern)
        self.coarse_analyses += 1
        return self._coarse_pattern


class _CoarsePattern:
    """An analysed pattern of the coarse matrix: ``indptr``, ``indices`` (CSC, sorted), the
    entries' ``keys`` (``_keys``) and PARDISO's handle, analysed by nested dissection
    (``KrylovSolver._coarse_lu``)."""

    def __init__(self, pattern: sp.csc_matrix):
        self.indptr, self.indices = pattern.indptr.copy(), pattern.indices.copy()
        self.keys = _keys(pattern)
        self.handle = pardiso.Pardiso(self.indptr, self.indices, pattern.shape[0], order=2)
        self._pairs = None
        #: analysed from a coarse seed as it is (``KrylovSolver.coarse_on_seed``), not grown
        self.seeded = False

    def sibling(self) -> _CoarsePattern:
        """The same pattern, its arrays shared, with a PARDISO handle of its own (analysed at
        its first factorisation, as this one's was: the same pattern, the same order)."""
        other = copy.copy(self)
        other.handle = pardiso.Pardiso(self.indptr, self.indices, len(self.indptr) - 1,
                                       order=2)
        return other

    def pairs(self, columns: np.ndarray, n_bodies: int) -> tuple[np.ndarray, np.ndarray]:
        """Where the entries of each pair of bodies are, for ``coarse_entries``: the pairs'
        keys ``b_row n_bodies + b_col`` (sorted) and ``pos`` (pairs, 6, 6), the entry of the
        modes ``(p, q)`` of the pair (-1: none), ``columns`` the coarse unknowns
        (``coarse_columns``); made once."""
        if self._pairs is None:
            body, mode = columns // 6, columns % 6
            rows = self.indices
            cols = np.repeat(np.arange(len(self.indptr) - 1), np.diff(self.indptr))
            keys, at = np.unique(body[rows] * n_bodies + body[cols], return_inverse=True)
            pos = np.full((len(keys), 6, 6), -1, dtype=np.int64)
            pos[at, mode[rows], mode[cols]] = np.arange(len(rows))
            self._pairs = (keys, pos)
        return self._pairs


def _ones(indptr: np.ndarray, indices: np.ndarray, shape: tuple[int, int]) -> sp.csc_matrix:
    """The CSC pattern ``(indptr, indices)`` with ones for values (sums of such patterns never
    cancel an entry)."""
    return sp.csc_matrix((np.ones(len(indices)), indices, indptr), shape=shape)


def _keys(A: sp.csc_matrix) -> np.ndarray:
    """The keys ``column n + row`` of the entries of ``A`` (CSC, ``n`` rows), sorted when its
    indices are."""
    cols = np.repeat(np.arange(A.shape[1], dtype=np.int64), np.diff(A.indptr))
    return cols * A.shape[0] + A.indices


def _on_pattern(keys: np.ndarray, A: sp.csc_matrix) -> np.ndarray | None:
    """The values of ``A`` (CSC, sorted indices) laid on a pattern given by its entries' keys
    (``_keys``, sorted), zeros where ``A`` has no entry; None when ``A`` has an entry outside
    it."""
    mine = _keys(A)
    at = np.searchsorted(keys, mine)
    if np.any(at >= len(keys)) or not np.array_equal(keys[np.minimum(at, len(keys) - 1)], mine):
        return None
    data = np.zeros(len(keys))
    data[at] = A.data
    return data


@njit(cache=True)
def diagonal_blocks(indptr, indices, data, body_of, block_of, local, size_of, flat):
    """The entries of a CSR matrix that couple two dofs of one body, written into that body's
    dense block: ``flat[block_of[i] + local[i] size_of[i] + local[j]] = S_ij``."""
    for i in range(indptr.shape[0] - 1):
        b, o, k, li = body_of[i], block_of[i], size_of[i], local[i]
        for p in range(indptr[i], indptr[i + 1]):
            j = indices[p]
            if body_of[j] == b:
                flat[o + li * k + local[j]] = data[p]


@njit(cache=True)
def nonzero_entries(indptr, indices, data, out_indptr, out_indices, out_data):
    """The entries of a CSR matrix whose value is not zero, in their order, written into
    ``out_*`` (``out_indices`` and ``out_data`` of exactly that many entries)."""
    k = 0
    out_indptr[0] = 0
    for i in range(indptr.shape[0] - 1):
        for p in range(indptr[i], indptr[i + 1]):
            if data[p] != 0.0:
                out_indices[k] = indices[p]
                out_data[k] = data[p]
                k += 1
        out_indptr[i + 1] = k


def nonzero_csr(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray,
                n: int) -> sp.csr_matrix:
    """The ``n x n`` CSR matrix of the non-zero entries of the CSR arrays given (a fixed
    pattern that holds structural zeros), with 32-bit indices where they fit: one compiled pass
    where scipy would copy the pattern, check it, narrow its indices and drop the zeros in four
    (the Krylov body system of 16 times the study's wall: 4.4 M entries, 2.3 M of them not
    zero)."""
    nnz = int(np.count_nonzero(data))
    kind = np.int32 if max(nnz, n) < np.iinfo(np.int32).max else np.int64
    out_indptr = np.empty(n + 1, dtype=kind)
    out_indices = np.empty(nnz, dtype=kind)
    out_data = np.empty(nnz)
    nonzero_entries(indptr, indices, data, out_indptr, out_indices, out_data)
    return sp.csr_matrix((out_data, out_indices, out_indptr), shape=(n, n))


@njit(cache=True)
def coarse_entries(indptr, indices, data, row0, body_of, modes, n_bodies, pair_keys, pos, out):
    """Sum the rows of ``S`` given (CSR: row ``r`` is dof ``row0 + r``, the columns dofs)
    into the coarse matrix ``S_0 = R^T S R`` laid on an analysed pattern (``out``, by
    ``_CoarsePattern.pairs``: ``pair_keys``, ``pos``): with ``b_i`` the body of dof ``i``
    and ``m_i`` its row of the rigid-body ``modes``,

        S_0[(b_i, p), (b_j, q)] += m_i[p] t_q,   t_q = sum_{j of b_j} S_ij m_j[q]

    the sums ``t`` over the run of a row's columns in one body first (a body's dofs are
    contiguous), so a row costs six products per entry and 36 per body it touches. Returns
    the number of non-zero terms that found no entry in the pattern (0 when it holds them
    all)."""
    t = np.empty(6)
    missed = 0
    n_pairs = pair_keys.shape[0]
    for r in range(indptr.shape[0] - 1):
        i = row0 + r
        bi = body_of[i]
        k = indptr[r]
        end = indptr[r + 1]
        while k < end:
            bj = body_of[indices[k]]
            for q in range(6):
                t[q] = 0.0
            while k < end and body_of[indices[k]] == bj:
                j = indices[k]
                s = data[k]
                for q in range(6):
                    t[q] += s * modes[j, q]
                k += 1
            key = bi * n_bodies + bj
            pair = np.searchsorted(pair_keys, key)
            found = pair < n_pairs and pair_keys[min(pair, n_pairs - 1)] == key
            for p in range(6):
                m = modes[i, p]
                if m == 0.0:
                    continue
                for q in range(6):
                    v = m * t[q]
                    if v == 0.0:
                        continue
                    at = pos[pair, p, q] if found else -1
                    if at < 0:
                        missed += 1
                    else:
                        out[at] += v
    return missed


@njit(cache=True)
def moved_blocks(blocks, made_of, tolerance):
    """Per row of ``blocks`` (``(g, k k)``, each a flattened block): whether it differs from
    the same row of ``made_of`` by more than ``tolerance`` of that row's Euclidean norm
    (``tolerance`` 0: by any entry). A compiled pass that stops comparing a block at its first
    difference when ``tolerance`` is 0."""
    out = np.zeros(blocks.shape[0], dtype=np.bool_)
    for b in range(blocks.shape[0]):
        if tolerance == 0.0:
            for j in range(blocks.shape[1]):
                if blocks[b, j] != made_of[b, j]:
                    out[b] = True
                    break
            continue
        d2 = 0.0
        a2 = 0.0
        for j in range(blocks.shape[1]):
            d = blocks[b, j] - made_of[b, j]
            d2 += d * d
            a2 += made_of[b, j] * made_of[b, j]
        out[b] = d2 > tolerance * tolerance * a2
    return out


#: the fewest blocks a thread inverts (a thread's hand-over costs about one 54 x 54 inverse)
MIN_BLOCKS_PER_THREAD = 16
#: the most blocks inverted in one batch (``KrylovSolver.local_inverses``, ``_inverses``): each
#: block is inverted alone by the same LAPACK call whatever the batch, so the batch bounds only
#: the temporary copies (6 MB of 54 x 54 blocks)
REINVERTED_AT_ONCE = 256


def _inverses(blocks: np.ndarray) -> np.ndarray:
    """The inverses of the stacked blocks ``(g, k, k)``, the stack cut into ranges inverted on
    the kernels' threads (``threads.run_ranges``: numpy's LAPACK loop releases the interpreter),
    each block by the same LAPACK call as on one thread: the same inverses bit for bit. A
    range is inverted ``REINVERTED_AT_ONCE`` blocks at a time, so that LAPACK's result is not
    a second copy of every block beside ``out`` (at a run's first set-up, or the first after a
    step size let go of its inverses, the peak of a large wall's memory)."""
    out = np.empty_like(blocks)

    def invert(lo, hi):
        for a in range(lo, hi, REINVERTED_AT_ONCE):
            b = min(hi, a + REINVERTED_AT_ONCE)
            out[a:b] = np.linalg.inv(blocks[a:b])

    threads.run_ranges(invert, len(blocks), min_size=MIN_BLOCKS_PER_THREAD)
    return out


def block_diagonal(blocks: np.ndarray) -> sp.csr_matrix:
    """The block-diagonal CSR matrix of ``(m, 3, 3)`` blocks."""
    m = len(blocks)
    rows = np.repeat(np.arange(3 * m), 3)
    cols = (3 * np.arange(m)[:, None, None] + np.zeros((1, 3, 1), dtype=np.int64)
            + np.arange(3)[None, None, :]).ravel()
    return sp.csr_matrix((blocks.ravel(), (rows, cols)), shape=(3 * m, 3 * m))


def _diagonal_blocks(D: sp.spmatrix, m: int) -> np.ndarray:
    """The 3 x 3 diagonal blocks of a block-diagonal ``(3m, 3m)`` matrix, ``(m, 3, 3)``."""
    out = np.zeros((m, 3, 3))
    coo = D.tocoo()
    out[coo.row // 3, coo.row % 3, coo.col % 3] += coo.data
    return out


class Preconditioner:
    """The two-level preconditioner of one matrix ``S`` (module docstring): the inverses of
    its bodies' diagonal blocks, by size (``groups``: the dofs ``(g, k)`` and the inverses
    ``(g, k, k)`` of the bodies of ``k`` free dofs), and the LU of its coarse matrix."""

    def __init__(self, owner: KrylovSolver, S, groups, coarse):
        self.owner, self.S, self.groups, self.coarse = owner, S, groups, coarse

    def _coarse(self, r: np.ndarray) -> np.ndarray:
        o = self.owner
        return o.R @ self.coarse.solve(o.RT @ r)

    def _local(self, r: np.ndarray) -> np.ndarray:
        """``S_loc^-1 r``, one stacked product per body size."""
        out = np.empty_like(r)
        for idx, inv in self.groups:
            out[idx] = np.matmul(inv, r[idx][:, :, None])[:, :, 0]
        return out

    def product(self, x: np.ndarray) -> np.ndarray:
        """``S x``."""
        return self.S @ x

    def apply(self, r: np.ndarray) -> np.ndarray:
        """``P^-1 r``: the coarse correction, then the local one on what it leaves."""
        r = np.ravel(r)
        y = self._coarse(r)
        return y + self._local(r - self.product(y))


class KrylovOperator:
    """The body system ``S``, the elimination of the multipliers and the preconditioner;
    ``solve(b)`` answers ``J x = b``."""

    def __init__(self, owner: KrylovSolver, S, B, C, Dinv, preconditioner: Preconditioner):
        self.owner, self.S, self.B, self.C, self.Dinv = owner, S, B, C, Dinv
        self.preconditioner = preconditioner

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``x`` with ``|rhs - S v| <= rtol |rhs|`` on the body system; ``KrylovFailure`` when
        GMRES does not get there within ``max_iterations``."""
        o = self.owner
        nf = o.nf
        bv, bg = b[:nf], b[nf:]
        rhs = bv if self.B is None else bv + self.B @ (self.Dinv @ bg)
        rnorm = float(np.linalg.norm(rhs))
        if rnorm == 0.0:
            v = np.zeros(nf)
        else:
            v, count, left = self._gmres(rhs, o._x)
            res = left / rnorm
            o.iterations += count
            o.last_iterations, o.last_residual = count, res
            if not (res <= 2.0 * o.rtol and np.all(np.isfinite(v))):
                raise KrylovFailure(count, res, o.rtol)
            o._x = v
        if self.B is None:
            return v
        return np.concatenate([v, self.Dinv @ (bg - self.C @ v)])

    def _gmres(self, rhs: np.ndarray, x0: np.ndarray | None
               ) -> tuple[np.ndarray, int, float]:
        """GMRES on the body system ``S v = rhs`` from ``x0`` (the last solution, or None):
        ``(v, iterations, |rhs - S v|)`` (``gmres``)."""
        o = self.owner
        return gmres(self.S.dot, self.preconditioner.apply, rhs, x0, o.rtol, o.restart,
                     o.max_iterations)


def gmres(matvec, precondition, b: np.ndarray, x0: np.ndarray | None, rtol: float,
          restart: int, max_iterations: int, inner=None,
          norm=None) -> tuple[np.ndarray, int, float]:
    """Restarted GMRES with right preconditioning: ``x = x0 + M^-1 V_k y`` minimising
    ``|b - A x|`` over the Krylov space of ``A M^-1`` built from ``r0 = b - A x0``, stopping
    when ``|b - A x| <= rtol |b|`` (its estimate from the Hessenberg least squares, checked
    on the true residual at each restart). ``x0`` (a guess, such as the last solve's
    solution, or None) is the start only when its residual is below ``|b|``, else zero.
    Arnoldi by classical Gram-Schmidt done twice (one matrix product per pass over the basis);
    the small least-squares problem by Givens rotations. Returns ``(x, iterations, |b - A
    x|)``, the true residual of the last restart's check (so a caller needs no product of its
    own to judge it).

    ``inner(V, w)``: the products ``V @ w`` of the rows of ``V`` with ``w``, and ``norm(w)``:
    ``|w|``; by default those of the vectors given. A solve over several processes gives
    each its own rows of the vectors and sums the processes' parts in both (``mpi.py``)."""
    if inner is None:
        def inner(V, w):
            return V @ w
    if norm is None:
        def norm(w):
            return float(np.linalg.norm(w))
    n = len(b)
    bnorm = norm(b)
    x = np.zeros(n)
    r, beta = b.copy(), bnorm
    if x0 is not None:
        r0 = b - matvec(x0)
        beta0 = norm(r0)
        if beta0 < bnorm:
            x, r, beta = x0.copy(), r0, beta0
    iterations = 0
    V = np.empty((restart + 1, n))
    Z = np.empty((restart, n))
    H = np.zeros((restart + 1, restart))
    cs, sn = np.zeros(restart), np.zeros(restart)
    while True:
        if beta <= rtol * bnorm or iterations >= max_iterations:
            return x, iterations, beta
        V[0] = r / beta
        g = np.zeros(restart + 1)
        g[0] = beta
        k = 0
        while k < restart and iterations < max_iterations:
            Z[k] = precondition(V[k])
            w = matvec(Z[k])
            h = inner(V[:k + 1], w)
            w -= h @ V[:k + 1]
            h2 = inner(V[:k + 1], w)  # second pass: orthogonal to round-off
            w -= h2 @ V[:k + 1]
            h += h2
            hn = norm(w)
            H[:k + 1, k] = h
            H[k + 1, k] = hn
            for i in range(k):  # the earlier rotations on the new column
                t = cs[i] * H[i, k] + sn[i] * H[i + 1, k]
                H[i + 1, k] = -sn[i] * H[i, k] + cs[i] * H[i + 1, k]
                H[i, k] = t
            d = math.hypot(H[k, k], H[k + 1, k])
            cs[k], sn[k] = (1.0, 0.0) if d == 0.0 else (H[k, k] / d, H[k + 1, k] / d)
            H[k, k], H[k + 1, k] = d, 0.0
            g[k + 1] = -sn[k] * g[k]
            g[k] = cs[k] * g[k]
            iterations += 1
            k += 1
            if hn == 0.0 or abs(g[k]) <= rtol * bnorm:
                break
            V[k] = w / hn
        y = np.linalg.solve(np.triu(H[:k, :k]), g[:k]) if k else np.zeros(0)
        x += y @ Z[:k]
        r = b - matvec(x)
        beta = norm(r)
