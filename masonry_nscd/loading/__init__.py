r"""Load histories (functions of time) and the external loads they scale.

A ramp goes from 0 at ``start`` to 1 at ``start + duration`` (s) along

    s(x) = (tanh(k (2 x - 1)) + tanh(k)) / (2 tanh(k)),     x = (t - start) / duration,

with ``k = 3``: an S-curve whose slope at both ends is ``k (1 - tanh(k)^2) / tanh(k)``, about
3 % of its mid-ramp slope, so loads start and stop with no shock. Forces are the ramp times their
full value; the horizontal displacement is driven through its velocity, ``rate * s(t)``, so that
the top beam starts moving smoothly and then moves at constant rate.

Its integral, ``S(x) = int_0^x s(y) dy`` (:func:`ramp_integral`), is 0 for ``x <= 0``, ``x - 1/2``
for ``x >= 1`` and in between

    S(x) = x / 2 + (ln cosh(k (2 x - 1)) - ln cosh(k)) / (4 k tanh(k)),

so a velocity ``v(t) = rate * s((t - start) / duration)`` moves a point by exactly
``U(t) = rate * duration * S((t - start) / duration)`` (:class:`RampedVelocity`).

An imposed velocity is a *motion*: a callable ``v(t)`` (m/s) with a ``displacement(t)`` method
(m), ``U(t) = int_0^t v``. The integrator sets the velocity at the end of each step from the
displacement (:func:`step_velocity`), so that a driven dof is on its path ``U(t)`` at the end of
every step, whatever the steps' sizes and their subdivisions.

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


def smooth_step(t: float, start: float, duration: float) -> float:
    """The tanh ramp from 0 (t <= start) to 1 (t >= start + duration)."""
    if t <= start:
        return 0.0
    if t >= start + duration:
        return 1.0
    x = (t - start) / duration
    return (math.tanh(K_TANH * (2.0 * x - 1.0)) + math.tanh(K_TANH)) / (2.0 * math.tanh(K_TANH))


def ramp_integral(x: float) -> float:
    """``S(x) = int_0^x s(y) dy`` of the unit tanh ramp ``s`` (dimensionless, module
    docstring): 0 for ``x <= 0``, ``x - 1/2`` for ``x >= 1``."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return x - 0.5
    k = K_TANH
    return 0.5 * x + (_log_cosh(k * (2.0 * x - 1.0)) - _log_cosh(k)) / (4.0 * k * math.tanh(k))


def _log_cosh(z: float) -> float:
    z = abs(z)
    return z + math.log1p(math.exp(-2.0 * z)) - math.log(2.0)


@dataclass(frozen=True)
class Ramp:
    """``value * smooth_step(t, start, duration)`` as a callable history."""

    value: float
    start: float
    duration: float

    def __call__(self, t: float) -> float:
        return self.value * smooth_step(t, self.start, self.duration)


@dataclass(frozen=True)
class RampedVelocity:
    """A motion (module docstring) whose velocity rises along the tanh ramp to ``rate`` (m/s)
    from ``start`` over ``duration`` (s) and stays there: ``v(t) = rate s(x)``,
    ``U(t) = rate duration S(x)``, ``x = (t - start) / duration``. After the ramp the point
    lags the sharp path ``rate (t - start)`` by ``rate duration / 2``."""

    rate: float
    start: float
    duration: float

    def __call__(self, t: float) -> float:
        return self.rate * smooth_step(t, self.start, self.duration)

    def displacement(self, t: float) -> float:
        return self.rate * self.duration * ramp_integral((t - self.start) / self.duration)


@dataclass(frozen=True)
class Still:
    """The motion of a dof held still: zero velocity and displacement at all times."""

    def __call__(self, t: float) -> float:
        return 0.0

    def displacement(self, t: float) -> float:
        return 0.0


#: a dof held still (a :class:`Still` motion)
at_rest = Still()


def step_velocity(motion: History, t0: float, t1: float, theta: float, v0: float) -> float:
    r"""The imposed velocity at the end of a step from ``t0`` to ``t1`` (s), given ``v0`` (m/s)
    at its start: the one that moves the dof by exactly ``U(t1) - U(t0)`` of the motion's
    displacement ``U`` (m) under the theta scheme ``u1 = u0 + h (theta v1 + (1 - theta) v0)``:

        v1 = ((U(t1) - U(t0)) / h - (1 - theta) v0) / theta,     h = t1 - t0.

    So the driven dof is on its path at the end of every step however the steps are sized or
    subdivided. Sampling the velocity instead, ``v1 = v(t1)``, moves it by ``h v(t1)``, which
    differs from ``U(t1) - U(t0)`` wherever the velocity changes: a push that made one step of
    its ramp as two halves ended 1.2e-4 mm off its path on the smoke wall, and every run off
    the path by half a step times the velocity reached. A history with no ``displacement``
    is a TypeError."""
    displacement = getattr(motion, "displacement", None)
    if displacement is None:
        raise TypeError(f"an imposed velocity needs its displacement (a 'displacement(t)' "
                        f"method), got {motion!r}")
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

    def without(self, dofs) -> Loads:
        """The same loads with nothing on ``dofs`` (global dof indices): those of bodies taken
        out of the model."""
        patterns = [p.copy() for p in self.patterns]
        for p in patterns:
            p[np.asarray(dofs, dtype=np.int64)] = 0.0
        return Loads(patterns, list(self.histories))
