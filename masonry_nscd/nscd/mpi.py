r"""The Krylov solve of the Newton matrix on several processes (``masonry run --processes P``).

A run launched by ``mpiexec -n P`` (``masonry run --processes P`` does it) splits the body
system of the Krylov solver (``linear.py``)

    S v = rhs,   S = A + B D^-1 C   (free dofs, kg)

by rows among its processes. Process ``p`` owns the bodies of one contiguous range
(``partition``: whole bodies, about as many dofs in each range; the builders number the units
course by course, so a range is a band of courses), their dofs' rows of ``S`` and their entries
of every vector of GMRES. Per Newton matrix (a set-up), a process holds:

- its rows of ``S``, the columns numbered its own dofs first, then its *ghosts*: the dofs of
  other processes' bodies that its rows couple to (the far side of the joints across a cut);
- the inverses of its bodies' diagonal blocks, the local level of the preconditioner;
- the coarse matrix ``S_0 = R^T S R`` (six rigid-body motions per body): each process makes
  the rows of its own bodies, ``R_p^T S_p R``, they are gathered on every process, and each
  factorises the whole (redundantly: six unknowns per body, 3,300 at 8 times the study's wall).

Per GMRES iteration (``linear.gmres`` on each process's rows), what crosses between processes:

- for each product ``S x`` (two per iteration, with the preconditioner's): the ghosts'
  entries of ``x``, sent by their owners (``Alltoallv``);
- for the inner products and the norms: each process's partial sums, added (``Allreduce``);
- for each coarse correction ``R S_0^-1 R^T r`` (one per iteration): the coarse residual
  ``R_p^T r_p`` of each process, gathered on all (``Allgatherv``); each solves ``S_0`` and
  keeps its own bodies' part.

Process 0 runs the case as on one process (the joints, the blocks, Newton's iterations, the
Newton matrix, the outputs). At a set-up it sends every process its rows of ``S`` (their
arrays as they are in memory); at a solve, its rows of the right-hand side and of the start;
it takes part in GMRES with its own rows and gathers the solution. The other processes wait
for its commands (``serve``), looking every ``POLL_S`` and sleeping in between, so that they
leave the cores to process 0's kernels. So the linear solve's work and memory are split; the
rest of a step is not yet (``docs/scaling.md``, "Beyond one machine").

The iterates are those of GMRES on one process but for round-off (the inner products summed by
process), and a solve stops at the same relative residual; Newton's iterations then stop at
their own tolerance, so the curve is that of one process within it.
"""

from __future__ import annotations

import atexit
import itertools
import os
import signal
import sys
import time
import traceback
import weakref

import numpy as np
import scipy.sparse as sp

from masonry_nscd import MPI_SIZE_VARIABLES, timing
from masonry_nscd.nscd import linear

#: the environment variables in which mpiexec gives the number of processes and this one's rank
#: (MPICH's Hydra, Open MPI)
SIZE_VARIABLES = MPI_SIZE_VARIABLES
RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK")
#: how long a process waiting for a command sleeps between two looks, s
POLL_S = 2e-4
MISSING = ("several processes need mpi4py and an MPI library: pip install 'masonry_nscd[mpi]' "
           "(mpi4py and MPICH)")

_STOP, _INIT, _SETUP, _SOLVE, _FORGET = range(5)
_comm = None
_stopped = False
_forgotten: list[int] = []  # ids of process 0's solvers gone since its last command
_ids = itertools.count()


def launched_processes() -> int:
    """The number of processes mpiexec launched this run on (1 without mpiexec)."""
    for name in SIZE_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return max(1, int(value))
    return 1


def launched_rank() -> int:
    """This process's rank among those mpiexec launched (0 without mpiexec), read before MPI
    starts."""
    for name in RANK_VARIABLES:
        value = os.environ.get(name, "").strip()
        if value.isdigit():
            return int(value)
    return 0


def krylov_solver(body_of: np.ndarray, modes: np.ndarray) -> linear.KrylovSolver:
    """The Krylov solver of a Newton solver: on every process when mpiexec launched several,
    else on this one."""
    comm = world()
    if comm is None:
        return linear.KrylovSolver(body_of, modes)
    return MpiKrylovSolver(comm, body_of, modes)


def world():
    """MPI's world communicator when mpiexec launched several processes, else None (MPI is
    started at the first call; process 0 stops the others when Python exits, or earlier by
    ``shutdown``)."""
    global _comm
    if launched_processes() <= 1:
        return None
    if _comm is None:
        try:
            from mpi4py import MPI
        except ImportError as exc:
            raise RuntimeError(MISSING) from exc
        _comm = MPI.COMM_WORLD
        if _comm.rank == 0:
            atexit.register(shutdown)
    return _comm


def shutdown() -> None:
    """Process 0: tell the other processes that the run is over, and end MPI (once; nothing
    without several processes)."""
    if _stopped:
        return
    comm = world()
    if comm is None or comm.rank != 0:
        return
    _command(comm, _STOP, 0)
    _finalize()


def _finalize() -> None:
    """End MPI in this process (no MPI call may follow: ``shutdown`` is then a no-op)."""
    global _stopped
    from mpi4py import MPI

    _stopped = True
    MPI.Finalize()


def relaunch(processes: int, argv: list[str]) -> int:
    """Run ``masonry ARGV`` on ``processes`` processes under this environment's ``mpiexec``
    and return its exit code. A first Ctrl-C or a SIGTERM reaches every process (process 0
    ends its step and keeps its outputs); this process waits for them. A RuntimeError where
    mpiexec or mpi4py is missing."""
    import importlib.util
    import shutil
    import subprocess

    mpiexec = os.path.join(os.path.dirname(sys.executable), "mpiexec")
    if not os.access(mpiexec, os.X_OK):
        mpiexec = shutil.which("mpiexec")
    if mpiexec is None or importlib.util.find_spec("mpi4py") is None:
        raise RuntimeError(f"--processes {processes}: {MISSING}")
    child = subprocess.Popen([mpiexec, "-n", str(processes), sys.executable, "-m",
                              "masonry_nscd.cli", *argv])

    def forward(signum, frame):
        child.send_signal(signum)

    signal.signal(signal.SIGTERM, forward)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the terminal sends it to mpiexec as well
    try:
        return child.wait()
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)


def partition(body_of: np.ndarray, parts: int) -> np.ndarray:
    """The first free dof of each process's range, then the number of free dofs (``(parts +
    1,)``): ranges of whole bodies (``body_of``, the body of each free dof, sorted), each cut
    at the boundary between two bodies nearest to ``p nf / parts``. A ValueError when a range
    would hold no body."""
    nf = len(body_of)
    bounds = np.r_[np.flatnonzero(np.r_[True, body_of[1:] != body_of[:-1]]), nf]
    cuts = [0]
    for p in range(1, parts):
        cuts.append(max(int(bounds[np.argmin(np.abs(bounds - p * nf / parts))]), cuts[-1]))
    cuts.append(nf)
    cuts = np.asarray(cuts, dtype=np.int64)
    if np.any(np.diff(cuts) == 0):
        raise ValueError(f"{parts} processes for {len(bounds) - 1} bodies: a process would "
                         f"hold none")
    return cuts


class _Part:
    """One process's share of a distributed Krylov solver (module docstring): its range of
    free dofs ``[lo, hi)``, its rows of ``S`` with their ghosts, its blocks' inverses, the
    coarse LU, and the plan of the ghost exchange."""

    def __init__(self, comm, body_of: np.ndarray, modes: np.ndarray, rtol: float,
                 restart: int, max_iterations: int):
        self.comm = comm
        self.cuts = partition(body_of, comm.size)
        lo, hi = self.lo, self.hi = int(self.cuts[comm.rank]), int(self.cuts[comm.rank + 1])
        # the coarse space of all the bodies (for the rows R_p^T S_p R of S_0) and where each
        # process's coarse unknowns are (the columns of R follow the bodies)
        self.R = linear.coarse_space(body_of, modes)
        first_row = self.R.indices[self.R.indptr[:-1]]
        self.coarse_cuts = np.searchsorted(first_row, self.cuts).astype(np.int64)
        self.own_body = (body_of[lo:hi] - body_of[lo]).astype(np.int64)
        # the bodies of this range: their groups of equal size, their blocks' inverses kept
        # between set-ups, their own coarse columns (R_p, R_p^T)
        self.local = linear.KrylovSolver(self.own_body, modes[lo:hi], rtol, max_iterations,
                                         restart)
        # every free dof's body and modes, and the coarse unknowns: this range's rows of S
        # summed into the coarse matrix (``linear.KrylovSolver.coarse_on_seed``)
        self.body_of = np.asarray(body_of, dtype=np.int64)
        self.modes = np.ascontiguousarray(modes, dtype=float)
        self.columns = linear.coarse_columns(body_of, modes)
        self.n_bodies = int(self.body_of.max()) + 1 if len(body_of) else 0
        self.S = self.preconditioner = self.seed = None

    def setup(self, rows: sp.csr_matrix, seed: sp.csc_matrix | None = None) -> None:
        """Take this process's rows of ``S`` (CSR, the columns numbered globally): renumber
        them with the ghosts after the own dofs, agree the ghost exchange with the other
        processes, invert the changed diagonal blocks, make and factorise ``S_0``: each
        process sums its rows into the seed's pattern and the processes add their parts
        (``Allreduce``), or, before the seed is known, each gathers every process's rows of
        ``R^T S R``; ``seed``: the coarse matrix's whole pattern, when process 0 first knows
        it (kept)."""
        if seed is not None:
            self.seed = seed
        lo, hi, n = self.lo, self.hi, self.hi - self.lo
        cols = rows.indices
        outside = (cols < lo) | (cols >= hi)
        ghosts = np.unique(cols[outside])
        self._plan(ghosts)
        local_cols = np.where(outside, n + np.searchsorted(ghosts, cols), cols - lo)
        self.S = sp.csr_matrix((rows.data, local_cols, rows.indptr),
                               shape=(n, n + len(ghosts)))
        body_ext = np.r_[self.own_body, np.full(len(ghosts), -1, dtype=np.int64)]
        groups = self.local.local_inverses(self.S, body_ext)
        lu = None
        if self.seed is not None:
            lu = self.local.coarse_on_seed(self.seed, rows, lo, self.body_of, self.modes,
                                           self.columns, self.n_bodies, self._total)
        if lu is None:
            coarse_rows = (self.local.RT @ (rows @ self.R)).tocsr()
            S0 = sp.vstack(self.comm.allgather(coarse_rows)).tocsc()
            lu = self.local._coarse_lu(S0, self.seed)
        self.preconditioner = _PartPreconditioner(self, groups, lu)

    def _total(self, a: np.ndarray) -> None:
        """``a`` summed over the processes, in place."""
        from mpi4py import MPI

        self.comm.Allreduce(MPI.IN_PLACE, a, op=MPI.SUM)

    def _plan(self, ghosts: np.ndarray) -> None:
        """Which entries this process sends to which (the ghosts of the others in its range)
        and receives (its own ghosts, sorted, so grouped by their owners in order)."""
        owner = np.searchsorted(self.cuts, ghosts, side="right") - 1
        wanted = [ghosts[owner == q] for q in range(self.comm.size)]
        asked = self.comm.alltoall(wanted)  # asked[q]: the dofs of this range q needs
        self.send_index = (np.concatenate(asked) - self.lo).astype(np.int64)
        self.send_counts = np.array([len(a) for a in asked], dtype=np.int64)
        self.recv_counts = np.array([len(w) for w in wanted], dtype=np.int64)

    def product(self, x: np.ndarray) -> np.ndarray:
        """This range's rows of ``S x`` (``x``: this range's entries)."""
        from mpi4py import MPI

        ghosts = np.empty(int(self.recv_counts.sum()))
        sent = x[self.send_index]
        self.comm.Alltoallv(
            [sent, (self.send_counts, _offsets(self.send_counts)), MPI.DOUBLE],
            [ghosts, (self.recv_counts, _offsets(self.recv_counts)), MPI.DOUBLE])
        return self.S @ np.concatenate([x, ghosts])

    def coarse(self, r: np.ndarray) -> np.ndarray:
        """This range's entries of ``R S_0^-1 R^T r``."""
        from mpi4py import MPI

        counts = np.diff(self.coarse_cuts)
        full = np.empty(int(self.coarse_cuts[-1]))
        self.comm.Allgatherv(self.local.RT @ r,
                             [full, (counts, self.coarse_cuts[:-1]), MPI.DOUBLE])
        y = self.preconditioner.coarse.solve(full)
        return self.local.R @ y[self.coarse_cuts[self.comm.rank]:
                                self.coarse_cuts[self.comm.rank + 1]]

    def inner(self, V: np.ndarray, w: np.ndarray) -> np.ndarray:
        """``V @ w`` summed over the processes' rows."""
        from mpi4py import MPI

        out = np.ascontiguousarray(V @ w)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out

    def norm(self, w: np.ndarray) -> float:
        """``|w|`` over the processes' rows."""
        return float(np.sqrt(self.inner(w[None, :], w)[0]))

    def solve(self, b: np.ndarray, x0: np.ndarray | None) -> tuple[np.ndarray, int, float]:
        """GMRES on this range's rows of ``S v = b``, with the others: ``(v, iterations,
        |b - S v|)`` (the same iterations and residual on every process: its decisions come
        from the sums)."""
        pre, loc = self.preconditioner, self.local
        return linear.gmres(self.product, pre.apply, b, x0, loc.rtol, loc.restart,
                            loc.max_iterations, inner=self.inner, norm=self.norm)


def _offsets(counts: np.ndarray) -> np.ndarray:
    return np.r_[0, np.cumsum(counts)[:-1]].astype(np.int64)


class _PartPreconditioner(linear.Preconditioner):
    """The two-level preconditioner on a process's rows: the local level on its own blocks,
    the products and the coarse level with the other processes (``_Part``)."""

    def __init__(self, part: _Part, groups, lu):
        super().__init__(part.local, part.S, groups, lu)
        self.part = part

    def product(self, x: np.ndarray) -> np.ndarray:
        return self.part.product(x)

    def _coarse(self, r: np.ndarray) -> np.ndarray:
        return self.part.coarse(r)


class MpiKrylovSolver(linear.KrylovSolver):
    """The Krylov solver of ``linear.py`` whose body system is solved by all the processes of
    ``comm`` (made and called by process 0; the others ``serve``). Its arguments are those of
    ``linear.KrylovSolver``."""

    def __init__(self, comm, body_of: np.ndarray, modes: np.ndarray, rtol: float = 1e-2,
                 max_iterations: int = 300, restart: int = 40):
        super().__init__(body_of, modes, rtol, max_iterations, restart)
        body_of = np.asarray(body_of, dtype=np.int64)
        modes = np.asarray(modes, dtype=float)
        self.comm, self.id = comm, next(_ids)
        _command(comm, _INIT, self.id)
        comm.bcast((body_of, modes, rtol, restart, max_iterations), root=0)
        self.part = _Part(comm, body_of, modes, rtol, restart, max_iterations)
        weakref.finalize(self, _forgotten.append, self.id)

    def factorise_system(self, S: sp.csr_matrix, B, C, Dinv) -> linear.KrylovOperator:
        with timing.part("preconditioner set-up"):
            _command(self.comm, _SETUP, self.id)
            # the coarse matrix's whole pattern, once it is known (``linear.coarse_seed``)
            seed = self.coarse_seed() if self.part.seed is None else None
            self.comm.bcast(seed, root=0)
            cuts = self.part.cuts
            for q in range(1, self.comm.size):
                _send_rows(self.comm, q, S, int(cuts[q]), int(cuts[q + 1]))
            self.part.setup(_rows(S, int(cuts[0]), int(cuts[1])), seed)
        return _Operator(self, S, B, C, Dinv, None)


class _Operator(linear.KrylovOperator):
    """``linear.KrylovOperator`` with GMRES on all the processes."""

    def _gmres(self, rhs: np.ndarray, x0: np.ndarray | None
               ) -> tuple[np.ndarray, int, float]:
        o = self.owner
        _command(o.comm, _SOLVE, o.id)
        cuts = o.part.cuts
        b, x = o.comm.scatter([(rhs[a:e], None if x0 is None else x0[a:e])
                               for a, e in itertools.pairwise(cuts)], root=0)
        v, count, left = o.part.solve(b, x)
        return np.concatenate(o.comm.gather(v, root=0)), count, left


def _rows(S: sp.csr_matrix, lo: int, hi: int) -> sp.csr_matrix:
    """Rows ``[lo, hi)`` of ``S`` (CSR, the columns as they are), views of its arrays but the
    row pointers."""
    p0, p1 = int(S.indptr[lo]), int(S.indptr[hi])
    return sp.csr_matrix((S.data[p0:p1], S.indices[p0:p1], S.indptr[lo:hi + 1] - p0),
                         shape=(hi - lo, S.shape[1]))


def _send_rows(comm, dest: int, S: sp.csr_matrix, lo: int, hi: int) -> None:
    """Send rows ``[lo, hi)`` of ``S`` to process ``dest`` (``_receive_rows``): their sizes,
    then the three arrays as they are in memory (no pickling: 4 M entries at 32 times the
    study's wall)."""
    rows = _rows(S, lo, hi)
    comm.send((rows.shape, rows.indices.dtype.str, rows.nnz), dest=dest)
    for a in (rows.indptr, rows.indices, rows.data):
        comm.Send(np.ascontiguousarray(a), dest=dest)


def _receive_rows(comm) -> sp.csr_matrix:
    """The rows process 0 sends (``_send_rows``)."""
    shape, kind, nnz = comm.recv(source=0)
    indptr = np.empty(shape[0] + 1, dtype=kind)
    indices = np.empty(nnz, dtype=kind)
    data = np.empty(nnz)
    for a in (indptr, indices, data):
        comm.Recv(a, source=0)
    return sp.csr_matrix((data, indices, indptr), shape=shape)


def _command(comm, code: int, ident: int) -> None:
    """Process 0: send a command to the others (the solvers dropped since the last one first)."""
    while _forgotten:
        _broadcast(comm, _FORGET, _forgotten.pop())
    _broadcast(comm, code, ident)


def _broadcast(comm, code: int, ident: int) -> None:
    comm.Ibcast(np.array([code, ident], dtype=np.int64), root=0).Wait()


def _next_command(comm) -> tuple[int, int]:
    """A process other than 0: wait for process 0's next command, sleeping between looks."""
    buf = np.zeros(2, dtype=np.int64)
    request = comm.Ibcast(buf, root=0)
    while not request.Test():
        time.sleep(POLL_S)
    return int(buf[0]), int(buf[1])


def serve(comm) -> None:
    """A process other than 0: take part in process 0's solves until it stops, then end MPI.
    Interrupts are process 0's to handle (it finishes its step and keeps its outputs); an
    error here ends every process (``Abort``) rather than leave process 0 waiting."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    parts: dict[int, _Part] = {}
    try:
        while True:
            code, ident = _next_command(comm)
            if code == _STOP:
                break
            if code == _INIT:
                body_of, modes, rtol, restart, max_iterations = comm.bcast(None, root=0)
                parts[ident] = _Part(comm, body_of, modes, rtol, restart, max_iterations)
            elif code == _SETUP:
                seed = comm.bcast(None, root=0)
                parts[ident].setup(_receive_rows(comm), seed)
            elif code == _SOLVE:
                b, x0 = comm.scatter(None, root=0)
                comm.gather(parts[ident].solve(b, x0)[0], root=0)
            elif code == _FORGET:
                parts.pop(ident, None)
    except Exception:  # noqa: BLE001 (any error: the others must not wait for this one)
        traceback.print_exc()
        sys.stderr.flush()
        comm.Abort(1)
    _finalize()
