"""The displacement histories: the ramp's integral, cyclic and tabulated paths, tables; the
growing load multiplier and its hold."""

from __future__ import annotations

import numpy as np
import pytest

from masonry_nscd.loading import smooth_step
from masonry_nscd.loading.histories import (
    REVERSAL_SHORTFALL,
    cyclic,
    ramp_integral,
    read_displacement_table,
    table,
)
from masonry_nscd.loading.multiplier import GrowingMultiplier


def test_ramp_integral_is_the_integral_of_the_ramp():
    x = np.linspace(0.0, 1.0, 20001)
    s = np.array([smooth_step(v, 0.0, 1.0) for v in x])
    num = np.concatenate(([0.0], np.cumsum(0.5 * (s[1:] + s[:-1]) * np.diff(x))))
    assert max(abs(num[i] - ramp_integral(x[i])) for i in range(0, len(x), 500)) < 1e-9
    assert ramp_integral(1.0) == 0.5 and ramp_integral(2.5) == 2.0
    assert REVERSAL_SHORTFALL == pytest.approx(0.1132, abs=1e-4)


def test_a_held_multiplier_keeps_the_value_it_reached():
    """After its ramp the multiplier grows as ``value + rate (t - start - ramp / 2)``; held
    at ``hold`` it keeps that value, and a level above it is never reached."""
    grow = GrowingMultiplier(0.01, 0.05, 0.2, 0.1)
    held = GrowingMultiplier(0.01, 0.05, 0.2, 0.1, hold=2.0)
    at_hold = 0.01 + 0.05 * (2.0 - 0.25)
    assert grow(2.0) == pytest.approx(at_hold, rel=1e-12)
    for t in (0.0, 0.25, 1.0, 2.0):
        assert held(t) == grow(t)
    for t in (2.0001, 3.0, 100.0):
        assert held(t) == grow(2.0)
    assert held.time_of(0.5 * at_hold) == grow.time_of(0.5 * at_hold)
    assert held.time_of(1.001 * at_hold) is None


def test_cyclic_history_reaches_each_amplitude_and_ends_at_rest_at_zero():
    rate, ramp = 2e-3, 0.05
    h = cyclic([1e-3, 2e-3], 2, rate, 0.25, ramp)
    assert [(c.amplitude_m, c.repetition) for c in h.cycles] == [
        (1e-3, 1), (1e-3, 2), (2e-3, 1), (2e-3, 2)]
    t = np.linspace(0.0, h.end_s, 100001)
    u = np.array([h.path.displacement(x) for x in t])
    v = np.array([h.velocity(x) for x in t])
    assert u.max() == pytest.approx(2e-3, rel=1e-6) and u.min() == pytest.approx(-2e-3, rel=1e-6)
    assert abs(v).max() == pytest.approx(rate) and h.velocity(h.end_s) == 0.0
    assert abs(h.path.displacement(h.end_s)) < 1e-15
    for c in h.cycles:  # each cycle starts and ends at U = 0, turns at exactly +-A
        assert abs(h.path.displacement(c.start_s)) < 1e-15
        turns = [x for x, w in zip(h.path.corners_s, h.path.jumps_m_s, strict=True)
                 if c.start_s < x < c.end_s and abs(w) == 2 * rate]
        assert [h.path.displacement(x) for x in turns] == pytest.approx(
            [c.amplitude_m, -c.amplitude_m], rel=1e-12)
        assert [h.velocity(x) for x in turns] == pytest.approx([0.0, 0.0], abs=1e-15)
    # the velocity is the derivative of the displacement
    dudt = np.gradient(u, t)
    assert np.abs(dudt - v)[5:-5].max() < 1e-4 * rate
    # before the stage the beam is at rest
    assert h.velocity(0.2499) == 0.0 and h.velocity(0.2501) > 0.0


def test_tabulated_history_follows_the_table_between_its_corners(tmp_path):
    path = tmp_path / "u.csv"
    path.write_text("time_s,displacement_m\n0,0\n1,0.002\n3,-0.002\n4,0\n")
    tt, uu = read_displacement_table(path)
    ramp, start = 0.1, 0.5
    h = table(tt, uu, start, ramp)
    origin = start + ramp / 2
    for x in (0.3, 0.5, 1.5, 2.0, 2.7, 3.5):  # away from the corners: exactly the table
        assert h.path.displacement(origin + x) == pytest.approx(np.interp(x, tt, uu), abs=1e-15)
    assert h.velocity(start) == 0.0 and h.velocity(h.end_s) == 0.0
    assert h.end_s == pytest.approx(origin + 4 + ramp / 2)
    # a reversal from +2 mm/s to -2 mm/s falls short of the corner by 0.1132 |w| r
    assert h.path.displacement(origin + 1) == pytest.approx(
        0.002 - REVERSAL_SHORTFALL * 0.002 * ramp, rel=1e-9)
    assert [(c.amplitude_m, c.start_s) for c in h.cycles] == [(0.002, start)]
    assert h.cycles[0].end_s == h.end_s


def test_a_table_that_first_goes_down_has_its_cycles_from_its_down_crossings():
    h = table([0, 1, 3, 4, 5, 7, 8], [0, -1e-3, 1e-3, 0, -2e-3, 2e-3, 0], 0.5, 0.1)
    assert [c.amplitude_m for c in h.cycles] == pytest.approx([1e-3, 2e-3])
    assert h.cycles[0].start_s == 0.5 and h.cycles[1].end_s == h.end_s
    assert h.cycles[1].start_s == pytest.approx(0.55 + 4.0)


@pytest.mark.parametrize("text, what", [
    ("t,u\n0,0\n1,1\n", "header"),
    ("time_s,displacement_m\n0,0\n", "at least two rows"),
    ("time_s,displacement_m\n0,0\n1,x\n", "line 3"),
    ("time_s,displacement_m\n0,0\n1,1\n1,2\n", "increase strictly"),
    ("time_s,displacement_m\n0,0.001\n1,1\n", "time 0, displacement 0"),
])
def test_a_bad_table_is_refused_naming_the_problem(tmp_path, text, what):
    path = tmp_path / "u.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=what):
        read_displacement_table(path)
