r"""The Krylov solve of the Newton matrix on several processes, by PETSc (``masonry run
--processes P``; installed by ``make mpi``: PETSc, petsc4py and mpi4py built on the system's
MPICH).

The body system of the Krylov solver (``linear.py``)

    S v = rhs,   S = A + B D^-1 C   (free dofs, kg)

is a PETSc ``MPIAIJ`` matrix whose rows are split among the processes by ``mpi.partition``
(whole bodies, about as many dofs in each range). Process 0 runs the case as on one process
(the joints, the blocks, Newton, the outputs); at a set-up it sends every process its rows of
``S`` (``mpi.py``'s commands), each makes its part of the PETSc matrix from them, and at a
solve the right-hand side and the start are scattered, PETSc's ``KSP`` solves on every
process and process 0 gathers the solution.

The solve, by default (``DEFAULT_OPTIONS``, PETSc's own option names): flexible GMRES
(``KSPFGMRES``, restart 40; right preconditioning, so that it stops on the true relative
residual ``|rhs - S v| <= rtol |rhs|`` as on one process; it keeps the preconditioned vectors,
so forming the solution applies the preconditioner no more, where GMRES applies it once more
a solve: the whole coarse solve again) with the two levels of the one-process preconditioner
in PETSc's multigrid ``PCMG``: the coarse space ``R`` of six rigid-body motions per body as the
interpolation, the coarse matrix ``R^T S R`` made by PETSc (Galerkin), gathered and factorised
by LU on every process (``PCREDUNDANT``: MKL's PARDISO where PETSc was built with it, as ``make
mpi`` builds it, else PETSc's own LU; ``COARSE_LU``); then, on what the coarse correction
leaves, one Richardson sweep of the bodies' diagonal blocks inverted (``PCVPBJACOBI``, the
blocks of variable size given by the bodies): the kaskade cycle, the one-process method's
order.
The case's ``solver.petsc_options`` and the command line's ``--petsc-options``, in that order,
override any of them (docs/guide/solvers.md): for example ``-pc_type asm -sub_pc_type ilu``
or ``-pc_type bjacobi -sub_pc_type lu``; with ``-pc_type mg`` the interpolation is always the
rigid-body space.

The iterates differ from those of one process by the partition and PETSc's arithmetic, and a
solve stops at the same relative residual; Newton's iterations stop at their own tolerance, so
the curve is that of one process within it.
"""

from __future__ import annotations

import itertools
import shlex
import weakref

import numpy as np
import scipy.sparse as sp

from masonry_nscd import timing
from masonry_nscd.nscd import linear, mpi

#: PETSc's options for the solve unless the case or the command line give others (module
#: docstring; chosen by measurement, docs/scaling.md)
DEFAULT_OPTIONS = (
    "-ksp_type fgmres -ksp_pc_side right "
    "-pc_type mg -pc_mg_galerkin both -pc_mg_type kaskade "
    "-mg_levels_ksp_type richardson -mg_levels_ksp_max_it 1 -mg_levels_pc_type vpbjacobi "
    "-mg_coarse_ksp_type preonly -mg_coarse_pc_type redundant "
    "-mg_coarse_redundant_pc_type lu -options_left 0")
#: The coarse level's LU by MKL's PARDISO, where PETSc has it: put before the case's and the
#: command line's options, which may name another (``petsc`` for PETSc's own LU, which
#: factorises a large coarse matrix many times slower: docs/scaling.md)
COARSE_LU = "-mg_coarse_redundant_pc_factor_mat_solver_type mkl_pardiso"
#: PETSc's error code for a type name it does not know
PETSC_ERR_UNKNOWN_TYPE = 86
MISSING = ("several processes need PETSc, petsc4py and mpi4py built on the system's MPI: "
           "make mpi (docs/guide/solvers.md)")

#: the options of the command line (``--petsc-options``), set by process 0 before the run
command_line_options = ""
#: the case's options (``solver.petsc_options``), set by process 0 before the run
case_options = ""
_ids = itertools.count()
_PETSc = None


def petsc(option_string: str = ""):
    """petsc4py's ``PETSc`` module, initialised on MPI's world communicator (mpi4py's, started
    first): a RuntimeError that says how to install it where it is missing. ``option_string``
    is given to PETSc's initialisation, the first call's only: the options PETSc reads there
    alone (``-log_view``, ``-info``, ``-malloc_debug``) then take effect."""
    global _PETSc
    if _PETSc is None:
        try:
            import petsc4py
            from mpi4py import MPI
        except ImportError as exc:
            raise RuntimeError(MISSING) from exc
        # Python keeps its signal handlers: SIGTERM and Ctrl-C end a run at the end of a step
        petsc4py.init(["masonry", "-no_signal_handler", *shlex.split(option_string)],
                      comm=MPI.COMM_WORLD)
        from petsc4py import PETSc

        _PETSc = PETSc
    return _PETSc


def available() -> bool:
    """Whether petsc4py and mpi4py are installed (without starting either)."""
    import importlib.util

    return all(importlib.util.find_spec(m) is not None for m in ("petsc4py", "mpi4py"))


def finalize() -> None:
    """End PETSc in this process, before MPI ends (nothing where it was not started)."""
    global _PETSc
    if _PETSc is not None:
        import gc

        gc.collect()  # the solvers' PETSc objects first
        _PETSc._finalize()
        _PETSc = None


def options() -> str:
    """The options a solver is made with: the defaults, then the case's, then the command
    line's (a later one wins)."""
    return " ".join(s for s in (DEFAULT_OPTIONS, case_options, command_line_options) if s)


def with_coarse_lu(PETSc, option_string: str) -> str:
    """``option_string`` after ``COARSE_LU`` where this PETSc has MKL's PARDISO (the options
    given then override it)."""
    if PETSc.Sys.hasExternalPackage("mkl_pardiso"):
        return f"{COARSE_LU} {option_string}"
    return option_string


def _refused(PETSc, option_string: str) -> str | None:
    """Why PETSc refuses the options (a KSP or PC type it does not know, a bad value), or
    None: a solver of one unknown on this process reads them, PETSc's error handler silenced
    (its message would come once per process), before any run's matrix is made."""
    A = PETSc.Mat().createAIJ(size=(1, 1), nnz=1, comm=PETSc.COMM_SELF)
    A.setValue(0, 0, 1.0)
    A.assemble()
    ksp = PETSc.KSP().create(comm=PETSc.COMM_SELF)
    ksp.setOperators(A)
    PETSc.Sys.pushErrorHandler("return")
    try:
        ksp.setFromOptions()
    except PETSc.Error as exc:
        given = option_string.removeprefix(DEFAULT_OPTIONS).strip()
        why = ("a type it does not know" if exc.ierr == PETSC_ERR_UNKNOWN_TYPE
               else "a bad value")
        return (f"solver.petsc_options and --petsc-options: PETSc refuses {given!r}: {why} "
                f"(PETSc error {exc.ierr}; its types and options: docs/guide/solvers.md)")
    finally:
        PETSc.Sys.popErrorHandler()
        ksp.destroy()
        A.destroy()
    return None


def _int(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=petsc().IntType)


class Part:
    """One process's share of a distributed solver: its range ``[lo, hi)`` of the free dofs,
    its rows of the rigid-body space ``R`` (PETSc's interpolation), the KSP, and its rows of
    the last matrix given."""

    def __init__(self, comm, body_of: np.ndarray, modes: np.ndarray, rtol: float,
                 restart: int, max_iterations: int, option_string: str):
        PETSc = petsc(option_string)
        self.comm = comm
        self.cuts = mpi.partition(body_of, comm.size)
        lo, hi = self.lo, self.hi = int(self.cuts[comm.rank]), int(self.cuts[comm.rank + 1])
        nf = self.nf = len(body_of)
        self.rtol = rtol
        # this range's bodies' sizes: PCVPBJACOBI's blocks
        own = np.asarray(body_of[lo:hi])
        starts = np.flatnonzero(np.r_[True, own[1:] != own[:-1]])
        self.block_sizes = _int(np.diff(np.r_[starts, hi - lo]))
        # R's rows of this range: its columns (the coarse unknowns) follow the bodies, so this
        # range's bodies own a contiguous range of them
        R = linear.coarse_space(body_of, modes)
        first_row = R.indices[R.indptr[:-1]]
        c_cuts = np.searchsorted(first_row, self.cuts)
        Rp = R.tocsr()[lo:hi]
        Rp.sort_indices()
        self.P = PETSc.Mat().createAIJ(
            size=((hi - lo, nf), (int(c_cuts[comm.rank + 1] - c_cuts[comm.rank]),
                                  R.shape[1])),
            csr=(_int(Rp.indptr), _int(Rp.indices), Rp.data), comm=PETSc.COMM_WORLD)
        self.P.assemble()
        PETSc.Options().insertString(with_coarse_lu(PETSc, option_string))
        # every process finds the same refusal; process 0 ends the run (exit 2), the others
        # wait for its stop
        refused = _refused(PETSc, option_string)
        if refused is not None and comm.rank == 0:
            raise ValueError(refused)
        self.rtol, self.restart, self.max_iterations = rtol, restart, max_iterations
        self.S = self.ksp = None

    def setup(self, rows: sp.csr_matrix) -> None:
        """Take this process's rows of ``S`` (CSR, the columns numbered globally) as its part
        of a new PETSc matrix, and make a KSP for it (PETSc's preconditioner set-up). A new
        KSP at each set-up: the matrix's pattern changes as joints open and close, and PCMG's
        Galerkin product kept from an earlier pattern would lose the new entries."""
        PETSc = petsc()
        rows = sp.csr_matrix(rows)
        rows.sort_indices()
        n = self.hi - self.lo
        S = PETSc.Mat().createAIJ(size=((n, self.nf), (n, self.nf)),
                                  csr=(_int(rows.indptr), _int(rows.indices), rows.data),
                                  comm=PETSc.COMM_WORLD)
        S.setVariableBlockSizes(self.block_sizes)
        S.assemble()
        if self.ksp is not None:
            self.ksp.destroy()
            self.S.destroy()
        self.S = S
        ksp = self.ksp = PETSc.KSP().create(comm=PETSc.COMM_WORLD)
        ksp.setOperators(S)
        ksp.setType(PETSc.KSP.Type.FGMRES)
        ksp.setGMRESRestart(self.restart)
        ksp.getPC().setType(PETSc.PC.Type.MG)
        ksp.getPC().setMGLevels(2)  # the blocks and the blocks as rigid bodies
        ksp.setFromOptions()
        pc = ksp.getPC()
        if pc.getType() == PETSc.PC.Type.MG:
            pc.setMGInterpolation(1, self.P)
        # the Newton solver's forcing and limit, whatever the options say
        ksp.setTolerances(rtol=self.rtol, atol=0.0, max_it=self.max_iterations)
        ksp.setUp()

    def solve(self, b: np.ndarray, x0: np.ndarray | None) -> tuple[np.ndarray, int, float]:
        """The KSP on this range's rows of ``S v = b``, with the others: ``(v, iterations,
        |b - S v|)``; ``x0`` (the last solution) is the start where its residual is below
        ``|b|``, as on one process."""
        S = self.S
        rhs, x = S.createVecLeft(), S.createVecRight()
        rhs.setArray(b)
        r = S.createVecLeft()
        guess = False
        if x0 is not None:
            x.setArray(x0)
            S.mult(x, r)
            r.aypx(-1.0, rhs)
            guess = r.norm() < rhs.norm()
        if not guess:
            x.set(0.0)
        self.ksp.setInitialGuessNonzero(guess)
        self.ksp.solve(rhs, x)
        S.mult(x, r)
        r.aypx(-1.0, rhs)
        return x.getArray().copy(), int(self.ksp.getIterationNumber()), float(r.norm())

    def describe(self) -> str:
        """The KSP and preconditioner the options made (after the first set-up), and with
        ``PCMG`` its coarse solver: the package of its LU, read from the coarse PC itself (a
        redundant one factorises with the options of its inner solver, prefix
        ``mg_coarse_redundant_``), or the coarse PC's type where it is no LU."""
        PETSc = petsc()
        pc = self.ksp.getPC()
        text = f"KSP {self.ksp.getType()}, PC {pc.getType()}"
        if pc.getType() == PETSc.PC.Type.MG:
            text += f", {_coarse(PETSc, pc.getMGCoarseSolve().getPC())}"
        return text


def _coarse(PETSc, coarse) -> str:
    """What PCMG's coarse PC ``coarse`` is: ``coarse LU PACKAGE``, or ``coarse PC TYPE``."""
    kind = coarse.getType()
    factors = (PETSc.PC.Type.LU, PETSc.PC.Type.CHOLESKY)
    if kind == PETSc.PC.Type.REDUNDANT:
        opts = PETSc.Options("mg_coarse_redundant_")
        inner = opts.getString("pc_type", PETSc.PC.Type.LU)
        if inner in factors:
            return f"coarse {inner.upper()} {opts.getString('pc_factor_mat_solver_type', 'petsc')}"
        return f"coarse PC redundant {inner}"
    if kind in factors:
        return f"coarse {kind.upper()} {coarse.getFactorSolverType()}"
    return f"coarse PC {kind}"


class PetscKrylovSolver(linear.KrylovSolver):
    """The Krylov solver of ``linear.py`` whose body system is solved by PETSc on all the
    processes of ``comm`` (made and called by process 0; the others ``mpi.serve``). Its
    arguments are those of ``linear.KrylovSolver``."""

    def __init__(self, comm, body_of: np.ndarray, modes: np.ndarray, rtol: float = 1e-2,
                 max_iterations: int = 300, restart: int = 40):
        super().__init__(body_of, modes, rtol, max_iterations, restart)
        body_of = np.asarray(body_of, dtype=np.int64)
        modes = np.asarray(modes, dtype=float)
        self.comm, self.id = comm, next(_ids)
        self.options = options()
        mpi.command(comm, mpi.INIT, self.id)
        args = (body_of, modes, rtol, restart, max_iterations, self.options)
        comm.bcast(args, root=0)
        self.part = Part(comm, *args)
        weakref.finalize(self, mpi.forget, self.id)

    def factorise_system(self, S: sp.csr_matrix, B, C, Dinv) -> linear.KrylovOperator:
        with timing.part("preconditioner set-up"):
            mpi.command(self.comm, mpi.SETUP, self.id)
            cuts = self.part.cuts
            for q in range(1, self.comm.size):
                mpi.send_rows(self.comm, q, S, int(cuts[q]), int(cuts[q + 1]))
            self.part.setup(mpi.rows(S, int(cuts[0]), int(cuts[1])))
        return _Operator(self, S, B, C, Dinv, None)

    def describe(self) -> str:
        """What solves: PETSc's KSP and preconditioner on how many processes."""
        return f"PETSc {self.part.describe()} on {self.comm.size} processes"


class _Operator(linear.KrylovOperator):
    """``linear.KrylovOperator`` with PETSc's KSP on all the processes."""

    def _gmres(self, rhs: np.ndarray, x0: np.ndarray | None
               ) -> tuple[np.ndarray, int, float]:
        o = self.owner
        mpi.command(o.comm, mpi.SOLVE, o.id)
        cuts = o.part.cuts
        b, x = o.comm.scatter([(rhs[a:e], None if x0 is None else x0[a:e])
                               for a, e in itertools.pairwise(cuts)], root=0)
        v, count, left = o.part.solve(b, x)
        return np.concatenate(o.comm.gather(v, root=0)), count, left


def serve_command(comm, parts: dict, code: int, ident: int) -> None:
    """A process other than 0: carry out process 0's command ``code`` for its solver
    ``ident`` (``mpi.serve``)."""
    if code == mpi.INIT:
        parts[ident] = Part(comm, *comm.bcast(None, root=0))
    elif code == mpi.SETUP:
        parts[ident].setup(mpi.receive_rows(comm))
    elif code == mpi.SOLVE:
        b, x0 = comm.scatter(None, root=0)
        comm.gather(parts[ident].solve(b, x0)[0], root=0)
    elif code == mpi.FORGET:
        parts.pop(ident, None)

