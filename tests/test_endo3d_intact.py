"""The intact points' shortcut of the ENDO3D update (``endo3d._intact_update``).

An intact point (no crack ever opened, no crushing) whose trial stays elastic is updated in
closed form, without the eigen solver. The shortcut must give the full update's result to
round-off and decide exactly when the full update finds the trial elastic:

* its principal stresses against LAPACK's (``numpy.linalg.eigvalsh``), repeated ones included;
* pure shear, where the principal split is known by hand: ``s = +-tau`` along the diagonals,
  so ``sigma_xy = tau (1 + f) / 2`` and ``sigma_xx = sigma_yy = tau (1 - f) / 2`` with
  ``f = 1 - d_cpp`` (the pre-peak damage acts on the compressive part only);
* random strains from random intact and damaged states: the update with and without the
  shortcut, the same stress, state and status to round-off, and the shortcut taken only where
  it may be.
"""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.materials import endo3d as m
from masonry_nscd.materials.point_driver import cube_nodes

STUDY = {"E": 11.1e9, "nu": 0.2, "R_t": 1.0e6, "eps_pic_t": 0.9009e-4, "G_ft": 60.0,
         "R_c": 9.46e6, "eps_pic_c": 0.13e-1, "delta": 0.4, "beta": 0.2, "eps_kdc": 0.18e-1,
         "DCPK": 1.0, "REF": 0.3e6, "GFR": 4.5, "crushing_length": 0.005}


def _rotation(rng: np.random.Generator) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    return q * np.sign(np.diag(r))


CLUSTERS = [(3.0, -1.0, 0.5), (2.0, 2.0, -5.0), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0),
            (1e6, 1e6 * (1 + 1e-13), -3e5), (-4e6, -4e6, -4e6 + 1e-3), (7.0, 0.0, 0.0),
            (1e5, 1e5 * (1 - 1e-9), -1e6), (3e5, -2e5 * (1 + 1e-10), -2e5)]


@pytest.mark.parametrize("values", CLUSTERS)
def test_principal_values_against_lapack(values):
    """Within the bound the shortcut assumes (``_CLOSED_FORM_ERROR`` of the scale) always, and
    to round-off for an eigenvalue ``_PROJECTOR_GAP`` from the others."""
    rng = np.random.default_rng(1)
    for _ in range(20):
        q = _rotation(rng)
        a = q @ np.diag(values) @ q.T
        a = 0.5 * (a + a.T)
        s1, s2, s3, q, p = m._principal_values(a)
        expected = np.linalg.eigvalsh(a)[::-1]
        assert q == pytest.approx(np.trace(a) / 3, abs=1e-15 * np.abs(a).max())
        scale = abs(q) + 2 * p
        assert s1 >= s2 - 1e-15 * scale and s2 >= s3 - 1e-15 * scale  # s2 = 3 q - s1 - s3
        assert np.abs([s1, s2, s3] - expected).max() <= m._CLOSED_FORM_ERROR * scale + 1e-300
        for k in range(3):
            gap = min(abs(expected[k] - expected[j]) for j in range(3) if j != k)
            if gap >= m._PROJECTOR_GAP * 2 * p:
                assert abs([s1, s2, s3][k] - expected[k]) <= 1e-13 * scale


@pytest.mark.parametrize(("values", "resolved"), [
    ((3.0, -1.0, 0.5), True), ((2e5, 2e5, -3e5), True), ((1e5, -1e-3, -1e-3), True),
    ((2e5, 1e5, -1e-9), True), ((-1e5, -2e5, -4e5), True), ((3e5, 2e5, 1e5), True),
    ((0.0, 0.0, -4e5), False), ((1e2, -1e2, -3e5), False), ((-1e-9, -2e-9, -4e5), False),
])
def test_split_against_lapack(values, resolved):
    """The intact elastic stress ``(1 - d_c)(S+ + (1 - d_cpp) S-)`` from LAPACK's
    eigenvectors, on clustered principal stresses: the shortcut agrees to round-off, or,
    where a lone eigenvalue of its sign is within ``_PROJECTOR_GAP`` of a neighbour of the
    other sign or zero (``resolved`` False), leaves the point to the full update."""
    prm = m.endo3d_params(**STUDY)
    rng = np.random.default_rng(2)
    state = m.endo3d_initial_state()
    taken = 0
    for _ in range(30):
        q = _rotation(rng)
        s_tr = q @ np.diag(values) @ q.T
        s_tr = 0.5 * (s_tr + s_tr.T)
        out, sigma = np.empty(m.N_STATE), np.empty(6)
        if not m._intact_update(s_tr, state, prm, out, sigma):
            continue
        taken += 1
        w, v = np.linalg.eigh(s_tr)
        plus = (v * np.maximum(w, 0.0)) @ v.T
        minus = (v * np.minimum(w, 0.0)) @ v.T
        expected = plus + (1.0 - out[m.S_D_CPP]) * minus
        expected6 = expected[[0, 1, 2, 1, 0, 0], [0, 1, 2, 2, 2, 1]]
        assert np.abs(sigma - expected6).max() <= 1e-12 * np.abs(values).max()
    assert taken == (30 if resolved else 0)


def test_pure_shear_split_by_hand():
    prm = m.endo3d_params(**STUDY)
    g = prm[m.P_G]
    gamma = 0.5 * STUDY["R_t"] / g  # tau = R_t / 2: elastic under Rankine and Drucker-Prager
    eps = np.array([0.0, 0.0, 0.0, 0.0, 0.0, gamma])
    state = m.endo3d_initial_state()
    out = np.empty(m.N_STATE)
    sigma = np.empty(6)
    status = m._update(eps, state, prm, cube_nodes(0.1), out, sigma,
                       np.empty((m.N_WORK, 3, 3)), True)
    assert status == 0
    tau = g * gamma
    f = 1.0 - out[m.S_D_CPP]
    assert 0.0 < out[m.S_D_CPP] < prm[m.P_D_PIC]  # shear raises the pre-peak damage
    assert sigma[5] == pytest.approx(tau * (1.0 + f) / 2.0, rel=1e-13)
    assert sigma[0] == pytest.approx(tau * (1.0 - f) / 2.0, rel=1e-12)
    assert sigma[1] == pytest.approx(tau * (1.0 - f) / 2.0, rel=1e-12)
    assert np.abs(sigma[[2, 3, 4]]).max() <= 1e-12 * tau
    # taken by the shortcut, and the same as the full update
    s_tr = np.zeros((3, 3))
    s_tr[0, 1] = s_tr[1, 0] = tau
    assert m._intact_update(s_tr, state, prm, np.empty(m.N_STATE), np.empty(6))


def _states(prm: np.ndarray, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """States reached by random strain paths of a few steps (intact, cracked, crushed)."""
    out = []
    xe = cube_nodes(0.1)
    wk = np.empty((m.N_WORK, 3, 3))
    sigma = np.empty(6)
    for _ in range(n):
        state = m.endo3d_initial_state()
        direction = rng.standard_normal(6)
        amp = rng.choice([2e-5, 1e-4, 1e-3, 1e-2])
        for k in range(1, rng.integers(1, 6) + 1):
            new = np.empty(m.N_STATE)
            m._update(direction * amp * k / 5, state, prm, xe, new, sigma, wk, False)
            state = new
        out.append(state)
    return out


@pytest.mark.parametrize("nu", [0.0, 0.2, 0.35])
def test_shortcut_gives_the_full_update(nu):
    prm = m.endo3d_params(**{**STUDY, "nu": nu})
    rng = np.random.default_rng(int(nu * 100))
    xe = cube_nodes(0.1)
    wk = np.empty((m.N_WORK, 3, 3))
    taken = declined_cracked = 0
    for state in _states(prm, rng, 60):
        cracked = bool(np.any(state[m.S_W_MAX:m.S_W_MAX + 6] != 0.0))
        for _ in range(20):
            eps = (state[m.S_EPS_PR:m.S_EPS_PR + 6] * np.array([1, 1, 1, 2, 2, 2])
                   + rng.standard_normal(6) * rng.choice([1e-6, 3e-5, 1e-4]))
            out_a, out_b = np.empty(m.N_STATE), np.empty(m.N_STATE)
            sig_a, sig_b = np.empty(6), np.empty(6)
            st_a = m._update(eps, state, prm, xe, out_a, sig_a, wk, True)
            st_b = m._update(eps, state, prm, xe, out_b, sig_b, wk, False)
            assert st_a == st_b
            scale = max(np.abs(out_b[:6]).max(), 1.0)
            assert np.abs(sig_a - sig_b).max() <= 1e-13 * scale
            assert np.abs(out_a[:6] - out_b[:6]).max() <= 1e-13 * scale
            assert np.allclose(out_a[6:], out_b[6:], rtol=1e-12, atol=1e-15)
            # was it taken?
            s_tr = np.empty((3, 3))
            m._from6(out_b, m.S_SIG_EFF, s_tr)
            if m._intact_update(s_tr, state, prm, np.empty(m.N_STATE), np.empty(6)):
                taken += 1
                assert not cracked
                assert out_b[m.S_LAMBDA_D] == state[m.S_LAMBDA_D]
            elif cracked:
                declined_cracked += 1
    assert taken > 100 and declined_cracked > 10  # both branches were exercised


def test_shortcut_leaves_the_tensile_strength_to_the_full_update():
    """Beyond ``R_t`` by more than the return mapping's tolerance: not elastic. Within its
    closed-form error of it: for the full update to decide. Clearly below: elastic."""
    prm = m.endo3d_params(**STUDY)
    state = m.endo3d_initial_state()
    for s1, taken in [(STUDY["R_t"] + 2.0 * prm[m.P_TOL], False),
                      (STUDY["R_t"] * (1.0 - 1e-8), False), (STUDY["R_t"] * (1.0 - 1e-5), True)]:
        s_tr = np.diag([s1, -1e5, 0.0])
        assert m._intact_update(s_tr, state, prm, np.empty(m.N_STATE), np.empty(6)) == taken
