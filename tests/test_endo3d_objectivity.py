"""ENDO3D over the whole parameter ranges of the case schema, and under rotations (hypothesis).

Completes tests/test_endo3d_properties.py (NaN, monotone damages and energy over the ranges of
a typical stone):

* the kernel's ``endo3d_params`` accepts every parameter set that the schema (``case.Blocks``
  with ENDO3D) accepts, so that a case that validates never fails when the scene is built;
* over the schema's ranges, monotonic and cyclic strain paths give finite stresses and states
  and damages that never decrease;
* objectivity: the same strain history turned by a rotation R, applied to the element turned
  by R (the Hillerborg lengths follow the element), gives the stresses turned by R and the
  same damages - until a crack opens (cracked states are not objective yet: an xfail test
  keeps an example).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from test_endo3d_properties import check_monotone, direction, material, segments

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
    hypothesis skips the example (a known failure, see test_round_off_peak_plastic_strain)."""
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
    to the step where a crack opens (W_max > 0): cracked states are not objective yet, see
    test_cracked_state_is_objective."""
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


@pytest.mark.xfail(strict=True, reason="ENDO3D with cracks is not objective (issue 7, reported)")
def test_cracked_state_is_objective():
    """Found by test_objective_under_rotation (before it stopped at the first crack): a cube
    of 0.5 m sheared in xy to gamma = 0.01 (one crack), then towards -0.01 in xz; the same
    history turned by pi about y (cube turned with it) gives stresses off by 4.0e4 Pa (of
    2.3e5) at the first step of the second leg. With random rotations and paths, 26 of 400
    cracked histories differ by 1e-3 to 12 % of the stresses. Likely cause (not checked): the
    per-axis choices made in the eigenbasis of W or W_max, whose eigenvalues are repeated (0,
    0) while only one crack is open: ``W_max,ii := max(W_max,ii, w_i)`` and the reclosure's
    ``w_i,cur`` depend on the basis picked in the degenerate plane."""
    prm = _study_like(E=1e9, R_t=3e5, eps_pic_t=3e-4, G_ft=5.0, R_c=1.5e6, eps_pic_c=1.5e-3,
                      delta=0.0, beta=0.0, eps_kdc=0.03125, DCPK=0.0, REF=3e5, GFR=1.0)
    e_xy, e_xz = np.eye(6)[5], np.eye(6)[4]
    hist = segments([0.01 * e_xy, -0.01 * e_xz, 0.01 * e_xy], 12)
    R = np.diag([-1.0, 1.0, -1.0])
    S, _ = run_in(prm, hist, cube_nodes(0.5))
    S_r, _ = run_in(prm, _turn_strains(R, hist), np.ascontiguousarray(cube_nodes(0.5) @ R.T))
    expected = np.array([_voigt(R @ _tensor(s, False) @ R.T, False) for s in S])
    assert np.abs(S_r - expected).max() <= 1e-6 * np.abs(S).max()


@pytest.mark.xfail(strict=True, reason="return mapping not converged, its iterate has a negative "
                   "cumulated multiplier (issue 7, reported)")
def test_return_mapping_converges_in_shear_with_dilatancy():
    """Found by test_whole_schema_range_cyclic_paths: a yz shear to 0.1 and back with
    beta = 1.5 > delta = 0 (allowed by the schema, with a warning of the kernel): at
    gamma = 0.0467 on the way back the return mapping stops with status 1 and writes
    lambda_D = -0.126 and sigma_xx = 655 Pa (the strain has no xx part, nu = 0); the steps
    after it, from that state, oscillate in sign."""
    prm = _study_like(E=1e6, R_t=1e3, eps_pic_t=1e-3, G_ft=1.0, R_c=1.77827941e3,
                      eps_pic_c=0.1, delta=0.0, beta=1.5, eps_kdc=0.1, DCPK=0.5, REF=100.0,
                      GFR=1.0)
    hist = segments([0.1 * np.eye(6)[3], -0.1 * np.eye(6)[3], np.zeros(6)], 15)
    state = m.endo3d_initial_state()
    sig = np.empty(6)
    for eps in hist[:19]:
        new = np.empty(m.N_STATE)
        assert m.endo3d_update(np.ascontiguousarray(eps), state, prm, cube_nodes(0.5), new,
                               sig) == 0
        assert new[m.S_LAMBDA_D] >= 0.0
        state = new


@pytest.mark.xfail(strict=True, reason="endo3d_params leaves a round-off plastic strain at the "
                   "peak (issue 7, reported)")
def test_round_off_peak_plastic_strain():
    """Found by test_objective_under_rotation_until_a_crack_opens (return mapping status 1 on a
    compressive path): when the cap DCPK does not bind, the peak is reached without plastic
    strain, but ``eps_pl,pk = eps_pic_c - R_c,eff / E`` with ``R_c,eff = E eps_pic_c`` is
    5.4e-20 here (E eps / E != eps in floating point, for about 1 value in 10), so
    lambda_pk = 9.4e-20 and the hardening slope 2 (C_max - C_min) / lambda_pk ~ 2.6e26 Pa."""
    prm = _study_like(E=46889313201.390625, R_t=3832408.5, eps_pic_t=8.173309093992743e-05,
                      G_ft=5.0, R_c=19162042.5, eps_pic_c=0.0004469778410777281, delta=0.0,
                      beta=0.0, eps_kdc=0.03125, DCPK=1.0, REF=3832408.5, GFR=1.0)
    assert prm[m.P_D_PIC] > 0.0  # the cap does not bind: d_pic = 1 - R_c / (E eps_pic_c)
    assert prm[m.P_EPS_PL_PK] == 0.0 and prm[m.P_LAMBDA_PK] == 0.0


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
