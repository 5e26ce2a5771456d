"""The slide of a rigid Signorini-Coulomb point at the onset of its slip: the tangential load
``|r0|`` one or a few ulps above the friction bound ``phi`` (a wedge on a tilting table as
``lambda`` reaches ``mu``), solved by the Gauss-Seidel sweeps (``solver.method: nlgs``).

Reference: the tangential equation of the slide ``r0 = H s + phi e``, ``s = lam e``
(``contact.laws.fczm._tangential_slip``). Dotted with ``e``, ``e.r0 = lam e.H.e + phi``; as
``phi`` rises to ``|r0|`` the slip vanishes along ``e = r0 / |r0|`` and its derivative is
``t = -ds/dphi = e / (e.H.e)`` (m/Pa). Written from the entries of
``J = H + (phi / lam) (I - e e^T)``, the determinant of J cancels to round-off there (phi / lam
of 1e24 Pa/m) and can come out 0: a division by zero in the sweeps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from masonry_nscd.contact.laws import fczm


def _slip(r, H, phi):
    h11, h12, h22 = H[0, 0], H[0, 1], H[1, 1]
    hmax = 0.5 * (h11 + h22) + math.sqrt(0.25 * (h11 - h22) ** 2 + h12 * h12)
    hmin = (h11 * h22 - h12 * h12) / hmax
    return fczm._tangential_slip(r[0], r[1], h11, h12, h22, hmin, hmax, phi, 0.0)


def _check_onset(r, H, phi):
    s1, s2, lam, t1, t2 = _slip(r, H, phi)
    e = r / np.linalg.norm(r)
    t_expected = e / (e @ H @ e)
    assert np.isfinite([s1, s2, lam, t1, t2]).all()
    # a slip of round-off size along the load, which meets the tangential equation
    assert 0.0 < lam <= 1e-12 * np.linalg.norm(r) / np.linalg.eigvalsh(H)[0]
    residual = r - H @ np.array([s1, s2]) - phi * np.array([s1, s2]) / lam
    assert np.linalg.norm(residual) <= 1e-12 * np.linalg.norm(r)
    assert np.array([t1, t2]) == pytest.approx(t_expected, rel=1e-9)


def test_the_slip_onset_of_the_wedge_on_the_tilting_table():
    """A point of the tilting wedge (mu = 0.9, lambda from 0 at 0.02 /s, Gauss-Seidel) at
    lambda = 0.9, where its slide calls ``_tangential_slip`` with J's determinant at round-off
    (a ZeroDivisionError out of the sweeps, from J's entries): tangential
    load ``r0`` (Pa), ``H = G_tt`` (Pa/m, strongly coupled: the wedge's four base corners
    through the block's inverse mass), ``phi = mu N`` a few ulps below ``|r0|``."""
    r = np.array([3711.04434141378, 270.55548148365995])
    H = np.array([[213494221.61794704, 115023793.33786555],
                  [115023793.33786555, 204803988.21663275]])
    phi = 3720.893759905016
    assert 0.0 < np.linalg.norm(r) / phi - 1.0 < 1e-14
    _check_onset(r, H, phi)


@pytest.mark.parametrize("ulps", [1, 2, 8])
@pytest.mark.parametrize("turn", [0.0, 0.7, 2.5])
def test_slip_onset_within_ulps_of_the_friction_bound(ulps, turn):
    """Coupled tangential stiffnesses (Pa/m) and loads in several directions, the friction
    bound ``ulps`` floats below the load's norm: a finite slip and its derivative."""
    rng = np.random.default_rng(7)
    for _ in range(20):
        Q = np.linalg.qr(rng.normal(size=(2, 2)))[0]
        H = Q @ np.diag(10.0 ** rng.uniform(7, 10, size=2)) @ Q.T
        r = 10.0 ** rng.uniform(-3, 6) * np.array([math.cos(turn), math.sin(turn)])
        phi = float(np.linalg.norm(r))
        for _ in range(ulps):
            phi = float(np.nextafter(phi, 0.0))
        _check_onset(r, H, phi)


def test_a_non_finite_load_gives_a_non_finite_slip_not_a_division_by_zero():
    """A NaN load (a state already broken) is passed on as a NaN slip: the integrator's check
    of the tractions then stops the step with a DivergenceError that names it."""
    H = np.array([[2e8, 1e8], [1e8, 2e8]])
    assert all(math.isnan(x) for x in _slip(np.array([math.nan, 1.0]), H, 0.0))


# --- the other divisors of the sweeps ---------------------------------------------------------


def test_a_free_rigid_body_without_mass_is_refused_by_name():
    """``W = H^T M_hat^-1 H``, which the sweeps and Newton divide by, needs ``M_hat^-1``: a
    free rigid body of zero mass (a block of zero volume) is refused, naming it, before any
    step (a ValueError, which the run reports as an invalid case)."""
    from masonry_nscd.model import RigidBody
    from masonry_nscd.nscd.system import build_system

    flat = RigidBody(center=np.zeros(3), mass=0.0, inertia=np.zeros(3), name="flat stone")
    ground = RigidBody.fixed(np.zeros(3), name="ground")
    with pytest.raises(ValueError, match="body 'flat stone': mass 0 kg.*positive mass"):
        build_system([flat, ground], [], 0.002, 1.0)


def test_a_contact_point_of_zero_area_carries_nothing_in_the_sweeps():
    """A point of zero area: ``A = theta h^2 S W = 0``, and with rigid contacts no spring
    either, so its local problem has a zero compliance. The sweeps take no division by it
    (the law's 3 x 3 solves test their pivots): the point carries no impulse, and the block
    on the three others stands, its weight on them (``m g``, to the solver's tolerance)."""
    import dataclasses

    from masonry_nscd.scenes.small import tilting_block

    scene = tilting_block(rate_per_s=0.0, method="nlgs")
    scene.points[0] = dataclasses.replace(scene.points[0], area=0.0)
    integ = scene.integrator()
    for _ in range(100):  # 0.2 s: the gravity ramp over
        integ.step()
    T = integ.joints.T
    assert np.isfinite(T).all() and np.isfinite(integ.v).all()
    assert np.all(T[0] == 0.0)
    block = scene.bodies[0]
    normal = -sum(p.area * T[a, 0] for a, p in enumerate(scene.points))  # N, upwards
    assert normal == pytest.approx(block.mass * 9.81, rel=1e-6)
