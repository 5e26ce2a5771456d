r"""The energy balance of a run: every term from the step's own quantities.

The Moreau-Jean theta step (``nscd/integrator.py``) solves, for every free dof,

    M (v1 - v0) = h F_th - h F_int,th + H r,        u1 = u0 + h v_th                      (1)

with ``F_th = theta F1 + (1 - theta) F0`` the external loads (N), ``F_int,th = theta F_int(u1) +
(1 - theta) F_int(u0)`` (``K u_th`` for linear elastic blocks: the step's ``M_hat = M +
(theta h)^2 K`` is exactly this; for ENDO3D blocks the material correction of the Newton
residual makes it so), ``v_th = theta v1 + (1 - theta) v0``, and ``H r`` the contact impulses
(N s; ``r = -h S T`` per point, ``T`` the traction at the end of the step, Pa, ``S`` the
point's area). On an imposed dof (1) holds with a reaction impulse ``R`` added, which this
module computes from (1) itself: ``R = M (v1 - v0) - h F_th - H r`` on those rows.

Multiplying (1) by ``v_th`` (every dof, so the imposed ones too) and writing
``v_th = v_m + (theta - 1/2) dv``, ``v_m = (v0 + v1) / 2``, ``dv = v1 - v0``,
``du = u1 - u0``, gives per step the identity (J)

    du . F_th  +  v_th . R                                           external work
      = d(1/2 v.M v)                                                 kinetic energy
      + du . (F_int(u0) + F_int(u1)) / 2                             work of the blocks
      + sum_a S_a T_a . du_m,a                                       work of the joints
      + (theta - 1/2) [ dv . (M dv - H r) + du . (F_int(u1) - F_int(u0)) ]   numerical  (2)

with ``du_m,a = h (U0 + U1)_a / 2`` the point's relative displacement over the step at its
mean relative velocity (``U = H^T v``): the contact impulses' work on the mean relative
velocity, ``-r . U_m``, as Kelvin's theorem counts an impact (for a perfectly inelastic impact
at a point whose relative velocity jumps from ``U-`` to 0, ``-r . U- / 2 = dv . M dv / 2``: what
the bodies lost). The last line is the theta scheme's own dissipation: zero for theta = 1/2,
``(theta - 1/2) (|dv_smooth|_M^2 + |du|_K^2) >= 0`` for linear elastic blocks, where
``M dv_smooth = M dv - H r`` is the part of the velocity change not due to the contact impulses
(``h (F_th - F_int,th) + R``, O(h) per step for smooth loads): an impact's velocity jump is
physics (the joint's dissipation), not the scheme's.

The terms, each from its own quantities:

* external work: the loads (gravity, the vertical stress) ``du . F_th``; the imposed motions
  ``v_th . R`` on the imposed dofs (a driven beam, a moving base, held dofs, whose ``v = 0``);
* kinetic energy ``1/2 v . M v`` (lumped mass of the blocks, full 6x6 matrix of rigid bodies);
* blocks: linear elastic ``1/2 u . K u`` (stored; the accumulated work of (2) equals it when
  the step is solved); ENDO3D stored ``1/2 sum_g w_g sigma_g : C0^-1 : sigma_g`` over the Gauss
  points (the energy an elastic unloading at the undamaged stiffness would give back: a lower
  bound of the recoverable energy) and dissipated = their accumulated work minus that stored
  energy, so the balance does not check the ENDO3D blocks' own split;
* joints (the law of each point, at the end of each step, ``T`` and the cohesive displacement
  ``u_c`` of the law, integrity ``beta``, spring compliance ``c``, normal by the sign of
  ``T_n``):

  - stored: springs ``1/2 T . c T``, cohesion ``1/2 beta b (K_I u_c,n^2 + K_II |u_c,t|^2)``;
  - cohesion dissipated: ``1/2 (beta0 - beta1) b (K_I u_c0,n^2 + K_II |u_c0,t|^2)`` (the
    secant energy released by the damage of the step);
  - friction dissipated: ``(T_t - beta1 b K_II u_c1,t) . (u_c1,t - u_c0,t)``, the friction
    traction on the law's own slip increment;
  - numerical: the implicit (end-of-step) traction on the spring and the cohesion,
    ``T1 . (c T1 - c T0) - d(1/2 T . c T)`` and ``1/2 beta1 b |K^1/2 (u_c1 - u_c0)|^2``, both
    >= 0 (convex potentials), and the glue's work (its compliance of 1e-9, no physics);
  - what the joint's work ``S T . du_m`` leaves after those is the impulses' work on the
    change of relative velocity within the step, ``-(theta - 1/2) h S T . (U1 - U0)`` (plus
    the solver's tolerance). At a rigid contact (``coulomb``, no spring) the tractions are
    impulsive and this is the inelastic impact, normal and, for a sticking point,
    tangential: **impacts**. At a joint with a spring in series the traction is a function
    of the displacement, its change over a step is smooth, and this term belongs with the
    scheme's: **numerical** (with the bodies' term it makes ``(theta - 1/2) |dv|_M^2`` of the
    smooth motion whole).

Summed over the steps, (2) gives ``W_ext = KE + E_stored + D_joints + D_blocks + D_num`` up to
the solvers' tolerance: the imbalance is a check of the state (``u, v, T`` consistent with
each other and with the loads), of the reactions, and of the numerical term. The relative
imbalance is ``|W_ext - sum of the terms| / max(|W_ext|, largest term)``. Kinetic damping
(``Integrator.kinetic_damping``) sets the velocities to zero between two steps, outside (1): the
kinetic energy it takes is added to the bodies' numerical term, a dissipation of the method.

Cost: per step a handful of dot products over the dofs and vectorised arithmetic over the
contact points (no kernel call: the internal forces at ``u1`` are those the next step needs,
computed once); the stored energies only at output steps.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.contact.laws import KIND_GLUED, KIND_JOINT
from masonry_nscd.contact.laws.fczm import P_B, P_CN_C, P_CN_T, P_CT, P_KI, P_KII
from masonry_nscd.model import Block, RigidBody

#: The accumulated terms kept in the integrator's state (J), in this order.
ACCUMULATED = ("work_loads", "work_imposed", "work_blocks_elastic", "work_blocks_endo3d",
               "work_joints", "friction", "cohesion", "impact", "numerical_bodies",
               "numerical_blocks", "numerical_joints")
_I = {k: i for i, k in enumerate(ACCUMULATED)}

#: The columns of ``energy.csv`` (J; the relative imbalance dimensionless).
ENERGY_COLUMNS = [
    "step", "time_s", "external_work_J", "work_of_loads_J", "work_of_imposed_motions_J",
    "kinetic_J", "elastic_blocks_J", "elastic_joints_J", "dissipated_friction_J",
    "dissipated_cohesion_J", "dissipated_impacts_J", "dissipated_blocks_J", "numerical_J",
    "imbalance_J", "relative_imbalance",
]


def energy_row(step: int, time: float, balance: dict[str, float]) -> list:
    """A row of ``energy.csv`` from :meth:`EnergyAccount.balance`."""
    return [step, time] + [balance[c.removesuffix("_J")]
                           for c in ENERGY_COLUMNS[2:]]


class EnergyAccount:
    """Per-step increments and stored energies of one integrator's scene (module docstring)."""

    def __init__(self, integ):
        s = integ.sys
        self.h, self.theta = s.h, s.theta
        # off-diagonal mass of rigid bodies whose reference point is not the centre of mass
        self._mass_extra = []
        self._endo_dofs = np.zeros(s.ndof, dtype=bool)
        self._elastic_dofs = np.zeros(s.ndof, dtype=bool)
        for i, b in enumerate(integ.bodies):
            sl = slice(int(s.body_dof0[i]), int(s.body_dof0[i + 1]))
            if isinstance(b, RigidBody):
                M = b.mass_matrix()
                off = M - np.diag(np.diag(M))
                if np.any(off):
                    self._mass_extra.append((sl, off))
            elif isinstance(b, Block):
                self._elastic_dofs[sl] = True
        mat = integ.material
        # the ENDO3D points' undamaged compliance C0^-1 (1/Pa, (points, 6, 6)), inverted once
        self._compliance = None if mat is None else np.linalg.inv(mat.C0)
        if mat is not None:
            self._endo_dofs[mat.all_dofs] = True
            self._elastic_dofs[mat.all_dofs] = False
        self.mass = s.mass
        # the contact impulses on the imposed dofs: entries (point, side, slot) of H there
        imp = np.asarray(s.imposed_dofs, dtype=np.int64)
        self.imposed = imp
        pos = np.full(s.ndof, -1, dtype=np.int64)
        pos[imp] = np.arange(len(imp))
        sd = s.side_dofs
        hit = (sd >= 0) & (pos[np.where(sd >= 0, sd, 0)] >= 0)
        self._hit = np.nonzero(hit)
        self._hit_pos = pos[sd[self._hit]]
        self._hit_coef = s.side_coef[self._hit]  # (k, 3)
        # per point: law columns
        P = integ.params[s.law]
        self.area = s.area
        joint = s.kind == KIND_JOINT
        self.joint = joint
        self.glue = s.kind == KIND_GLUED
        self.cn_t, self.cn_c, self.ct = P[:, P_CN_T], P[:, P_CN_C], P[:, P_CT]
        self.kI, self.kII = P[:, P_KI], P[:, P_KII]
        self.b = np.where(joint, P[:, P_B], 0.0)
        # rigid contacts (no spring in series, law coulomb) and joints with a spring
        self.rigid = joint & (self.cn_t == 0.0) & (self.cn_c == 0.0) & (self.ct == 0.0)
        self.sprung = joint & ~self.rigid

    # --- pieces ---------------------------------------------------------------------------
    def mass_times(self, v: np.ndarray) -> np.ndarray:
        out = self.mass * v
        for sl, off in self._mass_extra:
            out[sl] += off @ v[sl]
        return out

    def _spring(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Spring displacements ``c T`` (npt, 3, m) and energies ``1/2 T . c T`` (Pa m)."""
        us = np.empty_like(T)
        us[:, 0] = np.where(T[:, 0] >= 0.0, self.cn_t, self.cn_c) * T[:, 0]
        us[:, 1] = self.ct * T[:, 1]
        us[:, 2] = self.ct * T[:, 2]
        us[~self.joint] = 0.0
        return us, 0.5 * np.einsum("ai,ai->a", T, us)

    def _cohesion(self, uc: np.ndarray, beta: np.ndarray) -> np.ndarray:
        """``1/2 b (K_I u_c,n^2 + K_II |u_c,t|^2)`` per point (Pa m), without beta."""
        return 0.5 * self.b * (self.kI * uc[:, 0] ** 2
                               + self.kII * (uc[:, 1] ** 2 + uc[:, 2] ** 2))

    # --- one step -------------------------------------------------------------------------
    def step(self, acc: np.ndarray, *, u0, v0, u1, v1, F0, F1, fint0, fint1, j0, j1) -> None:
        """Add the increments of one step (module docstring, (2)) to ``acc`` (J)."""
        h, th = self.h, self.theta
        du, dv = u1 - u0, v1 - v0
        Fth = th * F1 + (1.0 - th) * F0
        Mdv = self.mass_times(dv)
        S = self.area
        T1 = j1.T
        dU = j1.U - j0.U
        dum = (j1.u - j0.u) - (th - 0.5) * h * dU
        # contact impulses r = -h S T; their generalised force on the imposed dofs
        r = -h * S[:, None] * T1
        dv_Hr = float(np.einsum("ai,ai->", r, dU))
        imp = self.imposed
        if len(imp):
            a = self._hit[0]
            Hr = np.bincount(self._hit_pos, weights=np.einsum("ki,ki->k", self._hit_coef, r[a]),
                             minlength=len(imp))
            R = Mdv[imp] - h * Fth[imp] - Hr
            acc[_I["work_imposed"]] += float(du[imp] @ R) / h
        acc[_I["work_loads"]] += float(du @ Fth)
        fsum = fint0 + fint1
        el, en = self._elastic_dofs, self._endo_dofs
        acc[_I["work_blocks_elastic"]] += 0.5 * float(du[el] @ fsum[el])
        if en.any():
            acc[_I["work_blocks_endo3d"]] += 0.5 * float(du[en] @ fsum[en])
        acc[_I["numerical_bodies"]] += (th - 0.5) * (float(dv @ Mdv) - dv_Hr)
        acc[_I["numerical_blocks"]] += (th - 0.5) * float(du @ (fint1 - fint0))
        # joints
        work = S * np.einsum("ai,ai->a", T1, dum)
        acc[_I["work_joints"]] += float(work.sum())
        us0, psi_s0 = self._spring(j0.T)
        us1, psi_s1 = self._spring(T1)
        c0, c1 = self._cohesion(j0.uc, j0.beta), self._cohesion(j1.uc, j1.beta)
        dpsi = psi_s1 - psi_s0 + j1.beta * c1 - j0.beta * c0
        cohesion = (j0.beta - j1.beta) * c0
        duc = j1.uc - j0.uc
        num = (np.einsum("ai,ai->a", T1, us1 - us0) - (psi_s1 - psi_s0)
               + 0.5 * j1.beta * self.b * (self.kI * duc[:, 0] ** 2
                                           + self.kII * (duc[:, 1] ** 2 + duc[:, 2] ** 2)))
        kb = j1.beta * self.b * self.kII
        friction = ((T1[:, 1] - kb * j1.uc[:, 1]) * duc[:, 1]
                    + (T1[:, 2] - kb * j1.uc[:, 2]) * duc[:, 2])
        jt = self.joint
        acc[_I["cohesion"]] += float(S[jt] @ cohesion[jt])
        acc[_I["friction"]] += float(S[jt] @ friction[jt])
        rest = work - S * (dpsi + cohesion + num + friction)
        acc[_I["impact"]] += float(rest[self.rigid].sum())
        acc[_I["numerical_joints"]] += (float(S[jt] @ num[jt]) + float(rest[self.sprung].sum())
                                        + float(work[self.glue].sum()))

    # --- stored energies and the balance --------------------------------------------------
    def stored(self, integ) -> dict[str, float]:
        """Kinetic and stored elastic energies of the current state (J): ``kinetic``,
        ``elastic_blocks`` (linear elastic and ENDO3D blocks), ``endo3d_stored`` (the ENDO3D
        part of it), ``elastic_joints``."""
        u, v = integ.u, integ.v
        kinetic = 0.5 * float(v @ self.mass_times(v))
        f = integ.current_internal_forces()
        el = self._elastic_dofs
        elastic = 0.5 * float(u[el] @ f[el])
        endo = (endo3d_stored_energy(integ.material, self._compliance)
                if integ.material is not None else 0.0)
        j = integ.joints
        _, psi_s = self._spring(j.T)
        psi = psi_s + j.beta * self._cohesion(j.uc, j.beta)
        joints = float(self.area[self.joint] @ psi[self.joint])
        return {"kinetic": kinetic, "elastic_blocks": elastic + endo, "endo3d_stored": endo,
                "elastic_joints": joints}

    def balance(self, integ) -> dict[str, float]:
        """The terms of the balance at the current state (J), the imbalance and the relative
        imbalance (module docstring); keys as the columns of ``energy.csv`` without the unit."""
        acc = integ.energy
        a = {k: float(acc[i]) for k, i in _I.items()}
        st = self.stored(integ)
        out = {
            "work_of_loads": a["work_loads"], "work_of_imposed_motions": a["work_imposed"],
            "external_work": a["work_loads"] + a["work_imposed"],
            "kinetic": st["kinetic"], "elastic_blocks": st["elastic_blocks"],
            "elastic_joints": st["elastic_joints"], "dissipated_friction": a["friction"],
            "dissipated_cohesion": a["cohesion"], "dissipated_impacts": a["impact"],
            "dissipated_blocks": a["work_blocks_endo3d"] - st["endo3d_stored"],
            "numerical": a["numerical_bodies"] + a["numerical_blocks"] + a["numerical_joints"],
        }
        terms = [out[k] for k in ("kinetic", "elastic_blocks", "elastic_joints",
                                  "dissipated_friction", "dissipated_cohesion",
                                  "dissipated_impacts", "dissipated_blocks", "numerical")]
        out["imbalance"] = out["external_work"] - sum(terms)
        scale = max([abs(out["external_work"])] + [abs(x) for x in terms])
        out["relative_imbalance"] = abs(out["imbalance"]) / scale if scale > 0.0 else 0.0
        return out


def endo3d_stored_energy(material, compliance: np.ndarray | None = None) -> float:
    """``1/2 sum_g w_g sigma_g : C0^-1 : sigma_g`` over the ENDO3D Gauss points (J), the
    committed stresses (Pa) and the undamaged elasticity ``C0`` (engineering shear strains);
    ``compliance``: ``C0^-1`` per point when already inverted (the points' ``C0`` never
    change), else each point's ``C0`` is solved."""
    sig = material.sigma_committed_all
    if compliance is None:
        eps = np.linalg.solve(material.C0, sig[:, :, None])[:, :, 0]
    else:
        eps = np.einsum("pij,pj->pi", compliance, sig)
    return 0.5 * float(material.w.reshape(-1) @ np.einsum("pi,pi->p", sig, eps))
