r"""numba kernels of the Moreau-Jean step: local velocities, Gauss-Seidel sweeps.

Theta-method for the bodies (model.md section 4), with ``M_hat = M + (theta h)^2 K``::

    v_free  = v_n + M_hat^-1 [ h (theta F_n+1 + (1 - theta) F_n) - h F_int(u_n) - theta h^2 K v_n ]
    v_n+1   = v_free + M_hat^-1 H r
    u_n+1   = u_n + h (theta v_n+1 + (1 - theta) v_n)

Contact points: local velocities ``U = H^T v``, impulses ``r`` (N s) acting on the relative
motion, ``U = U_free + W r``. The joint law is written with tractions (Pa, tension positive)
``T = -r / (h S)``, ``S`` the tributary area. With the others' impulses frozen, the relative
displacement of point ``a`` at the end of the step is

    u_a = u~_a - A_a T_a,   u~_a = u_a,n + h (1 - theta) U_a,n + h theta U_a^others,
    A_a = theta h^2 S_a W_aa                                        (m/Pa)

which is the local problem solved by the law of the point (``contact.laws.solve``).

Convergence of the sweeps: every ``check_every`` sweeps, the relative change of the contact
forces over the last sweep, ``sqrt(sum |S dT|^2) / sqrt(sum |S T|^2)``, against the tolerance.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from masonry_nscd.contact import laws


@njit(cache=True)
def local_velocities(side_dofs, side_coef, v, U):
    """Local relative velocities ``U_a = H_a^T v`` (npt, 3), m/s."""
    npt = side_dofs.shape[0]
    for a in range(npt):
        for c in range(3):
            U[a, c] = 0.0
        for s in range(2):
            for j in range(side_dofs.shape[2]):
                d = side_dofs[a, s, j]
                if d < 0:
                    break
                for c in range(3):
                    U[a, c] += side_coef[a, s, j, c] * v[d]


@njit(cache=True)
def _apply_impulse(a, dr0, dr1, dr2, side_body, body_dof0, y_off, y, dv):
    for s in range(2):
        yo = y_off[a, s]
        if yo < 0:
            continue
        b = side_body[a, s]
        d0 = body_dof0[b]
        n = body_dof0[b + 1] - d0
        for i in range(n):
            dv[d0 + i] += y[yo + 3 * i] * dr0 + y[yo + 3 * i + 1] * dr1 + y[yo + 3 * i + 2] * dr2


@njit(cache=True)
def nlgs(
    U_free, u_old, U_old, kind, law, params, area, W, side_dofs, side_coef, side_body,
    body_dof0, y_off, y, h, theta, uc_old, beta_old,
    T, uc, beta, status, dv, tol, max_iter, check_every,
):
    """Non-linear Gauss-Seidel over the contact points, warm-started from ``T``.

    In: free local velocities ``U_free`` (npt, 3); local relative displacement and velocity at
    the start of the step; the joint states ``uc_old``, ``beta_old``. In/out: tractions ``T``
    (warm start in, solution out). Out: ``uc``, ``beta``, ``status`` at the end of the step,
    and ``dv`` = ``M_hat^-1 H r`` (ndof). Sweeps go forward and backward in turn.

    Returns ``(sweeps, residual, n_ambiguous)``; the caller decides what non-convergence means.
    """
    npt = U_free.shape[0]
    dv[:] = 0.0
    for a in range(npt):
        f = -h * area[a]
        _apply_impulse(a, f * T[a, 0], f * T[a, 1], f * T[a, 2], side_body, body_dof0, y_off,
                       y, dv)
    A = np.empty((3, 3))
    ut = np.empty(3)
    Tn = np.empty(3)
    ucn = np.empty(3)
    ucold = np.empty(3)
    residual = math.inf
    sweeps = 0
    n_amb = 0
    if npt == 0:
        return 0, 0.0, 0
    while sweeps < max_iter:
        num = 0.0
        den = 0.0
        n_amb = 0
        forward = sweeps % 2 == 0
        for ii in range(npt):
            a = ii if forward else npt - 1 - ii
            S = area[a]
            # current local velocity
            Ua0 = U_free[a, 0]
            Ua1 = U_free[a, 1]
            Ua2 = U_free[a, 2]
            for s in range(2):
                for j in range(side_dofs.shape[2]):
                    d = side_dofs[a, s, j]
                    if d < 0:
                        break
                    Ua0 += side_coef[a, s, j, 0] * dv[d]
                    Ua1 += side_coef[a, s, j, 1] * dv[d]
                    Ua2 += side_coef[a, s, j, 2] * dv[d]
            # remove the point's own contribution: U_others = U - W_aa r_a, r_a = -h S T_a
            f = -h * S
            r0 = f * T[a, 0]
            r1 = f * T[a, 1]
            r2 = f * T[a, 2]
            Uo0 = Ua0 - (W[a, 0, 0] * r0 + W[a, 0, 1] * r1 + W[a, 0, 2] * r2)
            Uo1 = Ua1 - (W[a, 1, 0] * r0 + W[a, 1, 1] * r1 + W[a, 1, 2] * r2)
            Uo2 = Ua2 - (W[a, 2, 0] * r0 + W[a, 2, 1] * r1 + W[a, 2, 2] * r2)
            c = h * (1.0 - theta)
            ut[0] = u_old[a, 0] + c * U_old[a, 0] + h * theta * Uo0
            ut[1] = u_old[a, 1] + c * U_old[a, 1] + h * theta * Uo1
            ut[2] = u_old[a, 2] + c * U_old[a, 2] + h * theta * Uo2
            g = theta * h * h * S
            for i in range(3):
                for j in range(3):
                    A[i, j] = g * W[a, i, j]
                ucold[i] = uc_old[a, i]
            st, bnew = laws.solve(ut, A, ucold, beta_old[a], params[law[a]], kind[a], Tn, ucn)
            if st == laws.ST_AMBIGUOUS:
                n_amb += 1
            d0 = Tn[0] - T[a, 0]
            d1 = Tn[1] - T[a, 1]
            d2 = Tn[2] - T[a, 2]
            num += S * S * (d0 * d0 + d1 * d1 + d2 * d2)
            den += S * S * (Tn[0] * Tn[0] + Tn[1] * Tn[1] + Tn[2] * Tn[2])
            if d0 != 0.0 or d1 != 0.0 or d2 != 0.0:
                _apply_impulse(a, f * d0, f * d1, f * d2, side_body, body_dof0, y_off, y, dv)
            for i in range(3):
                T[a, i] = Tn[i]
                uc[a, i] = ucn[i]
            beta[a] = bnew
            status[a] = st
        sweeps += 1
        if sweeps % check_every == 0 or sweeps == max_iter:
            if den > 0.0:
                residual = math.sqrt(num / den)
            else:
                residual = 0.0 if num == 0.0 else math.inf
            if residual <= tol:
                break
    return sweeps, residual, n_amb
