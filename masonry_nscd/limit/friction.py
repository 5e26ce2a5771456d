r"""The Coulomb cone ``|T| <= c A + mu N`` as a pyramid of ``k`` facets (a linear programme's
rows).

The tangential force ``(T, S)`` (N, along the point's ``t`` and ``s``) is kept inside the regular
polygon of ``k`` sides inscribed in the circle of radius ``rho = c A + mu N``, with vertices at
the angles ``2 pi j / k`` (on ``+-t`` and ``+-s`` when ``k`` is a multiple of 4): one row per
facet ``j``,

    cos(phi_j) T + sin(phi_j) S - mu cos(pi/k) N  <=  c A cos(pi/k),   phi_j = (2 j + 1) pi / k

(the facet's outward normal at ``phi_j``, at the distance ``rho cos(pi/k)`` from the centre).
The polygon lies between the circles of radii ``rho cos(pi/k)`` and ``rho``: the friction that
resists sliding in any direction is under-estimated by at most ``1 - cos(pi/k)``
(:func:`cone_error_bound`; 7.6 % for 8 facets, 1.9 % for 16, 0.5 % for 32), and not at all
along ``t`` and ``s``. Since a smaller cone admits fewer forces, the multiplier with the
pyramid lies between those of the exact cone with ``mu cos(pi/k)`` and with ``mu`` (and
``c cos(pi/k)``, ``c``).
"""

from __future__ import annotations

import math

import numpy as np

#: The friction unless asked otherwise: 0, Coulomb's cone itself (a second-order cone of the
#: programme, :mod:`.lp`); ``k >= 3`` asks for the pyramid of ``k`` facets.
DEFAULT_FACETS = 0


def facet_normals(k: int) -> np.ndarray:
    """The outward normals (k, 2) of the facets, in the (t, s) plane (module docstring)."""
    if k < 3:
        raise ValueError(f"facets: at least 3, got {k}")
    phi = (2.0 * np.arange(k) + 1.0) * math.pi / k
    return np.stack([np.cos(phi), np.sin(phi)], axis=1)


def inscribed_fraction(k: int) -> float:
    """``cos(pi/k)``: the polygon's inscribed radius over the cone's radius (1 for the cone
    itself, ``k = 0``)."""
    return math.cos(math.pi / k) if k else 1.0


def cone_error_bound(k: int) -> float:
    """``1 - cos(pi/k)``: the largest relative under-estimate of the friction resistance (0
    for the cone itself, ``k = 0``)."""
    return 1.0 - inscribed_fraction(k)
