"""Write the synthetic acceleration record of cases/wall_ground_motion.yaml (no download).

    python cases/make_ground_motion_record.py            # writes cases/ground_motion_record.csv
    python cases/make_ground_motion_record.py --seed 7 --pga 4.0 -o other.csv

What it makes (SI units: s, m/s^2):

1. Gaussian white noise, ``--dt`` apart, from ``numpy.random.default_rng(--seed)``;
2. filtered in the frequency domain to the Kanai-Tajimi spectrum of a firm soil,

       S(w) ~ (w_g^4 + 4 z_g^2 w_g^2 w^2) / ((w_g^2 - w^2)^2 + 4 z_g^2 w_g^2 w^2),

   ``w_g = 2 pi --fg`` (5 Hz by default), ``z_g = --zg`` (0.6), with a Clough-Penzien high-pass
   ``w^4 / ((w_f^2 - w^2)^2 + 4 z_f^2 w_f^2 w^2)``, ``w_f = w_g / 10``, ``z_f = z_g``, that
   keeps the record's long periods (and the base's displacement) bounded;
3. shaped by a Jennings envelope: ``(t / t1)^2`` up to ``t1`` (--rise), 1 up to ``t2``
   (--rise + --strong), ``exp(-c (t - t2)) (T - t) / (T - t2)`` after, ``c = ln(20) / --decay``,
   ``T = t2 + --decay`` (so that it ends at 0);
4. baseline-corrected: ``c0 (1 - t/T) + c1 (t/T) (1 - t/T)`` taken off the acceleration (zero
   at ``T`` too) so that the base ends at rest where it started: its velocity and
   displacement, integrated as the program does (piecewise-linear acceleration), are zero at
   ``T`` (to the rounding of the written values);
5. scaled to the peak ground acceleration ``--pga`` (m/s^2), and followed by ``--tail`` s of
   zero acceleration, in which the wall comes to rest (its residual drift is read at the end).

The file starts with comment lines (``#``) that record how it was made, then the header
``time_s,acceleration_m_s2``.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np


def integrate(t: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and displacement at the rows of a piecewise-linear acceleration (exact)."""
    dt = np.diff(t)
    v = np.concatenate(([0.0], np.cumsum((a[:-1] + a[1:]) / 2.0 * dt)))
    d = np.concatenate(([0.0], np.cumsum(v[:-1] * dt + (2.0 * a[:-1] + a[1:]) * dt ** 2 / 6.0)))
    return v, d


def record(seed: int, dt: float, rise: float, strong: float, decay: float, fg: float,
           zg: float, pga: float, tail: float) -> tuple[np.ndarray, np.ndarray]:
    n = int(round((rise + strong + decay) / dt)) + 1
    t = dt * np.arange(n)
    noise = np.random.default_rng(seed).standard_normal(n)
    w = 2.0 * math.pi * np.fft.rfftfreq(n, dt)
    wg, wf = 2.0 * math.pi * fg, 0.2 * math.pi * fg
    kt = (wg ** 4 + 4 * zg ** 2 * wg ** 2 * w ** 2) / \
        ((wg ** 2 - w ** 2) ** 2 + 4 * zg ** 2 * wg ** 2 * w ** 2)
    cp = w ** 4 / ((wf ** 2 - w ** 2) ** 2 + 4 * zg ** 2 * wf ** 2 * w ** 2)
    a = np.fft.irfft(np.fft.rfft(noise) * np.sqrt(kt * cp), n)
    t1, t2 = rise, rise + strong
    T = t[-1]
    env = np.where(t < t1, (t / t1) ** 2, np.where(
        t < t2, 1.0, np.exp(-math.log(20.0) / decay * (t - t2)) * (T - t) / (T - t2)))
    a *= env
    # a - (c0 phi0 + c1 phi1) with V(T) = D(T) = 0: both are linear in (c0, c1)
    phi0, phi1 = 1.0 - t / T, (t / T) * (1.0 - t / T)
    v, d = integrate(t, a)
    v0, d0 = integrate(t, phi0)
    v1, d1 = integrate(t, phi1)
    c0, c1 = np.linalg.solve([[v0[-1], v1[-1]], [d0[-1], d1[-1]]], [v[-1], d[-1]])
    a -= c0 * phi0 + c1 * phi1
    a *= pga / np.abs(a).max()
    a[-1] = 0.0
    m = int(round(tail / dt))
    return np.concatenate((t, t[-1] + dt * np.arange(1, m + 1))), \
        np.concatenate((a, np.zeros(m)))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seed", type=int, default=17)
    p.add_argument("--dt", type=float, default=0.01, help="time step of the record (s)")
    p.add_argument("--rise", type=float, default=0.5, help="rise of the envelope (s)")
    p.add_argument("--strong", type=float, default=1.5, help="strong motion (s)")
    p.add_argument("--decay", type=float, default=1.0, help="decay to 5 %% (s)")
    p.add_argument("--fg", type=float, default=5.0, help="Kanai-Tajimi frequency (Hz)")
    p.add_argument("--zg", type=float, default=0.6, help="Kanai-Tajimi damping ratio")
    p.add_argument("--pga", type=float, default=8.0, help="peak acceleration (m/s^2)")
    p.add_argument("--tail", type=float, default=1.0, help="quiet tail (s)")
    p.add_argument("-o", "--output", type=Path,
                   default=Path(__file__).with_name("ground_motion_record.csv"))
    args = p.parse_args()
    t, a = record(args.seed, args.dt, args.rise, args.strong, args.decay, args.fg, args.zg,
                  args.pga, args.tail)
    v, d = integrate(t, a)
    head = [
        "# synthetic record of cases/make_ground_motion_record.py (see its docstring):",
        f"# seed {args.seed}, dt {args.dt:g} s, envelope {args.rise:g} + {args.strong:g} + "
        f"{args.decay:g} s, Kanai-Tajimi {args.fg:g} Hz / {args.zg:g}, PGA {args.pga:g} m/s^2, "
        f"tail {args.tail:g} s",
        f"# base at the end: velocity {v[-1]:.2e} m/s, displacement {d[-1]:.2e} m; largest "
        f"displacement {np.abs(d).max():.4f} m",
        "time_s,acceleration_m_s2",
    ]
    rows = [f"{x:.4f},{y:.6g}" for x, y in zip(t, a)]
    args.output.write_text("\n".join(head + rows) + "\n")
    print(f"wrote {args.output}: {len(t)} rows, {t[-1]:g} s")


if __name__ == "__main__":
    main()
