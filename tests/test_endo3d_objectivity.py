"""ENDO3D over the whole parameter ranges of the case schema, and under rotations (hypothesis).

Completes tests/test_endo3d_properties.py (NaN, monotone damages and energy over the ranges of
a typical stone):

* the kernel's ``endo3d_params`` accepts every parameter set that the schema (``case.Blocks``
  with ENDO3D) accepts, so that a case that validates never fails when the scene is built;
* over the schema's ranges, monotonic and cyclic strain paths give finite stresses and states
  and damages that never decrease;
* objectivity: the same strain history turned by a rotation R, applied to the element turned
  by R (the Hillerborg lengths follow the element), gives the stresses turned by R and the
  same damages, before and after cracks open (choices made per direction in a repeated
  eigenspace take their basis from the state). A rare residual, a sensitivity of
  the law near crack closure to differences at the return mapping's tolerance, is kept as an
  xfail example (test_cracked_state_objectivity_residual).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_endo3d_properties import (
    check_monotone,
    direction,
    drucker_prager_excess,
    material,
    segments,
)

from masonry_nscd.case import CaseError, case_from_dict
from masonry_nscd.materials import endo3d as m
from masonry_nscd.materials.point_driver import cube_nodes, params_from_case

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
SQRT3 = math.sqrt(3.0)


def _log(lo: float, hi: float):
    return st.floats(math.log10(lo), math.log10(hi)).map(lambda x: 10.0**x)


@st.composite
def schema_blocks(draw) -> dict:
    """A ``blocks`` section with ENDO3D parameters drawn across the schema's bounds."""
    E = draw(_log(1e6, 1e13))
    R_t = draw(_log(1e3, 1e9))
    R_c = R_t * draw(_log(1.0, 1e3))
    return {
        "material": "endo3d",
        "E_Pa": E,
        "nu": draw(st.floats(-0.99, 0.49)),
        "endo3d": {
            "R_t_Pa": R_t,
            "eps_pic_t": R_t / E if R_t / E < 1.0 else 0.5,
            "G_ft_J_m2": draw(_log(1e-3, 1e6)),
            "R_c_Pa": min(R_c, 1e10),
            "eps_pic_c": draw(_log(1e-7, 0.99)),
            "delta": draw(st.floats(0.0, SQRT3 * 0.999)),
            "beta": draw(st.floats(0.0, SQRT3 * 0.999)),
            "eps_kdc": draw(_log(1e-6, 0.99)),
            "DCPK": draw(st.one_of(st.sampled_from([0.0, 1.0]), st.floats(0.0, 1.0))),
            "REF_Pa": draw(_log(1e2, 1e9)),
            "GFR_J_m2": draw(_log(1e-3, 1e6)),
        },
    }


def _kernel_params(blocks: dict):
    """``endo3d_params`` of a blocks section, or the ValueError it raises."""
    e = blocks["endo3d"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return m.endo3d_params(
                E=blocks["E_Pa"], nu=blocks["nu"], R_t=e["R_t_Pa"], eps_pic_t=e["eps_pic_t"],
                G_ft=e["G_ft_J_m2"], R_c=e["R_c_Pa"], eps_pic_c=e["eps_pic_c"],
                delta=e["delta"], beta=e["beta"], eps_kdc=e["eps_kdc"], DCPK=e["DCPK"],
                REF=e["REF_Pa"], GFR=e["GFR_J_m2"])
        except ValueError as exc:
            return exc


@SETTINGS
@given(blocks=schema_blocks())
def test_schema_accepts_what_the_kernel_accepts(blocks):
    try:
        case = case_from_dict({"blocks": blocks})
    except CaseError:
        accepted = False
    else:
        accepted = True
    kernel = _kernel_params(blocks)
    # the schema may be stricter (it asks R_t < R_c, the kernel R_t < R_c,eff >= R_c)
    if accepted:
        assert not isinstance(kernel, ValueError), kernel
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert np.array_equal(params_from_case(case), kernel)


@st.composite
def schema_params(draw):
    """ENDO3D parameters of a blocks section that the schema accepts."""
    try:
        case = case_from_dict({"blocks": draw(schema_blocks())})
    except CaseError:
        assume(False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return params_from_case(case)


def _strain_scale(p) -> float:
    """Strain of the tensile peak and of the compressive one, whichever is larger."""
    return max(p[m.P_RT] / p[m.P_E], p[m.P_EPS_PIC_C])


@SETTINGS
@given(prm=schema_params(), a=direction(), b=direction(), amp=st.floats(-1.0, 1.5),
       f=st.floats(0.2, 2.0), h=st.floats(0.02, 0.5))
def test_whole_schema_range_cyclic_paths(prm, a, b, amp, f, h):
    """Up to 30 times the peak strains, there and back: finite stresses and states; damages
    that never decrease, up to a step where the return mapping reports that it did not
    converge (status 1 or 2: its last iterate is written and the caller is to retry the step,
    so the history is not followed further)."""
    e = _strain_scale(prm) * 10.0**amp
    assume(e < 0.5)
    hist = segments([e * a, -f * e * b, np.zeros(6)], 15)
    xe = cube_nodes(h)
    state = m.endo3d_initial_state()
    sig = np.empty(6)
    states = [state]
    for eps in hist:
        new = np.empty(m.N_STATE)
        status = m.endo3d_update(np.ascontiguousarray(eps), state, prm, xe, new, sig)
        assert status in (0, 1, 2)
        assert np.isfinite(sig).all() and np.isfinite(new).all()
        if status != 0:
            break
        states.append(new)
        state = new
    states = np.array(states)
    # the crack damages come from the eigenvalues of W_max (round-off 1e-16 |W_max|, m) through
    # dd/dw <= 2 / w_k, w_k = G_ft / R_t down to 1e-15 m in these ranges: scale the tolerance
    w_max = np.abs(states[:, m.S_W_MAX:m.S_W_MAX + 6]).max()
    tol_t = 1e-9 + 1e-14 * w_max / prm[m.P_W_K]
    d_t = states[:, m.S_D_T:m.S_D_T + 3]
    assert np.all(np.diff(d_t, axis=0) >= -tol_t)
    states[:, m.S_D_T:m.S_D_T + 3] = np.maximum.accumulate(d_t, axis=0)  # checked above
    check_monotone(states)


# --------------------------------------------------------------------------------------------
# Objectivity
# --------------------------------------------------------------------------------------------


def _tensor(v: np.ndarray, engineering: bool) -> np.ndarray:
    """Symmetric 3x3 tensor of a Voigt vector [xx, yy, zz, yz, xz, xy]."""
    s = 0.5 if engineering else 1.0
    return np.array([[v[0], s * v[5], s * v[4]], [s * v[5], v[1], s * v[3]],
                     [s * v[4], s * v[3], v[2]]])


def _voigt(t: np.ndarray, engineering: bool) -> np.ndarray:
    s = 2.0 if engineering else 1.0
    return np.array([t[0, 0], t[1, 1], t[2, 2], s * t[1, 2], s * t[0, 2], s * t[0, 1]])


def _turn_strains(R: np.ndarray, hist: np.ndarray) -> np.ndarray:
    return np.array([_voigt(R @ _tensor(e, True) @ R.T, True) for e in hist])


@st.composite
def rotation(draw) -> np.ndarray:
    """A rotation matrix from a random unit quaternion."""
    q = np.array([draw(st.floats(-1.0, 1.0)) for _ in range(4)])
    n = np.linalg.norm(q)
    assume(n > 0.1)
    w, x, y, z = q / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def run_in(prm, hist, xe, *, converged: bool = True):
    """Drive one point of the element of nodes ``xe`` (8, 3), m, along ``hist``: stresses (Pa)
    and states per step. ``converged``: assert that every return mapping converged; else
    hypothesis skips the example (status 1 remains possible with beta > delta, which
    material() draws and the case schema refuses)."""
    state = m.endo3d_initial_state()
    sig = np.empty(6)
    S, states = [], []
    for e in hist:
        new = np.empty(m.N_STATE)
        status = m.endo3d_update(np.ascontiguousarray(e), state, prm, xe, new, sig)
        if converged:
            assert status == 0
        else:
            assume(status == 0)
        S.append(sig.copy())
        states.append(new)
        state = new
    return np.array(S), np.array(states)


SCALARS = (m.S_D_C, m.S_D_CPP, m.S_D_T, m.S_D_T + 1, m.S_D_T + 2, m.S_W_OPEN_MAX, m.S_LAMBDA_D)


@SETTINGS
@given(prm=material(), R=rotation(), a=direction(), b=direction(),
       amp=st.floats(-5.0, -2.0).map(lambda x: 10.0**x), f=st.floats(0.2, 2.0),
       h=st.floats(0.02, 0.5))
def test_objective_under_rotation_until_a_crack_opens(prm, R, a, b, amp, f, h):
    """Elasticity, Drucker-Prager plasticity and compressive damage are objective. Compared up
    to the step where a crack opens (W_max > 0), with hypothesis' directions; cracked states are
    compared by test_cracked_histories_are_objective."""
    hist = segments([amp * a, -f * amp * b, amp * a], 12)
    xe = cube_nodes(h)
    S, states = run_in(prm, hist, xe, converged=False)
    S_r, states_r = run_in(prm, _turn_strains(R, hist), np.ascontiguousarray(xe @ R.T),
                           converged=False)
    cracked = (states[:, m.S_W_OPEN_MAX] > 0.0) | (states_r[:, m.S_W_OPEN_MAX] > 0.0)
    n = int(np.argmax(cracked)) if cracked.any() else len(hist)
    assume(n > 0)
    S, states, S_r, states_r = S[:n], states[:n], S_r[:n], states_r[:n]
    expected = np.array([_voigt(R @ _tensor(s, False) @ R.T, False) for s in S])
    # the return mapping converges to 1e-8 max(R_t, R_c,eff, REF) (Pa) and the principal
    # directions of nearly equal principal stresses are ill-defined: compare at that scale
    tol = 1e-6 * max(prm[m.P_RC_EFF], np.abs(S).max())
    assert np.abs(S_r - expected).max() <= tol
    for k in SCALARS:  # damages (dimensionless), opening (m), multiplier: round-off floors
        floor = 1e-15 if k == m.S_W_OPEN_MAX else 1e-12
        tol_k = 1e-6 * np.abs(states[:, k]).max() + floor
        assert np.abs(states_r[:, k] - states[:, k]).max() <= tol_k, k


def _study_like(**kw) -> np.ndarray:
    values = {"E": 11.1e9, "nu": 0.0, "R_t": 1e6, "eps_pic_t": 0.9009e-4, "G_ft": 60.0,
              "R_c": 9.46e6, "eps_pic_c": 0.013, "delta": 0.4, "beta": 0.2, "eps_kdc": 0.018,
              "DCPK": 1.0, "REF": 0.3e6, "GFR": 4.5}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return m.endo3d_params(**(values | kw))


def _turn_back(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """6 tensor components (no factor 2) turned by R^T."""
    return _voigt(R.T @ _tensor(v, False) @ R, False)


def _compare_frames(prm, hist, xe, R):
    """Stresses of ``hist`` on the element ``xe`` and of the turned history on the turned
    element: (largest difference of the stresses turned back / largest stress, largest
    difference of the scalar states relative to their largest value beyond the round-off
    floors of test_objective_under_rotation_until_a_crack_opens, the runs)."""
    S, states = run_in(prm, hist, xe)
    S_r, states_r = run_in(prm, _turn_strains(R, hist), np.ascontiguousarray(xe @ R.T))
    expected = np.array([_voigt(R @ _tensor(s, False) @ R.T, False) for s in S])
    d_sig = np.abs(S_r - expected).max() / max(prm[m.P_RC_EFF], np.abs(S).max())
    d_state = 0.0
    for k in SCALARS:
        floor = 1e-15 if k == m.S_W_OPEN_MAX else 1e-12
        excess = np.abs(states_r[:, k] - states[:, k]).max() - floor
        d_state = max(d_state, excess / (np.abs(states[:, k]).max() + 1e-300))
    return d_sig, d_state, (S, states, S_r, states_r)


def test_cracked_state_is_objective():
    """A cube of 0.5 m sheared in xy to gamma = 0.01 (one crack), then towards -0.01 in xz,
    and the same history turned by pi about y (cube turned with it): the stresses turned back
    agree, also at the first step of the second leg, where the crack's basis matters.

    Why it could differ: W_max has the eigenvalues (0, 0, 1.1e-3 m) (one crack) and the
    current W, whose crack has turned, has terms of 1e-6 m in the plane of the repeated 0: the
    reclosure's w_i,cur, the diagonal of W in the eigenbasis of W_max, would depend on the
    basis the eigen solver picks in that plane, and so would rho_i and the compressive stress
    across it (4.0e4 Pa of 2.3e5 between the frames). So a repeated eigenspace of W_max
    gets the basis that diagonalises W there (then the element's edges), and likewise for the
    other per-direction choices in repeated eigenspaces (trial stress: eps_pR, W, edges; W in
    the W_max update: W_max, edges). Objective to round-off, damages included."""
    prm = _study_like(E=1e9, R_t=3e5, eps_pic_t=3e-4, G_ft=5.0, R_c=1.5e6, eps_pic_c=1.5e-3,
                      delta=0.0, beta=0.0, eps_kdc=0.03125, DCPK=0.0, REF=3e5, GFR=1.0)
    e_xy, e_xz = np.eye(6)[5], np.eye(6)[4]
    hist = segments([0.01 * e_xy, -0.01 * e_xz, 0.01 * e_xy], 12)
    R = np.diag([-1.0, 1.0, -1.0])
    d_sig, d_state, (S, states, _S_r, states_r) = _compare_frames(prm, hist, cube_nodes(0.5), R)
    assert states[:, m.S_W_OPEN_MAX].max() > 0.0  # cracked
    assert d_sig <= 1e-6 * np.abs(S).max() / max(prm[m.P_RC_EFF], np.abs(S).max())
    assert d_state <= 1e-6
    for off in (m.S_W, m.S_W_MAX, m.S_EPS_PR):
        turned = np.array([_turn_back(R, v[off:off + 6]) for v in states_r])
        assert np.abs(turned - states[:, off:off + 6]).max() <= 1e-9 * np.abs(
            states[:, off:off + 6]).max()


_SPECIAL_TURNS = (np.diag([-1.0, 1.0, -1.0]), np.diag([1.0, -1.0, -1.0]),
                  np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
                  np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))


def _random_direction(rng) -> np.ndarray:
    """A unit strain direction: generic, or along the axes, or with two equal normal strains
    (repeated principal values), or a pure engineering shear."""
    kind = rng.integers(4)
    v = rng.uniform(-1.0, 1.0, 6)
    if kind == 1:
        v[3:] = 0.0
    elif kind == 2:
        v[:3] = rng.uniform(-1.0, 1.0)
        v[3:] = 0.0
        v[rng.integers(3)] += rng.uniform(-1.0, 1.0)
    elif kind == 3:
        v[:] = 0.0
        v[3 + rng.integers(3)] = rng.choice([-1.0, 1.0])
    return v / np.linalg.norm(v)


def _random_case(rng):
    """Material (ranges of test_endo3d_properties.material, beta <= delta, nu = 0 for half
    the draws), rotation (random, or a half or quarter turn about an axis), element size and
    path a -> -f b -> c -> 0 (12 steps per leg); None when endo3d_params refuses the draw."""
    E = rng.uniform(1e9, 5e10)
    R_t = rng.uniform(0.3e6, 5e6)
    R_c = R_t * rng.uniform(5.0, 30.0)
    delta = rng.uniform(0.0, 0.8)
    kw = {"E": E, "nu": rng.choice([0.0, rng.uniform(0.0, 0.45)]), "R_t": R_t,
          "eps_pic_t": R_t / E, "G_ft": rng.uniform(5.0, 300.0), "R_c": R_c,
          "eps_pic_c": R_c / E * rng.uniform(0.5, 30.0), "delta": delta,
          "beta": delta * rng.uniform(0.0, 1.0), "eps_kdc": rng.uniform(1e-3, 5e-2),
          "DCPK": rng.uniform(0.0, 1.0), "REF": R_t * rng.uniform(0.05, 1.0),
          "GFR": rng.uniform(0.5, 20.0)}
    if rng.uniform() < 0.5:
        R = _SPECIAL_TURNS[rng.integers(len(_SPECIAL_TURNS))]
    else:
        q = rng.uniform(-1.0, 1.0, 4)
        w, x, y, z = q / np.linalg.norm(q)
        R = np.array([
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])
    a, b, c = _random_direction(rng), _random_direction(rng), _random_direction(rng)
    amp = 10.0 ** rng.uniform(-4.5, -2.0)
    f = rng.uniform(0.2, 2.0)
    h = rng.uniform(0.02, 0.5)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            prm = m.endo3d_params(**kw)
    except ValueError:
        return None
    return prm, R, segments([amp * a, -f * amp * b, amp * c, np.zeros(6)], 12), cube_nodes(h)


def test_cracked_histories_are_objective():
    """150 cracked histories drawn with a fixed seed (deterministic), many of them through
    repeated eigenvalues (strains along the axes, two equal normal strains, pure shears; half
    and quarter turns, which keep a diagonal tensor diagonal): stresses and damages turned
    with the element agree to round-off. With the eigen solver's basis in repeated
    eigenspaces about one such history in four would differ; with the basis taken from the
    state, the rare residual of test_cracked_state_objectivity_residual is not in this
    sample."""
    rng = np.random.default_rng(0)
    n = 0
    while n < 150:
        case = _random_case(rng)
        if case is None:
            continue
        prm, R, hist, xe = case
        d_sig, d_state, (_S, states, _S_r, _st_r) = _compare_frames(prm, hist, xe, R)
        if not states[:, m.S_W_OPEN_MAX].max() > 0.0:
            continue
        n += 1
        assert d_sig <= 1e-6 and d_state <= 1e-6, (n, d_sig, d_state)


@pytest.mark.xfail(strict=True, reason="residual: sensitivity near crack closure")
def test_cracked_state_objectivity_residual():
    """The residual of objectivity: a rare history of test_cracked_histories_are_objective's
    generator (none with generic directions), a sensitivity of the law to the
    differences that the return mapping's tolerance (1e-8 max(R_t, R_c,eff, REF)) leaves
    between the two frames; no choice of basis in a repeated eigenspace is involved.

    This one: the frames agree to 1.6e-14 up to step 40; from step 41 the difference grows by
    1e1 to 1e3 per step: 7.5e-12, 2.7e-10, 1.3e-7 of the stresses, 3.3e-6 at the end, and
    4.7e-4 on a damage (the smallest crack of W_max). A crack closes there (reclosure,
    r_i = e_i . eps_pR . e_i down to 1e-9) while |eps_pR| ~ 2e-3 is not coaxial with the
    stress: r_i is a small difference of large terms, along a direction e_i that the state
    fixes to about 1e-6 rad only (the trial principal stresses are 7.6e4 Pa apart), and the
    closure decision (r_i + dlambda_i < 0) amplifies the difference; a tolerance 1e4 times
    smaller still leaves 2e-4 on the damage.

    The other one: two principal trial stresses 0.035 Pa apart (4e-9 of them: below the
    tolerance, 0.13 Pa, but not repeated to round-off) have directions that the state does
    not fix, and their reclosures differ (2e-4 of the stresses). Counting such stresses as
    repeated would make the elastic stress inexact by up to the tolerance, with which the bar
    of test_bar_localisation_energy does not converge. Not fixed: ill-conditioning of the law,
    not of the kernel's choices."""
    prm = _study_like(E=44141621431.093124, nu=0.07530702256385323, R_t=2834527.2478444823,
                      eps_pic_t=6.421438895871316e-05, G_ft=88.63967539745457,
                      R_c=34256349.9312529, eps_pic_c=0.017282629885891444,
                      delta=0.7053092702536282, beta=0.26457780586556456,
                      eps_kdc=0.014408335783380459, DCPK=0.9238230897151699,
                      REF=470391.1082309651, GFR=8.62498768297892)
    R = np.array([[0.7285677456316662, 0.21105343322817194, -0.6516482857706244],
                  [-0.6838891168726765, 0.2776465277809088, -0.6746911007522745],
                  [0.038532010696333274, 0.9372133449400979, 0.34662145089115737]])
    a = np.array([-0.4974700031115845, -0.3380975435580651, -0.40567076067283603,
                  0.16952347424810382, -0.4679382408795576, -0.4753319633484397])
    b = np.array([-0.697563376445598, 0.13626261997246447, -0.7034471083457923, 0.0, 0.0, 0.0])
    c = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    amp, f, h = 0.005863908978244308, 1.9898718372690922, 0.2023595263848279
    hist = segments([amp * a, -f * amp * b, amp * c, np.zeros(6)], 12)
    d_sig, d_state, _runs = _compare_frames(prm, hist, cube_nodes(h), R)
    assert d_sig <= 1e-6 and d_state <= 1e-6, (d_sig, d_state)


def test_return_mapping_converges_in_shear_with_dilatancy():
    """A yz shear to 0.1 and back with beta = 1.5 > delta = 0 (the kernel accepts it with a
    warning): every step returns status 0, lambda_D never decreases and Drucker-Prager holds.

    What it checks: from the first step, Rankine + Drucker-Prager give a negative
    Drucker-Prager multiplier; a Drucker-Prager excluded for the step and never admitted again
    would end the step with status 0 and f_D many orders above the tolerance (the effective
    stress at 28 R_c with lambda_D = 0), and a written lambda_D could decrease (the strain has
    no xx part and nu = 0, so sigma_xx must stay 0). The return mapping (module docstring of
    endo3d) makes one correction of the active set per pass, admits again an excluded surface
    that the final stress violates, accepts only a Kuhn-Tucker point, then searches the active
    sets by closest points; the written lambda_D never decreases, also when it fails.

    Decision on beta > delta: the Drucker-Prager flow dissipates dlambda (C + (delta - beta) p)
    (J/m^3), negative at pressures p > C/(beta - delta): the law creates energy, and here the
    converged answer ratchets the effective pressure up by about 4 kPa per step of the shear
    cycle (to 200 kPa = 110 R_c at the end), lambda_D growing while the shear goes back. The
    case schema refuses beta > delta (blocks.endo3d.beta, 0 <= beta <= delta);
    endo3d_params still accepts it with a warning, for studies of the kernel, which converges
    here and never writes a negative multiplier."""
    prm = _study_like(E=1e6, R_t=1e3, eps_pic_t=1e-3, G_ft=1.0, R_c=1.77827941e3,
                      eps_pic_c=0.1, delta=0.0, beta=1.5, eps_kdc=0.1, DCPK=0.5, REF=100.0,
                      GFR=1.0)
    hist = segments([0.1 * np.eye(6)[3], -0.1 * np.eye(6)[3], np.zeros(6)], 15)
    state = m.endo3d_initial_state()
    sig = np.empty(6)
    lam = [0.0]
    for eps in hist:
        new = np.empty(m.N_STATE)
        assert m.endo3d_update(np.ascontiguousarray(eps), state, prm, cube_nodes(0.5), new,
                               sig) == 0
        assert new[m.S_LAMBDA_D] >= lam[-1]
        assert drucker_prager_excess(prm, new) <= 0.0
        lam.append(new[m.S_LAMBDA_D])
        state = new
    blocks = {"material": "endo3d", "E_Pa": 1e6, "nu": 0.0,
              "endo3d": {"R_t_Pa": 1e3, "eps_pic_t": 1e-3, "G_ft_J_m2": 1.0,
                         "R_c_Pa": 1.77827941e3, "eps_pic_c": 0.1, "delta": 0.0, "beta": 1.5,
                         "eps_kdc": 0.1, "DCPK": 0.5, "REF_Pa": 100.0, "GFR_J_m2": 1.0}}
    with pytest.raises(CaseError, match=r"blocks\.endo3d\.beta.*0 <= beta <= delta"):
        case_from_dict({"blocks": blocks})
    blocks["endo3d"]["beta"] = 0.0  # beta = delta: accepted
    case_from_dict({"blocks": blocks})


def test_round_off_peak_plastic_strain():
    """When the cap DCPK does not bind, the peak is reached without plastic strain: the
    computed ``eps_pl,pk = eps_pic_c - R_c,eff / E`` with ``R_c,eff = E eps_pic_c`` would be
    5.4e-20 here (E eps / E != eps in floating point, for about 1 value in 10), so
    lambda_pk = 9.4e-20 and the hardening slope 2 (C_max - C_min) / lambda_pk ~ 2.6e26 Pa, and
    the return mapping could fail on a compressive path. So eps_pl,pk = 0 exactly when the cap
    does not bind, and a plastic peak strain below 16 machine epsilons of eps_pic_c (round-off of the difference when DCPK is within a
    few ulps of 1 - R_c/(E eps_pic_c)) is set to zero."""
    prm = _study_like(E=46889313201.390625, R_t=3832408.5, eps_pic_t=8.173309093992743e-05,
                      G_ft=5.0, R_c=19162042.5, eps_pic_c=0.0004469778410777281, delta=0.0,
                      beta=0.0, eps_kdc=0.03125, DCPK=1.0, REF=3832408.5, GFR=1.0)
    assert prm[m.P_D_PIC] > 0.0  # the cap does not bind: d_pic = 1 - R_c / (E eps_pic_c)
    assert prm[m.P_EPS_PL_PK] == 0.0 and prm[m.P_LAMBDA_PK] == 0.0
    # a cap 1 ulp below 1 - R_c/(E eps_pic_c) binds: its eps_pl,pk is round-off too
    thr = 1.0 - 19162042.5 / (46889313201.390625 * 0.0004469778410777281)
    prm = _study_like(E=46889313201.390625, R_t=3832408.5, eps_pic_t=8.173309093992743e-05,
                      G_ft=5.0, R_c=19162042.5, eps_pic_c=0.0004469778410777281, delta=0.0,
                      beta=0.0, eps_kdc=0.03125, DCPK=np.nextafter(thr, 0.0), REF=3832408.5,
                      GFR=1.0)
    assert prm[m.P_EPS_PL_PK] == 0.0 and prm[m.P_LAMBDA_PK] == 0.0


def test_small_peak_plastic_strain_return_mapping_converges():
    """A genuine but small plastic strain at the peak (cap DCPK binding just below
    1 - R_c/(E eps_pic_c): eps_pl,pk = 1e-10 eps_pic_c, lambda_pk = 7.7e-14, cohesion from
    C_min to C_max over that range of lambda_D). The return mapping's iterates with a negative
    multiplier increment would evaluate the parabola C(lambda_D) below 0 (cohesion -1e17 Pa,
    slope 3e20 Pa), or a cohesion jumping between C_min and C_max within the round-off of
    lambda_n + dlambda, and fail (status 1 on this path). The cohesion of such iterates is the
    tangent at the start of the step: every step converges and lambda_D never decreases."""
    thr = 1.0 - 19162042.5 / (46889313201.390625 * 0.0004469778410777281)
    prm = _study_like(E=46889313201.390625, R_t=3832408.5, eps_pic_t=8.173309093992743e-05,
                      G_ft=5.0, R_c=19162042.5, eps_pic_c=0.0004469778410777281, delta=0.0,
                      beta=0.0, eps_kdc=0.03125, DCPK=thr - 1e-10 * (1.0 - thr),
                      REF=3832408.5, GFR=1.0)
    assert 0.0 < prm[m.P_LAMBDA_PK] < 1e-12
    a = np.array([-0.835, -0.47, -0.125, 0.068, -0.136, -0.206])
    b = np.array([-0.578, 0.506, -0.276, 0.421, 0.391, 0.069])
    hist = segments([1.366e-3 * a, -1.366e-3 * b, 1.366e-3 * a], 12)
    _S, states = run_in(prm, hist, cube_nodes(0.1))
    assert np.all(np.diff(states[:, m.S_LAMBDA_D]) >= 0.0) and states[-1, m.S_LAMBDA_D] > 0.0


@pytest.mark.parametrize("angle", [math.pi / 2, math.pi / 5])
def test_uniaxial_tension_turned_about_z(angle):
    """Past the tensile peak along x, and the same along a direction turned about z (the cube
    turned with it): the same axial stress and tensile damage."""
    prm = _study_like()
    hist = np.outer(np.linspace(0.0, 4e-4, 41)[1:], [1, 0, 0, 0, 0, 0])
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    S, states = run_in(prm, hist, cube_nodes(0.1))
    S_r, states_r = run_in(prm, _turn_strains(R, hist), np.ascontiguousarray(cube_nodes(0.1) @ R.T))
    axial = np.array([R[:, 0] @ _tensor(v, False) @ R[:, 0] for v in S_r])
    assert states[-1, m.S_D_T] > 0.5  # well past the peak
    assert np.allclose(axial, S[:, 0], rtol=1e-9, atol=1e-3)
    assert np.allclose(states_r[:, m.S_D_T], states[:, m.S_D_T], rtol=1e-9, atol=1e-12)
