"""Line loads and block loads on named blocks (``loading.line_loads``, ``loading.block_loads``).

References: a uniform load ``q`` on a segment of length ``L`` has the resultant ``q L``, acting
at the segment's middle; the part over a block, of length ``l``, puts ``q l`` on it at the
middle of that part; the supports of a structure at rest carry its weight and the loads.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import case_from_dict
from masonry_nscd.cli import app
from masonry_nscd.io.mesh_file import BlockMesh, write_block_mesh
from masonry_nscd.model import RigidBody
from masonry_nscd.scenes import build_scene
from masonry_nscd.scenes.limit_loads import LINE_PIECES

RHO, G, DEPTH = 2000.0, 9.81, 0.25
#: two boxes side by side on a ground slab: (name, x0, x1, y0, y1), z from 0 to DEPTH (m)
BOXES = (("ground", -0.6, 0.6, -0.2, 0.0), ("left", -0.4, 0.0, 0.0, 0.3),
         ("right", 0.0, 0.4, 0.0, 0.3))
Q = (0.0, -2000.0, 0.0)  # N/m
FROM, TO = (-0.3, 0.3, 0.125), (0.5, 0.3, 0.125)  # 0.8 m, its last 0.1 m beyond the right box


def _mesh() -> BlockMesh:
    points, hexes = [], []
    for _, x0, x1, y0, y1 in BOXES:
        hexes.append(list(range(len(points), len(points) + 8)))
        points += [(x0, y0, 0.0), (x1, y0, 0.0), (x1, y1, 0.0), (x0, y1, 0.0),
                   (x0, y0, DEPTH), (x1, y0, DEPTH), (x1, y1, DEPTH), (x0, y1, DEPTH)]
    return BlockMesh(points=np.array(points), hexes=np.array(hexes, dtype=np.int64),
                     tags=np.array([1, 2, 3]), names={1: "ground", 2: "left", 3: "right"})


def _case(tmp_path: Path, blocks=("left", "right")) -> dict:
    write_block_mesh(tmp_path / "pair.msh", _mesh())
    return {"name": "pair",
            "assembly": {"mesh_file": str(tmp_path / "pair.msh"),
                         "supports": [{"group": "ground"}], "driven_block": "left"},
            "blocks": {"material": "rigid", "density_kg_m3": RHO},
            "joint": {"law": "dry", "mu": 0.8, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11},
            "loading": {"gravity": {"value_m_s2": G, "start_s": 0.0, "ramp_s": 0.1},
                        "line_loads": [{"blocks": list(blocks), "force_N_m": list(Q),
                                        "from_m": list(FROM), "to_m": list(TO)}]},
            "collapse": {"end_time_s": 0.3},
            "solver": {"time_step_s": 0.002, "tolerance": 1e-8},
            "output": {"vtu": False}}


def test_the_resultant_is_the_load_per_metre_times_the_length_and_each_block_its_part(tmp_path):
    scene = build_scene(case_from_dict(_case(tmp_path)))
    pattern = scene.loads.patterns[-1]  # the line load's, after gravity's
    names = [b.name for b in scene.bodies]
    d0 = np.cumsum([0] + [b.ndof for b in scene.bodies])
    force = {n: pattern[d0[i]:d0[i] + 3] for i, n in enumerate(names)}
    length = np.linalg.norm(np.subtract(TO, FROM))
    total = sum(force.values())
    assert total == pytest.approx(np.multiply(Q, length), rel=1e-12, abs=1e-9)
    # the left box carries the 0.3 m over it; the right one the 0.4 m over it and the 0.1 m
    # beyond its edge, the box nearest in plan
    assert force["left"] == pytest.approx(np.multiply(Q, 0.3), rel=1e-12, abs=1e-9)
    assert force["right"] == pytest.approx(np.multiply(Q, 0.5), rel=1e-12, abs=1e-9)
    assert not force["ground"].any()
    # its moment about the right box's reference point: the resultant at the middle of its
    # part, x = 0.25 m, to the pieces' resolution
    right = scene.bodies[names.index("right")]
    assert isinstance(right, RigidBody)
    i = names.index("right")
    mz = pattern[d0[i] + 5]
    expect = (0.25 - right.reference[0]) * Q[1] * 0.5 - (0.3 - right.reference[1]) * Q[0] * 0.5
    assert mz == pytest.approx(expect, abs=abs(Q[1]) * 0.5 * 0.8 / LINE_PIECES)


def test_the_supports_carry_the_line_load_with_the_weights(tmp_path):
    """At rest under gravity and the line load (both ramped over 0.1 s), the ground carries
    both boxes' weights and the load's resultant, to the solver's tolerance."""
    fy = _ground_force_at_rest(build_scene(case_from_dict(_case(tmp_path))))
    weights = _weights()
    load = -Q[1] * np.linalg.norm(np.subtract(TO, FROM))
    assert fy[1] == pytest.approx(weights + load, rel=1e-6)
    assert fy[0] == pytest.approx(0.0, abs=1e-6 * (weights + load))


def test_a_line_load_on_a_block_that_is_not_there_exits_2_naming_the_field(tmp_path):
    path = tmp_path / "case.yaml"  # JSON is YAML 1.2
    path.write_text(json.dumps(_case(tmp_path, blocks=("left", "middle"))))
    res = CliRunner().invoke(app, ["validate", str(path)])
    assert res.exit_code == 2, res.output
    assert "loading.line_loads[0].blocks[1]: got 'middle'" in res.output
    assert "'left', 'right'" in res.output  # the blocks of the structure listed


def test_block_loads_put_the_force_on_each_named_block_and_the_ground_carries_them(tmp_path):
    """``block_loads``: 3 kN down on each of the two boxes, dead with gravity: each box's
    pattern is the force, and the ground carries both weights and 6 kN."""
    d = _case(tmp_path)
    d["loading"].pop("line_loads")
    d["loading"]["block_loads"] = [{"blocks": ["left", "right"], "force_N": [0.0, -3000.0, 0.0]}]
    scene = build_scene(case_from_dict(d))
    pattern = scene.loads.patterns[-1]
    d0 = np.cumsum([0] + [b.ndof for b in scene.bodies])
    for i, b in enumerate(scene.bodies):
        expect = [0.0, -3000.0, 0.0] if b.name in ("left", "right") else [0.0, 0.0, 0.0]
        assert pattern[d0[i]:d0[i] + 3] == pytest.approx(expect, abs=1e-9)
    fy = _ground_force_at_rest(scene)
    assert fy[1] == pytest.approx(_weights() + 6000.0, rel=1e-6)
    path = tmp_path / "bad.yaml"
    d["loading"]["block_loads"][0]["blocks"] = ["left", "centre"]
    path.write_text(json.dumps(d))
    res = CliRunner().invoke(app, ["validate", str(path)])
    assert res.exit_code == 2 and "loading.block_loads[0].blocks[1]: got 'centre'" in res.output


def _ground_force_at_rest(scene) -> np.ndarray:
    """The force the ground carries after 150 steps (0.3 s: the loads' 0.1 s ramps and rest),
    N."""
    integ = scene.integrator(0.0)
    for _ in range(150):
        integ.step()
    return scene.reaction_weights(integ.sys.side_body)["top"] @ integ.point_forces()


def _weights() -> float:
    """The boxes' weights (the ground aside), N."""
    return sum(RHO * G * (x1 - x0) * (y1 - y0) * DEPTH for n, x0, x1, y0, y1 in BOXES
               if n != "ground")
