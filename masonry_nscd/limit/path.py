r"""The non-associative collapse load by following the load from rest: rigid blocks on the
joints' springs, Coulomb friction without dilatancy, the growing load raised step by step.

With Coulomb friction that does not dilate, the collapse load of rigid blocks is not unique:
it depends on how the normal forces were built up (docs/limit.md). The iteration of fixed
friction capacities (:func:`masonry_nscd.limit.lp.solve_non_associative`) finds one fixed
point, not necessarily the one the structure loaded from rest reaches. This module follows
that structure: an incremental static analysis of rigid blocks whose joints are the case's
springs, the same unknowns and interface points as the static programme
(:mod:`.statics`).

Unknowns: the small displacement ``u`` (m, rad) of every body's reference point, six per free
body. The relative displacement of a point, in its frame ``(n, t, s)``, is ``g = B^T u``
(``B`` the equilibrium matrix, :func:`masonry_nscd.limit.statics.equilibrium_matrix`;
``g_n > 0`` opens). Each point is a spring of stiffness ``k_n = A / c_n`` in compression (no
tension) and ``k_t = A / c_t`` in shear (N/m; ``A`` its area, ``c`` the joint's compliances),
with Coulomb's friction and a plastic slip ``p`` (m) that remembers the path:

    N = k_n max(0, -g_n),     F* = -k_t (g_t - p),     F = F*                 if |F*| <= mu N
                                                        F = mu N F* / |F*|     otherwise

(the return to the cone along ``F*``: the slip has no normal part, no dilatancy). Equilibrium
of the free dofs at load factor ``lambda``:

    R(u) = B f(B^T u; p) + F_dead + lambda F_live = 0                   (N, N m)

solved by Newton's method on the non-smooth ``R`` (the slip's tangent is not symmetric) with a
line search on ``max |R|``; where even a thousandth of the step does not descend (a point
closes, sticks or slips within it) the full step is taken, up to three times a step, as the
active-set method takes all its steps. Each matrix is factorised by PARDISO (its pattern
analysed once) where MKL is installed, by SuperLU otherwise. The dead loads are applied in
ten steps, then ``lambda`` grows in steps; each converged step updates the slip ``p``.

**Viscous steps.** Where a step finds no static state (a point that sticks and slips in turn,
or a slip that must run before the blocks lock again) it is taken in pseudo-time: each step
solves ``R(u) = c (u - u_k)``, a dashpot ``c`` (N/m) on every dof pulling toward the last
state (the Duvaut-Lions regularisation of plasticity; a proximal point step of the equilibrium),
halving ``c`` after a success and multiplying it by 8 after a failure. The blocks are at rest
when the dashpot's force ``c |u_{k+1} - u_k|`` is below the tolerance of equilibrium; they
collapse when a block point has moved ``flow_m`` since the load step began, or when the flow
is steady: the same out-of-balance load over three successful steps at whatever dashpot means
constant forces, and a flow at constant forces only changes when an open point closes. It then
runs along its last step to the first such closing in one move, or is a collapse if the blocks
move ``flow_m`` before any closes. The collapse multiplier is then
bracketed between the last load at rest and the first that collapses, the step halved until
the bracket is narrower than ``rtol`` of the multiplier.

**The first flow ends the path.** ``flow_m`` is a tenth (``FLOW_PART``) of the case's collapse
displacement ``collapse_m`` (1 mm for the shipped 10 mm): a load step moves the blocks microns
while they stand and millimetres once they flow. A flow that stops again before the collapse
displacement leaves the blocks in a new state whose later capacity depends on the path to the
rounding of its sums (the dome at mu = 2 carried 0.70 or 0.77 after such flows, from two orders
of the same sums; docs/limit.md), while the load at which the first flow starts does not: it
is the counterpart of the NSCD run's onset, its last step with every block at rest.

The mechanism is the displacement of the collapsing flow (the bodies' motion from the last
state at rest), normalised as the programme's dual (fastest node 1); the joint forces are those
of the last state at rest. Displacements are small: the joints' geometry is that of the scene.
This is the quasi-static counterpart of the NSCD run with rigid blocks: no inertia, no
impacts, no large displacements.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from masonry_nscd.limit import path_kernels as kernels
from masonry_nscd.limit.lp import LimitSolution, normalised_mechanism
from masonry_nscd.limit.statics import RigidModel, point_velocities, spring_compliances
from masonry_nscd.nscd import pardiso

#: Newton's tolerance: ``max |R|`` below this times the largest load component.
TOLERANCE = 1e-7
#: At rest: the dashpot's force (the out-of-balance load) below this times the largest load
#: component.
REST = TOLERANCE
#: Newton iterations per (static or viscous) step.
NEWTON_ITERATIONS = 20
#: Full Newton steps taken without descent of ``max |R|`` per (static or viscous) step.
UNGUARDED = 3
#: The dead loads' steps.
DEAD_STEPS = 10
#: The first load step, as a part of the dead loads' largest component over the live load's.
FIRST_STEP = 0.01
#: The bracket of the collapse multiplier, relative.
RTOL = 1e-3
#: The reason a load step ends in collapse (other reasons are the solver's failures).
COLLAPSED = "the blocks moved"
#: Load steps at most.
MAX_STEPS = 2000
#: Viscous steps per load step at most, and the dashpot's range over the mean stiffness.
FLOW_STEPS = 5000
DASHPOT_MIN, DASHPOT_FIRST, DASHPOT_MAX = 1e-9, 1e-6, 1e3
#: The flow that ends the path, as a part of the case's collapse displacement (module
#: docstring).
FLOW_PART = 0.1
#: A line of progress at most this often within a load step (s of wall clock): a viscous step
#: of a large scene takes seconds (the nave bay's 17,478 dofs: about 13 Newton iterations of
#: 0.1 s each), so a count of steps would leave the user minutes without a word.
REPORT_S = 15.0
#: A steady flow: this many successful viscous steps in a row whose out-of-balance loads
#: agree within ``STEADY`` of the largest component, at whatever dashpot.
STEADY_STEPS, STEADY = 3, 1e-6
#: A point's gap closes in a flow when it shrinks faster than this part of the fastest
#: gap's rate (slower: rounding).
RATE_FLOOR = 1e-9


def joint_forces(g: np.ndarray, slip: np.ndarray, kn: np.ndarray, kt: np.ndarray,
                 mu: np.ndarray, glued: np.ndarray):
    """The forces ``(N, T, S)`` (p, 3) (N) of the points at relative displacement ``g`` (p, 3)
    (m) with plastic slip ``slip`` (p, 2) (module docstring), their tangent ``df/dg`` (p, 3, 3)
    (N/m), the slip after the step, and the masks of the closed and sliding points. A glued
    point is a linear spring in every direction (:func:`.path_kernels.law`)."""
    p = len(g)
    f, D, after = np.empty((p, 3)), np.empty((p, 3, 3)), np.empty((p, 2))
    closed, sliding = np.empty(p, np.bool_), np.empty(p, np.bool_)
    kernels.law(np.ascontiguousarray(g, dtype=float), np.ascontiguousarray(slip, dtype=float),
                kn, kt, mu, glued, f, D, after, closed, sliding)
    return f, D, after, closed, sliding


class _Points:
    """The map between the free dofs and the points: ``G`` (p, 12, 3), each point's three
    frame directions as generalised forces on the six dofs of its two bodies (the columns of
    ``B``), ``dof`` (p, 12) their free-dof numbers (-1: not free); the Newton matrix
    ``B D B^T`` summed into a fixed pattern."""

    def __init__(self, m: RigidModel, linear: str = "auto"):
        self.n = int(m.free.sum())
        number = np.full(6 * m.bodies, -1)
        number[m.free] = np.arange(self.n)
        G = np.zeros((m.points, 12, 3))
        dof = np.zeros((m.points, 12), np.int64)
        for side, sign in ((0, 1.0), (1, -1.0)):
            b = m.pair[:, side]
            r = m.x - m.reference[b]
            for k in range(3):
                d = m.frame[:, k, :]
                G[:, 6 * side:6 * side + 3, k] = sign * d
                G[:, 6 * side + 3:6 * side + 6, k] = sign * np.cross(r, d)
            dof[:, 6 * side:6 * side + 6] = number[6 * b[:, None] + np.arange(6)]
        G[dof < 0] = 0.0
        self.G, self.dof = G, dof
        i = np.repeat(dof, 12, axis=1).ravel()
        j = np.tile(dof, (1, 12)).ravel()
        used = (i >= 0) & (j >= 0)  # in the order point, row, column: the kernel's
        # the pattern in compressed columns, with the whole diagonal (the dashpot's)
        n = self.n
        diagonal = np.arange(n) * (n + 1)
        key, slot = np.unique(np.concatenate([j[used] * n + i[used], diagonal]),
                              return_inverse=True)
        pairs = len(slot) - n  # the points' entries first, then the diagonal's
        self.slot, self.diagonal = slot[:pairs], slot[pairs:]
        self.indices = (key % n).astype(np.int32)
        self.indptr = np.searchsorted(key // n, np.arange(n + 1)).astype(np.int32)
        self.nnz = len(key)
        # one thread: the matrices are small, and a second OpenMP thread waits on a busy core
        self._pardiso = pardiso.Pardiso(self.indptr, self.indices, n, n_threads=1) \
            if linear == "auto" and pardiso.available() and n else None

    def gap(self, x: np.ndarray) -> np.ndarray:
        """``B^T u`` (p, 3) for the free dofs' displacements ``x``."""
        g = np.empty((len(self.G), 3))
        kernels.gaps(np.ascontiguousarray(x, dtype=float), self.G, self.dof, g)
        return g

    def force(self, f: np.ndarray) -> np.ndarray:
        """``B f`` on the free dofs for the point forces ``f`` (p, 3)."""
        r = np.empty(self.n)
        kernels.forces(np.ascontiguousarray(f, dtype=float), self.G, self.dof, r)
        return r

    def matrix(self, D: np.ndarray, c: float = 0.0) -> np.ndarray:
        """The values of ``B D B^T - c I`` on the free dofs, in the pattern's order, for the
        point blocks ``D`` (p, 3, 3) and the dashpot ``c``."""
        data = np.empty(self.nnz)
        kernels.matrix(np.ascontiguousarray(D, dtype=float), self.G, self.dof, self.slot, data)
        data[self.diagonal] -= c
        return data

    @property
    def linear_solver(self) -> str:
        """The direct solver of the Newton matrices: ``PARDISO`` or ``SuperLU``."""
        return "SuperLU" if self._pardiso is None else "PARDISO"

    def solve(self, data: np.ndarray, b: np.ndarray) -> np.ndarray:
        """``x`` with ``J x = b``, ``J`` the matrix of values ``data``: PARDISO, its pattern
        analysed once, where MKL is installed; SuperLU otherwise. Raises ``RuntimeError``
        where the matrix is singular."""
        if self._pardiso is not None:
            return self._pardiso.factorise(data).solve(b)
        J = sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                return spl.splu(J).solve(b)
            except (spl.MatrixRankWarning, RuntimeWarning) as error:
                raise RuntimeError(str(error)) from error


def _stiffness(m: RigidModel) -> tuple[np.ndarray, np.ndarray]:
    """The points' springs ``k_n = A / c_n``, ``k_t = A / c_t`` (N/m)."""
    cn, ct = spring_compliances(m)
    return m.area / cn, m.area / ct


class _Path:
    """The state along the load path and its steps (module docstring)."""

    def __init__(self, m: RigidModel, flow_m: float, linear: str = "auto"):
        self.m, self.flow_m = m, flow_m
        self.points = _Points(m, linear)
        self.kn, self.kt = _stiffness(m)
        self.free = np.flatnonzero(m.free)
        D0 = np.zeros((m.points, 3, 3))
        D0[:, 0, 0] = -self.kn
        self.stiff = float(np.abs(self.points.matrix(D0)[self.points.diagonal]).mean()) or 1.0
        self.dashpot = DASHPOT_FIRST * self.stiff
        reach = np.zeros(m.bodies)  # a body's largest node distance from its reference (m)
        for b, (X, _) in enumerate(m.meshes):
            if len(X):
                reach[b] = float(np.linalg.norm(X - m.reference[b], axis=1).max())
        self.reach = reach
        self.x = np.zeros(self.points.n)
        self.slip = np.zeros((m.points, 2))
        self.newton = self.flow_steps = self.jumps = 0

    def moved(self, x: np.ndarray, x0: np.ndarray) -> float:
        """The largest displacement of a block point between two states (m; a bound: the
        translation plus the rotation times the body's reach)."""
        d = np.zeros(6 * self.m.bodies)
        d[self.free] = x - x0
        d = d.reshape(-1, 6)
        return float((np.linalg.norm(d[:, :3], axis=1)
                      + np.linalg.norm(d[:, 3:], axis=1) * self.reach).max())

    def _residual(self, x, F, x0, c, slip):
        m = self.m
        f, D, after, closed, sliding = joint_forces(self.points.gap(x), slip, self.kn,
                                                    self.kt, m.mu, m.glued)
        return self.points.force(f) + F - c * (x - x0), D, (f, after, closed, sliding)

    def step(self, F: np.ndarray, x0: np.ndarray, slip: np.ndarray, c: float):
        """Newton on ``R(x) = c (x - x0)``; ``(x, (f, slip, closed, sliding))`` or None."""
        scale = max(float(np.abs(F).max()), 1e-300)
        x = x0.copy()
        r, D, state = self._residual(x, F, x0, c, slip)
        res = float(np.abs(r).max()) / scale
        unguarded = 0
        for _ in range(NEWTON_ITERATIONS):
            self.newton += 1
            if res < TOLERANCE:
                return x, state
            try:
                dx = self.points.solve(self.points.matrix(D, c), -r)
            except RuntimeError:  # PardisoError is one
                return None
            if not np.all(np.isfinite(dx)):
                return None
            t = 1.0
            while True:
                trial = self._residual(x + t * dx, F, x0, c, slip)
                new = float(np.abs(trial[0]).max()) / scale
                if new < (1.0 - 1e-4 * t) * res or t < 1e-3:
                    break
                t *= 0.5
            if new >= res:
                if unguarded == UNGUARDED:
                    return None
                # no descent: a kink (a point that closes, sticks or slips) within the
                # shortest trial; the full step crosses it, as the active-set method would
                unguarded += 1
                t = 1.0
                trial = self._residual(x + dx, F, x0, c, slip)
                new = float(np.abs(trial[0]).max()) / scale
            x = x + t * dx
            r, D, state = trial
            res = new
            if self.moved(x, x0) > self.flow_m:
                return None
        return None

    def settle(self, F: np.ndarray, report: Callable[[str], None] | None = None):
        """The state at rest under the free dofs' load ``F`` from the current one, by viscous
        steps (module docstring): ``(x, (f, slip, closed, sliding))``, or ``(None, why,
        x_last)`` when the blocks move ``flow_m`` or no step converges. ``report``, if
        given, is told at most every ``REPORT_S`` seconds how far the blocks have moved and the
        out-of-balance load."""
        scale = max(float(np.abs(F).max()), 1e-300)
        x0 = self.x.copy()
        x, slip, c = x0.copy(), self.slip, self.dashpot
        last: list[np.ndarray] = []  # the out-of-balance of the last successful steps
        told = time.perf_counter()
        for k in range(1, FLOW_STEPS + 1):
            if report is not None and time.perf_counter() - told >= REPORT_S:
                told = time.perf_counter()
                pull = (f", out-of-balance {float(np.abs(last[-1]).max()) / scale:.2e} of the "
                        "largest load" if last else "")
                report(f"flowing after {k} viscous steps, moved {1e3 * self.moved(x, x0):.3g} "
                       f"mm{pull}")
            self.flow_steps += 1
            out = self.step(F, x, slip, c)
            if out is None:
                c *= 8.0
                if c > DASHPOT_MAX * self.stiff:
                    return None, "no viscous step converges", x
                continue
            new, state = out
            dx = new - x
            x, slip = new, state[1]
            if self.moved(x, x0) > self.flow_m:
                return None, f"{COLLAPSED} {self.flow_m:g} m", x
            pull = c * dx  # the dashpot's force: the out-of-balance load at x (N, N m)
            if float(np.abs(pull).max()) <= REST * scale:
                self.dashpot = max(c / 8.0, DASHPOT_MIN * self.stiff)
                return x, state
            last = last[-(STEADY_STEPS - 1):] + [pull]
            if len(last) == STEADY_STEPS and all(
                    float(np.abs(q - pull).max()) <= STEADY * float(np.abs(pull).max())
                    for q in last[:-1]):
                # a steady flow: the same out-of-balance whatever the dashpot, the forces
                # constant; it runs along dx until an open point closes
                self.jumps += 1
                last = []
                run = self.flow_run(x, dx)
                per = self.moved(x + dx, x)
                left = self.flow_m - self.moved(x, x0)
                if run * per >= left:
                    return None, f"{COLLAPSED} {self.flow_m:g} m (a steady flow)", \
                        x + (left / per) * dx
                x = x + run * dx
                slip = joint_forces(self.points.gap(x), slip, self.kn, self.kt, self.m.mu,
                                    self.m.glued)[2]
                continue
            c = max(c / 2.0, DASHPOT_MIN * self.stiff)
        return None, f"not at rest after {FLOW_STEPS} viscous steps", x

    def flow_run(self, x: np.ndarray, dx: np.ndarray) -> float:
        """How far a steady flow from ``x`` runs along ``dx`` (in multiples of ``dx``) before
        an open point closes (``inf`` if none closes): in a steady flow the forces are
        constant, the sliding points keep their direction and the closed points their
        gaps, so the first open point to close is the flow's only event."""
        g = self.points.gap(x)[:, 0]
        rate = self.points.gap(dx)[:, 0]
        closing = (g > 0.0) & (rate < -RATE_FLOOR * max(float(np.abs(rate).max()), 1e-300))
        return float((g[closing] / -rate[closing]).min()) if closing.any() else np.inf


def follow_load(m: RigidModel, *, collapse_m: float = 0.01, rtol: float = RTOL,
                progress: Callable[[str], None] | None = None,
                linear: str = "auto") -> tuple[LimitSolution, dict]:
    """The collapse multiplier of the growing load followed from rest (module docstring), the
    path ended by a flow of ``FLOW_PART`` of ``collapse_m`` (m) in one load step:
    the solution (its multiplier the last load at rest, the forces there, the mechanism of
    the collapsing flow) and the record (``dead_loads``, ``steps``, ``viscous_steps``,
    ``newton_iterations``, ``bracket``, ``stopped_by``, ``collapsed``: whether the last load
    step above the multiplier collapsed or the solver failed there, ``steady_flows``: the
    steady flows run in one move, ``linear_solver``). ``progress``, if given,
    is called with a line per load step (the load, at rest or why not, the viscous steps and
    the time so far). ``linear``: ``auto`` (PARDISO where MKL is installed, else SuperLU) or
    ``lu`` (SuperLU)."""
    if linear not in ("auto", "lu"):
        raise ValueError(f"linear: auto or lu, got {linear!r}")
    def say(text: str) -> None:
        if progress is not None:
            progress(f"load path: {text} ({path.flow_steps} viscous steps, "
                     f"{time.perf_counter() - t0:.0f} s)")

    t0 = time.perf_counter()
    path = _Path(m, FLOW_PART * collapse_m, linear)
    F_dead, F_live = m.dead[path.free], m.live[path.free]
    record = {"method": "load followed from rest, rigid blocks on the joints' springs, "
                        "viscous steps where no static state is found",
              "collapse_m": collapse_m, "flow_m": FLOW_PART * collapse_m, "rtol": rtol,
              "dead_loads": "carried", "steps": 0, "bracket": None, "stopped_by": None}
    npt = m.points
    forces, velocity, status, message, multiplier = np.zeros((npt, 3)), np.zeros((m.bodies, 6)), \
        "optimal", "", None
    state = None
    for k in range(1, DEAD_STEPS + 1):
        out = path.settle(k / DEAD_STEPS * F_dead,
                          lambda text, k=k: say(f"dead loads {k}/{DEAD_STEPS}: {text}"))
        if out[0] is None:
            record["dead_loads"] = f"not carried: at {k}/{DEAD_STEPS} of them, {out[1]}"
            status, message = "infeasible", record["dead_loads"]
            break
        path.x, state = out
        path.slip = state[1]
        say(f"dead loads {k}/{DEAD_STEPS}: carried")
    if status == "optimal" and m.factor is not None:
        big = float(np.abs(F_live).max()) or 1.0
        first = FIRST_STEP * max(float(np.abs(F_dead).max()), 1e-12) / big
        lam, dl = 0.0, first
        while dl > rtol * max(lam, 1e-300):
            if record["steps"] >= MAX_STEPS:
                record["stopped_by"] = f"no collapse within {MAX_STEPS} load steps"
                status, message = "unbounded", record["stopped_by"]
                break
            out = path.settle(F_dead + (lam + dl) * F_live,
                              lambda text, v=lam + dl: say(f"{m.factor} = {v:.6g}: {text}"))
            say(f"{m.factor} = {lam + dl:.6g}: " + (
                f"at rest, moved {1e3 * path.moved(out[0], path.x):.3g} mm"
                if out[0] is not None else f"{out[1]}; the step halved"))
            if out[0] is None:
                record["stopped_by"] = out[1]
                record["bracket"] = [lam, lam + dl]
                fall = out[2]
                dl *= 0.5
                continue
            path.x, state = out
            path.slip = state[1]
            lam += dl
            record["steps"] += 1
            dl = min(1.5 * dl, first)
        multiplier = lam if status == "optimal" else None
        if record["bracket"] is not None and multiplier is not None:
            d = np.zeros(6 * m.bodies)
            d[path.free] = fall - path.x
            velocity = normalised_mechanism(m, d.reshape(-1, 6))
    if state is not None:
        forces = state[0]
    # a collapse, or the solver's failure above the last load at rest (said, not hidden)
    record["collapsed"] = str(record["stopped_by"] or "").startswith(COLLAPSED)
    record["viscous_steps"] = path.flow_steps
    record["newton_iterations"] = path.newton
    record["steady_flows"] = path.jumps
    record["linear_solver"] = path.points.linear_solver
    counts = {"bodies": m.bodies, "free_bodies": int((~m.support).sum()), "points": npt,
              "glued_points": int(m.glued.sum()), "dofs": path.points.n}
    sol = LimitSolution(status, message, multiplier, forces, velocity,
                        point_velocities(m, velocity), counts,
                        {"assemble": 0.0, "solve": time.perf_counter() - t0})
    return sol, record
