r"""Ground motion: an acceleration record applied to the base as its imposed motion.

The record is a CSV file ``time_s, acceleration_m_s2`` (s, m/s^2; :func:`read_acceleration_record`)
read as a piecewise-linear acceleration ``a(t)`` between its rows, scaled by ``scale``, its time
0 at ``start_s`` of the run (zero before; after its last row the acceleration is zero and the base
keeps the velocity it has). The base (the lower beam of a wall) moves along ``direction`` with
the record integrated exactly, once to the velocity and again to the displacement: on
``[t_k, t_k+1]``, with ``tau = t - t_k`` and ``s_k = (a_k+1 - a_k) / (t_k+1 - t_k)``,

    V(t) = V_k + a_k tau + s_k tau^2 / 2
    D(t) = D_k + V_k tau + a_k tau^2 / 2 + s_k tau^3 / 6,       V_0 = D_0 = 0.

:class:`GroundMotion` is a velocity history with a ``displacement`` method, so that the
integrator imposes on the base the velocity that moves it by exactly ``D(t1) - D(t0)`` per step
(``loading.step_velocity``): the base stays on its path whatever the step and its halvings.

Why the base moves rather than an inertial body force ``-m a(t)`` on every body: with the
base moving, the contacts with the base and their friction are those of the real problem (a
free-standing block or wall can slide or rock on its base, the Housner check,
``tests/test_ground_motion.py``), the joint law sees the true relative displacements, the
reported forces of the beams are the true base shear, and the energy balance counts the input
as the work of the base's reaction (``nscd/energy.py``). A body force would give the same
relative motion for a structure fixed to a rigid base, but not for one that slides on it.
Drift is measured relative to the base (``scenes/wall.py``).

Units: s, m/s^2, m/s, m throughout.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from masonry_nscd.loading.histories import read_time_series

__all__ = ["GroundMotion", "read_acceleration_record"]


def read_acceleration_record(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``(time_s, acceleration_m_s2)`` of a CSV file with that header (s, m/s^2).

    Lines starting with ``#`` and empty lines are skipped. Raises ValueError naming the file
    and the line for: a missing or other header, a row that is not two numbers, a value that
    is not finite, fewer than two rows, a first time other than 0, times that do not increase
    strictly.
    """
    return read_time_series(path, "acceleration_m_s2",
                            time_zero="its time 0 is the case's loading.ground_motion.start_s")


@dataclass(frozen=True)
class GroundMotion:
    """The base's velocity ``__call__(t)`` (m/s), displacement and acceleration of a record
    (module docstring): rows ``time_s`` (from 0, increasing) and ``acceleration_m_s2``
    (already scaled), its time 0 at ``start_s`` of the run."""

    time_s: np.ndarray
    acceleration_m_s2: np.ndarray
    start_s: float = 0.0
    _v: np.ndarray = field(init=False, repr=False, compare=False)
    _d: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.time_s, dtype=float)
        a = np.asarray(self.acceleration_m_s2, dtype=float)
        object.__setattr__(self, "time_s", t)
        object.__setattr__(self, "acceleration_m_s2", a)
        dt = np.diff(t)
        s = np.diff(a) / dt
        v = np.concatenate(([0.0], np.cumsum(a[:-1] * dt + s * dt ** 2 / 2.0)))
        d = np.zeros_like(v)
        for k in range(len(dt)):
            d[k + 1] = d[k] + v[k] * dt[k] + a[k] * dt[k] ** 2 / 2.0 + s[k] * dt[k] ** 3 / 6.0
        object.__setattr__(self, "_v", v)
        object.__setattr__(self, "_d", d)

    def _at(self, t: float) -> tuple[int, float]:
        """The segment ``k`` holding record time ``t`` (the last row for ``t`` past the end)
        and ``tau = t - t_k``; ``(-1, 0)`` before the record."""
        if t <= 0.0:
            return -1, 0.0
        k = int(np.searchsorted(self.time_s, t, side="right")) - 1
        return k, t - float(self.time_s[k])

    def acceleration(self, t: float) -> float:
        """``a(t)`` (m/s^2), run time ``t`` (s)."""
        k, tau = self._at(t - self.start_s)
        if k < 0 or k >= len(self.time_s) - 1:
            return 0.0
        a, dt = self.acceleration_m_s2, self.time_s[k + 1] - self.time_s[k]
        return float(a[k] + (a[k + 1] - a[k]) * tau / dt)

    def __call__(self, t: float) -> float:
        """The base's velocity ``V(t)`` (m/s), run time ``t`` (s)."""
        k, tau = self._at(t - self.start_s)
        if k < 0:
            return 0.0
        if k >= len(self.time_s) - 1:
            return float(self._v[-1])
        a, s = self._segment(k)
        return float(self._v[k] + a * tau + s * tau ** 2 / 2.0)

    def displacement(self, t: float) -> float:
        """The base's displacement ``D(t)`` (m), run time ``t`` (s)."""
        k, tau = self._at(t - self.start_s)
        if k < 0:
            return 0.0
        if k >= len(self.time_s) - 1:
            return float(self._d[-1] + self._v[-1] * tau)
        a, s = self._segment(k)
        return float(self._d[k] + self._v[k] * tau + a * tau ** 2 / 2.0 + s * tau ** 3 / 6.0)

    def _segment(self, k: int) -> tuple[float, float]:
        a = self.acceleration_m_s2
        return float(a[k]), float((a[k + 1] - a[k]) / (self.time_s[k + 1] - self.time_s[k]))

    @property
    def end_s(self) -> float:
        """Run time of the record's last row (s)."""
        return self.start_s + float(self.time_s[-1])

    @property
    def peak_acceleration_m_s2(self) -> float:
        """Largest ``|a|`` of the record (m/s^2)."""
        return float(np.abs(self.acceleration_m_s2).max())
