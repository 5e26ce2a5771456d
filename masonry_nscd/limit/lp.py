r"""The static theorem of limit analysis for rigid blocks as a conic programme, and its dual,
the collapse mechanism.

Unknowns: the force ``(N, T, S)`` (N) of every interface point (:mod:`.statics`) and the load
multiplier ``lambda`` (the unit of the growing load factor). The programme

    maximise lambda   subject to   B f + lambda F_live = -F_dead     (free dofs, 6 per body)
                                   N >= -f_t A                      (f_t = 0: no tension)
                                   |(T, S)| <= c A + mu N           (Coulomb's cone)
                                   N <= f_c A                       (optional: crushing)

Glued points carry any force. The optional bound ``f_c`` (Pa) caps the compression of each
point by its tributary area: a joint's resultant can then not reach its edge, the hinges move
inwards. Coulomb's cone is taken exactly, as a second-order cone
(``facets = 0``, the default), or as the pyramid of ``k`` facets of :mod:`.friction`
(``facets = k``, a linear programme). Its optimum is the largest multiplier that admissible
forces equilibrate: the collapse multiplier of the associative (normality) model, in which a
sliding joint also dilates by ``mu`` times its slip. With the frictional capacity exact (a
joint that does not slide) it is the collapse multiplier itself; where sliding takes part, the
associative multiplier is an upper bound of the one with non-associative Coulomb friction (no
dilatancy).

**Solvers** (:data:`SOLVERS`). ``clarabel`` (the default): Clarabel's interior point for
conic programmes, whose every step factorises the sparse KKT system directly (QDLDL, or faer's
supernodal LDL for large programmes, :data:`SUPERNODAL_FROM`); it takes the exact cone and the
pyramid alike. The equilibrium rows couple only bodies in contact, so the system is sparse,
but its factor fills in and the cost grows faster than the points. ``highs``: HiGHS's
interior point with crossover through ``scipy.optimize.linprog``, the pyramid only; its
interior point solves its normal equations iteratively (conjugate gradients), which on
thousands of points is 5 to 30 times slower, but its crossover ends on a vertex: an
independent check of the same programme.

The **mechanism** is the dual: the multipliers of the equilibrium rows are the virtual
velocities ``(v, omega)`` (m/s, rad/s per unit) of the bodies' reference points, normalised so
that the fastest node of a free body moves at 1 and the growing load does positive work.
``lambda F_live . v = - F_dead . v - (work of the cohesion)``: the virtual work equation of
the kinematic theorem, checked in the tests.

Rows are scaled before the solve: forces by the larger of the dead and live loads' resultants
``W`` (N), moments by ``W L`` (``L`` the extent of the interface points, m).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from masonry_nscd.limit import friction
from masonry_nscd.limit.statics import (
    RigidModel,
    equilibrium_matrix,
    point_velocities,
    spring_compliances,
)

#: The solvers of the programme (module docstring), the default first.
SOLVERS = ("clarabel", "highs")
#: HiGHS's method when asked for: its interior point with crossover (a vertex, whose duals are
#: the mechanism).
HIGHS_METHOD = "highs-ipm"
#: Clarabel's tolerances (relative gap, feasibility): tighter than its defaults, so that the
#: multiplier is good to about 1e-9 and the mechanism's small velocities are read clearly.
CLARABEL_TOLERANCE = 1e-10
#: Clarabel's factorisation: QDLDL (a simple LDL) below this many unknowns, faer's supernodal
#: LDL from there, where its fill-reducing supernodes pay (docs/limit.md, the timing table).
SUPERNODAL_FROM = 100_000
#: ``linprog``'s status codes, by name.
LP_STATUS = {0: "optimal", 1: "iteration limit", 2: "infeasible", 3: "unbounded",
             4: "numerical difficulties"}
#: Clarabel's statuses, by the names of :data:`LP_STATUS`.
CLARABEL_STATUS = {"Solved": "optimal", "AlmostSolved": "optimal",
                   "PrimalInfeasible": "infeasible", "AlmostPrimalInfeasible": "infeasible",
                   "DualInfeasible": "unbounded", "AlmostDualInfeasible": "unbounded",
                   "MaxIterations": "iteration limit", "MaxTime": "time limit"}


@dataclass
class LimitSolution:
    """The solution of :func:`solve_limit`."""

    status: str  # optimal, infeasible, unbounded, ... (LP_STATUS)
    message: str
    multiplier: float | None  # the growing factor's value at collapse (None: not optimal)
    forces: np.ndarray  # (p, 3) N: N, T, S per point (zeros unless optimal)
    velocity: np.ndarray  # (b, 6) the mechanism (zeros unless optimal with a growing load)
    point_velocity: np.ndarray  # (p, 3) the relative velocity of each point (n, t, s)
    counts: dict = field(default_factory=dict)
    times_s: dict = field(default_factory=dict)


def _scales(m: RigidModel) -> tuple[float, float]:
    def resultant(F: np.ndarray) -> float:
        return float(np.abs(F.reshape(-1, 6)[:, :3]).sum())

    W = max(resultant(m.dead), resultant(m.live), 1e-12)
    L = float(np.ptp(m.x, axis=0).max()) if m.points else 1.0
    return W, max(L, 1e-6)


@dataclass
class _Programme:
    """The scaled programme: ``min c x`` subject to ``A_eq x = b_eq``, ``G x <= h`` (rows
    ``G_lin``) and, per cone ``i``, ``h_i - G_i x`` in the second-order cone of dimension 3."""

    c: np.ndarray
    A_eq: sp.csr_matrix
    b_eq: np.ndarray
    G_lin: sp.csr_matrix
    h_lin: np.ndarray
    G_soc: sp.csr_matrix  # (3 q, n)
    h_soc: np.ndarray
    row_scale: np.ndarray  # of the equilibrium rows (N, N m)
    lam_scale: float  # lambda = x[-1] * lam_scale
    W: float
    P_diag: np.ndarray | None = None  # a quadratic term (1/2) x P x, P diagonal (proximal)
    normal_cols: np.ndarray | None = None  # the variables N of the first rows of G_lin
    crush_cols: np.ndarray | None = None  # the variables N of the crushing rows after them


def _programme(m: RigidModel, facets: int, tension: bool, with_lambda: bool,
               normal_limit: np.ndarray | None, proximal: float = 0.0,
               compressive_Pa: float | None = None, normal_penalty: float = 0.0) -> _Programme:
    npt = m.points
    W, L = _scales(m)
    row_scale = np.tile([W, W, W, W * L, W * L, W * L], m.bodies)[m.free]
    B = equilibrium_matrix(m)[m.free]
    A_eq = sp.diags(1.0 / row_scale) @ B * W  # the forces in units of W
    b_eq = -m.dead[m.free] / row_scale
    live = m.live[m.free] / row_scale
    lam_scale = 1.0
    if with_lambda:
        lam_scale = 1.0 / max(float(np.abs(live).max()), 1e-300)
        A_eq = sp.hstack([A_eq, sp.csr_matrix(live[:, None] * lam_scale)])
    A_eq = sp.csr_matrix(A_eq)
    nvar = 3 * npt + int(with_lambda)
    joint = np.flatnonzero(~m.glued)
    nj = len(joint)
    # the cone's radius: capacity + mu_eff N (in units of W)
    cohesion = m.cohesion_Pa if tension else np.zeros(npt)
    capacity = cohesion * m.area / W
    mu_eff = m.mu.copy()
    if normal_limit is not None:  # a fixed capacity mu Nbar, no dilatancy
        capacity = capacity + m.mu * np.maximum(normal_limit, 0.0) / W
        mu_eff = np.zeros(npt)
    # N >= -f_t A  as  -N <= f_t A; with the cone, mu N >= |(T, S)| >= 0 already says N >= 0
    # where there is no capacity (the row would only add to the factorisation)
    tensile = m.tensile_Pa[joint] * m.area[joint] / W if tension else np.zeros(nj)
    bound = np.ones(nj, bool) if facets else (capacity[joint] > 0.0) | (mu_eff[joint] <= 0.0)
    rows_n = np.flatnonzero(bound)
    G_n = sp.csr_matrix((-np.ones(len(rows_n)), (np.arange(len(rows_n)), 3 * joint[rows_n])),
                        shape=(len(rows_n), nvar))
    h_n = tensile[rows_n]
    crush_cols = np.zeros(0, np.int64)
    if compressive_Pa is not None:  # N <= f_c A
        crush_cols = 3 * joint
        G_c = sp.csr_matrix((np.ones(nj), (np.arange(nj), crush_cols)), shape=(nj, nvar))
        G_n = sp.vstack([G_n, G_c]).tocsr()
        h_n = np.concatenate([h_n, compressive_Pa * m.area[joint] / W])
    if facets:  # the pyramid's rows (module friction)
        normals = friction.facet_normals(facets)
        k = len(normals)
        cosk = friction.inscribed_fraction(facets)
        rows = np.repeat(np.arange(nj * k), 3)
        pcol = np.repeat(3 * joint, k)
        cols = np.stack([pcol, pcol + 1, pcol + 2], axis=1).ravel()
        vals = np.stack([-np.repeat(mu_eff[joint], k) * cosk, np.tile(normals[:, 0], nj),
                         np.tile(normals[:, 1], nj)], axis=1).ravel()
        G_f = sp.csr_matrix((vals, (rows, cols)), shape=(nj * k, nvar))
        G_lin = sp.vstack([G_n, G_f]).tocsr()
        h_lin = np.concatenate([h_n, np.repeat(capacity[joint] * cosk, k)])
        G_soc, h_soc = sp.csr_matrix((0, nvar)), np.zeros(0)
    else:  # (capacity + mu N, T, S) in the second-order cone: h - G x
        G_lin, h_lin = G_n, h_n
        rows = np.arange(3 * nj)
        cols = (3 * joint[:, None] + np.arange(3)).ravel()
        vals = -np.stack([mu_eff[joint], np.ones(nj), np.ones(nj)], axis=1).ravel()
        G_soc = sp.csr_matrix((vals, (rows, cols)), shape=(3 * nj, nvar))
        h_soc = np.zeros(3 * nj)
        h_soc[0::3] = capacity[joint]
    c = np.zeros(nvar)
    if with_lambda:
        c[-1] = -1.0
    P_diag = None
    if proximal > 0.0 and normal_limit is not None:
        # (proximal / 2) sum (N - Nbar)^2 in units of W: the force set nearest Nbar; and
        # normal_penalty sum N: no normal force that carries nothing (the slack)
        P_diag = np.zeros(nvar)
        P_diag[3 * joint] = proximal
        c[3 * joint] += normal_penalty - proximal * np.maximum(normal_limit[joint], 0.0) / W
    return _Programme(c, A_eq, b_eq, G_lin, h_lin, G_soc, h_soc, row_scale, lam_scale, W,
                      P_diag, 3 * joint[rows_n], crush_cols)


def _solve_clarabel(p: _Programme) -> tuple[str, str, np.ndarray | None, np.ndarray | None]:
    """Status, message, the solution ``x`` and the equilibrium rows' multipliers."""
    import clarabel

    n = len(p.c)
    A = sp.vstack([p.A_eq, p.G_lin, p.G_soc]).tocsc()
    b = np.concatenate([p.b_eq, p.h_lin, p.h_soc])
    cones = [clarabel.ZeroConeT(p.A_eq.shape[0])]
    if p.G_lin.shape[0]:
        cones.append(clarabel.NonnegativeConeT(p.G_lin.shape[0]))
    cones += [clarabel.SecondOrderConeT(3)] * (p.G_soc.shape[0] // 3)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = CLARABEL_TOLERANCE
    settings.tol_feas = CLARABEL_TOLERANCE
    settings.max_threads = 1
    settings.direct_solve_method = "faer" if n >= SUPERNODAL_FROM else "qdldl"
    P = sp.csc_matrix((n, n)) if p.P_diag is None else sp.diags(p.P_diag).tocsc()
    sol = clarabel.DefaultSolver(P, p.c, A, b, cones, settings).solve()
    name = str(sol.status).split(".")[-1]
    status = CLARABEL_STATUS.get(name, "numerical difficulties")
    message = f"Clarabel: {name} after {sol.iterations} iterations"
    if status != "optimal":
        return status, message, None, None
    return status, message, np.asarray(sol.x), np.asarray(sol.z[:p.A_eq.shape[0]])


def _solve_highs(p: _Programme) -> tuple[str, str, np.ndarray | None, np.ndarray | None]:
    from scipy.optimize import linprog

    if p.G_soc.shape[0] or p.P_diag is not None:
        raise ValueError("the solver highs takes the friction pyramid only (facets >= 3) and "
                         "no proximal term")
    bounds = np.column_stack([np.full(len(p.c), -np.inf), np.full(len(p.c), np.inf)])
    # the rows -N <= f_t A as bounds of the variables (HiGHS takes them at no cost)
    k, kc = len(p.normal_cols), len(p.crush_cols)
    bounds[p.normal_cols, 0] = -p.h_lin[:k]
    bounds[p.crush_cols, 1] = p.h_lin[k:k + kc]
    G, h = p.G_lin[k + kc:], p.h_lin[k + kc:]
    res = linprog(p.c, A_ub=G if G.shape[0] else None, b_ub=h if G.shape[0] else None,
                  A_eq=p.A_eq, b_eq=p.b_eq, bounds=bounds, method=HIGHS_METHOD)
    status = LP_STATUS.get(res.status, f"status {res.status}")
    if res.status != 0:
        return status, str(res.message), None, None
    return status, str(res.message), np.asarray(res.x), np.asarray(res.eqlin.marginals)


def solve_limit(m: RigidModel, facets: int = friction.DEFAULT_FACETS, *, tension: bool = False,
                dead_only: bool = False, normal_limit: np.ndarray | None = None,
                solver: str = SOLVERS[0], proximal: float = 0.0,
                compressive_Pa: float | None = None,
                normal_penalty: float = 0.0) -> LimitSolution:
    """The programme of the module docstring for the rigid model ``m``; ``facets``: 0 for
    Coulomb's cone, ``k >= 3`` for the pyramid of ``k`` facets; ``tension``: the joints'
    tensile strength and cohesion (:mod:`.statics`) count; ``dead_only`` (or a model with no
    growing load): whether the dead loads alone can be carried (no multiplier);
    ``normal_limit`` (p,) N: friction of fixed capacity ``mu normal_limit`` instead of
    ``mu N`` (a step of :func:`solve_non_associative`); ``solver``: one of :data:`SOLVERS`;
    ``compressive_Pa``: the compressive strength ``f_c`` (None: infinite); ``proximal`` and
    ``normal_penalty``: the terms of a non-associative step (:func:`solve_non_associative`)."""
    if solver not in SOLVERS:
        raise ValueError(f"solver: one of {', '.join(SOLVERS)}, got {solver!r}")
    if facets and facets < 3:
        raise ValueError(f"facets: 0 (the cone) or at least 3, got {facets}")
    t0 = time.perf_counter()
    npt = m.points
    with_lambda = not dead_only and m.factor is not None
    prog = _programme(m, facets, tension, with_lambda, normal_limit, proximal, compressive_Pa,
                      normal_penalty)
    t1 = time.perf_counter()
    run = _solve_clarabel if solver == "clarabel" else _solve_highs
    status, message, x, y = run(prog)
    t2 = time.perf_counter()
    forces = np.zeros((npt, 3))
    velocity = np.zeros((m.bodies, 6))
    multiplier = None
    if status == "optimal":
        forces = x[:3 * npt].reshape(npt, 3) * prog.W
        if with_lambda:
            multiplier = float(x[-1] * prog.lam_scale)
            velocity = _mechanism(m, y, prog.row_scale)
    counts = {"bodies": m.bodies, "free_bodies": int((~m.support).sum()), "points": npt,
              "glued_points": int(m.glued.sum()), "variables": len(prog.c),
              "equations": int(prog.A_eq.shape[0]),
              "inequalities": int(prog.G_lin.shape[0]), "cones": int(prog.G_soc.shape[0] // 3),
              "facets": facets}
    return LimitSolution(status, message, multiplier, forces, velocity,
                         point_velocities(m, velocity), counts,
                         {"assemble": t1 - t0, "solve": t2 - t1})


def _mechanism(m: RigidModel, marginals: np.ndarray, row_scale: np.ndarray) -> np.ndarray:
    """The bodies' velocities (b, 6) from the multipliers of the scaled equilibrium rows
    (module docstring)."""
    y = np.zeros(6 * m.bodies)
    y[m.free] = np.asarray(marginals) / row_scale
    return normalised_mechanism(m, y.reshape(-1, 6))


def normalised_mechanism(m: RigidModel, vel: np.ndarray) -> np.ndarray:
    """The bodies' velocities ``vel`` (b, 6) scaled so that the fastest node of a free body
    moves at 1 and the growing load does positive work."""
    if float(m.live @ vel.ravel()) < 0.0:
        vel = -vel
    speed = 0.0
    for b in np.flatnonzero(~m.support):
        X = m.meshes[b][0] if len(m.meshes[b][0]) else m.reference[b][None, :]
        v = vel[b, :3] + np.cross(vel[b, 3:], X - m.reference[b])
        speed = max(speed, float(np.linalg.norm(v, axis=1).max()))
    return vel / speed if speed > 0.0 else vel


#: The weight of the normal forces' sum in a step of the non-associative iteration (forces in
#: units of ``W``, the multiplier of order 1): among the force sets that carry the same load it
#: takes the one with the least normal force. Without it the interior point leaves a face that
#: carries nothing about 1e-5 W of normal force (its barrier's slack), which the next step's
#: capacity lets carry friction: the multiplier crept up by about 0.05 % a step.
NORMAL_PENALTY = 1e-4
#: The non-associative iteration: the first and the largest weight of its proximal term (in
#: the programme's units: forces in ``W``, the multiplier of order 1), the steps over which
#: its multiplier must stay within ``rtol`` to have converged, and that tolerance.
PROXIMAL = 0.002
PROXIMAL_MAX = 0.05
STEADY_STEPS = 5
NON_ASSOCIATIVE_RTOL = 5e-3
#: The normal forces the iteration starts from (:func:`solve_non_associative`), the default
#: first: ``elastic``, the joints' springs under the dead loads with Coulomb friction
#: (:func:`elastic_state`); ``associative``, the associative solution at collapse; ``run``, the
#: normal forces of an NSCD run of the same scene at one of its output steps (given).
STARTS = ("elastic", "associative", "run")
#: The elastic state's successive friction bounds: at most this many, until the normal forces
#: change by less than ``ELASTIC_RTOL`` of the largest between two.
ELASTIC_STEPS = 20
ELASTIC_RTOL = 1e-4


def _energy_weights(m: RigidModel) -> np.ndarray:
    """The diagonal (3 p) of the complementary energy ``(1/2) sum (c_n N^2 + c_t (T^2 +
    S^2)) / A`` of the joints' springs, scaled to a mean normal weight of 1; a joint without
    springs (zero compliance, a ``coulomb`` joint) counts as a spring as stiff as the others'
    (as stiff in shear as in compression if none has one)."""
    cn, ct = spring_compliances(m)
    area = np.maximum(m.area, 1e-300)
    wn, wt = cn / area, ct / area
    unit = float(wn.mean())
    return np.stack([wn, wt, wt], axis=1).ravel() / unit


def _elastic_step(m: RigidModel, nbar: np.ndarray | None, tension: bool,
                  compressive_Pa: float | None) -> tuple[str, str, np.ndarray | None]:
    """One state of least complementary energy under the dead loads: friction bounded by
    ``c A + mu nbar`` (Tresca's), or by ``c A + mu N`` (Coulomb's cone, ``nbar`` None)."""
    prog = _programme(m, 0, tension, False, nbar, compressive_Pa=compressive_Pa)
    prog.P_diag = _energy_weights(m)
    prog.c = np.zeros(len(prog.c))
    status, message, x, _ = _solve_clarabel(prog)
    return status, message, None if x is None else x.reshape(-1, 3) * prog.W


#: A capacity update that leaves no admissible forces is halved this many times at most (the
#: update under-relaxed, :func:`_relaxed`) before the iteration stops.
HALVINGS = 4


def _relaxed(solve, nbar: np.ndarray, target: np.ndarray):
    """``solve(c)`` at the capacity ``c = nbar + t (target - nbar)``, ``t = 1, 1/2, ...``
    (:data:`HALVINGS` halvings): the first with a solution, ``(solution, c, t)``, or
    ``(None, c, t)`` with the last ``c`` tried. The capacity ``nbar`` admitted forces, the
    new one need not: the fixed point is the same, the update only shorter."""
    t = 1.0
    for _ in range(HALVINGS + 1):
        c = nbar + t * (target - nbar)
        out = solve(c)
        if out is not None:
            return out, c, t
        t *= 0.5
    return None, c, 2.0 * t


def elastic_state(m: RigidModel, *, tension: bool = False,
                  compressive_Pa: float | None = None, steps: int = ELASTIC_STEPS,
                  rtol: float = ELASTIC_RTOL
                  ) -> tuple[np.ndarray | None, np.ndarray | None, dict]:
    r"""The joint forces (p, 3) (N) that the dead loads alone give when the joints are the
    stiff springs of their law (normal compliance ``c_n``, tangential ``c_t``, m/Pa), the
    blocks rigid, no tension, and Coulomb friction that does not dilate: the state a structure
    loaded from rest is in before its growing load starts (the NSCD run's after gravity).

    With the friction bound fixed, the forces of elastic joints minimise the complementary
    energy ``(1/2) sum_p (c_n N_p^2 + c_t (T_p^2 + S_p^2)) / A_p`` over the forces that
    equilibrate the loads with ``N >= 0`` and ``|(T, S)| <= mu Nbar`` (Tresca's friction, a
    given bound: the principle of least complementary energy extended to unilateral contact
    with given friction). Coulomb's bound ``mu N`` depends on the unknown normal force, and
    the state is found by successive Tresca problems, ``Nbar`` the normal forces of the one
    before (Panagiotopoulos, Ingenieur-Archiv 44, 1975; Kikuchi and Oden, Contact Problems in
    Elasticity, SIAM 1988: the method of successive approximations), until they change by less
    than ``rtol`` of the largest. The first bound is that of the least-energy forces within
    Coulomb's cone itself (admissible whenever the dead loads can be carried); a bound that
    leaves no admissible forces is moved only part of the way (:func:`_relaxed`). Each problem
    is convex, a quadratic objective with second-order cones (Clarabel, whichever solver the
    analysis uses).

    Within the cone a self-stress may lower the energy by letting faces carry friction (faces
    pressed together through the rigid blocks, the dilatancy of the normality rule); with the
    bound fixed it only costs energy and buys nothing, and the successive bounds take it out:
    faces that nothing presses carry nothing (the rings of a barrel vault side by side under
    loads in their plane). Returns the forces (None if the dead loads cannot be carried), the
    last bound ``Nbar`` (N, p; the forces are admissible with ``mu Nbar``, and with ``mu N`` too
    once converged) and the record: ``steps``, ``converged``, ``normal_change`` per step (the largest change of the
    bound over the largest force), ``relaxation`` per step (the part of the update taken) and
    ``stopped_by``."""
    record: dict = {"method": "least complementary energy of the joints' springs, "
                              "successive Tresca bounds (Panagiotopoulos 1975)",
                    "steps": 0, "converged": False, "normal_change": [], "relaxation": [],
                    "stopped_by": None}
    status, message, f = _elastic_step(m, None, tension, compressive_Pa)
    if f is None:
        record["stopped_by"] = f"the cone: {status} ({message})"
        return None, None, record
    nbar, target = f[:, 0].copy(), f[:, 0].copy()

    def solve(c):
        return _elastic_step(m, c, tension, compressive_Pa)[2]

    for i in range(1, steps + 1):
        g, c, t = _relaxed(solve, nbar, target)
        if g is None:
            record["stopped_by"] = f"step {i}: no admissible forces within {t:g} of the update"
            break
        change = float(np.abs(c - nbar).max() / max(float(np.abs(g[:, 0]).max()), 1e-300))
        record["steps"] = i
        record["normal_change"].append(change)
        record["relaxation"].append(t)
        f, nbar, target = g, c, g[:, 0].copy()
        if i > 1 and change <= rtol:
            record["converged"] = True
            break
    return f, nbar, record


def solve_non_associative(m: RigidModel, facets: int = friction.DEFAULT_FACETS, *,
                          tension: bool = False, proximal: float = PROXIMAL,
                          rtol: float = NON_ASSOCIATIVE_RTOL, max_iterations: int = 60,
                          solver: str = SOLVERS[0], compressive_Pa: float | None = None,
                          start: str = STARTS[0], start_normal: np.ndarray | None = None
                          ) -> tuple[LimitSolution, dict]:
    r"""The multiplier with Coulomb friction that does not dilate, by the iteration of fixed
    friction capacities (Gilbert, Casapulla and Ahmed, Computers & Structures 84, 2006) made
    proximal: from the normal forces ``N^0`` of the start, step ``i`` solves the
    programme with the friction of each point bounded by the fixed capacity ``mu Nbar_i`` (a
    capacity that does not depend on the unknown ``N``: the flow rule has no dilatancy) and,
    among the force sets that carry nearly the most, takes the one nearest ``Nbar_i``: it
    maximises ``lambda - (proximal / 2) sum ((N - Nbar_i) / W)^2 - p sum N / W`` (``p``,
    :data:`NORMAL_PENALTY`, a tie-break that leaves no normal force where none is needed, the
    interior point's slack); then ``Nbar_{i+1} = N_i``. The weight starts at ``proximal`` and doubles (up to :data:`PROXIMAL_MAX`) at each step
    where the multiplier turns back (it rose after falling, or fell after rising): a
    monotone approach keeps its pace, an oscillation is damped.

    ``start`` (:data:`STARTS`): ``elastic`` (the default) takes ``N^0`` from the state of the
    joints' springs under the dead loads (:func:`elastic_state`), the state the structure is in
    when its load starts to grow; ``associative`` from the associative solution at collapse,
    Gilbert, Casapulla and Ahmed's start; ``run`` from ``start_normal`` (N, per point), the
    normal forces of an NSCD run of the same scene (the state the run was in, its settling
    included). Non-associative collapse loads are not unique, and
    the iteration ends at the one its start leads to: the associative start carries the
    self-stress of the associative solution (rings of a vault pressed together and held by
    friction, which the static method may use and the structure loaded from rest never builds)
    into the first capacities, and the steps drain it only gradually (the barrel vault at
    mu = 2: 0.1471 after 17 steps, against its weakest ring's 0.145918 from the elastic state
    at the first; docs/limit.md).

    A fixed point (``N = Nbar``) is a state of the non-associative model: its forces are
    admissible with the friction their own normal forces give, and the proximal term, zero
    there, leaves the multiplier that of the programme. The term keeps a statically
    indeterminate assembly (the dome, the vault), whose normal forces are not unique, from
    jumping from one force set to another between steps, the cause of the plain iteration's
    wandering. The iteration has converged when the multiplier stays within ``rtol`` over
    :data:`STEADY_STEPS` steps; the normal forces of an indeterminate assembly may still move
    (``normal_change``, the largest change over the largest force, per step). A step whose
    capacities admit no forces (they need not: the forces of the step before were bounded by
    the capacities before) takes only part of the update (:func:`_relaxed`; ``relaxation``
    in the record), and the iteration stops at the step before only if no part admits forces.
    The mechanism comes from the last capacities solved once more without the penalty (its
    dual would open every compressed point by it; ``final`` in the record, its multiplier).
    Returns that solution (the failed first step's, without a multiplier, if there is none)
    and the record:
    ``start`` (with the elastic state's own record), ``converged``, ``iterations``,
    ``multipliers`` and ``normal_change`` (one per step), ``associative`` (the associative
    multiplier, None where that programme has no optimum), ``band`` (the least and largest
    multiplier of the last :data:`STEADY_STEPS` steps)."""
    if start not in STARTS:
        raise ValueError(f"start: one of {', '.join(STARTS)}, got {start!r}")
    if (start == "run") != (start_normal is not None) or \
            (start_normal is not None and len(start_normal) != m.points):
        raise ValueError(f"start run takes the normal forces of the {m.points} points "
                         "(start_normal), and only it")
    first = solve_limit(m, facets, tension=tension, solver=solver,
                        compressive_Pa=compressive_Pa)
    record = {"method": "fixed friction capacities, proximal", "start": start,
              "associative": first.multiplier, "multipliers": [], "normal_change": [],
              "converged": False, "iterations": 0, "proximal": proximal, "rtol": rtol,
              "steady_steps": STEADY_STEPS, "band": None, "stopped_by": None}
    solve_s = first.times_s["solve"]
    if start == "elastic":
        t0 = time.perf_counter()
        state, bound, record["elastic_state"] = elastic_state(m, tension=tension,
                                                              compressive_Pa=compressive_Pa)
        solve_s += time.perf_counter() - t0
        if state is None or m.factor is None:
            return first, record
        # the bound its forces are admissible with; its own normal forces the first target
        nbar, target = bound.copy(), state[:, 0].copy()
    elif start == "run":
        nbar = np.maximum(np.asarray(start_normal, float), 0.0)
        target = nbar
    else:
        if first.status != "optimal" or first.multiplier is None:
            return first, record
        nbar = first.forces[:, 0].copy()
        target = nbar
    last = first
    weight = proximal
    record["weights"], record["relaxation"] = [], []
    for i in range(1, max_iterations + 1):
        lams = record["multipliers"]
        if len(lams) >= 3 and (lams[-1] - lams[-2]) * (lams[-2] - lams[-3]) < 0.0:
            weight = min(2.0 * weight, max(PROXIMAL_MAX, proximal))
        record["weights"].append(weight)
        tried = []

        def solve(c, weight=weight, tried=tried):
            sol = solve_limit(m, facets, tension=tension, normal_limit=c, solver=solver,
                              proximal=weight, compressive_Pa=compressive_Pa,
                              normal_penalty=NORMAL_PENALTY)
            tried.append(sol)
            ok = sol.status == "optimal" and sol.multiplier is not None
            return sol if ok else None

        sol, c, t = _relaxed(solve, nbar, target)
        if sol is None and i == 1:  # the elastic state's bound itself admits its forces
            sol, c, t = solve(nbar), nbar, 0.0
        solve_s += sum(s.times_s["solve"] for s in tried)
        record["iterations"] = i
        if sol is None:
            record["stopped_by"] = f"step {i}: {tried[-1].status} within {t:g} of the update"
            if i == 1:  # no non-associative state at all: not the associative solution
                last = tried[-1]
            break
        record["relaxation"].append(t)
        nbar = c
        N = sol.forces[:, 0]
        record["multipliers"].append(sol.multiplier)
        record["normal_change"].append(
            float(np.abs(N - nbar).max() / max(float(np.abs(N).max()), 1e-300)))
        last = sol
        recent = record["multipliers"][-STEADY_STEPS:]
        record["band"] = [min(recent), max(recent)]
        if len(recent) == STEADY_STEPS and \
                max(recent) - min(recent) <= rtol * max(abs(sol.multiplier), 1e-12):
            record["converged"] = True
            break
        target = N.copy()
    if record["multipliers"]:
        # the last capacities once more without the penalty, whose dual would open every
        # compressed point by it: the mechanism of the fixed capacities
        final = solve_limit(m, facets, tension=tension, normal_limit=nbar, solver=solver,
                            proximal=weight, compressive_Pa=compressive_Pa)
        solve_s += final.times_s["solve"]
        if final.status == "optimal" and final.multiplier is not None:
            last = final
        record["final"] = final.multiplier
    last.times_s = {**last.times_s, "solve": solve_s}
    return last, record
