"""The joint law against the check table of model.md section 2 (single point, unit area).

Expected numbers come from the closed forms of model.md, not from the code: the peaks of the
series system are where the cohesive response meets the envelope, the energies are G_f.
"""

import math

import numpy as np
import pytest

from masonry_nscd.contact.laws import fczm as jl
from masonry_nscd.contact.point_driver import drive_joint_point

B_STUDY = 1.0 - 0.99944


def virgin(**kw):
    return jl.joint_params(d_coh_initial=0.0, **kw)


def peak(curve, which):
    T = curve.T_n if which == "n" else curve.T_t
    u = curve.u_n if which == "n" else curve.u_t
    i = int(np.argmax(T))
    return T[i], u[i]


def test_pure_mode_quantities():
    P = virgin()
    _, de1, _, _, phi1, _ = jl.mixed_mode(1.0, 0.0, P)
    _, de2, _, _, phi2, _ = jl.mixed_mode(0.0, 1.0, P)
    assert de1 == pytest.approx(4.1322e-7, rel=1e-4)
    assert phi1 == pytest.approx(16724.3, rel=1e-5)
    assert de2 == pytest.approx(9.6429e-7, rel=1e-4)
    assert phi2 == pytest.approx(1311.51, rel=1e-5)


@pytest.mark.parametrize("path,to,G", [("opening", 6e-4, 3.0), ("sliding", 8e-3, 206.0)])
def test_energy_to_failure_equals_fracture_energy(path, to, G):
    c = drive_joint_point(virgin(), path, to, steps=4000)
    assert c.d_coh[-1] == 1.0  # fully broken at the end of the path
    # what is left out is the tail beyond the eta cut-off: sigma_e * eta / phi, far below 0.1 %
    assert c.work() == pytest.approx(G, rel=1e-3)


def test_virgin_mode_I_peak_with_spring():
    c = drive_joint_point(virgin(), "opening", 4e-6, steps=4000)
    T, u = peak(c, "n")
    assert T == pytest.approx(0.05e6, rel=1e-3)
    assert u == pytest.approx(2.887e-6, rel=2e-3)


def test_virgin_mode_II_peak_with_spring():
    c = drive_joint_point(virgin(), "sliding", 4e-5, steps=8000)
    T, u = peak(c, "t")
    assert T == pytest.approx(0.27e6, rel=1e-3)
    assert u == pytest.approx(3.288e-5, rel=2e-3)


def test_initial_damage_lowers_mode_II_peak_to_0403():
    P = jl.joint_params()
    c = drive_joint_point(P, "sliding", 2e-3, steps=8000)
    T, _ = peak(c, "t")
    assert T == pytest.approx(0.1088e6, rel=2e-3)
    assert T / 0.27e6 == pytest.approx(0.403, abs=1e-3)


def test_initial_damage_mode_I_peak():
    c = drive_joint_point(jl.joint_params(), "opening", 3e-4, steps=8000)
    T, _ = peak(c, "n")
    assert T == pytest.approx(7.64e3, rel=2e-3)


def test_mixed_mode_45_degrees_damage_onset():
    # a practically rigid spring, so that the 45 degree path is that of the cohesive part
    P = virgin(K_I_spring=1e22, K_II_spring=1e22, d_spring=0.0)
    c = drive_joint_point(P, "mixed", 6e-7, steps=6000)
    first = int(np.argmax(c.d_coh > 0.0))
    assert first > 0
    assert c.u_n[first - 1] <= 3.798e-7 <= c.u_n[first] * (1 + 1e-9)
    assert c.u_n[first] == pytest.approx(3.798e-7, rel=1e-3)


def test_unload_reload_along_secant_without_healing():
    P = virgin()
    c = drive_joint_point(P, "opening", 2e-5, steps=2000, unload_to=0.0)
    n = 2001
    d_top = c.d_coh[n - 1]
    beta = 1.0 - d_top
    assert 0.1 < d_top < 0.99
    # unloading: the damage is frozen and the traction follows the secant of the series system
    assert np.all(c.d_coh[n:] == d_top)
    k_sec = 1.0 / (1.0 / (beta * P[jl.P_KI]) + P[jl.P_CN_T])
    un = c.u_n[n + 100 : -1]
    assert np.allclose(c.T_n[n + 100 : -1], k_sec * un, rtol=1e-9)
    # reloading to the same opening: no further damage, the same traction (no healing)
    r = drive_joint_point(P, "opening", 2e-5, steps=2000)
    assert r.d_coh[-1] == pytest.approx(d_top, rel=1e-12)


@pytest.mark.parametrize("switch,factor", [("damaged", 1.0 - 0.953), ("undamaged", 1.0)])
def test_compression_carried_by_spring(switch, factor):
    P = jl.joint_params(compression_spring=switch)
    c = drive_joint_point(P, "opening", -1e-5, steps=50)
    assert np.allclose(c.T_n[1:], factor * 4.3e11 * c.u_n[1:], rtol=1e-12)
    assert np.all(c.d_coh == pytest.approx(0.99944))


def test_friction_under_held_compression():
    P = jl.joint_params(mu=0.7, p=1.0)
    steps = 8000
    c = drive_joint_point(P, "sliding", 8e-3, steps=steps, normal_stress=-0.5e6)
    assert np.allclose(c.T_n, -0.5e6)
    # stick limit: mu (1 - b) |sigma|; the last sticking step lies within one step of it
    limit = 0.7 * (1.0 - B_STUDY) * 0.5e6
    assert limit == pytest.approx(0.3498e6, rel=1e-4)
    first_slide = int(np.argmax(c.status == jl.ST_SLIDE))
    du = 8e-3 / steps
    k_t = (1 - 0.953) * 1.8e11
    assert c.T_t[first_slide - 1] <= limit <= c.T_t[first_slide - 1] + k_t * du
    T, u = peak(c, "t")
    assert T == pytest.approx(0.4586e6, rel=1e-3)
    assert u == pytest.approx(7.48e-4, rel=3e-3)
    assert c.d_coh[-1] == 1.0
    assert c.T_t[-1] == pytest.approx(0.35e6, rel=1e-9)


def test_series_stiffness_per_unit_area():
    P = jl.joint_params()
    du = 1e-8
    ten = drive_joint_point(P, "opening", du, steps=10)
    assert ten.T_n[-1] / du == pytest.approx(6.753e7, rel=1e-3)
    shear = drive_joint_point(P, "sliding", du, steps=10, normal_stress=0.0)
    assert shear.T_t[-1] / du == pytest.approx(1.539e8, rel=1e-3)
    comp = drive_joint_point(P, "opening", -du, steps=10)
    assert comp.T_n[-1] / -du == pytest.approx(2.021e10, rel=1e-3)


def test_coulomb_law_is_rigid_plastic():
    P = jl.joint_params(law="coulomb", mu=0.6)
    A = np.diag([1e-9, 1e-9, 1e-9])
    T = np.zeros(3)
    uc = np.zeros(3)
    # pushed down and sideways: slides with |T_t| = mu |T_n|
    st, _ = jl.solve(
        np.array([-1e-4, 1e-3, 0.0]), A, np.zeros(3), 1.0, P, T, uc
    )
    assert st == jl.ST_SLIDE
    assert T[0] == pytest.approx(-1e5)
    assert T[1] == pytest.approx(0.6e5)
    # a joint being pulled apart carries nothing
    st, _ = jl.solve(
        np.array([1e-4, 1e-3, 0.0]), A, np.zeros(3), 1.0, P, T, uc
    )
    assert st == jl.ST_OPEN and np.all(T == 0.0)


def test_dry_law_is_a_spring_in_series_with_coulomb_friction():
    """``law='dry'``: ``T_n = K_n u_n`` in compression, nothing in tension, ``T_t = K_t u_t``
    while ``K_t |u_t| <= mu K_n |u_n|``, then ``|T_t| = mu |T_n|`` with the slip carrying the
    rest; the tangent is ``diag(K_n, K_t, K_t)`` in stick, ``K_tn = -mu e K_n`` in slide."""
    K_n, K_t, mu = 1e11, 4e10, 0.65
    P = jl.joint_params(law="dry", mu=mu, K_n=K_n, K_t=K_t)
    A0 = np.zeros((3, 3))
    T, uc, K = np.zeros(3), np.zeros(3), np.zeros((3, 3))
    un = -2e-5  # T_n = -2 MPa; slides once K_t u_t > 1.3 MPa, u_t > 3.25e-5 m
    st, _ = jl.solve(np.array([un, 3e-5, 0.0]), A0, np.zeros(3), 1.0, P, T, uc)
    assert st == jl.ST_STICK
    assert T == pytest.approx([K_n * un, K_t * 3e-5, 0.0], rel=1e-12)
    jl.tangent(np.array([un, 3e-5, 0.0]), T, np.zeros(3), 1.0, st, P, K)
    assert np.diag(K) == pytest.approx([K_n, K_t, K_t], rel=1e-12)
    u = np.array([un, 3e-5, 4e-5])  # |u_t| = 5e-5 m
    st, _ = jl.solve(u, A0, np.zeros(3), 1.0, P, T, uc)
    assert st == jl.ST_SLIDE
    assert T[0] == pytest.approx(K_n * un, rel=1e-12)
    assert T[1:] == pytest.approx(mu * -K_n * un * np.array([0.6, 0.8]), rel=1e-10)
    # the slip is what the spring does not carry: |u_t| - |T_t| / K_t along e
    assert uc[1:] == pytest.approx((5e-5 - 1.3e6 / K_t) * np.array([0.6, 0.8]), rel=1e-9)
    jl.tangent(u, T, np.zeros(3), 1.0, st, P, K)
    assert K[1:, 0] == pytest.approx(-mu * K_n * np.array([0.6, 0.8]), rel=1e-10)
    st, _ = jl.solve(np.array([1e-6, 3e-5, 0.0]), A0, np.zeros(3), 1.0, P, T, uc)
    assert st == jl.ST_OPEN and np.all(T == 0.0)
    assert jl.initial_damage(P) == 1.0  # no cohesion: the joint is broken as built


def test_dry_law_needs_its_stiffnesses():
    with pytest.raises(ValueError, match="K_n > 0 and K_t > 0"):
        jl.joint_params(law="dry", mu=0.6)


def test_coupled_compliance_slide_satisfies_the_law():
    """With a full (coupled) compliance the iterated slide solution meets every condition.

    Two regimes: the coupling of a joint point with its spring (A up to a third of the spring
    compliance), where the split iteration converges, and a dry contact (no spring, A full and
    strongly coupled), where the slip-direction scan takes over.
    """
    rng = np.random.default_rng(3)
    P = jl.joint_params()
    for _ in range(200):
        if rng.random() < 0.5:
            Q = rng.uniform(-0.5, 0.5, size=(3, 3))
            A = 0.3 * P[jl.P_CN_T] * (np.eye(3) + 0.5 * (Q + Q.T) / 2)
        else:
            Q = rng.normal(size=(3, 3))
            A = 1e-11 * (Q @ Q.T + 0.3 * np.eye(3))
        ut = rng.normal(size=3) * 1e-5
        ut[0] = -abs(ut[0])
        uc_old = np.array([0.0, *rng.normal(size=2) * 1e-6])
        T = np.zeros(3)
        uc = np.zeros(3)
        st = jl.local_solve(ut, A, uc_old, 0.5, P, T, uc)
        assert st != jl.ST_AMBIGUOUS
        D = A + np.diag([P[jl.P_CN_T] if T[0] > 0 else P[jl.P_CN_C], P[jl.P_CT], P[jl.P_CT]])
        assert np.allclose(ut - D @ T, uc, atol=1e-12 * np.abs(ut).max() + 1e-18)
        if st == jl.ST_SLIDE:
            kt = 0.5 * B_STUDY * 2.8e11
            mu_eff = 0.7 * (1 - 0.5 * B_STUDY)
            R = T[1:] - kt * uc[1:]
            assert np.linalg.norm(R) == pytest.approx(mu_eff * -T[0], rel=1e-8)
            s = uc[1:] - uc_old[1:]
            assert np.dot(s, R) >= 0.0
            assert math.isclose(abs(np.dot(s, R)), np.linalg.norm(s) * np.linalg.norm(R), rel_tol=1e-8)


def _ac(u, r, old, mu=0.6, rho=1e4):
    from masonry_nscd.contact import alart_curnier

    Phi, uc = np.empty(3), np.empty(3)
    Gu, Gr = np.empty((3, 3)), np.empty((3, 3))
    st = alart_curnier.residual(np.asarray(u, float), np.asarray(r, float),
                                np.asarray(old, float), mu, rho, Phi, Gu, Gr, uc)
    return st, Phi, Gu, Gr, uc


def test_alart_curnier_zeros_are_the_signorini_coulomb_states():
    """The function vanishes exactly at the states of the law: open with no impulse, closed and
    stuck within the cone, closed and sliding with the impulse on the cone against the slip; and
    not elsewhere (a penetration, a pull, an impulse off the cone)."""
    old = np.array([0.0, 2e-4, -1e-4])
    mu = 0.6
    st, Phi, *_ = _ac([3e-4, 1e-3, 0.0], [0.0, 0.0, 0.0], old, mu)
    assert st == jl.ST_OPEN and np.all(Phi == 0.0)
    st, Phi, *_ = _ac([0.0, 2e-4, -1e-4], [10.0, 3.0, -4.0], old, mu)  # |r_t| = 5 <= 6
    assert st == jl.ST_STICK and np.all(Phi == 0.0)
    slip = np.array([3e-5, 4e-5])
    st, Phi, *_ = _ac([0.0, *(old[1:] + slip)], [10.0, *(-6.0 * slip / 5e-5)], old, mu)
    assert st == jl.ST_SLIDE and np.abs(Phi).max() < 1e-18
    for u, r in (([-1e-6, 2e-4, -1e-4], [10.0, 0.0, 0.0]),  # penetrates
                 ([0.0, 2e-4, -1e-4], [-1.0, 0.0, 0.0]),  # pulls
                 ([0.0, 2e-4, -1e-4], [10.0, 7.0, 0.0]),  # off the cone
                 ([0.0, *(old[1:] + slip)], [10.0, *(6.0 * slip / 5e-5)])):  # helps the slip
        assert np.abs(_ac(u, r, old, mu)[1]).max() > 1e-9


def test_alart_curnier_derivatives_are_those_of_the_function():
    """``Gu``, ``Gr`` against central differences at random states of each status (away from
    the kinks, where both sides of the difference have the same status)."""
    rng = np.random.default_rng(0)
    rho, seen, worst = 1e4, set(), 0.0
    for _ in range(300):
        u, r = rng.normal(size=3) * 1e-4, rng.normal(size=3)
        old = rng.normal(size=3) * 1e-4
        st, _, Gu, Gr, _ = _ac(u, r, old, rho=rho)
        for x, G, dx in ((u, Gu, 1e-10), (r, Gr, 1e-6)):
            for j in range(3):
                xp, xm = x.copy(), x.copy()
                xp[j] += dx
                xm[j] -= dx
                if x is u:
                    sp, Pp, *_ = _ac(xp, r, old, rho=rho)
                    sm, Pm, *_ = _ac(xm, r, old, rho=rho)
                else:
                    sp, Pp, *_ = _ac(u, xp, old, rho=rho)
                    sm, Pm, *_ = _ac(u, xm, old, rho=rho)
                if sp != st or sm != st:
                    continue
                seen.add(st)
                fd = (Pp - Pm) / (2 * dx)
                scale = np.abs(G).max() or 1.0  # Gu = 0 when open: the difference must be too
                worst = max(worst, np.abs(fd - G[:, j]).max() / scale)
    assert seen == {jl.ST_OPEN, jl.ST_STICK, jl.ST_SLIDE}
    assert worst < 1e-6
