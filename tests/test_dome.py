"""The dome builder (``scenes/dome.py``): its voussoirs, their joints, and the dome standing
under its weight on its ring."""

from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, case_from_dict
from masonry_nscd.cli import app
from masonry_nscd.model.mesh_checks import inverted_elements
from masonry_nscd.scenes import build_scene

DRY = {"law": "dry", "mu": 0.7, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11}


def _dome(**dome):
    return case_from_dict({"dome": {"radius_m": 5.0, "thickness_m": 0.5, "courses": 6,
                                    "voussoirs": 12, **dome},
                           "blocks": {"material": "rigid"}, "joint": DRY,
                           "loading": {"gravity": {"ramp_s": 0.1}},
                           "collapse": {"end_time_s": 0.4},
                           "solver": {"time_step_s": 2e-3, "tolerance": 1e-6},
                           "output": {"every_steps": 25, "vtu": False}})


@pytest.mark.parametrize("shape", [{}, {"shape": "pointed", "radius_m": 6.0, "span_m": 10.0}])
def test_the_voussoirs_are_true_hexahedra_alike_around_each_course(shape):
    """Every half voussoir has a positive Jacobian, its faces flat (each face's corners in one
    plane to 1e-12 of its size), and the voussoirs of a course have one mass (the dome is
    symmetric about its axis)."""
    case = _dome(**shape)
    scene = build_scene(case)
    blocks = scene.bodies[:-1]
    assert len(blocks) == 6 * 12
    for b in blocks:
        assert not len(inverted_elements(b.X, b.conn))
        for quad in b.X[b.conn][:, [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [3, 2, 6, 7],
                                    [0, 3, 7, 4], [1, 2, 6, 5]]].reshape(-1, 4, 3):
            n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
            assert abs((quad[2] - quad[0]) @ n) <= 1e-12 * np.linalg.norm(n) * 5.0
    masses = np.array([b.mass for b in blocks]).reshape(6, 12)
    assert np.allclose(masses, masses[:, :1], rtol=1e-12)


@pytest.mark.parametrize("stagger", [True, False])
def test_a_staggered_voussoir_rests_on_two_below_it(stagger):
    """With stagger, every voussoir above the lowest course shares bed area (contact points of
    the rule ``overlap``, on common areas only) with two voussoirs of the course below;
    without, with one. The lowest course rests on the ring."""
    scene = build_scene(_dome(stagger=stagger, contact_point_rule="overlap"))
    names = [b.name for b in scene.bodies]
    below: dict[str, set] = {}
    for p in scene.points:
        if scene.groups[p.group] != "bed":
            continue
        upper, lower = sorted((names[b] for b in p.bodies), key=lambda s: -int(s.split()[1]))
        below.setdefault(upper, set()).add(lower)
    assert len(below) == 5 * 12
    assert Counter(len(v) for v in below.values()) == {2 if stagger else 1: 5 * 12}
    on_base = {names[b] for p in scene.points if scene.groups[p.group] == "base"
               for b in p.bodies} - {"base"}
    assert on_base == {f"course 1 voussoir {k}" for k in range(1, 13)}


def test_the_dome_stands_on_its_ring_which_carries_its_weight(tmp_path):
    """Under its weight (0.5 m thick on a 5 m radius: ten times Heyman's minimum) the dome
    stands, and the ring carries its weight to the solver's tolerance (the blocks' last
    accelerations), with no net horizontal force."""
    case = _dome()
    path = tmp_path / "dome.yaml"
    from masonry_nscd.case import case_to_yaml

    path.write_text(case_to_yaml(case))
    res = CliRunner().invoke(app, ["run", str(path), "-o", str(tmp_path / "run")])
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "standing"
    weight_kN = sum(b.mass for b in build_scene(case).bodies[:-1]) * 9.81 / 1e3
    fx, fy = summary["support_forces_last_kN"]["base"]
    assert fy == pytest.approx(weight_kN, rel=1e-6)  # the solver's tolerance: a dynamic run
    assert abs(fx) <= 1e-9 * weight_kN


def test_dome_case_checks():
    with pytest.raises(CaseError, match="dome.span_m"):
        _dome(shape="pointed")
    with pytest.raises(CaseError, match="dome.span_m"):
        _dome(span_m=9.0)
    with pytest.raises(CaseError, match="dome.oculus_deg"):
        _dome(shape="pointed", radius_m=6.0, span_m=10.0, oculus_deg=85.0)  # apex at 80.4
    with pytest.raises(CaseError, match="loading.point_load.block"):
        case_from_dict({"dome": {}, "loading": {"point_load": {"block": "voussoir 3"}}})
    with pytest.raises(CaseError, match="dome: given with arch"):
        case_from_dict({"arch": {}, "dome": {}})
    with pytest.raises(CaseError, match="supports: given with a dome case"):
        case_from_dict({"dome": {}, "supports": {"top_vertical": "load"}})
    d = _dome(shape="pointed", radius_m=6.0, span_m=10.0).dome
    assert d.apex_deg == pytest.approx(math.degrees(math.acos(1.0 / 6.0)))
