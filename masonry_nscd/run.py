"""Run one case: build its scene, step it to its stop rule, record the results.

The loop only: the scene (:mod:`masonry_nscd.scenes`) says what is driven, what is reported and
when to stop; the recorder (:mod:`masonry_nscd.io.recorder`) writes the run folder
(:mod:`masonry_nscd.io.runfolder`), the log goes to ``run.log`` (:mod:`masonry_nscd.io.run_log`);
the fields come from :mod:`masonry_nscd.post.fields`; the summary from
:mod:`masonry_nscd.report`. Per step, the CSV row: ``U_x``, ``U_y`` the driven
body's reference point, ``F_x``, ``F_y`` the force of the scene's ``top`` reaction body on the
others (the upper beam on the wall), ``*_bottom`` that of the ``bottom`` one, the solver's
iterations and residual, the largest damages.

Failures: a step whose solver diverges or ends with a residual over :data:`LOST_RESIDUAL`, a
NaN about to be written, or a solver bug end the run with :class:`RunFailure` naming the step,
the load stage and the cause; results up to the last output step are kept and the summary is
written. Ctrl-C and SIGTERM (:data:`TERMINATE`) do the same with KeyboardInterrupt.
"""

from __future__ import annotations

import contextlib
import gc
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from masonry_nscd import arithmetic, threads, timing
from masonry_nscd.case import case_to_yaml
from masonry_nscd.collapse import CollapseMonitor
from masonry_nscd.errors import RunFailure, RunInputError, RunOutputError
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.recorder import Recorder, StepOutput, read_resume_point
from masonry_nscd.io.run_log import RunLog
from masonry_nscd.io.runfolder import CSV_COLUMNS
from masonry_nscd.nscd import mpi
from masonry_nscd.nscd.checkpoint import CheckpointError, restore_integrator
from masonry_nscd.nscd.energy import energy_row
from masonry_nscd.nscd.integrator import DivergenceError
from masonry_nscd.nscd.newton import CYCLE_VISITS
from masonry_nscd.post.fields import OutputMesh, StepFields, point_initial_damage, von_mises
from masonry_nscd.report import report_run
from masonry_nscd.scenes import build_scene
from masonry_nscd.scenes.scene import DOF_NAMES

__all__ = ["CSV_COLUMNS", "LOST_RESIDUAL", "TERMINATE", "WRITING", "RunFailure",
           "RunInputError", "RunOutputError", "RunResult", "request_stop", "run_case"]

#: Set by a signal handler (``masonry run`` on SIGTERM) that also raises KeyboardInterrupt: the
#: step loop raises it again at the next step, should the handler's exception have been lost
#: (a SIGTERM that arrives while numba is loading its kernels could otherwise leave the run
#: going).
TERMINATE = threading.Event()

#: Set while the run writes its files (an output step, the files' closing): a stop request
#: (:func:`request_stop`) then only sets :data:`TERMINATE`, and the step loop stops once the
#: writing is done. An exception raised inside h5py's calls left results.h5 flagged as still
#: open for writing (a SIGTERM test, once in CI).
WRITING = threading.Event()


def request_stop(signum=None, frame=None) -> None:
    """The signal handler of ``masonry run`` (SIGTERM, Ctrl-C): stop the run like Ctrl-C,
    the outputs kept. Sets :data:`TERMINATE` (the step loop raises KeyboardInterrupt at its
    next step, should this handler's exception be lost inside a library) and raises
    KeyboardInterrupt now, unless the run is writing its files (:data:`WRITING`) or runs on
    several processes (``nscd/mpi.py``: an exception inside a solve would leave the others
    waiting in it; the run stops at the end of its step)."""
    TERMINATE.set()
    if not WRITING.is_set() and mpi.launched_processes() == 1:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _writing_files():
    """The block writes the run's files: a stop request waits for its end."""
    WRITING.set()
    try:
        yield
    finally:
        WRITING.clear()

#: A step that ends with a residual (relative change of the contact forces between the last
#: iterates; for Newton also the momentum residual against the contact impulses) above this
#: has lost its solution: the run stops (RunFailure) rather than record it.
#: Steps that stall below it are recorded and counted: the steps a run stalls on while it
#: still follows its path stay about a decade below it, and a step that has lost its solution
#: (an ENDO3D block driven far past its peak) ends near 1 with forces off by a factor of ten.
LOST_RESIDUAL = 0.1


@dataclass
class RunResult:
    steps: int
    ux_mm: float
    fx_kN: float
    seconds: float
    unconverged_steps: int
    outdir: Path
    stopped: bool = False  # ended by ``stop_when`` before the target


def output_mesh_arrays(scene, mesh, integ) -> dict:
    """The ``mesh`` group of results.h5: the structure's hexahedra and the contact points."""
    import numpy as np

    s = integ.sys
    return {"nodes_m": mesh.nodes, "hexes": mesh.hexes, "block_of_element": mesh.block_of_element,
            "structure_bodies": np.array(mesh.bodies, dtype=np.int64).reshape(-1),
            "contact_points_m": np.array([p.x for p in scene.points]).reshape(-1, 3),
            "contact_group": np.array([p.group for p in scene.points], dtype=np.int64),
            "contact_bodies": s.side_body.copy(), "contact_area_m2": s.area,
            "contact_frame": s.frame, "contact_gap_m": np.array([p.gap for p in scene.points]),
            "contact_initial_damage": point_initial_damage(integ.params, s.kind, s.law),
            **{f"contact_{k}": v for k, v in scene.point_fields.items()}}


#: The parts of a run that ``run.log`` times (``masonry_nscd.timing``); the solver's parts
#: are inside "steps"
_RUN_PARTS = ("scene build", "steps", "outputs")


def _log_end(log: RunLog, integ, secs: float, ux: float, top, unconverged: int, worst: float,
             spans: dict[int, int], h: float) -> None:
    """The closing lines of ``run.log``: the run's end, the linear solver's work, where the
    time went (``masonry_nscd.timing``), the step sizes taken, the peak memory of each
    process and the energy balance."""
    log(f"done: {integ.step_index} steps in {secs:.1f} s, Ux {1e3 * ux:.4f} mm, "
        f"Fx {1e-3 * top[0]:.3f} kN; {unconverged} steps not converged "
        f"(worst residual {worst:.2e})")
    if integ.newton is not None and integ.newton.linear == "krylov":
        counts = integ.solver_counts()
        engine = integ.newton.linear_engine
        log(f"linear solver krylov: {counts['factorisations']} preconditioner set-ups, "
            f"{counts['linear_iterations']} GMRES iterations, {counts['linear_fallbacks']} "
            "solves made by LU" + (f" ({engine})" if engine else ""))
    parts = timing.table()
    outer = [r for r in parts if r.name in _RUN_PARTS]
    if outer:
        log("time: " + ", ".join(f"{r.name} {r.total_s:.2f} s" for r in outer)
            + f", the rest {secs - sum(r.total_s for r in outer):.2f} s")
    inner = [r for r in parts if r.name not in _RUN_PARTS]
    for r in inner:
        log(f"time in the steps: {r.name} {r.total_s:.2f} s ({r.calls} calls, median "
            f"{r.median_ms:.3g} ms)")
    steps = next((r for r in outer if r.name == "steps"), None)
    if inner and steps is not None:
        log(f"time in the steps: the rest {steps.total_s - sum(r.total_s for r in inner):.2f} s "
            "(the Newton iterations' own work, the step's set-up)")
    if any(k > 1 for k in spans):
        log("step sizes: " + ", ".join(f"{spans[k]} of {k * h:g} s" for k in sorted(spans)))
    memory = mpi.peak_memory_per_process()
    log(f"memory: peak {memory[0]:,.0f} MiB" if len(memory) == 1 else
        "memory: peak per process " + " + ".join(f"{m:,.0f}" for m in memory)
        + f" = {sum(memory):,.0f} MiB")
    if integ.energy_account is not None:
        e = integ.energy_account.balance(integ)
        log(f"energy: external work {e['external_work']:.6g} J = kinetic {e['kinetic']:.4g} "
            f"+ elastic {e['elastic_blocks'] + e['elastic_joints']:.4g} + dissipated "
            f"(friction {e['dissipated_friction']:.4g}, cohesion {e['dissipated_cohesion']:.4g}, "
            f"impacts {e['dissipated_impacts']:.4g}, blocks {e['dissipated_blocks']:.4g}) + "
            f"numerical {e['numerical']:.4g} J; imbalance {e['imbalance']:.3g} J "
            f"(relative {e['relative_imbalance']:.2e})")


def _open_run(case_yaml: str, outdir: Path, resume: bool, overwrite: bool):
    """The checkpoint a resumed run continues from (``io.recorder.ResumePoint``), after the
    checks that it may; None for a new run, whose folder is made ready (RunInputError when it
    may not be written)."""
    if not resume:
        rf.prepare_outdir(outdir, overwrite)
        return None
    try:
        point = read_resume_point(outdir)
    except CheckpointError as exc:
        raise RunInputError(str(exc)) from exc
    if point is None:
        raise RunInputError(f"{outdir} has no checkpoint ({rf.CHECKPOINT}): nothing to "
                            "resume (not a run folder, or no output step was written)")
    if point.finished:
        raise RunInputError(f"the run in {outdir} is finished (step {point.step})")
    if point.case_yaml != case_yaml:
        raise RunInputError(f"{outdir}/{rf.CASE} differs from the case of the checkpoint: "
                            "a run resumes with the case it started with")
    return point


def _case_line(case, scene, integ) -> str:
    """The first line of ``run.log``: the model's size and the solvers the run uses."""
    s, solver = integ.sys, scene.solver
    return (
        f"case {case.name}: {len(scene.structure)} units, {s.npt} contact points, {s.ndof} "
        f"dofs, blocks {case.blocks.material}"
        + f", {scene.label or scene.builder}"
        + f", contact solver {solver.method}"
        + (f", steps of {solver.h:g} s to {solver.h * (1 << solver.max_growth):g} "
           "s (adaptive)" if solver.max_growth else "")
        + (" (auto)" if case.solver.method == "auto" else "")
        + (", kinetic damping" if solver.kinetic_damping else "")
        + (f", linear solver {integ.newton.linear}"
           + (" (auto)" if case.solver.linear == "auto" else "")
           + (f" on {mpi.launched_processes()} processes" if mpi.launched_processes() > 1
              else "")
           if integ.newton is not None else "")
        + (f", contact points at {scene.meta['contact_point_rule']} points"
           if "contact_point_rule" in scene.meta else "")
        + f", kernels on {threads.count()} thread(s)")


def _arithmetic_line() -> str:
    """The second line of ``run.log``: the libraries' kernels and threads, and whether the run
    gives the same bits on any x86-64 processor (``arithmetic.py``)."""
    a = arithmetic.describe()
    what = ("the same bits on any x86-64 processor and thread count"
            if a["reproducible"] == "bitwise" else
            "not the same bits everywhere, " + a["reproducible"].removeprefix("no: "))
    return (f"arithmetic: {what} (OpenBLAS {a['openblas_kernels']} kernels on "
            f"{a['openblas_threads']} thread(s), MKL {a['mkl']})")


def _failure(scene, step: int, t: float, what: str) -> RunFailure:
    """A run failure at ``step`` (time ``t``, s), named with its load stage."""
    return RunFailure(f"step {step} ({scene.stage_at(t)} stage, t = {t:.6g} s): {what}")


def _advance(integ, scene, log: RunLog):
    """One step of ``integ`` (its ``StepReport``): a divergence or a solver's exception ends
    the run with a RunFailure naming the step and the load stage (the traceback in run.log)."""
    t1 = integ.t + scene.solver.h
    try:
        with timing.part("steps"):
            return integ.step()
    except DivergenceError as exc:
        raise RunFailure(f"{exc} ({scene.stage_at(t1)} stage)") from exc
    except (KeyboardInterrupt, RunFailure):
        raise
    except Exception as exc:  # a solver bug must still end in a clean message
        with contextlib.suppress(RunOutputError):
            log(traceback.format_exc(), show=False)
        raise _failure(scene, integ.step_index + 1, t1, f"the solver raised "
                       f"{type(exc).__name__}: {exc} (traceback in {rf.LOG})") from exc


@dataclass
class _StepNotes:
    """What the steps of a run reported: steps not converged and the worst residual, steps
    made again as smaller ones, Krylov solves made again by LU, steps by size (in steps of h).
    :meth:`note` logs the unusual steps (the first five of each kind shown, all in run.log)."""

    log: RunLog
    scene: object
    unconverged: int = 0
    worst: float = 0.0
    subdivided: int = 0
    linear_fallbacks: int = 0
    spans: dict[int, int] = field(default_factory=dict)

    def note(self, rep, integ, before: dict[str, int]) -> None:
        """Count and log the step ``rep`` of ``integ`` (whose ``solver_counts`` were ``before``
        before it); RunFailure when its residual is over :data:`LOST_RESIDUAL`."""
        log, solver = self.log, self.scene.solver
        counts = integ.solver_counts()
        if counts["linear_fallbacks"] > before["linear_fallbacks"]:
            self.linear_fallbacks += 1
            log(f"step {rep.step} (t = {rep.time:.4f} s): Krylov solve not converged, made "
                f"by LU ({(integ.linear_notes() or ['no reason recorded'])[-1]})",
                show=self.linear_fallbacks <= 5)
        self.worst = max(self.worst, rep.residual)
        self.spans[rep.span] = self.spans.get(rep.span, 0) + 1
        if rep.substeps > 1:
            self.subdivided += 1
            cycled = ""
            if counts["cycles"] > before["cycles"]:
                cycled = (" (Newton's iterations cycled: an iterate met "
                          f"{CYCLE_VISITS} times)")
            why = (f"not converged with h = {solver.h:g} s{cycled}, made again" if rep.tried_h
                   else f"made at once{cycled}")
            log(f"step {rep.step} (t = {rep.time:.4f} s): {why} as {rep.substeps} smaller "
                f"steps ({'converged' if rep.converged else 'still not converged'})",
                show=self.subdivided <= 5)
        if rep.converged:
            return
        self.unconverged += 1
        show = self.unconverged <= 5
        if rep.material_failures:
            at = rep.material_failure_at
            place = (f" (the first in the element centred at x = {at[0]:.3f}, y = "
                     f"{at[1]:.3f}, z = {at[2]:.3f} m)") if at else ""
            log(f"step {rep.step} (t = {rep.time:.4f} s): ENDO3D return mapping not "
                f"converged at {rep.material_failures} Gauss points{place}", show=show)
        if rep.residual > solver.tolerance:
            log(f"step {rep.step} (t = {rep.time:.4f} s): contact solver "
                f"({solver.method}) not converged after {rep.sweeps} iterations, "
                f"residual {rep.residual:.3e} > {solver.tolerance:.1e}", show=show)
        if rep.residual > LOST_RESIDUAL:
            raise _failure(self.scene, rep.step, rep.time, (
                f"the contact solver ({solver.method}) stopped after "
                f"{rep.sweeps} iterations with the forces still changing by "
                f"{rep.residual:.3g} (relative) per iteration, over {LOST_RESIDUAL:g}: no "
                "solution worth recording (results kept up to the last output step)"))


def _write_output_step(rec, scene, integ, fields, mesh, damage: dict, rep, done: bool,
                       notes: _StepNotes) -> None:
    """The fields of step ``rep`` into the run's files (VTU, HDF5, energy, checkpoint):
    RunFailure when a value is not finite (the writers refuse NaN and inf, naming the
    field)."""
    import numpy as np

    with timing.part("outputs"):
        sig = fields.element_stress()
        disp = fields.nodal_displacement()
        j = integ.joints
        removed = {}
        if scene.removal is not None:  # 1 on the cells of the blocks out of the model
            out = np.isin(mesh.bodies, scene.removed_bodies(rep.time - scene.solver.h))
            removed = {"removed": out[mesh.block_of_element].astype(float)}
        step_out = StepOutput(
            block_points={"displacement_m": disp},
            block_cells={"block": mesh.block_of_element.astype(float), "stress_Pa": sig,
                         "von_mises_Pa": von_mises(sig), **damage, **removed},
            joint_points=fields.joint_fields(),
            h5={"u": integ.u, "v": integ.v, "element_stress_Pa": sig,
                "nodal_displacement_m": disp,
                **{f"element_{k}": v for k, v in damage.items()},
                "joint_u_m": j.u, "joint_uc_m": j.uc, "joint_beta": j.beta,
                "joint_T_Pa": j.T, "joint_status": j.status})
        acct = integ.energy_account
        energy = None if acct is None else acct.balance(integ)
        try:
            with _writing_files():
                rec.write_output(rep.step, rep.time, step_out, integ, done=done,
                                 unconverged=notes.unconverged, worst_residual=notes.worst,
                                 energy_row=None if energy is None else
                                 energy_row(rep.step, rep.time, energy))
        except ValueError as exc:
            raise _failure(scene, rep.step, rep.time, f"{exc} (not written)") from exc


def run_case(case, outdir: Path, *, overwrite: bool = False,
             echo: Callable[[str], None] = print, progress_every: int | None = None,
             stop_when: Callable[[dict[str, list]], bool] | None = None,
             resume: bool = False) -> RunResult:
    """Run ``case`` into ``outdir`` (the module docstring; the files: ``io/runfolder.py``).

    ``resume``: continue the run of ``outdir`` (made with this ``case``) from its checkpoint,
    its outputs cut back to that step; RunInputError when it has no checkpoint, is finished, or
    the checkpoint does not fit the case.

    ``stop_when(curve)``, called after every step with the curve so far (``{column: [values]}``
    of the CSV columns), ends the run early when it returns True (e.g. once a stiffness is
    measured, :mod:`masonry_nscd.studies.calibrate`).
    """
    import numpy as np

    outdir = Path(outdir)
    case_yaml = case_to_yaml(case)
    point = _open_run(case_yaml, outdir, resume, overwrite)
    log = RunLog(outdir, resume, echo)

    t_start = time.perf_counter()
    timing.reset()
    try:
        with timing.part("scene build"):
            scene = build_scene(case)
            integ = scene.integrator(point.state["t"] if point else 0.0)
    except ValueError as exc:  # parameters the schema lets through but the scene refuses
        log.close()
        raise RunInputError(f"invalid case {case.name}: {exc}") from exc
    log(_case_line(case, scene, integ))
    log(_arithmetic_line())
    for group in scene.removal.groups if scene.removal is not None else ():
        log(f"removal: {', '.join(group.names)} leave the model at t = "
            f"{group.at_s(scene.solver.h):.6g} s")
    if case.step_growth_note:
        log(case.step_growth_note)
    if point is not None:
        try:
            restore_integrator(integ, point.state)
        except CheckpointError as exc:
            raise RunInputError(f"{outdir / rf.CHECKPOINT}: {exc}") from exc
        scene.settle(integ)  # a run resumed at or after a removal
        log(f"resumed from the checkpoint of step {point.step} (t = {integ.t:.6g} s)")
    mesh = OutputMesh.of(scene)
    fields = StepFields(scene, mesh, integ)
    arrays = output_mesh_arrays(scene, mesh, integ)
    out = case.output
    if point is None:
        rec = Recorder.start(outdir, case_yaml, scene.info(), arrays, vtu=out.vtu,
                             hdf5=out.hdf5, energy=out.energy)
    else:
        rec = Recorder.resume(outdir, point, arrays, vtu=out.vtu, hdf5=out.hdf5)
    curve = rec.curve
    monitor = None  # a limit-state scene's watch for its collapse (masonry_nscd/collapse.py)
    if scene.collapse is not None:
        monitor = CollapseMonitor(scene, integ, outdir, log,
                                  resume_step=point.step if point else None)
    h = scene.solver.h
    t_end = scene.expected_end_s
    # a progress line every progress_every steps, else at each fortieth of the expected end
    # (steps of adaptive size: the time says how far the run is, the step count does not)
    next_line = integ.t + t_end / 40
    notes = _StepNotes(log, scene)
    if point:
        notes.unconverged, notes.worst = point.unconverged, point.worst_residual
    (mx, wx), (my, wy) = scene.measured_dofs(integ.sys.body_dof0)
    weights = scene.reaction_weights(integ.sys.side_body)
    holds = scene.holds_at(integ.t)

    # the scene's objects, built once, out of the cyclic garbage collector's way: its full
    # full collections would walk every one of them at each pass
    gc.freeze()
    try:
        while True:
            if TERMINATE.is_set():
                raise KeyboardInterrupt
            new = scene.next_integrator(integ)  # a hold or the removal begins: a new system
            if new is not integ:
                if scene.holds_at(integ.t) != holds:
                    holds = scene.holds_at(integ.t)
                    log(f"from t = {integ.t:.6g} s: " + ", ".join(
                        f"{scene.bodies[hd.body].name} held in {DOF_NAMES[hd.dof]}"
                        for hd in holds))
                for group in scene.removal.groups[integ.phase[1]:scene.removed_at(integ.t)] \
                        if scene.removal is not None else ():
                    log(f"from t = {integ.t:.6g} s: removed " + ", ".join(group.names))
                integ = new
                fields = StepFields(scene, mesh, integ)
            counts = integ.solver_counts()
            rep = _advance(integ, scene, log)
            notes.note(rep, integ, counts)
            f = integ.point_forces()
            top = weights["top"] @ f if "top" in weights else np.zeros(3)
            bot = weights["bottom"] @ f
            ux, uy = float(wx @ integ.u[mx]), float(wy @ integ.u[my])
            damage = fields.block_damage()
            dj, db, dcpp = fields.largest(damage)
            row = [rep.step, rep.time, 1e3 * ux, 1e-3 * top[0], 1e3 * uy, 1e-3 * top[1],
                   1e-3 * bot[0], 1e-3 * bot[1], rep.sweeps, rep.residual, int(rep.converged),
                   dj, db, dcpp, rep.material_failures, rep.substeps, rep.span * h]
            try:
                rec.add_row(row)
            except RunFailure as exc:
                raise _failure(scene, rep.step, rep.time, str(exc)) from exc
            done = scene.finished(ux, rep.time)
            if monitor is not None and monitor.observe(integ, rep.step, rep.time):
                done = True  # a collapse, and its after_s have passed
            stopped = not done and stop_when is not None and bool(stop_when(curve))
            done = done or stopped
            if round(rep.time / h) % case.output.every_steps == 0 or done:
                _write_output_step(rec, scene, integ, fields, mesh, damage, rep, done, notes)
            if (rep.step % progress_every == 0 if progress_every else
                    rep.time >= next_line - 1e-9 * h) or done:
                while next_line <= rep.time + 1e-9 * h:
                    next_line += t_end / 40
                log(f"[{scene.stage_at(rep.time):10s}] step {rep.step:6d}  t {rep.time:7.4f}/"
                    f"{t_end:.4f} s ({100 * rep.time / t_end:3.0f} %)  "
                    f"Ux {1e3 * ux:8.4f} mm  Fx {1e-3 * top[0]:9.3f} kN  "
                    f"Fy {1e-3 * top[1]:9.3f} kN  sweeps {rep.sweeps:6d}  res {rep.residual:.2e}")
            if done:
                break
    except (RunFailure, KeyboardInterrupt) as exc:
        stop = exc
    else:
        stop = None
    finally:
        gc.unfreeze()
        with _writing_files():
            rec.close()
        if monitor is not None:
            monitor.close()
    if stop is not None:
        # after the recorder has settled: the summary reads results.h5, which its background
        # writer may still be appending the last output step to (HDF5 refuses a file opened
        # for reading to a writer of the same process, and that step was lost)
        _close_stopped(stop, outdir, log, curve, monitor, integ.step_index)
        raise stop
    secs = time.perf_counter() - t_start
    _log_end(log, integ, secs, ux, top, notes.unconverged, notes.worst, notes.spans, h)
    if monitor is not None:
        monitor.finish("done")
    report_run(outdir, log)
    log.close()
    return RunResult(integ.step_index, 1e3 * ux, 1e-3 * top[0], secs, notes.unconverged, outdir,
                     stopped)


def _close_stopped(exc: BaseException, outdir: Path, log: RunLog, curve, monitor,
                   step: int) -> None:
    """The end of a run stopped by a RunFailure or an interruption (KeyboardInterrupt, at
    step ``step``): the log's last line, the collapse watch told, the summary of what was
    computed (not after a failure to write the outputs), the log closed."""
    failed = isinstance(exc, RunFailure)
    with contextlib.suppress(RunOutputError):
        log(f"failed: {exc}" if failed else
            f"interrupted at step {step}: results kept up to the last output step (resume "
            f"with: masonry run --resume {outdir})", show=not failed)
    if monitor is not None:
        with contextlib.suppress(OSError):
            monitor.finish(*(("failed", str(exc)) if failed else ("interrupted",)))
    if not isinstance(exc, RunOutputError):
        report_run(outdir, log, curve)  # never raises
    with contextlib.suppress(OSError):
        log.close()
