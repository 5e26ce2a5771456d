r"""The joint law: a frictional cohesive zone (FCZM) in series with an elastic spring.

One law per contact point and per unit area (model.md section 2). Sign conventions: the normal
relative displacement ``u_n > 0`` opens the joint, the normal traction ``T_n > 0`` is tension.
Displacements are measured from the initial state (the initial gap is already subtracted).

Series split of the total relative displacement ``u`` (m) into a cohesive and a spring part::

    u = u_c + u_s,      T = (1 - d_spring) K^spring u_s = T_coh + T_fric        (Pa)

Cohesion: ``T_coh = beta b (K_I^coh u_c,n, K_II^coh u_c,t)`` with the integrity ``beta`` in [0, 1]
and the constant initial integrity ``b = 1 - d_coh,0``. Signorini on ``u_c,n >= 0``; Coulomb
friction on the rate of ``u_c,t``, active in compression only, with
``mu_eff = mu (1 - beta b)^p``. The integrity follows the exponential envelope of model.md::

    beta_env(nu) = sigma_e / (b k nu) exp(phi (delta_e - nu))   for delta_e < nu <= nu_u

and is irreversible: ``beta = min(beta_old, beta_env)``.

The local problem of one time step
----------------------------------
Inside a step the integrity is frozen. The contact point sees the rest of the system through
a compliance ``A`` (m/Pa, symmetric positive semi-definite, 3x3) and a predictor ``u~`` (m)::

    u_{n+1} = u~ - A T          (A = theta h^2 S W_aa for NSCD; A = 0 for a driven point)

so that ``u_c = u~ - (A + C_s) T`` with the spring compliance ``C_s = diag(c_n, c_t, c_t)``,
``c = 1 / ((1 - d_spring) K^spring)``. The solver tries the statuses in turn, each in closed form:

* open (``u_c,n > 0``, no friction): ``(I + D kappa) u_c = u~`` with ``D = A + C_s``,
  ``kappa = beta b diag(K_I^coh, K_II^coh, K_II^coh)``;
* stick (``u_c,n = 0``, ``u_c,t`` unchanged): ``T = D^-1 (u~ - u_c)``, valid while
  ``|T_t - kappa_t u_c,t| <= mu_eff (-T_n)``;
* slide: ``T_t = kappa_t u_c,t + mu_eff N e`` with ``e`` the slip direction and ``N = -T_n``.
  For a given ``N`` the slip solves a strongly convex 2-D problem (one scalar root); the
  slide is then a root ``N >= 0`` of the scalar ``h(N) = N(slip(N)) - N`` (see ``_slide``),
  unique whenever the normal-tangential coupling of ``D`` is small against its tangential
  stiffness (``mu_eff |G_nt| < lambda_min(G_tt + kappa_t)``, ``G = D^-1``), and linear for
  ``mu_eff = 0``.

Dry Signorini-Coulomb is this same law with ``b = 0`` (no cohesion, ``mu_eff = mu``) and no spring.

The compressive normal spring is ``(1 - d_spring) K_I^spring`` (the study's equation 2, switch
``damaged``) or ``K_I^spring`` (switch ``undamaged``, as the reference code LMGC90 does in 3D).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from masonry_nscd.contact.laws.common import (  # noqa: F401 (re-exported for the law's users)
    KIND_GLUED,
    KIND_JOINT,
    N_COLUMNS,
    P_LAW,
    ST_AMBIGUOUS,
    ST_GLUED,
    ST_OPEN,
    ST_SLIDE,
    ST_STICK,
    solve3,
    solve3_values,
)

NAMES = ("fczm", "coulomb", "dry")  # the case's joint.law values this module serves
CODE = 0  # its code in column P_LAW

# --- layout of the parameter vector of one joint law (float64) ----------------------------
P_CN_T = 0  # normal spring compliance in tension, m/Pa
P_CN_C = 1  # normal spring compliance in compression, m/Pa
P_CT = 2  # tangential spring compliance, m/Pa
P_KI = 3  # K_I^coh, Pa/m
P_KII = 4  # K_II^coh, Pa/m
P_B = 5  # initial integrity b = 1 - d_coh,0
P_MU = 6  # friction coefficient
P_P = 7  # friction growth exponent
P_D1 = 8  # delta_1 = sigma_I^e / K_I^coh, m
P_D2 = 9  # delta_2 = sigma_II^e / K_II^coh, m
P_GI = 10  # G_fI, J/m^2
P_GII = 11  # G_fII, J/m^2
P_ETA = 12  # residual integrity at full failure


def joint_params(
    *,
    K_I_spring: float = 4.3e11,
    K_II_spring: float = 1.8e11,
    d_spring: float = 0.953,
    sigma_I_e: float = 0.05e6,
    K_I_coh: float = 1.21e11,
    G_fI: float = 3.0,
    sigma_II_e: float = 0.27e6,
    K_II_coh: float = 2.8e11,
    G_fII: float = 206.0,
    d_coh_initial: float = 0.99944,
    mu: float = 0.7,
    p: float = 1.0,
    eta: float = 1e-4,
    compression_spring: str = "damaged",
    law: str = "fczm",
    K_n: float | None = None,
    K_t: float | None = None,
) -> np.ndarray:
    """Pack the joint parameters (SI units, model.md Table 3) into a float64 vector.

    ``law='coulomb'`` gives dry Signorini-Coulomb: no cohesion (b = 0), no spring (zero
    compliance), friction coefficient ``mu``. ``law='dry'`` gives a dry joint: no cohesion,
    a spring of normal and tangential stiffnesses ``K_n``, ``K_t`` (Pa/m) in series with
    Signorini-Coulomb contact (the closure of a rough joint), so that
    ``T_n = K_n <u_n>_-`` and ``|T_t| <= mu |T_n|``: the b = 0 limit of the law, which the
    Newton solver takes.
    """
    P = np.zeros(N_COLUMNS)
    P[P_LAW] = CODE
    P[P_MU] = mu
    P[P_P] = p
    P[P_ETA] = eta
    if law in ("coulomb", "dry"):
        # no cohesion: the envelope is never evaluated (b = 0); its columns stay finite
        P[P_KI] = K_I_coh
        P[P_KII] = K_II_coh
        P[P_D1] = sigma_I_e / K_I_coh
        P[P_D2] = sigma_II_e / K_II_coh
        P[P_GI] = G_fI
        P[P_GII] = G_fII
        if law == "dry":
            if not (K_n is not None and K_n > 0.0 and K_t is not None and K_t > 0.0):
                raise ValueError(f"the dry law needs K_n > 0 and K_t > 0 (Pa/m), got {K_n}, {K_t}")
            P[P_CN_T] = P[P_CN_C] = 1.0 / K_n
            P[P_CT] = 1.0 / K_t
        return P
    if law != "fczm":
        raise ValueError(f"unknown joint law {law!r}: allowed 'fczm', 'coulomb' or 'dry'")
    if compression_spring not in ("damaged", "undamaged"):
        raise ValueError("compression_spring must be 'damaged' or 'undamaged'")
    P[P_CN_T] = 1.0 / ((1.0 - d_spring) * K_I_spring)
    P[P_CN_C] = P[P_CN_T] if compression_spring == "damaged" else 1.0 / K_I_spring
    P[P_CT] = 1.0 / ((1.0 - d_spring) * K_II_spring)
    P[P_KI] = K_I_coh
    P[P_KII] = K_II_coh
    P[P_B] = 1.0 - d_coh_initial
    P[P_D1] = sigma_I_e / K_I_coh
    P[P_D2] = sigma_II_e / K_II_coh
    P[P_GI] = G_fI
    P[P_GII] = G_fII
    return P


@njit(cache=True)
def mixed_mode(ucn: float, uct2: float, P: np.ndarray):
    """Mixed-mode quantities of the envelope for a cohesive opening (u_c,n, |u_c,t|^2).

    Returns ``(nu, delta_e, sigma_e, k, phi, nu_u)`` in m, m, Pa, Pa/m, 1/m, m. Written with the
    weights ``a = <u_c,n>_+^2`` and ``c = |u_c,t|^2`` (so ``m = c / a``) to stay finite in pure
    mode II (``m = infinity``).
    """
    a = ucn * ucn if ucn > 0.0 else 0.0
    c = uct2
    nu = math.sqrt(a + c)
    d1 = P[P_D1]
    d2 = P[P_D2]
    if a + c <= 0.0:
        a = 1.0  # no opening: take pure mode I (only delta_e is used then)
    else:  # only the mixity c / a matters: weights scaled to a + c = 1, so that the tiny
        # openings of round-off (u ~ 1e-156 m) cannot underflow ``den`` to zero
        s = a + c
        a /= s
        c /= s
    den = d2 * d2 * a + d1 * d1 * c
    delta_e = d1 * d2 * math.sqrt((a + c) / den)
    G = (d2 * d2 * a * P[P_GI] + d1 * d1 * c * P[P_GII]) / den
    k = math.sqrt((P[P_KI] ** 2 * a + P[P_KII] ** 2 * c) / (a + c))
    sigma_e = k * delta_e
    phi = sigma_e / (G - 0.5 * sigma_e * delta_e)
    nu_u = delta_e - math.log(P[P_ETA]) / phi
    return nu, delta_e, sigma_e, k, phi, nu_u


@njit(cache=True)
def envelope_integrity(ucn: float, uct1: float, uct2: float, beta_old: float, P: np.ndarray):
    """Irreversible integrity ``beta = min(beta_old, beta_env(u_c))`` (dimensionless)."""
    b = P[P_B]
    if b <= 0.0:
        return beta_old
    nu, delta_e, sigma_e, k, phi, nu_u = mixed_mode(ucn, uct1 * uct1 + uct2 * uct2, P)
    if nu <= delta_e:
        return beta_old
    if nu >= nu_u:
        return 0.0
    env = sigma_e / (b * k * nu) * math.exp(phi * (delta_e - nu))
    return min(beta_old, env)


@njit(cache=True)
def _norm2(x: float, y: float) -> float:
    """``sqrt(x^2 + y^2)`` without the underflow (or overflow) of the squares."""
    r = math.sqrt(x * x + y * y)
    if r < 1e-150 or r > 1e150:
        return math.hypot(x, y)
    return r


@njit(cache=True)
def _tangential_slip(r1, r2, h11, h12, h22, hmin, hmax, phi, lam):
    """Slip of a closed point for a given friction bound ``phi = mu_eff N`` (Pa).

    Solves ``r0 = H s + phi e`` for the slip ``s = lam e`` (m; ``lam > 0``, ``|e| = 1``), with
    ``r0 = (r1, r2)`` (Pa) and ``H = [[h11, h12], [h12, h22]]`` (Pa/m, symmetric positive
    definite, eigenvalues ``hmin <= hmax``); ``s = 0`` when ``|r0| <= phi``. This is the
    stationarity of the strongly convex ``s.H s / 2 + phi |s| - r0.s`` (J/m^2), so ``s`` is
    unique. For ``phi = 0`` (or a ``phi`` below the round-off of ``r0``): ``s = H^-1 r0``.
    Otherwise, with ``m = lam / phi`` (m/Pa) and ``q = r0 / phi`` (``|q| > 1``), the equation
    reads ``(m H + I) e = q``, so ``e = (m H + I)^-1 q`` and ``m`` is the root of

        psi(m) = 1 / |(m H + I)^-1 q| - 1        (dimensionless)

    which is increasing (in the eigenbasis of H, ``|.|^2 = sum q_i^2 / (m h_i + 1)^2``),
    linear when H is isotropic, and bracketed by ``(|q| - 1) / hmax <= m <= (|q| - 1) /
    hmin``; Newton's method kept in the bracket converges in a few steps. Written in ``m``
    and ``q`` the iteration is free of the units of the tractions, so the tiny tractions of
    round-off-sized displacements do not underflow. ``lam`` on input is a first guess (m,
    <= 0: none; then ``m = (|q| - 1) / h_q`` with ``h_q`` the Rayleigh quotient of H along
    q, exact when q is an eigenvector of H).

    Returns ``(s1, s2, lam, t1, t2)`` with ``t = -ds/dphi = J^-1 e`` (m/Pa), ``J = H + phi /
    lam (I - e e^T)`` the derivative of ``H s + phi s / |s|`` with respect to ``s``
    (``t = 0`` where ``s = 0``).
    """
    rn = _norm2(r1, r2)
    if not (rn < math.inf and phi >= 0.0):
        # a non-finite load: a non-finite slip, which the integrator's check of the
        # tractions reports (DivergenceError, naming the step), not a division by phi = 0
        return math.nan, math.nan, math.nan, math.nan, math.nan
    if rn <= phi or rn == 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    if phi <= 1e-17 * rn:
        idet = 1.0 / (h11 * h22 - h12 * h12)
        s1 = (h22 * r1 - h12 * r2) * idet
        s2 = (h11 * r2 - h12 * r1) * idet
        lam = _norm2(s1, s2)
        if lam == 0.0:
            return 0.0, 0.0, 0.0, 0.0, 0.0
        e1 = s1 / lam
        e2 = s2 / lam
        return s1, s2, lam, (h22 * e1 - h12 * e2) * idet, (h11 * e2 - h12 * e1) * idet
    q1 = r1 / phi
    q2 = r2 / phi
    a = rn / phi - 1.0
    lo = a / hmax
    hi = a / hmin
    if lam > 0.0:
        m = lam / phi
    else:
        qq = q1 * q1 + q2 * q2
        m = a * qq / (q1 * (h11 * q1 + h12 * q2) + q2 * (h12 * q1 + h22 * q2))
    m = min(max(m, lo), hi)
    w1 = 0.0
    w2 = 0.0
    last = False
    for _ in range(100):
        m11 = m * h11 + 1.0
        m12 = m * h12
        m22 = m * h22 + 1.0
        idet = 1.0 / (m11 * m22 - m12 * m12)
        w1 = (m22 * q1 - m12 * q2) * idet
        w2 = (m11 * q2 - m12 * q1) * idet
        if last:
            break
        wn = math.sqrt(w1 * w1 + w2 * w2)
        psi = 1.0 / wn - 1.0
        if psi == 0.0:
            break
        if psi < 0.0:
            lo = m
        else:
            hi = m
        # d psi / d m = -w.w' / |w|^3 with w' = -(m H + I)^-1 H w
        z1 = h11 * w1 + h12 * w2
        z2 = h12 * w1 + h22 * w2
        dw1 = -(m22 * z1 - m12 * z2) * idet
        dw2 = -(m11 * z2 - m12 * z1) * idet
        dpsi = -(w1 * dw1 + w2 * dw2) / (wn * wn * wn)
        new = m - psi / dpsi if dpsi > 0.0 else lo
        if dpsi > 0.0 and lo < new < hi:
            # the round-off floor of m is eps |q| / h = eps (m + 1 / h); a Newton step this
            # small leaves an error of its square: take it and stop
            last = abs(new - m) <= 1e-8 * (m + 1.0 / hmax)
        else:
            new = 0.5 * (lo + hi)
            if new == lo or new == hi:
                break
        m = new
    wn = math.sqrt(w1 * w1 + w2 * w2)
    e1 = w1 / wn
    e2 = w2 / wn
    lam = m * phi
    c = 1.0 / m  # phi / lam, Pa/m (m >= lo > 0: |r0| > phi gives |q| - 1 >= 2^-52)
    # t = J^-1 e with J = H + c e' e'^T (e' = e turned by 90 degrees, |e| = 1), written
    # without J's entries: det J = det H + c e.H.e and adj(J) e = adj(H) e + c e. From J's
    # entries, c (1 - e1^2) (1 - e2^2) - (c e1 e2)^2 cancels to round-off when the slip
    # starts (|r0| a few ulps above phi: c = phi / lam ~ 1e24 Pa/m), and det J can come out 0
    eHe = e1 * (h11 * e1 + h12 * e2) + e2 * (h12 * e1 + h22 * e2)
    idet = 1.0 / (hmin * hmax + c * eHe)
    return (lam * e1, lam * e2, lam, (h22 * e1 - h12 * e2 + c * e1) * idet,
            (h11 * e2 - h12 * e1 + c * e2) * idet)


@njit(cache=True)
def _normal_root(N0, g1, g2, gn, r1, r2, rn, h11, h12, h22, hmin, hmax, mu_eff, h, s1, s2,
                 lam, t1, t2):
    """The root ``N`` (Pa) of ``h(N) = N0 + g.s(mu_eff N) - N`` for :func:`_slide`, from the
    frictionless slide: ``h = h(0)``, its slip ``s`` (m), ``lam = |s|`` and ``t = -ds/dphi``.
    Newton's method kept inside a bracket, after a scan of ``[0, hi]`` for a sign change when
    ``h(0) < 0`` and ``kappa >= 1`` (:func:`_slide`'s docstring). Returns ``(found, N, s1, s2,
    lam)``: whether a root was found, and the slip and its length there."""
    gs = g1 * s1 + g2 * s2
    # bracket [xl, xr] of a root of h: h >= 0 at xl when pos_left, at xr otherwise
    hi = min(rn / mu_eff, N0 + gn * rn / hmin)  # h(hi) <= 0
    xl = 0.0
    xr = hi
    pos_left = True
    N = 0.0
    if h < 0.0:
        if mu_eff * gn < hmin:
            return False, N, s1, s2, lam  # h decreases strictly: no root
        # kappa >= 1: sample h on [0, hi] for a sign change
        n_scan = 32
        pos_left = False
        for k in range(1, n_scan + 1):
            N = hi * k / n_scan
            s1, s2, lam, t1, t2 = _tangential_slip(r1, r2, h11, h12, h22, hmin, hmax,
                                                   mu_eff * N, lam)
            gs = g1 * s1 + g2 * s2
            h = N0 + gs - N
            if h >= 0.0:
                xr = N
                break
            xl = N
        if h < 0.0:
            return False, N, s1, s2, lam
    dh = -1.0 - mu_eff * (g1 * t1 + g2 * t2)
    # Newton on h, kept inside the bracket
    converged = False
    for _ in range(100):
        if h == 0.0:
            converged = True
            break
        if (h > 0.0) == pos_left:
            xl = N
        else:
            xr = N
        new = N - h / dh if dh < 0.0 else xl
        scale = abs(N0) + abs(gs) + N
        if dh < 0.0 and xl <= new <= xr:
            if abs(new - N) <= 1e-8 * scale:
                # last step: s to first order, s(phi + dphi) = s - t dphi, which
                # zeroes h exactly and leaves O(dphi^2) in the tangential equation
                dphi = mu_eff * (new - N)
                s1 -= t1 * dphi
                s2 -= t2 * dphi
                lam = _norm2(s1, s2)
                N = new
                converged = True
                break
        else:
            new = 0.5 * (xl + xr)
            if xr - xl <= 1e-15 * scale:
                converged = True
                break
        # first guess of the slip length: lam - e.t dphi
        if lam > 0.0:
            lam -= ((s1 * t1 + s2 * t2) / lam) * (mu_eff * (new - N))
        N = new
        s1, s2, lam, t1, t2 = _tangential_slip(r1, r2, h11, h12, h22, hmin, hmax,
                                               mu_eff * N, lam)
        gs = g1 * s1 + g2 * s2
        h = N0 + gs - N
        dh = -1.0 - mu_eff * (g1 * t1 + g2 * t2)
    return converged, N, s1, s2, lam


@njit(cache=True)
def _slide(a, b, c, d, e, f, v0, v1, v2, T, u0_1, u0_2, kt, mu_eff, uc) -> int:
    """Sliding contact: ``u_c,n = 0``, Coulomb at its limit, slip along the friction traction.

    On entry ``a, b, c`` are the diagonal of the compliance ``D`` (m/Pa) and ``d, e, f`` the
    entries (0, 1), (0, 2), (1, 2) of its symmetric part, ``v = (u~_n, u~_t - u0)`` (m), with
    ``u0`` the cohesive slip at the start of the step, and ``T`` holds the stick traction
    ``T0 = D^-1 v`` (Pa) from the solve of the stick status; on success ``T`` and ``uc`` hold
    the slide.
    Equations, with ``G = D^-1`` (Pa/m; D symmetric positive definite) and the slip ``s`` (m)
    of the step, ``u_c,t = u0 + s``::

        T(s) = T0 - G[:, t] s                       (Pa)   kinematics, D T = u~ - u_c
        N(s) = -T_n(s) = N0 + g.s,  N0 = -T0_n,  g = G[n, t]   (Pa, Pa/m)
        R(s) = T_t(s) - kt u_c,t = r0 - H s,   r0 = T0_t - kt u0,  H = G[t, t] + kt I
        slide:  R = mu_eff N e,  s = lam e,  lam > 0,  |e| = 1,  N >= 0

    For a given ``N`` the tangential equation ``r0 = H s + mu_eff N e`` has exactly one
    solution ``s(mu_eff N)`` (``_tangential_slip``), so the slides are the roots in
    ``[0, |r0| / mu_eff)`` of the scalar function

        h(N) = N0 + g.s(mu_eff N) - N          (Pa).

    ``s`` is Lipschitz in ``phi = mu_eff N`` with constant ``1 / hmin`` (``hmin`` the smallest
    eigenvalue of H: subtract the equations at two values of phi and dot with the difference of
    the slips), so ``h' <= -(1 - kappa)`` with ``kappa = mu_eff |g| / hmin``. When ``kappa < 1``
    (a normal-tangential coupling of D small against its tangential stiffness, as expected
    where a joint's spring adds to the diagonal) h decreases strictly: there is at most one
    slide, and there is one exactly when ``h(0) >= 0``, i.e. when the frictionless slide
    ``s = H^-1 r0`` is in compression (``h < 0`` at ``N = |r0| / mu_eff``, where ``s = 0``,
    because the stick failed; ``h <= 0`` at ``N0 + |g| |r0| / hmin``, since
    ``|s| <= |r0| / hmin``). With ``mu_eff = 0`` the slide is linear: ``s = H^-1 r0``,
    ``N = h(0)``, and it exists when ``N >= 0``. The root is found by Newton's method on h
    (``h' = -1 - mu_eff g.t``, ``t = -ds/dphi`` from ``_tangential_slip``) kept inside the
    bracket, from ``N = 0``: when the coupling is small the first step lands on ``N ~ N0``. A
    last step smaller than 1e-8 of the scale of h is taken to first order in s
    (``s - t dphi``), which zeroes h and leaves an error of its square. When ``kappa >= 1`` (a
    dry contact with a strongly coupled compliance) several slides may exist; if ``h(0) < 0``,
    h is sampled on the bracket and the first sign change is refined. A value of ``h(0)``
    within 1e-13 of the terms it sums (``h(0) = -G_nn v_n - g.(v_t - s)``) is taken as zero:
    a slide at ``N = 0``, which is also the open status with ``u_c,n = 0`` (the boundary
    between the two, where one of them must be taken). The tractions are those of the law,
    ``T_n = -N``, ``T_t = kt u_c,t + mu_eff N e``; they meet the
    kinematics to the tolerance of the roots. Everything is written with invariants of the
    tangent plane, so the result does not depend on the tangent frame (up to round-off).
    Returns ST_SLIDE, or ST_STICK where the stick test of ``local_solve`` failed by the
    round-off of its solve only (the stick holds with the traction recomputed here), or -1
    when no slide exists; ``T`` is then left as it came.
    """
    # G = D^-1 by cofactors of the symmetric part of D
    c00 = b * c - f * f
    c01 = e * f - d * c
    c02 = d * f - b * e
    det = a * c00 + d * c01 + e * c02
    if not det > 0.0:
        return -1
    idet = 1.0 / det
    g1 = c01 * idet
    g2 = c02 * idet
    g11 = (a * c - e * e) * idet
    g12 = (d * e - a * f) * idet
    g22 = (a * b - d * d) * idet
    h11 = g11 + kt
    h12 = g12
    h22 = g22 + kt
    hmax = 0.5 * (h11 + h22) + math.sqrt(0.25 * (h11 - h22) ** 2 + h12 * h12)
    hmin = (h11 * h22 - h12 * h12) / hmax
    if not hmin > 0.0:
        return -1
    gn = _norm2(g1, g2)
    if gn == 0.0:
        T0n = T[0]
        T0t1 = T[1]
        T0t2 = T[2]
    else:
        # T0 = G v again: the partial pivoting of the stick's solve, on a D whose normal and
        # tangential compliances differ by orders, can take T0_n from a cancelling difference
        # (a relative error of 1e-12 where |T0_n| ~ |D_nt T_t| / D_nn); the cofactors are
        # invariant under a diagonal scaling of D, and their terms bound the round-off of h
        T0n = c00 * idet * v0 + g1 * v1 + g2 * v2
        T0t1 = g1 * v0 + g11 * v1 + g12 * v2
        T0t2 = g2 * v0 + g12 * v1 + g22 * v2
    N0 = -T0n
    r1 = T0t1 - kt * u0_1
    r2 = T0t2 - kt * u0_2
    rn = _norm2(r1, r2)
    if gn > 0.0 and N0 >= 0.0 and rn <= mu_eff * N0:
        # the stick holds with these values: its test failed by the round-off of its solve
        # (r0 is a difference of tangential tractions, which can carry a round-off of
        # eps |G_tn v_n| far above a small friction bound)
        T[0] = T0n
        T[1] = T0t1
        T[2] = T0t2
        uc[0] = 0.0
        uc[1] = u0_1
        uc[2] = u0_2
        return ST_STICK
    if gn == 0.0:
        # the normal traction does not depend on the slip (D uncoupled): h(N) = N0 - N
        if N0 < 0.0:
            return -1
        N = N0
        s1, s2, lam, t1, t2 = _tangential_slip(r1, r2, h11, h12, h22, hmin, hmax, mu_eff * N,
                                               0.0)
    else:
        # frictionless slide (N = 0)
        s1, s2, lam, t1, t2 = _tangential_slip(r1, r2, h11, h12, h22, hmin, hmax, 0.0, 0.0)
        gs = g1 * s1 + g2 * s2
        h = N0 + gs
        # the round-off of h = -G_nn v_n - g.(v_t - s) (Pa), a normal traction within it of
        # zero being zero: that of the terms it sums
        tiny = 1e-13 * (abs(c00 * idet * v0) + abs(g1 * v1) + abs(g2 * v2)
                        + abs(g1 * s1) + abs(g2 * s2))
        N = max(h, 0.0)
        if mu_eff <= 0.0 or abs(h) <= tiny:
            # the linear frictionless slide, or a slide at N = 0 up to round-off
            if h < -tiny:
                return -1
        else:
            found, N, s1, s2, lam = _normal_root(N0, g1, g2, gn, r1, r2, rn, h11, h12, h22,
                                                 hmin, hmax, mu_eff, h, s1, s2, lam, t1, t2)
            if not found:
                return -1
    if s1 == 0.0 and s2 == 0.0:
        return -1  # a slide of zero length is the stick, which was refused
    # tractions from the law (N >= 0 the root, R = mu_eff N e); they meet the kinematics
    # D T = u~ - u_c to the tolerance of the root
    phi = mu_eff * N
    T[0] = -N
    T[1] = kt * (u0_1 + s1) + phi * (s1 / lam)  # (phi s1 could be subnormal)
    T[2] = kt * (u0_2 + s2) + phi * (s2 / lam)
    uc[0] = 0.0
    uc[1] = u0_1 + s1
    uc[2] = u0_2 + s2
    return ST_SLIDE


@njit(cache=True)
def local_solve(
    ut: np.ndarray,
    A: np.ndarray,
    uc_old: np.ndarray,
    beta: float,
    P: np.ndarray,
    T: np.ndarray,
    uc: np.ndarray,
) -> int:
    """Solve the local problem of one contact point for one step (frozen integrity).

    Inputs: predictor ``ut`` (m), compliance ``A`` (m/Pa), cohesive displacement at the start of
    the step ``uc_old`` (m), integrity ``beta``, parameters ``P``.
    Outputs written in place: traction ``T`` (Pa, tension positive) and cohesive displacement
    ``uc`` (m) at the end of the step. Returns the status code (ST_*).
    """
    b = P[P_B]
    kn = beta * b * P[P_KI]
    kt = beta * b * P[P_KII]
    mu_eff = P[P_MU] * (1.0 - beta * b) ** P[P_P]
    # scalars, not 3x3 arrays: the joint law runs this several times per point and evaluation

    # --- open: no friction, Signorini inactive ------------------------------------------
    # the compliance D = A + diag(c_n,t, c_t, c_t)
    d00 = A[0, 0] + P[P_CN_T]
    d01 = A[0, 1]
    d02 = A[0, 2]
    d10 = A[1, 0]
    d11 = A[1, 1] + P[P_CT]
    d12 = A[1, 2]
    d20 = A[2, 0]
    d21 = A[2, 1]
    d22 = A[2, 2] + P[P_CT]
    # (I + D diag(kn, kt, kt)) u_c = u~
    solved, x0, x1, x2 = solve3_values(
        1.0 + d00 * kn, 0.0 + d01 * kt, 0.0 + d02 * kt,
        0.0 + d10 * kn, 1.0 + d11 * kt, 0.0 + d12 * kt,
        0.0 + d20 * kn, 0.0 + d21 * kt, 1.0 + d22 * kt, ut[0], ut[1], ut[2])
    if solved and x0 > 0.0:
        uc[0] = x0
        uc[1] = x1
        uc[2] = x2
        T[0] = kn * x0
        T[1] = kt * x1
        T[2] = kt * x2
        return ST_OPEN

    # --- closed: stick ----------------------------------------------------------------------
    d00 += P[P_CN_C] - P[P_CN_T]
    v0 = ut[0]
    v1 = ut[1] - uc_old[1]
    v2 = ut[2] - uc_old[2]
    solved, t0, t1, t2 = solve3_values(d00, d01, d02, d10, d11, d12, d20, d21, d22, v0, v1, v2)
    if solved:
        T[0] = t0
        T[1] = t1
        T[2] = t2
        if T[0] <= 0.0:
            r1 = T[1] - kt * uc_old[1]
            r2 = T[2] - kt * uc_old[2]
            if _norm2(r1, r2) <= mu_eff * (-T[0]) * (1.0 + 1e-12):
                uc[0] = 0.0
                uc[1] = uc_old[1]
                uc[2] = uc_old[2]
                return ST_STICK
        # --- closed: slide ----------------------------------------------------------------
        st = _slide(d00, d11, d22, 0.5 * (d01 + d10), 0.5 * (d02 + d20), 0.5 * (d12 + d21),
                    v0, v1, v2, T, uc_old[1], uc_old[2], kt, mu_eff, uc)
        if st >= 0:
            return st
    # No status fits every condition. With the slide solved as a root of h(N) (``_slide``)
    # the tests do not meet it; it remains possible at the round-off boundaries
    # between statuses, and where A couples the normal and the tangential directions far
    # more than a contact point of a block does (h with several roots, which its sampling
    # may miss). Take the stick solution with the friction projected radially onto the
    # Coulomb disk (or, under tension, the open solution); the Gauss-Seidel sweeps go on
    # from there, and the caller counts these points.
    if solved and t0 < 0.0:
        T[0] = t0
        T[1] = t1
        T[2] = t2
        r1 = T[1] - kt * uc_old[1]
        r2 = T[2] - kt * uc_old[2]
        rn = _norm2(r1, r2)
        lim = mu_eff * (-T[0])
        if rn > lim:
            T[1] = kt * uc_old[1] + r1 * (lim / rn)
            T[2] = kt * uc_old[2] + r2 * (lim / rn)
        uc[0] = 0.0
        uc[1] = uc_old[1]
        uc[2] = uc_old[2]
        return ST_AMBIGUOUS
    uc[0] = max(x0, 0.0)
    uc[1] = x1
    uc[2] = x2
    T[0] = kn * uc[0]
    T[1] = kt * uc[1]
    T[2] = kt * uc[2]
    return ST_AMBIGUOUS


@njit(cache=True)
def solve(
    ut: np.ndarray,
    A: np.ndarray,
    uc_old: np.ndarray,
    beta_old: float,
    P: np.ndarray,
    T: np.ndarray,
    uc: np.ndarray,
):
    """Local problem with the integrity consistent with the end of the step.

    Finds ``beta`` in ``[0, beta_old]`` with ``beta = min(beta_old, beta_env(u_c(beta)))``,
    where ``u_c(beta)`` solves the local problem with that integrity (``local_solve``). The
    function ``g(beta) = beta_env(u_c(beta)) - beta`` is >= 0 at 0 and < 0 at ``beta_old``
    whenever the integrity must drop, so the root is bracketed; it is found by regula falsi
    (Illinois variant), which also copes with the jumps of ``g`` at status changes; after three
    iterates in a row on the same side of the root (the secant crawls where ``g`` is nearly
    flat on one side and falls steeply at the root, as when ``mu_eff = mu (1 - beta b)^p``
    makes the slip very sensitive to ``beta``), it bisects, so that the bracket keeps
    shrinking. This makes the softening implicit: the traction never overshoots the
    envelope, whatever the step.

    Returns ``(status, beta)``; ``T`` and ``uc`` hold the solution for that ``beta``.
    """
    st = local_solve(ut, A, uc_old, beta_old, P, T, uc)
    if P[P_B] <= 0.0:
        return st, beta_old
    g_hi = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P) - beta_old
    if g_hi >= 0.0:
        return st, beta_old
    hi = beta_old
    lo = 0.0
    st = local_solve(ut, A, uc_old, 0.0, P, T, uc)
    g_lo = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P)
    if g_lo <= 0.0:
        return st, 0.0
    side = 0
    run = 0  # iterates in a row on the same side of the root
    beta = lo
    for _ in range(100):
        if run < 3:
            beta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        else:
            # the secant crawls (g nearly flat on one side, a cliff at the root): bisect
            beta = 0.5 * (lo + hi)
        st = local_solve(ut, A, uc_old, beta, P, T, uc)
        g = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P) - beta
        if abs(g) <= 1e-14 or hi - lo <= 1e-14:
            break
        if g > 0.0:
            lo = beta
            g_lo = g
            if side == -1:
                g_hi *= 0.5
                run += 1
            else:
                run = 1
            side = -1
        else:
            hi = beta
            g_hi = g
            if side == 1:
                g_lo *= 0.5
                run += 1
            else:
                run = 1
            side = 1
    return st, beta


@njit(cache=True)
def tangent(u, T, uc_old, beta, status, P, K):
    """Tangent ``K = dT/du`` (3x3, Pa/m) of the law at the solution (u, T) for its status,
    with the integrity frozen (``A = 0``: the point driven by its total relative displacement).

    Per status, with the spring compliances ``c`` and the cohesive stiffness ``kappa``: open
    ``K = diag(kappa / (1 + c kappa))``; stick ``K = diag(1 / c)``; slide ``K_nn = 1 / c_n``,
    ``K_tt = (kappa_t I + mu_eff N (I - e e^T) / |q|) / (1 + c_t kappa_t)``,
    ``K_tn = -mu_eff e / (c_n (1 + c_t kappa_t))`` with ``q = u_t - (1 + c_t kappa_t) u_c,t,old``.
    """
    b = P[P_B]
    kn = beta * b * P[P_KI]
    kt = beta * b * P[P_KII]
    cnt = P[P_CN_T]
    cnc = P[P_CN_C]
    ct = P[P_CT]
    for i in range(3):
        for j in range(3):
            K[i, j] = 0.0
    if status == ST_OPEN:
        K[0, 0] = kn / (1.0 + cnt * kn)
        K[1, 1] = kt / (1.0 + ct * kt)
        K[2, 2] = K[1, 1]
        return
    K[0, 0] = 1.0 / cnc
    if status == ST_SLIDE:
        mu_eff = P[P_MU] * (1.0 - beta * b) ** P[P_P]
        N = -T[0]
        f = 1.0 + ct * kt
        q1 = u[1] - f * uc_old[1]
        q2 = u[2] - f * uc_old[2]
        qn = math.sqrt(q1 * q1 + q2 * q2)
        if qn > 0.0:
            e1 = q1 / qn
            e2 = q2 / qn
            g = mu_eff * N / qn
            K[1, 1] = (kt + g * (1.0 - e1 * e1)) / f
            K[2, 2] = (kt + g * (1.0 - e2 * e2)) / f
            K[1, 2] = -g * e1 * e2 / f
            K[2, 1] = K[1, 2]
            K[1, 0] = -mu_eff * e1 / (cnc * f)
            K[2, 0] = -mu_eff * e2 / (cnc * f)
            return
    K[1, 1] = 1.0 / ct
    K[2, 2] = 1.0 / ct


# --- the law interface (contact.laws) ------------------------------------------------------
def params_from_case(joint) -> np.ndarray:
    """The parameter row of a case's ``joint`` section (``case.Joint``)."""
    return joint_params(
        K_I_spring=joint.K_I_spring_Pa_m, K_II_spring=joint.K_II_spring_Pa_m,
        d_spring=joint.d_spring, sigma_I_e=joint.sigma_I_e_Pa, K_I_coh=joint.K_I_coh_Pa_m,
        G_fI=joint.G_fI_J_m2, sigma_II_e=joint.sigma_II_e_Pa, K_II_coh=joint.K_II_coh_Pa_m,
        G_fII=joint.G_fII_J_m2, d_coh_initial=joint.d_coh_initial, mu=joint.mu, p=joint.p,
        eta=joint.eta, compression_spring=joint.compression_spring, law=joint.law,
        K_n=joint.K_n_Pa_m, K_t=joint.K_t_Pa_m,
    )


def initial_damage(P: np.ndarray) -> float:
    """The cohesive damage of the joint as built, ``d_coh,0 = 1 - b`` (so that the damage of a
    point is ``1 - beta (1 - d_coh,0)``)."""
    return 1.0 - float(P[P_B])


def normal_displacement(sigma: float, beta: float, P: np.ndarray) -> float:
    """Total normal displacement (m) that carries the normal traction ``sigma`` (Pa) with the
    integrity ``beta``: the spring alone in compression, the open joint in series with the
    spring in tension (ValueError when no cohesion is left to carry it)."""
    if sigma <= 0.0:
        return sigma * P[P_CN_C]
    kn = beta * P[P_B] * P[P_KI]
    if kn <= 0.0:
        raise ValueError(
            f"the joint cannot carry a normal tension of {sigma} Pa: it has no cohesion left"
        )
    return sigma / kn + sigma * P[P_CN_T]


def rigid_friction(P: np.ndarray) -> float | None:
    """The friction coefficient when the law is rigid Signorini-Coulomb (``coulomb``: no spring,
    no cohesion), which the Newton solver takes with the impulse as an unknown
    (``contact.alart_curnier``); None when ``T(u)`` is a function (a spring in series)."""
    if P[P_CN_C] == 0.0 and P[P_CN_T] == 0.0 and P[P_CT] == 0.0 and P[P_B] == 0.0:
        return float(P[P_MU])
    return None


def newton_ready(P: np.ndarray) -> bool:
    """Whether the Newton solver can take the law: a spring in series (finite ``T(u)``), or
    rigid Signorini-Coulomb (:func:`rigid_friction`)."""
    return bool(P[P_CN_C] > 0.0 and P[P_CT] > 0.0) or rigid_friction(P) is not None
