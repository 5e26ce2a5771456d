"""Property tests of the ENDO3D kernel over the parameter ranges (hypothesis).

* no NaN/inf and a converged return mapping on monotonic and cyclic (non-proportional) paths;
* damages (d_c, d_cpp, the tensile damages of the cracks, the largest crack opening) and the
  cumulated Drucker-Prager multiplier never decrease;
* the work of a closed strain cycle from the virgin state is not negative - asserted where the
  law as specified guarantees it, see below.

Energy over a closed cycle: what the specified law guarantees, and what it does not.
Found with random searches of ~3000 cycles each (kept out of the test suite):

1. beta > delta: the Drucker-Prager flow dissipates ``dlam (C + (delta - beta) p)``, negative at
   pressures ``p > C/(beta - delta)``: closed cycles then return more work than they received
   (18 of 1500 proportional cycles). Thermodynamics asks beta <= delta (the study: 0.2 <= 0.4).
2. Crack reclosure: the transmission ``rho(W)`` recovers while the effective stress sits at
   ``-REF``, which releases up to ``(1/2) REF^2/E`` per direction and per closure (even with
   nu = 0, on proportional paths). Bound used below: ``3 REF^2/E`` for the 0 -> a -> b -> a -> 0
   cycles (two compressive phases, three directions).
3. nu > 0: splitting the effective stress into principal parts and damaging them differently is
   not derived from a potential (the ``tr(s+) tr(ds)`` term of the compliance); the work of
   elastic cycles in a damaged state then depends on the path and can be negative, on
   non-proportional cycles even with the study's parameters (about -1.2 % of the gross work:
   ``test_nonproportional_cycle_can_release_energy``, xfail strict) and rarely on proportional
   ones (1 of 3000).

So the energy property is asserted for nu = 0, beta <= delta, proportional cycles (the
principal directions do not rotate), with the bound of item 2. The work is integrated with the
trapezoidal rule, whose error scales as 1/N^2 (20, 200, 2000 steps per segment gave -5e-4,
-5e-6, -5e-8 of the gross work on a cycle that dissipates almost nothing): tolerance 1e-3 of the
gross work with 40 steps per segment.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from masonry_nscd.materials import endo3d as m
from masonry_nscd.materials.point_driver import cube_nodes

SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])

MONOTONE_KEYS = (
    m.S_D_C,
    m.S_D_CPP,
    m.S_D_T,
    m.S_D_T + 1,
    m.S_D_T + 2,
    m.S_W_OPEN_MAX,
    m.S_LAMBDA_D,
)


@st.composite
def material(draw, nu_max=0.45, beta_le_delta=False):
    E = draw(st.floats(1e9, 5e10))
    R_t = draw(st.floats(0.3e6, 5e6))
    R_c = R_t * draw(st.floats(5.0, 30.0))
    delta = draw(st.floats(0.0, 0.8))
    beta = delta * draw(st.floats(0.0, 1.0)) if beta_le_delta else draw(st.floats(0.0, 0.8))
    kw = {
        "E": E,
        "nu": draw(st.floats(0.0, nu_max)) if nu_max > 0.0 else 0.0,
        "R_t": R_t,
        "eps_pic_t": R_t / E,
        "G_ft": draw(st.floats(5.0, 300.0)),
        "R_c": R_c,
        "eps_pic_c": R_c / E * draw(st.floats(0.5, 30.0)),
        "delta": delta,
        "beta": beta,
        "eps_kdc": draw(st.floats(1e-3, 5e-2)),
        "DCPK": draw(st.floats(0.0, 1.0)),
        "REF": R_t * draw(st.floats(0.05, 1.0)),
        "GFR": draw(st.floats(0.5, 20.0)),
    }
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            p = m.endo3d_params(**kw)
    except ValueError:
        assume(False)
    return p


def unit6(draw):
    v = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(6)])
    n = np.linalg.norm(v)
    assume(n > 0.1)
    return v / n


@st.composite
def direction(draw):
    return unit6(draw)


amplitude = st.floats(-5.0, -1.5).map(lambda x: 10.0**x)
size = st.floats(0.02, 0.5)


def run(prm, hist, h):
    xe = cube_nodes(h)
    st_ = m.endo3d_initial_state()
    sig = np.empty(6)
    S = [np.zeros(6)]
    states = [st_]
    for e in hist:
        new = np.empty(m.N_STATE)
        status = m.endo3d_update(np.ascontiguousarray(e), st_, prm, xe, new, sig)
        assert status == 0, f"return mapping status {status} at strain {e}"
        assert np.all(np.isfinite(sig)) and np.all(np.isfinite(new))
        S.append(sig.copy())
        states.append(new)
        st_ = new
    return np.array(S), np.array(states)


def check_monotone(states):
    # round-off: the damages of the cracks come from the eigenvalues of W_max, accurate to
    # ~1e-16 |W_max|, times dd/dw <= 2/w_k: 1e-9 is far above it and far below anything physical
    # the opening (m) and lambda_D: relative round-off
    for k in MONOTONE_KEYS:
        d = np.diff(states[:, k])
        if k in (m.S_W_OPEN_MAX, m.S_LAMBDA_D):
            tol = 1e-12 * np.abs(states[1:, k]) + 1e-30
        else:
            tol = 1e-9
        assert np.all(d >= -tol), (k, d.min())
    for k in (m.S_D_C, m.S_D_CPP, m.S_D_T):
        assert np.all(states[:, k] >= 0.0) and np.all(states[:, k] <= 1.0)


def drucker_prager_excess(prm, state) -> float:
    """How far the effective stress of a state lies outside the admissible set of the return
    mapping (Pa, <= 0 inside), less its tolerance: the largest of ``s_i - R_t`` and
    ``f_D = sqrt(J2) - delta p - C(lambda_D)``, the latter unless three principal stresses sit
    on Rankine-type constraints (R_t or -REF), where Drucker-Prager is skipped. Tolerance:
    10 times the return mapping's (1e-8 max(R_t, R_c,eff, REF)) plus the eigenvalues'
    round-off (1e-12 of the largest principal stress)."""
    v = state[m.S_SIG_EFF:m.S_SIG_EFF + 6]
    s = np.linalg.eigvalsh(np.array([[v[0], v[5], v[4]], [v[5], v[1], v[3]],
                                     [v[4], v[3], v[2]]]))
    tol = 10.0 * prm[m.P_TOL] + 1e-12 * np.abs(s).max()
    mean = s.mean()
    q = math.sqrt(0.5 * np.sum((s - mean) ** 2))
    lam, lpk = state[m.S_LAMBDA_D], prm[m.P_LAMBDA_PK]
    x = min(lam / lpk, 1.0) if lpk > 0.0 else 1.0
    C = prm[m.P_C_MIN] + (prm[m.P_C_MAX] - prm[m.P_C_MIN]) * (2.0 * x - x * x)
    on_corner = np.all((np.abs(s - prm[m.P_RT]) <= tol) | (np.abs(s + prm[m.P_REF]) <= tol))
    excess = s.max() - prm[m.P_RT]
    if not on_corner:
        excess = max(excess, q + prm[m.P_DELTA] * mean - C)
    return float(excess - tol)


def segments(points, n):
    t = np.linspace(0.0, 1.0, n + 1)[1:, None]
    out = []
    prev = np.zeros(6)
    for p in points:
        out.append(prev + t * (p - prev))
        prev = p
    return np.concatenate(out)


@SETTINGS
@given(prm=material(), n=direction(), amp=amplitude, h=size)
def test_monotonic_paths(prm, n, amp, h):
    hist = segments([amp * n], 30)
    _S, states = run(prm, hist, h)
    check_monotone(states)


@SETTINGS
@given(
    prm=material(),
    a=direction(),
    b=direction(),
    c=direction(),
    amp=amplitude,
    f=st.floats(0.2, 2.0),
    h=size,
)
def test_cyclic_nonproportional_paths(prm, a, b, c, amp, f, h):
    """Damages never decrease, and a return mapping that reports convergence (status 0, as
    ``run`` asserts) leaves the effective stress in the admissible set: Rankine and
    Drucker-Prager hold to the tolerance (a Drucker-Prager excluded on one pass must be
    admitted again when the final stress violates it)."""
    hist = segments([amp * a, -f * amp * b, amp * c, np.zeros(6)], 15)
    _S, states = run(prm, hist, h)
    check_monotone(states)
    for state in states[1:]:
        assert drucker_prager_excess(prm, state) <= 0.0


@SETTINGS
@given(
    prm=material(nu_max=0.0, beta_le_delta=True),
    n=direction(),
    amp=amplitude,
    ra=st.floats(-2.0, 2.0),
    rb=st.floats(-2.0, 2.0),
    h=size,
)
def test_closed_proportional_cycle_dissipates(prm, n, amp, ra, rb, h):
    """Work of 0 -> a n -> b n -> a n -> 0 (J/m^3) >= -(reclosure bound 3 REF^2/E) within the
    quadrature error (module docstring)."""
    assume(abs(ra) > 0.05)
    hist = segments([amp * ra * n, amp * rb * n, amp * ra * n, np.zeros(6)], 40)
    S, states = run(prm, hist, h)
    check_monotone(states)
    E = np.vstack([np.zeros(6), hist])
    dW = np.sum(0.5 * (S[1:] + S[:-1]) * np.diff(E, axis=0), axis=1)
    gross = float(np.sum(np.abs(dW)))
    bound = 3.0 * prm[m.P_REF] ** 2 / prm[m.P_E]
    assert dW.sum() >= -bound - 1e-3 * gross, (dW.sum(), gross, bound)


def test_shear_cycle_states_are_admissible():
    """The yz shear cycle of test_return_mapping_converges_in_shear_with_dilatancy with
    beta = delta = 0 (associated): on the way back (step 16) the return mapping closes a crack
    and, on the same pass, Drucker-Prager's multiplier comes out negative; dropping it for good
    would leave f_D far above the tolerance with status 0. The stress is admissible at every
    step and lambda_D non-decreasing."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prm = m.endo3d_params(E=1e6, nu=0.0, R_t=1e3, eps_pic_t=1e-3, G_ft=1.0,
                              R_c=1.77827941e3, eps_pic_c=0.1, delta=0.0, beta=0.0, eps_kdc=0.1,
                              DCPK=0.5, REF=100.0, GFR=1.0)
    hist = segments([0.1 * np.eye(6)[3], -0.1 * np.eye(6)[3], np.zeros(6)], 15)
    _S, states = run(prm, hist, 0.5)
    assert all(drucker_prager_excess(prm, st_) <= 0.0 for st_ in states[1:])
    assert np.all(np.diff(states[:, m.S_LAMBDA_D]) >= 0.0)


@pytest.mark.xfail(
    strict=True,
    reason="model.md section 3 as specified: non-proportional "
    "closed cycles can return more work than they received (see module doc)",
)
def test_nonproportional_cycle_can_release_energy():
    """Known property of the specified law, kept visible: the study's parameters, a cube of
    0.1 m, the strain cycle 0 -> A -> B -> 0 (amplitudes 2.6e-5, in the 'elastic' range where
    only d_cpp evolves) gives a negative work of about -1.2 % of the gross work, independent of
    the step (the same with 10 times more steps)."""
    rng = np.random.default_rng(0)
    for _ in range(10):  # the 10th draw of the exploration that found it
        amp = 10 ** rng.uniform(-5, -1.7)
        A = rng.normal(size=6)
        A *= amp / np.linalg.norm(A)
        B = rng.normal(size=6)
        B *= amp * rng.uniform(0.2, 2) / np.linalg.norm(B)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prm = m.endo3d_params(
            E=11.1e9,
            nu=0.2,
            R_t=1e6,
            eps_pic_t=0.9009e-4,
            G_ft=60.0,
            R_c=9.46e6,
            eps_pic_c=0.013,
            delta=0.4,
            beta=0.2,
            eps_kdc=0.018,
            DCPK=1.0,
            REF=0.3e6,
            GFR=4.5,
        )
    hist = segments([A, B, np.zeros(6)], 200)
    S, _ = run(prm, hist, 0.1)
    E = np.vstack([np.zeros(6), hist])
    dW = np.sum(0.5 * (S[1:] + S[:-1]) * np.diff(E, axis=0), axis=1)
    assert dW.sum() >= -1e-3 * np.sum(np.abs(dW))


def test_module_constants():
    assert m.N_STATE == len(m.endo3d_initial_state())
    assert math.isclose(m.elastic_matrix(1.0, 0.0)[0, 0], 1.0)


def test_a_strain_whose_active_set_corrections_cycle_ends_admissible():
    """The return mapping's last resort, the search over the active sets
    (``endo3d._search_active_sets``), on a state and a strain where the cutting-plane passes and
    their corrections of the active set cycle. Found by a random search of strain paths (twelve
    random increments from the virgin state, the study's parameters with a 5 mm crushing band,
    an element 0.15 x 0.05 x 0.15 m; the kernels run as Python with a counter on the search).
    The point it returns must be converged and admissible: updated again at the same strain
    from that state, the trial is elastic, so the apparent stress and the state are the same
    (but the iteration count)."""
    from masonry_nscd.fe import hex8

    eps = np.array([0.00013498221383425203, 0.004918595128487089, 0.005627258660139776,
                    -2.088304788845283e-05, 0.0008167246299402223, 0.0032169738736691766])
    nonzero = {
        0: -262590.27066690195, 1: 964840.4734097002, 2: 997749.7972572016,
        3: 8894.721084383664, 4: -53301.82070140859, 5: 210694.27185893455,
        6: 0.004324067040847104, 7: 0.004491370562891839, 8: 0.003603689717826517,
        9: -0.0003655986169628828, 10: 0.0006698619632163756, 11: 0.001205863618731003,
        18: 0.000786189998426393, 19: 0.0007218801792320251, 20: 0.0008149501439235777,
        21: -0.00020652369085084876, 22: 7.969373164170678e-05, 23: 0.00015589999878542387,
        24: 0.0009360701347669755, 25: 0.0008545675005470412, 26: 0.000693823715864998,
        27: -0.0002967987181952513, 28: 0.00024242648224126267, 29: 3.464982407422772e-05,
        31: 0.6967864645891405, 33: 0.997611948612715, 34: 0.9963661722002652,
        35: 0.9815161754192515, 36: 0.0011678050531300406, 37: 5.0}
    state = np.zeros(m.N_STATE)
    for i, v in nonzero.items():
        state[i] = v
    prm = m.endo3d_params(E=11.1e9, nu=0.2, R_t=1.0e6, eps_pic_t=1.0e6 / 11.1e9, G_ft=60.0,
                          R_c=9.46e6, eps_pic_c=0.013, delta=0.4, beta=0.2, eps_kdc=0.018,
                          DCPK=1.0, REF=0.3e6, GFR=4.5, crushing_length=0.005)
    X, conn = hex8.box_mesh(np.zeros(3), np.array([0.15, 0.05, 0.15]), (1, 1, 1))
    xe = np.ascontiguousarray(X[conn[0]])
    out, sigma = np.empty(m.N_STATE), np.empty(6)
    assert m.endo3d_update(eps, state, prm, xe, out, sigma) == 0
    again, sigma_again = np.empty(m.N_STATE), np.empty(6)
    assert m.endo3d_update(eps, out, prm, xe, again, sigma_again) == 0
    np.testing.assert_allclose(sigma_again, sigma, rtol=0.0, atol=1e-12 * np.max(np.abs(sigma)))
    keep = np.arange(m.N_STATE) != m.S_ITER
    np.testing.assert_allclose(again[keep], out[keep], rtol=1e-9, atol=0.0)
