r"""Cycles of a force-displacement curve: peaks, stiffness, energy, damping, envelope.

Plain arrays in, plain rows out (no run folder, no scene): ``t`` (s), ``u`` (mm), ``f`` (kN),
and the cycle windows of the history (:class:`masonry_nscd.loading.histories.Cycle`, as kept
in ``scene.json``: ``start_s``, ``end_s``, ``amplitude_m``, ``repetition``). Forces in kN
times displacements in mm are joules.

Per cycle (:func:`cycle_row`), on the rows of its window, the window's ends interpolated
linearly in time (:func:`cut`):

* peak forces: ``F+ = max F`` and ``F- = min F`` (signed, kN) and the displacements ``U(F+)``,
  ``U(F-)`` (mm) where they are reached;
* the tips of the loop: the largest and smallest displacements ``U_max``, ``U_min`` (mm) and
  the forces there, ``F(U_max)``, ``F(U_min)`` (kN);
* secant (peak-to-peak) stiffness ``K = (F(U_max) - F(U_min)) / (U_max - U_min)`` (kN/mm),
  through the tips of the loop, as for the cycle stiffness of cyclic wall tests (ASTM E2126,
  EN 12512): on a plateau of sliding the force peaks anywhere along it, while the tips are
  where the protocol turns;
* work done on the wall over the cycle, ``E = int F dU`` (J), the trapezoidal rule along the
  path: the area of the loop, traversed clockwise. It is the energy dissipated when the wall
  ends the cycle in the state it started it in (a closed loop); otherwise it also holds the
  change of the elastic energy stored (a residual force at ``U = 0``);
* equivalent viscous damping ratio (Jacobsen; Chopra, *Dynamics of Structures*, section 3.9:
  ``xi = E_D / (4 pi E_So)``, ``E_So = k u0^2 / 2`` the strain energy of the equivalent linear
  system at the amplitude), with ``E_So`` taken as the mean of the strain energies at the two
  tips, ``(F(U_max) U_max + |F(U_min) U_min|) / 4``::

      xi = E / (2 pi (F(U_max) U_max + |F(U_min) U_min|) / 2)

  (dimensionless; ``None`` when the denominator is not positive). For a symmetric loop of
  tips ``+-(U0, F0)`` this is ``E / (2 pi F0 U0)``; for the parallelogram of an elastic,
  perfectly plastic spring (stiffness k, yield force Fy, amplitude U0 > Uy = Fy/k),
  ``E = 4 Fy (U0 - Uy)`` and ``xi = 2 (1 - Uy/U0) / pi``.

Envelope (backbone, :func:`envelope_rows`): in each direction, the peak-force point
``(U(F+), F+)`` (and ``(U(F-), F-)``) of the first cycle at each amplitude (``repetition``
1), in the order of the amplitudes.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]



def cut(t: Sequence[float], u: Sequence[float], f: Sequence[float], start_s: float,
        end_s: float) -> tuple[FloatArray, FloatArray]:
    """``(u, f)`` of the rows with ``start_s < t < end_s``, with the values at ``start_s``
    and ``end_s`` interpolated linearly in ``t`` added at both ends (clamped to the data)."""
    t, u, f = (np.asarray(a, dtype=float) for a in (t, u, f))
    inside = (t > start_s) & (t < end_s)
    ends = [np.interp([s], t, a)[0] for s in (start_s, end_s) for a in (u, f)]
    uu = np.concatenate(([ends[0]], u[inside], [ends[2]]))
    ff = np.concatenate(([ends[1]], f[inside], [ends[3]]))
    return uu, ff


def loop_work(u: Sequence[float], f: Sequence[float]) -> float:
    """``int F dU`` along the path (trapezoidal rule); kN x mm = J."""
    u, f = np.asarray(u, dtype=float), np.asarray(f, dtype=float)
    if len(u) < 2:
        return 0.0
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(u)))


def cycle_row(u: Sequence[float], f: Sequence[float]) -> dict[str, float | None]:
    """The quantities of one cycle from its path (module docstring); keys as
    :data:`CYCLE_COLUMNS`."""
    u, f = np.asarray(u, dtype=float), np.asarray(f, dtype=float)
    ip, ineg = int(np.argmax(f)), int(np.argmin(f))
    imax, imin = int(np.argmax(u)), int(np.argmin(u))
    work = loop_work(u, f)
    du = u[imax] - u[imin]
    k = (f[imax] - f[imin]) / du if du > 0.0 else None
    strain = 0.5 * (f[imax] * u[imax] + abs(f[imin] * u[imin]))
    xi = work / (2.0 * math.pi * strain) if strain > 0.0 else None
    return {"peak_force_pos_kN": float(f[ip]), "ux_at_peak_pos_mm": float(u[ip]),
            "peak_force_neg_kN": float(f[ineg]), "ux_at_peak_neg_mm": float(u[ineg]),
            "ux_max_mm": float(u[imax]), "fx_at_ux_max_kN": float(f[imax]),
            "ux_min_mm": float(u[imin]), "fx_at_ux_min_kN": float(f[imin]),
            "secant_stiffness_kN_mm": None if k is None else float(k),
            "dissipated_energy_J": work, "damping_ratio_eq": None if xi is None else float(xi)}


def cycle_rows(t: Sequence[float], u: Sequence[float], f: Sequence[float],
               cycles: Sequence[Mapping[str, Any]],
               last_time_s: float | None = None) -> list[dict[str, Any]]:
    """One row per cycle of ``cycles`` (``start_s``, ``end_s``, ``amplitude_m``,
    ``repetition``) completed by ``last_time_s`` (default: the last ``t``; within 1e-9 s), with
    the keys of :data:`CYCLE_COLUMNS`."""
    t = np.asarray(t, dtype=float)
    if not len(t):
        return []
    last = float(t[-1]) if last_time_s is None else float(last_time_s)
    rows = []
    for n, c in enumerate(cycles, start=1):
        if c["end_s"] > last + 1e-9:
            break
        uu, ff = cut(t, u, f, c["start_s"], c["end_s"])
        rows.append({"cycle": int(c.get("index", n)), "amplitude_mm": 1e3 * c["amplitude_m"],
                     "repetition": int(c.get("repetition", 1)), "start_s": float(c["start_s"]),
                     "end_s": float(c["end_s"]), **cycle_row(uu, ff)})
    return rows


def envelope_rows(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The envelope in each direction: the peak-force points of the first cycle at each
    amplitude (``repetition`` 1), positive direction first; keys :data:`ENVELOPE_COLUMNS`."""
    first = [r for r in rows if r["repetition"] == 1]
    out = []
    for direction, sign in (("positive", "pos"), ("negative", "neg")):
        out += [{"direction": direction, "amplitude_mm": r["amplitude_mm"], "cycle": r["cycle"],
                 "ux_mm": r[f"ux_at_peak_{sign}_mm"], "fx_kN": r[f"peak_force_{sign}_kN"]}
                for r in first]
    return out


def envelope_arrays(envelope: Sequence[Mapping[str, Any]],
                    direction: str) -> tuple[FloatArray, FloatArray]:
    """``(ux_mm, fx_kN)`` of the envelope points of one direction, from the origin."""
    pts = [(r["ux_mm"], r["fx_kN"]) for r in envelope if r["direction"] == direction]
    u = np.array([0.0] + [p[0] for p in pts])
    f = np.array([0.0] + [p[1] for p in pts])
    return u, f
