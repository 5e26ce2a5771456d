"""The linear algebra of the Newton solver, against independent calculations.

* ``_Pattern``: the Newton matrix filled into the fixed pattern equals the one assembled from
  the triplets by scipy, and the LU of the matrix permuted once (the order of the first
  factorisation, natural order afterwards) solves the system of a later, different matrix.
* ``anderson.ChordHistory``: on a linear residual with a stale matrix, the accelerated chord
  iteration is GMRES preconditioned by the stale matrix, so with a depth at least the
  dimension it converges in at most dimension + 1 steps, where the plain chord iteration
  converges only at the rate of the spectral radius of I - J0^-1 A. Its step is the weighted
  least squares of numpy's ``lstsq`` over the last ``depth`` differences, the oldest dropped
  first, and the Jacobi rotations give numpy's eigenvalues.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from masonry_nscd.nscd.anderson import ChordHistory, _jacobi_eigen
from masonry_nscd.nscd.newton import _Pattern


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


def _chord(A, b, J0, depth, steps):
    """Chord iterations x <- x + step on F(x) = A x - b, steps f = -J0^-1 F, accelerated
    with ``depth``; the residual norms."""
    x = np.zeros(len(b))
    history = ChordHistory(np.ones(len(b)), depth)
    out = []
    for _ in range(steps):
        F = A @ x - b
        out.append(np.linalg.norm(F))
        f = -np.linalg.solve(J0, F)
        step, _ = history.advance(x.copy(), f)
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


def test_anderson_step_is_the_weighted_least_squares_of_the_last_differences():
    rng = np.random.default_rng(5)
    n, depth = 40, 3
    w = 0.5 + rng.random(n)
    history = ChordHistory(w, depth)
    xs, fs = [], []
    for it in range(7):  # the ring wraps: the oldest differences are dropped
        x, f = rng.normal(size=n), rng.normal(size=n)
        step, accelerated = history.advance(x, f)
        assert accelerated == (it > 0)
        xs.append(x)
        fs.append(f)
        if it == 0:
            assert step is f
            continue
        k = min(it, depth)
        dX = np.column_stack([xs[i + 1] - xs[i] for i in range(it - k, it)])
        dF = np.column_stack([fs[i + 1] - fs[i] for i in range(it - k, it)])
        gamma = np.linalg.lstsq(dF * w[:, None], f * w, rcond=None)[0]
        expected = f - (dX + dF) @ gamma
        assert np.allclose(step, expected, rtol=0, atol=1e-10 * np.abs(expected).max())
    history.clear()
    assert history.advance(xs[0], fs[0])[1] is False


def test_anderson_step_leaves_out_a_repeated_difference():
    # the same difference twice: G is singular, and the step is that of the one difference
    rng = np.random.default_rng(6)
    n = 30
    w = np.ones(n)
    x0, f0, dx, df = (rng.normal(size=n) for _ in range(4))
    history = ChordHistory(w, 5)
    history.advance(x0, f0)
    history.advance(x0 + dx, f0 + df)
    step, _ = history.advance(x0 + 2 * dx, f0 + df + df)  # the same difference again
    f = f0 + 2 * df
    gamma = (df @ f) / (df @ df) / 2.0  # split between the two equal columns
    assert np.all(np.isfinite(step))
    assert np.allclose(step, f - 2 * gamma * (dx + df), rtol=0, atol=1e-9 * np.abs(f).max())


def test_jacobi_eigen_gives_numpys_eigenvalues_and_vectors():
    rng = np.random.default_rng(7)
    for m in (1, 2, 5):
        B = rng.normal(size=(m, m))
        A = B @ B.T + np.diag(np.linspace(0.0, 1e-3, m))
        lam, Q = np.empty(m), np.empty((m, m))
        _jacobi_eigen(A.copy(), lam, Q)
        assert np.allclose(np.sort(lam), np.linalg.eigvalsh(A), rtol=0,
                           atol=1e-13 * np.abs(A).max())
        assert np.allclose(Q @ np.diag(lam) @ Q.T, A, rtol=0, atol=1e-13 * np.abs(A).max())
        assert np.allclose(Q.T @ Q, np.eye(m), rtol=0, atol=1e-14 * m)
