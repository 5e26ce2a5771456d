"""Property tests of the joint law over the whole parameter ranges of the case schema (hypothesis).

One contact point of unit area is driven along random histories of its relative displacement,
with the integrity consistent with the end of each step (``joint_law.local_solve_implicit``,
as in the NSCD step and the point driver), either directly (``A = 0``, a rigid loading device)
or through a compliance ``A`` (the rest of a system, as in the Gauss-Seidel sweeps). Along
every history:

* tractions and cohesive displacements are finite;
* the integrity never grows (the damage never decreases) and stays in [0, 1];
* the dissipated energy never decreases: with the stored energy
  ``psi = T . u_s / 2 + beta b (K_I <u_c,n>^2 + K_II |u_c,t|^2) / 2`` (J/m^2; springs and
  cohesive part), each step's work ``T_n+1 . (u_n+1 - u_n)`` is at least ``psi_n+1 - psi_n``
  (the implicit update of a convex stored energy with a decreasing integrity and Coulomb
  friction dissipates);
* objectivity: in a tangent frame turned by any angle about the normal, the same history gives
  the same tractions and cohesive displacements, turned, and the same integrity.

Parameters are drawn log-uniformly across the bounds of ``case.Joint`` and checked by it (a
draw that the schema refuses is skipped).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from masonry_nscd.case import CaseError, case_from_dict
from masonry_nscd.contact import joint_law as jl
from masonry_nscd.scenes.wall import joint_params_from_case

SETTINGS = settings(max_examples=60, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def _log(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda x: 10.0**x)


@st.composite
def joint_params(draw) -> np.ndarray:
    """A parameter vector of the fczm law, from a joint section the schema accepts."""
    joint = {
        "law": "fczm",
        "K_I_spring_Pa_m": draw(_log(1e3, 1e16)),
        "K_II_spring_Pa_m": draw(_log(1e3, 1e16)),
        "d_spring": draw(st.one_of(st.just(0.0), st.floats(0.0, 0.999))),
        "sigma_I_e_Pa": draw(_log(1e2, 1e9)),
        "K_I_coh_Pa_m": draw(_log(1e3, 1e16)),
        "G_fI_J_m2": draw(_log(1e-3, 1e6)),
        "sigma_II_e_Pa": draw(_log(1e2, 1e9)),
        "K_II_coh_Pa_m": draw(_log(1e3, 1e16)),
        "G_fII_J_m2": draw(_log(1e-3, 1e6)),
        "d_coh_initial": draw(st.one_of(st.sampled_from([0.0, 0.99944, 1.0 - 1e-9]),
                                        st.floats(0.0, 0.999999))),
        "mu": draw(st.floats(0.0, 2.0)),
        "p": draw(_log(1e-2, 100.0)),
        "eta": draw(_log(1e-12, 0.49)),
        "compression_spring": draw(st.sampled_from(["damaged", "undamaged"])),
    }
    try:
        case = case_from_dict({"joint": joint})
    except CaseError:
        assume(False)
    return joint_params_from_case(case)


def _scale(P: np.ndarray) -> float:
    """A displacement scale of the law (m): the larger of the elastic limits and the springs'
    displacement at the mode I limit."""
    return max(P[jl.P_D1], P[jl.P_D2], P[jl.P_CN_T] * P[jl.P_D1] * P[jl.P_KI])


@st.composite
def history(draw, P):
    """Relative displacements (n, 3), m: jumps of random direction and size around the law's
    scale, from small to 100 times past it."""
    n = draw(st.integers(2, 25))
    amp = _scale(P) * draw(_log(1e-2, 1e2))
    pts = [draw(st.tuples(*[st.floats(-1.0, 1.0)] * 3)) for _ in range(n)]
    grow = draw(st.booleans())  # also monotonic-ish paths that march away from the origin
    path = np.array([np.array(p) * amp * ((k + 1) if grow else 1.0) for k, p in enumerate(pts)])
    # no subnormal numbers (below 2.2e-308 m the open status's u_c,n > 0 test fails after a
    # division that underflows; nothing physical lives there)
    path[np.abs(path) < 1e-290] = 0.0
    return path


@st.composite
def compliance(draw, P):
    """``A = 0`` or a random SPD compliance (m/Pa) up to the tangential spring's."""
    if draw(st.booleans()):
        return np.zeros((3, 3))
    Q = np.array([draw(st.tuples(*[st.floats(-1.0, 1.0)] * 3)) for _ in range(3)])
    return draw(_log(1e-3, 1.0)) * P[jl.P_CT] * (Q @ Q.T + 0.1 * np.eye(3)) / 3.0


def drive(P, A, path):
    """Drive the point along predictors ``path`` with compliance ``A``: per step the point's
    displacement u = u~ - A T (m), T (Pa), u_c (m), beta, status."""
    T = np.zeros(3)
    uc = np.zeros(3)
    uc_old = np.zeros(3)
    beta = 1.0
    out = {k: [] for k in ("u", "T", "uc", "beta", "status")}
    for ut in path:
        ut = np.ascontiguousarray(ut, dtype=float)
        st_, beta = jl.local_solve_implicit(ut, A, uc_old, beta, P, jl.KIND_JOINT, T, uc)
        uc_old[:] = uc
        for k, v in (("u", ut - A @ T), ("T", T.copy()), ("uc", uc.copy()), ("beta", beta),
                     ("status", st_)):
            out[k].append(v)
    return {k: np.array(v) for k, v in out.items()}


def stored_energy(P, r):
    """Stored energy per unit area (J/m^2) at every step of a driven history ``r``."""
    b = P[jl.P_B]
    us = r["u"] - r["uc"]
    spring = 0.5 * np.sum(r["T"] * us, axis=1)
    ucn = np.maximum(r["uc"][:, 0], 0.0)
    coh = 0.5 * r["beta"] * b * (P[jl.P_KI] * ucn**2 + P[jl.P_KII] * np.sum(r["uc"][:, 1:]**2, 1))
    return spring + coh


@SETTINGS
@given(data=st.data())
def test_finite_irreversible_and_dissipative(data):
    P = data.draw(joint_params())
    A = data.draw(compliance(P))
    path = data.draw(history(P))
    r = drive(P, A, path)
    assert np.isfinite(r["T"]).all() and np.isfinite(r["uc"]).all()
    beta = np.concatenate([[1.0], r["beta"]])
    assert np.all(np.diff(beta) <= 0.0) and np.all((beta >= 0.0) & (beta <= 1.0))
    ambiguous = r["status"] == jl.ST_AMBIGUOUS
    if not A.any():  # a driven point always has an exact solution
        assert not ambiguous.any()
    # a step without an exact status (reported to the caller, resolved by its sweeps) carries
    # a provisional traction: the energy statement is about exact solutions
    assume(not ambiguous.any())
    # dissipation of each step (J/m^2): work of the end-of-step traction minus the change of
    # the stored energy; tolerance: round-off of the terms involved (psi comes from u - u_c,
    # a difference of displacements that may be far larger than the springs' part)
    u = np.vstack([np.zeros(3), r["u"]])
    T = np.vstack([np.zeros(3), r["T"]])
    psi = np.concatenate([[0.0], stored_energy(P, r)])
    dissipated = np.sum(T[1:] * np.diff(u, axis=0), axis=1) - np.diff(psi)
    t_abs = np.abs(T).sum(axis=1)
    u_abs = np.abs(u).sum(axis=1) + np.abs(np.vstack([np.zeros(3), r["uc"]])).sum(axis=1)
    size = (t_abs[1:] + t_abs[:-1]) * (u_abs[1:] + u_abs[:-1]) + np.abs(psi[1:]) + np.abs(psi[:-1])
    # and the round-off of the whole history (a state left by 1e-17 m of round-off at 0.1 m of
    # slip carries its error into later steps at 1e-112 m)
    size = np.maximum(size, 1e-12 * size.max())
    assert np.all(dissipated >= -1e-8 * size), (dissipated / np.maximum(size, 1e-300)).min()


def _turn(alpha: float) -> np.ndarray:
    """Rotation of the tangent frame by ``alpha`` about the normal (3x3, normal first)."""
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@SETTINGS
@given(data=st.data(), alpha=st.floats(0.0, 2.0 * math.pi))
def test_objective_in_the_tangent_plane(data, alpha):
    """The law (a driven point, A = 0). With a coupled compliance the local solver is not
    objective yet: see the two xfail tests below."""
    P = data.draw(joint_params())
    A = np.zeros((3, 3))
    path = data.draw(history(P))
    Q = _turn(alpha)
    r = drive(P, A, path)
    q = drive(P, A, path @ Q.T)
    # T = D^-1 (u - u_c): with stiff springs u - u_c is a small difference of displacements,
    # whose round-off (1e-16 |u|, turned differently in each frame) is divided by the smallest
    # compliance of D = A + C_s
    c_min = min(np.diag(A).min() + P[jl.P_CT], A[0, 0] + min(P[jl.P_CN_T], P[jl.P_CN_C]))
    tol = 1e-7 * np.abs(r["T"]).max() + 1e-12 * np.abs(path).max() / c_min
    assert np.abs(q["T"] - r["T"] @ Q.T).max() <= tol
    # u_c = u - C_s T: the error of T, times the largest spring compliance
    c_max = max(P[jl.P_CN_T], P[jl.P_CN_C], P[jl.P_CT])
    assert np.abs(q["uc"] - r["uc"] @ Q.T).max() <= 1e-7 * np.abs(r["uc"]).max() + c_max * tol
    assert np.allclose(q["beta"], r["beta"], rtol=1e-7, atol=1e-12)
    # statuses may differ only where they coincide: a slide of zero length is a stick


@pytest.mark.parametrize("compression_spring", ["damaged", "undamaged"])
def test_pure_compression_stores_and_returns_the_spring_energy(compression_spring):
    """A closed cycle in compression (spring only): zero dissipation, up to round-off."""
    P = jl.joint_params(compression_spring=compression_spring)
    path = np.array([[-k * 1e-6, 0.0, 0.0] for k in (*range(11), *range(9, -1, -1))])
    r = drive(P, np.zeros((3, 3)), path)
    u = np.vstack([np.zeros(3), r["u"]])
    T = np.vstack([np.zeros(3), r["T"]])
    work = np.cumsum(np.sum(0.5 * (T[1:] + T[:-1]) * np.diff(u, axis=0), axis=1))  # exact here
    psi = stored_energy(P, r)
    assert np.allclose(psi, work, rtol=1e-12, atol=1e-12 * psi.max())
    assert psi[-1] == 0.0 and psi.max() > 0.0


@pytest.mark.xfail(strict=True, reason="local_solve finds no status for a slide whose first "
                   "diagonal iterate is in tension (issue 7, reported)")
def test_frictionless_slide_under_a_mildly_coupled_compliance():
    """Found by test_finite_irreversible_and_dissipative: mu = 0, the normal-tangential
    coupling of D = A + C_s only 0.03 of its diagonal; the slide T = (-0.133, 0, 98.65) Pa
    satisfies every condition (solve (D + diag(0, 1/k_t, 1/k_t)) T = u~), but the iteration of
    ``_slide`` stops at its uncoupled first iterate (normal traction in tension) and the
    direction scan of ``_slide_by_angle`` brackets no root: ST_AMBIGUOUS."""
    P = jl.joint_params(K_I_spring=1e4, K_II_spring=1e6, d_spring=0.0, sigma_I_e=100.0,
                        K_I_coh=1e4, G_fI=1.0, sigma_II_e=100.0, K_II_coh=1e4, G_fII=1.0,
                        d_coh_initial=0.0, mu=0.0, eta=0.1)
    A = np.array([[11.0, 0.0, 10.0], [0.0, 1.0, 0.0], [10.0, 0.0, 11.0]]) / 3e7
    T, uc = np.zeros(3), np.zeros(3)
    st_ = jl.local_solve(np.array([1.953125e-05, 0.0, 1e-2]), A, np.array([0.0, 0.00494886, 0.0]),
                         1.0, P, jl.KIND_JOINT, T, uc)
    assert st_ == jl.ST_SLIDE


@pytest.mark.xfail(strict=True, reason="local_solve finds no status for a slide whose first "
                   "diagonal iterate is in tension (issue 7, reported)")
def test_slide_under_a_coupled_compliance_is_objective():
    """Found by a long run of test_objective_in_the_tangent_plane with coupled compliances: the
    same point in two tangent frames (turned by 1 rad) ends with integrities 0.0075 and 0.074.
    The normal predictor is 4.9e-276 m (0 gives the right answer in both frames): in the turned
    frame ``local_solve`` at beta = 0.00747 gives up on the slide (first diagonal iterate in
    tension by 1e-272 Pa) and returns ST_AMBIGUOUS, and the regula falsi of
    ``local_solve_implicit`` then settles on another integrity, reported as a plain slide."""
    P = jl.joint_params(K_I_spring=1e4, K_II_spring=1e6, d_spring=0.0, sigma_I_e=100.0,
                        K_I_coh=1e4, G_fI=1.0, sigma_II_e=100.0, K_II_coh=1e6, G_fII=1.0,
                        d_coh_initial=0.5, mu=1.0, p=1.0, eta=0.1)
    A = (np.ones((3, 3)) + 0.1 * np.eye(3)) / 3e6
    path = np.array([[0.0, 0.0, 0.0], [4.9222445203277148e-276, 0.0, 1e-2]])
    Q = _turn(1.0)
    r = drive(P, A, path)
    q = drive(P, Q @ A @ Q.T, path @ Q.T)
    assert q["beta"][-1] == pytest.approx(r["beta"][-1], rel=1e-9)


def test_round_off_sized_openings_do_not_underflow():
    """Found by the search above: a slip of 1.8e-156 m with delta_1 = 1e-6 m made the mixed-mode
    weights underflow to zero (ZeroDivisionError in the kernel)."""
    P = jl.joint_params(K_I_spring=1e3, K_II_spring=1e3, d_spring=0.0, sigma_I_e=100.0,
                        K_I_coh=1e8, G_fI=1.0, sigma_II_e=100.0, K_II_coh=1e3, G_fII=10.0,
                        d_coh_initial=0.0, mu=0.0, eta=0.1)
    for u in ([0.0, 0.0, 1.79e-156], [1e-170, 1e-200, 0.0], [0.0, 5e-324, 0.0]):
        r = drive(P, np.zeros((3, 3)), np.array([u]))
        assert np.isfinite(r["T"]).all() and r["beta"][0] == 1.0
    nu, delta_e, sigma_e, k, phi, nu_u = jl.mixed_mode(0.0, 1e-320, P)
    assert np.isfinite([nu, delta_e, sigma_e, k, phi, nu_u]).all()
    assert delta_e == pytest.approx(P[jl.P_D2])  # pure mode II
