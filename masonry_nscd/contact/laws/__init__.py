"""Joint laws: the registry from a case's ``joint.law`` to a law module, and the dispatch that the
solvers call.

A law module provides, besides its own documentation and checks:

* ``NAMES``: the ``joint.law`` values it serves; ``CODE``: its code in column ``P_LAW``;
* ``params_from_case(joint)``: its parameter row (``N_COLUMNS`` floats, code included);
* ``solve(ut, A, uc_old, beta_old, P, T, uc) -> (status, beta)`` (numba): the local problem of
  one step, ``u_{n+1} = u~ - A T`` with the integrity ``beta`` consistent with the end of the
  step; ``T`` (Pa) and the cohesive displacement ``uc`` (m) written in place;
* ``tangent(u, T, uc_old, beta, status, P, K)`` (numba): ``K = dT/du`` (Pa/m) at a solution,
  integrity frozen, for the Newton matrix;
* ``initial_damage(P)``: the damage of the joint as built (outputs: ``1 - beta (1 - d_0)``);
* ``newton_ready(P)``: whether the Newton solver can take it;
* ``rigid_friction(P)``: the friction coefficient when the law is rigid Signorini-Coulomb (the
  Newton solver then keeps the point's impulse as an unknown), else None;
* ``normal_displacement(sigma, beta, P)``: the normal displacement that carries a normal
  traction (``masonry point joint --path sliding``).

Adding a law: its module here, its fields in ``case/joint.py``, and a line in ``_MODULES`` and a
branch in the three dispatches below (``solve_joint``, ``solve_points``, ``tangent_points``).
The Gauss-Seidel kernel calls ``solve`` of this module, the Newton solver ``solve_points`` for
the residual and ``tangent_points`` for the matrix; glued points are solved here
(``common.glue_solve``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from masonry_nscd.contact.laws import fczm
from masonry_nscd.contact.laws.common import (
    KIND_GLUED,
    KIND_JOINT,
    N_COLUMNS,
    P_LAW,
    ST_AMBIGUOUS,
    ST_GLUED,
    ST_OPEN,
    ST_SLIDE,
    ST_STICK,
    glue_solve,
)

__all__ = ["KIND_GLUED", "KIND_JOINT", "LAWS", "N_COLUMNS", "P_LAW", "ST_AMBIGUOUS", "ST_GLUED",
           "ST_OPEN", "ST_SLIDE", "ST_STICK", "initial_damage", "law_module", "newton_ready",
           "normal_displacement", "params_from_case", "rigid_friction", "solve", "solve_joint",
           "solve_points", "tangent_fd", "tangent_points"]

_MODULES = (fczm,)
#: joint.law value -> law module
LAWS = {name: m for m in _MODULES for name in m.NAMES}
_BY_CODE = {m.CODE: m for m in _MODULES}


def law_module(P: np.ndarray):
    """The module of the law of parameter row ``P``."""
    return _BY_CODE[int(P[P_LAW])]


def params_from_case(joint) -> np.ndarray:
    """The parameter row of a case's ``joint`` section."""
    return LAWS[joint.law].params_from_case(joint)


def initial_damage(P: np.ndarray) -> float:
    """Damage of a joint of parameter row ``P`` as built (dimensionless)."""
    return law_module(P).initial_damage(P)


def newton_ready(P: np.ndarray) -> bool:
    """Whether the Newton solver can take the law of row ``P``."""
    return law_module(P).newton_ready(P)


def rigid_friction(P: np.ndarray) -> float | None:
    """The friction coefficient of a rigid Signorini-Coulomb law of row ``P``, else None."""
    return law_module(P).rigid_friction(P)


def normal_displacement(sigma: float, beta: float, P: np.ndarray) -> float:
    """Normal displacement (m) carrying the normal traction ``sigma`` (Pa) at integrity
    ``beta``, for the law of row ``P``."""
    return law_module(P).normal_displacement(sigma, beta, P)


@njit(cache=True)
def solve_joint(ut, A, uc_old, beta_old, P, T, uc):
    """The local problem of a joint point with the law of ``P`` (module docstring). Returns
    ``(status, beta)``; an unknown law gives a non-finite integrity (the step fails loudly)."""
    if P[P_LAW] == fczm.CODE:
        return fczm.solve(ut, A, uc_old, beta_old, P, T, uc)
    return ST_AMBIGUOUS, math.nan


@njit(cache=True)
def solve(ut, A, uc_old, beta_old, P, kind, T, uc):
    """The local problem of one contact point: the glue, or the law of ``P``. Returns
    ``(status, beta)``."""
    if kind == KIND_GLUED:
        return glue_solve(ut, A, T, uc), beta_old
    return solve_joint(ut, A, uc_old, beta_old, P, T, uc)


@njit(cache=True)
def tangent_fd(u, T, uc_old, beta_old, P, K):
    """Consistent tangent ``K = dT/du`` (3x3, Pa/m) of the law with the integrity implicit in
    the step (its ``solve``), by forward differences.

    Used where the integrity drops within the step: ``T(u) = T(u; beta(u))`` with
    ``beta = beta_env(u_c(u, beta))``. Steps ``delta = 1e-7 max(|u|, 1e-9 m)``; the regula
    falsi solves beta to 1e-14, so the difference quotient carries about 1e-7 of noise.
    """
    A = np.zeros((3, 3))
    up = np.empty(3)
    tp = np.empty(3)
    cp = np.empty(3)
    delta = 1e-7 * max(math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), 1e-9)
    for j in range(3):
        for i in range(3):
            up[i] = u[i]
        up[j] += delta
        solve_joint(up, A, uc_old, beta_old, P, tp, cp)
        for i in range(3):
            K[i, j] = (tp[i] - T[i]) / delta


@njit(cache=True, nogil=True)
def solve_points(u0, du, scale, skip, law, params, uc_old, beta_old, T, uc, beta, status):
    """The local problems of the points ``a`` with ``skip[a] < 0``, each driven by its total
    relative displacement ``u = u0[a] + scale du[a]`` (m; ``A = 0``), for the Newton residual:
    tractions ``T`` (Pa), cohesive displacements ``uc`` (m), integrities and statuses, as
    :func:`solve_joint` gives them. One loop with the dispatch written in it: the same dispatch
    as a function called per point, even inlined, is slower (``docs/performance.md``)."""
    A = np.zeros((3, 3))
    u = np.empty(3)
    t = np.empty(3)
    c = np.empty(3)
    co = np.empty(3)
    for a in range(u0.shape[0]):
        if skip[a] >= 0:
            continue
        P = params[law[a]]
        for i in range(3):
            u[i] = u0[a, i] + scale * du[a, i]
            co[i] = uc_old[a, i]
        if P[P_LAW] == fczm.CODE:
            st, bn = fczm.solve(u, A, co, beta_old[a], P, t, c)
        else:
            st, bn = ST_AMBIGUOUS, math.nan
        for i in range(3):
            T[a, i] = t[i]
            uc[a, i] = c[i]
        beta[a] = bn
        status[a] = st


@njit(cache=True, nogil=True)
def tangent_points(u0, du, scale, skip, law, params, uc_old, beta_old, T, beta, status, K):
    """Consistent tangents ``K[a] = dT/du`` (Pa/m) of the points of :func:`solve_points` at
    the solutions ``(T, beta, status)`` it gave for the same ``u``, for the Newton matrix: the
    law's own ``tangent`` with the integrity frozen where it did not drop within the step,
    differences of the implicit law (:func:`tangent_fd`) where it did (the frozen one misses
    the softening, by 100 % and in sign on opening joints). Apart from the solve: the residual
    is evaluated far more often than the matrix is made, and at a softening point the
    differences cost three more solves. The rows of the skipped points, and of a point of an
    unknown law, are left as they are."""
    u = np.empty(3)
    for a in range(u0.shape[0]):
        if skip[a] >= 0:
            continue
        P = params[law[a]]
        for i in range(3):
            u[i] = u0[a, i] + scale * du[a, i]
        if P[P_LAW] == fczm.CODE:
            if beta[a] >= beta_old[a]:
                fczm.tangent(u, T[a], uc_old[a], beta[a], status[a], P, K[a])
            else:
                tangent_fd(u, T[a], uc_old[a], beta_old[a], P, K[a])
