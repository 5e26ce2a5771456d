"""The energy balance (nscd/energy.py) on small scenes: it closes, and its terms are physics."""

import numpy as np
import pytest

from masonry_nscd.nscd.checkpoint import integrator_state, restore_integrator
from masonry_nscd.scenes.small import block_launched


def _run(integ, end):
    while integ.t < end - 1e-9:
        rep = integ.step()
        assert rep.converged
    return integ.energy_account.balance(integ)


@pytest.mark.parametrize("rigid", [False, True])
def test_block_bouncing_and_sliding_balances_its_energy(rigid):
    # launched by a force pulse, the elastic block flies, lands (an impact on rigid contact
    # points), bounces on its elastic modes and slides until friction stops it; the rigid
    # block lands and slides
    integ, _ = block_launched(rigid=rigid)
    b = _run(integ, 0.4)
    w = b["external_work"]
    # the input: the pulse's work (gravity's work nets out over the flight, the block ends
    # where it started in y); about the kinetic energy of the launch
    assert w > 1.0
    assert abs(b["imbalance"]) < 0.01 * w
    for k in ("dissipated_friction", "dissipated_impacts"):
        assert b[k] > 0.02 * w, k
    assert b["numerical"] >= 0.0
    assert b["dissipated_cohesion"] == 0.0 and b["dissipated_blocks"] == 0.0
    # at rest at the end (implicit Euler damps the elastic vibrations)
    assert b["kinetic"] < 1e-6 * w
    if not rigid:  # the landing sets the elastic block vibrating: strain energy on the way
        assert b["elastic_blocks"] > 0.0


def test_energy_balance_survives_halved_steps_and_a_checkpoint():
    # a step made again as two halves, and a state restored into a new integrator, carry the
    # accumulated terms: the balance of the whole run still closes
    integ, _ = block_launched(rigid=True, h=1e-3)
    _run(integ, 0.1)
    state = integrator_state(integ)
    again, _ = block_launched(rigid=True, h=1e-3, max_halvings=1)
    restore_integrator(again, state)
    assert np.array_equal(again.energy, integ.energy)
    half = again._subdivide(integrator_state(again), None)
    assert half.substeps == 2
    b = _run(again, 0.4)
    assert abs(b["imbalance"]) < 1e-6 * b["external_work"]
