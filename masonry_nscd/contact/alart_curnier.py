r"""Rigid Signorini-Coulomb contact as a semi-smooth equation (Alart-Curnier), for Newton.

A rigid contact (joint law ``coulomb``: no spring, no cohesion) has no traction as a function of
the relative displacement, so the Newton solver keeps its impulse as an unknown, as it does for
the glue. With the point's relative displacement at the end of the step ``u`` (m; ``u_n > 0``
opens) and its impulse ``r = -h S T`` (N s, local frame; ``r_n >= 0`` presses, ``r_t`` resists
the slip ``s = u_t - u_c,t,old`` of the step), the conditions of the law

    u_n >= 0,  r_n >= 0,  u_n r_n = 0                              (Signorini)
    |r_t| <= mu r_n,  r_t = -mu r_n s / |s| where s != 0            (Coulomb)

are the zeros of the Alart-Curnier function (m), with ``rho`` (N s/m) any positive number::

    a_n   = r_n - rho u_n                              (the augmented normal impulse)
    Phi_n = (r_n - max(0, a_n)) / rho                  (= min(u_n, r_n / rho))
    q     = r_t - rho s,    R = mu max(0, a_n)
    Phi_t = (r_t - proj_R(q)) / rho                    (proj_R: onto the disk of radius R)

Its generalised derivative, per status:

* open (``a_n <= 0``): ``Phi = r / rho``; ``dPhi/dr = I / rho``, ``dPhi/du = 0``;
* closed (``a_n > 0``): ``Phi_n = u_n``, ``dPhi_n/du_n = 1``; and

  - stick (``|q| <= R``): ``Phi_t = s``, ``dPhi_t/du_t = I``;
  - slide, with ``e = q / |q|``, ``c = R / |q|`` and ``P = I - e e^T``:
    ``Phi_t = (r_t - R e) / rho``, ``dPhi_t/dr_t = (I - c P) / rho``,
    ``dPhi_t/du_t = c P``, ``dPhi_t/dr_n = -mu e / rho``, ``dPhi_t/du_n = mu e``.

The choice of ``rho`` does not change the solution, only the path of Newton's iterations; the
solver takes ``rho = 1 / (theta h w)`` with ``w`` the mean diagonal of the point's Delassus
matrix (1/kg), the impulse that closes a gap of 1 m within the step for the point alone.
"""

from __future__ import annotations

import math

from numba import njit

from masonry_nscd.contact.laws.common import ST_OPEN, ST_SLIDE, ST_STICK


@njit(cache=True)
def residual(u, r, uc_old, mu, rho, Phi, Gu, Gr, uc):
    """The Alart-Curnier function ``Phi`` (m) of one rigid contact point and its derivatives
    ``Gu = dPhi/du`` (dimensionless) and ``Gr = dPhi/dr`` (m/(N s)), written in place, with the
    cohesive displacement at the end of the step ``uc`` (m: ``u`` when open, ``(0, u_t)`` when
    sliding, ``(0, u_c,t,old)`` when sticking). ``u`` (m) and ``r`` (N s) as in the module docstring, ``uc_old`` (m) the cohesive
    displacement at the start of the step, ``mu`` the friction coefficient, ``rho`` (N s/m).
    Returns the status (ST_OPEN, ST_STICK or ST_SLIDE)."""
    for i in range(3):
        for j in range(3):
            Gu[i, j] = 0.0
            Gr[i, j] = 0.0
    an = r[0] - rho * u[0]
    closed = an > 0.0
    if closed:
        Phi[0] = u[0]
        Gu[0, 0] = 1.0
    else:
        Phi[0] = r[0] / rho
        Gr[0, 0] = 1.0 / rho
    radius = mu * an if closed else 0.0
    s1 = u[1] - uc_old[1]
    s2 = u[2] - uc_old[2]
    q1 = r[1] - rho * s1
    q2 = r[2] - rho * s2
    qn = math.sqrt(q1 * q1 + q2 * q2)
    uc[0] = 0.0 if closed else u[0]
    uc[1] = u[1]
    uc[2] = u[2]
    if not closed:
        Phi[1] = r[1] / rho
        Phi[2] = r[2] / rho
        Gr[1, 1] = 1.0 / rho
        Gr[2, 2] = 1.0 / rho
        return ST_OPEN
    if qn <= radius:
        Phi[1] = s1
        Phi[2] = s2
        Gu[1, 1] = 1.0
        Gu[2, 2] = 1.0
        # the stick keeps its reference: the slip that the multipliers' compliance lets through
        # (1e-9 of the step's) does not accumulate from step to step
        uc[1] = uc_old[1]
        uc[2] = uc_old[2]
        return ST_STICK
    e1 = q1 / qn
    e2 = q2 / qn
    c = radius / qn
    Phi[1] = (r[1] - radius * e1) / rho
    Phi[2] = (r[2] - radius * e2) / rho
    p11 = 1.0 - e1 * e1
    p12 = -e1 * e2
    p22 = 1.0 - e2 * e2
    Gr[1, 1] = (1.0 - c * p11) / rho
    Gr[1, 2] = -c * p12 / rho
    Gr[2, 1] = Gr[1, 2]
    Gr[2, 2] = (1.0 - c * p22) / rho
    Gr[1, 0] = -mu * e1 / rho
    Gr[2, 0] = -mu * e2 / rho
    Gu[1, 1] = c * p11
    Gu[1, 2] = c * p12
    Gu[2, 1] = c * p12
    Gu[2, 2] = c * p22
    Gu[1, 0] = mu * e1
    Gu[2, 0] = mu * e2
    return ST_SLIDE
