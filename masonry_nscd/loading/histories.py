r"""Displacement histories of the driven point: monotonic, cyclic, tabulated.

The horizontal displacement ``U(t)`` (m) of the top beam's load point is imposed through its
velocity ``v(t) = dU/dt`` (m/s): the integrator takes a velocity history of the beam's x dof,
whatever the history.

Monotonic (the push, :func:`monotonic`)
    ``v(t) = rate * s((t - start) / ramp)``, the tanh ramp ``s`` of
    :func:`masonry_nscd.loading.smooth_step`: the velocity rises smoothly to ``rate`` over
    ``ramp`` and stays there, ``U(t) = rate ramp S((t - start) / ramp)``
    (:class:`masonry_nscd.loading.RampedVelocity`); the run stops on the displacement
    (``target_m``), at ``start + ramp / 2 + target / rate``.

A path with rounded corners (:class:`SmoothPath`, the cyclic and tabulated histories)
    A sharp piecewise-linear path ``U*(t)`` with corners at times ``t_k`` (s), velocity
    ``w_k`` (m/s) after corner ``k`` (``w_{-1} = 0``), each change of velocity spread over a
    tanh ramp of duration ``r`` centred on its corner::

        v(t) = sum_k (w_k - w_{k-1}) s((t - t_k) / r + 1/2)                            (1)
        U(t) = sum_k (w_k - w_{k-1}) r S((t - t_k) / r + 1/2)                          (2)

    with ``S(x) = int_0^x s``: 0 for ``x <= 0``, ``x - 1/2`` for ``x >= 1``, and in between
    ``S(x) = x/2 + (ln cosh(K (2x - 1)) - ln cosh K) / (4 K tanh K)``, ``K = K_TANH = 3``.
    Since ``s(x) + s(1 - x) = 1``, ``int_0^1 s = 1/2``: a ramp centred on a corner takes as
    much displacement before it as it gives back after it, so ``U(t) = U*(t)`` exactly outside
    the ramps (also where ramps overlap, by linearity), and a corner is only rounded. At a
    reversal from ``+w`` to ``-w`` the velocity is zero at the middle of the ramp, where the
    path turns ``2 w r S(1/2) = 0.1132 w r`` short of the sharp corner
    (:data:`REVERSAL_SHORTFALL`, ``S(1/2) = 0.0566``).

Cyclic (:func:`cyclic`)
    For each amplitude ``A`` of ``amplitudes`` in turn, ``n`` cycles ``0 -> +A -> -A -> 0`` at
    the speed ``rate``; the path leaves 0 at ``start`` with the ramp of the monotonic history,
    and stops at 0 after the last cycle. To reach exactly ``+-A``, the sharp path turns at
    ``+-(A + delta)``, ``delta = 2 rate r S(1/2)``: the real path then stops exactly at ``A``
    (velocity zero) and turns back. It crosses 0 at constant velocity between cycles (no
    reversal there). Cycle ``j`` spans from the up-crossing of 0 that starts it to the next
    one (the first from ``start``, the last to the end, where the beam is back at rest at 0).
    The ramps do not overlap when ``A + delta >= rate r`` for every amplitude; the case asks
    ``A >= rate r``. End: ``start + r + sum over cycles of 4 (A + delta) / rate``.

Tabulated (:func:`table`)
    A CSV file ``time_s, displacement_m`` read as the sharp path ``U*`` (linear between the
    rows, :func:`read_displacement_table`), its time 0 at ``start + r/2`` (the middle of the
    first ramp, as the monotonic path lags its ideal ``rate (t - start)`` by ``r/2``): so the
    beam starts to move at ``start``. A corner at every row, the last one bringing the beam to
    rest; the path follows the table exactly except within ``r/2`` of a row, where it is
    rounded (a reversal falls short by ``0.1132 |w| r``, as above). The table must start at
    time 0 with displacement 0 (the beam's place when the stage starts). Its cycles are the
    windows between the crossings of 0 by ``U*`` in the direction of its first move (upwards,
    from 0 or below to above 0, for a table that first goes up), counted only where the path
    also goes past 0 the other way; amplitude ``(max U* - min U*) / 2`` in the window.

Units: s, m, m/s throughout. A history gives what the summary needs to read a run
(:meth:`DisplacementHistory.info`): its kind, its end, its cycles.
"""

from __future__ import annotations

import bisect
import csv
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from masonry_nscd.loading import RampedVelocity, ramp_integral, smooth_step

__all__ = ["REVERSAL_SHORTFALL", "Cycle", "DisplacementHistory", "SmoothPath", "cyclic",
           "monotonic", "ramp_integral", "read_displacement_table", "table"]


#: How far short of a sharp corner a reversal from ``+w`` to ``-w`` turns, in units of
#: ``w r`` (velocity times ramp duration): ``2 S(1/2)`` (dimensionless).
REVERSAL_SHORTFALL = 2.0 * ramp_integral(0.5)


@dataclass(frozen=True)
class Cycle:
    """One cycle of a history: from ``start_s`` to ``end_s`` (s), amplitude ``amplitude_m``
    (m); ``index`` counts from 1, ``repetition`` counts the cycles of the same amplitude from
    1."""

    index: int
    amplitude_m: float
    repetition: int
    start_s: float
    end_s: float


@dataclass(frozen=True)
class SmoothPath:
    """The velocity history (1) and displacement (2) of a sharp path with rounded corners.

    ``corners_s``: the corner times ``t_k`` (s, increasing); ``jumps_m_s``: the velocity change
    ``w_k - w_{k-1}`` at each (m/s); ``ramp_s``: the duration ``r`` of each change (s).
    """

    corners_s: np.ndarray
    jumps_m_s: np.ndarray
    ramp_s: float
    _before: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # velocity reached once every ramp up to corner k is over: cumulative jumps
        object.__setattr__(self, "_before", np.concatenate(([0.0], np.cumsum(self.jumps_m_s))))

    def _window(self, t: float) -> tuple[int, int]:
        """Corners whose ramp is over at ``t`` (the first ``i``) and those under way (``i..j``)."""
        half = 0.5 * self.ramp_s
        i = bisect.bisect_right(self.corners_s, t - half)  # corners with t_k + r/2 <= t
        j = bisect.bisect_right(self.corners_s, t + half)  # corners with t_k - r/2 <= t
        return i, j

    def __call__(self, t: float) -> float:
        """The velocity ``v(t)`` (m/s), equation (1)."""
        i, j = self._window(t)
        v = float(self._before[i])
        r = self.ramp_s
        for k in range(i, j):
            v += float(self.jumps_m_s[k]) * smooth_step(t, self.corners_s[k] - 0.5 * r, r)
        return v

    def displacement(self, t: float) -> float:
        """The displacement ``U(t)`` (m), equation (2)."""
        r = self.ramp_s
        x = (t - self.corners_s) / r + 0.5
        return float(sum(w * r * ramp_integral(float(xk)) for w, xk in
                         zip(self.jumps_m_s, x, strict=True) if xk > 0.0))

    @property
    def end_s(self) -> float:
        """When the last ramp is over (s)."""
        return float(self.corners_s[-1]) + 0.5 * self.ramp_s if len(self.corners_s) else 0.0


@dataclass(frozen=True)
class DisplacementHistory:
    """A displacement history: the kind (``monotonic``, ``cyclic``, ``table``), the beam's
    velocity ``velocity(t)`` (m/s), the end of the motion ``end_s`` (s; ``None`` for the
    monotonic push, which stops on its displacement), and the cycles."""

    kind: str
    velocity: Callable[[float], float]
    end_s: float | None
    cycles: tuple[Cycle, ...] = ()
    path: SmoothPath | None = None

    def turns_s(self) -> tuple[tuple[float, float], ...]:
        """The windows ``(t_k - r/2, t_k + r/2)`` (s) in which the velocity changes, one per
        corner of the path (none for the monotonic push, whose one ramp is at its start)."""
        if self.path is None:
            return ()
        half = 0.5 * self.path.ramp_s
        return tuple((float(t) - half, float(t) + half) for t in self.path.corners_s)

    def info(self) -> dict:
        """What the run folder keeps of the history (``scene.json``, SI units)."""
        return {"kind": self.kind, "end_s": self.end_s,
                "cycles": [{"index": c.index, "amplitude_m": c.amplitude_m,
                            "repetition": c.repetition, "start_s": c.start_s, "end_s": c.end_s}
                           for c in self.cycles]}


def monotonic(rate_m_s: float, start_s: float, ramp_s: float) -> DisplacementHistory:
    """The push: the velocity ramps to ``rate_m_s`` and stays (module docstring)."""
    return DisplacementHistory("monotonic", RampedVelocity(rate_m_s, start_s, ramp_s), None)


def cyclic(amplitudes_m: Sequence[float], cycles_per_amplitude: int, rate_m_s: float,
           start_s: float, ramp_s: float) -> DisplacementHistory:
    """``cycles_per_amplitude`` cycles ``0 -> +A -> -A -> 0`` per amplitude, at ``rate_m_s``,
    each reversal a tanh ramp of ``ramp_s`` that stops exactly at ``+-A`` (module docstring)."""
    rate, r = float(rate_m_s), float(ramp_s)
    delta = REVERSAL_SHORTFALL * rate * r
    t = start_s + 0.5 * r  # the first corner: from rest to +rate
    corners, jumps = [t], [rate]
    cycles = []
    for A in amplitudes_m:
        quarter = (float(A) + delta) / rate  # time from 0 to a sharp turn at +-(A + delta)
        for rep in range(1, int(cycles_per_amplitude) + 1):
            begin = t
            corners += [t + quarter, t + 3.0 * quarter]
            jumps += [-2.0 * rate, 2.0 * rate]
            t += 4.0 * quarter
            cycles.append([len(cycles) + 1, float(A), rep, begin, t])
    corners.append(t)  # back at 0: to rest
    jumps.append(-rate)
    path = SmoothPath(np.array(corners), np.array(jumps), r)
    if cycles:
        cycles[0][3] = float(start_s)
        cycles[-1][4] = path.end_s
    return DisplacementHistory("cyclic", path, path.end_s, tuple(Cycle(*c) for c in cycles),
                               path)


def read_time_series(path: str | Path, column: str,
                     time_zero: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``(time_s, <column>)`` of a two-column CSV file with the header
    ``time_s,<column>`` (lines starting with ``#`` and empty lines skipped).

    Raises ValueError naming the file and the line for: a missing file, a missing or other
    header, a row that is not two numbers, a value that is not finite, times that do not
    increase strictly, fewer than two rows, and, when ``time_zero`` says what the series'
    time 0 is, a first time other than 0.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ValueError(f"file not found: {path}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read {path}: {exc}") from None
    rows = [(n, row) for n, row in enumerate(csv.reader(text.splitlines()), start=1)
            if row and any(c.strip() for c in row) and not row[0].lstrip().startswith("#")]
    if not rows or [c.strip() for c in rows[0][1]] != ["time_s", column]:
        raise ValueError(f"{path}: the first line must be the header 'time_s,{column}'")
    t, v = [], []
    for n, row in rows[1:]:
        try:
            a, b = (float(c) for c in row)
        except ValueError:
            raise ValueError(f"{path}, line {n}: expected two numbers (time_s, {column}), "
                             f"got {','.join(row)!r}") from None
        if not (math.isfinite(a) and math.isfinite(b)):
            raise ValueError(f"{path}, line {n}: values must be finite")
        if t and not a > t[-1]:
            raise ValueError(f"{path}, line {n}: time {a:g} s does not follow {t[-1]:g} s "
                             "(times must increase strictly)")
        if not t and time_zero is not None and a != 0.0:
            raise ValueError(f"{path}, line {n}: the record must start at time 0 ({time_zero}),"
                             f" got {a:g} s")
        t.append(a)
        v.append(b)
    if len(t) < 2:
        raise ValueError(f"{path}: at least two rows are needed, found {len(t)}")
    return np.array(t), np.array(v)


def read_displacement_table(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The rows ``(time_s, displacement_m)`` of a CSV file with that header (s, m).

    Raises ValueError naming the line for: a missing or other header, a row that is not two
    numbers, a value that is not finite, fewer than two rows, a first row other than
    ``0, 0``, times that do not increase strictly (:func:`read_time_series`).
    """
    t, u = read_time_series(path, "displacement_m")
    if t[0] != 0.0 or u[0] != 0.0:
        raise ValueError(f"{path}: the first row must be time 0, displacement 0 (the beam's "
                         f"place when the horizontal stage starts), got {t[0]:g}, {u[0]:g}")
    return np.array(t), np.array(u)


def table(time_s: Sequence[float], displacement_m: Sequence[float], start_s: float,
          ramp_s: float) -> DisplacementHistory:
    """The tabulated path (module docstring): rows ``(time_s, displacement_m)`` from
    :func:`read_displacement_table`, corners rounded over ``ramp_s``."""
    tt, uu = np.asarray(time_s, dtype=float), np.asarray(displacement_m, dtype=float)
    origin = start_s + 0.5 * ramp_s
    w = np.diff(uu) / np.diff(tt)  # velocity of each segment
    jumps = np.diff(np.concatenate(([0.0], w, [0.0])))
    corners = origin + tt
    keep = jumps != 0.0  # a row in the middle of a straight segment is no corner
    path = SmoothPath(corners[keep], jumps[keep], float(ramp_s))
    cycles = []
    moving = np.flatnonzero(w != 0.0)
    d = np.sign(w[moving[0]]) if moving.size else 1.0  # the direction of the first move
    ud = d * uu  # in which cycles start upwards
    ups = [i for i in range(len(w)) if d * w[i] > 0.0 and ud[i] <= 0.0 < ud[i + 1]]
    last = len(uu) - 1
    for a, b in zip(ups, [*ups[1:], last], strict=True):
        # from the crossing of 0 in segment a to the next one, in segment b (or the table's end)
        inside = ud[a + 1:b + 1]
        if not (inside.size and inside.min() < 0.0):
            continue  # no way back past 0: not a cycle
        t0 = float(start_s) if a == 0 and uu[0] == 0.0 else origin + tt[a] - uu[a] / w[a]
        t1 = path.end_s if b == last else origin + tt[b] - uu[b] / w[b]
        amp = 0.5 * (max(0.0, inside.max()) - min(0.0, inside.min()))
        cycles.append([len(cycles) + 1, float(amp), 1, t0, float(t1)])
    for i, c in enumerate(cycles):  # repetitions of the same amplitude in a row
        prev = cycles[i - 1] if i else None
        c[2] = prev[2] + 1 if prev and math.isclose(prev[1], c[1], rel_tol=1e-9) else 1
    return DisplacementHistory("table", path, path.end_s, tuple(Cycle(*c) for c in cycles),
                               path)
