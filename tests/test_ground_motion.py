"""Ground motion: the record, the base's path, and Housner's rocking block on a moving base."""

from __future__ import annotations

import math

import numpy as np
import pytest

from masonry_nscd.loading import step_velocity
from masonry_nscd.loading.ground_motion import GroundMotion, read_acceleration_record
from masonry_nscd.scenes.small import rocking_block


def test_record_is_integrated_exactly_to_velocity_and_displacement():
    # a ramp of acceleration a(t) = 2 t on [0, 1], then 2 held to 2 s, then nothing
    g = GroundMotion(np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0, 2.0]), start_s=0.5)
    assert g(0.5) == 0.0 and g.displacement(0.4) == 0.0
    assert g.acceleration(1.0) == pytest.approx(1.0)
    assert g(1.0) == pytest.approx(0.25)  # t^2 at t = 0.5
    assert g.displacement(1.0) == pytest.approx(0.125 / 3.0)  # t^3 / 3
    assert g(2.5) == pytest.approx(1.0 + 2.0 * 1.0)
    assert g.displacement(2.5) == pytest.approx(1.0 / 3.0 + 1.0 + 1.0)
    # after the record: no acceleration, constant velocity
    assert g.acceleration(3.0) == 0.0 and g(3.5) == pytest.approx(3.0)
    assert g.displacement(3.5) == pytest.approx(g.displacement(2.5) + 3.0)
    assert g.end_s == 2.5


def test_imposed_base_stays_on_its_path_whatever_the_steps():
    t = np.linspace(0.0, 1.0, 41)
    g = GroundMotion(t, 3.0 * np.sin(2 * math.pi * 3 * t))
    u = v = 0.0
    for t0, t1 in [(0.0, 0.013), (0.013, 0.02), (0.02, 0.5), (0.5, 0.5005), (0.5005, 1.0)]:
        v1 = step_velocity(g, t0, t1, 1.0, v)
        u, v = u + (t1 - t0) * v1, v1
        assert u == pytest.approx(g.displacement(t1), abs=1e-15)


@pytest.mark.parametrize(("text", "message"), [
    ("t,a\n0,0\n1,1\n", "header 'time_s,acceleration_m_s2'"),
    ("time_s,acceleration_m_s2\n0,0\n1,x\n", "line 3: expected two numbers"),
    ("time_s,acceleration_m_s2\n0,0\n0,1\n", "line 3: time 0 s does not follow 0 s"),
    ("time_s,acceleration_m_s2\n0.5,0\n1,1\n", "line 2: the record must start at time 0"),
    ("time_s,acceleration_m_s2\n0,0\n1,inf\n", "line 3: values must be finite"),
    ("time_s,acceleration_m_s2\n0,0\n", "at least two rows"),
])
def test_record_errors_name_the_line(tmp_path, text, message):
    path = tmp_path / "rec.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_acceleration_record(path)


def _pulse(level):
    """A base acceleration pulse along x: ramp up over 50 ms, hold 0.3 s, ramp down (m/s^2)."""
    return np.array([0.0, 0.05, 0.1, 0.4, 0.45, 0.6]), np.array([0, 0, level, level, 0, 0])


@pytest.mark.parametrize(("factor", "rocks"), [(0.98, False), (1.02, True)])
def test_block_on_moving_base_rocks_above_housners_threshold(factor, rocks):
    # Housner (1963): a rigid block of half width b and half height h on a base accelerating
    # at a rocks once a > g b / h (here b / h = 1/4, friction 0.8 > 1/4 holds the toe)
    _, info = rocking_block()
    integ, info = rocking_block(record=_pulse(factor * info["threshold_m_s2"]), h=1e-3)
    rotation = 0.0
    while integ.t < 0.6 - 1e-9:
        assert integ.step().converged
        rotation = max(rotation, abs(integ.u[info["rotation_dof"]]))
    if rocks:
        # 2 % over the threshold for 0.3 s: rotation (a - g b/h) m h t^2 / (2 I_toe), about
        # 4e-3 rad
        assert rotation > 1e-3
    else:
        assert rotation < 1e-9
    b = integ.energy_account.balance(integ)  # the base's reaction did the work
    assert b["work_of_imposed_motions"] > 0.0 and b["relative_imbalance"] < 1e-6


def test_free_rocking_impact_keeps_housners_fraction_of_angular_velocity():
    # From a tilt about its left corner the block falls back onto its right corner. At the
    # impact, the contact points (restitution 0 in Moreau-Jean: the position-level
    # Signorini condition of a theta = 1 step) stop the right corner, friction keeps it from
    # sliding, the left corner lifts off; nothing else acts in the impact, so the angular
    # momentum about the right corner is kept: omega2 / omega1 = 1 - (3/2) sin^2(alpha), the
    # scheme gives Housner's factor (the impact takes the step in which the corner arrives
    # and the next one). The kinetic energy lost, 1/2 I_O (omega1^2 - omega2^2), is counted as
    # impact dissipation.
    integ, info = rocking_block(tilt=0.01, h=1e-4)
    right = np.array([p.x[0] for p in integ.points]) > 0.1
    acc = integ.energy_account
    omega, impacts = [], []
    while integ.t < 0.1:
        integ.step()
        omega.append(integ.v[info["rotation_dof"]])
        impacts.append(acc.balance(integ)["dissipated_impacts"])
        if (integ.joints.T[right, 0] < 0.0).any() and len(omega) > 2 and omega[-2] < 0.0:
            break
    k = len(omega) - 1  # the step in which the right corner arrives
    for _ in range(2):
        integ.step()
        omega.append(integ.v[info["rotation_dof"]])
        impacts.append(acc.balance(integ)["dissipated_impacts"])
    w1, w2 = omega[k - 1], omega[k + 1]
    assert w1 < -0.2  # sqrt(2 (3 g b / 4 R^2) tilt) = 0.29 rad/s, clockwise
    assert w2 / w1 == pytest.approx(info["housner_factor"], rel=0.05)
    width, height, m = 0.2, 0.8, info["mass"]
    inertia = m * (width ** 2 + height ** 2) / 3.0  # about a corner (kg m^2)
    lost = impacts[k + 1] - impacts[k - 1]
    assert lost == pytest.approx(0.5 * inertia * (w1 ** 2 - w2 ** 2), rel=0.05)
