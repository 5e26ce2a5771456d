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
* Drucker-Prager (skipped when three Rankine criteria are active, see below):
  ``f_D = sqrt(J2) - delta p - C(lambda_D)``, ``p = -tr(s~)/3`` (Pa), non-associated flow
  ``d eps_pD = dlam_D (s_dev / (2 sqrt(J2)) + beta/3 1)`` (so ``tr d eps_pD = beta dlam_D``).
  Its dissipation is ``dlam_D (C + (delta - beta) p)`` (J/m^3): non-negative for
  ``beta <= delta`` (``p >= -R_t`` under Rankine); the case schema asks ``beta <= delta``,
  :func:`endo3d_params` only warns (kept for studies of the kernel itself).
* Cohesion hardening (Pa): ``C = C_min + (C_max - C_min)(2x - x^2)``, ``x = lambda_D/lambda_pk``
  for ``x < 1``, ``C = C_max`` afterwards (and always when ``lambda_pk = 0``: no division by
  it), with ``C_min = R_t delta``, ``C_max = R_c,eff (1/sqrt(3) - delta/3)``. Slope
  ``H = dC/dlambda_D = 2 (C_max - C_min)(1 - x)/lambda_pk`` (Pa). Iterates of the return
  mapping with a negative increment ``dlam_D < 0`` (transient: such a pass drops
  Drucker-Prager) use the tangent at the start of the step, ``C = C_n + H_n dlam_D``.
* Peak quantities: if ``DCPK > 0`` and ``eps_pic_c > R_c/E``:
  ``d_pic = min(DCPK, 1 - R_c/(E eps_pic_c))``, ``R_c,eff = R_c/(1 - d_pic)``; otherwise
  ``d_pic = 0``, ``eps_pic_c := R_c/E``, ``R_c,eff = R_c``.  ``eps_pl,pk = eps_pic_c - R_c,eff/E``
  (exactly 0 when the cap DCPK does not bind, and set to 0 below ``16 eps_machine eps_pic_c``,
  its round-off), ``lambda_pk = 3 eps_pl,pk / (sqrt(3) - beta)``.

Return mapping (in the principal basis of the trial effective stress, which all flows share;
principal values in decreasing order). Passes of a cutting-plane algorithm: a criterion violated
by more than the tolerance ``tol = 1e-8 max(R_t, R_c,eff, REF)`` (Pa) becomes active and stays
active (consistency condition ``f = 0``) for the rest of the pass; at each iteration the active
ones are linearised at the current stress and the multiplier increments solved from

    Rankine/Rankine:   J_ij = M (i = j),  lam (i != j)
    Rankine i / DP:    J_iD = G dev_i / sqrt(J2) + K beta,   J_Di = G dev_i / sqrt(J2) + delta K
    DP/DP:             J_DD = G + K beta delta + H,   H = dC/dlambda_D

(one Rankine alone: ``dlam = f/(K + 4G/3)``; DP alone: ``dlam_D = f_D/(G + K beta delta + H)``).
Between passes the active set is corrected (one kind of correction per restart, the
multipliers of a pass that needs one kind saying nothing about the next): (1) Drucker-Prager
flowed and was then skipped (three Rankine-type constraints): redone without it; (2) a
reclosure that would make ``e_i . eps_pR . e_i`` negative becomes the full closure of that
direction (prescribed increment ``-r_i``); (3) of the multipliers with the wrong sign
(Rankine < 0, reclosure > 0, Drucker-Prager < 0) the largest is excluded; (4) an excluded
surface, or a closure, that the final stress violates (``f > tol``, or a closed direction with
``s_i > -REF``) is admitted again. A pass is accepted only when the Kuhn-Tucker conditions hold
(right signs, no criterion violated by more than ``tol``), so that a step never ends with a
violated criterion and status 0 (correction (4) is what re-admits an excluded
Drucker-Prager). If the corrections cycle (8 passes:
non-associated flow, corners), the active sets are searched, fewest active surfaces first (each
direction inactive, Rankine or, crack open, reclosure or full closure; Drucker-Prager off or
on) by a closest-point (backward Euler) solve per set (:func:`_closest_point`), and the first
that satisfies the Kuhn-Tucker conditions is taken. Drucker-Prager is skipped with three
Rankine constraints (their corner ``R_t (1, 1, 1)`` satisfies it, ``delta R_t = C_min <= C``),
and so, in the cutting-plane passes, with three Rankine-type ones; a closed direction
prescribes a strain increment, not a stress, and does not count. A singular or ill-conditioned
system (a multiplier increment above 1) involving Drucker-Prager drops it for the pass. The
kernel returns status 1 when no active set satisfies the conditions (a pass not converged in
``MAX_RETURN_ITER`` iterations and no set found), 2 when a linear system is singular; the state
is written, with ``lambda_D`` never decreased (a negative Drucker-Prager increment of the last
iterate is removed, stress kept equal to ``C0 : (eps - eps_pR - eps_pD)``).

Repeated eigenvalues. The eigen solver's basis of a repeated eigenspace (and its order)
depends on the frame. Where a choice is made per direction in such a space, the basis is taken
from the state instead (:func:`_refine_basis`: rotated to diagonalise another tensor of the
state there, ordered by its diagonal terms, then the next tensor if that one is isotropic
there), so that the law is objective:

* trial stress with repeated principal values: by ``eps_pR`` (reclosure criterion
  ``e_i . eps_pR . e_i``), then ``W``, then the element's edges (Hillerborg lengths ``L_i``);
* ``W`` (basis of the ``W_max`` update) with a repeated positive eigenvalue: by ``W_max``,
  then the edges;
* ``W_max`` (crack basis) with a repeated eigenvalue (one crack: ``(0, 0, w)``): by ``W``
  (``w_i,cur`` of the reclosure), then the edges.

The edge tensor ``a1 a1^T + 2 a2 a2^T + 3 a3 a3^T`` (m^2, three edges of the hexahedron from
its node 0) has distinct eigenvalues also for a cube. Eigenvalues are repeated when equal to
``DEGENERATE_REL = 1e-12`` of the largest (round-off is ~1e-16); outside such spaces nothing
changes. What remains frame-dependent is a sensitivity of the law to differences at the
return mapping's tolerance, near crack closure or nearly repeated principal stresses, not a
choice of basis (tests/test_endo3d_objectivity.py::test_cracked_state_objectivity_residual).

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
  diagonal term of the current ``W`` in the crack basis (choice; in a repeated eigenspace of
  ``W_max`` the basis diagonalises ``W``, see above).
* Pre-peak compressive damage: ``s_eq = max(0, sqrt(J2) - delta p)``, ``x = min(1, s_eq/C_max)``;
  ``d_cpp = d_pic x`` while ``0 < lambda_D < lambda_pk``, else ``d_pic x^((1-d_pic)/d_pic)``
  (``0`` when ``d_pic = 0``); irreversible (running maximum).
* Post-peak compressive damage: ``kappa = tr(eps_pD) - beta lambda_pk``,
  ``d_c = kappa/(kappa + eps_kdc)`` for ``kappa > 0``; irreversible. As specified this is a
  strain law: ``eps_kdc`` is the plastic volumetric strain past the peak at which ``d_c = 1/2``
  whatever the element, so the energy of a crushing band shrinks with the element and the
  softening does not converge with the mesh. With a crushing length ``l_c > 0``
  (``P_L_CRUSH``; our choice, not in model.md) ``eps_kdc`` is the strain of an element ``l_c``
  long: an element of extent ``L`` along its most compressive principal direction uses
  ``eps_kdc l_c / L``, so that the post-peak shortening of a band, ``kappa L``, is the same
  whatever the mesh (Hillerborg's regularisation, as in tension).

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
* Drucker-Prager is also skipped, in the cutting-plane passes, when reclosure constraints fix
  the remaining principal stresses (three Rankine-type constraints: the stress is prescribed;
  ``f_D`` can then be enforced only through the hardening, which the active-set search tries).
* Not derived from a potential: with nu > 0 the principal split of the effective stress, and the
  recovery of ``rho`` at ``s~ = -REF``, can make a closed strain cycle return more work than it
  received (up to ``REF^2/(2E)`` per direction and closure for the latter); with
  ``beta > delta`` the Drucker-Prager flow dissipates ``dlam (C + (delta - beta) p) < 0`` at
  high pressure (:func:`endo3d_params` warns; the case schema refuses it): a yz shear cycle
  with ``beta = 1.5``, ``delta = 0`` then ratchets the effective pressure up to 100 R_c.

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
    "endo3d_tangent_elements",
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
P_L_CRUSH = 27  # crushing length (m): eps_kdc is the strain of an element this long; 0: none
N_PARAMS = 28

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
#: Maximal number of passes of the return mapping (changes of its active set).
MAX_RESTARTS = 8
#: Eigenvalues (of the trial stress, W, W_max) equal to within this fraction of the largest
#: are one repeated eigenvalue (the eigen solver's round-off is ~1e-16 of it), whose
#: eigenspace gets a frame-independent basis (:func:`_refine_basis`).
DEGENERATE_REL = 1e-12
#: 3x3 work matrices of one point's update (:func:`_update`): its tensors, its 3-vectors (rows
#: of a matrix) and the eigen solver's work.
N_WORK = 21

_SQRT3 = math.sqrt(3.0)

#: A plastic strain at the compressive peak below this fraction of eps_pic_c is round-off of
#: ``eps_pic_c - R_c,eff/E`` (each term is computed to a few ulps) and is set to exactly zero.
_PEAK_ROUND_OFF = 16.0 * np.finfo(np.float64).eps


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
    crushing_length: float = 0.0,
) -> FloatArray:
    """Parameter vector of the ENDO3D kernels, with the derived quantities precomputed.

    Arguments in SI units: ``E``, ``R_t``, ``R_c``, ``REF`` in Pa; ``G_ft``, ``GFR`` in J/m^2;
    ``nu``, ``eps_pic_t``, ``eps_pic_c``, ``delta``, ``beta``, ``eps_kdc``, ``DCPK``
    dimensionless; ``crushing_length`` in m (0: the post-peak compressive law as specified, a
    strain law; > 0: regularised by the element size, see the module docstring). Raises
    ``ValueError`` for values outside the range where the law is defined
    (E, R_t, G_ft, R_c, REF, GFR, eps_kdc > 0; -1 < nu < 0.5; 0 <= delta, beta < sqrt 3;
    0 <= DCPK <= 1; R_t < R_c,eff; C_min <= C_max). Warns when ``eps_pic_t`` differs from
    ``R_t/E`` by more than 1 % (the law ignores it: its tensile peak is at ``R_t/E``) and when
    ``beta > delta`` (negative plastic dissipation at pressures above ``C/(beta - delta)``;
    kept for studies of the kernel, the case schema refuses it). The plastic strain at the
    compressive peak ``eps_pl,pk = eps_pic_c - R_c,eff/E`` is exactly 0 when the cap DCPK does
    not bind, and is set to 0 below ``16 eps_machine eps_pic_c`` (round-off of the difference,
    which would make ``lambda_pk`` ~ 1e-19 and the hardening slope ~ 1e26 Pa).
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
            # cap not binding: the peak is reached without plastic strain, eps_pl,pk = 0
            # exactly (eps_pic_c - (E eps_pic_c)/E is a few 1e-20 for 1 value in 10)
            d_pic = 1.0 - R_c / (E * eps_pic_c)
            rc_eff = E * eps_pic_c
            eps_pl_pk = 0.0
        else:
            d_pic = DCPK
            rc_eff = R_c / (1.0 - d_pic)
            eps_pl_pk = eps_c - rc_eff / E
    else:
        d_pic = 0.0
        eps_c = R_c / E
        rc_eff = R_c
        eps_pl_pk = 0.0
    if eps_pl_pk <= _PEAK_ROUND_OFF * eps_c:
        # below the round-off of eps_pic_c - R_c,eff/E (a cap DCPK within a few ulps of
        # 1 - R_c/(E eps_pic_c)): no plastic strain at the peak. A round-off lambda_pk would
        # make the hardening slope 2 (C_max - C_min)/lambda_pk absurd (1e26 Pa and more).
        eps_pl_pk = 0.0
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
    p[P_L_CRUSH] = crushing_length
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
def _jacobi_tangent(app, aqq, apq):
    """``t = tan(phi)`` of the Jacobi rotation that zeroes the (p, q) term of a symmetric
    matrix with diagonal terms ``app``, ``aqq`` (``apq != 0``); the smaller root, |phi| <= pi/4.
    After the rotation the diagonal terms are ``app - t apq`` and ``aqq + t apq``."""
    theta = (aqq - app) / (2.0 * apq)
    t = 1.0 / (abs(theta) + math.sqrt(theta * theta + 1.0))
    return -t if theta < 0.0 else t


@njit(cache=True)
def _rotate_columns(M, p, q, c, s):
    """Columns ``p``, ``q`` of the 3-row ``M`` turned by the rotation of cosine ``c``, sine
    ``s``: ``(M_p, M_q) := (c M_p - s M_q, s M_p + c M_q)``."""
    for r in range(3):
        mrp = M[r, p]
        mrq = M[r, q]
        M[r, p] = c * mrp - s * mrq
        M[r, q] = s * mrp + c * mrq


@njit(cache=True)
def _swap_pair(w, V, p, q):
    """Swap the eigenvalues ``w[p]``, ``w[q]`` and the columns ``p``, ``q`` of ``V``."""
    tmp = w[p]
    w[p] = w[q]
    w[q] = tmp
    for r in range(3):
        tmp = V[r, p]
        V[r, p] = V[r, q]
        V[r, q] = tmp


@njit(cache=True)
def _eig_sym3(A, w, V):
    """Eigenvalues ``w`` and eigenvectors (columns of ``V``) of a symmetric 3x3 ``A`` by cyclic
    Jacobi rotations (accurate to round-off, also for repeated eigenvalues). ``A`` is untouched.
    """
    _eig_sym3_work(A, w, V, np.empty((3, 3)))


@njit(cache=True)
def _eig_sym3_work(A, w, V, a):
    """:func:`_eig_sym3` with the 3x3 work array ``a`` given (overwritten): no allocation."""
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
            t = _jacobi_tangent(a[p, p], a[q, q], apq)
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            _rotate_columns(a, p, q, c, s)
            for r in range(3):
                apr = a[p, r]
                aqr = a[q, r]
                a[p, r] = c * apr - s * aqr
                a[q, r] = s * apr + c * aqr
            a[p, q] = 0.0
            a[q, p] = 0.0
            _rotate_columns(V, p, q, c, s)
    for i in range(3):
        w[i] = a[i, i]


@njit(cache=True)
def _sort_desc(w, V):
    """Sort the eigenvalues ``w`` (3,) in decreasing order, with the columns of ``V``."""
    for a in range(2):
        for b in range(2 - a):
            if w[b] < w[b + 1]:
                _swap_pair(w, V, b, b + 1)


@njit(cache=True)
def _label_equal(w, tol, g):
    """``g[i]``: the smallest index ``j`` with ``w_j`` equal to ``w_i`` to within ``tol``
    (linked: ``w_0 ~ w_2 ~ w_1`` is one group)."""
    e01 = abs(w[1] - w[0]) <= tol
    e02 = abs(w[2] - w[0]) <= tol
    e12 = abs(w[2] - w[1]) <= tol
    g[0] = 0
    g[1] = 1
    g[2] = 2
    if e01 or (e02 and e12):
        g[1] = 0
    if e02 or (e01 and e12):
        g[2] = 0
    elif e12:
        g[2] = 1


@njit(cache=True)
def _count_shared(g):
    """Number of labels of ``g`` (3,) that another index shares (0, 2 or 3)."""
    n = 0
    for i in range(3):
        for j in range(3):
            if i != j and g[i] == g[j]:
                n += 1
                break
    return n


@njit(cache=True)
def _in_basis(P, S, out):
    """``out = P^T S P`` (3x3): the tensor ``S`` in the basis of the columns of ``P``."""
    for k in range(3):
        for m in range(3):
            acc = 0.0
            for i in range(3):
                for j in range(3):
                    acc += P[i, k] * S[i, j] * P[j, m]
            out[k, m] = acc


@njit(cache=True)
def _eigen_tol(w, tol_abs):
    """Tolerance for equal eigenvalues ``w`` (3,): the larger of ``DEGENERATE_REL`` of the
    largest ``|w_i|`` and ``tol_abs``."""
    return max(DEGENERATE_REL * max(abs(w[0]), max(abs(w[1]), abs(w[2]))), tol_abs)


@njit(cache=True)
def _tensor_tol(A, tol_abs):
    """``(max |A_ij|, tol)`` of a 3x3 tensor, ``tol`` the larger of ``DEGENERATE_REL`` times
    that maximum and ``tol_abs``."""
    amax = 0.0
    for i in range(3):
        for j in range(3):
            amax = max(amax, abs(A[i, j]))
    return amax, max(DEGENERATE_REL * amax, tol_abs)


@njit(cache=True)
def _equal_groups(w, g, tol_abs):
    """Label the eigenvalues ``w`` (3,) by groups of equal values, to within the larger of
    ``DEGENERATE_REL`` of the largest ``|w_i|`` and ``tol_abs`` (:func:`_label_equal`).
    Returns the number of indices that share a group (0: all distinct)."""
    tol = _eigen_tol(w, tol_abs)
    _label_equal(w, tol, g)
    return _count_shared(g)


@njit(cache=True)
def _refine_basis(w, V, g, A, tol_abs):
    """Give the repeated eigenspaces of a tensor a basis that turns with the state.

    ``w`` (3,), ``V`` (3, 3): eigenvalues and eigenvectors (columns) of a symmetric tensor;
    ``g`` (3,): groups of equal eigenvalues (:func:`_equal_groups`); ``A`` (3, 3): another
    symmetric tensor of the state. In each group the columns are rotated so that ``V^T A V``
    is diagonal there and ordered by increasing diagonal term (``w`` follows its columns), and
    the group is split where those terms differ by more than ``tol``, the larger of
    ``DEGENERATE_REL`` times the largest ``|A_ij|`` and ``tol_abs`` (the round-off level of
    ``A``, in its units: a closed crack leaves ``W`` at 1e-15 of ``W_max``, not zero).
    Returns the number of columns still sharing a group. The eigen solver's basis of a
    repeated eigenspace, and its order, depend on the frame (Jacobi sweeps from the axes);
    refined by tensors of the state (which turn with the frame), they do not.
    """
    if not (g[0] == g[1] and g[1] == g[2]):
        for p in range(3):
            for q in range(p + 1, 3):
                if g[p] == g[q]:
                    if _refine_pair(w, V, p, q, A, tol_abs) != 0:
                        return 2  # A does not tell the two directions apart either
                    g[q] = q
                    return 0
        return 0
    amax, tol = _tensor_tol(A, tol_abs)
    if amax <= tol:
        return 3
    B = np.empty((3, 3))
    _in_basis(V, A, B)
    b = np.empty(3)
    U = np.empty((3, 3))
    _eig_sym3(B, b, U)
    order = np.empty(3, dtype=np.int64)  # indices by increasing b (bubble sort of three)
    for k in range(3):
        order[k] = k
    for a in range(2):
        for k in range(2 - a):
            if b[order[k]] > b[order[k + 1]]:
                tmp_i = order[k]
                order[k] = order[k + 1]
                order[k + 1] = tmp_i
    Vn = np.empty((3, 3))
    wn = np.empty(3)
    bn = np.empty(3)
    for k in range(3):
        ok = order[k]
        wn[k] = w[ok]
        bn[k] = b[ok]
        for i in range(3):
            acc = 0.0
            for m in range(3):
                acc += V[i, m] * U[m, ok]
            Vn[i, k] = acc
    for k in range(3):
        w[k] = wn[k]
        for i in range(3):
            V[i, k] = Vn[i, k]
    _label_equal(bn, tol, g)
    return _count_shared(g)


@njit(cache=True)
def _has_repeated(w, tol_abs):
    """Whether two of the eigenvalues ``w`` (3,) are equal to within the larger of
    ``DEGENERATE_REL`` of the largest ``|w_i|`` and ``tol_abs`` (``w = 0`` counts)."""
    tol = _eigen_tol(w, tol_abs)
    return abs(w[1] - w[0]) <= tol or abs(w[2] - w[0]) <= tol or abs(w[2] - w[1]) <= tol


@njit(cache=True)
def _refine_pair(w, V, p, q, A, tol_abs):
    """:func:`_refine_basis` for one pair ``p < q`` of equal eigenvalues, without work arrays:
    rotate columns ``p``, ``q`` of ``V`` to diagonalise ``A`` on their plane, order them by
    increasing diagonal term (``w`` follows). Returns 0 when done, 1 when ``A`` vanishes on
    the plane, 2 when it is isotropic there (1 and 2: ``V`` unchanged; to within
    ``max(DEGENERATE_REL max |A_ij|, tol_abs)``)."""
    amax, tol = _tensor_tol(A, tol_abs)
    if amax <= tol:
        return 1
    bpp = 0.0
    bqq = 0.0
    bpq = 0.0
    for i in range(3):
        for j in range(3):
            a = A[i, j]
            bpp += V[i, p] * a * V[j, p]
            bqq += V[i, q] * a * V[j, q]
            bpq += V[i, p] * a * V[j, q]
    if abs(bpq) <= tol and abs(bqq - bpp) <= tol:
        return 1 if abs(bpp) <= tol and abs(bqq) <= tol else 2
    if bpq != 0.0:
        # the Jacobi rotation that zeroes the (p, q) term (as in _eig_sym3)
        t = _jacobi_tangent(bpp, bqq, bpq)
        c = 1.0 / math.sqrt(t * t + 1.0)
        _rotate_columns(V, p, q, c, t * c)
        bpp, bqq = bpp - t * bpq, bqq + t * bpq
    if bpp > bqq:
        _swap_pair(w, V, p, q)
    return 0


@njit(cache=True)
def _pair_value(w):
    """``|w_i|`` of the repeated eigenvalue of ``w`` (3,) when exactly two are equal to within
    ``DEGENERATE_REL`` of the largest (else +inf): lets a caller skip a pair at zero."""
    t = DEGENERATE_REL * max(abs(w[0]), max(abs(w[1]), abs(w[2])))
    e01 = abs(w[1] - w[0]) <= t
    e02 = abs(w[2] - w[0]) <= t
    e12 = abs(w[2] - w[1]) <= t
    if (1 if e01 else 0) + (1 if e02 else 0) + (1 if e12 else 0) != 1:
        return np.inf
    if e01:
        return abs(w[0])
    if e02:
        return abs(w[0])
    return abs(w[1])


@njit(cache=True)
def _state_basis(w, V, A, tol_abs, xe, zero_tol):
    """Frame-independent basis of the repeated eigenspaces of the eigenvectors ``V`` (columns,
    eigenvalues ``w``): refined by the tensor ``A`` (round-off level ``tol_abs``), then by the
    element's edges (:func:`_refine_basis`, :func:`_edge_tensor`). A pair whose eigenvalue is
    zero (to within ``zero_tol``) and on whose plane ``A`` vanishes is left as it is: the
    callers' results do not depend on its basis then (one crack: no damage across that plane;
    the common case, kept free of work arrays)."""
    tol = DEGENERATE_REL * max(abs(w[0]), max(abs(w[1]), abs(w[2])))
    e01 = abs(w[1] - w[0]) <= tol
    e02 = abs(w[2] - w[0]) <= tol
    e12 = abs(w[2] - w[1]) <= tol
    if (1 if e01 else 0) + (1 if e02 else 0) + (1 if e12 else 0) == 1:
        p = 0 if (e01 or e02) else 1
        q = 1 if e01 else 2
        code = _refine_pair(w, V, p, q, A, tol_abs)
        if code == 2 or (code == 1 and abs(w[p]) > zero_tol):
            Et = np.empty((3, 3))
            _edge_tensor(xe, Et)
            _refine_pair(w, V, p, q, Et, 0.0)
        return
    grp = np.empty(3, dtype=np.int64)
    if _equal_groups(w, grp, 0.0) > 0 and _refine_basis(w, V, grp, A, tol_abs) > 0:
        Et = np.empty((3, 3))
        _edge_tensor(xe, Et)
        _refine_basis(w, V, grp, Et, 0.0)


@njit(cache=True)
def _trial_basis(s, Q, epsR, state_in, xe, open_tol):
    """Frame-independent basis of the repeated eigenspaces of the trial stress (principal
    values ``s`` (Pa), directions ``Q``): refined by eps_pR (round-off ``open_tol``), then by
    the crack opening W (round-off 1e-12 of W_max, m), then by the element's edges; the
    principal values of a group are then set to their mean (they differ by round-off)."""
    grp = np.empty(3, dtype=np.int64)
    _equal_groups(s, grp, 0.0)
    Wn = np.empty((3, 3))
    _from6(state_in, S_W, Wn)
    w_tol = 0.0
    for k in range(6):
        w_tol = max(w_tol, DEGENERATE_REL * abs(state_in[S_W_MAX + k]))
    if _refine_basis(s, Q, grp, epsR, open_tol) > 0 and _refine_basis(s, Q, grp, Wn, w_tol) > 0:
        Et = np.empty((3, 3))
        _edge_tensor(xe, Et)
        _refine_basis(s, Q, grp, Et, 0.0)
    _equal_groups(s, grp, 0.0)
    for i in range(3):
        acc = 0.0
        cnt = 0
        for j in range(3):
            if grp[j] == grp[i]:
                acc += s[j]
                cnt += 1
        s[i] = acc / cnt


@njit(cache=True)
def _edge_tensor(xe, Et):
    """``Et = a1 a1^T + 2 a2 a2^T + 3 a3 a3^T`` (m^2) from three edges of the element, node
    0 to nodes 1, 3 and 4 of a hexahedron (hex8 order), to nodes 1, 2 and 3 of a tetrahedron
    (the three edges at its corner 0): a tensor of the element with distinct eigenvalues (also
    for a cube), the last tie-break of :func:`_refine_basis`."""
    for i in range(3):
        for j in range(3):
            Et[i, j] = 0.0
    hexahedron = xe.shape[0] == 8
    for k in range(3):
        nk = k + 1 if not hexahedron else (1 if k == 0 else (3 if k == 1 else 4))
        c = float(k + 1)
        for i in range(3):
            for j in range(3):
                Et[i, j] += c * (xe[nk, i] - xe[0, i]) * (xe[nk, j] - xe[0, j])


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
    """Drucker-Prager cohesion C (Pa) and its slope H = dC/dlambda_D (Pa) at ``lam_d >= 0``.

    ``C = C_min + (C_max - C_min)(2x - x^2)``, ``H = 2 (C_max - C_min)(1 - x)/lambda_pk`` with
    ``x = lambda_D/lambda_pk < 1``; ``C = C_max``, ``H = 0`` for ``x >= 1`` and when
    ``lambda_pk = 0`` (no division by it). For the iterates of the return mapping with a
    negative increment see :func:`_cohesion_iterate`.
    """
    c_min = prm[P_C_MIN]
    c_max = prm[P_C_MAX]
    lpk = prm[P_LAMBDA_PK]
    if lpk > 0.0 and lam_d < lpk:
        x = lam_d / lpk
        return c_min + (c_max - c_min) * (2.0 * x - x * x), (c_max - c_min) * 2.0 * (1.0 - x) / lpk
    return c_max, 0.0


@njit(cache=True)
def _cohesion_iterate(lam_n, dlam, c_n, h_n, prm):
    """Cohesion C (Pa) and slope H (Pa) at an iterate ``lambda_D = lam_n + dlam`` of the return
    mapping, ``c_n, h_n = _cohesion(lam_n)`` at the start of the step.

    ``dlam >= 0``: :func:`_cohesion`. ``dlam < 0`` (a transient iterate: a pass that ends with
    a negative increment drops Drucker-Prager): the tangent at the start of the step,
    ``C = C_n + H_n dlam``, ``H = H_n``. Extrapolating the parabola instead gave, with a small
    lambda_pk (1e-13), cohesions of -1e37 Pa and slopes of 1e41 Pa, or a cohesion that jumps
    between C_min and C_max within the round-off of ``lam_n + dlam``: the iteration stalled.
    """
    if dlam >= 0.0:
        return _cohesion(lam_n + dlam, prm)
    return c_n + h_n * dlam, h_n


@njit(cache=True)
def _crack_damage(S, P, d, nup, out, work):
    """Damage a stress tensor ``S`` (3x3, Pa) by cracks of damages ``d`` (3,) along the columns
    of ``P``: series normal compliance ``d_k/((1-d_k) M)`` per crack and shear terms multiplied
    by ``1 - min(d_k, d_l)`` in the crack basis. ``nup = lam/M = nu/(1-nu)``. Result in ``out``;
    ``work`` (3, 3, 3) scratch.
    """
    if d[0] <= 0.0 and d[1] <= 0.0 and d[2] <= 0.0:
        for i in range(3):
            for j in range(3):
                out[i, j] = S[i, j]
        return
    T = work[0]
    _in_basis(P, S, T)
    A = work[1]
    b = work[2, 0]
    y = work[2, 1]
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
# Return mapping
# --------------------------------------------------------------------------------------------

#: Index of Drucker-Prager in the exclusion flags of the return mapping (0-2: Rankine on each
#: principal direction, 3-5: reclosure on each principal direction).
_EXCL_D = 6


@njit(cache=True, inline="always")
def _return_pass(s_trial, r, closed, excl, lam_d_n, c_n, h_n, params, open_tol, s, dlR, depD,
                 mode, kind, Jm, fv, xs, dev, nD, xR):
    """One pass of the cutting-plane return mapping from the principal trial stress ``s_trial``
    (Pa). ``r`` (3,): ``e_i . eps_pR . e_i`` at the start of the step; ``closed`` (3,): the
    directions fully closed in this step (prescribed ``dlambda_i = -r_i``); ``excl`` (7,):
    the surfaces not to activate (see ``_EXCL_D``). ``mode`` starts empty; a violated surface
    is added and kept (consistency condition ``f = 0``) to the end of the pass.

    Written: ``s`` (3,) the stress (Pa), ``dlR`` (3,) the Rankine/reclosure multipliers,
    ``depD`` (3,) the principal Drucker-Prager plastic strain increments, ``mode`` (4,);
    the others are work arrays. Returns ``(code, dlambda_D, iterations)``, ``code`` 0 when no
    criterion is violated by more than the tolerance, 1 when not converged in
    ``MAX_RETURN_ITER`` iterations, 2 when the linearised system is singular.
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
    n_it = 0
    for _it in range(MAX_RETURN_ITER):
        n_it += 1
        C, H = _cohesion_iterate(lam_d_n, dlD, c_n, h_n, params)
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
            elif s[i] - rt > tol and not excl[i]:
                mode[i] = 1
                violated = True
            elif s[i] + ref < -tol and r[i] + dlR[i] > open_tol and not excl[3 + i]:
                mode[i] = -1
                violated = True
        ntens = 0
        for i in range(3):
            if mode[i] != 0:
                ntens += 1
        if ntens == 3:
            # Drucker-Prager skipped when the three Rankine criteria are active (and, by
            # extension, when reclosure fixes the remaining principal stresses: the three
            # principal stresses are then prescribed and f_D cannot be enforced). A closed
            # direction prescribes its plastic strain increment, not its stress: it does not
            # count.
            mode[3] = 0
        elif mode[3] == 1:
            if abs(fD) > tol:
                violated = True
        elif fD > tol and not excl[_EXCL_D]:
            mode[3] = 1
            violated = True
        if not violated:
            return 0, dlD, n_it

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
            return 2, dlD, n_it
        for a in range(n):
            # a multiplier increment above 1 (a strain of 100 %) or not finite: the system is
            # numerically singular
            if not abs(xs[a]) <= 1.0:
                return 2, dlD, n_it
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
    return 1, dlD, n_it


@njit(cache=True)
def _cp_residual(s_trial, r, closed, mode, kind, n, dp, dlR, dlD, lam_d_n, c_n, h_n, params, s,
                 dev, fv):
    """Residuals (Pa) of :func:`_closest_point` at the multipliers ``dlR`` (the closed and
    inactive directions are set here), ``dlD``: writes ``s`` (final stress), ``dev`` (the
    deviator of ``s*``) and ``fv``; returns ``(q*, 1 - G dlD/q*, H, max |residual|)``."""
    E_lame = params[P_LAME]
    G = params[P_G]
    K = params[P_K]
    beta = params[P_BETA]
    for i in range(3):
        if closed[i]:
            dlR[i] = -r[i]
        elif mode[i] == 0:
            dlR[i] = 0.0
    tr_d = dlR[0] + dlR[1] + dlR[2]
    for i in range(3):
        s[i] = s_trial[i] - E_lame * tr_d - 2.0 * G * dlR[i]
    mean = (s[0] + s[1] + s[2]) / 3.0
    for i in range(3):
        dev[i] = s[i] - mean
    q = math.sqrt(0.5 * (dev[0] * dev[0] + dev[1] * dev[1] + dev[2] * dev[2]))
    phi = 1.0
    if dp:
        if not q > 0.0:
            return q, 0.0, 0.0, np.inf  # no deviator: no Drucker-Prager direction
        phi = 1.0 - G * dlD / q
    for i in range(3):
        s[i] = mean - K * beta * dlD + phi * dev[i]
    C, H = _cohesion_iterate(lam_d_n, dlD, c_n, h_n, params)
    res = 0.0
    for a in range(n):
        i = kind[a]
        fv[a] = s[i] - params[P_RT] if mode[i] == 1 else s[i] + params[P_REF]
        res = max(res, abs(fv[a]))
    if dp:
        fv[n] = q - G * dlD + params[P_DELTA] * (mean - K * beta * dlD) - C
        res = max(res, abs(fv[n]))
    if not res < np.inf:
        res = np.inf
    return q, phi, H, res


@njit(cache=True)
def _closest_point(s_trial, r, closed, mode, lam_d_n, params, s, dlR, depD, dev, kind, Jm, fv,
                   xs, x0):
    """Closest-point (backward Euler) return for a given active set: the fallback of the
    return mapping when its cutting-plane passes cycle.

    ``mode`` (4,): the active set (as in :func:`_return_pass`); ``closed`` (3,): the directions
    fully closed (``dlambda_i = -r_i``). With ``D_i = dlambda_i`` (Rankine, reclosure, closure),
    ``s* = s_trial - C0 : D`` (Pa), its mean ``mean*`` and deviator ``dev*``,
    ``q* = sqrt(J2(s*))``, the Drucker-Prager flow taken at the final stress keeps the
    direction of ``dev*``:

        s = (mean* - K beta dlambda_D) 1 + (1 - G dlambda_D / q*) dev*,
        f_D = q* - G dlambda_D + delta (mean* - K beta dlambda_D) - C(lambda_n + dlambda_D)

    (Pa), and ``d eps_pD,i = dlambda_D (dev*_i / (2 q*) + beta/3)``. The active criteria
    (``s_i - R_t``, ``s_i + REF``, ``f_D``, Pa) are solved by Newton's method with the exact
    Jacobian and a backtracking line search on the largest residual, from the Rankine-type
    solution without Drucker-Prager; converged at the tolerance of the return mapping. Writes
    ``s``, ``dlR``, ``depD``; returns ``(code, dlambda_D)``, code 0 when converged with
    ``G dlambda_D <= q*`` (not past the apex of the cone), 1 otherwise. Unlike those of the
    cutting-plane passes (normals at the iterates), its multipliers are those of the
    projection, whose signs the Kuhn-Tucker check can trust.
    """
    G = params[P_G]
    K = params[P_K]
    delta = params[P_DELTA]
    beta = params[P_BETA]
    tol = params[P_TOL]
    c_n, h_n = _cohesion(lam_d_n, params)
    n = 0
    for i in range(3):
        dlR[i] = 0.0
        if mode[i] != 0:
            kind[n] = i
            n += 1
    dlD = 0.0
    # the Rankine-type multipliers without Drucker-Prager (linear: one Newton step), then all
    for phase in range(2):
        dp = phase == 1 and mode[3] == 1
        if phase == 1 and not dp:
            break
        m_ = n + (1 if dp else 0)
        q, phi, H, res = _cp_residual(s_trial, r, closed, mode, kind, n, dp, dlR, dlD, lam_d_n,
                                      c_n, h_n, params, s, dev, fv)
        converged = False
        for _it in range(MAX_RETURN_ITER):
            if res <= tol:
                converged = True
                break
            if not res < np.inf:
                return 1, dlD
            for a in range(n):
                i = kind[a]
                for b in range(n):
                    j = kind[b]
                    # ds_i/d(dlambda_j), with dq*/d(dlambda_j) = -G dev*_j/q*
                    dphi = G * dlD / (q * q) * (-G * dev[j] / q) if dp else 0.0
                    kron = 1.0 if i == j else 0.0
                    Jm[a, b] = -K - phi * 2.0 * G * (kron - 1.0 / 3.0) + dev[i] * dphi
                if dp:
                    Jm[a, n] = -K * beta - G * dev[i] / q
            if dp:
                for b in range(n):
                    Jm[n, b] = -G * dev[kind[b]] / q - delta * K
                Jm[n, n] = -G - delta * K * beta - H
            for a in range(m_):
                x0[a] = fv[a]
            if not _solve_small(Jm, x0, m_, xs):
                return 1, dlD
            # backtracking on the largest residual
            step = 1.0
            for a in range(n):
                x0[a] = dlR[kind[a]]
            d0 = dlD
            res0 = res
            for _ls in range(30):
                for a in range(n):
                    dlR[kind[a]] = x0[a] - step * xs[a]
                if dp:
                    dlD = d0 - step * xs[n]
                q, phi, H, res = _cp_residual(s_trial, r, closed, mode, kind, n, dp, dlR, dlD,
                                              lam_d_n, c_n, h_n, params, s, dev, fv)
                if res < res0:
                    break
                step *= 0.5
            if not res < res0:
                return 1, dlD
        if not converged:
            return 1, dlD
    if mode[3] == 1:
        q, phi, H, res = _cp_residual(s_trial, r, closed, mode, kind, n, True, dlR, dlD, lam_d_n,
                                      c_n, h_n, params, s, dev, fv)
        if not phi >= 0.0:
            return 1, dlD
        for i in range(3):
            depD[i] = dlD * (dev[i] / (2.0 * q) + beta / 3.0)
    else:
        for i in range(3):
            depD[i] = 0.0
    return 0, dlD


@njit(cache=True)
def _dp_violated(s, lam_d_n, dlD, c_n, h_n, params, mode):
    """Whether the principal stress ``s`` (Pa) violates Drucker-Prager by more than the
    tolerance, ``f_D = sqrt(J2) - delta p - C(lambda_n + dlambda_D) > tol``, where it is to be
    enforced (fewer than three Rankine-type constraints active in ``mode``)."""
    ntens = 0
    for i in range(3):
        if mode[i] != 0:
            ntens += 1
    if ntens == 3:
        return False
    C, _H = _cohesion_iterate(lam_d_n, dlD, c_n, h_n, params)
    mean = (s[0] + s[1] + s[2]) / 3.0
    q2 = 0.0
    for i in range(3):
        q2 += (s[i] - mean) * (s[i] - mean)
    return math.sqrt(0.5 * q2) + params[P_DELTA] * mean - C > params[P_TOL]


@njit(cache=True)
def _kkt_holds(s, r, dlR, dlD, mode, closed, lam_d_n, c_n, h_n, params, open_tol):
    """Kuhn-Tucker conditions of a converged pass: active Rankine multipliers >= 0, active
    reclosure multipliers <= 0 and not past the full closure (``r_i + dlambda_i >= 0``), the
    Drucker-Prager multiplier >= 0 (and zero when it is skipped), and no inactive criterion
    violated by more than the tolerance (Pa)."""
    rt = params[P_RT]
    ref = params[P_REF]
    tol = params[P_TOL]
    for i in range(3):
        if closed[i]:
            # fully closed: held closed by a compression beyond the reclosure stress
            if s[i] + ref > tol:
                return False
            continue
        if mode[i] == 1:
            if dlR[i] < 0.0:
                return False
        elif mode[i] == -1:
            if dlR[i] > 0.0 or r[i] + dlR[i] < -open_tol:
                return False
        else:
            if s[i] - rt > tol:
                return False
            if s[i] + ref < -tol and r[i] + dlR[i] > open_tol:
                return False
    if mode[3] == 1:
        return dlD >= 0.0
    if dlD != 0.0:
        return False
    return not _dp_violated(s, lam_d_n, dlD, c_n, h_n, params, mode)


@njit(cache=True)
def _trial_admissible(s, r, c_n, params, open_tol):
    """Whether the principal trial stress ``s`` (Pa) violates no criterion by more than the
    tolerance: ``s_i - R_t``, ``-(s_i + REF)`` where the crack is open (``r_i > open_tol``),
    ``f_D`` with ``C(lambda_n) = c_n``. The first iteration of :func:`_return_pass` then stops
    with nothing active: the step is elastic."""
    rt = params[P_RT]
    ref = params[P_REF]
    tol = params[P_TOL]
    for i in range(3):
        if s[i] - rt > tol:
            return False
        if s[i] + ref < -tol and r[i] > open_tol:
            return False
    mean = (s[0] + s[1] + s[2]) / 3.0
    q2 = 0.0
    for i in range(3):
        q2 += (s[i] - mean) * (s[i] - mean)
    return not (math.sqrt(0.5 * q2) + params[P_DELTA] * mean - c_n > tol)


@njit(cache=True)
def _correct_active_set(s, r, dlR, dlD, mode, closed, excl, lam_d_n, c_n, h_n, params,
                        open_tol):
    """Whether the pass of :func:`_return_mapping` that ended at ``s`` (with the multipliers
    ``dlR``, ``dlD`` and the active set ``mode``) must be made again, after one correction of
    the active set (``closed``, ``excl`` changed in place). The corrections, one kind per
    restart, in this order (the multipliers of a pass that needs a correction of one kind say
    nothing about the next kinds):

    1. Drucker-Prager flowed and was then skipped (three Rankine-type constraints): its flow is
       in the pass's plastic strains; redo the pass without it;
    2. a reclosure went past the full closure: that direction is closed (prescribed increment
       ``-r_i``);
    3. multipliers of the wrong sign: the most wrong one is excluded (one at a time: the others
       change once it is gone; all multipliers are strains);
    4. an excluded surface that the final stress violates is admitted again, a closed direction
       whose stress is above ``-REF`` is opened again (decided on an earlier pass, with another
       active set, neither is final).
    """
    rt = params[P_RT]
    ref = params[P_REF]
    tol = params[P_TOL]
    redo = False
    if mode[3] == 0 and dlD != 0.0:
        excl[_EXCL_D] = True
        redo = True
    if not redo:
        for i in range(3):
            if mode[i] == -1 and r[i] + dlR[i] < -open_tol:
                closed[i] = True
                redo = True
    if not redo:
        # (ties, to round-off, go to the lowest index: directions of a repeated principal
        # stress are ordered by the state, see _refine_basis)
        worst = -1
        wrong = 0.0
        for i in range(3):
            if mode[i] == 1 and -dlR[i] > wrong * (1.0 + 1e-9):
                worst = i
                wrong = -dlR[i]
            elif mode[i] == -1 and dlR[i] > wrong * (1.0 + 1e-9):
                worst = i
                wrong = dlR[i]
        if -dlD > wrong * (1.0 + 1e-9):
            worst = _EXCL_D
        elif worst >= 0 and mode[worst] == -1:
            worst += 3
        if worst >= 0:
            excl[worst] = True
            redo = True
    if not redo:
        for i in range(3):
            if closed[i] and s[i] + ref > tol:
                # a closure decided on an earlier pass that the final stress does not hold
                closed[i] = False
                redo = True
            if mode[i] != 0 or closed[i]:
                continue
            if excl[i] and s[i] - rt > tol:
                excl[i] = False
                redo = True
            if excl[3 + i] and s[i] + ref < -tol and r[i] + dlR[i] > open_tol:
                excl[3 + i] = False
                redo = True
        if excl[_EXCL_D] and _dp_violated(s, lam_d_n, dlD, c_n, h_n, params, mode):
            excl[_EXCL_D] = False
            redo = True
    return redo


@njit(cache=True)
def _search_active_sets(s_trial, r, closed, mode, lam_d_n, c_n, h_n, params, open_tol, s, dlR,
                        depD, dev, kind, Jm, fv, xs, dlD):
    """Where the corrections of :func:`_return_mapping` cycle (non-associated flow, corners,
    closures): the active sets tried in turn, fewest active surfaces first, each direction
    inactive, Rankine, or, if its crack is open, reclosure or full closure, and Drucker-Prager
    off or on. The first closest point (:func:`_closest_point`) that converges to a point
    meeting the Kuhn-Tucker conditions is the answer. Returns ``(found, dlambda_D, tried)``:
    ``dlambda_D`` that of the last set tried (``dlD`` when none was), ``tried`` the count."""
    tried = 0
    found = False
    wk = np.empty(4)
    for size in range(5):
        for code4 in range(128):
            c = code4
            cnt = 0
            ntens = 0
            nrecl = 0
            ok = True
            for i in range(3):
                opt = c % 4  # 0 inactive, 1 Rankine, 2 reclosure, 3 closed
                c //= 4
                if opt >= 2 and not r[i] > open_tol:
                    ok = False
                mode[i] = 1 if opt == 1 else (-1 if opt == 2 else 0)
                closed[i] = opt == 3
                if opt != 0:
                    cnt += 1
                if opt == 1 or opt == 2:
                    ntens += 1
                if opt == 2:
                    nrecl += 1
            mode[3] = c  # 0 or 1
            if mode[3] == 1 and ntens == 3 and nrecl == 0:
                # Drucker-Prager is skipped with three Rankine constraints (their corner,
                # R_t (1, 1, 1), satisfies it: delta R_t <= C_min <= C); with a reclosure
                # among them the corner can violate it, and the hardening (H > 0) can
                # restore it: that set is tried
                ok = False
            cnt += mode[3]
            if not ok or cnt != size:
                continue
            code, dlD = _closest_point(s_trial, r, closed, mode, lam_d_n, params, s, dlR,
                                       depD, dev, kind, Jm, fv, xs, wk)
            tried += 1
            if code == 0 and _kkt_holds(s, r, dlR, dlD, mode, closed, lam_d_n, c_n, h_n,
                                        params, open_tol):
                found = True
                break
        if found:
            break
    return found, dlD, tried


@njit(cache=True)
def _return_mapping(s, r, lam_d_n, c_n, h_n, params, open_tol, dlR, depD):
    """Return mapping from the principal trial stress ``s`` (3,) (Pa, overwritten by the
    returned stress), ``r`` (3,) = ``e_i . eps_pR . e_i`` at the start of the step,
    ``lambda_n``, ``C(lambda_n)``, ``H(lambda_n)`` (Pa); writes the Rankine/reclosure
    multipliers ``dlR`` (3,) and the principal Drucker-Prager plastic strain increments
    ``depD`` (3,). Returns ``(status, dlambda_D, iterations)``, status as
    :func:`endo3d_update`. Algorithm: module docstring (passes of :func:`_return_pass`, active
    set corrections, then a closest-point search over the active sets)."""
    E_lame = params[P_LAME]
    G = params[P_G]
    s_trial = s.copy()
    mode = np.zeros(4, dtype=np.int64)
    excl = np.zeros(7, dtype=np.bool_)  # surfaces not to activate (see _EXCL_D)
    closed = np.zeros(3, dtype=np.bool_)
    kind = np.zeros(4, dtype=np.int64)
    Jm = np.empty((4, 4))
    fv = np.empty(4)
    xs = np.empty(4)
    dev = np.empty(3)
    nD = np.empty(3)
    xR = np.empty(3)
    n_iter = 0
    status = 1
    dlD = 0.0
    for _restart in range(MAX_RESTARTS):
        code, dlD, it = _return_pass(s_trial, r, closed, excl, lam_d_n, c_n, h_n, params,
                                     open_tol, s, dlR, depD, mode, kind, Jm, fv, xs, dev, nD, xR)
        n_iter += it
        if code == 2:
            if mode[3] == 1 and not excl[_EXCL_D]:
                # the Rankine/reclosure block (diagonal M, off-diagonal lam) is always regular:
                # the degeneracy comes with Drucker-Prager (its flow no longer changes f_D once
                # the other constraints are enforced); redo the pass without it
                excl[_EXCL_D] = True
                continue
            status = 2
            break
        if code == 1:
            break
        if not _correct_active_set(s, r, dlR, dlD, mode, closed, excl, lam_d_n, c_n, h_n,
                                   params, open_tol):
            status = 0
            break
    if status == 1:
        # the rules cycle (non-associated flow, corners, closures): search the active sets
        found, dlD, tried = _search_active_sets(s_trial, r, closed, mode, lam_d_n, c_n, h_n,
                                                params, open_tol, s, dlR, depD, dev, kind, Jm,
                                                fv, xs, dlD)
        n_iter += tried
        if found:
            status = 0
    if status != 0 and dlD < 0.0:
        # the iterate written when the return mapping fails must not lower lambda_D: remove
        # its Drucker-Prager flow (the stress stays C0 : (eps - eps_pR - eps_pD))
        tr_d = depD[0] + depD[1] + depD[2]
        for i in range(3):
            s[i] += E_lame * tr_d + 2.0 * G * depD[i]
            depD[i] = 0.0
        dlD = 0.0

    return status, dlD, n_iter


# --------------------------------------------------------------------------------------------
# The Gauss-point kernel
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def _pre_peak_damage(s_eq, lam_d, d_cpp_n, params):
    """Pre-peak compressive damage ``d_cpp`` (-) after an update to the equivalent stress
    ``s_eq = sqrt(J2) - delta p`` (Pa) with ``lambda_D = lam_d``, from ``d_cpp_n``:
    ``max(d_cpp_n, d_pic x^n)``, ``x = min(s_eq / C_max, 1)``, ``n = (1 - d_pic)/d_pic``
    (``n = 1`` while ``0 < lambda_D < lambda_pk``); unchanged when ``d_pic = 0`` or
    ``s_eq <= 0``."""
    d_pic = params[P_D_PIC]
    if d_pic > 0.0 and s_eq > 0.0:
        x = min(s_eq / params[P_C_MAX], 1.0)
        if lam_d > 0.0 and lam_d < params[P_LAMBDA_PK]:
            dn = d_pic * x
        else:
            dn = d_pic * x ** params[P_EXP_CPP]
        return max(d_cpp_n, dn)
    return d_cpp_n


@njit(cache=True)
def _post_peak_damage(s, Q, epsD, d_c_n, params, xe):
    """Post-peak compressive damage ``d_c`` (-) after an update that left the Drucker-Prager
    plastic strain ``epsD`` (3x3) and the principal effective stresses ``s`` (directions
    ``Q``), from ``d_c_n``: ``max(d_c_n, kappa / (kappa + eps_kdc))`` with ``kappa = tr eps_pD
    - beta lambda_pk`` once positive; with a crushing length ``l_c`` (m), ``eps_kdc`` is scaled
    by ``l_c / L``, ``L`` the element's extent along the most compressive direction (module
    docstring)."""
    kappa = epsD[0, 0] + epsD[1, 1] + epsD[2, 2] - params[P_BETA] * params[P_LAMBDA_PK]
    d_c = d_c_n
    if kappa > 0.0:
        eps_kdc = params[P_EPS_KDC]
        if params[P_L_CRUSH] > 0.0:  # regularised: along the most compressive direction
            k_c = 0
            for k in range(1, 3):
                if s[k] < s[k_c]:
                    k_c = k
            eps_kdc *= params[P_L_CRUSH] / _extent(xe, Q, k_c)
        dn = kappa / (kappa + eps_kdc)
        d_c = max(d_c, dn)
    return d_c


@njit(cache=True)
def _principal_values(A):
    """Eigenvalues ``s1 >= s2 >= s3`` of the symmetric 3x3 ``A`` (its upper triangle read) in
    closed form (the trigonometric solution of the characteristic cubic):

        q = tr A / 3,  p = sqrt(|A - q 1|^2 / 6),  r = det((A - q 1) / p) / 2 in [-1, 1],
        phi = acos(r) / 3,  s1 = q + 2 p cos(phi),  s3 = q + 2 p cos(phi + 2 pi / 3),
        s2 = 3 q - s1 - s3

    An eigenvalue at a distance ``g`` from the others is found to about ``eps p^2 / g``
    (``eps`` the machine's): a few ulps of ``max(|q|, p)`` when the three are apart, but of
    the order of ``sqrt(eps) p`` for two that coincide (``acos`` is steep at ``r = +-1``), where
    an iterative solver keeps a few ulps. Returns ``(s1, s2, s3, q, p)`` in the units of
    ``A`` (``q`` the mean, ``p = sqrt(J2 / 3)`` of a stress)."""
    q = (A[0, 0] + A[1, 1] + A[2, 2]) / 3.0
    b00 = A[0, 0] - q
    b11 = A[1, 1] - q
    b22 = A[2, 2] - q
    a01 = A[0, 1]
    a02 = A[0, 2]
    a12 = A[1, 2]
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)
    if p2 == 0.0:
        return q, q, q, q, 0.0
    p = math.sqrt(p2 / 6.0)
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02)
           + a02 * (a01 * a12 - b11 * a02))
    r = 0.5 * det / (p * p * p)
    r = min(1.0, max(-1.0, r))
    phi = math.acos(r) / 3.0
    s1 = q + 2.0 * p * math.cos(phi)
    s3 = q + 2.0 * p * math.cos(phi + 2.0 * math.pi / 3.0)
    return s1, 3.0 * q - s1 - s3, s3, q, p


#: Bound (a fraction of ``|tr s| / 3 + 2 p``) on the error of an eigenvalue of
#: :func:`_principal_values`, whatever the gaps (``sqrt(eps)`` is 1.5e-8): the intact points'
#: shortcut decides a criterion or a sign only when the trial is farther from it than this.
_CLOSED_FORM_ERROR = 1e-7
#: Gap (a fraction of ``2 p``) between the eigenvalue whose projector the shortcut uses and its
#: neighbour, below which it leaves the point to the full update: the eigenvalue is then found
#: to within ``eps / gap``, some 1e-13 of the stresses.
_PROJECTOR_GAP = 1e-3


@njit(cache=True)
def _intact_update(s_tr, state_in, params, state_out, sigma):
    """The update of an intact point whose trial stays elastic, without eigenvectors
    (``s_tr`` exactly symmetric, as :func:`_update` makes it).

    Intact: no crack was ever opened (``eps_pR``, ``W`` and ``W_max`` all zero, so no
    tensile nor reclosure damage and no reclosure criterion) and no crushing
    (``kappa = tr eps_pD - beta lambda_pk <= 0``, so ``d_c`` keeps its value). Elastic: the
    trial effective stress ``s_tr`` (3x3, Pa) satisfies Rankine and Drucker-Prager by more
    than the error of its closed-form eigenvalues (``_CLOSED_FORM_ERROR``), so that the full
    update (:func:`_update`) would find it elastic too. It would then leave the plastic
    strains and ``lambda_D`` as they are, and give

        s~ = s_tr,   d_cpp = max(d_cpp_n, d_pic x^n)  (:func:`_pre_peak_damage`),
        sigma = (1 - d_c) (S+ + (1 - d_cpp) S-)

    with ``S+-`` the parts of ``s_tr`` of positive and negative principal values. When they
    are of one sign, one part is ``s_tr`` and the other 0. Otherwise the lone one of its sign
    ``l`` (``s1`` when only ``s1 > 0``, else ``s3``) gives its part through its spectral
    projector, written with the sum ``a + b`` and product ``a b`` of the two others, which
    do not suffer from their being close (``a + b = tr s - l``, ``a b = I2 - l (a + b)``,
    ``I2`` the second invariant):

        S_l = l (s_tr - a 1)(s_tr - b 1) / ((l - a)(l - b)),   the other part s_tr - S_l

    accurate to round-off of the stresses once ``l`` is ``_PROJECTOR_GAP`` from its neighbour
    (the denominator is then at least ``l`` times that gap). Writes ``state_out`` and
    ``sigma`` (Pa, Voigt, true shear) and returns True; returns False, having written nothing,
    when the point is not intact or its trial not clearly elastic or its split not clearly
    resolved: the full update then does it."""
    for k in range(6):
        if (state_in[S_EPS_PR + k] != 0.0 or state_in[S_W + k] != 0.0
                or state_in[S_W_MAX + k] != 0.0):
            return False
    lam_d = state_in[S_LAMBDA_D]
    tr_d = state_in[S_EPS_PD] + state_in[S_EPS_PD + 1] + state_in[S_EPS_PD + 2]
    if tr_d - params[P_BETA] * params[P_LAMBDA_PK] > 0.0:
        return False
    s1, s2, s3, mean, p = _principal_values(s_tr)
    c_n = _cohesion(lam_d, params)[0]
    rt = params[P_RT]
    sure = _CLOSED_FORM_ERROR * (abs(mean) + 2.0 * p)
    margin = params[P_TOL] - sure - _CLOSED_FORM_ERROR * (rt + c_n)
    if s1 - rt > margin:
        return False
    s_eq = _SQRT3 * p + params[P_DELTA] * mean  # sqrt(J2) - delta p; J2 = 3 p^2
    if s_eq - c_n > margin:
        return False
    # the principal split, or False when it is not clearly resolved
    gap = _PROJECTOR_GAP * 2.0 * p
    apart1 = s1 - s2 >= gap
    apart3 = s2 - s3 >= gap
    if s1 <= -sure or (s1 <= 0.0 and apart1):
        split = 0  # all compressive
    elif s3 >= sure or (s3 >= 0.0 and apart3):
        split = 1  # all tensile
    elif s2 <= 0.0 and apart1:
        split = 2  # s1 alone positive
    elif s2 > 0.0 and apart3:
        split = 3  # s3 alone negative
    else:
        return False

    for k in range(N_STATE):
        state_out[k] = state_in[k]
    _to6(s_tr, state_out, S_SIG_EFF)
    d_cpp = _pre_peak_damage(s_eq, lam_d, state_in[S_D_CPP], params)
    state_out[S_D_CPP] = d_cpp
    state_out[S_D_T] = 0.0
    state_out[S_D_T + 1] = 0.0
    state_out[S_D_T + 2] = 0.0
    state_out[S_W_OPEN_MAX] = 0.0
    state_out[S_ITER] = 1.0

    f_plus = 1.0 - state_in[S_D_C]
    f_minus = f_plus * (1.0 - d_cpp)
    if split <= 1:
        f = f_minus if split == 0 else f_plus
        sigma[0] = f * s_tr[0, 0]
        sigma[1] = f * s_tr[1, 1]
        sigma[2] = f * s_tr[2, 2]
        sigma[3] = f * s_tr[1, 2]
        sigma[4] = f * s_tr[0, 2]
        sigma[5] = f * s_tr[0, 1]
        return True
    if split == 2:
        lone, f_lone, f_rest = s1, f_plus, f_minus
    else:
        lone, f_lone, f_rest = s3, f_minus, f_plus
    i2 = (s_tr[0, 0] * s_tr[1, 1] + s_tr[0, 0] * s_tr[2, 2] + s_tr[1, 1] * s_tr[2, 2]
          - s_tr[0, 1] * s_tr[0, 1] - s_tr[0, 2] * s_tr[0, 2] - s_tr[1, 2] * s_tr[1, 2])
    a_plus_b = 3.0 * mean - lone
    ab = i2 - lone * a_plus_b
    # sigma = f_rest s_tr + (f_lone - f_rest) S_l,  S_l = g (s_tr^2 - (a + b) s_tr + a b 1)
    g = (f_lone - f_rest) * lone / (lone * lone - lone * a_plus_b + ab)
    for v in range(6):
        if v < 3:
            i = v
            j = v
        elif v == 3:
            i = 1
            j = 2
        elif v == 4:
            i = 0
            j = 2
        else:
            i = 0
            j = 1
        sq = s_tr[i, 0] * s_tr[0, j] + s_tr[i, 1] * s_tr[1, j] + s_tr[i, 2] * s_tr[2, j]
        num = sq - a_plus_b * s_tr[i, j]
        if i == j:
            num += ab
        sigma[v] = f_rest * s_tr[i, j] + g * num
    return True


@njit(cache=True)
def _open_cracks(dlR, Q, xe, W, Wm, wk):
    """The crack openings ``W`` and their maxima ``W_max`` (m, 3x3, updated in place) after
    the Rankine multipliers ``dlR`` of the step along the principal directions ``Q``: each
    opens by ``dlR_k`` times the element's extent along ``e_k`` (Hillerborg), and ``W_max``
    keeps, in the basis of ``W``, the largest opening met along each of its directions."""
    for k in range(3):
        if dlR[k] != 0.0:
            dw = dlR[k] * _extent(xe, Q, k)
            for i in range(3):
                for j in range(3):
                    W[i, j] += dw * Q[i, k] * Q[j, k]
    ww = wk[7, 1]
    Vw = wk[10]
    _eig_sym3_work(W, ww, Vw, wk[6])
    w_scale = max(ww[0], max(ww[1], ww[2]))
    if w_scale > 0.0 and _has_repeated(ww, 0.0):
        # repeated openings: W_max, then the element, order their eigenspace. With one
        # crack the repeated eigenvalue is 0, where max(W_max,kk, 0) = W_max,kk whatever
        # the basis (W_max is positive semi-definite): nothing to do
        zero = DEGENERATE_REL * w_scale
        if not (_pair_value(ww) <= zero):
            _state_basis(ww, Vw, Wm, 0.0, xe, zero)
    for k in range(3):
        ww[k] = max(ww[k], 0.0)
    # W_max in the basis of W: diagonal maxima, off-diagonal terms kept
    B = wk[11]
    _in_basis(Vw, Wm, B)
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


@njit(cache=True)
def _crack_damages(W, Wm, xe, params, wm, P, d_t, d_r, work):
    """The tensile damages ``d_t`` and the reclosure damages ``d_r`` along the principal
    directions ``P`` of the largest openings ``W_max`` (eigenvalues ``wm``, m):
    ``d_t = 1 - (w_k / (w_k + w_max))^2`` and ``d_r = 1 - (w_r / (w_r + w_cur))^2``, with
    ``w_cur = e . W . e`` the current opening along each direction (``work``: 3x3 scratch)."""
    _eig_sym3_work(Wm, wm, P, work)
    # repeated eigenvalues of W_max (one crack: (0, 0, w)): the basis of their eigenspace, where
    # the reclosure takes w_i,cur, from W, then from the element's edges (no crack: no damage)
    w_scale = max(abs(wm[0]), max(abs(wm[1]), abs(wm[2])))
    if w_scale > 0.0 and _has_repeated(wm, 0.0):
        _state_basis(wm, P, W, DEGENERATE_REL * w_scale, xe, DEGENERATE_REL * w_scale)
    w_k = params[P_W_K]
    w_r = params[P_W_R]
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


@njit(cache=True)
def _apparent_stress(s, Q, P, d_t, d_r, d_c, d_cpp, nup, sigma, wk):
    """The apparent stress ``sigma`` (Pa, Voigt) from the principal effective stresses ``s``
    (directions ``Q``): its tensile part damaged by the cracks ``d_t`` and its compressive part
    by their reclosure ``d_r`` (``_crack_damage``, along ``P``), the compressive part also by
    the pre-peak damage ``d_cpp``, and the whole by the post-peak one ``d_c``:
    ``sigma = (1 - d_c) (T+ + (1 - d_cpp) T-)``. ``nup`` is ``lambda / M`` (``wk``: work
    arrays of :func:`_update`)."""
    Sp = wk[14]
    Sp[:] = 0.0
    Sm = wk[15]
    Sm[:] = 0.0
    for k in range(3):
        sp = max(0.0, s[k])
        sm = s[k] - sp
        for i in range(3):
            for j in range(3):
                qq = Q[i, k] * Q[j, k]
                Sp[i, j] += sp * qq
                Sm[i, j] += sm * qq
    Tp = wk[16]
    Tm = wk[17]
    _crack_damage(Sp, P, d_t, nup, Tp, wk[18:21])
    _crack_damage(Sm, P, d_r, nup, Tm, wk[18:21])
    f_c = 1.0 - d_c
    f_cpp = 1.0 - d_cpp
    sigma[0] = f_c * (Tp[0, 0] + f_cpp * Tm[0, 0])
    sigma[1] = f_c * (Tp[1, 1] + f_cpp * Tm[1, 1])
    sigma[2] = f_c * (Tp[2, 2] + f_cpp * Tm[2, 2])
    sigma[3] = f_c * (0.5 * (Tp[1, 2] + Tp[2, 1]) + f_cpp * 0.5 * (Tm[1, 2] + Tm[2, 1]))
    sigma[4] = f_c * (0.5 * (Tp[0, 2] + Tp[2, 0]) + f_cpp * 0.5 * (Tm[0, 2] + Tm[2, 0]))
    sigma[5] = f_c * (0.5 * (Tp[0, 1] + Tp[1, 0]) + f_cpp * 0.5 * (Tm[0, 1] + Tm[1, 0]))


@njit(cache=True)
def _update(eps, state_in, params, xe, state_out, sigma, wk, shortcut=True):
    """:func:`endo3d_update` with the work array ``wk`` (N_WORK, 3, 3) given: the 3x3
    matrices and 3-vectors of the update are its slices, so that a batch of points allocates
    once. An intact point whose trial stays elastic takes :func:`_intact_update` (the same
    result to round-off) unless ``shortcut`` is False."""
    E_lame = params[P_LAME]
    G = params[P_G]
    M = params[P_M]
    rt = params[P_RT]
    delta = params[P_DELTA]

    # ---- trial effective stress ------------------------------------------------------------
    epsR = wk[0]
    epsD = wk[1]
    _from6(state_in, S_EPS_PR, epsR)
    _from6(state_in, S_EPS_PD, epsD)
    ee = wk[2]
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
    s_tr = wk[3]
    for i in range(3):
        for j in range(3):
            s_tr[i, j] = 2.0 * G * ee[i, j]
        s_tr[i, i] += E_lame * tr_e
    if shortcut and _intact_update(s_tr, state_in, params, state_out, sigma):
        return 0
    s = wk[4, 0]
    Q = wk[5]
    _eig_sym3_work(s_tr, s, Q, wk[6])
    _sort_desc(s, Q)  # a canonical order: the return mapping's choices go by index
    # an opening below this strain is round-off (r_i is a projection of the tensor eps_pR)
    open_tol = 1e-10 * rt / params[P_E]
    if _has_repeated(s, 0.0):
        # repeated principal trial stresses: the basis of their eigenspace, where the flows,
        # the reclosure criterion (e_i . eps_pR . e_i) and the Hillerborg lengths are taken,
        # from the state: eps_pR, then W, then the element's edges (frame-independent)
        _trial_basis(s, Q, epsR, state_in, xe, open_tol)

    # Rankine plastic strain in the principal directions (for the reclosure criterion)
    r = wk[4, 1]
    for i in range(3):
        acc = 0.0
        for k in range(3):
            for m in range(3):
                acc += Q[k, i] * epsR[k, m] * Q[m, i]
        r[i] = acc

    # ---- return mapping (principal space) -------------------------------------------------------
    # mode[i] (i < 3): 1 Rankine tension, -1 crack reclosure, 0 inactive on principal direction
    # i; mode[3]: 1 Drucker-Prager active (see _return_mapping). An admissible trial stress
    # (the common, elastic case) skips it and its work arrays.
    lam_d_n = state_in[S_LAMBDA_D]
    c_n, h_n = _cohesion(lam_d_n, params)
    dlR = wk[4, 2]
    dlR[:] = 0.0
    depD = wk[7, 0]
    depD[:] = 0.0
    if _trial_admissible(s, r, c_n, params, open_tol):
        status = 0
        dlD = 0.0
        n_iter = 1
    else:
        status, dlD, n_iter = _return_mapping(s, r, lam_d_n, c_n, h_n, params, open_tol, dlR,
                                              depD)

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
    W = wk[8]
    Wm = wk[9]
    _from6(state_in, S_W, W)
    _from6(state_in, S_W_MAX, Wm)
    if dlR[0] != 0.0 or dlR[1] != 0.0 or dlR[2] != 0.0:
        _open_cracks(dlR, Q, xe, W, Wm, wk)
        _to6(W, state_out, S_W)
        _to6(Wm, state_out, S_W_MAX)

    # ---- damages -------------------------------------------------------------------------------
    wm = wk[7, 2]
    P = wk[12]
    d_t = wk[13, 0]
    d_r = wk[13, 1]
    _crack_damages(W, Wm, xe, params, wm, P, d_t, d_r, wk[6])
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
    d_cpp = _pre_peak_damage(s_eq, lam_d, state_in[S_D_CPP], params)
    state_out[S_D_CPP] = d_cpp

    d_c = _post_peak_damage(s, Q, epsD, state_in[S_D_C], params, xe)
    state_out[S_D_C] = d_c

    # ---- apparent stress -------------------------------------------------------------------------
    _apparent_stress(s, Q, P, d_t, d_r, d_c, d_cpp, E_lame / M, sigma, wk)
    return status


@njit(cache=True)
def endo3d_update(eps, state_in, params, xe, state_out, sigma):
    """Update one Gauss point from ``state_in`` to the total strain ``eps``.

    ``eps`` (6,): total strain, Voigt [xx, yy, zz, yz, xz, xy], engineering shear (-).
    ``state_in`` (N_STATE,): converged state of the previous step (read only).
    ``params`` (N_PARAMS,): from :func:`endo3d_params`.
    ``xe`` (nodes, 3): node coordinates (m) of the element (a hexahedron or a tetrahedron),
    for the Hillerborg lengths.
    ``state_out`` (N_STATE,): written. ``sigma`` (6,): apparent stress (Pa), true shear, written.
    Returns 0 (the written state satisfies the Kuhn-Tucker conditions of the return mapping),
    or 1 when no active set satisfies them (cutting-plane passes not converged or cycling,
    and the closest-point search found none), or 2 when its linear system was (numerically)
    singular; in both cases the last iterate is written (``lambda_D`` not decreased) and the
    caller should retry the step (e.g. with a smaller one).
    """
    return _update(eps, state_in, params, xe, state_out, sigma, np.empty((N_WORK, 3, 3)))


#: ``_update`` for the batch kernels of other modules (``materials.blocks``): one point, with
#: the caller's work array ``wk`` (N_WORK, 3, 3); the arguments and the status as
#: :func:`endo3d_update`
update_point = _update


@njit(cache=True)
def endo3d_update_all(eps, state_in, params, xe_of_point, state_out, sigma):
    """Update ``ngp`` Gauss points: ``eps`` (ngp, 6), ``state_in``/``state_out``
    (ngp, N_STATE), ``xe_of_point`` (ngp, 8, 3) the nodes of the element of each point (m),
    ``sigma`` (ngp, 6) written (Pa). Plain loop. Returns the number of points whose return
    mapping did not converge (status > 0)."""
    nfail = 0
    wk = np.empty((N_WORK, 3, 3))
    for g in range(eps.shape[0]):
        st = _update(eps[g], state_in[g], params, xe_of_point[g], state_out[g], sigma[g], wk)
        if st != 0:
            nfail += 1
    return nfail


@njit(cache=True)
def endo3d_update_elements(eps, state_in, params, xe, elem_of_point, state_out, sigma):
    """As :func:`endo3d_update_all` with the node coordinates given per element: ``xe``
    (nel, 8, 3) and ``elem_of_point`` (ngp,) int64, the element of each point. Returns the
    number of points whose return mapping did not converge."""
    nfail = 0
    wk = np.empty((N_WORK, 3, 3))
    for g in range(eps.shape[0]):
        st = _update(
            eps[g], state_in[g], params, xe[elem_of_point[g]], state_out[g], sigma[g], wk
        )
        if st != 0:
            nfail += 1
    return nfail


@njit(cache=True, nogil=True)
def endo3d_tangent_elements(eps, state_in, params, xe, elem_of_point, sigma, delta, C):
    """Consistent tangent ``C[g] = d sigma / d eps`` (ngp, 6, 6; Pa, engineering shear) of
    each point's update from ``state_in`` at the strains ``eps``, by forward differences:

        C[g, :, j] = (sigma(eps_g + delta e_j) - sigma(eps_g)) / delta

    ``sigma`` (ngp, 6): the points' stresses at ``eps`` (their last update, so that only the
    six perturbed updates are made here); ``xe``, ``elem_of_point`` as in
    :func:`endo3d_update_elements`. The perturbed states are scratch."""
    wk = np.empty((N_WORK, 3, 3))
    e = np.empty(6)
    st = np.empty(N_STATE)
    sp = np.empty(6)
    for g in range(eps.shape[0]):
        for j in range(6):
            for i in range(6):
                e[i] = eps[g, i]
            e[j] += delta
            _update(e, state_in[g], params, xe[elem_of_point[g]], st, sp, wk)
            for i in range(6):
                C[g, i, j] = (sp[i] - sigma[g, i]) / delta
