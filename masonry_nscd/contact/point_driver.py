"""Drive one joint contact point of unit area along a displacement path (a "joint mtest").

The point is driven by its total relative displacement (the loading device is rigid, so the
compliance ``A`` of the local problem is zero) and solved with the same local solver and the
same integrity update as the NSCD step: the integrity is consistent with the cohesive
displacement at the end of the step (``contact.laws.solve``), so the traction
follows the envelope whatever the step size.

Paths (``to`` is the final value, m):

* ``opening``: ``u_n`` from 0 to ``to``, no slip;
* ``sliding``: ``u_t`` from 0 to ``to`` with the normal traction held at ``normal_stress`` (Pa,
  negative in compression): ``u_n`` per step from the law's ``normal_displacement`` (for the
  FCZM, in compression the normal response is the spring alone, ``u_n = T_n c_n``; in tension
  the open joint carries ``T_n`` with the integrity of the start of the step);
* ``mixed``: ``u_n = u_t`` from 0 to ``to`` each (45 degrees).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from masonry_nscd.contact import laws

PATHS = ("opening", "sliding", "mixed")


@dataclass(frozen=True)
class JointCurve:
    """The response of one joint point: arrays of length steps + 1 (SI units)."""

    u_n: np.ndarray  # m, total normal relative displacement (opening positive)
    u_t: np.ndarray  # m, total tangential relative displacement
    T_n: np.ndarray  # Pa, normal traction (tension positive)
    T_t: np.ndarray  # Pa, tangential traction
    d_coh: np.ndarray  # total cohesive damage 1 - beta (1 - d_coh,0)
    status: np.ndarray  # ST_* code of the local solver

    def work(self) -> float:
        """Work done on the point per unit area, J/m^2 (trapezoidal rule)."""
        dn = np.diff(self.u_n)
        dt = np.diff(self.u_t)
        tn = 0.5 * (self.T_n[1:] + self.T_n[:-1])
        tt = 0.5 * (self.T_t[1:] + self.T_t[:-1])
        return float(np.sum(tn * dn + tt * dt))

    def write_csv(self, path: str | Path) -> None:
        """Write ``step,u_n_m,u_t_m,T_n_Pa,T_t_Pa,d_coh``."""
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["step", "u_n_m", "u_t_m", "T_n_Pa", "T_t_Pa", "d_coh"])
            for i in range(len(self.u_n)):
                w.writerow(
                    [i, f"{self.u_n[i]:.9e}", f"{self.u_t[i]:.9e}", f"{self.T_n[i]:.9e}",
                     f"{self.T_t[i]:.9e}", f"{self.d_coh[i]:.9e}"]
                )


def drive_joint_point(
    P: np.ndarray, path: str, to: float, steps: int = 2000, normal_stress: float = 0.0,
    unload_to: float | None = None,
) -> JointCurve:
    """Drive one point of unit area with the law of parameter row ``P`` (``contact.laws``).

    ``unload_to``: after reaching ``to``, go back linearly to this value in as many steps
    (used for unload/reload checks); the curve then has ``2 steps + 1`` entries.
    """
    if path not in PATHS:
        raise ValueError(f"path must be one of {PATHS}, got {path!r}")
    if steps < 1:
        raise ValueError("steps must be >= 1")
    s = np.linspace(0.0, to, steps + 1)
    if unload_to is not None:
        s = np.concatenate([s, np.linspace(to, unload_to, steps + 1)[1:]])
    n = len(s)
    out = {k: np.zeros(n) for k in ("u_n", "u_t", "T_n", "T_t", "d_coh")}
    status = np.zeros(n, dtype=np.int64)
    A = np.zeros((3, 3))
    ut = np.zeros(3)
    T = np.zeros(3)
    uc = np.zeros(3)
    uc_old = np.zeros(3)
    beta = 1.0
    b = 1.0 - laws.initial_damage(P)
    for i in range(n):
        if path == "opening":
            ut[:] = (s[i], 0.0, 0.0)
        elif path == "mixed":
            ut[:] = (s[i], s[i], 0.0)
        else:
            ut[0] = laws.normal_displacement(normal_stress, beta, P)
            ut[1] = s[i]
            ut[2] = 0.0
        st, beta = laws.solve(ut, A, uc_old, beta, P, laws.KIND_JOINT, T, uc)
        uc_old[:] = uc
        out["u_n"][i] = ut[0]
        out["u_t"][i] = ut[1]
        out["T_n"][i] = T[0]
        out["T_t"][i] = T[1]
        out["d_coh"][i] = 1.0 - beta * b
        status[i] = st
    return JointCurve(status=status, **out)


def drive_joint_history(P: np.ndarray, u_path: np.ndarray) -> JointCurve:
    """Drive one point along an arbitrary history of total relative displacements (n, 3), m.

    Used to check that the NSCD step, given the relative displacements it produced, gives the
    tractions of the stand-alone law.
    """
    A = np.zeros((3, 3))
    T = np.zeros(3)
    uc = np.zeros(3)
    uc_old = np.zeros(3)
    beta = 1.0
    b = 1.0 - laws.initial_damage(P)
    n = len(u_path)
    out = {k: np.zeros(n) for k in ("u_n", "u_t", "T_n", "T_t", "d_coh")}
    status = np.zeros(n, dtype=np.int64)
    Ts = np.zeros((n, 3))
    for i in range(n):
        ut = np.ascontiguousarray(u_path[i], dtype=float)
        status[i], beta = laws.solve(ut, A, uc_old, beta, P, laws.KIND_JOINT, T, uc)
        uc_old[:] = uc
        Ts[i] = T
        out["u_n"][i], out["u_t"][i] = ut[0], ut[1]
        out["T_n"][i], out["T_t"][i] = T[0], T[1]
        out["d_coh"][i] = 1.0 - beta * b
    return JointCurve(status=status, **out)
