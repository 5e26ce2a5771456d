r"""Load histories (functions of time) and the external loads they scale.

A ramp goes from 0 at ``start`` to 1 at ``start + duration`` (s) along

    s(x) = (tanh(k (2 x - 1)) + tanh(k)) / (2 tanh(k)),     x = (t - start) / duration,

with ``k = 3``: an S-curve whose slope at both ends is ``k (1 - tanh(k)^2) / tanh(k)``, about
3 % of its mid-ramp slope, so loads start and stop with no shock. Forces are the ramp times their
full value; the horizontal displacement is driven through its velocity, ``rate * s(t)``, so that
the top beam starts moving smoothly and then moves at constant rate.

External loads are a sum of fixed patterns (N per dof) scaled by histories:
``F(t) = sum_k history_k(t) pattern_k`` (:class:`Loads`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

K_TANH = 3.0

History = Callable[[float], float]


def at_rest(t: float) -> float:
    """The history of a dof held still: zero velocity at all times."""
    return 0.0


def smooth_step(t: float, start: float, duration: float) -> float:
    """The tanh ramp from 0 (t <= start) to 1 (t >= start + duration)."""
    if t <= start:
        return 0.0
    if t >= start + duration:
        return 1.0
    x = (t - start) / duration
    return (math.tanh(K_TANH * (2.0 * x - 1.0)) + math.tanh(K_TANH)) / (2.0 * math.tanh(K_TANH))


@dataclass(frozen=True)
class Ramp:
    """``value * smooth_step(t, start, duration)`` as a callable history."""

    value: float
    start: float
    duration: float

    def __call__(self, t: float) -> float:
        return self.value * smooth_step(t, self.start, self.duration)


def step_velocity(history: History, t0: float, t1: float, theta: float, v0: float) -> float:
    r"""The imposed velocity at the end of a step from ``t0`` to ``t1`` (s), given ``v0`` (m/s)
    at its start.

    A history that knows its displacement ``U(t)`` (a ``displacement`` method, m: the cyclic
    and tabulated paths) gets the velocity that moves the dof by exactly ``U(t1) - U(t0)``
    under the theta scheme ``u1 = u0 + h (theta v1 + (1 - theta) v0)``:

        v1 = ((U(t1) - U(t0)) / h - (1 - theta) v0) / theta,     h = t1 - t0,

    so the driven point stays on its path however the steps are subdivided (sampling the
    velocity at ``t1`` integrates the reversals' ramps with an error that grows with each
    subdivided step). Any other history is sampled, ``v1 = history(t1)``: the monotonic push
    as the study made it."""
    displacement = getattr(history, "displacement", None)
    if displacement is None:
        return history(t1)
    mean = (displacement(t1) - displacement(t0)) / (t1 - t0)
    return (mean - (1.0 - theta) * v0) / theta


@dataclass
class Loads:
    """External loads: ``F(t) = sum_k history_k(t) * pattern_k`` (N)."""

    patterns: list[np.ndarray] = field(default_factory=list)
    histories: list[History] = field(default_factory=list)

    def add(self, pattern: np.ndarray, history: History) -> None:
        self.patterns.append(np.asarray(pattern, dtype=float))
        self.histories.append(history)

    def at(self, t: float, ndof: int) -> np.ndarray:
        F = np.zeros(ndof)
        for p, h in zip(self.patterns, self.histories):
            F += h(t) * p
        return F
