"""Blocks removed at a time (``loading.removal``): a hole opened in a structure.

References: the weights of rigid boxes (density x g x volume), the statics of a stack (the
ground carries the weight of what stands on it), and the arch's thrust line (an arch with its
keystone out has two free ends: no thrust line closes, it falls). What the solver must give:
the reactions to its tolerance (1e-6 relative), the same curve when a run is resumed.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
from conftest import interrupt_at
from typer.testing import CliRunner

from masonry_nscd.case import case_from_dict, load_case
from masonry_nscd.cli import app
from masonry_nscd.collapse import watch
from masonry_nscd.io.mesh_file import BlockMesh, write_block_mesh
from masonry_nscd.limit.analysis import analyse
from masonry_nscd.run import run_case
from masonry_nscd.scenes import build_scene

ROOT = Path(__file__).resolve().parents[1]
ARCH = ROOT / "cases" / "arch_semicircular.yaml"
QUIET = {"echo": lambda msg: None}
RHO, G = 2000.0, 9.81
DEPTH = 0.25
#: the stack: (name, x0, x1, y0, y1) of each box, z from 0 to DEPTH (m)
BOXES = (("ground", -0.5, 0.5, -0.2, 0.0), ("lower", -0.2, 0.2, 0.0, 0.3),
         ("upper", -0.2, 0.2, 0.3, 0.5))


def _weight(name: str, boxes=BOXES) -> float:
    """The weight (N) of a box of the stack."""
    _, x0, x1, y0, y1 = next(b for b in boxes if b[0] == name)
    return RHO * G * (x1 - x0) * (y1 - y0) * DEPTH


def stack_mesh(boxes=BOXES) -> BlockMesh:
    """The boxes one on the other, one hexahedron each (tags 1, 2, 3...)."""
    points, hexes = [], []
    for x0, x1, y0, y1 in (b[1:] for b in boxes):
        base = len(points)
        corners = [(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0),
                   (x0, y0, DEPTH), (x1, y0, DEPTH), (x1, y1, DEPTH), (x0, y1, DEPTH)]
        points += corners
        hexes.append(list(range(base, base + 8)))
    return BlockMesh(points=np.array(points), hexes=np.array(hexes, dtype=np.int64),
                     tags=np.arange(1, len(boxes) + 1),
                     names={k + 1: b[0] for k, b in enumerate(boxes)})


def stack_case(tmp_path: Path, loading: dict | None = None, end_s: float = 0.4,
               boxes=BOXES) -> dict:
    """A case of the stack on the fixed ground: rigid boxes, dry joints, gravity only."""
    write_block_mesh(tmp_path / "stack.msh", stack_mesh(boxes))
    return {"name": "stack",
            "assembly": {"mesh_file": str(tmp_path / "stack.msh"),
                         "supports": [{"group": "ground"}], "driven_block": "lower"},
            "blocks": {"material": "rigid", "density_kg_m3": RHO},
            "joint": {"law": "dry", "mu": 0.8, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11},
            "loading": {"gravity": {"value_m_s2": G, "start_s": 0.0, "ramp_s": 0.1},
                        **(loading or {})},
            "collapse": {"end_time_s": end_s},
            "solver": {"time_step_s": 0.002, "tolerance": 1e-8},
            "output": {"every_steps": 25, "vtu": False}}


def _curve(out: Path) -> dict[str, np.ndarray]:
    with open(out / "force_displacement.csv") as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def test_removing_the_top_block_drops_the_reaction_by_its_weight(tmp_path):
    """The upper box out at t = 0.2 s (on the grid of the step): the lower one stands, the
    ground carried the weight of both up to 0.2 s and that of the lower one after, exactly to
    the solver's tolerance; the summary and scene.json name the block and the time."""
    case = case_from_dict(stack_case(tmp_path, {"removal": {"blocks": ["upper"],
                                                            "time_s": 0.2}}))
    out = tmp_path / "run"
    run_case(case, out, **QUIET)
    c = _curve(out)
    fy = 1e3 * c["fy_kN"]  # the force of the ground on the stack, upwards (N)
    t = c["time_s"]
    both, lower = _weight("lower") + _weight("upper"), _weight("lower")
    before = (t > 0.15) & (t <= 0.2 + 1e-9)
    assert before.sum() >= 20
    assert np.allclose(fy[before], both, rtol=1e-6)
    assert np.allclose(fy[t > 0.25], lower, rtol=1e-6)
    # not before the removal: the step ending at 0.2 s still had the block
    assert fy[np.argmin(abs(t - 0.2))] == pytest.approx(both, rel=1e-6)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "standing"
    assert summary["removal"] == [{"blocks": ["upper"], "time_s": 0.2,
                                   "at_s": pytest.approx(0.2)}]
    scene = json.loads((out / "scene.json").read_text())
    assert scene["removal"][0]["blocks"] == ["upper"]
    assert "removed" in (out / "run.log").read_text()


def test_removal_before_any_step_and_between_steps(tmp_path):
    """At t = 0 the block is out from the first step: the ground carries the lower box only.
    At a time inside a step (0.201 s, steps of 0.002 s) it leaves at the start of that step,
    0.2 s."""
    case = case_from_dict(stack_case(tmp_path, {"removal": {"blocks": ["upper"],
                                                            "time_s": 0.0}}, end_s=0.2))
    scene = build_scene(case)
    assert scene.removed_at(0.0)
    out = watch(scene, 0.2)
    assert out["status"] == "standing"
    integ = scene.integrator(0.0)
    for _ in range(100):
        integ.step()
    fy = scene.reaction_weights(integ.sys.side_body)["top"] @ integ.point_forces()
    assert fy[1] == pytest.approx(_weight("lower"), rel=1e-6)
    # the upper box never moved, held where it was
    d0 = integ.sys.body_dof0
    upper = [b.name for b in scene.bodies].index("upper")
    assert not integ.u[d0[upper]:d0[upper + 1]].any()

    mid = build_scene(case_from_dict(stack_case(tmp_path, {"removal": {"blocks": ["upper"],
                                                                     "time_s": 0.201}})))
    assert mid.removal.groups[0].at_s(0.002) == pytest.approx(0.2)
    assert not mid.removed_at(0.198) and mid.removed_at(0.2)


def test_elastic_blocks_the_lower_one_stands_the_removed_one_moves_on_untouched(tmp_path):
    """Elastic boxes: the upper one out at 0.2 s (it keeps moving, with no contact and no
    load); the lower one, compressed by it until then, springs back and stands on the ground,
    which carries its weight alone. (The Newton solver once took a step in which no point
    carried a force for converged at its first iterate: the lower box, launched by its own
    spring-back, flew off 0.3 m.)"""
    d = stack_case(tmp_path, {"removal": {"blocks": ["upper"], "time_s": 0.2}})
    d["blocks"] = {"material": "elastic", "density_kg_m3": RHO, "E_Pa": 1e9, "nu": 0.2}
    scene = build_scene(case_from_dict(d))
    integ = scene.integrator(0.0)
    while integ.t < 0.3 - 1e-9:
        integ = scene.next_integrator(integ)
        assert integ.step().converged
    fy = scene.reaction_weights(integ.sys.side_body)["top"] @ integ.point_forces()
    assert fy[1] == pytest.approx(_weight("lower"), rel=1e-6)
    d0 = integ.sys.body_dof0
    lower = [b.name for b in scene.bodies].index("lower")
    assert np.abs(integ.u[d0[lower]:d0[lower + 1]]).max() < 1e-5  # m: no flight


def test_a_resumed_run_across_the_removal_gives_the_same_curve(tmp_path, monkeypatch):
    """Interrupted before the step after the removal (its checkpoint at the removal's time)
    and resumed: the same curve as the run made at once."""
    loading = {"removal": {"blocks": ["upper"], "time_s": 0.2}}
    ref = tmp_path / "ref"
    run_case(case_from_dict(stack_case(tmp_path, loading, end_s=0.3)), ref, **QUIET)
    out = tmp_path / "run"
    interrupt_at(monkeypatch, 110)  # the checkpoint of step 100 (t = 0.2 s) is the last
    with pytest.raises(KeyboardInterrupt):
        run_case(case_from_dict(stack_case(tmp_path, loading, end_s=0.3)), out, **QUIET)
    monkeypatch.undo()
    run_case(load_case(out / "case.yaml"), out, resume=True, **QUIET)
    a, b = _curve(out), _curve(ref)
    assert np.array_equal(a["step"], b["step"])
    for k in ("ux_mm", "uy_mm", "fx_kN", "fy_kN"):
        assert np.abs(a[k] - b[k]).max() <= 1e-6 * max(np.abs(b[k]).max(), 1e-12), k


def test_an_arch_without_its_keystone_falls_after_the_removal_and_not_before():
    """The shipped arch with 25 voussoirs (voussoir 13 at the crown), under its weight only:
    it stands until the keystone leaves at 0.4 s, then the two halves fall (no thrust line
    closes without it): the onset of the mechanism is the removal's time, and the collapse is
    found soon after (a fall of 1 cm takes about 0.045 s)."""
    sets = ["loading.body_force.rate_per_s=0", "arch.voussoirs=25",
            "loading.removal={blocks: [voussoir 13], time_s: 0.4}"]
    scene = build_scene(load_case(ARCH, sets))
    out = watch(scene, 0.8)
    assert out["status"] == "collapse"
    c = out["collapse"]
    assert c["onset_time_s"] == pytest.approx(0.4, abs=1e-9)
    assert 0.4 < c["detected_time_s"] < 0.5
    assert "voussoir 13" not in [m["body"] for m in c["moved_most"]]


def test_bad_names_exit_2_naming_the_field():
    res = CliRunner().invoke(app, ["validate", str(ARCH), "--set",
                                   "loading.removal={blocks: [voussoir 3, keystone], time_s: 1}"])
    assert res.exit_code == 2
    assert "loading.removal.blocks[1]: got 'keystone'" in res.output
    assert "voussoir 1 to voussoir 24" in res.output
    res = CliRunner().invoke(app, ["validate", str(ROOT / "cases" / "smoke.yaml"), "--set",
                                   "loading.removal={blocks: [a], time_s: 1}"])
    assert res.exit_code == 2 and "loading.removal" in res.output


def test_limit_analysis_takes_the_structure_with_the_hole(tmp_path):
    """The stack under a horizontal body force ``lambda g m`` (friction 2: no sliding): whole,
    it overturns about its toe at ``lambda = (b / 2) / (h / 2) = 0.2 / 0.25 = 0.8``; with the
    upper box out, the lower one alone at ``0.2 / 0.15 = 4 / 3``."""
    loading = {"body_force": {"direction": [1.0, 0.0, 0.0], "rate_per_s": 0.1}}
    whole = stack_case(tmp_path, loading)
    whole["joint"]["mu"] = 2.0
    holed = stack_case(tmp_path, {**loading, "removal": {"blocks": ["upper"], "time_s": 0.2}})
    holed["joint"]["mu"] = 2.0
    assert analyse(case_from_dict(whole)).record["multiplier"]["value"] == pytest.approx(
        0.8, rel=1e-6)
    assert analyse(case_from_dict(holed)).record["multiplier"]["value"] == pytest.approx(
        4.0 / 3.0, rel=1e-6)


def test_validate_says_what_is_removed_and_when():
    res = CliRunner().invoke(app, ["validate", str(ARCH), "--set",
                                   "loading.removal={blocks: [voussoir 12], time_s: 1.5}"])
    assert res.exit_code == 0, res.output
    assert res.output.strip().endswith("voussoir 12 removed at 1.5 s")


#: a stack of three boxes on the ground
TALL = (*BOXES[:2], ("middle", -0.2, 0.2, 0.3, 0.5), ("upper", -0.2, 0.2, 0.5, 0.7))


def test_two_removals_at_two_times_drop_the_reaction_by_each_weight(tmp_path):
    """``removal`` as a list: the upper box out at 0.2 s, the middle one at 0.3 s (both on the
    grid of the step). The ground carries the three boxes up to 0.2 s, the lower two up to
    0.3 s, the lower one after, each to the solver's tolerance; the summary, scene.json and
    the run log give both groups with their times, in their order."""
    loading = {"removal": [{"blocks": ["middle"], "time_s": 0.3},
                           {"blocks": ["upper"], "time_s": 0.2}]}
    case = case_from_dict(stack_case(tmp_path, loading, end_s=0.4, boxes=TALL))
    out = tmp_path / "run"
    run_case(case, out, **QUIET)
    c = _curve(out)
    fy, t = 1e3 * c["fy_kN"], c["time_s"]
    w = {name: _weight(name, TALL) for name in ("lower", "middle", "upper")}
    for lo, hi, carried in ((0.15, 0.2, w["lower"] + w["middle"] + w["upper"]),
                            (0.25, 0.3, w["lower"] + w["middle"]), (0.35, 0.4, w["lower"])):
        window = (t > lo + 1e-9) & (t <= hi + 1e-9)
        assert window.sum() >= 20
        assert np.allclose(fy[window], carried, rtol=1e-6), (lo, hi)
    summary = json.loads((out / "summary.json").read_text())
    groups = [{"blocks": ["upper"], "time_s": 0.2, "at_s": pytest.approx(0.2)},
              {"blocks": ["middle"], "time_s": 0.3, "at_s": pytest.approx(0.3)}]
    assert summary["removal"] == groups
    assert json.loads((out / "scene.json").read_text())["removal"] == groups
    log = (out / "run.log").read_text()
    assert log.index("removed upper") < log.index("removed middle")


def test_an_arch_loses_two_groups_of_voussoirs_each_at_its_time(tmp_path):
    """The shipped arch under its weight: voussoir 1 out at 0.1 s, voussoirs 12 and 13 at
    0.2 s (the watch's bound set far, so that the run goes on). The VTU cells are flagged
    ``removed`` from the first output after each time, those of the group's voussoirs only;
    the summary lists both groups."""
    import meshio

    sets = ["loading.body_force.rate_per_s=0", "collapse.displacement_m=50",
            "collapse.end_time_s=0.3", "output.every_steps=25",
            ("loading.removal=[{blocks: [voussoir 1], time_s: 0.1}, "
             "{blocks: [voussoir 12, voussoir 13], time_s: 0.2}]")]
    out = tmp_path / "arch"
    run_case(load_case(ARCH, sets), out, **QUIET)
    summary = json.loads((out / "summary.json").read_text())
    assert [g["blocks"] for g in summary["removal"]] == [["voussoir 1"],
                                                         ["voussoir 12", "voussoir 13"]]
    assert [g["at_s"] for g in summary["removal"]] == pytest.approx([0.1, 0.2])
    expected = {0.1: set(), 0.15: {1}, 0.2: {1}, 0.25: {1, 12, 13}, 0.3: {1, 12, 13}}
    by_time = {}
    for entry in ElementTree.parse(out / "wall.pvd").iter("DataSet"):
        if "blocks_" not in entry.get("file"):
            continue
        m = meshio.read(out / entry.get("file"))
        flag = np.concatenate(m.cell_data["removed"])
        block = np.concatenate(m.cell_data["block"]).astype(int)  # structure index
        by_time[round(float(entry.get("timestep")), 6)] = set((block[flag > 0.5] + 1).tolist())
    for when, blocks in expected.items():
        assert by_time[when] == blocks, when


def test_removals_in_a_list_are_checked_and_described_in_their_order():
    """A block in two groups, an empty list and a name the arch does not have exit 2, naming
    the group; ``validate`` says what leaves when, in the order of the times."""
    def validate(value: str):
        return CliRunner().invoke(app, ["validate", str(ARCH), "--set",
                                        f"loading.removal={value}"])

    res = validate("[{blocks: [voussoir 1], time_s: 0.1}, "
                   "{blocks: [voussoir 3, voussoir 1], time_s: 0.2}]")
    assert res.exit_code == 2
    assert ("loading.removal[1].blocks[1]: got 'voussoir 1', already removed by "
            "loading.removal[0]") in res.output
    res = validate("[]")
    assert res.exit_code == 2 and "loading.removal: an empty list" in res.output
    res = validate("[{blocks: [voussoir 1], time_s: 0.1}, {blocks: [keystone], time_s: 0.2}]")
    assert res.exit_code == 2 and "loading.removal[1].blocks[0]: got 'keystone'" in res.output
    res = validate("[{blocks: [voussoir 12], time_s: 1.5}, {blocks: [voussoir 2], time_s: 0.5}]")
    assert res.exit_code == 0, res.output
    assert res.output.strip().endswith("voussoir 2 removed at 0.5 s; voussoir 12 removed at "
                                       "1.5 s")
