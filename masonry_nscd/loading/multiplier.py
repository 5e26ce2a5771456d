r"""Load multipliers that grow until collapse, and the smooth motion of a support.

A limit-state run loads a structure with a pattern (the weight of every block along a
direction, a force on one block) scaled by a multiplier that rises to a constant part and then
grows at a constant rate (the pseudo-static seismic or tilting-table test)::

    lambda(t) = value s((t - start) / ramp) + rate ramp S((t - start) / ramp)

with ``s`` the tanh ramp of :func:`masonry_nscd.loading.smooth_step` and ``S(x) = int_0^x s``
(:func:`masonry_nscd.loading.ramp_integral`): the constant part rises over ``ramp``
and the growth starts along the same ramp, so that ``d lambda / dt`` has no jump; after the
ramp ``lambda = value + rate (t - start - ramp / 2)``. The multiplier is dimensionless for a body
force (``lambda g m`` on each block) and a force (N) for a point load. Where a time ``hold`` is
given, the multiplier stops there and keeps the value it reached, ``lambda(t) =
lambda(min(t, hold))``: the load held, to see whether the structure comes to rest under it.

A support that settles moves by ``d s((t - start) / duration)`` (m, per component): its
velocity is imposed, with the displacement known exactly (``displacement``, so that
:func:`masonry_nscd.loading.step_velocity` moves it by ``U(t1) - U(t0)`` in every step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from masonry_nscd.loading import K_TANH, ramp_integral, smooth_step


@dataclass(frozen=True)
class GrowingMultiplier:
    """``lambda(t)`` of the module docstring (a history: ``lambda(t)`` by calling it)."""

    value: float
    rate: float  # per s
    start: float  # s
    ramp: float  # s
    hold: float | None = None  # s; the multiplier is held from there on (None: never)

    def __call__(self, t: float) -> float:
        if self.hold is not None:
            t = min(t, self.hold)
        x = (t - self.start) / self.ramp
        return self.value * smooth_step(t, self.start, self.ramp) + \
            self.rate * self.ramp * ramp_integral(x)

    def time_of(self, level: float) -> float | None:
        """The first time (s) at which ``lambda`` reaches ``level`` (None: never)."""
        if self.hold is not None:
            t = GrowingMultiplier(self.value, self.rate, self.start, self.ramp).time_of(level)
            return t if t is None or t <= self.hold else None
        if level <= 0.0 or (self.value <= 0.0 and self.rate <= 0.0):
            return None if level > 0.0 else 0.0
        lo, hi = self.start, self.start + self.ramp
        if self(hi) < level:
            if self.rate <= 0.0:
                return None
            return hi + (level - self(hi)) / self.rate
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self(mid) < level else (lo, mid)
        return hi


@dataclass(frozen=True)
class SmoothMotion:
    """The velocity (m/s) of one component of a support that moves by ``distance`` (m) along
    the tanh ramp of ``duration`` (s) from ``start`` (s); ``displacement(t)`` is exact."""

    distance: float
    start: float
    duration: float

    def displacement(self, t: float) -> float:
        return self.distance * smooth_step(t, self.start, self.duration)

    def __call__(self, t: float) -> float:
        if t <= self.start or t >= self.start + self.duration:
            return 0.0
        k = K_TANH
        x = (t - self.start) / self.duration
        slope = k / (math.tanh(k) * math.cosh(k * (2.0 * x - 1.0)) ** 2)  # ds/dx
        return self.distance * slope / self.duration
