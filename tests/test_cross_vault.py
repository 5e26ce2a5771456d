"""The cross vault builder (``scenes/cross_vault.py``): its stones, springers and ribs, their
joints, and the vault standing on its four supports under its weight."""

from __future__ import annotations

import json
import math
from itertools import pairwise

import numpy as np
import pytest
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, case_from_dict, case_to_yaml
from masonry_nscd.cli import app
from masonry_nscd.model.mesh_checks import inverted_elements
from masonry_nscd.scenes import build_scene

DRY = {"law": "dry", "mu": 0.7, "K_n_Pa_m": 1e11, "K_t_Pa_m": 1e11}
HEX_FACES = [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [3, 2, 6, 7], [0, 3, 7, 4],
             [1, 2, 6, 5]]


def _vault(loading=None, **vault):
    return case_from_dict(_data(loading, **vault))


def _data(loading=None, **vault) -> dict:
    return ({"cross_vault": {"span_x_m": 4.0, "span_z_m": 4.0,
                                           "thickness_m": 0.5, "courses": 8,
                                           "springer_courses": 3, **vault},
                           "blocks": {"material": "rigid", "density_kg_m3": 2000.0},
                           "joint": DRY,
                           "loading": {"gravity": {"ramp_s": 0.1}, **(loading or {})},
                           "collapse": {"end_time_s": 0.3},
                           "solver": {"time_step_s": 2e-3, "tolerance": 1e-6},
                           "output": {"every_steps": 25, "vtu": False}})


def _run(case, tmp_path) -> dict:
    """Run ``case`` by the command line into ``tmp_path / "run"``; its summary."""
    path = tmp_path / "vault.yaml"
    path.write_text(case_to_yaml(case))
    res = CliRunner().invoke(app, ["run", str(path), "-o", str(tmp_path / "run")])
    assert res.exit_code == 0, res.output
    return json.loads((tmp_path / "run" / "summary.json").read_text())


def _arch_point(v, j: int, rho: float) -> tuple[float, float]:
    """``(r, y)`` of level ``j`` of the arch across z at radius ``rho`` (m): the angle cut
    into equal parts from 0 to where the arc meets the bay's axis."""
    c = v.arch_radius_m - v.span_z_m / 2.0
    alpha = math.acos(c / rho) * j / v.courses
    return rho * math.cos(alpha) - c, rho * math.sin(alpha)


def _expected_volume(v) -> float:
    """Volume of the vault (m^3) by integrals over the arch's section, apart from the builder.

    A web course between levels j - 1 and j is the section's quadrilateral Q swept along the
    axis from the groin to the web's end: at a point of Q at ``r`` from the axis the stone runs
    ``(a / 2)(1 - r / (b / 2))``, so its volume is ``(a / 2)(A - S_r / (b / 2))`` with A the
    area of Q and S_r its first moment about the axis (the barrel across x gives the same,
    its section being this one scaled by ``a / b``). A springer's hexahedron under the bed of
    level k holds, over the section's horizontal segment from r_in to r_out, the height of
    that bed (linear in r) times the same run: ``int y(r) (a / 2)(1 - 2 r / b) dr``."""
    a, b, t = v.span_x_m, v.span_z_m, v.thickness_m
    R = v.arch_radius_m
    rin, rout = R - t / 2, R + t / 2
    webs = 0.0
    for j in range(v.springer_courses + 1, v.courses + 1):
        Q = np.array([_arch_point(v, j - 1, rin), _arch_point(v, j - 1, rout),
                      _arch_point(v, j, rout), _arch_point(v, j, rin)])
        x, y = Q[:, 0], Q[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        A = 0.5 * cross.sum()
        S_r = (cross * (x + np.roll(x, -1))).sum() / 6.0
        webs += abs(a / 2 * (A - S_r / (b / 2)))
    (r0, y0), (r1, y1) = (_arch_point(v, v.springer_courses, rin),
                          _arch_point(v, v.springer_courses, rout))
    g, w = np.polynomial.legendre.leggauss(3)
    r = 0.5 * (r0 + r1) + 0.5 * (r1 - r0) * g
    y = y0 + (y1 - y0) * (r - r0) / (r1 - r0)
    springer = abs(0.5 * (r1 - r0) * np.sum(w * y * (a / 2) * (1 - 2 * r / b)))
    return 8 * webs + 8 * springer


@pytest.mark.parametrize("vault", [{}, {"span_x_m": 6.0, "shape": "pointed", "radius_m": 2.6},
                                   {"transverse_ribs": True, "rib_depth_m": 0.7, "stagger": False}])
def test_the_blocks_are_true_hexahedra_and_fill_the_vault(vault):
    """Every hexahedron has a positive Jacobian and flat faces, and the stones and springers
    fill the volume that integrals over the arch's section give (1e-9), square bay or not,
    semicircular or pointed."""
    case = _vault(**vault)
    scene = build_scene(case)
    v = case.cross_vault
    blocks = [b for b in scene.bodies if not b.support]
    for b in blocks:
        assert not len(inverted_elements(b.X, b.conn)), b.name
        for quad in b.X[b.conn][:, HEX_FACES].reshape(-1, 4, 3):
            n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
            assert abs((quad[2] - quad[0]) @ n) <= 1e-12 * np.linalg.norm(n) * 10.0, b.name
    volume = sum(b.mass for b in blocks if "rib" not in b.name) / 2000.0
    assert volume == pytest.approx(_expected_volume(v), rel=1e-9)
    assert sum(b.name.startswith("springer") for b in blocks) == 4
    assert sum(" rib " in b.name for b in blocks) == (4 * v.courses if v.transverse_ribs else 0)


def test_the_webs_meet_on_the_groins_and_rest_on_the_springers():
    """The groin joints join stones of the same course of two webs, face to face (as many
    points on each side); every web stone of the first free course rests on a springer; the
    springers alone stand on the supports."""
    scene = build_scene(_vault(contact_point_rule="overlap"))
    names = [b.name for b in scene.bodies]
    groin, on_springer, on_base = set(), set(), set()
    for p in scene.points:
        a, b = (names[i] for i in p.bodies)
        group = scene.groups[p.group]
        if group == "groin":
            wa, wb = a.split(), b.split()
            assert wa[0] != wb[0] and wa[4] == wb[4]  # two webs, one course
            groin.add((a, b))
        elif group == "springer":
            on_springer.add(a if "web" in a else b)
        elif group == "base":
            on_base.add(a if "support" not in a else b)
    assert len(groin) == 4 * (8 - 3)  # per course, one pair of stones on each of four groins
    assert on_springer == {n for n in names if "course 4 stone 1" in n}
    assert on_base == {f"springer {c}" for c in ("north-east", "north-west", "south-east",
                                                   "south-west")}


@pytest.mark.parametrize("vault", [{}, {"diagonal_ribs": True, "diagonal_rib_depth_m": 0.2,
                                        "transverse_ribs": True, "rib_depth_m": 0.7}])
def test_the_vault_stands_and_its_four_supports_share_its_weight(tmp_path, vault):
    """Under its weight the vault (0.5 m thick over 4 m; a groin vault, or a rib vault with
    diagonal and transverse ribs) stands; its supports carry the weight to the solver's
    tolerance (the blocks' last accelerations), with no net horizontal force, and each corner a
    quarter of it (the bay's symmetry; 1e-4: looser than the tolerance); its mechanism figure
    draws it in perspective."""
    case = _vault(**vault)
    summary = _run(case, tmp_path)
    assert summary["status"] == "standing"
    weight_kN = sum(b.mass for b in build_scene(case).bodies if not b.support) * 9.81 / 1e3
    forces = summary["support_forces_last_kN"]
    fx, fy = forces["all supports"]
    assert fy == pytest.approx(weight_kN, rel=1e-6)  # the solver's tolerance: a dynamic run
    assert abs(fx) <= 1e-8 * weight_kN
    assert forces["support north-east"][1] == pytest.approx(weight_kN / 4, rel=1e-4)
    # the mechanism figure of a structure without a front plane: its blocks in perspective
    res = CliRunner().invoke(app, ["plot", str(tmp_path / "run")])
    assert res.exit_code == 0, res.output
    (figure,) = (tmp_path / "run" / "plots").glob("mechanism_*.png")
    assert figure.stat().st_size > 10_000


def test_a_side_that_spreads_moves_its_two_supports():
    """``settlement.support: east`` moves the two supports at +x and holds the others."""
    case = _vault({"settlement": {"support": "east", "displacement_m": [0.02, 0.0, 0.0]}})
    scene = build_scene(case)
    moving = {b.name for b in scene.bodies if b.support
              and abs(b.imposed_velocity[0].displacement(10.0)) > 0.0}
    assert moving == {"support north-east", "support south-east"}
    for b in scene.bodies:
        if b.support and b.name in moving:
            assert b.imposed_velocity[0].displacement(10.0) == pytest.approx(0.02)


def test_cross_vault_case_checks():
    with pytest.raises(CaseError, match="cross_vault.radius_m"):
        _vault(shape="pointed")
    with pytest.raises(CaseError, match="cross_vault.springer_courses"):
        _vault(springer_courses=8)
    with pytest.raises(CaseError, match="cross_vault.springer_courses: got 2; .* at least 3"):
        build_scene(_vault(springer_courses=2))
    with pytest.raises(CaseError, match="loading.settlement.support: got 'left'"):
        _vault({"settlement": {"support": "left", "displacement_m": [0.01, 0.0, 0.0]}})
    with pytest.raises(CaseError, match="loading.point_load.block"):
        build_scene(_vault({"point_load": {"block": "voussoir 3"}}))


def test_diagonal_ribs_join_the_groin_stones_and_leave_the_webs_as_they_were():
    """With ``diagonal_ribs`` the two groin stones of a course at a corner are one block of two
    true hexahedra sharing their groin face (12 nodes), deeper than the two stones it replaces;
    the top course's eight are the boss; every other stone is the groin vault's, node for node;
    the ribs' voussoirs rest on each other and the first on its corner's springer."""
    plain = {b.name: b for b in build_scene(_vault()).bodies}
    scene = build_scene(_vault(diagonal_ribs=True, diagonal_rib_depth_m=0.2))
    ribbed = {b.name: b for b in scene.bodies}
    k, n = 3, 8
    for name, b in ribbed.items():
        if "web" in name:
            np.testing.assert_array_equal(b.X, plain[name].X)
    ribs = {name: b for name, b in ribbed.items() if name.startswith("diagonal rib")}
    assert len(ribs) == 4 * (n - k - 1)
    assert not any("stone 1" in name for name in ribbed)
    for corner in ("north-east", "north-west", "south-east", "south-west"):
        for i in range(1, n - k):
            b = ribs[f"diagonal rib {corner} voussoir {i}"]
            assert b.conn.shape == (2, 8) and len(b.X) == 12
            assert not len(inverted_elements(b.X, b.conn))
            j = k + i
            replaced = [plain[f"{web} web {half} course {j} stone 1"].mass
                        for web, half in _corner_halves(corner)]
            assert b.mass > sum(replaced)
    boss = ribbed["boss"]
    assert boss.conn.shape == (8, 8)
    assert boss.mass > sum(b.mass for name, b in plain.items()
                           if name.endswith(f"course {n} stone 1"))
    names = [b.name for b in scene.bodies]
    rib_joints = set()
    for p in scene.points:
        pair = tuple(sorted(names[i] for i in p.bodies))
        if scene.groups[p.group] == "rib":
            rib_joints.add(pair)
    for corner in ("north-east", "north-west", "south-east", "south-west"):
        chain = [f"springer {corner}"] + [f"diagonal rib {corner} voussoir {i}"
                                           for i in range(1, n - k)] + ["boss"]
        for a, b in pairwise(chain[1:]):
            assert tuple(sorted((a, b))) in rib_joints


def _corner_halves(corner: str):
    ns, ew = corner.split("-")
    return ((ew, ns), (ns, ew))


def test_a_diagonal_rib_deeper_than_its_arch_is_refused():
    with pytest.raises(CaseError, match="cross_vault.diagonal_rib_depth_m: got 1.8 m"):
        build_scene(_vault(diagonal_ribs=True, diagonal_rib_depth_m=1.8))


def test_piers_of_drums_stand_under_the_vault_and_carry_its_weight(tmp_path):
    """``piers``: each corner on a square pier of drums centred on the corner of the bay, its
    lowest drum on the fixed support ``pier_height_m`` below the springing. Wide piers (2.5 m)
    stand under the vault's weight; the supports carry the vault's weight (that of the same
    vault on fixed supports, the same stones) plus the piers', 4 rho g w^2 H from their
    outline, to the solver's tolerance, with no net horizontal force."""
    w, H, drums = 2.5, 3.0, 6
    case = _vault(piers=True, pier_width_m=w, pier_height_m=H, pier_drums=drums)
    scene = build_scene(case)
    for corner, (sx, sz) in {"north-east": (1, 1), "south-west": (-1, -1)}.items():
        names = [f"pier {corner} drum {k + 1}" for k in range(drums)]
        X = [next(b for b in scene.bodies if b.name == n).X for n in names]
        for k, Xk in enumerate(X):
            assert Xk[:, 1].min() == pytest.approx(-H + k * H / drums, abs=1e-12)
            assert Xk[:, 1].max() == pytest.approx(-H + (k + 1) * H / drums, abs=1e-12)
            assert Xk[:, 0].min() == pytest.approx(sx * 2.0 - w / 2, abs=1e-12)
            assert Xk[:, 2].max() == pytest.approx(sz * 2.0 + w / 2, abs=1e-12)
    support = next(b for b in scene.bodies if b.name == "support north-east")
    assert support.X[:, 1].max() == pytest.approx(-H, abs=1e-12)
    summary = _run(case, tmp_path)
    assert summary["status"] == "standing"
    vault_kg = sum(b.mass for b in build_scene(_vault()).bodies if not b.support)
    weight_kN = (vault_kg + 4 * 2000.0 * w * w * H) * 9.81 / 1e3
    fx, fy = summary["support_forces_last_kN"]["all supports"]
    assert fy == pytest.approx(weight_kN, rel=1e-6)
    assert abs(fx) <= 1e-8 * weight_kN


def test_piers_lower_the_collapse_multiplier_and_narrow_ones_cannot_carry_the_vault(tmp_path):
    """Limit analysis: any joint forces that hold the vault on piers hold it on fixed supports
    (the supports take any force), so the multiplier on piers is at most the one on fixed
    supports; piers as narrow as the springers' feet cannot carry the vault's thrust at all,
    and the NSCD run collapses under the vault's weight alone; a pier narrower than the feet
    is refused, naming the field."""
    from masonry_nscd.limit.analysis import analyse

    grow = {"body_force": {"direction": [1.0, 0.0, 0.0], "multiplier": 0.0,
                           "rate_per_s": 0.1, "start_s": 0.3, "ramp_s": 0.1}}

    def lam(**kw):
        return analyse(_vault(grow, **kw)).record["multiplier"]["value"]

    fixed = lam()
    assert lam(piers=True, pier_width_m=1.5) <= fixed + 1e-6
    assert lam(piers=True, pier_width_m=1.5, pier_height_m=6.0) < fixed
    assert analyse(_vault(piers=True)).record["status"] == "infeasible"
    summary = _run(_vault(piers=True), tmp_path)
    assert summary["status"] == "collapse"
    with pytest.raises(CaseError, match=r"cross_vault.pier_width_m: got 0.3 m; .* at least"):
        build_scene(_vault(piers=True, pier_width_m=0.3))
