"""The NSCD time loop of one scene: state, one Moreau-Jean step, reports.

``Integrator.step`` advances from t_n to t_n+1 = t_n + h:

1. external forces at t_n and t_n+1, internal forces at u_n;
2. free velocities of every body (``_free_velocity``), imposed velocities set;
3. local free velocities of the contact points;
4. the contact problem, by semi-smooth Newton on the whole step (``newton.NewtonSolver``, the
   default; in a step that will not be subdivided, started again from the free velocities and
   then finished by Gauss-Seidel sweeps when it does not converge, ``_newton_solve``, elastic
   blocks only for the sweeps) or by non-linear Gauss-Seidel (``kernels.nlgs``), warm-started
   from the previous step;
5. velocities, displacements, local relative displacements, joint and ENDO3D states updated.

ENDO3D blocks enter the Newton residual through their internal forces, and its matrix through
their consistent tangent stiffness, refreshed at the current iterate whenever the iterations
slow down (docs/choices.md: a secant stiffness, C0 scaled per element by the damages, took
twice as long per step on the 0.5 MPa ENDO3D wall and stalled once the heel cracked).

A rigid body whose reference point is not its centre of mass has a full mass matrix: where one
of its dofs is imposed, the change of the imposed velocity over the step acts on its free dofs
through the coupling of the mass matrix, ``dv_f = -M_ff^-1 M_fi dv_i`` (``_coupled``).

A step that did not reach the tolerance, or whose ENDO3D return mapping failed at some Gauss
point (``StepReport.material_failures``), is made again from its start as two steps of h/2
(``max_halvings`` times at most, each half again halved if it fails): at a kink of the joint
law (a joint opening on a rocking wall, a very stiff spring closing) Newton can cycle between
two statuses, and a smaller step moves the state less across the kink (the smoke wall of the
stress test, with no vertical stress or with very stiff springs, is such a case;
docs/choices.md). A step
still unconverged at the smallest size is reported (``StepReport.converged`` False) and the
caller decides; NaN or infinity anywhere in the new state raises ``DivergenceError`` naming the
step and what diverged. After a step of h that had to be subdivided, the next
``halve_after_failure`` steps of h skip the attempt at h and are made as halves at once (each
half still halved again if it fails, without that memory); if the attempt at h after them fails
again, the run of halved steps doubles (up to ``MAX_HALVE_RUN``), and it falls back to
``halve_after_failure`` when an attempt at h converges. Failures come in runs while a mechanism
forms, and each failed attempt at h costs a full Newton budget.

With ``max_growth`` > 0 the step size adapts (``nscd/step_size.py``): steps of ``h 2^k``, ``k`` up
to ``max_growth``, made by integrators of the same scene built at those sizes on first use (the
``_rungs``), grown while the steps stay easy and lowered when one is hard; a step of ``h 2^k``
that does not converge is made again from its start at ``h 2^(k-1)``. This integrator holds the
state of the run throughout: the state a rung's step ends in is put back into it.

With ``kinetic_damping`` (Cundall's kinetic damping, a dynamic relaxation) every free velocity
is set to zero after a step in which the blocks' kinetic energy ``1/2 v . M v`` fell: its peak
has passed, the blocks are about where the potential energy is least along their motion, and
they start again from rest there. A structure that can carry the load comes to rest without
the momentum a dynamic run builds (a rattle, a flow that overshoots); one that cannot keeps
gaining kinetic energy, and no reset stops it. The energy taken away is the scheme's: it is
counted with the numerical dissipation of the balance (``nscd/energy.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from masonry_nscd import timing
from masonry_nscd.contact import laws
from masonry_nscd.loading import Loads, step_velocity
from masonry_nscd.materials.blocks import Endo3dBlocks
from masonry_nscd.model import DOF_IMPOSED, ContactPoint, RigidBody
from masonry_nscd.nscd import kernels
from masonry_nscd.nscd.block_diagonal import without
from masonry_nscd.nscd.checkpoint import integrator_state, restore_integrator
from masonry_nscd.nscd.energy import ACCUMULATED, EnergyAccount
from masonry_nscd.nscd.newton import NewtonSolver
from masonry_nscd.nscd.step_size import StepSizeControl
from masonry_nscd.nscd.system import build_system

NEWTON_MAX_ITERATIONS = 50  # beyond this, the step is finished by Gauss-Seidel sweeps


class DivergenceError(RuntimeError):
    """The state became NaN or infinite: ``what`` (e.g. "body velocities") at ``time`` (s), in
    step ``step`` of the run."""

    def __init__(self, step: int, time: float, what: str, note: str = ""):
        super().__init__(f"step {step} (t = {time:.6g} s): {what} not finite{note}")
        self.step, self.time, self.what = step, time, what


#: the longest run of steps made as halves at once before h is tried again (count)
MAX_HALVE_RUN = 64


@dataclass(frozen=True)
class StepReport:
    step: int
    time: float  # s, end of the step
    sweeps: int
    residual: float
    converged: bool
    ambiguous: int  # contact points whose local problem had no exact status
    # ENDO3D Gauss points whose return mapping did not converge in the accepted state, and the
    # centre (m) of the element of the first of them
    material_failures: int = 0
    material_failure_at: tuple[float, float, float] | None = None
    # steps of h/2^k it was made of (1: not subdivided; see Integrator.max_halvings)
    substeps: int = 1
    # False: made as halves at once, after an earlier step that did not converge at h
    tried_h: bool = True
    # steps of h it covered (1, or 2^k for a step of the adaptive step size, max_growth)
    span: int = 1
    # the largest loss of integrity of a joint point (beta_n - beta_n+1) or growth of an ENDO3D
    # damage (d_t, d_c) of a Gauss point in the step (dimensionless)
    damage_growth: float = 0.0


@dataclass
class JointState:
    """Per contact point, at the end of the last step (SI units)."""

    u: np.ndarray  # (npt, 3) m, relative displacement in the local frame (n, t, s)
    U: np.ndarray  # (npt, 3) m/s, relative velocity
    uc: np.ndarray  # (npt, 3) m, cohesive part of u
    beta: np.ndarray  # (npt,) integrity
    T: np.ndarray  # (npt, 3) Pa, traction (tension positive)
    status: np.ndarray  # (npt,) contact.laws.ST_*


class Integrator:
    """Moreau-Jean theta-method with implicit contact impulses for one scene."""

    def __init__(
        self,
        bodies: list,
        points: list[ContactPoint],
        params: np.ndarray,
        loads: Loads,
        *,
        h: float,
        theta: float = 1.0,
        tolerance: float = 1e-6,
        max_iterations: int = 10000,
        check_every: int = 5,
        beta0: float | np.ndarray = 1.0,
        method: str = "nlgs",
        endo3d_params: np.ndarray | None = None,
        endo3d_tau: float = 0.0,
        max_halvings: int = 0,
        halve_after_failure: int = 0,
        energy: bool = True,
        max_growth: int = 0,
        grow_after: int = 2,
        easy_iterations: int = 4,
        easy_damage: float = math.inf,
        step_limit=None,
        linear: str = "lu",
        layout=None,
        kinetic_damping: bool = False,
    ):
        if max_halvings < 0:
            raise ValueError(f"max_halvings must be >= 0, got {max_halvings}")
        self.max_halvings = int(max_halvings)
        # what a half-step integrator (built when a step is first subdivided) is built with
        self._half_args = {"theta": theta, "tolerance": tolerance,
                           "max_iterations": max_iterations, "check_every": check_every,
                           "method": method, "endo3d_params": endo3d_params,
                           "endo3d_tau": endo3d_tau,
                           "max_halvings": max_halvings - 1, "energy": energy,
                           "linear": linear}
        self._half: Integrator | None = None
        # after a step of h that did not converge, the next ``halve_after_failure`` steps are
        # made straight away as two halves: the failed attempt costs a full Newton budget, and
        # failures come in runs (a mechanism forming); ``_halve_next`` counts them down
        if halve_after_failure < 0:
            raise ValueError(f"halve_after_failure must be >= 0, got {halve_after_failure}")
        self.halve_after_failure = int(halve_after_failure)
        self._halve_next = 0
        self._halve_run = self.halve_after_failure  # doubles while the failures go on
        # the adaptive step size: the control, the integrators of steps h 2^k by k, and the
        # level of the one whose state this integrator took last (0: its own step)
        self.control = StepSizeControl(max_growth, grow_after, easy_iterations, easy_damage) \
            if max_growth > 0 else None
        self._rungs: dict[int, Integrator] = {}
        self._made_by = 0
        # ``step_limit(t)``: the latest time (s) a step starting at t may end at (the next
        # change of the supports, the end of the loading); None: no bound
        self.step_limit = step_limit
        # a step that Newton did not converge and that will not be subdivided gets the last
        # resorts: a second start (``_newton_solve``), then Gauss-Seidel sweeps (no ENDO3D
        # blocks); not in a rung, whose failed step is made again smaller
        self.last_resorts = True
        self.bodies = bodies
        self.points = points
        self.params = np.ascontiguousarray(np.atleast_2d(params), dtype=float)
        self.loads = loads
        # ``layout``: the system's parts that do not depend on h, shared with the integrators
        # of the other step sizes (``nscd.system.DofLayout``, or their system; None: made here)
        self.sys = build_system(bodies, points, h, theta, layout)
        self.tolerance = tolerance
        self.max_iterations = max_iterations
        self.check_every = check_every
        s = self.sys
        self.imposed = []  # (global dof, history)
        self._coupled = []  # (free dofs, imposed dofs, -M_ff^-1 M_fi) of rigid bodies
        for i, b in enumerate(bodies):
            if isinstance(b, RigidBody):
                for d, hist in b.imposed_velocity.items():
                    self.imposed.append((int(s.body_dof0[i] + d), hist))
                M = b.mass_matrix()
                imp = b.dof_mode == DOF_IMPOSED
                if imp.any() and (~imp).any() and np.any(M[np.ix_(~imp, imp)]):
                    d0 = int(s.body_dof0[i])
                    C = -np.linalg.solve(M[np.ix_(~imp, ~imp)], M[np.ix_(~imp, imp)])
                    self._coupled.append((d0 + np.flatnonzero(~imp), d0 + np.flatnonzero(imp),
                                          C))
        n, npt = s.ndof, s.npt
        self.t = 0.0
        self.step_index = 0
        self.u = np.zeros(n)
        self.v = np.zeros(n)
        self.fint = np.zeros(n)
        self._fint_u = None  # the displacement array self.fint was computed at (identity)
        self.joints = JointState(
            u=np.zeros((npt, 3)), U=np.zeros((npt, 3)), uc=np.zeros((npt, 3)),
            beta=np.broadcast_to(np.asarray(beta0, dtype=float), (npt,)).copy(),
            T=np.zeros((npt, 3)), status=np.zeros(npt, dtype=np.int64),
        )
        self._F0 = loads.at(0.0, n)
        self._dv = np.zeros(n)
        if method not in ("nlgs", "newton"):
            raise ValueError(f"solver method must be 'nlgs' or 'newton', got {method!r}")
        self.method = method
        self.newton = None
        self.material = Endo3dBlocks(bodies, s.body_dof0, endo3d_params, tau=endo3d_tau, h=h) \
            if endo3d_params is not None else None
        if self.material is not None and not self.material:
            self.material = None
        self.tangent_updates = 0
        if self.material is not None and method != "newton":
            raise ValueError("ENDO3D blocks need the Newton solver (method 'newton'): the "
                             "material enters its residual")
        if method == "newton":
            joints = s.kind == laws.KIND_JOINT
            used = self.params[np.unique(s.law[joints])] if joints.any() else self.params[:0]
            if not all(laws.newton_ready(P) for P in used):
                raise ValueError("the Newton solver needs joints with a spring in series or "
                                 "rigid Signorini-Coulomb contacts: use method 'nlgs'")
            node_xyz = [b.X if s.body_deformable[i] else None for i, b in enumerate(bodies)]
            self.newton = NewtonSolver(s, s.minv_off, s.mhat, tolerance,
                                       min(max_iterations, NEWTON_MAX_ITERATIONS), self.params,
                                       linear=linear, node_xyz=node_xyz)
            self.newton.on_slow = self._on_slow
        self._products_without_blocks()
        # kinetic damping (module docstring): the kinetic energy (J) at the end of the last
        # step, after its reset if it had one (None: no step yet); not in the halves and rungs,
        # whose steps make up one step of this integrator
        self.kinetic_damping = bool(kinetic_damping)
        self._kinetic_last: float | None = None
        self.kinetic_resets = 0
        # the energy balance (nscd/energy.py): its accumulated terms are part of the state
        self.energy = np.zeros(len(ACCUMULATED))
        self.energy_account = EnergyAccount(self) if energy else None

    def _products_without_blocks(self) -> None:
        """The block products that leave the ENDO3D blocks out (``block_diagonal.without``):

        * ``_k_linear``, K of the linear blocks: the ENDO3D blocks' internal forces are the
          material's (``internal_forces`` writes them over whatever K u gave there);
        * ``_minv_free`` and ``_k_free``, those of the free velocity. The ENDO3D blocks' rows of
          the step residual take the form M v + h theta F_int(u) + b (``MaterialCorrection``),
          which needs no free velocity on their dofs, so they skip them and it is v_n there
          (``blocks_apart``). Not when the blocks cannot be left out of M_hat's
          (``NewtonSolver.mhat_without``): the residual then keeps M_hat (v - v_free) + c(v).
        """
        s, mat = self.sys, self.material
        self._k_linear = s.k_op
        self._minv_free, self._k_free = s.minv_op, s.k_op
        self.blocks_apart = False
        if mat is None:
            return
        k_rest = without(s.body_dof0, s.k_off, s.k, mat.index)
        self._k_linear = s.k_op if k_rest is None else k_rest
        if self.newton is not None and self.newton.mhat_without(mat.index) is not None:
            minv_rest = without(s.body_dof0, s.minv_off, s.minv, mat.index)
            if minv_rest is not None:
                self._minv_free, self._k_free = minv_rest, self._k_linear
                self.blocks_apart = True

    # --- one step -----------------------------------------------------------------------
    def internal_forces(self) -> np.ndarray:
        """Internal forces at the current displacements (N). Linear elastic blocks: K u."""
        self._k_linear.matvec(self.u, self.fint)
        if self.material is not None:
            self.material.internal_forces(self.u, self.fint, trial=False)
        self._fint_u = self.u
        return self.fint

    def current_internal_forces(self) -> np.ndarray:
        """The internal forces at the current displacements (N), computed once per state: the
        end of a step computes them for the energy balance, and the next step starts from
        them. A state put in by ``restore_integrator`` (a new ``u`` array) computes them
        again."""
        if self._fint_u is not self.u:
            self.internal_forces()
        return self.fint

    def _update_tangent(self) -> None:
        """Consistent tangent iteration matrix of the ENDO3D blocks at the current iterate.

        The Newton matrix then holds ``M + (theta h)^2 K_t`` for those blocks, with ``K_t`` the
        derivative of their internal forces at the last trial displacements
        (``Endo3dBlocks.tangent_stiffness``); it is kept for the following iterations and
        steps until the iterations slow down again.
        """
        self._set_material_matrix(self.material.tangent_stiffness())
        self.tangent_updates += 1

    def _set_material_matrix(self, stiffnesses: list[np.ndarray]) -> None:
        """Put ``M + (theta h)^2 K`` of each ENDO3D block (``K`` (3n, 3n) N/m, in the order of
        ``material.index``) into the Newton matrix; the other bodies keep their ``M_hat``."""
        s = self.sys
        mhat = s.mhat.copy()
        h, th = s.h, s.theta
        for i, K in zip(self.material.index, stiffnesses):
            m = s.mass[s.body_dof0[i]:s.body_dof0[i + 1]]
            mhat[s.minv_off[i]:s.minv_off[i] + len(m) ** 2] = \
                (np.diag(m) + (th * h) ** 2 * K).ravel()
        self.newton.set_iteration_mhat(mhat)

    def _on_slow(self) -> None:
        if self.material is not None:
            self._update_tangent()

    def step(self) -> StepReport:
        """Advance by one step: of h (made again as halves if it fails, ``_step_h``), or with
        ``max_growth`` of the size the control picks, ending at or before ``step_limit(t)``;
        with ``kinetic_damping``, from rest if the kinetic energy fell in it."""
        rep = self._any_step()
        if self.kinetic_damping:
            self._damp_kinetic()
        return rep

    def _damp_kinetic(self) -> None:
        """Kinetic damping after a step (module docstring): the free velocities set to zero
        when the kinetic energy is below the last step's, the joints' relative velocities with
        them; the energy removed is added to the bodies' numerical dissipation."""
        s = self.sys
        account = self.energy_account

        def kinetic(v: np.ndarray) -> float:  # J; the rigid bodies' full mass where kept
            return 0.5 * float(v @ (account.mass_times(v) if account is not None
                                    else s.mass * v))

        now = kinetic(self.v)
        last, self._kinetic_last = self._kinetic_last, now
        if last is None or now >= last:
            return
        v = np.zeros_like(self.v)
        v[s.imposed_dofs] = self.v[s.imposed_dofs]  # driven and held dofs keep their histories
        self._kinetic_last = kinetic(v)
        self.energy[ACCUMULATED.index("numerical_bodies")] += now - self._kinetic_last
        self.v = v
        U = np.empty((s.npt, 3))
        kernels.local_velocities(s.side_dofs, s.side_coef, v, U)
        self.joints.U = U
        self._made_by = -1  # a rung's own state is no longer the run's
        self.kinetic_resets += 1

    def _any_step(self) -> StepReport:
        """One step of the run, of h or of the adaptive size (:meth:`step`)."""
        if self.control is None:
            return self._step_h()
        h = self.sys.h
        until = math.inf if self.step_limit is None else self.step_limit(self.t)
        n = round(self.t / h)
        k = self.control.level_for(n, math.floor(until / h + 1e-6))
        self._release_idle(k)  # before the step: its set-up can take their room
        sweeps = 0  # the iterations of discarded attempts
        while k > 0:
            rung = self._rung(k)
            if self._made_by != k or rung.t != self.t:
                restore_integrator(rung, integrator_state(self))
                if rung.newton is not None:  # predict from the run's last steps
                    rung.newton.adopt_solutions(self.newton)
                self._made_by = k
            try:
                rep = rung._step()
            except DivergenceError:
                rep = None
            if rep is not None and rep.converged:
                self._take(rung)
                self.control.accepted(k, rep.sweeps, True, rep.damage_growth)
                self._release_idle(k)
                return replace(rep, step=self.step_index, sweeps=rep.sweeps + sweeps,
                               span=1 << k)
            self._made_by = -1  # the rung's state is the failed attempt's
            sweeps += rep.sweeps if rep is not None else 0
            k = self.control.failed(k)
        self._made_by = 0
        rep = self._step_h()
        self.control.accepted(0, rep.sweeps, rep.converged and rep.substeps == 1,
                              rep.damage_growth)
        self._release_idle(0)
        return replace(rep, sweeps=rep.sweeps + sweeps)

    def release(self) -> None:
        """Let go of what this step size keeps for its next step and can make again, and so
        do its halves: the run steps with another size. The Krylov solver's matrix and
        preconditioner (``NewtonSolver.release``); without ENDO3D blocks (whose tangent the
        Newton matrix's blocks hold, ``_update_tangent``), the bodies' ``M_hat`` and
        ``M_hat^-1`` (``System.release``), made again with the same bits at the next step
        (``_restore``)."""
        if self.newton is not None:
            self.newton.release()
        if self.material is None and not self.sys.released:
            self.sys.release()
            self._minv_free = None
            if self.newton is not None:
                self.newton.use_mhat(None)
        if self._half is not None:
            self._half.release()

    def _restore(self) -> None:
        """Make again what ``release`` let go of, before a step."""
        if not self.sys.released:
            return
        self.sys.restore()
        if self.newton is not None:
            self.newton.use_mhat(self.sys.mhat)
        self._products_without_blocks()

    def _release_idle(self, level: int) -> None:
        """Before and after a step of the adaptive step size at ``level``: the other step
        sizes let go of what they keep (``release``), so that one holds its matrix and
        preconditioner at a time, not every size the run has met (docs/scaling.md). Those
        released already have nothing more to let go of."""
        for k, rung in self._rungs.items():
            if k != level:
                rung.release()
        if level != 0:
            self.release()

    def solver_counts(self) -> dict[str, int]:
        """Work of the Newton linear solves so far, summed over this integrator and the ones it
        made steps with (halves, adaptive rungs): ``factorisations`` (of the Newton matrix or
        its preconditioner), ``linear_iterations`` (Krylov iterations; 0 for LU),
        ``linear_fallbacks`` (Krylov solves that did not converge and were made by LU) and
        ``cycles`` (steps given up because Newton's iterations cycled, ``newton._Cycle``)."""
        out = {"factorisations": 0, "linear_iterations": 0, "linear_fallbacks": 0, "cycles": 0}
        if self.newton is not None:
            for key in out:
                out[key] += int(getattr(self.newton, key))
        for sub in [*self._rungs.values(), *([self._half] if self._half is not None else [])]:
            for key, n in sub.solver_counts().items():
                out[key] += n
        return out

    def linear_notes(self) -> list[str]:
        """Why the Krylov solves that were made again by LU failed, oldest first (this
        integrator's Newton solver, then those of its halves and rungs)."""
        out = list(self.newton.linear_notes) if self.newton is not None else []
        for sub in [*self._rungs.values(), *([self._half] if self._half is not None else [])]:
            out += sub.linear_notes()
        return out

    def step_memory(self) -> dict[str, int]:
        """What the step control remembers of the last steps (the halving's run of failures,
        the adaptive step's level and easy steps) and, with kinetic damping, the last step's
        kinetic energy (J): a resumed run needs it to step the same."""
        level, easy = self.control.memory() if self.control is not None else (0, 0)
        out = {"halve_next": self._halve_next, "halve_run": self._halve_run,
               "step_level": level, "step_easy": easy}
        if self.kinetic_damping and self._kinetic_last is not None:
            out["kinetic_last_J"] = self._kinetic_last  # the kinetic damping's last energy
        return out

    def set_step_memory(self, memory) -> None:
        """Put back what :meth:`step_memory` gave (missing keys: no memory)."""
        if "halve_next" in memory:
            self._halve_next = int(memory["halve_next"])
            self._halve_run = int(memory["halve_run"])
        if self.control is not None and "step_level" in memory:
            self.control.level = min(int(memory["step_level"]), self.control.max_level)
            self.control.easy = int(memory["step_easy"])
        if "kinetic_last_J" in memory:
            self._kinetic_last = float(memory["kinetic_last_J"])

    def _rung(self, k: int) -> Integrator:
        """The integrator of steps of ``h 2^k``, built on first use (no halving of its own: a
        step of it that fails is made again by a lower rung); its Newton solve stops at
        ``4 easy_iterations`` iterations, a step that hard being made faster as smaller ones."""
        if k not in self._rungs:
            rung = Integrator(self.bodies, self.points, self.params, self.loads,
                              h=self.sys.h * (1 << k), layout=self.sys,
                              **{**self._half_args, "max_halvings": 0})
            rung.last_resorts = False
            if rung.newton is not None:
                rung.newton.max_iterations = min(rung.newton.max_iterations,
                                                 4 * self.control.easy_iterations)
                rung.newton.share_pattern(self.newton)
            self._rungs[k] = rung
        return self._rungs[k]

    def _take(self, rung: Integrator) -> None:
        """Take the state of ``rung`` after its step (it made one step of this run)."""
        number = self.step_index + 1
        restore_integrator(self, integrator_state(rung))
        self.step_index = rung.step_index = number
        if self.newton is not None:
            self.newton.adopt_solutions(rung.newton)

    def _step_h(self) -> StepReport:
        """Advance by h; made again as two steps of h/2 if it does not converge (module
        docstring), at most ``max_halvings`` times nested."""
        if not self.max_halvings:
            return self._step()
        start = integrator_state(self)
        # the solutions the step's predictor extrapolates, before a failed attempt adds its own
        before = [] if self.newton is None else self.newton.remembered()
        if self._halve_next > 0:
            self._halve_next -= 1
            return replace(self._subdivide(start, None, before), tried_h=False)
        try:
            rep = self._step()
        except DivergenceError:  # a smaller step may not diverge
            rep = None
        if rep is not None and rep.converged:
            self._halve_run = self.halve_after_failure
            if self._half is not None:  # idle until a step fails again
                self._half.release()
            return rep
        self._halve_next = self._halve_run
        self._halve_run = min(2 * self._halve_run, MAX_HALVE_RUN)
        return self._subdivide(start, rep, before)

    def _subdivide(self, start: dict, failed: StepReport | None,
                   before: list | None = None) -> StepReport:
        """Make the step that began in state ``start`` again as two steps of h/2 (each of which
        may subdivide again), with an integrator of the same scene built at h/2 on first use;
        the state it ends in becomes this integrator's. The halves predict from ``before``
        (the run's last solutions, ``NewtonSolver.remembered``, taken before the failed
        attempt; None: the solver's, no attempt having been made) and the next step from the
        halves. The iterations of the failed attempt (None: it diverged) count in the report;
        a divergence at the smallest step is raised with this step's number."""
        if before is None:
            before = [] if self.newton is None else self.newton.remembered()
        if self._half is None:
            self._half = Integrator(self.bodies, self.points, self.params, self.loads,
                                    h=0.5 * self.sys.h, layout=self.sys,
                                    **self._half_args)
            if self._half.newton is not None:
                self._half.newton.share_pattern(self.newton)
        half = self._half
        restore_integrator(half, start)
        if half.newton is not None:
            half.newton.remember(before)
        number = int(start["step_index"]) + 1
        try:
            reps = [half.step(), half.step()]
        except DivergenceError as exc:
            raise DivergenceError(number, exc.time, exc.what,
                                  f" (also in steps of {half.sys.h:g} s and smaller)") from exc
        restore_integrator(self, integrator_state(half))
        self.step_index = number
        if self.newton is not None:
            self.newton.adopt_solutions(half.newton)
        bad = [r for r in reps if r.material_failures]
        return StepReport(
            self.step_index, self.t,
            (failed.sweeps if failed is not None else 0) + sum(r.sweeps for r in reps),
            max(r.residual for r in reps), all(r.converged for r in reps),
            max(r.ambiguous for r in reps), sum(r.material_failures for r in reps),
            bad[0].material_failure_at if bad else None, sum(r.substeps for r in reps),
            damage_growth=self._damage_growth(
                start["joint_beta"],
                None if self.material is None else self.material.damages(start["material_state"])))

    def _free_velocity(self, fint: np.ndarray, F1: np.ndarray) -> np.ndarray:
        """Velocities at the end of the step without contact impulses (m/s), theta-method with
        ``M_hat = M + (theta h)^2 K`` (model.md section 4)::

            v_free = v_n + M_hat^-1 [h (theta F_n+1 + (1 - theta) F_n) - h F_int(u_n)
                                     - theta h^2 K v_n]

        On the ENDO3D blocks' dofs it is ``v_n`` when ``blocks_apart`` (their rows of the
        residual do not need it, ``MaterialCorrection``).
        """
        s = self.sys
        h, theta = s.h, s.theta
        rhs = h * (theta * F1 + (1.0 - theta) * self._F0) - h * fint
        rhs -= theta * h * h * self._k_free.matvec(self.v)
        return self.v + self._minv_free.matvec(rhs)

    def _step(self) -> StepReport:
        """One step of h (the module docstring's items 1 to 5), not subdivided."""
        self._restore()
        s = self.sys
        h, theta = s.h, s.theta
        t1 = self.t + h
        F1 = self.loads.at(t1, s.ndof)
        fint = self.current_internal_forces()
        if self.energy_account is not None:
            fint = fint.copy()  # the end of the step computes those at u1 into self.fint
        v_free = self._free_velocity(fint, F1)
        for d, hist in self.imposed:
            v_free[d] = step_velocity(hist, self.t, t1, theta, self.v[d])
        for free, imposed, C in self._coupled:
            v_free[free] += C @ (v_free[imposed] - self.v[imposed])
        j = self.joints
        if self.newton is not None:
            v1, T, uc, beta, status, sweeps, residual = self._newton_solve(v_free, fint, F1, t1)
            self._dv = v1 - v_free
            amb = int(np.sum(status == laws.ST_AMBIGUOUS))
        if self.newton is None or (residual > self.tolerance and self.material is None
                                   and self._for_good()):
            # Gauss-Seidel sweeps: the solver of the case, or the end of a step that Newton
            # did not finish and that will not be subdivided (warm-started from its last
            # tractions; not with ENDO3D blocks, whose material correction only the Newton
            # residual carries). Halving the step is tried first: the sweeps cost far more than
            # a Newton step and rarely reach a tight tolerance where Newton failed.
            newton_its = sweeps if self.newton is not None else 0
            T = j.T.copy() if self.newton is None else T
            uc = np.empty_like(j.uc)
            beta = np.empty_like(j.beta)
            status = np.empty_like(j.status)
            U_free = np.empty((s.npt, 3))  # the points' free relative velocities
            kernels.local_velocities(s.side_dofs, s.side_coef, v_free, U_free)
            y_off, y = s.velocity_maps()
            with timing.part("Gauss-Seidel sweeps"):
                sweeps, residual, amb = kernels.nlgs(
                    U_free, j.u, j.U, s.kind, s.law, self.params, s.area, s.W, s.side_dofs,
                    s.side_coef, s.side_body, s.body_dof0, y_off, y, h, theta, j.uc,
                    j.beta, T, uc, beta, status, self._dv, self.tolerance, self.max_iterations,
                    self.check_every,
                )
            sweeps += newton_its
            v1 = v_free + self._dv
        u1 = self.u + h * (theta * v1 + (1.0 - theta) * self.v)
        U1 = np.empty((s.npt, 3))
        kernels.local_velocities(s.side_dofs, s.side_coef, v1, U1)
        ul1 = j.u + h * (theta * U1 + (1.0 - theta) * j.U)
        self.step_index += 1
        if not (np.isfinite(u1).all() and np.isfinite(v1).all() and np.isfinite(T).all()):
            what = "body velocities" if not np.isfinite(v1).all() else "contact tractions"
            raise DivergenceError(self.step_index, t1, what)
        u0, v0, F0, j0 = self.u, self.v, self._F0, self.joints
        self.u, self.v, self.t, self._F0 = u1, v1, t1, F1
        failures, failure_at = 0, None
        if self.material is not None:
            failures = int(self.material.failures)
            if failures:
                bad = self.material.failed_points()
                if len(bad):
                    failure_at = tuple(float(x) for x in self.material.point_centre(bad[0]))
            damages0 = self.material.damages()
            self.material.commit()
        self.joints = JointState(u=ul1, U=U1, uc=uc, beta=beta, T=T, status=status)
        growth = self._damage_growth(j.beta, damages0 if self.material is not None else None)
        if self.energy_account is not None:
            self.energy_account.step(self.energy, u0=u0, v0=v0, u1=u1, v1=v1, F0=F0, F1=F1,
                                     fint0=fint, fint1=self.internal_forces(), j0=j0,
                                     j1=self.joints)
        return StepReport(self.step_index, t1, int(sweeps), float(residual),
                          bool(residual <= self.tolerance and failures == 0), int(amb),
                          failures, failure_at, damage_growth=growth)

    def _for_good(self) -> bool:
        """Whether a step of this integrator is made for good: it will not be subdivided
        (no halvings left) and is not an adaptive rung's attempt (``last_resorts``)."""
        return not self.max_halvings and self.last_resorts

    def _newton_solve(self, v_free: np.ndarray, fint: np.ndarray, F1: np.ndarray,
                      t1: float) -> tuple:
        """Newton's solve of the step ending at ``t1`` (``NewtonSolver.solve``'s tuple, the
        iterations of both attempts counted).

        Newton starts from the last two steps' solutions extrapolated to ``t1``. Where a step
        is made for good (it will not be subdivided and is not an adaptive rung's attempt) and
        Newton did not converge from there, it is solved again from ``v_free`` plus the last
        step's impulses, and the attempt of the smaller residual is kept. At a sudden failure
        (the brick wall's joints giving way one after the other at U_x = 0.93 mm) the
        extrapolation of the steps before it points away from the solution, and without this
        second start the step was left unconverged (docs/performance.md)."""
        j = self.joints

        def solve():
            corr = None if self.material is None else MaterialCorrection(self, fint, F1)
            return self.newton.solve(v_free, j.u, j.U, self.params, j.uc, j.beta, j.T,
                                     self._dv, correction=corr, t_end=t1)

        before = self.newton.remembered()
        first = solve()
        if (first[-1] <= self.tolerance or not self._for_good()
                or not self.newton.extrapolates(before)):
            return first
        after = self.newton.remembered()
        self.newton.remember([])
        second = solve()
        its = first[5] + second[5]
        if second[-1] < first[-1]:
            return (*second[:5], its, second[-1])
        self.newton.remember(after)
        return (*first[:5], its, first[-1])

    def _damage_growth(self, beta0: np.ndarray, damages0: np.ndarray | None) -> float:
        """The largest loss of integrity of a joint point and growth of an ENDO3D damage of a
        Gauss point (``Endo3dBlocks.damages``) from those at the start of a step to now."""
        growth = float(np.max(beta0 - self.joints.beta, initial=0.0))
        if damages0 is not None:
            growth = max(growth, float(np.max(self.material.damages() - damages0, initial=0.0)))
        return growth

    # --- read-outs ----------------------------------------------------------------------
    def point_forces(self) -> np.ndarray:
        """Force of each contact point on its candidate body, global frame (npt, 3), N.

        The antagonist body receives the opposite force.
        """
        s = self.sys
        return -s.area[:, None] * np.einsum("aij,ai->aj", s.frame, self.joints.T)

    def body_dofs(self, i: int) -> slice:
        return slice(int(self.sys.body_dof0[i]), int(self.sys.body_dof0[i + 1]))


class MaterialCorrection:
    """``c(v) = h theta [F_int(u) - F_int(u_n) - K0 (u - u_n)]`` for the ENDO3D blocks of one
    step, with ``u = u_n + h (theta v + (1 - theta) v_n)``, summed element by element from the
    stresses and strains committed at ``u_n`` (``Endo3dBlocks.internal_forces``); and the size
    of the internal impulses it corrects, ``h theta |F_int(u)|`` (N s). The Newton residual
    asks for it as a batch (:meth:`batch`), to run the trial in the same hand-over to the
    threads as the joint law.

    On the blocks' dofs the residual's ``M_hat (v - v_free) + c(v)`` is also, the ``K0`` terms
    cancelling (``M_hat = M + (theta h)^2 K0``, ``M`` lumped, and ``M_hat v_free = M_hat v_n +
    h F_theta - h F_int(u_n) - theta h^2 K0 v_n``, ``_free_velocity``),

        M v + h theta F_int(u) + b,   b = -M v_n - h F_theta + h (1 - theta) F_int(u_n)   (N s)

    the theta-method's momentum balance, with ``F_theta = theta F_n+1 + (1 - theta) F_n`` and
    ``b`` fixed over the step (:meth:`constant_impulses`). When the integrator's
    ``blocks_apart`` says so, the residual takes this form (``StepResidual``): it needs no
    product by the blocks' dense ``M_hat`` per evaluation, nor their free velocity, the trial's
    forces ``f_trial`` (N) standing for ``F_int(u)``. ``fint_n``: the internal forces at the
    step's start, ``F_int(u_n)`` (N, every dof); ``F1``: the loads at its end (N)."""

    def __init__(self, integ: Integrator, fint_n: np.ndarray, F1: np.ndarray):
        self.integ = integ
        s = integ.sys
        self.h, self.theta, self.ndof = s.h, s.theta, s.ndof
        self.f_trial = np.zeros(s.ndof)
        self.bodies = integ.material.index  # the ENDO3D blocks
        self.dofs = integ.material.all_dofs  # and their dofs
        self.apart = integ.blocks_apart  # their rows as M v + h theta F_int(u) + b
        self._fint_n = fint_n
        self._F1 = F1

    def constant_impulses(self) -> np.ndarray:
        """``b`` on the blocks' dofs (class docstring), N s."""
        h, th, integ, d = self.h, self.theta, self.integ, self.dofs
        F = th * self._F1[d] + (1.0 - th) * integ._F0[d]
        return -integ.sys.mass[d] * integ.v[d] - h * F + h * (1.0 - th) * self._fint_n[d]

    def batch(self, v: np.ndarray) -> tuple:
        """``(kernel, n, min_size, finish)``: the trial at ``v`` as a batch for
        ``threads.run_together``, and ``finish(results) -> (c, scale)`` once it has run."""
        h, th, integ = self.h, self.theta, self.integ
        du = h * (th * v + (1.0 - th) * integ.v)
        c = np.zeros(self.ndof)  # a new array: the solver compares it with the last one
        kernel, n, min_size, done = integ.material.trial_batch(integ.u + du, self.f_trial,
                                                               departure=c, scale=h * th)

        def finish(results: list) -> tuple[np.ndarray, float]:
            done(results)
            return c, h * th * float(np.linalg.norm(self.f_trial)) + 1e-300

        return kernel, n, min_size, finish
