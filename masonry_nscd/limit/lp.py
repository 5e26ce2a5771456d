r"""The static theorem of limit analysis for rigid blocks as a linear programme, and its dual,
the collapse mechanism.

Unknowns: the force ``(N, T, S)`` (N) of every interface point (:mod:`.statics`) and the load
multiplier ``lambda`` (the unit of the growing load factor). The programme

    maximise lambda   subject to   B f + lambda F_live = -F_dead     (free dofs, 6 per body)
                                   N >= -f_t A                      (f_t = 0: no tension)
                                   pyramid rows of the friction     (:mod:`.friction`)

is solved by HiGHS (``scipy.optimize.linprog``, :data:`METHOD`). Glued points carry any force.
Its optimum is the largest multiplier that admissible forces equilibrate: the collapse
multiplier of the associative (normality) model, in which a sliding joint also dilates by
``mu`` times its slip. With the frictional capacity exact (a joint that does not slide) it is
the collapse multiplier itself; where sliding takes part, the associative multiplier is an
upper bound of the one with non-associative Coulomb friction (no dilatancy).

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
from scipy.optimize import linprog

from masonry_nscd.limit import friction
from masonry_nscd.limit.statics import RigidModel, equilibrium_matrix, point_velocities

#: HiGHS's method: its interior point with crossover (a vertex, whose duals are the
#: mechanism); its dual simplex is slower on the larger scenes (docs/choices.md).
METHOD = "highs-ipm"
#: ``linprog``'s status codes, by name.
LP_STATUS = {0: "optimal", 1: "iteration limit", 2: "infeasible", 3: "unbounded",
             4: "numerical difficulties"}


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


def solve_limit(m: RigidModel, facets: int = friction.DEFAULT_FACETS, *, tension: bool = False,
                dead_only: bool = False, normal_limit: np.ndarray | None = None
                ) -> LimitSolution:
    """The programme of the module docstring for the rigid model ``m``; ``tension``: the
    joints' tensile strength and cohesion (:mod:`.statics`) count; ``dead_only`` (or a model
    with no growing load): whether the dead loads alone can be carried (no multiplier);
    ``normal_limit`` (p,) N: friction of fixed capacity ``mu normal_limit`` instead of
    ``mu N`` (a step of :func:`solve_non_associative`)."""
    t0 = time.perf_counter()
    npt = m.points
    W, L = _scales(m)
    with_lambda = not dead_only and m.factor is not None
    # equilibrium rows of the free dofs, scaled
    row_scale = np.tile([W, W, W, W * L, W * L, W * L], m.bodies)[m.free]
    B = equilibrium_matrix(m)[m.free]
    A_eq = sp.diags(1.0 / row_scale) @ B * W  # the forces in units of W
    b_eq = -m.dead[m.free] / row_scale
    live = m.live[m.free] / row_scale
    lam_scale = 1.0
    if with_lambda:
        lam_scale = 1.0 / max(float(np.abs(live).max()), 1e-300)
        A_eq = sp.hstack([A_eq, sp.csr_matrix(live[:, None] * lam_scale)]).tocsr()
    nvar = 3 * npt + int(with_lambda)
    # friction pyramid rows
    joint = np.flatnonzero(~m.glued)
    normals = friction.facet_normals(facets)
    k = len(normals)
    cosk = friction.inscribed_fraction(facets)
    rows = np.repeat(np.arange(len(joint) * k), 3)
    pcol = np.repeat(3 * joint, k)
    cols = np.stack([pcol, pcol + 1, pcol + 2], axis=1).ravel()
    mu = np.repeat(m.mu[joint], k) * (normal_limit is None)
    vals = np.stack([-mu * cosk, np.tile(normals[:, 0], len(joint)),
                     np.tile(normals[:, 1], len(joint))], axis=1).ravel()
    A_ub = sp.csr_matrix((vals, (rows, cols)), shape=(len(joint) * k, nvar))
    cohesion = m.cohesion_Pa if tension else np.zeros(npt)
    capacity = cohesion * m.area
    if normal_limit is not None:
        capacity = capacity + m.mu * np.maximum(normal_limit, 0.0)
    b_ub = np.repeat(capacity[joint] * cosk / W, k)
    lower = np.full((npt, 3), -np.inf)
    lower[joint, 0] = -(m.tensile_Pa[joint] * m.area[joint] / W if tension else 0.0)
    bounds = np.column_stack([lower.ravel(), np.full(3 * npt, np.inf)])
    c = np.zeros(nvar)
    if with_lambda:
        bounds = np.vstack([bounds, [-np.inf, np.inf]])
        c[-1] = -1.0
    t1 = time.perf_counter()
    res = linprog(c, A_ub=A_ub if A_ub.shape[0] else None, b_ub=b_ub if A_ub.shape[0] else None,
                  A_eq=A_eq, b_eq=b_eq, bounds=bounds, method=METHOD)
    t2 = time.perf_counter()
    status = LP_STATUS.get(res.status, f"status {res.status}")
    forces = np.zeros((npt, 3))
    velocity = np.zeros((m.bodies, 6))
    multiplier = None
    if res.status == 0:
        forces = res.x[:3 * npt].reshape(npt, 3) * W
        if with_lambda:
            multiplier = float(res.x[-1] * lam_scale)
            velocity = _mechanism(m, res.eqlin.marginals, row_scale)
    counts = {"bodies": m.bodies, "free_bodies": int((~m.support).sum()), "points": npt,
              "glued_points": int(m.glued.sum()), "variables": nvar,
              "equations": int(A_eq.shape[0]), "inequalities": int(A_ub.shape[0]),
              "facets": facets}
    return LimitSolution(status, str(res.message), multiplier, forces, velocity,
                         point_velocities(m, velocity), counts,
                         {"assemble": t1 - t0, "solve": t2 - t1})


def _mechanism(m: RigidModel, marginals: np.ndarray, row_scale: np.ndarray) -> np.ndarray:
    """The bodies' velocities (b, 6) from the multipliers of the scaled equilibrium rows
    (module docstring)."""
    y = np.zeros(6 * m.bodies)
    y[m.free] = np.asarray(marginals) / row_scale
    vel = y.reshape(-1, 6)
    if float(m.live @ vel.ravel()) < 0.0:
        vel = -vel
    speed = 0.0
    for b in np.flatnonzero(~m.support):
        X = m.meshes[b][0] if len(m.meshes[b][0]) else m.reference[b][None, :]
        v = vel[b, :3] + np.cross(vel[b, 3:], X - m.reference[b])
        speed = max(speed, float(np.linalg.norm(v, axis=1).max()))
    return vel / speed if speed > 0.0 else vel



#: The non-associative iteration has converged when its multiplier stays within ``rtol`` over
#: this many steps.
STEADY_STEPS = 3


def solve_non_associative(m: RigidModel, facets: int = friction.DEFAULT_FACETS, *,
                          tension: bool = False, relaxation: float = 0.5,
                          rtol: float = 1e-4, max_iterations: int = 60
                          ) -> tuple[LimitSolution, dict]:
    r"""The multiplier with Coulomb friction that does not dilate, by the iteration of fixed
    friction capacities (Gilbert, Casapulla and Ahmed, Computers & Structures 84, 2006):
    from the associative solution's normal forces ``N^0``, each step solves the programme with
    the friction of each point bounded by ``mu Nbar_i`` (a capacity that does not depend on
    the unknown ``N``, so the flow rule has no dilatancy), then updates
    ``Nbar_{i+1} = Nbar_i + relaxation (N_i - Nbar_i)``, until the multiplier and the normal
    the multiplier stays within ``rtol`` over :data:`STEADY_STEPS` steps (the normal forces of
    a statically indeterminate assembly need not settle: many sets carry the same load). A step
    whose programme has no solution (the fixed capacities too small for the dead loads) ends
    the iteration at the step before. Returns the last optimal solution and the iteration's record: ``converged``, ``iterations``,
    ``multipliers`` (one per step), ``associative`` (the first multiplier)."""
    first = solve_limit(m, facets, tension=tension)
    record = {"associative": first.multiplier, "multipliers": [], "converged": False,
              "iterations": 0, "relaxation": relaxation, "rtol": rtol, "stopped_by": None}
    if first.status != "optimal" or first.multiplier is None:
        return first, record
    nbar = first.forces[:, 0].copy()
    last = first
    solve_s = first.times_s["solve"]
    for i in range(1, max_iterations + 1):
        sol = solve_limit(m, facets, tension=tension, normal_limit=nbar)
        solve_s += sol.times_s["solve"]
        record["iterations"] = i
        if sol.status != "optimal" or sol.multiplier is None:
            record["stopped_by"] = f"step {i}: {sol.status}"
            break
        record["multipliers"].append(sol.multiplier)
        last = sol
        recent = record["multipliers"][-STEADY_STEPS:]
        if len(recent) == STEADY_STEPS and \
                max(recent) - min(recent) <= rtol * max(abs(sol.multiplier), 1e-12):
            record["converged"] = True
            break
        nbar = nbar + relaxation * (sol.forces[:, 0] - nbar)
    last.times_s = {**last.times_s, "solve": solve_s}
    return last, record
