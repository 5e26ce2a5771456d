"""The linear algebra of the Newton solver, against independent calculations.

* ``_Pattern``: the Newton matrix filled into the fixed pattern equals the one assembled from
  the triplets by scipy, and the LU of the matrix permuted once (the order of the first
  factorisation, natural order afterwards) solves the system of a later, different matrix.
* ``NewtonSolver._anderson``: on a linear residual with a stale matrix, the accelerated chord
  iteration is GMRES preconditioned by the stale matrix, so with a depth at least the
  dimension it converges in at most dimension + 1 steps, where the plain chord iteration
  converges only at the rate of the spectral radius of I - J0^-1 A.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from masonry_nscd.nscd.newton import NewtonSolver, _Pattern


def _triplets(rng, n, k):
    """Random triplets with repeated entries, a symmetric pattern and a heavy diagonal."""
    r = rng.integers(0, n, k)
    c = rng.integers(0, n, k)
    rows = np.concatenate([r, c, np.arange(n)])
    cols = np.concatenate([c, r, np.arange(n)])
    return rows.astype(np.int64), cols.astype(np.int64)


def _values(rng, n, k):
    return np.concatenate([rng.normal(size=2 * k), 10.0 + rng.random(n) * n])


def test_pattern_fills_the_same_matrix_as_scipy_and_its_lu_solves_later_matrices():
    rng = np.random.default_rng(1)
    n, k = 60, 400
    rows, cols = _triplets(rng, n, k)
    pat = _Pattern(rows, cols, n)
    for trial in range(3):  # the first factorisation finds the order, the later ones use it
        vals = _values(rng, n, k)
        J = sp.csc_matrix((vals, (rows, cols)), shape=(n, n)).toarray()
        if trial == 0:
            assert np.array_equal(pat.matrix(pat.values(vals)).toarray(), J)
        b = rng.normal(size=n)
        for pivoting in (False, True):
            x = pat.factorise(pat.values(vals), pivoting=pivoting).solve(b)
            assert np.allclose(J @ x, b, rtol=0, atol=1e-12 * np.abs(b).max() * n)
        assert pat.order is not None


class _Linear:
    """A bare solver object carrying only what ``_anderson`` reads."""

    def __init__(self, depth):
        self.anderson = depth


def _chord(A, b, J0, depth, steps):
    """Chord iterations x <- x + step on F(x) = A x - b, steps f = -J0^-1 F, accelerated
    with ``depth``; the residual norms."""
    x = np.zeros(len(b))
    last, d_x, d_f = None, [], []
    w = np.ones(len(b))
    out = []
    solver = _Linear(depth)
    for _ in range(steps):
        F = A @ x - b
        out.append(np.linalg.norm(F))
        f = -np.linalg.solve(J0, F)
        step = f if last is None or depth == 0 else NewtonSolver._anderson(
            solver, x, f, last, d_x, d_f, w)
        last = (x.copy(), f)
        x = x + step
    return np.array(out)


def test_anderson_is_gmres_on_a_linear_residual():
    rng = np.random.default_rng(3)
    n = 6
    Q = np.linalg.qr(rng.normal(size=(n, n)))[0]
    A = Q @ np.diag(np.linspace(1.0, 3.0, n)) @ Q.T
    J0 = A + np.diag(1.0 + rng.random(n))  # a stale matrix
    b = rng.normal(size=n)
    plain = _chord(A, b, J0, 0, n + 2)
    acc = _chord(A, b, J0, n, n + 2)
    rate = np.abs(np.linalg.eigvals(np.eye(n) - np.linalg.solve(J0, A))).max()
    assert 0.3 < rate < 1.0  # the plain chord iteration converges, slowly
    assert acc[n + 1] <= 1e-10 * acc[0]  # GMRES: exact after at most n + 1 residuals
    assert plain[n + 1] >= 1e-4 * plain[0]
