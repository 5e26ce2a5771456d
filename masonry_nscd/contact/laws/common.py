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
def solve3(M: np.ndarray, r: np.ndarray, x: np.ndarray) -> bool:
    """Solve the 3x3 system ``M x = r`` by Gaussian elimination with partial pivoting."""
    a = M.copy()
    y = r.copy()
    for col in range(3):
        piv = col
        for i in range(col + 1, 3):
            if abs(a[i, col]) > abs(a[piv, col]):
                piv = i
        if a[piv, col] == 0.0:
            return False
        if piv != col:
            for j in range(3):
                t = a[col, j]
                a[col, j] = a[piv, j]
                a[piv, j] = t
            t = y[col]
            y[col] = y[piv]
            y[piv] = t
        for i in range(col + 1, 3):
            f = a[i, col] / a[col, col]
            for j in range(col, 3):
                a[i, j] -= f * a[col, j]
            y[i] -= f * y[col]
    for i in range(2, -1, -1):
        s = y[i]
        for j in range(i + 1, 3):
            s -= a[i, j] * x[j]
        x[i] = s / a[i, i]
    return True


@njit(cache=True)
def glue_solve(ut: np.ndarray, A: np.ndarray, T: np.ndarray, uc: np.ndarray) -> int:
    """The glue's local problem: ``T = A^-1 u~`` (zero when A is singular), ``u_c = 0``."""
    if not solve3(A, ut, T):
        T[:] = 0.0
    uc[:] = 0.0
    return ST_GLUED
