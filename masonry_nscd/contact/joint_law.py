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
* slide: ``T_t = kappa_t u_c,t + mu_eff N e`` with ``e`` the slip direction and ``N = -T_n``;
  closed form when ``D`` is diagonal, iterated on the off-diagonal part when ``A`` couples the
  normal and tangential directions.

Glued points (blocks glued to the steel beams) are bilateral: ``u_{n+1} = 0``, ``T = A^-1 u~``.
Dry Signorini-Coulomb is this same law with ``b = 0`` (no cohesion, ``mu_eff = mu``) and no spring.

The compressive normal spring is ``(1 - d_spring) K_I^spring`` (the study's equation 2, switch
``damaged``) or ``K_I^spring`` (switch ``undamaged``, as the reference code LMGC90 does in 3D).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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
N_PARAMS = 13

# --- kinds of contact point ------------------------------------------------------------------
KIND_JOINT = 0  # the joint law (FCZM + spring, or dry Signorini-Coulomb)
KIND_GLUED = 1  # bilateral glue: relative displacement held at zero

# --- status codes ------------------------------------------------------------------------------
ST_OPEN = 0
ST_STICK = 1
ST_SLIDE = 2
ST_GLUED = 3
ST_AMBIGUOUS = 4  # no status satisfied every condition (reported, should not persist)


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
) -> np.ndarray:
    """Pack the joint parameters (SI units, model.md Table 3) into a float64 vector.

    ``law='coulomb'`` gives dry Signorini-Coulomb: no cohesion (b = 0), no spring (zero
    compliance), friction coefficient ``mu``.
    """
    P = np.zeros(N_PARAMS)
    P[P_MU] = mu
    P[P_P] = p
    P[P_ETA] = eta
    if law == "coulomb":
        # no spring, no cohesion: the envelope is never evaluated (b = 0)
        P[P_KI] = K_I_coh
        P[P_KII] = K_II_coh
        P[P_D1] = sigma_I_e / K_I_coh
        P[P_D2] = sigma_II_e / K_II_coh
        P[P_GI] = G_fI
        P[P_GII] = G_fII
        return P
    if law != "fczm":
        raise ValueError(f"unknown joint law {law!r}: allowed 'fczm' or 'coulomb'")
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
def _solve3(M: np.ndarray, r: np.ndarray, x: np.ndarray) -> bool:
    """Solve the 3x3 system ``M x = r`` by Gaussian elimination with partial pivoting."""
    a = M.copy()
    y = r.copy()
    for col in range(3):
        piv = col
        for i in range(col + 1, 3):
            if abs(a[i, col]) > abs(a[piv, col]):
                piv = i
        if a[piv, col] == 0.0:
            return False
        if piv != col:
            for j in range(3):
                t = a[col, j]
                a[col, j] = a[piv, j]
                a[piv, j] = t
            t = y[col]
            y[col] = y[piv]
            y[piv] = t
        for i in range(col + 1, 3):
            f = a[i, col] / a[col, col]
            for j in range(col, 3):
                a[i, j] -= f * a[col, j]
            y[i] -= f * y[col]
    for i in range(2, -1, -1):
        s = y[i]
        for j in range(i + 1, 3):
            s -= a[i, j] * x[j]
        x[i] = s / a[i, i]
    return True


@njit(cache=True)
def _slide_diagonal(ut0, ut1, ut2, dn, dt, u0_1, u0_2, kt, mu_eff, T, s):
    """Closed-form sliding for ``D = diag(dn, dt, dt)``; returns False if not admissible.

    Normal: ``T_n = u~_n / dn``. Tangential: with ``q = u~_t - u0 - dt kappa_t u0`` the slip is
    ``s = lambda e``, ``e = q / |q|``, ``lambda = (|q| - dt mu_eff N) / (1 + dt kappa_t)``.
    """
    Tn = ut0 / dn
    N = -Tn
    q1 = ut1 - u0_1 - dt * kt * u0_1
    q2 = ut2 - u0_2 - dt * kt * u0_2
    qn = math.sqrt(q1 * q1 + q2 * q2)
    if N < 0.0 or qn == 0.0:
        return False
    lam = (qn - dt * mu_eff * N) / (1.0 + dt * kt)
    if lam < 0.0:
        return False
    e1 = q1 / qn
    e2 = q2 / qn
    s[0] = lam * e1
    s[1] = lam * e2
    T[0] = Tn
    T[1] = kt * (u0_1 + s[0]) + mu_eff * N * e1
    T[2] = kt * (u0_2 + s[1]) + mu_eff * N * e2
    return True


@njit(cache=True)
def _slide(ut, D, u0_1, u0_2, kt, mu_eff, T, uc) -> bool:
    """Sliding contact: ``u_c,n = 0``, Coulomb at its limit, slip along the friction traction.

    ``D`` is split into its diagonal part ``diag(dn, dt, dt)`` (``dt`` the mean tangential
    compliance) and the rest ``D_o``; the closed form of the diagonal problem is iterated with
    ``u~ - D_o T`` as predictor until T stops changing (a contraction when the coupling is small
    against the diagonal, as it is for the contact points of blocks). Returns False when no
    admissible slide is found (then the caller reports the point).
    """
    dn = D[0, 0]
    dt = 0.5 * (D[1, 1] + D[2, 2])
    s = np.zeros(2)
    Tn_old = np.zeros(3)
    w0 = ut[0]
    w1 = ut[1]
    w2 = ut[2]
    converged = False
    for it in range(200):
        if not _slide_diagonal(w0, w1, w2, dn, dt, u0_1, u0_2, kt, mu_eff, T, s):
            return False
        change = abs(T[0] - Tn_old[0]) + abs(T[1] - Tn_old[1]) + abs(T[2] - Tn_old[2])
        if change <= 1e-13 * (abs(T[0]) + abs(T[1]) + abs(T[2])) or it > 0 and change == 0.0:
            converged = True
            break
        Tn_old[0] = T[0]
        Tn_old[1] = T[1]
        Tn_old[2] = T[2]
        # predictor shifted by the off-diagonal part: u~ - (D - diag(dn, dt, dt)) T
        w0 = ut[0] - D[0, 1] * T[1] - D[0, 2] * T[2]
        w1 = ut[1] - D[1, 0] * T[0] - (D[1, 1] - dt) * T[1] - D[1, 2] * T[2]
        w2 = ut[2] - D[2, 0] * T[0] - D[2, 1] * T[1] - (D[2, 2] - dt) * T[2]
    if not converged:
        return False
    uc[0] = 0.0
    uc[1] = u0_1 + s[0]
    uc[2] = u0_2 + s[1]
    return True


@njit(cache=True)
def _slide_residual(alpha, ut, Dinv, u0_1, u0_2, kt, mu_eff, T, s):
    """For a slip direction ``e(alpha)``: the slip length that puts the friction on the cone
    along e, the tractions, and the residual of the friction across e (zero at a solution).

    With ``s = lam e``, ``T = D^-1 (u~ - (0, u0 + lam e))`` is linear in ``lam``, and so is
    ``R_t . e - mu_eff N``; its root gives lam. Returns (residual, ok).
    """
    e1 = math.cos(alpha)
    e2 = math.sin(alpha)
    # T = T0 + lam * Te
    T0 = np.empty(3)
    Te = np.empty(3)
    for i in range(3):
        T0[i] = Dinv[i, 0] * ut[0] + Dinv[i, 1] * (ut[1] - u0_1) + Dinv[i, 2] * (ut[2] - u0_2)
        Te[i] = -(Dinv[i, 1] * e1 + Dinv[i, 2] * e2)
    # g(lam) = (T_t - kt (u0 + lam e)) . e + mu_eff T_n  (= R.e - mu N)
    g0 = (T0[1] - kt * u0_1) * e1 + (T0[2] - kt * u0_2) * e2 + mu_eff * T0[0]
    ge = Te[1] * e1 + Te[2] * e2 - kt + mu_eff * Te[0]
    if ge == 0.0:
        return 0.0, False
    lam = -g0 / ge
    if lam < 0.0:
        return 0.0, False
    for i in range(3):
        T[i] = T0[i] + lam * Te[i]
    if T[0] > 0.0:
        return 0.0, False
    s[0] = lam * e1
    s[1] = lam * e2
    r1 = T[1] - kt * (u0_1 + s[0])
    r2 = T[2] - kt * (u0_2 + s[1])
    return -r1 * e2 + r2 * e1, True


@njit(cache=True)
def _slide_by_angle(ut, D, u0_1, u0_2, kt, mu_eff, T, uc) -> bool:
    """Robust sliding solution: scan the slip direction, then bisect the residual across it.

    Used when the iteration of ``_slide`` does not converge (strong normal-tangential coupling,
    as for dry contacts of deformable blocks, where no spring adds to the diagonal).
    """
    Dinv = np.linalg.inv(D)
    s = np.zeros(2)
    n_scan = 72
    prev_ok = False
    prev_f = 0.0
    prev_a = 0.0
    for k in range(n_scan + 1):
        a = 2.0 * math.pi * k / n_scan
        f, ok = _slide_residual(a, ut, Dinv, u0_1, u0_2, kt, mu_eff, T, s)
        if ok and prev_ok and (f == 0.0 or (f > 0.0) != (prev_f > 0.0)):
            lo = prev_a
            hi = a
            flo = prev_f
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                fm, okm = _slide_residual(mid, ut, Dinv, u0_1, u0_2, kt, mu_eff, T, s)
                if not okm:
                    break
                if (fm > 0.0) == (flo > 0.0):
                    lo = mid
                    flo = fm
                else:
                    hi = mid
            fm, okm = _slide_residual(0.5 * (lo + hi), ut, Dinv, u0_1, u0_2, kt, mu_eff, T, s)
            if okm:
                uc[0] = 0.0
                uc[1] = u0_1 + s[0]
                uc[2] = u0_2 + s[1]
                return True
        prev_ok = ok
        prev_f = f
        prev_a = a
    return False


@njit(cache=True)
def local_solve(
    ut: np.ndarray,
    A: np.ndarray,
    uc_old: np.ndarray,
    beta: float,
    P: np.ndarray,
    kind: int,
    T: np.ndarray,
    uc: np.ndarray,
) -> int:
    """Solve the local problem of one contact point for one step (frozen integrity).

    Inputs: predictor ``ut`` (m), compliance ``A`` (m/Pa), cohesive displacement at the start of
    the step ``uc_old`` (m), integrity ``beta``, parameters ``P``, the point's ``kind``.
    Outputs written in place: traction ``T`` (Pa, tension positive) and cohesive displacement
    ``uc`` (m) at the end of the step. Returns the status code (ST_*).
    """
    D = np.empty((3, 3))
    if kind == KIND_GLUED:
        ok = _solve3(A, ut, T)
        uc[0] = 0.0
        uc[1] = 0.0
        uc[2] = 0.0
        if not ok:
            T[:] = 0.0
        return ST_GLUED

    b = P[P_B]
    kn = beta * b * P[P_KI]
    kt = beta * b * P[P_KII]
    mu_eff = P[P_MU] * (1.0 - beta * b) ** P[P_P]

    # --- open: no friction, Signorini inactive ------------------------------------------
    for i in range(3):
        for j in range(3):
            D[i, j] = A[i, j]
    D[0, 0] += P[P_CN_T]
    D[1, 1] += P[P_CT]
    D[2, 2] += P[P_CT]
    M = np.empty((3, 3))
    for i in range(3):
        M[i, 0] = (1.0 if i == 0 else 0.0) + D[i, 0] * kn
        M[i, 1] = (1.0 if i == 1 else 0.0) + D[i, 1] * kt
        M[i, 2] = (1.0 if i == 2 else 0.0) + D[i, 2] * kt
    x = np.empty(3)
    if _solve3(M, ut, x) and x[0] > 0.0:
        uc[0] = x[0]
        uc[1] = x[1]
        uc[2] = x[2]
        T[0] = kn * x[0]
        T[1] = kt * x[1]
        T[2] = kt * x[2]
        return ST_OPEN
    open_uc = x.copy()

    # --- closed: stick ----------------------------------------------------------------------
    D[0, 0] += P[P_CN_C] - P[P_CN_T]
    rhs = np.empty(3)
    rhs[0] = ut[0]
    rhs[1] = ut[1] - uc_old[1]
    rhs[2] = ut[2] - uc_old[2]
    if _solve3(D, rhs, T):
        if T[0] <= 0.0:
            r1 = T[1] - kt * uc_old[1]
            r2 = T[2] - kt * uc_old[2]
            if math.sqrt(r1 * r1 + r2 * r2) <= mu_eff * (-T[0]) * (1.0 + 1e-12):
                uc[0] = 0.0
                uc[1] = uc_old[1]
                uc[2] = uc_old[2]
                return ST_STICK
        # --- closed: slide ----------------------------------------------------------------
        if _slide(ut, D, uc_old[1], uc_old[2], kt, mu_eff, T, uc):
            return ST_SLIDE
        if _slide_by_angle(ut, D, uc_old[1], uc_old[2], kt, mu_eff, T, uc):
            return ST_SLIDE
    # No status fits every condition. This happens only when A couples the normal and the
    # tangential directions strongly (far more than a contact point of a block does). Take the
    # stick solution with the friction projected radially onto the Coulomb disk (or, under
    # tension, the open solution); the Gauss-Seidel sweeps go on from there, and the caller
    # counts these points.
    if _solve3(D, rhs, T) and T[0] < 0.0:
        r1 = T[1] - kt * uc_old[1]
        r2 = T[2] - kt * uc_old[2]
        rn = math.sqrt(r1 * r1 + r2 * r2)
        lim = mu_eff * (-T[0])
        if rn > lim:
            T[1] = kt * uc_old[1] + r1 * lim / rn
            T[2] = kt * uc_old[2] + r2 * lim / rn
        uc[0] = 0.0
        uc[1] = uc_old[1]
        uc[2] = uc_old[2]
        return ST_AMBIGUOUS
    uc[0] = max(open_uc[0], 0.0)
    uc[1] = open_uc[1]
    uc[2] = open_uc[2]
    T[0] = kn * uc[0]
    T[1] = kt * uc[1]
    T[2] = kt * uc[2]
    return ST_AMBIGUOUS


@njit(cache=True)
def spring_displacement(T: np.ndarray, P: np.ndarray, us: np.ndarray) -> None:
    """Spring part ``u_s = C_s T`` of the relative displacement (m)."""
    us[0] = T[0] * (P[P_CN_T] if T[0] >= 0.0 else P[P_CN_C])
    us[1] = T[1] * P[P_CT]
    us[2] = T[2] * P[P_CT]


@njit(cache=True)
def local_solve_implicit(
    ut: np.ndarray,
    A: np.ndarray,
    uc_old: np.ndarray,
    beta_old: float,
    P: np.ndarray,
    kind: int,
    T: np.ndarray,
    uc: np.ndarray,
):
    """Local problem with the integrity consistent with the end of the step.

    Finds ``beta`` in ``[0, beta_old]`` with ``beta = min(beta_old, beta_env(u_c(beta)))``,
    where ``u_c(beta)`` solves the local problem with that integrity (``local_solve``). The
    function ``g(beta) = beta_env(u_c(beta)) - beta`` is >= 0 at 0 and < 0 at ``beta_old``
    whenever the integrity must drop, so the root is bracketed; it is found by regula falsi
    (Illinois variant), which also copes with the jumps of ``g`` at status changes. This makes
    the softening implicit: the traction never overshoots the envelope, whatever the step.

    Returns ``(status, beta)``; ``T`` and ``uc`` hold the solution for that ``beta``.
    """
    st = local_solve(ut, A, uc_old, beta_old, P, kind, T, uc)
    if kind == KIND_GLUED or P[P_B] <= 0.0:
        return st, beta_old
    g_hi = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P) - beta_old
    if g_hi >= 0.0:
        return st, beta_old
    hi = beta_old
    lo = 0.0
    st = local_solve(ut, A, uc_old, 0.0, P, kind, T, uc)
    g_lo = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P)
    if g_lo <= 0.0:
        return st, 0.0
    side = 0
    beta = lo
    for _ in range(100):
        beta = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        st = local_solve(ut, A, uc_old, beta, P, kind, T, uc)
        g = envelope_integrity(uc[0], uc[1], uc[2], beta_old, P) - beta
        if abs(g) <= 1e-14 or hi - lo <= 1e-14:
            break
        if g > 0.0:
            lo = beta
            g_lo = g
            if side == -1:
                g_hi *= 0.5
            side = -1
        else:
            hi = beta
            g_hi = g
            if side == 1:
                g_lo *= 0.5
            side = 1
    return st, beta
