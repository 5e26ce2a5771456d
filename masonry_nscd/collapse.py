r"""Collapse of a limit-state run: when a structure has become a mechanism, and at what load.

A limit-state scene (an arch, :mod:`masonry_nscd.scenes.arch`) carries a collapse rule
(:class:`~masonry_nscd.scenes.scene.CollapseRule`);
the run loop (:mod:`masonry_nscd.run`) gives every step to a :class:`CollapseMonitor`, which
reads the displacement and the velocity of every point of every block of the structure (the
nodes of its mesh: a rigid block's corners move by ``u_0 + theta x (x - x_ref)``) and decides:

* **collapse** when the largest displacement of a block point passes ``displacement_m`` (m), or,
  if the rule has one, its largest speed passes ``velocity_m_s`` (m/s): the structure has turned
  into a mechanism. The run goes on for ``after_s`` (s, so that the mechanism shows) and stops;
  its status is ``collapse``, not a failure: the command exits with 0.
* **with supports that move** (``loading.settlement``: an arch's springing, a cross vault's
  corner or side, an assembly's foundations), the displacements and speeds watched, reported
  and written are relative to the **rigid motion of the supports**: the small rigid motion
  ``t + theta x (x - c)`` (``c`` the centre of the supports' nodes) that best fits the
  displacements of the nodes of all the supports, fixed and moving, in the least-squares
  sense, each support weighing the same (:class:`SupportCarriage`). What a rigid carriage of
  the whole set of supports would do to the structure (a common translation, a settlement of
  one of two springings: a rotation about the other) is taken out; what the supports impose
  beyond a rigid motion (a spreading, a corner that sinks alone) is not, nor is the
  structure's response to it, which is physics: a spreading of ``d`` leaves ``d / 2`` at the
  blocks on the supports, and the arch's or the vault's three-hinge mechanism drops its crown
  by about as much (measured: an arch of t/R = 0.25 spread by 3 cm, 1.7 cm; sunk by 3 cm at
  one springing, 1.0 cm; the cross vault of ``cases/cross_vault.yaml`` spread by 3 cm on its
  east side, 1.8 cm, sunk by 3 cm at a corner, 1.6 cm). So ``displacement_m`` must exceed the
  structure's own deformation under the imposed motion, no longer the motion itself. Without
  a moving support the displacements are the absolute ones (the fit would be zero).
* the **onset** of the mechanism: the last step before the collapse at which every block point
  was slower than ``onset_velocity_m_s`` (m/s), the structure at rest, or, where the rule gives
  ``onset_kinetic_energy_J``, at which the blocks' kinetic energy ``v^T M v / 2`` (J, the
  lumped mass) was below it: a dry assembly's loosest stones may rattle faster than any speed
  that marks a mechanism while the whole stands, its kinetic energy small. The loads at collapse
  (the body-force multiplier ``lambda``, the force on a block, a settlement: the scene's
  :class:`~masonry_nscd.scenes.scene.LoadFactor` s) are read there: with a load that grows
  while the mechanism gains
  speed, the load when the displacement bound is passed is later, and higher, than the load
  that started it. Both are reported.
* **standing**: the run reached its end time (``collapse.end_time_s``) without collapse.

A solver failure is no collapse: the run stops with exit code 1 and the status ``failed``.

Outputs in the run folder (written by :mod:`masonry_nscd.io.limit_files`): ``limit.csv``, one
row per step (``step, time_s``, each load factor, ``max_displacement_m``, ``max_speed_m_s``:
relative to the supports' rigid motion when one moves, ``kinetic_energy_J``: absolute), and
``limit.json``, the status and the collapse (:meth:`CollapseMonitor.record`), which the
summary reads (:mod:`masonry_nscd.post.limit`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.io.limit_files import LimitTable, write_limit
from masonry_nscd.loading import at_rest
from masonry_nscd.model import RigidBody
from masonry_nscd.scenes.scene import CollapseRule

#: Blocks listed as those that moved most at collapse.
MOVED_MOST = 5


def moving_supports(bodies) -> bool:
    """Whether a support of ``bodies`` moves (a velocity imposed other than rest)."""
    return any(getattr(b, "support", False) and any(v is not at_rest for v in
                                                     b.imposed_velocity.values())
               for b in bodies)


@dataclass(frozen=True)
class SupportCarriage:
    """The rigid motion that best fits the displacements of the supports' nodes (module
    docstring): ``q = K u[dofs]`` (6,), the translation of the centre ``c`` of the supports'
    nodes and a small rotation, each support weighing the same whatever its number of nodes
    (the least squares of its nodes' misfits over their count)."""

    dofs: np.ndarray  # the supports' dofs
    K: np.ndarray  # (6, len(dofs))
    centre: np.ndarray  # m

    @classmethod
    def of(cls, bodies, body_dof0, ndof: int) -> SupportCarriage:
        supports = [i for i, b in enumerate(bodies) if getattr(b, "support", False)]
        G, owner, X = point_map(bodies, supports, body_dof0, ndof)
        dofs = np.concatenate([np.arange(body_dof0[i], body_dof0[i + 1]) for i in supports])
        G = G[:, dofs].toarray()  # (3n, len(dofs)): the nodes' displacements
        weight = 1.0 / np.bincount(owner)[owner]  # 1 / (the nodes of its support)
        centre = weight @ X / weight.sum()
        r = X - centre
        n = len(X)
        M = np.zeros((3 * n, 6))  # the displacement t + theta x r of each node
        for d in range(3):
            M[d::3, d] = 1.0
        for d, e, f, sgn in ((0, 1, 2, 1), (0, 2, 1, -1), (1, 2, 0, 1), (1, 0, 2, -1),
                             (2, 0, 1, 1), (2, 1, 0, -1)):
            M[d::3, 3 + e] = sgn * r[:, f]
        w = np.sqrt(np.repeat(weight, 3))[:, None]
        K = np.linalg.lstsq(w * M, w * G, rcond=None)[0]
        return cls(dofs, K, centre)

    def displacement(self, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The displacement (p, 3; m) that the fitted rigid motion of the supports' dofs
        ``u`` (the global vector) gives the points ``x`` (p, 3; m)."""
        q = self.K @ u[self.dofs]
        return q[:3] + np.cross(q[3:], x - self.centre)


def point_map(bodies, structure, body_dof0, ndof):
    """The sparse map ``B`` (3p, ndof) from the dofs to the displacements of the nodes of the
    structure's bodies (p points), the body of each point, and the points (p, 3; m)."""
    from scipy.sparse import csr_matrix

    rows, cols, vals, owner = [], [], [], []
    p = 0
    for k, i in enumerate(structure):
        b = bodies[i]
        d0 = int(body_dof0[i])
        if isinstance(b, RigidBody):
            for x in np.asarray(b.X, dtype=float):
                r = x - b.reference
                for d in range(3):
                    rows.append(3 * p + d)
                    cols.append(d0 + d)
                    vals.append(1.0)
                # theta x r: row d gets sum_e eps_{d e f} theta_e r_f
                for d, e, f, s in ((0, 1, 2, 1), (0, 2, 1, -1), (1, 2, 0, 1), (1, 0, 2, -1),
                                   (2, 0, 1, 1), (2, 1, 0, -1)):
                    rows.append(3 * p + d)
                    cols.append(d0 + 3 + e)
                    vals.append(s * r[f])
                owner.append(k)
                p += 1
        else:
            for node in range(len(b.X)):
                for d in range(3):
                    rows.append(3 * p + d)
                    cols.append(d0 + 3 * node + d)
                    vals.append(1.0)
                owner.append(k)
                p += 1
    x = np.concatenate([np.asarray(bodies[i].X, dtype=float).reshape(-1, 3) for i in structure]) \
        if structure else np.zeros((0, 3))
    return (csr_matrix((vals, (rows, cols)), shape=(3 * p, ndof)), np.asarray(owner, dtype=int),
            x)


class CollapseMonitor:
    """Watches a run step by step for the collapse of the structure (module docstring)."""

    def __init__(self, scene, integ, outdir: Path | str | None, log: Callable[..., None], *,
                 resume_step: int | None = None):
        self.rule: CollapseRule = scene.collapse
        self.log = log
        self.outdir = None if outdir is None else Path(outdir)
        s = integ.sys
        self.names = [scene.bodies[i].name or f"body {i}" for i in scene.structure]
        self.B, self.owner, x = point_map(scene.bodies, scene.structure, s.body_dof0, s.ndof)
        # with a moving support, the block points' motion relative to the supports' rigid one
        self.points = x
        self.carriage = SupportCarriage.of(scene.bodies, s.body_dof0, s.ndof) \
            if moving_supports(scene.bodies) else None
        self.starts = np.flatnonzero(np.r_[True, self.owner[1:] != self.owner[:-1]])
        # the removed blocks' points and dofs, left out once they are out (scenes/removal.py):
        # per number of groups out, the points out and the dofs kept
        self.scene = scene
        self.removed_points = [np.zeros(len(self.owner), dtype=bool)]
        self.kept_dofs = [np.ones(s.ndof, dtype=bool)]
        if scene.removal is not None:
            gone: list[int] = []
            for group in scene.removal.groups:
                gone += group.bodies
                out_now = set(gone)
                out = [k for k, i in enumerate(scene.structure) if i in out_now]
                self.removed_points.append(np.isin(self.owner, out))
                kept = np.ones(s.ndof, dtype=bool)
                kept[scene.removal.dofs(scene.bodies, gone)] = False
                self.kept_dofs.append(kept)
        self.onset: dict[str, Any] | None = None
        self.detected: dict[str, Any] | None = None
        self.stop_at = math.inf
        self.last: dict[str, Any] = {}
        self.columns = ["step", "time_s", *(f.name for f in self.rule.factors),
                        "max_displacement_m", "max_speed_m_s", "kinetic_energy_J"]
        self.table = None
        if self.outdir is None:  # no files (:func:`watch`)
            return
        self.table = LimitTable(self.outdir, self.columns, resume_step=resume_step)
        # a resumed run: the onset and the collapse the kept rows show
        for row in self.table.kept:
            self._judge(int(row["step"]), row["time_s"], row["max_displacement_m"],
                        row["max_speed_m_s"], row["kinetic_energy_J"], None, quiet=True)

    def loads(self, t: float) -> dict[str, float]:
        return {f.name: float(f.value(t)) for f in self.rule.factors}

    def relative(self, u: np.ndarray) -> np.ndarray:
        """The displacements (or, of the velocities ``u``, the velocities) of the block points
        (p, 3): relative to the supports' rigid motion when a support moves (module
        docstring), else as they are."""
        out = (self.B @ u).reshape(-1, 3)
        if self.carriage is not None:
            out -= self.carriage.displacement(u, self.points)
        return out

    def observe(self, integ, step: int, t: float) -> bool:
        """Take the state after ``step`` (ending at ``t``, s); True when the run should stop
        (the collapse was detected, and ``after_s`` has passed since)."""
        disp = np.linalg.norm(self.relative(integ.u), axis=1)
        speed = np.linalg.norm(self.relative(integ.v), axis=1)
        v = integ.v
        out = self.scene.removed_at(t - self.scene.solver.h)  # groups out in the step to t
        if out:
            disp[self.removed_points[out]] = 0.0
            speed[self.removed_points[out]] = 0.0
            v = np.where(self.kept_dofs[out], v, 0.0)
        d_max, v_max = float(disp.max(initial=0.0)), float(speed.max(initial=0.0))
        kinetic = 0.5 * float(v @ (integ.sys.mass * v))  # lumped (diagonal) mass
        loads = self.loads(t)
        self.last = {"step": step, "time_s": t, "loads": loads, "max_displacement_m": d_max,
                     "max_speed_m_s": v_max}
        if self.table is not None:
            self.table.write_row([step, t, *loads.values(), d_max, v_max, kinetic])
        self._judge(step, t, d_max, v_max, kinetic, disp)
        return self.detected is not None and t >= self.stop_at - 1e-9

    def _judge(self, step: int, t: float, d_max: float, v_max: float, kinetic: float,
               disp: np.ndarray | None, quiet: bool = False) -> None:
        r = self.rule
        if self.detected is not None:
            return
        at_rest = v_max < r.onset_velocity_m_s if r.onset_kinetic_energy_J is None else \
            kinetic < r.onset_kinetic_energy_J
        if at_rest:
            self.onset = {"step": step, "time_s": t, "loads": self.loads(t)}
        by = "displacement" if d_max > r.displacement_m else \
            "velocity" if r.velocity_m_s is not None and v_max > r.velocity_m_s else None
        if by is None:
            return
        moved = []
        if disp is not None:
            per_body = np.maximum.reduceat(disp, self.starts)
            order = np.argsort(-per_body)[:MOVED_MOST]
            moved = [{"body": self.names[self.owner[self.starts[k]]],
                      "displacement_m": float(per_body[k])} for k in order]
        self.detected = {"by": by, "step": step, "time_s": t, "loads": self.loads(t),
                         "max_displacement_m": d_max, "max_speed_m_s": v_max,
                         "moved_most": moved}
        self.stop_at = t + r.after_s
        if quiet:
            return
        onset = self.onset
        loads = onset["loads"] if onset else self.detected["loads"]
        text = ", ".join(f"{k} {v:.5g}" for k, v in loads.items())
        self.log(f"collapse at step {step} (t = {t:.4f} s): largest displacement "
                 f"{d_max:.4g} m, speed {v_max:.4g} m/s ({by} bound passed); onset of the "
                 f"mechanism at t = {onset['time_s']:.4f} s" if onset else
                 f"collapse at step {step} (t = {t:.4f} s): the structure never was at rest")
        if text:
            self.log(f"collapse: loads at the onset: {text}")
        if moved:
            self.log("collapse: moved most: " + ", ".join(
                f"{m['body']} {1e3 * m['displacement_m']:.3g} mm" for m in moved))

    def record(self, status: str, message: str = "") -> dict[str, Any]:
        """The status of the run and its collapse, as written to ``limit.json``."""
        collapse = None
        if self.detected is not None:
            onset = self.onset
            collapse = {
                "detected_by": self.detected["by"],
                "onset_step": onset["step"] if onset else None,
                "onset_time_s": onset["time_s"] if onset else None,
                "loads_at_onset": onset["loads"] if onset else None,
                "detected_step": self.detected["step"],
                "detected_time_s": self.detected["time_s"],
                "loads_at_detection": self.detected["loads"],
                "max_displacement_at_detection_m": self.detected["max_displacement_m"],
                "max_speed_at_detection_m_s": self.detected["max_speed_m_s"],
                "moved_most": self.detected["moved_most"]}
        out = {"status": status, "message": message, "rule": self.rule.info(),
               "collapse": collapse, "last": self.last}
        if self.carriage is not None:
            out["displacements"] = "relative to the supports' rigid motion"
        return out

    def finish(self, status: str, message: str = "") -> None:
        """Write ``limit.json`` with the run's ``status`` (``collapse`` when it was detected,
        whatever is passed, unless the run failed or was interrupted before)."""
        if status == "done":
            status = "collapse" if self.detected is not None else "standing"
        write_limit(self.outdir, self.record(status, message))

    def close(self) -> None:
        if self.table is not None:
            self.table.close()


def watch(scene, end_s: float, log: Callable[..., None] = lambda *_a, **_k: None
          ) -> dict[str, Any]:
    """Step a limit-state ``scene`` from rest until it collapses (and ``after_s`` has passed)
    or until ``end_s`` (s), without writing anything; returns :meth:`CollapseMonitor.record`
    with the rigid bodies' dofs at the end (``"u"``, by scene body index). For tests and
    studies that need no run folder."""
    integ = scene.integrator()
    mon = CollapseMonitor(scene, integ, None, log)
    h = scene.solver.h
    while integ.t < end_s - 1e-6 * h:
        integ = scene.next_integrator(integ)  # a hold or the removal begins
        rep = integ.step()
        if mon.observe(integ, rep.step, rep.time):
            break
    out = mon.record("collapse" if mon.detected is not None else "standing")
    d0 = integ.sys.body_dof0
    out["u"] = {i: integ.u[d0[i]:d0[i + 1]].copy() for i in range(len(scene.bodies))}
    return out
