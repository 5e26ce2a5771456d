"""What every joint law shares: the kinds and statuses of contact points, the layout of the
parameter table, the glue, and a 3x3 solve.

The parameter table has one row per law used in a scene (``N_COLUMNS`` floats); a law packs its
own parameters into the first columns of its row and its code into column ``P_LAW``, which is
how the kernels pick the law of a point (``contact.laws.solve``).

Glued points (blocks glued to the steel beams) are bilateral: the relative displacement at the
end of the step is zero, ``u_{n+1} = u~ - A T = 0``, so ``T = A^-1 u~`` (Pa).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# --- kinds of contact point ------------------------------------------------------------------
KIND_JOINT = 0  # a joint law (the row ``law`` of the parameter table)
KIND_GLUED = 1  # bilateral glue: relative displacement held at zero

# --- status codes ------------------------------------------------------------------------------
ST_OPEN = 0
ST_STICK = 1
ST_SLIDE = 2
ST_GLUED = 3
ST_AMBIGUOUS = 4  # no status satisfied every condition (reported, should not persist)

# --- the parameter table -----------------------------------------------------------------------
N_COLUMNS = 16  # floats per row
P_LAW = N_COLUMNS - 1  # the law's code (contact.laws.CODES)


@njit(cache=True)
def solve3_values(a00: float, a01: float, a02: float, a10: float, a11: float, a12: float,
                  a20: float, a21: float, a22: float, y0: float, y1: float, y2: float):
    """Solve the 3x3 system ``a x = y`` given by its entries, by Gaussian elimination with
    partial pivoting. Returns ``(solved, x0, x1, x2)``; not solved (zeros) when a pivot is
    zero. On scalars, so that no array is allocated: the local problem of a joint point solves
    several of these per evaluation, and their two copies per solve were a measurable part of
    the joint law's time (``docs/performance.md``)."""
    # column 0: the pivot row is the first of the largest |a_i0|, swapped into row 0
    piv = 0
    if abs(a10) > abs(a00):
        piv = 1
    if abs(a20) > abs(a10 if piv == 1 else a00):
        piv = 2
    if (a00, a10, a20)[piv] == 0.0:
        return False, 0.0, 0.0, 0.0
    if piv == 1:
        a00, a01, a02, y0, a10, a11, a12, y1 = a10, a11, a12, y1, a00, a01, a02, y0
    elif piv == 2:
        a00, a01, a02, y0, a20, a21, a22, y2 = a20, a21, a22, y2, a00, a01, a02, y0
    f = a10 / a00
    a11 -= f * a01
    a12 -= f * a02
    y1 -= f * y0
    f = a20 / a00
    a21 -= f * a01
    a22 -= f * a02
    y2 -= f * y0
    # column 1
    if abs(a21) > abs(a11):
        a11, a12, y1, a21, a22, y2 = a21, a22, y2, a11, a12, y1
    if a11 == 0.0:
        return False, 0.0, 0.0, 0.0
    f = a21 / a11
    a22 -= f * a12
    y2 -= f * y1
    if a22 == 0.0:
        return False, 0.0, 0.0, 0.0
    x2 = y2 / a22
    x1 = (y1 - a12 * x2) / a11
    x0 = (y0 - a01 * x1 - a02 * x2) / a00
    return True, x0, x1, x2


@njit(cache=True)
def solve3(M: np.ndarray, r: np.ndarray, x: np.ndarray) -> bool:
    """Solve the 3x3 system ``M x = r`` by Gaussian elimination with partial pivoting
    (:func:`solve3_values`); ``x`` is written only when solved."""
    ok, x0, x1, x2 = solve3_values(M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2],
                                   M[2, 0], M[2, 1], M[2, 2], r[0], r[1], r[2])
    if ok:
        x[0] = x0
        x[1] = x1
        x[2] = x2
    return ok


@njit(cache=True)
def glue_solve(ut: np.ndarray, A: np.ndarray, T: np.ndarray, uc: np.ndarray) -> int:
    """The glue's local problem: ``T = A^-1 u~`` (zero when A is singular), ``u_c = 0``."""
    if not solve3(A, ut, T):
        T[:] = 0.0
    uc[:] = 0.0
    return ST_GLUED
