"""The hexahedron's block matrices against what any consistent trilinear element must give:
six rigid-body modes, exact uniform strains under a linear displacement field (the patch test),
the mass of the block, and an inverted element refused."""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.fe import hex8


def _distorted_block(seed=1):
    X, conn = hex8.box_mesh(np.zeros(3), np.array([0.4, 0.2, 0.15]), (2, 3, 2))
    X = X + np.random.default_rng(seed).normal(0.0, 0.004, X.shape)
    return X, conn


def test_stiffness_has_the_six_rigid_body_modes_and_no_other():
    X, conn = _distorted_block()
    K, _ = hex8.assemble_block(X, conn, hex8.elastic_matrix(15e9, 0.2), 2300.0)
    assert np.allclose(K, K.T, rtol=0, atol=1e-6 * np.abs(K).max())
    ev = np.linalg.eigvalsh(K)
    assert np.all(np.abs(ev[:6]) < 1e-9 * ev[-1]) and ev[6] > 1e-6 * ev[-1]


def test_a_linear_displacement_field_gives_its_uniform_strain_and_balanced_forces():
    X, conn = _distorted_block(2)
    G = np.array([[1e-4, 2e-5, -3e-5], [4e-5, -2e-4, 1e-5], [0.0, 3e-5, 5e-5]])  # du_i/dx_j
    u = (X @ G.T).ravel()
    eps = np.empty((8 * len(conn), 6))
    hex8.gauss_strains(X, conn, u, eps)
    expected = [G[0, 0], G[1, 1], G[2, 2], G[1, 2] + G[2, 1], G[0, 2] + G[2, 0], G[0, 1] + G[1, 0]]
    assert np.allclose(eps, expected, rtol=0, atol=1e-12)
    # a uniform stress is self-balanced over the block: inner nodes carry no force
    C = hex8.elastic_matrix(15e9, 0.2)
    K, _ = hex8.assemble_block(X, conn, C, 2300.0)
    f = np.empty(3 * len(X))
    hex8.internal_forces(X, conn, eps @ C.T, f)
    assert np.allclose(f, K @ u, rtol=0, atol=1e-9 * np.abs(f).max())
    assert np.allclose(f.reshape(-1, 3).sum(axis=0), 0.0, atol=1e-9 * np.abs(f).max())


def test_the_mean_stress_map_gives_the_uniform_stress_of_a_linear_field_and_the_gauss_mean():
    X, conn = _distorted_block(2)
    C = hex8.elastic_matrix(15e9, 0.2)
    S = hex8.mean_stress_map(X, conn, C)
    G = np.array([[1e-4, 2e-5, -3e-5], [4e-5, -2e-4, 1e-5], [0.0, 3e-5, 5e-5]])  # du_i/dx_j
    eps = [G[0, 0], G[1, 1], G[2, 2], G[1, 2] + G[2, 1], G[0, 2] + G[2, 0], G[0, 1] + G[1, 0]]
    sig = (S @ (X @ G.T).ravel()).reshape(-1, 6)
    assert np.allclose(sig, C @ eps, rtol=1e-12, atol=0)
    # any field: the mean over the Gauss points of C eps
    u = np.random.default_rng(3).normal(scale=1e-4, size=3 * len(X))
    e = np.empty((8 * len(conn), 6))
    hex8.gauss_strains(X, conn, u, e)
    assert np.allclose((S @ u).reshape(-1, 6), (e @ C.T).reshape(-1, 8, 6).mean(axis=1),
                       rtol=1e-12, atol=1e-12 * np.abs(e @ C.T).max())


def test_the_lumped_mass_is_the_blocks_mass():
    X, conn = hex8.box_mesh(np.zeros(3), np.array([0.4, 0.2, 0.15]), (2, 3, 2))
    _, m = hex8.assemble_block(X, conn, hex8.elastic_matrix(15e9, 0.2), 2300.0)
    assert m.reshape(-1, 3).sum(axis=0) == pytest.approx([2300.0 * 0.4 * 0.2 * 0.15] * 3,
                                                         rel=1e-12)
    assert np.array_equal(m, hex8.lumped_mass(X, conn, 2300.0))


def test_an_inverted_element_is_refused():
    X, conn = hex8.box_mesh(np.zeros(3), np.ones(3), (1, 1, 1))
    with pytest.raises(ValueError, match="non-positive Jacobian"):
        hex8.precompute_b(X[conn[:, [4, 5, 6, 7, 0, 1, 2, 3]]])


def test_the_gradient_kernels_are_the_dense_b_products():
    """``forces_from_gradients`` and ``stiffness_from_gradients`` against ``sum_g w B^T sigma``
    and ``sum_g w B^T C B`` with the dense B matrices, on distorted elements and a
    nonsymmetric C per Gauss point."""
    rng = np.random.default_rng(3)
    cube = hex8.NODE_SIGNS * 0.05
    xe = np.stack([cube + 0.01 * rng.standard_normal((8, 3)) for _ in range(5)])
    B, w = hex8.precompute_b(xe)
    dN, w2 = hex8.precompute_gradients(xe)
    assert np.array_equal(w, w2)
    nel = len(xe)
    edofs = np.arange(24 * nel).reshape(nel, 24)
    sigma = rng.standard_normal((8 * nel, 6)) * 1e6
    f = np.zeros(24 * nel)
    hex8.forces_from_gradients(dN, w, edofs, sigma, f)
    dense = np.einsum("eg,egci,egc->ei", w, B, sigma.reshape(nel, 8, 6)).ravel()
    assert np.allclose(f, dense, rtol=1e-13, atol=1e-13 * np.abs(dense).max())
    C = rng.standard_normal((8 * nel, 6, 6)) * 1e10
    K = hex8.stiffness_from_gradients(dN, w, C)
    dense_K = np.einsum("eg,egia,egij,egjk->eak", w, B, C.reshape(nel, 8, 6, 6), B)
    assert np.allclose(K, dense_K, rtol=1e-13, atol=1e-13 * np.abs(dense_K).max())
