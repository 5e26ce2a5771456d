"""Stress test of the simulator: a matrix of variants of a small wall, each run to its end.

Every variant is the base case (``cases/smoke.yaml`` by default) with a few fields overridden
(the ``--set`` syntax of the CLI): the time step from 10 times smaller to 10 times larger,
theta from 0.5 to 1, the block modulus from 1e8 to 1e11 Pa, the joint springs from 1e9 to
1e13 Pa/m, the vertical stress from 0 to 5 MPa, friction from 0 to 1.2, virgin and fully
broken joints, one course, a tall slender wall, rigid blocks, and ENDO3D blocks driven far past
the peak. Each one is a point of the study (:func:`masonry_nscd.studies.point.run_point`) run
into its own folder under a wall-clock limit.

Outcome of a variant (``ACCEPTABLE`` ones are what the simulator promises), judged from the
run's record: ``failed``, ``timeout`` and ``error`` are its status (a variant the scene refuses
is an ``error`` too: the variants are the test's own input); a finished run is then judged:

``ok``
    finished; every value of the CSV and of results.h5 finite; every step converged; the wall
    in equilibrium at the end (below);
``failed``
    stopped by a :class:`~masonry_nscd.run.RunFailure` whose message names the step, the stage
    and the cause (a clean failure, exit code 1 of ``masonry run``);
``not_converged``
    finished, but some steps ended above the solver tolerance;
``imbalance``
    finished, but the beams' forces on the wall do not balance its weight (below);
``non_finite``
    a NaN or an infinity reached an output file;
``timeout``
    stopped after ``time_limit_s`` of wall-clock time;
``error``
    an exception other than RunFailure (a bug; its type and message are reported).

Equilibrium is the balance of the wall's momentum between the last two output steps k1 < k2
(the internal forces of the wall cancel, the contact forces of a step are its impulses over h):

    P(k2) - P(k1) = sum_{n = k1+1..k2} h (F_n + F_b,n + W),        P = sum_i m_i v_i  (N s)

with ``F``/``F_b`` the forces of the upper and lower beams on the wall, ``W`` its weight and
``m_i``, ``v_i`` the (lumped) masses and velocities of the wall's nodes, or of its rigid units.
The error is the worst of x and y of ``|lhs - rhs| / (h (k2 - k1) max(|F|, |F_b|, W))``
(dimensionless); it must not exceed ``EQUILIBRIUM_TOLERANCE``. A static check (F + F_b + W =
0) would flag the inertia of a wall that vibrates under fast loading (the soft-spring variant
bounces on its joints at 1.7 % of the load): that is dynamics, not an error.

``stress.csv`` (rewritten after every variant): ``case,outcome,steps,worst_residual,
unconverged_steps,equilibrium_error,time_s,message``.
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections.abc import Callable
from dataclasses import astuple, dataclass, fields
from pathlib import Path

import numpy as np

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.io.results_h5 import read_results, read_step_field
from masonry_nscd.io.runfolder import read_curve_csv
from masonry_nscd.model import body_mass, body_momentum, dof_offsets
from masonry_nscd.scenes import build_scene
from masonry_nscd.studies.point import ERROR, FAILED, TIMEOUT, as_error, run_point

EQUILIBRIUM_TOLERANCE = 1e-2
ACCEPTABLE = ("ok", "failed")
DEFAULT_BASE = Path(__file__).resolve().parents[2] / "cases" / "smoke.yaml"


@dataclass(frozen=True)
class Variant:
    """One case of the matrix: ``overrides(base) -> ["path=value", ...]``."""

    name: str
    description: str
    overrides: Callable[[object], list[str]]
    quick: bool = False  # part of the quick subset (each a few seconds on the smoke wall)


def _springs(k: float) -> Callable[[object], list[str]]:
    return lambda base: [f"joint.K_I_spring_Pa_m={k:g}", f"joint.K_II_spring_Pa_m={k:g}"]


def _set(*items: str) -> Callable[[object], list[str]]:
    return lambda base: list(items)


def _time_step(factor: float) -> Callable[[object], list[str]]:
    """The time step times ``factor``, with the outputs at about the same times."""
    return lambda base: [f"solver.time_step_s={base.solver.time_step_s * factor!r}",
                         f"output.every_steps={max(1, round(base.output.every_steps / factor))}"]


VARIANTS: tuple[Variant, ...] = (
    Variant("reference", "the base case as it is", _set(), quick=True),
    Variant("time_step_x0.1", "time step 10 times smaller", _time_step(0.1)),
    Variant("time_step_x0.3", "time step 3 times smaller", _time_step(0.3)),
    Variant("time_step_x3", "time step 3 times larger", _time_step(3.0), quick=True),
    Variant("time_step_x10", "time step 10 times larger", _time_step(10.0), quick=True),
    Variant("theta_0.5", "theta 0.5 (trapezoidal rule)", _set("solver.theta=0.5"), quick=True),
    Variant("theta_0.75", "theta 0.75", _set("solver.theta=0.75")),
    Variant("block_E_1e8", "block modulus 1e8 Pa", _set("blocks.E_Pa=1e8"), quick=True),
    Variant("block_E_1e11", "block modulus 1e11 Pa", _set("blocks.E_Pa=1e11")),
    Variant("spring_1e9", "joint springs 1e9 Pa/m", _springs(1e9), quick=True),
    Variant("spring_1e11", "joint springs 1e11 Pa/m", _springs(1e11)),
    Variant("spring_1e13", "joint springs 1e13 Pa/m", _springs(1e13)),
    Variant("stress_0", "no vertical stress", _set("loading.vertical_stress.value_Pa=0")),
    Variant("stress_5MPa", "vertical stress 5 MPa",
            _set("loading.vertical_stress.value_Pa=5e6"), quick=True),
    Variant("friction_0", "friction coefficient 0", _set("joint.mu=0"), quick=True),
    Variant("friction_1.2", "friction coefficient 1.2", _set("joint.mu=1.2")),
    Variant("joints_virgin", "no initial joint damage", _set("joint.d_coh_initial=0")),
    Variant("joints_broken", "joints fully broken (d_coh,0 = 1 - 1e-9)",
            _set("joint.d_coh_initial=0.999999999"), quick=True),
    Variant("one_course", "a single course", _set("wall.courses=1"), quick=True),
    Variant("slender", "a tall slender wall: one unit per course, 10 courses",
            _set("wall.units_per_course=1", "wall.courses=10"), quick=True),
    Variant("rigid_blocks", "rigid blocks", _set("blocks.material=rigid"), quick=True),
    Variant("endo3d_past_peak", "ENDO3D blocks driven to 3 mm, far past the peak",
            _set("blocks.material=endo3d", "loading.horizontal.target_m=3e-3",
                 "loading.horizontal.rate_m_s=0.05")),
)


@dataclass
class StressResult:
    """One row of ``stress.csv`` (SI units; forces in kN in the message)."""

    case: str
    outcome: str
    steps: int
    worst_residual: float  # largest solver residual of a step (dimensionless)
    unconverged_steps: int
    equilibrium_error: float  # see the module docstring (dimensionless), NaN if not finished
    time_s: float  # wall-clock time of the run
    message: str

    @property
    def acceptable(self) -> bool:
        return self.outcome in ACCEPTABLE


def select(quick: bool = False, names: list[str] | None = None) -> list[Variant]:
    """The variants to run: all, the quick subset, or those named (ValueError if unknown)."""
    if names:
        known = {v.name: v for v in VARIANTS}
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValueError(f"unknown variant(s) {', '.join(unknown)}; known: "
                             f"{', '.join(known)}")
        return [known[n] for n in names]
    return [v for v in VARIANTS if v.quick or not quick]


def _read_curve(path: Path) -> dict[str, np.ndarray]:
    """The CSV's columns, or none where the run wrote no row."""
    curve = read_curve_csv(path)
    return curve if len(curve.get("step", ())) else {}


def _non_finite_outputs(outdir: Path) -> str | None:
    """Where a NaN or an infinity sits in the CSV or results.h5 of a run, or None."""
    curve = _read_curve(outdir / rf.CSV)
    for k, v in curve.items():
        if not np.isfinite(v).all():
            return f"{rf.CSV} column {k}"
    h5 = outdir / rf.RESULTS
    if h5.exists():
        res = read_results(h5)
        arrays = [("curve/" + k, v) for k, v in res["curve"].items()]
        arrays += [(f"steps/{s.step}/{k}", v) for s in res["steps"] for k, v in s.fields.items()]
        for name, v in arrays:
            if v.dtype.kind == "f" and not np.isfinite(v).all():
                return f"{rf.RESULTS} {name}"
    return None


def wall_weight_kN(scene, gravity_m_s2: float) -> float:
    """Weight of the structure of a scene (its units, kN)."""
    mass = sum(body_mass(scene.bodies[i]) for i in scene.structure)
    return mass * gravity_m_s2 / 1e3


def equilibrium_error(curve: dict[str, np.ndarray], weight_kN: float, h_s: float,
                      steps: tuple[int, int], momentum_Ns: tuple[np.ndarray, np.ndarray]) -> float:
    """Relative error of the wall's momentum balance between output steps ``steps = (k1, k2)``
    (module docstring); ``momentum_Ns``: the wall's momentum (x, y) at both, N s. NaN for a
    curve without those steps."""
    k1, k2 = steps
    if "step" not in curve or k2 <= k1:
        return math.nan
    window = (curve["step"] > k1) & (curve["step"] <= k2)
    if int(window.sum()) != k2 - k1:
        return math.nan
    fx, fy = curve["fx_kN"][window], curve["fy_kN"][window]
    fxb, fyb = curve["fx_bottom_kN"][window], curve["fy_bottom_kN"][window]
    impulse = 1e3 * h_s * np.array([np.sum(fx + fxb), np.sum(fy + fyb - weight_kN)])
    change = np.asarray(momentum_Ns[1]) - np.asarray(momentum_Ns[0])
    scale = 1e3 * h_s * (k2 - k1) * max(np.abs(np.concatenate([fx, fy, fxb, fyb])).max(),
                                        weight_kN, 1e-9)
    return float(np.abs(change - impulse).max() / scale)


def wall_momentum(scene, outdir: Path) -> tuple[tuple[int, int], tuple[np.ndarray, ...]] | None:
    """The last two output steps of results.h5 and the momentum (x, y) of the scene's
    structure at each, N s; None without two output steps."""
    last = read_step_field(outdir / rf.RESULTS, "v", last=2)
    if len(last) < 2:
        return None
    names, vs = [k for k, _ in last], [np.asarray(v) for _, v in last]
    dof0 = dof_offsets(scene.bodies)
    out = []
    for v in vs:
        p = sum(body_momentum(scene.bodies[i], v[dof0[i]:dof0[i + 1]]) for i in scene.structure)
        out.append(np.asarray(p)[:2])
    return (int(names[-2]), int(names[-1])), tuple(out)


def run_variant(base_path: Path, variant: Variant, outdir: Path,
                time_limit_s: float = 600.0) -> StressResult:
    """Run one variant into ``outdir`` (replaced if it exists) and judge its outcome."""
    base = load_case(base_path)
    t0 = time.perf_counter()

    def result(outcome: str, message: str, steps: int = 0, worst: float = math.nan,
               unconverged: int = 0, eq: float = math.nan) -> StressResult:
        return StressResult(variant.name, outcome, steps, worst, unconverged, eq,
                            time.perf_counter() - t0, message)

    try:
        case = load_case(base_path, variant.overrides(base) + [f"name={variant.name}"])
    except CaseError as exc:
        return result("error", "invalid variant: " + "; ".join(exc.messages))
    rec = run_point(case, outdir, overwrite=True, time_limit_s=time_limit_s)
    status, message = as_error(rec)
    if status == FAILED:
        curve = _read_curve(outdir / rf.CSV)
        return result("failed", message, len(curve.get("step", ())),
                      float(np.max(curve["residual"], initial=0.0)) if curve else math.nan)
    if status == ERROR:  # a bug of the simulator, reported as such
        return result("error", message)
    curve = _read_curve(outdir / rf.CSV)
    worst = float(np.max(curve["residual"], initial=0.0)) if curve else math.nan
    scene = build_scene(case)
    mom = wall_momentum(scene, outdir) if case.output.hdf5 else None
    eq = (equilibrium_error(curve, wall_weight_kN(scene, case.loading.gravity.value_m_s2),
                            case.solver.time_step_s, *mom) if mom is not None else math.nan)
    bad = _non_finite_outputs(outdir)
    args = {"steps": rec.steps, "worst": worst, "unconverged": rec.unconverged_steps, "eq": eq}
    if bad is not None:
        return result("non_finite", f"NaN or infinity in {bad}", **args)
    if status == TIMEOUT:
        return result("timeout", message, **args)
    if rec.unconverged_steps:
        k = int(np.argmax(curve["residual"]))
        return result("not_converged", f"{rec.unconverged_steps} steps above the tolerance "
                      f"{case.solver.tolerance:g}; worst residual {worst:.3g} at step "
                      f"{int(curve['step'][k])} (t = {curve['time_s'][k]:.4g} s)", **args)
    if math.isnan(eq):
        return result("imbalance", f"the momentum balance cannot be checked: {rf.RESULTS} has "
                      "fewer than two output steps", **args)
    if not eq <= EQUILIBRIUM_TOLERANCE:
        return result("imbalance", f"beam forces off balance by {eq:.3g} of the largest "
                      f"force (tolerance {EQUILIBRIUM_TOLERANCE:g})", **args)
    return result("ok", f"Ux {rec.ux_mm:.4g} mm, Fx {rec.fx_kN:.4g} kN", **args)


CSV_HEADER = [f.name for f in fields(StressResult)]


def write_table(path: Path, results: list[StressResult]) -> None:
    """Write ``stress.csv`` atomically."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_HEADER)
    for r in results:
        w.writerow([f"{v:.6g}" if isinstance(v, float) else v for v in astuple(r)])
    atomic_write(path, lambda p: Path(p).write_text(buf.getvalue(), newline=""))


def stress_test(outdir: Path, *, base: Path = DEFAULT_BASE, quick: bool = False,
                names: list[str] | None = None, time_limit_s: float = 600.0,
                echo: Callable[[str], None] = print) -> list[StressResult]:
    """Run the selected variants into ``outdir/<variant>/`` and write ``outdir/stress.csv``."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    results: list[StressResult] = []
    for v in select(quick, names):
        echo(f"{v.name}: {v.description} ...")
        r = run_variant(Path(base), v, outdir / v.name, time_limit_s)
        results.append(r)
        write_table(outdir / "stress.csv", results)
        echo(f"  {r.outcome} in {r.time_s:.1f} s, {r.steps} steps, worst residual "
             f"{r.worst_residual:.2e}: {r.message}")
    return results


def format_table(results: list[StressResult]) -> str:
    """The results as a fixed-width text table."""
    lines = [(f"{'case':18s} {'outcome':14s} {'steps':>6s} {'worst res':>9s} {'equil.':>8s} "
              f"{'time s':>7s}")]
    for r in results:
        lines.append(f"{r.case:18s} {r.outcome:14s} {r.steps:6d} {r.worst_residual:9.2e} "
                     f"{r.equilibrium_error:8.1e} {r.time_s:7.1f}")
    return "\n".join(lines)
