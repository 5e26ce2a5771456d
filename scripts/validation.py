"""Run the benchmarks of docs/validation.md, redraw its figures and print what they measure.

    python scripts/validation.py [-o results/validation] [--figures docs/figures]
                                 [--full] [--only NAME,NAME,...] [--list]

Each benchmark runs its cases with the project's own commands (``masonry run``, ``threshold``,
``limit``, ``point``, ``plot``) into ``OUTDIR/<benchmark>/``, copies the figures the report
shows into ``--figures``, and adds rows to a table: benchmark, quantity, measured value,
reference, relative error, where the reference comes from, and the run time of the benchmark
(wall clock of its commands, start-up and compilation included). The table is printed as each
benchmark ends and written to ``OUTDIR/validation.csv``.

The references are those of the report: a closed form, the limit analysis computed here by
``masonry limit`` or by the tests, the study's 71 kN/mm, or, for a benchmark with no
independent reference, the case's record (``cases/record/NAME.csv``: the largest |F_x| of the
curve), which makes the row a regression check and says so.

By default every benchmark runs but the nave bay (two runs of about 2 and 5 minutes on a quiet
2-core machine); ``--full`` adds it. A benchmark whose command fails is reported as failed and
the others go on; the exit code is 1 if one failed.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "cases"
RECORD = CASES / "record"
NO_VTU = ("output.vtu=false",)  # the damage maps and mechanisms read results.h5, not the VTU

# References named in docs/validation.md (source in the table's last column).
STUDY_STIFFNESS_KN_MM = 71.0  # the study's initial stiffness, every stress (model.md)
ARCH_LIMIT_THICKNESS = 0.10710  # t/R, limit analysis of the 24 chord voussoirs (tests/test_arch.py)
ARCH_LIMIT_LAMBDA = 0.146722764  # kinematic enumeration of four-hinge mechanisms (tests/test_limit.py)
JOINT_PEAK_MPA = 0.4586  # model.md: joint point sliding under -0.5 MPa, mu 0.7
JOINT_RESIDUAL_MPA = 0.35  # the same, once the cohesion is gone: mu |sigma_n|
BLOCK_TENSION_PEAK_MPA = 1.000  # model.md: R_t
BLOCK_COMPRESSION_PEAK_MPA = 9.46  # model.md: R_c, reached at the strain eps_pic_c = 0.013
BLOCK_COMPRESSION_AT_2E2_MPA = 8.209  # model.md: the post-peak law as specified, at strain 0.02
DRY_WALL_WEIGHT_KN = 3.61  # the dry stone wall above its first course (docs/validation.md)
GROUND_MOTION_FRICTION_KN = 0.7 * (27.75 + 5.8)  # mu (N + W): top load and the wall's weight


@dataclass
class Row:
    benchmark: str
    quantity: str
    measured: float | str
    reference: float | str
    source: str
    seconds: float = math.nan

    @property
    def error(self) -> float:
        if isinstance(self.measured, str) or isinstance(self.reference, str):
            return math.nan
        if not self.reference or math.isnan(self.measured):
            return math.nan
        return (self.measured - self.reference) / abs(self.reference)


@dataclass
class Context:
    outdir: Path
    figures: Path
    masonry: list[str]
    done: dict[str, dict]  # runs made by this invocation, shared by the benchmarks
    seconds: float = 0.0
    drawn: list[Path] = field(default_factory=list)

    def command(self, argv: list[str], log: Path) -> None:
        """Run ``argv``; its output goes to ``log``; RuntimeError if it fails."""
        log.parent.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        with open(log, "w") as out:
            proc = subprocess.run(argv, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT,
                                  check=False)
        self.seconds += time.perf_counter() - t0
        if proc.returncode != 0:
            tail = log.read_text().strip().splitlines()[-3:]
            raise RuntimeError(f"{' '.join(argv)} exited with {proc.returncode}: "
                               + " / ".join(tail))

    def masonry_cmd(self, *args: str, log: Path) -> None:
        self.command([*self.masonry, *args], log)

    def run(self, bench: str, case: str, name: str | None = None,
            sets: tuple[str, ...] = ()) -> dict:
        """``masonry run cases/CASE.yaml`` into OUTDIR/runs/NAME (once per invocation: a run
        that another benchmark made is read again); returns its summary."""
        name = name or case
        out = self.outdir / "runs" / name
        if name not in self.done:
            args = ["run", str(CASES / f"{case}.yaml"), "-o", str(out), "--overwrite"]
            for s in (*NO_VTU, *sets):
                args += ["--set", s]
            self.masonry_cmd(*args, log=self.outdir / "runs" / f"{name}.log")
            self.done[name] = json.loads((out / "summary.json").read_text())
        return self.done[name]

    def plot(self, bench: str, runs: list[str], name: str, at: list[float] | None = None
             ) -> list[Path]:
        """``masonry plot`` of runs (OUTDIR/runs/RUN) into OUTDIR/BENCH/plots_NAME."""
        out = self.outdir / bench / f"plots_{name}"
        if out.exists():
            shutil.rmtree(out)
        args = ["plot", *(str(self.outdir / "runs" / r) for r in runs), "-o", str(out)]
        if at:
            args += ["--at", ",".join(f"{v:.4f}" for v in at)]
        self.masonry_cmd(*args, log=self.outdir / bench / f"plots_{name}.log")
        return sorted(out.glob("*.png"))

    def figure(self, source: Path, target: str) -> None:
        """Copy a drawn PNG to the report's figures."""
        self.figures.mkdir(parents=True, exist_ok=True)
        dest = self.figures / target
        shutil.copyfile(source, dest)
        self.drawn.append(dest)


def damage_maps(pngs: list[Path]) -> list[Path]:
    """The damage maps among ``pngs``, in the order of their U_x (the number in the name)."""
    maps = [p for p in pngs if p.name.startswith("damage_")]
    return sorted(maps, key=lambda p: float(re.search(r"_ux_(-?[0-9.]+)mm", p.name).group(1)))


def one(pngs: list[Path], prefix: str) -> Path:
    found = [p for p in pngs if p.name.startswith(prefix)]
    if len(found) != 1:
        raise RuntimeError(f"expected one {prefix}*.png, found {[p.name for p in pngs]}")
    return found[0]


def record_peak(case: str) -> float:
    """The largest |F_x| of the case's record (kN)."""
    with open(RECORD / f"{case}.csv") as f:
        return max(abs(float(r["fx_kN"])) for r in csv.DictReader(f))


def onset_factor(summary: dict) -> float:
    """The growing load's factor at the onset of collapse (NaN if the structure stood)."""
    c = summary.get("collapse") or {}
    loads = c.get("loads_at_onset") or {}
    return float(next(iter(loads.values()))) if loads else math.nan


def limit_multiplier(ctx: Context, bench: str, case: str, flow: str = "associative") -> float:
    out = ctx.outdir / bench / f"limit_{flow}"
    ctx.masonry_cmd("limit", str(CASES / f"{case}.yaml"), "-o", str(out), "--overwrite",
                    "--flow", flow, log=ctx.outdir / bench / f"limit_{flow}.log")
    return float(json.loads((out / "limit.json").read_text())["multiplier"]["value"])


def curve_column(run_dir: Path, column: str) -> list[float]:
    with open(run_dir / "force_displacement.csv") as f:
        return [float(r[column]) for r in csv.DictReader(f) if r[column] not in ("", "nan")]


# --- the benchmarks ------------------------------------------------------------------------

def study_walls(ctx: Context, b: str) -> list[Row]:
    rows = []
    for stress in ("0.3", "0.4", "0.5"):
        case = f"wall_{stress}MPa"
        s = ctx.run(b, case)
        rows += [Row(b, f"{stress} MPa stiffness (kN/mm)", s["initial_stiffness_kN_mm"],
                     STUDY_STIFFNESS_KN_MM, "study (model.md)"),
                 Row(b, f"{stress} MPa peak (kN)", s["peak_force_kN"], record_peak(case),
                     "record (regression)"),
                 Row(b, f"{stress} MPa mode at 10 mm", s["failure_mode"]["mode"]
                     if isinstance(s.get("failure_mode"), dict) else str(s.get("failure_mode")),
                     *(("base sliding", "study, low stress") if stress == "0.3" else
                       ("stair-step + toe crushing", "study, high stress")))]
        pngs = ctx.plot(b, [case], case, [s["ux_at_peak_mm"], s["last_ux_mm"]])
        peak, end = damage_maps(pngs)
        ctx.figure(peak, f"damage_{stress}MPa_refined_peak.png")
        ctx.figure(end, f"damage_{stress}MPa_refined_10mm.png")
    s = ctx.run(b, "wall_0.5MPa_elastic")
    rows += [Row(b, "0.5 MPa elastic stiffness (kN/mm)", s["initial_stiffness_kN_mm"],
                 STUDY_STIFFNESS_KN_MM, "study (model.md)"),
             Row(b, "0.5 MPa elastic peak (kN)", s["peak_force_kN"],
                 record_peak("wall_0.5MPa_elastic"), "record (regression)")]
    pngs = ctx.plot(b, ["wall_0.5MPa_elastic"], "elastic", [s["last_ux_mm"]])
    ctx.figure(damage_maps(pngs)[-1], "damage_0.5MPa_elastic_10mm.png")
    pngs = ctx.plot(b, ["wall_0.3MPa", "wall_0.4MPa", "wall_0.5MPa", "wall_0.5MPa_elastic"],
                    "curves", [])
    ctx.figure(one(pngs, "force_displacement"), "force_displacement_3_stresses_refined.png")
    return rows


def base_sliding(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "wall_0.3MPa_base_sliding")
    ref = ctx.run(b, "wall_0.3MPa")
    mode = s["failure_mode"]["mode"] if isinstance(s.get("failure_mode"), dict) \
        else str(s.get("failure_mode"))
    pngs = ctx.plot(b, ["wall_0.3MPa_base_sliding"], "weak", [s["last_ux_mm"]])
    ctx.figure(damage_maps(pngs)[-1], "damage_0.3MPa_weak_base_10mm.png")
    pngs = ctx.plot(b, ["wall_0.3MPa", "wall_0.3MPa_base_sliding"], "curves", [])
    ctx.figure(one(pngs, "force_displacement"), "force_displacement_weak_base.png")
    return [Row(b, "mode at 10 mm", mode, "base sliding", "study, low stress"),
            Row(b, "peak (kN)", s["peak_force_kN"], record_peak("wall_0.3MPa_base_sliding"),
                "record (regression)"),
            Row(b, "peak / the case's peak", s["peak_force_kN"] / ref["peak_force_kN"], 1.0,
                "wall_0.3MPa")]


def cyclic(ctx: Context, b: str) -> list[Row]:
    push = ctx.run(b, "wall_0.5MPa_elastic")
    s = ctx.run(b, "wall_0.5MPa_cyclic")
    fx = curve_column(ctx.outdir / "runs" / "wall_0.5MPa_cyclic", "fx_kN")
    pngs = ctx.plot(b, ["wall_0.5MPa_cyclic"], "cycles", [])
    ctx.figure(one(pngs, "cycles_"), "cycles_0.5MPa_elastic.png")
    pngs = ctx.plot(b, ["wall_0.5MPa_cyclic", "wall_0.5MPa_elastic"], "curves", [])
    ctx.figure(one(pngs, "force_displacement"), "force_displacement_0.5MPa_cyclic_and_monotonic.png")
    return [Row(b, "largest F+ (kN)", max(fx), push["peak_force_kN"], "the push's peak"),
            Row(b, "largest |F-| (kN)", -min(fx), max(fx), "F+ (symmetry)"),
            Row(b, "unconverged steps", s["unconverged_steps"], 0, "")]


def dry_stone(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "dry_stone_wall")
    n_kN = s["vertical_force_kN"]
    bound = (n_kN + DRY_WALL_WEIGHT_KN) * 0.5 / 0.9
    pngs = ctx.plot(b, ["dry_stone_wall"], "curves", [])
    ctx.figure(one(pngs, "force_displacement"), "force_displacement_dry_stone_wall.png")
    return [Row(b, "largest F_x (kN)", s["peak_force_kN"], bound, "rigid overturning bound")]


def window_brick(ctx: Context, b: str) -> list[Row]:
    w = ctx.run(b, "wall_window")
    k = ctx.run(b, "brick_wall_pattern")
    pngs = ctx.plot(b, ["wall_window"], "window", [w["last_ux_mm"]])
    ctx.figure(damage_maps(pngs)[-1], "damage_wall_window_10mm.png")
    pngs = ctx.plot(b, ["brick_wall_pattern"], "brick", [k["last_ux_mm"]])
    ctx.figure(damage_maps(pngs)[-1], "damage_brick_wall_pattern_4mm.png")
    pngs = ctx.plot(b, ["wall_window", "brick_wall_pattern"], "curves", [])
    ctx.figure(one(pngs, "force_displacement"), "force_displacement_window_and_brick.png")
    return [Row(b, "window wall peak (kN)", w["peak_force_kN"], record_peak("wall_window"),
                "record (regression)"),
            Row(b, "brick wall peak (kN)", k["peak_force_kN"],
                record_peak("brick_wall_pattern"), "record (regression)")]


def ground_motion(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "wall_ground_motion")
    pngs = ctx.plot(b, ["wall_ground_motion"], "gm", [])
    ctx.figure(one(pngs, "ground_motion_"), "ground_motion_wall.png")
    return [Row(b, "peak base shear (kN)", abs(s["peak_base_shear_kN"]),
                GROUND_MOTION_FRICTION_KN, "mu (N + W)"),
            Row(b, "energy imbalance (relative)", s["energy_worst_relative_imbalance"], 0.0,
                "balance (< 1e-6)")]


def arch(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "arch_semicircular")
    pngs = ctx.plot(b, ["arch_semicircular"], "body_force", [])
    ctx.figure(one(pngs, "mechanism_"), "arch_mechanism_body_force.png")
    ctx.run(b, "arch_semicircular", "self_weight_thin",
            ("arch.thickness_m=0.0964", "loading.body_force.rate_per_s=0",
             "collapse.end_time_s=2"))
    pngs = ctx.plot(b, ["self_weight_thin"], "self_weight", [])
    ctx.figure(one(pngs, "mechanism_"), "arch_mechanism_self_weight.png")
    out = ctx.outdir / b / "threshold"
    ctx.masonry_cmd("threshold", str(CASES / "arch_semicircular.yaml"), "--param",
                    "arch.thickness_m", "--bounds", "0.09:0.13", "-o", str(out), "--overwrite",
                    "--set", "loading.body_force.rate_per_s=0", "--set",
                    "collapse.end_time_s=2", log=ctx.outdir / b / "threshold.log")
    t = json.loads((out / "threshold.json").read_text())
    lam = limit_multiplier(ctx, b, "arch_semicircular")
    return [Row(b, "minimum t/R (NSCD threshold)", float(t["value"]), ARCH_LIMIT_THICKNESS,
                "limit analysis, 24 voussoirs"),
            Row(b, "lambda at the onset (NSCD)", onset_factor(s), ARCH_LIMIT_LAMBDA,
                "kinematic theorem"),
            Row(b, "lambda (masonry limit)", lam, ARCH_LIMIT_LAMBDA, "kinematic theorem")]


def vault(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "vault_barrel")
    pngs = ctx.plot(b, ["vault_barrel"], "body_force", [])
    ctx.figure(one(pngs, "mechanism_"), "vault_mechanism_body_force.png")
    lam = limit_multiplier(ctx, b, "vault_barrel", "non-associative")
    return [Row(b, "lambda at the onset (NSCD)", onset_factor(s), ARCH_LIMIT_LAMBDA,
                "the arch, kinematic theorem"),
            Row(b, "lambda at the onset (NSCD)", onset_factor(s), lam,
                "masonry limit, non-associative")]


def limit_state(case: str, figure: str, flow: str) -> Callable[[Context, str], list[Row]]:
    def bench(ctx: Context, b: str) -> list[Row]:
        s = ctx.run(b, case)
        pngs = ctx.plot(b, [case], "mechanism", [])
        ctx.figure(one(pngs, "mechanism_"), figure)
        lam = limit_multiplier(ctx, b, case, flow)
        return [Row(b, "lambda at the onset (NSCD)", onset_factor(s), lam,
                    f"masonry limit, {flow}")]
    return bench


def nave_bay(ctx: Context, b: str) -> list[Row]:
    s = ctx.run(b, "nave_bay")
    sp = ctx.run(b, "nave_bay_spreading")
    out = ctx.outdir / b / "nave_bay_sections.png"
    ctx.command([sys.executable, str(CASES / "plot_nave_bay.py"),
                 str(ctx.outdir / "runs" / "nave_bay_spreading"), "-o", str(out)],
                log=ctx.outdir / b / "sections.log")
    ctx.figure(out, "nave_bay_spreading_sections.png")
    hinges = len(sp.get("hinges") or [])
    return [Row(b, "lambda at the onset", onset_factor(s), 0.1600, "record"),
            Row(b, "spreading: status", str(sp.get("status")), "standing", "record"),
            Row(b, "spreading: hinges", hinges, 132, "record")]


def material_points(ctx: Context, b: str) -> list[Row]:
    case = str(CASES / "wall_0.5MPa.yaml")
    joint = ctx.outdir / b / "joint_sliding.csv"
    ctx.masonry_cmd("point", "joint", case, "--path", "sliding", "--normal-stress", "-0.5e6",
                    "--to", "0.005", "-o", str(joint), log=ctx.outdir / b / "joint.log")
    with open(joint) as f:
        tt = [abs(float(r["T_t_Pa"])) / 1e6 for r in csv.DictReader(f)]
    rows = [Row(b, "joint, -0.5 MPa: peak shear (MPa)", max(tt), JOINT_PEAK_MPA, "model.md"),
            Row(b, "joint, -0.5 MPa: residual (MPa)", tt[-1], JOINT_RESIDUAL_MPA,
                "mu |sigma_n|")]
    for path, to, in (("tension", "2e-4"), ("compression", "0.02")):
        out = ctx.outdir / b / f"block_{path}.csv"
        ctx.masonry_cmd("point", "block", case, "--path", path, "--to", to, "-o", str(out),
                        "--steps", "400", "--set", "blocks.endo3d.crushing_length_m=0",
                        log=ctx.outdir / b / f"block_{path}.log")
        with open(out) as f:
            sig = [float(r["sigma_axial_Pa"]) / 1e6 for r in csv.DictReader(f)]
        if path == "tension":
            rows.append(Row(b, "block: tensile peak (MPa)", max(sig), BLOCK_TENSION_PEAK_MPA,
                            "R_t"))
        else:
            rows += [Row(b, "block: compressive peak (MPa)", -min(sig),
                         BLOCK_COMPRESSION_PEAK_MPA, "R_c"),
                     Row(b, "block: stress at strain 0.02 (MPa)", -sig[-1],
                         BLOCK_COMPRESSION_AT_2E2_MPA, "model.md, post-peak law")]
    return rows


BENCHMARKS: dict[str, Callable[[Context, str], list[Row]]] = {
    "material_points": material_points,
    "study_walls": study_walls,
    "base_sliding": base_sliding,
    "cyclic": cyclic,
    "dry_stone_wall": dry_stone,
    "window_and_brick": window_brick,
    "ground_motion": ground_motion,
    "arch": arch,
    "vault": vault,
    "pier_arches": limit_state("pier_arches", "assembly_pier_arches_mechanism.png",
                               "associative"),
    "cross_vault": limit_state("cross_vault", "cross_vault_mechanism_body_force.png",
                               "non-associative"),
    "dome": limit_state("dome_hemispherical", "dome_mechanism_body_force.png",
                        "non-associative"),
    "nave_bay": nave_bay,
}
SLOW = ("nave_bay",)  # only with --full


def cell(v: float | str, digits: int = 5) -> str:
    if isinstance(v, str):
        return v
    if isinstance(v, int):
        return str(v)
    return "" if math.isnan(v) else f"{v:.{digits}g}"


def print_rows(rows: list[Row]) -> None:
    for r in rows:
        err = "" if math.isnan(r.error) else f"{100 * r.error:+.2f} %"
        print(f"{r.benchmark:<17} {r.quantity:<36} {cell(r.measured):>26} "
              f"{cell(r.reference):>26} {err:>9}  {r.source:<30} {cell(r.seconds, 4):>6}",
              flush=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("-o", "--output", type=Path, default=ROOT / "results" / "validation")
    p.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures")
    p.add_argument("--full", action="store_true", help="also the slow benchmarks (nave bay)")
    p.add_argument("--only", default="", help="benchmarks to run, separated by commas")
    p.add_argument("--list", action="store_true", help="list the benchmarks and stop")
    args = p.parse_args(argv)
    if args.list:
        for name in BENCHMARKS:
            print(name + (" (--full)" if name in SLOW else ""))
        return 0
    names = [n for n in args.only.split(",") if n] or \
        [n for n in BENCHMARKS if args.full or n not in SLOW]
    unknown = [n for n in names if n not in BENCHMARKS]
    if unknown:
        p.error(f"unknown benchmarks {unknown}; --list lists them")
    script = Path(sys.executable).with_name("masonry")
    masonry = [str(script)] if script.exists() else [sys.executable, "-m", "masonry_nscd.cli"]
    args.output.mkdir(parents=True, exist_ok=True)
    done: dict[str, dict] = {}
    all_rows: list[Row] = []
    failed: list[str] = []
    t_all = time.perf_counter()
    print(f"{'benchmark':<17} {'quantity':<36} {'measured':>26} {'reference':>26} "
          f"{'error':>9}  {'reference from':<30} {'run s':>6}", flush=True)
    for name in names:
        ctx = Context(args.output, args.figures, masonry, done)
        try:
            rows = BENCHMARKS[name](ctx, name)
        except (RuntimeError, OSError, KeyError, ValueError, TypeError) as exc:
            failed.append(name)
            rows = [Row(name, "FAILED", str(exc)[:200], "", "")]
        for r in rows:
            r.seconds = ctx.seconds
        print_rows(rows)
        for path in ctx.drawn:
            print(f"{'':<17} drew {path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}",
                  flush=True)
        all_rows += rows
        with open(args.output / "validation.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["benchmark", "quantity", "measured", "reference", "error",
                        "reference_from", "benchmark_s"])
            for r in all_rows:
                w.writerow([r.benchmark, r.quantity, cell(r.measured, 8), cell(r.reference, 8),
                            cell(r.error, 4), r.source, cell(r.seconds, 5)])
    total = time.perf_counter() - t_all
    print(f"{len(names)} benchmarks in {total:.0f} s ({total / 60:.1f} min); "
          f"{len(failed)} failed{': ' + ', '.join(failed) if failed else ''}; "
          f"table in {args.output / 'validation.csv'}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
