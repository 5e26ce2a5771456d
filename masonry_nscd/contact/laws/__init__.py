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
* ``normal_displacement(sigma, beta, P)``: the normal displacement that carries a normal
  traction (``masonry point joint --path sliding``).

Adding a law: its module here, its section in ``case.Joint``, and a line in ``_MODULES`` and in
the two dispatch functions below. The Newton and Gauss-Seidel kernels call only ``solve`` and
``tangent`` of this module; glued points are solved here (``common.glue_solve``).
"""

from __future__ import annotations

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
           "normal_displacement", "params_from_case", "solve", "tangent"]

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


def normal_displacement(sigma: float, beta: float, P: np.ndarray) -> float:
    """Normal displacement (m) carrying the normal traction ``sigma`` (Pa) at integrity
    ``beta``, for the law of row ``P``."""
    return law_module(P).normal_displacement(sigma, beta, P)


@njit(cache=True, inline="always")
def solve(ut, A, uc_old, beta_old, P, kind, T, uc):
    """The local problem of one contact point (module docstring): glue, or the law of ``P``.
    Returns ``(status, beta)``."""
    if kind == KIND_GLUED:
        return glue_solve(ut, A, T, uc), beta_old
    code = int(P[P_LAW])
    if code == fczm.CODE:
        return fczm.solve(ut, A, uc_old, beta_old, P, T, uc)
    T[:] = np.nan  # an unknown law code: the step fails loudly (non-finite tractions)
    return ST_AMBIGUOUS, beta_old


@njit(cache=True, inline="always")
def tangent(u, T, uc_old, beta, status, P, K):
    """``K = dT/du`` (3x3, Pa/m) of the law of ``P`` at a solution, integrity frozen."""
    code = int(P[P_LAW])
    if code == fczm.CODE:
        fczm.tangent(u, T, uc_old, beta, status, P, K)
        return
    K[:, :] = np.nan
