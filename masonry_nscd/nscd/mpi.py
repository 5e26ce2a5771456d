r"""Several processes for one run (``masonry run --processes P``): their launch, their
partition of the free dofs, and the commands by which process 0 drives the others.

A run launched by ``mpiexec -n P`` (``masonry run --processes P`` does it) solves the body
system of the Krylov solver (``linear.py``) with PETSc on all its processes
(``petsc_solve.py``); the rows of that system are split by ``partition``: process ``p`` owns
the bodies of one contiguous range (whole bodies, about as many dofs in each range; the
builders number the units course by course, so a range is a band of courses).

Process 0 runs the case as on one process (the joints, the blocks, Newton's iterations, the
Newton matrix, the outputs). It drives the others by commands (``command``): a new solver
(``INIT``), a new matrix (``SETUP``: it then sends every process its rows of ``S``, their
arrays as they are in memory, ``send_rows``), a solve (``SOLVE``), a solver dropped
(``FORGET``), each process's peak memory (``MEMORY``, gathered on process 0:
``peak_memory_per_process``), the end of the run (``STOP``). The other processes wait for
them (``serve``), looking every ``POLL_S`` and sleeping in between, so that they leave the
cores to process 0's kernels. So the linear solve's work and memory are split; the rest of a step is not yet
(``docs/scaling.md``, "Beyond one machine").
"""

from __future__ import annotations

import atexit
import os
import signal
import sys
import time
import traceback

import numpy as np
import scipy.sparse as sp

from masonry_nscd import MPI_SIZE_VARIABLES, timing
from masonry_nscd.nscd import linear

#: the environment variables in which mpiexec gives the number of processes and this one's rank
#: (MPICH's Hydra, Open MPI)
SIZE_VARIABLES = MPI_SIZE_VARIABLES
RANK_VARIABLES = ("PMI_RANK", "OMPI_COMM_WORLD_RANK")
#: the environment variable that names the file in which process 0 leaves its exit code
EXIT_FILE_VARIABLE = "MASONRY_EXIT_FILE"
#: how long a process waiting for a command sleeps between two looks, s
POLL_S = 2e-4
MISSING = ("several processes need PETSc, petsc4py and mpi4py built on the system's MPI: "
           "make mpi (docs/guide/solvers.md)")

#: process 0's commands to the others (module docstring)
STOP, INIT, SETUP, SOLVE, FORGET, MEMORY = range(6)
_comm = None
_stopped = False
_forgotten: list[int] = []  # ids of process 0's solvers gone since its last command


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
    """The Krylov solver of a Newton solver: PETSc's on every process when mpiexec launched
    several (``petsc_solve.py``), else the one of ``linear.py`` on this one."""
    comm = world()
    if comm is None:
        return linear.KrylovSolver(body_of, modes)
    from masonry_nscd.nscd import petsc_solve

    return petsc_solve.PetscKrylovSolver(comm, body_of, modes)


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
    command(comm, STOP, 0)
    _finalize()


def _finalize() -> None:
    """End MPI in this process (no MPI call may follow: ``shutdown`` is then a no-op)."""
    global _stopped
    from mpi4py import MPI

    from masonry_nscd.nscd import petsc_solve

    _stopped = True
    petsc_solve.finalize()
    MPI.Finalize()


def relaunch(processes: int, argv: list[str]) -> int:
    """Run ``masonry ARGV`` on ``processes`` processes under this environment's ``mpiexec``
    and return its exit code. A first Ctrl-C or a SIGTERM reaches every process (process 0
    ends its step and keeps its outputs); this process waits for them. A RuntimeError where
    mpiexec or mpi4py is missing."""
    import subprocess
    import tempfile

    launch = launcher(processes)
    fd, exit_file = tempfile.mkstemp(prefix="masonry-exit-")
    os.close(fd)
    child = subprocess.Popen([*launch, "-m", "masonry_nscd.cli", *argv],
                             env={**os.environ, EXIT_FILE_VARIABLE: exit_file})

    def forward(signum, frame):
        child.send_signal(signum)

    signal.signal(signal.SIGTERM, forward)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the terminal sends it to mpiexec as well
    try:
        code = child.wait()
        with open(exit_file) as f:
            told = f.read().strip()
        return int(told) if told else code
    finally:
        os.unlink(exit_file)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)


def launcher(processes: int) -> list[str]:
    """The command that starts this environment's Python on ``processes`` processes under its
    ``mpiexec`` (the module or script and its arguments to follow). A RuntimeError where
    mpiexec, mpi4py or petsc4py is missing."""
    import importlib.util
    import shutil

    mpiexec = os.path.join(os.path.dirname(sys.executable), "mpiexec")
    if not os.access(mpiexec, os.X_OK):
        mpiexec = shutil.which("mpiexec")
    if mpiexec is None or any(importlib.util.find_spec(m) is None
                              for m in ("mpi4py", "petsc4py")):
        raise RuntimeError(f"--processes {processes}: {MISSING}")
    return [mpiexec, "-n", str(processes), sys.executable]


def record_exit(code: int) -> None:
    """Process 0 under ``relaunch``: the exit code it leaves with, for ``relaunch`` to return
    (mpiexec returns 0 for a run it forwarded a SIGTERM to, whatever the processes' codes)."""
    path = os.environ.get(EXIT_FILE_VARIABLE)
    if path and launched_rank() == 0:
        with open(path, "w") as f:
            f.write(str(code))


def peak_memory_per_process() -> list[float]:
    """The peak resident memory of every process so far (MiB), process 0 first: this one's
    alone without mpiexec. Process 0 only (the others answer its ``MEMORY`` command)."""
    comm = world()
    if comm is None:
        return [timing.peak_memory_mib()]
    command(comm, MEMORY, 0)
    return [float(m) for m in comm.gather(timing.peak_memory_mib(), root=0)]


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


def rows(S: sp.csr_matrix, lo: int, hi: int) -> sp.csr_matrix:
    """Rows ``[lo, hi)`` of ``S`` (CSR, the columns as they are), views of its arrays but the
    row pointers."""
    p0, p1 = int(S.indptr[lo]), int(S.indptr[hi])
    return sp.csr_matrix((S.data[p0:p1], S.indices[p0:p1], S.indptr[lo:hi + 1] - p0),
                         shape=(hi - lo, S.shape[1]))


def send_rows(comm, dest: int, S: sp.csr_matrix, lo: int, hi: int) -> None:
    """Send rows ``[lo, hi)`` of ``S`` to process ``dest`` (``receive_rows``): their sizes,
    then the three arrays as they are in memory (no pickling: 4 M entries at 32 times the
    study's wall)."""
    part = rows(S, lo, hi)
    comm.send((part.shape, part.indices.dtype.str, part.nnz), dest=dest)
    for a in (part.indptr, part.indices, part.data):
        comm.Send(np.ascontiguousarray(a), dest=dest)


def receive_rows(comm) -> sp.csr_matrix:
    """The rows process 0 sends (``send_rows``)."""
    shape, kind, nnz = comm.recv(source=0)
    indptr = np.empty(shape[0] + 1, dtype=kind)
    indices = np.empty(nnz, dtype=kind)
    data = np.empty(nnz)
    for a in (indptr, indices, data):
        comm.Recv(a, source=0)
    return sp.csr_matrix((data, indices, indptr), shape=shape)


def command(comm, code: int, ident: int) -> None:
    """Process 0: send a command to the others (the solvers dropped since the last one first)."""
    while _forgotten:
        _broadcast(comm, FORGET, _forgotten.pop())
    _broadcast(comm, code, ident)


def forget(ident: int) -> None:
    """Process 0: its solver ``ident`` is gone; the others drop theirs at the next command."""
    _forgotten.append(ident)


def _broadcast(comm, code: int, ident: int) -> None:
    comm.Ibcast(np.array([code, ident], dtype=np.int64), root=0).Wait()


def _next_command(comm) -> tuple[int, int]:
    """A process other than 0: wait for process 0's next command, sleeping between looks."""
    buf = np.zeros(2, dtype=np.int64)
    request = comm.Ibcast(buf, root=0)
    while not request.Test():
        time.sleep(POLL_S)
    return int(buf[0]), int(buf[1])


def take_part() -> bool:
    """On a process other than 0 of those mpiexec launched: take part in process 0's solves
    until it stops (``serve``, this process's kernels on one thread), then True. False at once
    on process 0 or without mpiexec: the caller runs the work."""
    if launched_rank() == 0:
        return False
    from masonry_nscd import threads

    threads.set_count(1)
    serve(world())
    return True


def serve(comm) -> None:
    """A process other than 0: take part in process 0's solves until it stops, then end MPI.
    Interrupts are process 0's to handle (it finishes its step and keeps its outputs); an
    error here ends every process (``Abort``) rather than leave process 0 waiting."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    from masonry_nscd.nscd import petsc_solve

    parts: dict = {}
    try:
        while True:
            code, ident = _next_command(comm)
            if code == STOP:
                break
            if code == MEMORY:
                comm.gather(timing.peak_memory_mib(), root=0)
                continue
            petsc_solve.serve_command(comm, parts, code, ident)
    except Exception:  # noqa: BLE001 (any error: the others must not wait for this one)
        traceback.print_exc()
        sys.stderr.flush()
        comm.Abort(1)
    _finalize()
