r"""numba kernels of the load path (:mod:`.path`): the points' relative displacements, their
spring and Coulomb law, the body forces and the Newton matrix, one loop over the points each.

Every point ``a`` couples the six dofs of each of its two bodies through ``G_a`` (12, 3), the
three frame directions as generalised forces (the columns of the equilibrium matrix ``B``),
``dof_a`` (12) the free-dof numbers (-1: not free). Then

    g_a = G_a^T u[dof_a]                      relative displacement (n, t, s) (m)
    r[dof_a] += G_a f_a                       body forces of the point forces f_a (N, N m)
    J[dof_a, dof_a] += G_a D_a G_a^T          Newton matrix, D_a = df_a/dg_a (N/m)

The law of a point (spring ``k_n`` in compression, no tension; spring ``k_t`` in shear with a
plastic slip ``p`` returned to Coulomb's cone along the trial force, no dilatancy):

    N = k_n max(0, -g_n),   F* = -k_t (g_t - p),   F = F* if |F*| <= mu N, else mu N F*/|F*|

A glued point is a linear spring in every direction (``N = -k_n g_n``, ``F = F*``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def gaps(x, G, dof, g):
    """``g_a = G_a^T x[dof_a]`` (p, 3) (m) for the free dofs' displacements ``x``."""
    for a in range(G.shape[0]):
        for k in range(3):
            s = 0.0
            for i in range(12):
                d = dof[a, i]
                if d >= 0:
                    s += G[a, i, k] * x[d]
            g[a, k] = s


@njit(cache=True)
def law(g, slip, kn, kt, mu, glued, f, D, after, closed, sliding):
    """The point forces ``f`` (p, 3) (N), their tangent ``D = df/dg`` (p, 3, 3) (N/m), the slip
    ``after`` the step (p, 2) (m) and the masks of the ``closed`` and ``sliding`` points, for
    the relative displacements ``g`` (p, 3) and the slip ``slip`` (p, 2) before it (module
    docstring)."""
    for a in range(g.shape[0]):
        for i in range(3):
            f[a, i] = 0.0
            for j in range(3):
                D[a, i, j] = 0.0
        after[a, 0] = slip[a, 0]
        after[a, 1] = slip[a, 1]
        is_closed = g[a, 0] <= 0.0 or glued[a]
        closed[a] = is_closed
        sliding[a] = False
        if not is_closed:
            after[a, 0] = g[a, 1]
            after[a, 1] = g[a, 2]
            continue
        N = -kn[a] * g[a, 0] if glued[a] else kn[a] * max(0.0, -g[a, 0])
        t1 = -kt[a] * (g[a, 1] - slip[a, 0])
        t2 = -kt[a] * (g[a, 2] - slip[a, 1])
        size = math.sqrt(t1 * t1 + t2 * t2)
        cap = mu[a] * N
        f[a, 0] = N
        D[a, 0, 0] = -kn[a]
        if glued[a] or size <= cap:
            f[a, 1] = t1
            f[a, 2] = t2
            D[a, 1, 1] = -kt[a]
            D[a, 2, 2] = -kt[a]
            continue
        sliding[a] = True
        e1 = t1 / max(size, 1e-300)
        e2 = t2 / max(size, 1e-300)
        f[a, 1] = cap * e1
        f[a, 2] = cap * e2
        w = -kt[a] * cap / size
        D[a, 1, 1] = w * (1.0 - e1 * e1)
        D[a, 1, 2] = -w * e1 * e2
        D[a, 2, 1] = -w * e2 * e1
        D[a, 2, 2] = w * (1.0 - e2 * e2)
        D[a, 1, 0] = -mu[a] * kn[a] * e1
        D[a, 2, 0] = -mu[a] * kn[a] * e2
        after[a, 0] = g[a, 1] + f[a, 1] / kt[a]
        after[a, 1] = g[a, 2] + f[a, 2] / kt[a]


@njit(cache=True)
def forces(f, G, dof, r):
    """``r = B f`` on the free dofs (N, N m) for the point forces ``f`` (p, 3); ``r`` is
    overwritten."""
    r[:] = 0.0
    for a in range(G.shape[0]):
        for i in range(12):
            d = dof[a, i]
            if d >= 0:
                r[d] += G[a, i, 0] * f[a, 0] + G[a, i, 1] * f[a, 1] + G[a, i, 2] * f[a, 2]


@njit(cache=True)
def matrix(D, G, dof, slot, data):
    """The values of ``B D B^T`` summed into ``data`` (the pattern's entries, zeroed here):
    ``slot`` (the used pairs of every point, in the order point, row, column) gives each
    entry's place."""
    data[:] = 0.0
    GD = np.empty((12, 3))
    k = 0
    for a in range(G.shape[0]):
        for i in range(12):
            for c in range(3):
                GD[i, c] = G[a, i, 0] * D[a, 0, c] + G[a, i, 1] * D[a, 1, c] \
                    + G[a, i, 2] * D[a, 2, c]
        for i in range(12):
            if dof[a, i] < 0:
                continue
            for j in range(12):
                if dof[a, j] < 0:
                    continue
                data[slot[k]] += GD[i, 0] * G[a, j, 0] + GD[i, 1] * G[a, j, 1] \
                    + GD[i, 2] * G[a, j, 2]
                k += 1
