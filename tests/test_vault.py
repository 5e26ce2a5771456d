"""Barrel vaults: the arch's section in staggered rings along its depth.

Reference values are computed here from the geometry: the section of a vault of ``n`` voussoirs
is the polygon of the ``2 n`` half voussoirs' chords, of area ``(R_e^2 - R_i^2) n sin(pi /
(2 n))``; two neighbouring rings touch over whole half voussoirs, each of area ``(R_e^2 -
R_i^2) sin(pi / (2 n)) / 2``. The thrust check compares the vault with the arch of the same
section, both run by the package: under its own weight, a vault whose rings are arches side by
side (in running bond) pushes on its abutments as the arch does, per unit depth.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from masonry_nscd.case import CaseError, case_from_dict, load_case
from masonry_nscd.scenes import build_scene

ROOT = Path(__file__).resolve().parents[1]
VAULT = ROOT / "cases" / "vault_barrel.yaml"
ARCH = ROOT / "cases" / "arch_semicircular.yaml"
DRY = {"law": "dry", "mu": 0.8, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11}


def _vault(**kw):
    return case_from_dict({"vault": {"voussoirs": 6, "rings": 3, "depth_m": 0.75,
                                     "thickness_m": 0.2, **kw},
                           "blocks": {"material": "rigid", "density_kg_m3": 2000.0},
                           "joint": DRY})


def test_rings_are_staggered_and_their_joints_found():
    """Rings 1 and 3 have the arch's 6 voussoirs, ring 2 five whole ones and two halves; every
    radial joint, springing and ring-to-ring overlap is found, each with the area of the
    geometry, and the vault weighs its section times its depth."""
    n, R, t, depth, rings = 6, 1.0, 0.2, 0.75, 3
    scene = build_scene(_vault())
    names = [scene.bodies[i].name for i in scene.structure]
    assert [sum(nm.startswith(f"ring {r} ") for nm in names) for r in (1, 2, 3)] == [6, 7, 6]
    r_i, r_e = R - t / 2, R + t / 2
    section = (r_e ** 2 - r_i ** 2) * n * math.sin(math.pi / (2 * n))
    mass = sum(scene.bodies[i].mass for i in scene.structure)
    assert mass == pytest.approx(2000.0 * section * depth, rel=1e-12)
    # ring 2's first joint is half a voussoir up from the springing (15 deg for n = 6): the
    # joint between its voussoirs 1 and 2 lies on the radial line at pi / (2 n)
    by_pair = defaultdict(list)
    for p in scene.points:
        by_pair[tuple(sorted(scene.bodies[b].name for b in p.bodies))].append(p)
    pts = by_pair[("ring 2 voussoir 1", "ring 2 voussoir 2")]
    for p in pts:
        assert math.atan2(p.x[1], -p.x[0]) == pytest.approx(math.pi / (2 * n), abs=1e-12)
    groups = defaultdict(float)
    for members in by_pair.values():
        groups[scene.groups[members[0].group]] += sum(p.area for p in members)
    # radial joints: 5 + 6 + 5 between voussoirs, 2 springings per ring, each t x depth / 3
    face = t * depth / rings
    assert groups["voussoir"] == pytest.approx(16 * face, rel=1e-12)
    assert groups["springing"] == pytest.approx(6 * face, rel=1e-12)
    # between rings: the whole section, twice (rings 1-2 and 2-3)
    assert groups["ring"] == pytest.approx(2 * section, rel=1e-12)
    ring_pairs = [pair for pair, m in by_pair.items() if scene.groups[m[0].group] == "ring"]
    assert len(ring_pairs) == 2 * 2 * n  # each block of an unstaggered ring meets two


def test_vault_without_stagger_is_arches_side_by_side():
    scene = build_scene(_vault(stagger=False))
    names = [scene.bodies[i].name for i in scene.structure]
    assert len(names) == 18
    ring = [p for p in scene.points if scene.groups[p.group] == "ring"]
    n, t = 6, 0.2
    section = ((1 + t / 2) ** 2 - (1 - t / 2) ** 2) * n * math.sin(math.pi / (2 * n))
    assert sum(p.area for p in ring) == pytest.approx(2 * section, rel=1e-12)
    for p in ring:  # face to face, or a corner on the joint line the two rings share
        k0, k1 = (int(scene.bodies[b].name.split()[-1]) for b in p.bodies)
        if k0 != k1:
            angle = math.atan2(p.x[1], -p.x[0])
            assert angle == pytest.approx(math.pi * max(k0, k1) / n - math.pi / n, abs=1e-12)


def test_vault_case_checks():
    with pytest.raises(CaseError, match="vault.joint_thickness_m"):
        _vault(joint_thickness_m=0.01)
    with pytest.raises(CaseError, match="vault.rings"):
        _vault(rings=0)
    with pytest.raises(CaseError, match="vault: given with arch"):
        case_from_dict({"arch": {}, "vault": {}})
    with pytest.raises(CaseError, match="vault.radius_m"):  # the arch's checks hold
        case_from_dict({"vault": {"shape": "pointed", "span_m": 2.0, "radius_m": 0.9}})
    with pytest.raises(CaseError, match="loading.point_load.block.*ring 4 voussoir 25"):
        case_from_dict({"vault": {}, "loading": {"point_load": {"block": "voussoir 3"}}})
    case = case_from_dict({"vault": {}, "loading": {"point_load": {"block":
                                                                   "ring 2 voussoir 25"}}})
    assert case.structure.name == "vault" and case.limit_state is case.vault
    with pytest.raises(CaseError, match="wall: given with a vault case"):
        case_from_dict({"vault": {}, "wall": {"courses": 5}})


def _gravity_run(tmp_path, path, name):
    from masonry_nscd.run import run_case

    case = load_case(path, ["output.vtu=false", "loading.body_force.rate_per_s=0",
                            "collapse.end_time_s=0.3"])
    run_case(case, tmp_path / name, echo=lambda _m: None)
    return case, json.loads((tmp_path / name / "summary.json").read_text())


def test_vault_thrust_per_unit_depth_matches_the_arch(tmp_path):
    """The shipped vault (4 staggered rings of the shipped arch's section, 1 m deep) stands
    under its own weight; each abutment carries half the weight, and its horizontal thrust per
    unit depth is the arch's within 5 %."""
    arch_case, arch = _gravity_run(tmp_path, ARCH, "arch")
    vault_case, vault = _gravity_run(tmp_path, VAULT, "vault")
    assert vault["status"] == "standing" and arch["status"] == "standing"
    v = vault_case.vault
    r_i, r_e = v.radius_m - v.thickness_m / 2, v.radius_m + v.thickness_m / 2
    n = v.voussoirs
    weight = 2000.0 * 9.81 * v.depth_m * (r_e ** 2 - r_i ** 2) * n * math.sin(math.pi / (2 * n))
    left, right = (np.array(vault["support_forces_last_kN"][s]) for s in ("left", "right"))
    assert left[1] == pytest.approx(1e-3 * weight / 2, rel=1e-5)
    assert right[1] == pytest.approx(1e-3 * weight / 2, rel=1e-5)
    assert right[0] == pytest.approx(-left[0], rel=1e-5)
    thrust_vault = left[0] / v.depth_m
    thrust_arch = arch["support_forces_last_kN"]["left"][0] / arch_case.arch.depth_m
    assert thrust_vault == pytest.approx(thrust_arch, rel=0.05)


def test_collapse_multiplier_of_a_two_ring_vault(tmp_path):
    """Two staggered rings of the shipped section under a growing horizontal body force: the
    multiplier at the onset within 2 % of the limit analysis of the arch of the same joints
    (``test_arch``'s linear programme on the chord section, 0.2 % lighter than the vault's),
    and each ring turning on four hinges, one of them at its right springing."""
    from test_arch import collapse_multiplier

    from masonry_nscd.run import run_case

    case = load_case(VAULT, ["output.vtu=false", "vault.rings=2", "vault.depth_m=0.5"])
    run_case(case, tmp_path / "v", echo=lambda _m: None)
    s = json.loads((tmp_path / "v" / "summary.json").read_text())
    assert s["status"] == "collapse"
    lam = collapse_multiplier(case.vault.voussoirs, case.vault.thickness_m)
    assert s["collapse"]["loads_at_onset"]["lambda"] == pytest.approx(lam, rel=0.02)
    rings = defaultdict(list)
    for h in s["hinges"]:
        rings[h["bodies"][0].split()[1]].append(h["bodies"])
    assert sorted(rings) == ["1", "2"]
    for r, pairs in rings.items():
        assert len(pairs) == 4, pairs
        assert [f"ring {r} voussoir {24 + int(r) - 1}", "right abutment"] in pairs
