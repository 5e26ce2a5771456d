r"""Anderson acceleration (type II) of the Newton solver's chord steps.

With the iterates ``x_i`` and their chord steps ``f_i = -J0^-1 F(x_i)`` (one matrix ``J0``), the
accelerated step at ``x`` with the chord step ``f`` is

    gamma = argmin || W (f - dF gamma) ||_2,      step = f - (dX + dF) gamma

with ``dX``, ``dF`` the differences of consecutive iterates and steps (the last ``depth`` of
them, one column each) and ``W`` the weights of the unknowns (velocity units). For a linear
residual this is GMRES preconditioned by ``J0``: with a stale factorisation whose plain steps
shrink the residual by 0.5 per iteration (the reference wall), the iterations converge in about
half as many.

The least squares is solved by its normal equations, ``G gamma = (W dF)^T W f`` with ``G = (W
dF)^T (W dF)`` (at most ``depth`` x ``depth``), ``G`` diagonalised by Jacobi rotations and its
eigenvalues below 1e-14 of the largest left out: differences that the history repeats to 1e-7
(a direction taken twice) would otherwise let the rounding of ``G`` decide the mixture. An SVD of
the tall ``W dF`` would do the same at a higher cost (docs/choices.md).

Why a kernel: the step is made at every accelerated iteration, and in numpy (a dozen calls on
vectors of the scene's unknowns, and LAPACK's ``eigh`` of a 5 x 5 matrix) it ran cold after the
threads' kernels (docs/performance.md, session 25).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: eigenvalues of ``G`` below this fraction of the largest are left out of the least squares
RELATIVE_CUTOFF = 1e-14


@njit(cache=True)
def _jacobi_eigen(A, lam, Q):
    """Eigenvalues ``lam`` (m,) and eigenvectors ``Q`` (m, m; columns) of the symmetric ``A``
    (m, m, overwritten), by cyclic Jacobi rotations until the off-diagonal part is zero to
    round-off (each rotation zeroes one pair ``A[p, q]``; ``A = Q diag(lam) Q^T``)."""
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            Q[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        diag = 0.0
        for p in range(m):
            diag += A[p, p] * A[p, p]
            for q in range(p + 1, m):
                off += A[p, q] * A[p, q]
        if off <= 1e-36 * diag or off == 0.0:
            break
        for p in range(m - 1):
            for q in range(p + 1, m):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                # the rotation (c, s) with t = s / c the smaller root of t^2 + 2 theta t - 1 = 0
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(m):
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - s * akq
                    A[k, q] = s * akp + c * akq
                for k in range(m):
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - s * aqk
                    A[q, k] = s * apk + c * aqk
                A[p, q] = 0.0
                A[q, p] = 0.0
                for k in range(m):
                    qkp = Q[k, p]
                    qkq = Q[k, q]
                    Q[k, p] = c * qkp - s * qkq
                    Q[k, q] = s * qkp + c * qkq
    for i in range(m):
        lam[i] = A[i, i]


@njit(cache=True)
def anderson_step(x, f, last_x, last_f, w2, DX, DF, G, row, m, step):
    """The accelerated step (module docstring) into ``step`` (n,). The newest differences,
    ``x - last_x`` and ``f - last_f``, are first written into row ``row`` of ``DX`` and ``DF``
    (depth, n; the history as a ring), and row and column ``row`` of ``G`` (depth, depth, kept
    between calls: ``G[i, j] = sum_k w2_k DF[i, k] DF[j, k]``, ``w2`` the squared weights)
    made against rows ``0 .. m - 1``, every row holding a difference (in any order: the step
    does not depend on it)."""
    n = x.shape[0]
    dxr = DX[row]
    dfr = DF[row]
    for k in range(n):
        dxr[k] = x[k] - last_x[k]
        dfr[k] = f[k] - last_f[k]
    rhs = np.empty(m)
    for i in range(m):
        dfi = DF[i]
        g = 0.0
        r = 0.0
        for k in range(n):
            wd = w2[k] * dfi[k]
            g += wd * dfr[k]
            r += wd * f[k]
        G[row, i] = g
        G[i, row] = g
        rhs[i] = r
    A = G[:m, :m].copy()
    lam = np.empty(m)
    Q = np.empty((m, m))
    _jacobi_eigen(A, lam, Q)
    largest = 0.0
    for i in range(m):
        largest = max(largest, lam[i])
    gamma = np.zeros(m)
    for e in range(m):
        if not lam[e] > RELATIVE_CUTOFF * largest:
            continue
        qr = 0.0
        for i in range(m):
            qr += Q[i, e] * rhs[i]
        qr /= lam[e]
        for i in range(m):
            gamma[i] += Q[i, e] * qr
    for k in range(n):
        step[k] = f[k]
    for i in range(m):
        c = gamma[i]
        dxi = DX[i]
        dfi = DF[i]
        for k in range(n):
            step[k] -= (dxi[k] + dfi[k]) * c


class ChordHistory:
    """The acceleration's memory over the chord steps of one matrix: the last iterate and its
    chord step (``last``), the last ``depth`` differences of both (rows of ``DX``, ``DF``,
    written in turn) and their weighted products ``G`` (``anderson_step``), with ``weight`` the
    weights of the unknowns in the least squares (one per unknown)."""

    def __init__(self, weight: np.ndarray, depth: int):
        self.weight = weight
        self.w2 = np.square(weight)
        self.depth = int(depth)
        rows = max(self.depth, 1)
        self.DX = np.empty((rows, len(weight)))
        self.DF = np.empty((rows, len(weight)))
        self.G = np.zeros((rows, rows))
        self.clear()

    def clear(self) -> None:
        """Forget the steps (a new matrix, or a step that was not a full one)."""
        self.last: tuple[np.ndarray, np.ndarray] | None = None
        self.count = 0  # differences held (at most depth)
        self.row = 0  # the row the next difference goes to

    def advance(self, x: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, bool]:
        """The step from the iterate ``x`` whose chord step is ``f``, and whether it was
        accelerated: ``f`` itself at the first iterate of a matrix (or with ``depth`` 0), else
        the accelerated step, the history then holding the differences from the last iterate.
        ``x``, ``f`` become the last (kept by reference: neither may change afterwards)."""
        accelerated = self.last is not None and self.depth > 0
        if accelerated:
            step = np.empty_like(f)
            self.count = min(self.count + 1, self.depth)
            anderson_step(x, f, self.last[0], self.last[1], self.w2, self.DX, self.DF, self.G,
                          self.row, self.count, step)
            self.row = (self.row + 1) % self.depth
        else:
            step = f
        self.last = (x, f)
        return step, accelerated
