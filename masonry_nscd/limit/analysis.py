"""``masonry limit``: a case's scene taken as rigid blocks, its collapse multiplier and
mechanism, and the files that say them.

:func:`analyse` builds the scene with the case's builder (:func:`masonry_nscd.scenes.build_scene`),
takes it as rigid blocks (:mod:`.statics`), solves the static programme (:mod:`.lp`; with
``flow="non-associative"`` its iteration of fixed friction capacities, or with
``method="load-path"`` the load followed from rest, :mod:`.path`), and reads the
mechanism joint by joint (:mod:`.mechanism`). :func:`write_outputs` writes the folder
(:mod:`masonry_nscd.io.limit_analysis`). :func:`stands` says whether the dead loads alone can
be carried (the feasibility that :mod:`.thickness` bisects on).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from masonry_nscd.case import case_from_dict
from masonry_nscd.case.files import case_to_yaml
from masonry_nscd.case.yaml12 import read_yaml
from masonry_nscd.io import limit_analysis as files
from masonry_nscd.io import runfolder as rf
from masonry_nscd.io.results_h5 import output_steps, read_fields
from masonry_nscd.limit import friction, mechanism, thrust
from masonry_nscd.limit.lp import (
    SOLVERS,
    STARTS,
    LimitSolution,
    solve_limit,
    solve_non_associative,
)
from masonry_nscd.limit.path import follow_load
from masonry_nscd.limit.picture import draw_mechanism
from masonry_nscd.limit.statics import RigidModel, rigid_model
from masonry_nscd.post.limit import mechanism_line
from masonry_nscd.scenes import build_scene

FLOWS = ("associative", "non-associative")
#: How the non-associative multiplier is found, the default first: the iteration of fixed
#: friction capacities (:func:`.lp.solve_non_associative`) or the load followed from rest on
#: the joints' springs (:func:`.path.follow_load`).
METHODS = ("fixed-point", "load-path")
METHOD = "rigid-block limit analysis: static programme (Coulomb's cone or its pyramid), mechanism from its dual"


@dataclass
class LimitResult:
    """What :func:`analyse` found: the model, the solution, the joints and the record of
    ``limit.json``."""

    model: RigidModel
    solution: LimitSolution
    joints: list[dict[str, Any]]
    record: dict[str, Any]
    groups: tuple[str, ...]  # the scene's joint group names, by id


class RunStartError(ValueError):
    """The run a non-associative iteration was to start from cannot give its normal forces."""


def unheld(case):
    """``case`` with its growing loads not held (``hold_s`` null): a run's hold says when the
    load stops growing, and the analysis asks how far it could grow."""
    data = read_yaml(case_to_yaml(case, comments=False), case.name)  # the case as saved
    loading = data["loading"]
    held = [k for k in ("body_force", "point_load")
            if loading.get(k) is not None and loading[k].get("hold_s") is not None]
    if not held:
        return case
    for k in held:
        loading[k]["hold_s"] = None
    return case_from_dict(data)


def run_normal_forces(m: RigidModel, run_dir: Path | str, time_s: float | None = None
                      ) -> tuple[np.ndarray, dict[str, Any]]:
    """The normal forces (N, compression positive) of the points of ``m`` in an NSCD run of the
    same scene (the folder ``run_dir``, its ``results.h5``) at the output step nearest
    ``time_s`` (s; None: the last), each its traction times its area; and what was read
    (``run``, ``step``, ``time_s``). :class:`RunStartError` naming the problem when the folder
    has no results, no tractions, or its contact points are not those of ``m``."""
    h5 = Path(run_dir) / rf.RESULTS
    if not h5.is_file():
        raise RunStartError(f"{run_dir}: no {rf.RESULTS} (not the folder of a run)")
    steps = output_steps(h5)
    if not steps:
        raise RunStartError(f"{h5}: no output step written yet")
    step, at = steps[-1] if time_s is None else min(steps, key=lambda s: abs(s[1] - time_s))
    fields = read_fields(h5, step)
    assert fields is not None
    if fields.joint_T_Pa is None:
        raise RunStartError(f"{h5}: its output steps hold no joint tractions")
    x = fields.contact_points_m
    size = float(np.ptp(m.x, axis=0).max()) if m.points else 1.0
    if len(x) != m.points or float(np.abs(x - m.x).max(initial=0.0)) > 1e-9 * size:
        raise RunStartError(f"{run_dir}: its contact points are not this case's scene's "
                            f"({len(x)} points against {m.points}): a run of another case")
    N = np.maximum(-fields.joint_T_Pa[:, 0] * fields.contact_area_m2, 0.0)
    return N, {"run": str(run_dir), "step": int(step), "time_s": float(at)}


def _kind(flow: str, iteration: dict | None, method: str = METHODS[0]) -> str:
    if flow == "associative":
        return ("associative: the collapse multiplier of the normality rule (a sliding joint "
                "dilates); an upper bound of the non-associative one where sliding matters")
    if method == "load-path":
        above = ("the blocks flow (a tenth of the collapse displacement in one load step)"
                 if iteration and iteration.get("collapsed")
                 else "the solver failed (no collapse seen)")
        return ("non-associative: the load followed from rest, rigid blocks on the joints' "
                f"springs, Coulomb friction without dilatancy; the last load at rest before {above}")
    done = "converged" if iteration and iteration.get("converged") else "not converged"
    start = (iteration or {}).get("start", STARTS[0])
    origin = {"elastic": "the elastic state under the dead loads (least complementary energy, "
                         "successive Tresca bounds: Panagiotopoulos 1975)",
              "associative": "the associative solution",
              "run": "the normal forces of an NSCD run"}[start]
    return ("non-associative: fixed friction capacities (Gilbert, Casapulla and Ahmed 2006) "
            f"iterated from {origin}, proximal steps, {done}; one non-associative collapse "
            "load, not necessarily the least")


def analyse(case, *, facets: int = friction.DEFAULT_FACETS, tension: bool = False,
            flow: str = "associative", solver: str = SOLVERS[0],
            compressive_Pa: float | None = None, start: str = STARTS[0],
            run_dir: Path | str | None = None, run_time_s: float | None = None,
            method: str = METHODS[0], progress=None) -> LimitResult:
    """The limit analysis of ``case`` (module docstring); ``start``: the non-associative
    iteration's start (:data:`.lp.STARTS`; ``run``: the normal forces of the NSCD run in
    ``run_dir`` at its output step nearest ``run_time_s``, :func:`run_normal_forces`;
    :class:`RunStartError` where that run is not of this case); ``method``: how the
    non-associative multiplier is found (:data:`METHODS`; ``load-path`` has no tension and
    no compressive bound);
    ``progress``: a callable given the load path's line per load step."""
    if flow not in FLOWS:
        raise ValueError(f"flow: one of {', '.join(FLOWS)}, got {flow!r}")
    if method not in METHODS:
        raise ValueError(f"method: one of {', '.join(METHODS)}, got {method!r}")
    path = flow == "non-associative" and method == "load-path"
    if path and (tension or compressive_Pa is not None):
        raise ValueError("method load-path: the joints' springs carry no tension and crush "
                         "nowhere; leave out --tension and --compressive-strength")
    t0 = time.perf_counter()
    scene = build_scene(unheld(case))
    t1 = time.perf_counter()
    model = rigid_model(scene)
    t2 = time.perf_counter()
    iteration = None
    if path:
        sol, iteration = follow_load(model, collapse_m=case.collapse.displacement_m,
                                     progress=progress)
    elif flow == "associative":
        sol = solve_limit(model, facets, tension=tension, solver=solver,
                          compressive_Pa=compressive_Pa)
    else:
        normal, origin = (run_normal_forces(model, run_dir, run_time_s) if start == "run"
                          else (None, None))
        sol, iteration = solve_non_associative(model, facets, tension=tension, solver=solver,
                                               compressive_Pa=compressive_Pa, start=start,
                                               start_normal=normal)
        if origin is not None:
            iteration["start_run"] = origin
    info = scene.info()
    optimal = sol.status == "optimal"
    every = mechanism.joints(model, sol.point_velocity, info) if optimal else []
    # the line of thrust of the static solution (also of the dead loads alone)
    line = thrust.thrust_line(model, sol.forces, every, info.get("arch"))
    found = every if sol.multiplier is not None else []
    named = mechanism.summary(found)
    if sol.multiplier is None:
        named["mechanism"] = None
    record: dict[str, Any] = {
        "method": METHOD,
        "case": case.name,
        "status": sol.status,
        "lp_message": sol.message,
        "multiplier": {"name": model.factor, "unit": model.factor_unit,
                       "value": sol.multiplier, "kind": _kind(flow, iteration, method)},
        "flow": flow,
        "non_associative_method": method if flow == "non-associative" else None,
        "friction": ({"facets": 0, "model": "Coulomb's cone (the joints' return map)",
                      "cone_error_bound": 0.0} if path else
                     {"facets": facets,
                      "model": f"pyramid of {facets} facets, inscribed" if facets
                      else "Coulomb's cone (second-order cone)",
                      "cone_error_bound": friction.cone_error_bound(facets)}),
        "solver": None if path else solver,
        "compressive_strength_Pa": compressive_Pa,
        "tension": tension,
        **named,
        "counts": {**sol.counts, "joints": len(found)},
        "thrust_line": line,
        "times_s": {"scene": t1 - t0, "model": t2 - t1, **sol.times_s},
    }
    if model.factor is None:
        record["note"] = ("the case has no growing load (a load factor with a rate): "
                          "the programme says only whether the dead loads can be carried")
    if iteration is not None:
        record["load_path" if path else "non_associative"] = iteration
    return LimitResult(model, sol, found, record, tuple(scene.groups))


def stands(case, *, facets: int = friction.DEFAULT_FACETS, tension: bool = False,
           solver: str = SOLVERS[0]) -> bool:
    """Whether admissible forces carry the dead loads of ``case`` alone (its growing load at
    zero): the static programme is feasible."""
    model = rigid_model(build_scene(unheld(case)))
    return solve_limit(model, facets, tension=tension, dead_only=True,
                       solver=solver).status == "optimal"


def node_velocities(m: RigidModel, velocity: np.ndarray) -> list[np.ndarray]:
    """Per body, the velocity (k, 3) of each node of its mesh."""
    return [velocity[b, :3] + np.cross(velocity[b, 3:], X - m.reference[b])
            for b, (X, _) in enumerate(m.meshes)]


def write_outputs(result: LimitResult, outdir: Path | str) -> list[Path]:
    """The folder of :mod:`masonry_nscd.io.limit_analysis`; returns the paths written."""
    out = files.prepare(outdir)
    m, sol = result.model, result.solution
    nodes = node_velocities(m, sol.velocity)
    paths = [files.write_result(out, result.record),
             files.write_mechanism_vtu(out, m.meshes, nodes, m.support)]
    group_names = [result.groups[g] for g in m.group]
    paths += files.write_joint_forces(out, {
        "candidate": [m.names[a] for a in m.pair[:, 0]],
        "antagonist": [m.names[b] for b in m.pair[:, 1]],
        "group": group_names, "x": m.x, "frame": m.frame, "area": m.area,
        "forces": sol.forces, "velocity": sol.point_velocity})
    if result.record.get("thrust_line"):
        paths.append(files.write_thrust_line(out, result.record["thrust_line"]))
    value = sol.multiplier
    rec = result.record
    title = (f"{rec['case']}: {m.factor or 'multiplier'} = {value:.5g} "
             f"({rec['flow']}), {rec['mechanism']}" if value is not None
             else f"{rec['case']}: {rec['status']}")
    paths.append(draw_mechanism(out / files.MECHANISM_PNG, m.meshes, nodes, m.support, rec,
                                title))
    return paths


def _path_solver(record: dict[str, Any]) -> str:
    linear = (record.get("load_path") or {}).get("linear_solver", "SuperLU")
    return f"the load followed from rest (Newton, {linear})"


def format_result(record: dict[str, Any]) -> list[str]:
    """The lines that ``masonry limit`` prints."""
    mult = record["multiplier"]
    c, t = record["counts"], record["times_s"]
    fr = record["friction"]
    cone = (f"friction pyramid of {fr['facets']} facets (error bound "
            f"{100 * fr['cone_error_bound']:.2f} %)" if fr["facets"] else "Coulomb's cone")
    lines = [(f"{record['case']}: {c['bodies']} bodies ({c['free_bodies']} free), "
             f"{c['points']} interface points, {c['joints']} joints; {cone}, "
             f"{record.get('solver', SOLVERS[0]) or _path_solver(record)}")]
    if mult["name"] is None:
        carried = "carried" if record["status"] == "optimal" else "not carried"
        lines.append(f"dead loads: {carried} ({record['status']})")
    elif mult["value"] is None:
        lines.append(f"status: {record['status']} ({record['lp_message']})")
    else:
        unit = f" {mult['unit']}" if mult["unit"] else ""
        lines.append(f"collapse multiplier: {mult['name']} = {mult['value']:.6g}{unit} "
                     f"({record['flow']})")
        lines.append(mechanism_line(record["mechanism"], record["hinges"],
                                    record["sliding_joints"], rf.LIMIT_JSON))
    if record.get("note"):
        lines.append(f"note: {record['note']}")
    if "non_associative" in record:
        it = record["non_associative"]
        lines.append(f"non-associative iteration: {it['iterations']} steps, "
                     f"{'converged' if it['converged'] else 'not converged'}"
                     + (f" ({it['stopped_by']})" if it.get("stopped_by") else "")
                     + (f"; last {len(it['multipliers'][-5:])} multipliers within "
                        f"{it['band'][0]:.6g} to {it['band'][1]:.6g}" if it.get("band") else "")
                     + (f"; from the run {it['start_run']['run']} at t = "
                        f"{it['start_run']['time_s']:.6g} s (step {it['start_run']['step']})"
                        if it.get("start_run") else
                        f"; from the {it.get('start', STARTS[0])} state")
                     + (f"; associative multiplier {it['associative']:.6g}"
                        if it.get("associative") is not None else ""))
    if "load_path" in record:
        it = record["load_path"]
        lines.append(f"load path: {it['steps']} load steps, {it['viscous_steps']} viscous "
                     f"steps, {it['newton_iterations']} Newton iterations"
                     + (f"; collapse between {it['bracket'][0]:.6g} and {it['bracket'][1]:.6g}"
                        if it.get("bracket") else "")
                     + (f" ({it['stopped_by']})" if it.get("stopped_by") else ""))
    lines.append(f"times: scene {t['scene']:.3f} s, programme {t['assemble']:.3f} s, "
                 f"solve {t['solve']:.3f} s")
    return lines
