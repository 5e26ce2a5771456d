r"""ENDO3D: damage and plasticity of the stone blocks, one Gauss point at a time.

This module implements section 3 of ``docs/model.md`` (shared documentation). Conventions:
compression negative for stresses and strains; SI units (Pa, m, J/m^2, dimensionless strains).

Concept
-------
Plasticity is written on the *effective* (undamaged) stress and never softens; all softening is
damage applied afterwards to the effective stress.

Effective stress (Pa), isotropic elasticity ``C0`` (E in Pa, nu):

    s~ = C0 : (eps - eps_pR - eps_pD),   K = E / (3 (1 - 2 nu)),  G = E / (2 (1 + nu)),
    lam = K - 2G/3 (Lame),  M = K + 4G/3 (oedometric modulus)

Plastic criteria on the principal effective stresses ``s_i`` (directions ``e_i``):

* Rankine (cracking), for ``s_i >= 0``:  ``f_i = s_i - R_t``,  ``d eps_pR = dlam_i e_i (x) e_i``.
* Crack reclosure, for ``s_i < 0`` while ``e_i . eps_pR . e_i > 0``: ``f_i = s_i + REF``; the
  multiplier is negative and is capped so that ``e_i . eps_pR . e_i`` never becomes negative.
* Drucker-Prager (skipped when the three Rankine criteria are active):
  ``f_D = sqrt(J2) - delta p - C(lambda_D)``, ``p = -tr(s~)/3`` (Pa), non-associated flow
  ``d eps_pD = dlam_D (s_dev / (2 sqrt(J2)) + beta/3 1)`` (so ``tr d eps_pD = beta dlam_D``).
* Cohesion hardening (Pa): ``C = C_min + (C_max - C_min)(2x - x^2)``, ``x = lambda_D/lambda_pk``
  for ``x < 1``, ``C = C_max`` afterwards (and always when ``lambda_pk = 0``), with
  ``C_min = R_t delta``, ``C_max = R_c,eff (1/sqrt(3) - delta/3)``.
* Peak quantities: if ``DCPK > 0`` and ``eps_pic_c > R_c/E``:
  ``d_pic = min(DCPK, 1 - R_c/(E eps_pic_c))``, ``R_c,eff = R_c/(1 - d_pic)``; otherwise
  ``d_pic = 0``, ``eps_pic_c := R_c/E``, ``R_c,eff = R_c``.  ``eps_pl,pk = eps_pic_c - R_c,eff/E``,
  ``lambda_pk = 3 eps_pl,pk / (sqrt(3) - beta)``.

Return mapping (cutting plane, in the principal basis of the trial effective stress, which all
flows share): a criterion violated by more than the tolerance becomes active and stays active
(consistency condition ``f = 0``) for the rest of the pass; at each iteration the active ones are
linearised at the current stress and the multiplier increments solved from

    Rankine/Rankine:   J_ij = M (i = j),  lam (i != j)
    Rankine i / DP:    J_iD = G dev_i / sqrt(J2) + K beta,   J_Di = G dev_i / sqrt(J2) + delta K
    DP/DP:             J_DD = G + K beta delta + H,   H = dC/dlambda_D

(one Rankine alone: ``dlam = f/(K + 4G/3)``; DP alone: ``dlam_D = f_D/(G + K beta delta + H)``).
When no criterion is violated by more than ``1e-8 max(R_t, R_c,eff, REF)`` (Pa), the cumulative
multipliers of the pass are checked: a criterion whose multiplier has the wrong sign is dropped
and the pass restarts from the trial stress; a reclosure that would make ``e_i . eps_pR . e_i``
negative is replaced by the full closure of that direction (prescribed increment) and the pass
restarts. A singular or ill-conditioned system (a multiplier increment above 1) involving
Drucker-Prager drops Drucker-Prager for the step (choice: the Rankine/reclosure block is always
regular; the degeneracy appears when the DP flow, once the other constraints are enforced, no
longer changes f_D). The kernel returns status 1 (state still written) when a pass does not converge in
``MAX_RETURN_ITER`` iterations or after 8 restarts, 2 when a linear system is singular.

Damage (Hillerborg regularisation)
----------------------------------
* Crack opening tensor ``W`` (m): ``dW = sum_i dlam_i L_i e_i (x) e_i`` over the Rankine
  multiplier increments of the step (reclosure ones are negative), ``L_i`` (m) the extent of the
  element along ``e_i`` (max minus min of the projections of its 8 nodes); then the negative
  eigenvalues of ``W`` are clipped to zero.
* ``W_max`` (m): written in the eigenbasis of the new ``W``, its diagonal terms become
  ``max(W_max,ii, w_i)``; its off-diagonal terms are kept (choice: this keeps ``W_max``
  positive semi-definite and makes its eigenvalues non-decreasing, Weyl's inequality). The
  crack basis is the eigenbasis of ``W_max``, with eigenvalues ``w_i``.
* Tensile damage per crack: ``d_t,i = 1 - (w_k/(w_k + w_i))^2``, ``w_k = G_ft/R_t`` (m).
* Reclosure: ``rho_i = (w_r/(w_r + w_i,cur))^2``, ``w_r = GFR/REF`` (m), with ``w_i,cur`` the
  diagonal term of the current ``W`` in the crack basis (choice).
* Pre-peak compressive damage: ``s_eq = max(0, sqrt(J2) - delta p)``, ``x = min(1, s_eq/C_max)``;
  ``d_cpp = d_pic x`` while ``0 < lambda_D < lambda_pk``, else ``d_pic x^((1-d_pic)/d_pic)``
  (``0`` when ``d_pic = 0``); irreversible (running maximum).
* Post-peak compressive damage: ``kappa = tr(eps_pD) - beta lambda_pk``,
  ``d_c = kappa/(kappa + eps_kdc)`` for ``kappa > 0``; irreversible.

Apparent stress
---------------
``s~ = s+ + s-`` (positive and negative principal parts). Each part is damaged in the crack basis
``(n_1, n_2, n_3)`` by the operator ``D[d]``: a normal compliance ``c_k = d_k/((1-d_k) M)`` in
series per crack, i.e. with ``T = P^T S P`` the normal stresses solve
``sigma_kk + sum_l D0_kl c_l sigma_ll = T_kk`` (``D0_kl = M`` for k = l, ``lam`` otherwise; solved
in the form ``(1-d_k) y_k + sum_l (D0_kl/M) d_l y_l = T_kk``, ``sigma_kk = (1-d_k) y_k``, finite
for ``d = 1``), and the shear terms ``T_kl`` are multiplied by ``1 - min(d_k, d_l)``.  Tensile
damage acts on ``s+`` with ``d_k = d_t,k``; reclosure acts on ``s-`` with ``d_k = 1 - rho_k``
(choice: the same series-compliance operator). Then

    sigma = (1 - d_c) (D[d_t](s+) + (1 - d_cpp) D[1 - rho](s-))      (Pa)

With nu = 0 a single crack gives ``sigma_nn = (1 - d_t) s~_nn``; with nu > 0 the series crack
also relieves the lateral stresses through the Poisson coupling (this is what makes the nu = 0.2
softening curve of model.md lower than the nu = 0 one).

Tangent for the global iterations: the elastic ``C0`` (:func:`elastic_matrix`) is the iteration
matrix, as in the reference implementation; the kernels do not compute a consistent tangent.

Not used: ``eps_pic_t`` (the tensile peak of this law is at ``R_t/E``); it is stored in the
parameter vector for the record and :func:`endo3d_params` warns when it differs from ``R_t/E``.

Properties of the law as specified (checked in tests/test_endo3d*.py)
---------------------------------------------------------------------
* Energy of a crack band of size h (m), uniaxial tension: the post-peak integral of
  ``sigma d eps`` is ``G_ft/h`` (J/m^3) for nu = 0, and ``G_ft/h - nu^2/(1-nu) R_t^2/E`` for
  nu > 0 (the series crack relieves the lateral effective stresses); the total work to complete
  failure is ``G_ft/h + R_t^2/(2E)`` per unit volume: the elastic energy at the peak is also
  dissipated, by the damage, because the effective stress stays at ``R_t``. A bar of
  cross-section A therefore dissipates ``A G_ft + A h R_t^2/(2E)``, which tends to ``A G_ft``
  as the localising element gets small.
* ``s_eq = sqrt(J2) - delta p`` is positive in tension as well: a tensile history raises
  ``d_cpp`` (0.68 at the tensile peak with the study's parameters); it acts on compressive
  stresses only.
* Drucker-Prager is also skipped when reclosure/closure constraints fix the remaining principal
  stresses (three Rankine-type constraints: the stress is prescribed, f_D cannot be enforced).
* Not derived from a potential: with nu > 0 the principal split of the effective stress, and the
  recovery of ``rho`` at ``s~ = -REF``, can make a closed strain cycle return more work than it
  received (up to ``REF^2/(2E)`` per direction and closure for the latter); with
  ``beta > delta`` the Drucker-Prager flow dissipates ``dlam (C + (delta - beta) p) < 0`` at
  high pressure (:func:`endo3d_params` warns).

Data layout (plain float64 arrays, for numba)
---------------------------------------------
* Strain input ``eps`` (6,): Voigt ``[xx, yy, zz, yz, xz, xy]`` with ENGINEERING shear strains
  (``gamma_yz = 2 eps_yz``). Stress output ``sigma`` (6,): same order, true shear stresses (Pa).
* Parameter vector: see the ``P_*`` index constants and :func:`endo3d_params`.
* State vector (``N_STATE``,): see the ``S_*`` index constants. Tensor-valued internal variables
  (effective stress, plastic strains, crack openings) are stored as 6 TENSOR components in the
  order ``[xx, yy, zz, yz, xz, xy]`` (no factor 2 on the shear terms).

All kernels live in this module (numba ``cache=True`` serves stale code when a cached kernel
calls a kernel of another, edited, module).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = [
    "N_PARAMS",
    "N_STATE",
    "elastic_matrix",
    "endo3d_initial_state",
    "endo3d_outputs",
    "endo3d_params",
    "endo3d_update",
    "endo3d_update_all",
    "endo3d_update_elements",
]

FloatArray = NDArray[np.float64]

# --------------------------------------------------------------------------------------------
# Parameter vector layout
# --------------------------------------------------------------------------------------------
P_E = 0  # Young's modulus (Pa)
P_NU = 1  # Poisson's ratio (-)
P_RT = 2  # tensile strength R_t (Pa)
P_EPS_PIC_T = 3  # tensile peak strain (-), stored only
P_GFT = 4  # tensile fracture energy G_ft (J/m^2)
P_RC = 5  # compressive strength R_c (Pa)
P_EPS_PIC_C = 6  # compressive peak strain (-), after the ":= R_c/E" rule
P_DELTA = 7  # Drucker-Prager confinement coefficient (-)
P_BETA = 8  # Drucker-Prager dilatancy coefficient (-)
P_EPS_KDC = 9  # post-peak compressive damage strain scale (-)
P_DCPK = 10  # cap on the pre-peak compressive damage (-)
P_REF = 11  # crack reclosure stress (Pa)
P_GFR = 12  # crack reclosure energy (J/m^2)
P_K = 13  # bulk modulus (Pa)
P_G = 14  # shear modulus (Pa)
P_LAME = 15  # Lame's lambda (Pa)
P_M = 16  # K + 4G/3 (Pa)
P_D_PIC = 17  # pre-peak compressive damage at the peak (-)
P_RC_EFF = 18  # effective compressive strength R_c / (1 - d_pic) (Pa)
P_EPS_PL_PK = 19  # uniaxial plastic strain at the compressive peak (-)
P_LAMBDA_PK = 20  # Drucker-Prager multiplier at the peak (-)
P_C_MIN = 21  # initial cohesion R_t delta (Pa)
P_C_MAX = 22  # cohesion at the peak R_c,eff (1/sqrt3 - delta/3) (Pa)
P_W_K = 23  # G_ft / R_t (m)
P_W_R = 24  # GFR / REF (m)
P_EXP_CPP = 25  # (1 - d_pic)/d_pic, exponent of the pre-peak damage (0 if d_pic = 0)
P_TOL = 26  # absolute tolerance of the return mapping (Pa)
N_PARAMS = 27

# --------------------------------------------------------------------------------------------
# State vector layout
# --------------------------------------------------------------------------------------------
S_SIG_EFF = 0  # effective stress s~, 6 tensor components (Pa)
S_EPS_PR = 6  # Rankine plastic strain, 6 tensor components (-)
S_EPS_PD = 12  # Drucker-Prager plastic strain, 6 tensor components (-)
S_W = 18  # current crack opening tensor W, 6 tensor components (m)
S_W_MAX = 24  # maximal crack opening tensor W_max, 6 tensor components (m)
S_LAMBDA_D = 30  # cumulated Drucker-Prager multiplier (-)
S_D_CPP = 31  # pre-peak compressive damage (-)
S_D_C = 32  # post-peak compressive damage (-)
S_D_T = 33  # tensile damages of the three cracks, sorted in decreasing order (3 values, -)
S_W_OPEN_MAX = 36  # largest eigenvalue of W_max (m)
S_ITER = 37  # return-mapping iterations of the last update (-)
N_STATE = 38

#: Maximal number of cutting-plane iterations of the return mapping.
MAX_RETURN_ITER = 100

_SQRT3 = math.sqrt(3.0)


# --------------------------------------------------------------------------------------------
# Parameters and state (plain Python)
# --------------------------------------------------------------------------------------------


def endo3d_params(
    E: float,
    nu: float,
    R_t: float,
    eps_pic_t: float,
    G_ft: float,
    R_c: float,
    eps_pic_c: float,
    delta: float,
    beta: float,
    eps_kdc: float,
    DCPK: float,
    REF: float,
    GFR: float,
) -> FloatArray:
    """Parameter vector of the ENDO3D kernels, with the derived quantities precomputed.

    Arguments in SI units: ``E``, ``R_t``, ``R_c``, ``REF`` in Pa; ``G_ft``, ``GFR`` in J/m^2;
    ``nu``, ``eps_pic_t``, ``eps_pic_c``, ``delta``, ``beta``, ``eps_kdc``, ``DCPK``
    dimensionless. Raises ``ValueError`` for values outside the range where the law is defined
    (E, R_t, G_ft, R_c, REF, GFR, eps_kdc > 0; -1 < nu < 0.5; 0 <= delta, beta < sqrt 3;
    0 <= DCPK <= 1; R_t < R_c,eff; C_min <= C_max). Warns when ``eps_pic_t`` differs from
    ``R_t/E`` by more than 1 % (the law ignores it: its tensile peak is at ``R_t/E``) and when
    ``beta > delta`` (negative plastic dissipation at pressures above ``C/(beta - delta)``).
    Returns a float64 vector of length ``N_PARAMS`` indexed by the ``P_*`` constants.
    """
    vals = {
        "E": E,
        "nu": nu,
        "R_t": R_t,
        "eps_pic_t": eps_pic_t,
        "G_ft": G_ft,
        "R_c": R_c,
        "eps_pic_c": eps_pic_c,
        "delta": delta,
        "beta": beta,
        "eps_kdc": eps_kdc,
        "DCPK": DCPK,
        "REF": REF,
        "GFR": GFR,
    }
    for name, v in vals.items():
        if not math.isfinite(float(v)):
            raise ValueError(f"endo3d: {name} must be finite, got {v!r}")
    for name in ("E", "R_t", "G_ft", "R_c", "REF", "GFR", "eps_kdc", "eps_pic_c"):
        if not vals[name] > 0.0:
            raise ValueError(f"endo3d: {name} must be > 0, got {vals[name]!r}")
    if not -1.0 < nu < 0.5:
        raise ValueError(f"endo3d: nu must be in (-1, 0.5), got {nu!r}")
    for name in ("delta", "beta"):
        if not 0.0 <= vals[name] < _SQRT3:
            raise ValueError(f"endo3d: {name} must be in [0, sqrt 3), got {vals[name]!r}")
    if not 0.0 <= DCPK <= 1.0:
        raise ValueError(f"endo3d: DCPK must be in [0, 1], got {DCPK!r}")
    if beta > delta:
        warnings.warn(
            f"endo3d: beta = {beta!r} > delta = {delta!r}: the Drucker-Prager flow dissipates "
            "dlambda (C + (delta - beta) p), negative at high pressure",
            stacklevel=2,
        )
    if abs(eps_pic_t - R_t / E) > 0.01 * R_t / E:
        warnings.warn(
            f"endo3d: eps_pic_t = {eps_pic_t:.6g} differs from R_t/E = {R_t / E:.6g}; the law "
            "reaches its tensile peak at R_t/E and does not use eps_pic_t",
            stacklevel=2,
        )

    E = float(E)
    nu = float(nu)
    K = E / (3.0 * (1.0 - 2.0 * nu))
    G = E / (2.0 * (1.0 + nu))
    lame = K - 2.0 * G / 3.0
    M = K + 4.0 * G / 3.0

    if DCPK > 0.0 and eps_pic_c > R_c / E:
        eps_c = eps_pic_c
        if DCPK >= 1.0 - R_c / (E * eps_pic_c):
            # cap not binding: the peak is reached without plastic strain (lambda_pk = 0);
            # written so that round-off cannot leave a tiny positive eps_pl,pk
            d_pic = 1.0 - R_c / (E * eps_pic_c)
            rc_eff = E * eps_pic_c
        else:
            d_pic = DCPK
            rc_eff = R_c / (1.0 - d_pic)
    else:
        d_pic = 0.0
        eps_c = R_c / E
        rc_eff = R_c
    eps_pl_pk = max(0.0, eps_c - rc_eff / E)
    lambda_pk = 3.0 * eps_pl_pk / (_SQRT3 - beta)
    c_min = R_t * delta
    c_max = rc_eff * (1.0 / _SQRT3 - delta / 3.0)
    if not R_t < rc_eff:
        raise ValueError(f"endo3d: R_t = {R_t!r} must be lower than R_c,eff = {rc_eff!r}")
    if not c_min <= c_max:
        raise ValueError(
            f"endo3d: the initial cohesion R_t delta = {c_min:.6g} Pa exceeds the peak cohesion "
            f"R_c,eff (1/sqrt3 - delta/3) = {c_max:.6g} Pa; lower delta or R_t"
        )
    exp_cpp = (1.0 - d_pic) / d_pic if d_pic > 0.0 else 0.0

    p = np.zeros(N_PARAMS, dtype=np.float64)
    p[P_E] = E
    p[P_NU] = nu
    p[P_RT] = R_t
    p[P_EPS_PIC_T] = eps_pic_t
    p[P_GFT] = G_ft
    p[P_RC] = R_c
    p[P_EPS_PIC_C] = eps_c
    p[P_DELTA] = delta
    p[P_BETA] = beta
    p[P_EPS_KDC] = eps_kdc
    p[P_DCPK] = DCPK
    p[P_REF] = REF
    p[P_GFR] = GFR
    p[P_K] = K
    p[P_G] = G
    p[P_LAME] = lame
    p[P_M] = M
    p[P_D_PIC] = d_pic
    p[P_RC_EFF] = rc_eff
    p[P_EPS_PL_PK] = eps_pl_pk
    p[P_LAMBDA_PK] = lambda_pk
    p[P_C_MIN] = c_min
    p[P_C_MAX] = c_max
    p[P_W_K] = G_ft / R_t
    p[P_W_R] = GFR / REF
    p[P_EXP_CPP] = exp_cpp
    p[P_TOL] = 1e-8 * max(R_t, rc_eff, REF)
    return p


def endo3d_initial_state() -> FloatArray:
    """Virgin state of one Gauss point: all ``N_STATE`` entries zero (no stress, no plastic
    strain, no crack, no damage)."""
    return np.zeros(N_STATE, dtype=np.float64)


def endo3d_outputs(
    state: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per-point outputs for the result files, from a state array ``(ngp, N_STATE)`` (or one
    state ``(N_STATE,)``): ``(d_c, d_cpp, d_t_max, crack_opening_max)``, the post-peak and
    pre-peak compressive damages, the largest tensile damage and the largest eigenvalue of the
    maximal crack opening tensor ``W_max`` (m)."""
    st = np.atleast_2d(np.asarray(state, dtype=np.float64))
    return (
        st[:, S_D_C].copy(),
        st[:, S_D_CPP].copy(),
        st[:, S_D_T].copy(),
        st[:, S_W_OPEN_MAX].copy(),
    )


# --------------------------------------------------------------------------------------------
# Small linear-algebra kernels (3x3), all in this module
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def elastic_matrix(E: float, nu: float) -> FloatArray:
    """Isotropic elastic matrix C0 (6x6, Pa) in Voigt order [xx, yy, zz, yz, xz, xy] acting on
    ENGINEERING shear strains: C11 = lam + 2G, C12 = lam, C44 = G. This is also the iteration
    matrix the global solver uses for ENDO3D blocks (no consistent tangent)."""
    G = E / (2.0 * (1.0 + nu))
    lam = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu))
    C = np.zeros((6, 6))
    for i in range(3):
        for j in range(3):
            C[i, j] = lam
        C[i, i] = lam + 2.0 * G
        C[3 + i, 3 + i] = G
    return C


@njit(cache=True)
def _from6(v, off, A):
    """Symmetric 3x3 ``A`` from 6 tensor components ``v[off:off+6]`` (xx, yy, zz, yz, xz, xy)."""
    A[0, 0] = v[off]
    A[1, 1] = v[off + 1]
    A[2, 2] = v[off + 2]
    A[1, 2] = v[off + 3]
    A[2, 1] = v[off + 3]
    A[0, 2] = v[off + 4]
    A[2, 0] = v[off + 4]
    A[0, 1] = v[off + 5]
    A[1, 0] = v[off + 5]


@njit(cache=True)
def _to6(A, v, off):
    """6 tensor components of the symmetric part of ``A`` into ``v[off:off+6]``."""
    v[off] = A[0, 0]
    v[off + 1] = A[1, 1]
    v[off + 2] = A[2, 2]
    v[off + 3] = 0.5 * (A[1, 2] + A[2, 1])
    v[off + 4] = 0.5 * (A[0, 2] + A[2, 0])
    v[off + 5] = 0.5 * (A[0, 1] + A[1, 0])


@njit(cache=True)
def _eig_sym3(A, w, V):
    """Eigenvalues ``w`` and eigenvectors (columns of ``V``) of a symmetric 3x3 ``A`` by cyclic
    Jacobi rotations (accurate to round-off, also for repeated eigenvalues). ``A`` is untouched.
    """
    a = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            a[i, j] = 0.5 * (A[i, j] + A[j, i])
            V[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(40):
        off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
        dia = a[0, 0] * a[0, 0] + a[1, 1] * a[1, 1] + a[2, 2] * a[2, 2]
        if off == 0.0 or off <= 1e-34 * dia:
            break
        for k in range(3):
            if k == 0:
                p, q = 0, 1
            elif k == 1:
                p, q = 0, 2
            else:
                p, q = 1, 2
            apq = a[p, q]
            if apq == 0.0:
                continue
            theta = (a[q, q] - a[p, p]) / (2.0 * apq)
            t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
            if theta < 0.0:
                t = -t
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            for r in range(3):
                arp = a[r, p]
                arq = a[r, q]
                a[r, p] = c * arp - s * arq
                a[r, q] = s * arp + c * arq
            for r in range(3):
                apr = a[p, r]
                aqr = a[q, r]
                a[p, r] = c * apr - s * aqr
                a[q, r] = s * apr + c * aqr
            a[p, q] = 0.0
            a[q, p] = 0.0
            for r in range(3):
                vrp = V[r, p]
                vrq = V[r, q]
                V[r, p] = c * vrp - s * vrq
                V[r, q] = s * vrp + c * vrq
    for i in range(3):
        w[i] = a[i, i]


@njit(cache=True)
def _solve_small(A, b, n, x):
    """Solve the leading ``n x n`` block ``A x = b`` by Gauss elimination with partial
    pivoting (``A`` and ``b`` are overwritten). Returns False when singular."""
    for k in range(n):
        piv = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                piv = i
        if big == 0.0:
            return False
        if piv != k:
            for j in range(n):
                tmp = A[k, j]
                A[k, j] = A[piv, j]
                A[piv, j] = tmp
            tmp = b[k]
            b[k] = b[piv]
            b[piv] = tmp
        for i in range(k + 1, n):
            f = A[i, k] / A[k, k]
            if f != 0.0:
                for j in range(k, n):
                    A[i, j] -= f * A[k, j]
                b[i] -= f * b[k]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[i, j] * x[j]
        x[i] = acc / A[i, i]
    return True


@njit(cache=True)
def _extent(xe, V, i):
    """Extent (m) of the element with nodes ``xe`` (8, 3) along the unit column ``V[:, i]``:
    max minus min of the node projections."""
    lo = np.inf
    hi = -np.inf
    for n in range(xe.shape[0]):
        pr = xe[n, 0] * V[0, i] + xe[n, 1] * V[1, i] + xe[n, 2] * V[2, i]
        lo = min(lo, pr)
        hi = max(hi, pr)
    return hi - lo


@njit(cache=True)
def _cohesion(lam_d, prm):
    """Drucker-Prager cohesion C (Pa) and its slope H = dC/dlambda_D (Pa) at ``lam_d``."""
    c_min = prm[P_C_MIN]
    c_max = prm[P_C_MAX]
    lpk = prm[P_LAMBDA_PK]
    if lpk > 0.0 and lam_d < lpk:
        x = lam_d / lpk
        return c_min + (c_max - c_min) * (2.0 * x - x * x), (c_max - c_min) * 2.0 * (1.0 - x) / lpk
    return c_max, 0.0


@njit(cache=True)
def _crack_damage(S, P, d, nup, out):
    """Damage a stress tensor ``S`` (3x3, Pa) by cracks of damages ``d`` (3,) along the columns
    of ``P``: series normal compliance ``d_k/((1-d_k) M)`` per crack and shear terms multiplied
    by ``1 - min(d_k, d_l)`` in the crack basis. ``nup = lam/M = nu/(1-nu)``. Result in ``out``.
    """
    if d[0] <= 0.0 and d[1] <= 0.0 and d[2] <= 0.0:
        for i in range(3):
            for j in range(3):
                out[i, j] = S[i, j]
        return
    T = np.zeros((3, 3))
    for k in range(3):
        for m in range(3):
            acc = 0.0
            for i in range(3):
                for j in range(3):
                    acc += P[i, k] * S[i, j] * P[j, m]
            T[k, m] = acc
    A = np.empty((3, 3))
    b = np.empty(3)
    y = np.empty(3)
    for k in range(3):
        for m in range(3):
            A[k, m] = (1.0 if k == m else nup) * d[m]
        A[k, k] += 1.0 - d[k]
        b[k] = T[k, k]
    _solve_small(A, b, 3, y)
    for k in range(3):
        T[k, k] = (1.0 - d[k]) * y[k]
    for k in range(3):
        for m in range(k + 1, 3):
            f = 1.0 - min(d[k], d[m])
            T[k, m] *= f
            T[m, k] *= f
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                for m in range(3):
                    acc += P[i, k] * T[k, m] * P[j, m]
            out[i, j] = acc


# --------------------------------------------------------------------------------------------
# The Gauss-point kernel
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def endo3d_update(eps, state_in, params, xe, state_out, sigma):
    """Update one Gauss point from ``state_in`` to the total strain ``eps``.

    ``eps`` (6,): total strain, Voigt [xx, yy, zz, yz, xz, xy], engineering shear (-).
    ``state_in`` (N_STATE,): converged state of the previous step (read only).
    ``params`` (N_PARAMS,): from :func:`endo3d_params`.
    ``xe`` (8, 3): node coordinates (m) of the hexahedron, for the Hillerborg lengths.
    ``state_out`` (N_STATE,): written. ``sigma`` (6,): apparent stress (Pa), true shear, written.
    Returns 0, or 1 when the return mapping did not converge in ``MAX_RETURN_ITER`` iterations
    or 8 restarts, or 2 when its linear system was (numerically) singular; in both cases the
    last iterate is written and the caller should retry the step (e.g. with a smaller one).
    """
    E_lame = params[P_LAME]
    G = params[P_G]
    K = params[P_K]
    M = params[P_M]
    rt = params[P_RT]
    ref = params[P_REF]
    delta = params[P_DELTA]
    beta = params[P_BETA]
    tol = params[P_TOL]
    status = 0

    # ---- trial effective stress ------------------------------------------------------------
    epsR = np.empty((3, 3))
    epsD = np.empty((3, 3))
    _from6(state_in, S_EPS_PR, epsR)
    _from6(state_in, S_EPS_PD, epsD)
    ee = np.empty((3, 3))
    ee[0, 0] = eps[0]
    ee[1, 1] = eps[1]
    ee[2, 2] = eps[2]
    ee[1, 2] = 0.5 * eps[3]
    ee[2, 1] = 0.5 * eps[3]
    ee[0, 2] = 0.5 * eps[4]
    ee[2, 0] = 0.5 * eps[4]
    ee[0, 1] = 0.5 * eps[5]
    ee[1, 0] = 0.5 * eps[5]
    for i in range(3):
        for j in range(3):
            ee[i, j] -= epsR[i, j] + epsD[i, j]
    tr_e = ee[0, 0] + ee[1, 1] + ee[2, 2]
    s_tr = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            s_tr[i, j] = 2.0 * G * ee[i, j]
        s_tr[i, i] += E_lame * tr_e
    s = np.empty(3)
    Q = np.empty((3, 3))
    _eig_sym3(s_tr, s, Q)

    # Rankine plastic strain in the principal directions (for the reclosure criterion)
    r = np.empty(3)
    for i in range(3):
        acc = 0.0
        for k in range(3):
            for m in range(3):
                acc += Q[k, i] * epsR[k, m] * Q[m, i]
        r[i] = acc

    # ---- return mapping (cutting plane, principal space) ---------------------------------------
    # mode[i] (i < 3): 1 Rankine tension, -1 crack reclosure, 0 inactive on principal direction
    # i; mode[3]: 1 Drucker-Prager active. A surface gets a mode when it is violated and keeps it
    # (consistency condition f = 0) until the end of the pass; after convergence a surface whose
    # cumulative multiplier has the wrong sign is excluded and the pass restarts from the trial
    # stress; a reclosure that would make e_i . eps_pR . e_i negative is replaced by the full
    # closure of that direction (prescribed increment -r_i) and the pass restarts.
    lam_d_n = state_in[S_LAMBDA_D]
    s_trial = s.copy()
    dlR = np.zeros(3)
    dlD = 0.0
    depD = np.zeros(3)
    mode = np.zeros(4, dtype=np.int64)
    excl_t = np.zeros(3, dtype=np.bool_)
    excl_r = np.zeros(3, dtype=np.bool_)
    excl_d = False
    closed = np.zeros(3, dtype=np.bool_)
    kind = np.zeros(4, dtype=np.int64)
    Jm = np.empty((4, 4))
    fv = np.empty(4)
    xs = np.empty(4)
    dev = np.empty(3)
    nD = np.empty(3)
    xR = np.empty(3)
    # an opening below this strain is round-off (r_i is a projection of the tensor eps_pR)
    open_tol = 1e-10 * rt / params[P_E]
    n_iter = 0
    status = 1
    for _restart in range(8):
        tr_f = 0.0
        for i in range(3):
            s[i] = s_trial[i]
            dlR[i] = -r[i] if closed[i] else 0.0
            depD[i] = 0.0
            mode[i] = 0
            tr_f += dlR[i]
        for i in range(3):
            s[i] -= E_lame * tr_f + 2.0 * G * dlR[i]
        mode[3] = 0
        dlD = 0.0
        converged = False
        singular = False
        for _it in range(MAX_RETURN_ITER):
            n_iter += 1
            C, H = _cohesion(lam_d_n + dlD, params)
            mean = (s[0] + s[1] + s[2]) / 3.0
            for i in range(3):
                dev[i] = s[i] - mean
            q = math.sqrt(0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]))
            fD = q + delta * mean - C  # sqrt(J2) - delta p - C, p = -mean

            violated = False
            for i in range(3):
                if closed[i]:
                    continue
                if mode[i] == 1:
                    if abs(s[i] - rt) > tol:
                        violated = True
                elif mode[i] == -1:
                    if abs(s[i] + ref) > tol:
                        violated = True
                elif s[i] - rt > tol and not excl_t[i]:
                    mode[i] = 1
                    violated = True
                elif s[i] + ref < -tol and r[i] + dlR[i] > open_tol and not excl_r[i]:
                    mode[i] = -1
                    violated = True
            ntens = 0
            for i in range(3):
                if mode[i] != 0 or closed[i]:
                    ntens += 1
            if ntens == 3:
                # Drucker-Prager skipped when the three Rankine criteria are active (and, by
                # extension, when reclosure or closure fixes the remaining principal stresses:
                # the three principal stresses are then prescribed and f_D cannot be enforced)
                mode[3] = 0
            elif mode[3] == 1:
                if abs(fD) > tol:
                    violated = True
            elif fD > tol and not excl_d:
                mode[3] = 1
                violated = True
            if not violated:
                converged = True
                break

            qpos = q > 1e-14 * (abs(mean) + rt)
            n = 0
            for i in range(3):
                if mode[i] != 0:
                    kind[n] = i
                    n += 1
            if mode[3] == 1:
                kind[n] = 3
                n += 1
            for a in range(n):
                ka = kind[a]
                if ka < 3:
                    fv[a] = s[ka] - rt if mode[ka] == 1 else s[ka] + ref
                    for b in range(n):
                        kb = kind[b]
                        if kb < 3:
                            Jm[a, b] = M if ka == kb else E_lame
                        else:
                            Jm[a, b] = (G * dev[ka] / q if qpos else 0.0) + K * beta
                else:
                    fv[a] = fD
                    for b in range(n):
                        kb = kind[b]
                        if kb < 3:
                            Jm[a, b] = (G * dev[kb] / q if qpos else 0.0) + delta * K
                        else:
                            Jm[a, b] = (G if qpos else 0.0) + K * beta * delta + H
            if not _solve_small(Jm, fv, n, xs):
                singular = True
                break
            for a in range(n):
                # a multiplier increment above 1 (a strain of 100 %) or not finite: the system
                # is numerically singular
                if not abs(xs[a]) <= 1.0:
                    singular = True
            if singular:
                break
            for i in range(3):
                xR[i] = 0.0
            xD = 0.0
            for a in range(n):
                if kind[a] < 3:
                    xR[kind[a]] = xs[a]
                else:
                    xD = xs[a]
            if xD > 0.0 and qpos and G * xD > q:
                xD = q / G  # do not go past the apex of the cone
            for i in range(3):
                nD[i] = (dev[i] / (2.0 * q) if qpos else 0.0) + beta / 3.0
            tr_de = 0.0
            for i in range(3):
                tr_de += xR[i] + xD * nD[i]
            for i in range(3):
                s[i] -= E_lame * tr_de + 2.0 * G * (xR[i] + xD * nD[i])
                dlR[i] += xR[i]
                depD[i] += xD * nD[i]
            dlD += xD
        if singular:
            if mode[3] == 1 and not excl_d:
                # the Rankine/reclosure block (diagonal M, off-diagonal lam) is always regular:
                # the degeneracy comes with Drucker-Prager (its flow no longer changes f_D once
                # the other constraints are enforced); redo the pass without it
                excl_d = True
                continue
            status = 2
            break
        if not converged:
            status = 1
            break
        redo = False
        for i in range(3):
            if mode[i] == 1 and dlR[i] < 0.0:
                excl_t[i] = True
                redo = True
            elif mode[i] == -1:
                if dlR[i] > 0.0:
                    excl_r[i] = True
                    redo = True
                elif r[i] + dlR[i] < -open_tol:
                    closed[i] = True
                    redo = True
        if dlD < 0.0 or (mode[3] == 0 and dlD != 0.0):
            # wrong sign, or Drucker-Prager flowed and was then skipped (three Rankine-type
            # constraints): redo the pass without it
            excl_d = True
            redo = True
        if not redo:
            status = 0
            break

    # ---- plastic strains, effective stress -------------------------------------------------------
    lam_d = lam_d_n + dlD
    for i in range(3):
        for j in range(3):
            accR = 0.0
            accD = 0.0
            accS = 0.0
            for k in range(3):
                qq = Q[i, k] * Q[j, k]
                accR += dlR[k] * qq
                accD += depD[k] * qq
                accS += s[k] * qq
            epsR[i, j] += accR
            epsD[i, j] += accD
            s_tr[i, j] = accS  # converged effective stress
    for k in range(N_STATE):
        state_out[k] = state_in[k]
    _to6(s_tr, state_out, S_SIG_EFF)
    _to6(epsR, state_out, S_EPS_PR)
    _to6(epsD, state_out, S_EPS_PD)
    state_out[S_LAMBDA_D] = lam_d
    state_out[S_ITER] = n_iter

    # ---- crack openings ------------------------------------------------------------------------
    W = np.empty((3, 3))
    Wm = np.empty((3, 3))
    _from6(state_in, S_W, W)
    _from6(state_in, S_W_MAX, Wm)
    if dlR[0] != 0.0 or dlR[1] != 0.0 or dlR[2] != 0.0:
        for k in range(3):
            if dlR[k] != 0.0:
                dw = dlR[k] * _extent(xe, Q, k)
                for i in range(3):
                    for j in range(3):
                        W[i, j] += dw * Q[i, k] * Q[j, k]
        ww = np.empty(3)
        Vw = np.empty((3, 3))
        _eig_sym3(W, ww, Vw)
        for k in range(3):
            ww[k] = max(ww[k], 0.0)
        # W_max in the basis of W: diagonal maxima, off-diagonal terms kept
        B = np.empty((3, 3))
        for k in range(3):
            for m in range(3):
                acc = 0.0
                for i in range(3):
                    for j in range(3):
                        acc += Vw[i, k] * Wm[i, j] * Vw[j, m]
                B[k, m] = acc
        for k in range(3):
            B[k, k] = max(B[k, k], ww[k])
        for i in range(3):
            for j in range(3):
                accW = 0.0
                accM = 0.0
                for k in range(3):
                    accW += ww[k] * Vw[i, k] * Vw[j, k]
                    for m in range(3):
                        accM += Vw[i, k] * B[k, m] * Vw[j, m]
                W[i, j] = accW
                Wm[i, j] = accM
        _to6(W, state_out, S_W)
        _to6(Wm, state_out, S_W_MAX)

    # ---- damages -------------------------------------------------------------------------------
    wm = np.empty(3)
    P = np.empty((3, 3))
    _eig_sym3(Wm, wm, P)
    w_k = params[P_W_K]
    w_r = params[P_W_R]
    d_t = np.empty(3)
    d_r = np.empty(3)
    for k in range(3):
        wk_ = max(0.0, wm[k])
        ratio = w_k / (w_k + wk_)
        d_t[k] = 1.0 - ratio * ratio
        wc = 0.0
        for i in range(3):
            for j in range(3):
                wc += P[i, k] * W[i, j] * P[j, k]
        wc = max(wc, 0.0)
        rho = w_r / (w_r + wc)
        d_r[k] = 1.0 - rho * rho
    # sorted tensile damages and largest opening, for the outputs
    a0 = d_t[0]
    a1 = d_t[1]
    a2 = d_t[2]
    if a0 < a1:
        a0, a1 = a1, a0
    if a1 < a2:
        a1, a2 = a2, a1
    if a0 < a1:
        a0, a1 = a1, a0
    state_out[S_D_T] = a0
    state_out[S_D_T + 1] = a1
    state_out[S_D_T + 2] = a2
    state_out[S_W_OPEN_MAX] = max(0.0, max(wm[0], max(wm[1], wm[2])))

    # pre-peak compressive damage
    mean = (s[0] + s[1] + s[2]) / 3.0
    q2 = 0.0
    for i in range(3):
        q2 += (s[i] - mean) * (s[i] - mean)
    s_eq = math.sqrt(0.5 * q2) + delta * mean  # sqrt(J2) - delta p, p = -mean
    d_pic = params[P_D_PIC]
    d_cpp = state_in[S_D_CPP]
    if d_pic > 0.0 and s_eq > 0.0:
        x = s_eq / params[P_C_MAX]
        x = min(x, 1.0)
        lpk = params[P_LAMBDA_PK]
        if lam_d > 0.0 and lam_d < lpk:
            dn = d_pic * x
        else:
            dn = d_pic * x ** params[P_EXP_CPP]
        d_cpp = max(d_cpp, dn)
    state_out[S_D_CPP] = d_cpp

    # post-peak compressive damage
    kappa = epsD[0, 0] + epsD[1, 1] + epsD[2, 2] - beta * params[P_LAMBDA_PK]
    d_c = state_in[S_D_C]
    if kappa > 0.0:
        dn = kappa / (kappa + params[P_EPS_KDC])
        d_c = max(d_c, dn)
    state_out[S_D_C] = d_c

    # ---- apparent stress -------------------------------------------------------------------------
    Sp = np.zeros((3, 3))
    Sm = np.zeros((3, 3))
    for k in range(3):
        sp = max(0.0, s[k])
        sm = s[k] - sp
        for i in range(3):
            for j in range(3):
                qq = Q[i, k] * Q[j, k]
                Sp[i, j] += sp * qq
                Sm[i, j] += sm * qq
    nup = E_lame / M
    Tp = np.empty((3, 3))
    Tm = np.empty((3, 3))
    _crack_damage(Sp, P, d_t, nup, Tp)
    _crack_damage(Sm, P, d_r, nup, Tm)
    f_c = 1.0 - d_c
    f_cpp = 1.0 - d_cpp
    sigma[0] = f_c * (Tp[0, 0] + f_cpp * Tm[0, 0])
    sigma[1] = f_c * (Tp[1, 1] + f_cpp * Tm[1, 1])
    sigma[2] = f_c * (Tp[2, 2] + f_cpp * Tm[2, 2])
    sigma[3] = f_c * (0.5 * (Tp[1, 2] + Tp[2, 1]) + f_cpp * 0.5 * (Tm[1, 2] + Tm[2, 1]))
    sigma[4] = f_c * (0.5 * (Tp[0, 2] + Tp[2, 0]) + f_cpp * 0.5 * (Tm[0, 2] + Tm[2, 0]))
    sigma[5] = f_c * (0.5 * (Tp[0, 1] + Tp[1, 0]) + f_cpp * 0.5 * (Tm[0, 1] + Tm[1, 0]))
    return status


@njit(cache=True)
def endo3d_update_all(eps, state_in, params, xe_of_point, state_out, sigma):
    """Update ``ngp`` Gauss points: ``eps`` (ngp, 6), ``state_in``/``state_out``
    (ngp, N_STATE), ``xe_of_point`` (ngp, 8, 3) the nodes of the element of each point (m),
    ``sigma`` (ngp, 6) written (Pa). Plain loop. Returns the number of points whose return
    mapping did not converge (status > 0)."""
    nfail = 0
    for g in range(eps.shape[0]):
        st = endo3d_update(eps[g], state_in[g], params, xe_of_point[g], state_out[g], sigma[g])
        if st != 0:
            nfail += 1
    return nfail


@njit(cache=True)
def endo3d_update_elements(eps, state_in, params, xe, elem_of_point, state_out, sigma):
    """As :func:`endo3d_update_all` with the node coordinates given per element: ``xe``
    (nel, 8, 3) and ``elem_of_point`` (ngp,) int64, the element of each point. Returns the
    number of points whose return mapping did not converge."""
    nfail = 0
    for g in range(eps.shape[0]):
        st = endo3d_update(
            eps[g], state_in[g], params, xe[elem_of_point[g]], state_out[g], sigma[g]
        )
        if st != 0:
            nfail += 1
    return nfail
