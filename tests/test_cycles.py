"""Cycle post-processing (``post/cycles.py``) on hand-computable loops."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from masonry_nscd.post.cycles import cycle_row, cycle_rows, envelope_rows, loop_work


def _polyline(points, n=50):
    """A path through ``points`` (u, f), each segment cut in ``n`` pieces."""
    u, f = [points[0][0]], [points[0][1]]
    for (u0, f0), (u1, f1) in itertools.pairwise(points):
        s = np.linspace(0.0, 1.0, n + 1)[1:]
        u += list(u0 + s * (u1 - u0))
        f += list(f0 + s * (f1 - f0))
    return np.array(u), np.array(f)


def test_parallelogram_loop_of_an_elastic_perfectly_plastic_spring():
    # k = 10 kN/mm, Fy = 10 kN (Uy = 1 mm), amplitude 3 mm, steady state, from U = 0 going up
    # on the plastic branch: area 4 Fy (U0 - Uy) = 80 J; xi = 2 (1 - Uy/U0) / pi
    u, f = _polyline([(0, 10), (3, 10), (1, -10), (-3, -10), (-1, 10), (0, 10)])
    r = cycle_row(u, f)
    assert r["dissipated_energy_J"] == pytest.approx(80.0, rel=1e-12)
    assert r["damping_ratio_eq"] == pytest.approx(2.0 * (1.0 - 1.0 / 3.0) / math.pi, rel=1e-12)
    assert r["secant_stiffness_kN_mm"] == pytest.approx(20.0 / 6.0, rel=1e-12)
    assert (r["ux_max_mm"], r["fx_at_ux_max_kN"]) == (3.0, 10.0)
    assert (r["ux_min_mm"], r["fx_at_ux_min_kN"]) == (-3.0, -10.0)
    assert r["peak_force_pos_kN"] == 10.0 and r["peak_force_neg_kN"] == -10.0


def test_first_cycle_from_rest_counts_the_elastic_energy_left():
    # the same spring from rest: work 75 J = 70 J dissipated (Fy x 7 mm of plastic slip) + 5 J
    # stored at the end (10 kN at U = 0: F^2 / 2k)
    u, f = _polyline([(0, 0), (1, 10), (3, 10), (1, -10), (-3, -10), (-1, 10), (0, 10)])
    assert loop_work(u, f) == pytest.approx(75.0, rel=1e-12)


def test_an_elastic_line_dissipates_nothing():
    u, f = _polyline([(0, 0), (2, 8), (-2, -8), (0, 0)])
    r = cycle_row(u, f)
    assert r["dissipated_energy_J"] == pytest.approx(0.0, abs=1e-12)
    assert r["damping_ratio_eq"] == pytest.approx(0.0, abs=1e-12)
    assert r["secant_stiffness_kN_mm"] == pytest.approx(4.0)


def test_cycles_are_cut_by_their_windows_and_give_the_envelope():
    # two elastic-plastic cycles in time, amplitudes 1 and 3 mm (Fy 5 kN at 0.5 mm)
    u1, f1 = _polyline([(0, 0), (0.5, 5), (1, 5), (0, -5), (-1, -5), (0, 5)], 20)
    u2, f2 = _polyline([(0, 5), (3, 5), (2, -5), (-3, -5), (-2, 5), (0, 5)], 20)
    u = np.concatenate((u1, u2[1:]))
    f = np.concatenate((f1, f2[1:]))
    t = np.arange(len(u), dtype=float)
    cycles = [{"index": 1, "amplitude_m": 1e-3, "repetition": 1, "start_s": 0.0,
               "end_s": float(len(u1) - 1)},
              {"index": 2, "amplitude_m": 3e-3, "repetition": 1, "start_s": float(len(u1) - 1),
               "end_s": float(len(u) - 1)},
              {"index": 3, "amplitude_m": 3e-3, "repetition": 2, "start_s": float(len(u) - 1),
               "end_s": float(len(u) + 50)}]  # not run: left out
    rows = cycle_rows(t, u, f, cycles)
    assert [r["cycle"] for r in rows] == [1, 2]
    # cycle 1 from rest: plastic slips 0.5 + 1 mm at 5 kN, + 1.25 J stored at the end (5 kN at
    # U = 0, k = 10 kN/mm); cycle 2, a parallelogram: 4 Fy (U0 - Uy) = 4 x 5 x 2.5
    assert rows[0]["dissipated_energy_J"] == pytest.approx(7.5 + 1.25)
    assert rows[1]["dissipated_energy_J"] == pytest.approx(50.0)
    env = envelope_rows(rows)
    assert [(e["direction"], e["amplitude_mm"], e["fx_kN"]) for e in env] == [
        ("positive", 1.0, 5.0), ("positive", 3.0, 5.0),
        ("negative", 1.0, -5.0), ("negative", 3.0, -5.0)]
