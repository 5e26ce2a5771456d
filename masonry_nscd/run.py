"""Run one wall case: build the scene, step it to the target displacement, record the results.

Outputs in the run folder (SI units unless the column name says otherwise):

* ``case.yaml``: the case as run, every default filled in;
* ``force_displacement.csv``: one row per step, ``step,time_s,ux_mm,fx_kN,uy_mm,fy_kN,
  fx_bottom_kN,fy_bottom_kN,iterations,residual,converged,max_joint_damage,max_block_damage``;
  ``ux``/``uy`` are the upper beam's displacements, ``fx``/``fy`` the force of the upper beam on
  the wall, ``fx_bottom``/``fy_bottom`` the force of the lower beam on the wall;
* ``results.h5``: the case, the mesh, per output step the dofs, the element stresses and the
  joint states, and the curve;
* ``wall.pvd`` with ``vtu/blocks_NNNNNN.vtu`` and ``vtu/joints_NNNNNN.vtu`` per output step;
* ``summary.json``: stiffness, peak, force at the target, convergence, largest damages and where
  they are (:mod:`masonry_nscd.report`), written at the end, also when the run is interrupted;
* ``checkpoint.npz``: the state at the last output step, to resume from (``resume=True``,
  ``masonry run --resume``; see :mod:`masonry_nscd.resume`);
* ``run.log``.

The CSV rows are written (and fsynced) at every output step, and the VTU, PVD, HDF5 and
checkpoint files are written atomically, so an interrupted run keeps valid results up to its
last output step. A write error (disk full...) raises :class:`RunOutputError` naming the file;
a NaN or infinity about to be written raises :class:`RunFailure`: no output file ever holds
one.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import threading
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

CSV_COLUMNS = [
    "step", "time_s", "ux_mm", "fx_kN", "uy_mm", "fy_kN", "fx_bottom_kN", "fy_bottom_kN",
    "iterations", "residual", "converged", "max_joint_damage", "max_block_damage", "max_d_cpp",
    "failed_gauss_points", "substeps",
]


#: Set by a signal handler (``masonry run`` on SIGTERM) that also raises KeyboardInterrupt: the
#: step loop raises it again at the next step, should the handler's exception have been lost
#: (a SIGTERM 16 s into a run, while numba was loading its kernels, left the run going).
TERMINATE = threading.Event()

#: A step that ends with a residual (relative change of the contact forces between the last
#: iterates) above this has lost its solution: the run stops (RunFailure) rather than record it.
#: Steps that stall below it are recorded and counted (measured on the ENDO3D wall at 0.5 MPa:
#: worst 7e-3 over 2638 steps; an ENDO3D block driven far past its peak: 1.96, with forces off
#: by a factor of ten).
LOST_RESIDUAL = 0.1


class RunInputError(ValueError):
    """A problem with what the user asked for (exit code 2)."""


class RunFailure(RuntimeError):
    """The computation failed (exit code 1)."""


class RunOutputError(RunFailure):
    """An output file could not be written (disk full, permissions...; exit code 1)."""


@contextlib.contextmanager
def _writing(path: Path) -> Iterator[None]:
    """Turn an OSError raised inside the block into a :class:`RunOutputError` naming ``path``."""
    try:
        yield
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise RunOutputError(f"cannot write {path}: {reason}") from exc


def stage_at(case, t: float) -> str:
    """Name of the load stage at time ``t`` (s): gravity, vertical or horizontal."""
    return ("gravity" if t < case.loading.vertical_stress.start_s else
            "vertical" if t < case.loading.horizontal.start_s else "horizontal")


@dataclass
class RunResult:
    steps: int
    ux_mm: float
    fx_kN: float
    seconds: float
    unconverged_steps: int
    outdir: Path
    stopped: bool = False  # ended by ``stop_when`` before the target


def prepare_outdir(outdir: Path, overwrite: bool) -> None:
    """Create the run folder; refuse a non-empty one unless ``overwrite``."""
    if outdir.exists() and not outdir.is_dir():
        raise RunInputError(f"output path {outdir} exists and is not a folder")
    if outdir.exists() and any(outdir.iterdir()) and not overwrite:
        raise RunInputError(f"output folder {outdir} exists and is not empty: "
                            "use --overwrite or another -o")
    try:
        (outdir / "vtu").mkdir(parents=True, exist_ok=True)
        probe = outdir / ".write_test"
        probe.write_text("")
        probe.unlink()
    except OSError as exc:
        raise RunInputError(f"cannot write to output folder {outdir}: {exc.strerror}") from exc


def run_case(case, outdir: Path, *, overwrite: bool = False,
             echo: Callable[[str], None] = print, progress_every: int | None = None,
             stop_when: Callable[[dict[str, list]], bool] | None = None,
             resume: bool = False) -> RunResult:
    """Run ``case`` into ``outdir``; see the module docstring for what is written.

    ``resume``: continue the run of ``outdir`` (made with this ``case``) from its checkpoint,
    its outputs cut back to that step (:mod:`masonry_nscd.resume`); RunInputError when it has
    no checkpoint, is finished, or the checkpoint does not fit the case.

    ``stop_when(curve)``, called after every step with the curve so far (``{column: [values]}``
    of the CSV columns), ends the run early when it returns True (e.g. once a stiffness is
    measured, :mod:`masonry_nscd.calibrate`).
    """
    from masonry_nscd.case import case_to_yaml
    from masonry_nscd.contact import joint_law as jl
    from masonry_nscd.io.results_h5 import ResultsFile
    from masonry_nscd.io.vtu import atomic_write, write_blocks_vtu, write_points_vtu, write_pvd
    from masonry_nscd.nscd.checkpoint import CheckpointError, restore_integrator, save_checkpoint
    from masonry_nscd.nscd.integrator import DivergenceError
    from masonry_nscd.resume import (
        CHECKPOINT_NAME,
        checkpoint_extra,
        prune_vtu,
        read_resume_point,
        truncate_csv,
    )
    from masonry_nscd.scenes.wall import GROUP_GLUE_BOTTOM, GROUP_GLUE_TOP, build_wall

    outdir = Path(outdir)
    case_yaml = case_to_yaml(case)
    ckpt_path = outdir / CHECKPOINT_NAME
    if resume:
        try:
            point = read_resume_point(outdir)
        except CheckpointError as exc:
            raise RunInputError(str(exc)) from exc
        if point is None:
            raise RunInputError(f"{outdir} has no checkpoint ({CHECKPOINT_NAME}): nothing to "
                                "resume (not a run folder, or no output step was written)")
        if point.finished:
            raise RunInputError(f"the run in {outdir} is finished (step {point.step})")
        if point.case_yaml != case_yaml:
            raise RunInputError(f"{outdir}/case.yaml differs from the case of the checkpoint: "
                                "a run resumes with the case it started with")
    else:
        prepare_outdir(outdir, overwrite)
        with _writing(ckpt_path):
            ckpt_path.unlink(missing_ok=True)  # an older run's checkpoint, never to resume
        with _writing(outdir / "case.yaml"):
            atomic_write(outdir / "case.yaml", lambda p: Path(p).write_text(case_yaml))
    with _writing(outdir / "run.log"):
        logf = open(outdir / "run.log", "a" if resume else "w")  # noqa: SIM115 (closed below)

    def log(msg: str, show: bool = True) -> None:
        if show:
            echo(msg)
        with _writing(outdir / "run.log"):
            logf.write(f"{time.strftime('%H:%M:%S')} {msg}\n")
            logf.flush()

    t_start = time.perf_counter()
    try:
        scene = build_wall(case)
    except ValueError as exc:  # parameters the schema lets through but the scene refuses
        raise RunInputError(f"invalid case {case.name}: {exc}") from exc
    integ = scene.integrator
    s = integ.sys
    log(f"case {case.name}: {len(scene.units)} units, {s.npt} contact points, {s.ndof} dofs, "
        f"blocks {case.blocks.material}, sigma_N {case.loading.vertical_stress.value_Pa:.4g} Pa")
    if resume:
        try:
            restore_integrator(integ, point.state)
        except CheckpointError as exc:
            raise RunInputError(f"{ckpt_path}: {exc}") from exc
        log(f"resumed from the checkpoint of step {point.step} (t = {integ.t:.6g} s)")
    # mesh for the outputs: all block nodes (deformable blocks only carry nodal displacements)
    deformable = [i for i in range(len(scene.units)) if s.body_deformable[i]]
    nodes = np.concatenate([scene.units[i].X for i in range(len(scene.units))])
    offs = np.cumsum([0] + [len(u.X) for u in scene.units])
    hexes = np.concatenate([u.conn + offs[i] for i, u in enumerate(scene.units)])
    elem_block = np.concatenate([np.full(len(u.conn), i) for i, u in enumerate(scene.units)])
    offs_e = np.cumsum([0] + [len(u.conn) for u in scene.units])
    pts_x = np.array([p.x for p in integ.points])
    b_init = integ.params[0, jl.P_B]
    joint_mask = np.isin(scene.group, (GROUP_GLUE_BOTTOM, GROUP_GLUE_TOP), invert=True)

    from masonry_nscd.fe import hex8

    C0 = hex8.elastic_matrix(case.blocks.E_Pa, case.blocks.nu)

    mat = integ.material
    endo_elems = np.concatenate([np.arange(offs_e[i], offs_e[i + 1]) for i in mat.index]) \
        if mat is not None else np.zeros(0, dtype=int)

    def block_fields() -> dict[str, np.ndarray]:
        """Per element: ENDO3D damages and crack opening (zeros where the blocks are elastic)."""
        nel = len(hexes)
        out = {k: np.zeros(nel) for k in ("d_c", "d_cpp", "d_t", "crack_opening_m")}
        if mat is not None:
            f = mat.element_fields()
            for k, arr in out.items():
                arr[endo_elems] = f[k]
        return out

    def element_stress() -> np.ndarray:
        """Mean stress of each element (nel, 6), Pa, Voigt [xx, yy, zz, yz, xz, xy].

        Linear elastic blocks: C0 times the Gauss-point strains, averaged over the 8 points;
        ENDO3D blocks: the apparent (damaged) stress; rigid units: zeros.
        """
        out = []
        endo = mat.element_fields()["stress_Pa"] if mat is not None else None
        pos = 0
        for i, u in enumerate(scene.units):
            if mat is not None and i in mat.index:
                out.append(endo[pos:pos + len(u.conn)])
                pos += len(u.conn)
            elif i in deformable:
                eps = np.empty((8 * len(u.conn), 6))
                hex8.gauss_strains(u.X, u.conn, np.ascontiguousarray(integ.u[integ.body_dofs(i)]),
                                   eps)
                out.append((eps @ C0.T).reshape(-1, 8, 6).mean(axis=1))
            else:
                out.append(np.zeros((len(u.conn), 6)))
        return np.concatenate(out)

    def von_mises(sig: np.ndarray) -> np.ndarray:
        sxx, syy, szz, syz, sxz, sxy = sig.T
        return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2)
                       + 3.0 * (syz ** 2 + sxz ** 2 + sxy ** 2))

    def nodal_displacement() -> np.ndarray:
        d = np.zeros_like(nodes)
        for i, u in enumerate(scene.units):
            sl = integ.body_dofs(i)
            if i in deformable:
                d[offs[i]:offs[i + 1]] = integ.u[sl].reshape(-1, 3)
            else:  # rigid unit: small rotation about its centre
                q = integ.u[sl]
                r = u.X - integ.bodies[i].center
                d[offs[i]:offs[i + 1]] = q[:3] + np.cross(q[3:], r)
        return d

    csv_path, h5_path, pvd_path = (outdir / "force_displacement.csv", outdir / "results.h5",
                                   outdir / "wall.pvd")
    h5 = None
    if resume:  # the outputs back to the checkpoint's step
        try:
            curve = truncate_csv(csv_path, point.step, CSV_COLUMNS)
            if case.output.hdf5:
                h5 = ResultsFile.reopen(h5_path, last_step=point.step, curve_length=point.step)
        except (CheckpointError, ValueError) as exc:
            raise RunInputError(f"cannot resume the outputs in {outdir}: {exc}") from exc
        except OSError as exc:  # unreadable, flagged as open for write, or disk full
            raise RunOutputError(f"cannot resume the outputs in {outdir}: {exc}") from exc
        pvd: list = list(point.pvd)
        if case.output.vtu:
            with _writing(pvd_path):
                write_pvd(pvd_path, pvd)
                prune_vtu(outdir / "vtu", point.step)
    else:
        if case.output.hdf5:
            with _writing(h5_path):
                h5 = ResultsFile(h5_path, case_yaml, {
                    "nodes_m": nodes, "hexes": hexes, "block_of_element": elem_block,
                    "contact_points_m": pts_x, "contact_group": scene.group,
                    "contact_area_m2": s.area, "contact_frame": s.frame})
        pvd = []
        curve = {c: [] for c in CSV_COLUMNS}
    with _writing(csv_path):  # unbuffered: whole rows only, see flush_rows
        f_csv = open(csv_path, "ab" if resume else "wb", buffering=0)  # noqa: SIM115
    pending = io.StringIO()  # CSV rows not yet written: they go to the file at output steps
    wr = csv.writer(pending)
    if not resume:
        wr.writerow(CSV_COLUMNS)
    target = case.loading.horizontal.target_m
    t_end = case.loading.end_time_s
    h = case.solver.time_step_s
    n_est = math.ceil(t_end / h)
    every = progress_every or max(1, n_est // 40)
    unconverged, worst = (point.unconverged, point.worst_residual) if resume else (0, 0.0)
    subdivided = 0  # steps made again as smaller ones (the log shows the first five)

    def flush_rows() -> None:
        """Append the pending CSV rows to the file and fsync it; after a failed write the file
        is cut back to where it was, so that it only ever holds whole rows."""
        data = memoryview(pending.getvalue().encode())
        end = f_csv.seek(0, os.SEEK_END)
        try:
            with _writing(csv_path):
                while data:
                    data = data[f_csv.write(data):]
                os.fsync(f_csv.fileno())
        except RunOutputError:
            with contextlib.suppress(OSError):
                os.ftruncate(f_csv.fileno(), end)
            raise
        pending.seek(0)
        pending.truncate()

    try:
        while True:
            if TERMINATE.is_set():
                raise KeyboardInterrupt
            where = (f"step {integ.step_index + 1} ({stage_at(case, integ.t + h)} stage, "
                     f"t = {integ.t + h:.6g} s)")
            try:
                rep = integ.step()
            except DivergenceError as exc:
                raise RunFailure(f"{exc} ({stage_at(case, integ.t + h)} stage)") from exc
            except (KeyboardInterrupt, RunFailure):
                raise
            except Exception as exc:  # a solver bug must still end in a clean message
                with contextlib.suppress(RunOutputError):
                    log(traceback.format_exc(), show=False)
                raise RunFailure(f"{where}: the solver raised {type(exc).__name__}: {exc} "
                                 "(traceback in run.log)") from exc
            worst = max(worst, rep.residual)
            if rep.substeps > 1:
                subdivided += 1
                log(f"step {rep.step} (t = {rep.time:.4f} s): not converged with h = {h:g} s, "
                    f"made again as {rep.substeps} smaller steps ("
                    f"{'converged' if rep.converged else 'still not converged'})",
                    show=subdivided <= 5)
            if not rep.converged:
                unconverged += 1
                if rep.material_failures:
                    at = rep.material_failure_at
                    place = (f" (the first in the element centred at x = {at[0]:.3f}, y = "
                             f"{at[1]:.3f}, z = {at[2]:.3f} m)") if at else ""
                    log(f"step {rep.step} (t = {rep.time:.4f} s): ENDO3D return mapping not "
                        f"converged at {rep.material_failures} Gauss points{place}",
                        show=unconverged <= 5)
                if rep.residual > case.solver.tolerance:
                    log(f"step {rep.step} (t = {rep.time:.4f} s): contact solver "
                        f"({case.solver.method}) not converged after {rep.sweeps} iterations, "
                        f"residual {rep.residual:.3e} > {case.solver.tolerance:.1e}",
                        show=unconverged <= 5)
                if rep.residual > LOST_RESIDUAL:
                    raise RunFailure(
                        f"step {rep.step} ({stage_at(case, rep.time)} stage, t = {rep.time:.6g} "
                        f"s): the contact solver ({case.solver.method}) stopped after "
                        f"{rep.sweeps} iterations with the forces still changing by "
                        f"{rep.residual:.3g} (relative) per iteration, over {LOST_RESIDUAL:g}: no "
                        "solution worth recording (results kept up to the last output step)")
            f = integ.point_forces()
            top = f[scene.group == GROUP_GLUE_TOP].sum(axis=0)
            bot = f[scene.group == GROUP_GLUE_BOTTOM].sum(axis=0)
            ux = integ.u[scene.top_dof_x]
            uy = integ.u[scene.top_dof_y]
            dj = float((1.0 - integ.joints.beta[joint_mask] * b_init).max()) \
                if joint_mask.any() else 0.0
            bf = block_fields()
            db = float(np.maximum(bf["d_c"], bf["d_t"]).max()) if len(hexes) else 0.0
            row = [rep.step, rep.time, 1e3 * ux, 1e-3 * top[0], 1e3 * uy, 1e-3 * top[1],
                   1e-3 * bot[0], 1e-3 * bot[1], rep.sweeps, rep.residual, int(rep.converged),
                   dj, db, float(bf["d_cpp"].max()) if len(hexes) else 0.0,
                   rep.material_failures, rep.substeps]
            bad = [c for c, v in zip(CSV_COLUMNS, row) if not math.isfinite(v)]
            if bad:
                raise RunFailure(f"step {rep.step} ({stage_at(case, rep.time)} stage, t = "
                                 f"{rep.time:.6g} s): {', '.join(bad)} not finite (the step is "
                                 "not written)")
            wr.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in row])
            for c, v in zip(CSV_COLUMNS, row):
                curve[c].append(v)
            done = ux >= target or rep.time >= t_end + 0.5 * case.loading.horizontal.ramp_s
            stopped = not done and stop_when is not None and bool(stop_when(curve))
            done = done or stopped
            if rep.step % case.output.every_steps == 0 or done:
                flush_rows()
                j = integ.joints
                sig = element_stress()
                tag = f"{rep.step:06d}"
                blocks_vtu, joints_vtu = (outdir / "vtu" / f"blocks_{tag}.vtu",
                                          outdir / "vtu" / f"joints_{tag}.vtu")
                try:  # the writers refuse NaN/inf (ValueError naming the field)
                    if case.output.vtu:
                        with _writing(blocks_vtu):
                            write_blocks_vtu(blocks_vtu, nodes, hexes,
                                             point_data={"displacement_m": nodal_displacement()},
                                             cell_data={"block": elem_block.astype(float),
                                                        "stress_Pa": sig,
                                                        "von_mises_Pa": von_mises(sig), **bf})
                        with _writing(joints_vtu):
                            write_points_vtu(
                                joints_vtu, pts_x,
                                point_data={"d_coh": 1.0 - j.beta * b_init,
                                            "opening_m": j.u[:, 0],
                                            "slip_m": np.hypot(j.u[:, 1], j.u[:, 2]),
                                            "T_n_Pa": j.T[:, 0],
                                            "T_t_Pa": np.hypot(j.T[:, 1], j.T[:, 2]),
                                            "status": j.status.astype(float),
                                            "group": scene.group.astype(float)})
                        pvd += [(rep.time, f"vtu/blocks_{tag}.vtu", 0),
                                (rep.time, f"vtu/joints_{tag}.vtu", 1)]
                        with _writing(pvd_path):
                            write_pvd(pvd_path, pvd)
                    if h5 is not None:
                        with _writing(h5_path):
                            h5.write_step(rep.step, rep.time, {
                                "u": integ.u, "v": integ.v, "element_stress_Pa": sig,
                                **{f"element_{k}": v for k, v in bf.items()},
                                "joint_u_m": j.u, "joint_uc_m": j.uc, "joint_beta": j.beta,
                                "joint_T_Pa": j.T, "joint_status": j.status})
                            h5.write_curve({c: np.asarray(v, dtype=float)
                                            for c, v in curve.items()})
                except ValueError as exc:
                    raise RunFailure(f"step {rep.step} ({stage_at(case, rep.time)} stage, t = "
                                     f"{rep.time:.6g} s): {exc} (not written)") from exc
                with _writing(ckpt_path):
                    save_checkpoint(ckpt_path, integ, checkpoint_extra(
                        rep.step, done, pvd, unconverged, worst, case_yaml))
            if rep.step % every == 0 or done:
                stage = stage_at(case, rep.time)
                log(f"[{stage:10s}] step {rep.step:6d}/{n_est} t {rep.time:7.4f} s  "
                    f"Ux {1e3 * ux:8.4f} mm  Fx {1e-3 * top[0]:9.3f} kN  "
                    f"Fy {1e-3 * top[1]:9.3f} kN  sweeps {rep.sweeps:6d}  res {rep.residual:.2e}")
            if done:
                break
    except RunFailure as exc:
        with contextlib.suppress(RunOutputError):
            log(f"failed: {exc}", show=False)
        if not isinstance(exc, RunOutputError):  # the summary of what was computed
            from masonry_nscd.report import report_run

            report_run(outdir, log, curve)  # never raises
        raise
    except KeyboardInterrupt:
        with contextlib.suppress(RunOutputError):
            log(f"interrupted at step {integ.step_index}: results kept up to the last output "
                f"step (resume with: masonry run --resume {outdir})")
        from masonry_nscd.report import report_run

        report_run(outdir, log, curve)
        raise
    finally:
        with contextlib.suppress(RunOutputError, OSError):
            flush_rows()  # complete rows of the steps after the last output step, if any
        with contextlib.suppress(OSError):
            f_csv.close()
        if h5 is not None:
            h5.close()
    secs = time.perf_counter() - t_start
    log(f"done: {integ.step_index} steps in {secs:.1f} s, Ux {1e3 * ux:.4f} mm, "
        f"Fx {1e-3 * top[0]:.3f} kN; {unconverged} steps not converged "
        f"(worst residual {worst:.2e})")
    from masonry_nscd.report import report_run

    report_run(outdir, log)
    logf.close()
    return RunResult(integ.step_index, 1e3 * ux, 1e-3 * top[0], secs, unconverged, outdir,
                     stopped)
