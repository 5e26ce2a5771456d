"""The campaign of tested walls: the parameter rules on hand-computed numbers, the case made
for a row, the dry run on the shipped table, the statistics on made-up numbers."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from masonry_nscd.case import case_from_dict, read_yaml
from masonry_nscd.materials import rules
from masonry_nscd.studies import campaign

ROOT = Path(__file__).resolve().parents[1]
TESTS_CSV = ROOT / "tests" / "data" / "stone_walls_tests.csv"
TEMPLATE = ROOT / "cases" / "campaign" / "stone_walls.yaml"


def _row(name: str) -> dict[str, str]:
    with open(TESTS_CSV, newline="") as f:
        return next(r for r in csv.DictReader(f) if r["test"] == name)


# --- the rules ------------------------------------------------------------------------------


def test_joint_stiffness_series_spring():
    # E_m = E_u / 2: the joints as compliant as the units, h K_n = E_u
    assert rules.joint_normal_stiffness(5000, 10000, 100) == pytest.approx(1e11, rel=1e-12)
    # the relation it inverts, on a tested row's numbers
    K = rules.joint_normal_stiffness(360, 26000, 300)
    assert 1 / 26000e6 + 1 / (0.3 * K) == pytest.approx(1 / 360e6, rel=1e-12)
    assert rules.joint_shear_stiffness(1e11) == pytest.approx(1e11 / 2.4, rel=1e-12)
    with pytest.raises(ValueError):
        rules.joint_normal_stiffness(20000, 20000, 100)
    # with a joint of j: a prism h + j high; E_m = E_u (h + j) / (2 h) leaves the joint as
    # compliant as the unit again
    assert rules.joint_normal_stiffness(10000 * 110 / 200, 10000, 100, 10) == pytest.approx(1e11)
    # the mortar layer: 27 MPa over 10 mm
    assert rules.mortar_joint_normal_stiffness(27, 10) == pytest.approx(2.7e9, rel=1e-12)
    # Lourenco's form for units expanded by the joint gives the layer's own once the expanded
    # part of the unit is taken back: 1/k_n + j/E_u = j/E_mo
    E_u, E_mo, j = 20000e6, 87e6, 0.010
    k_lourenco = E_u * E_mo / (j * (E_u - E_mo))
    assert 1 / k_lourenco + j / E_u == pytest.approx(1 / rules.mortar_joint_normal_stiffness(87, 10))
    with pytest.raises(ValueError):
        rules.mortar_joint_normal_stiffness(27, 0)


def test_joint_strengths_and_energies():
    assert rules.joint_cohesion_MPa(1.0) == pytest.approx(0.125)      # M1: 0.10 / 0.8
    assert rules.joint_cohesion_MPa(4.08) == pytest.approx(0.1875)    # M2.5-M9: 0.15 / 0.8
    assert rules.joint_cohesion_MPa(12.0) == pytest.approx(0.25)      # M10-M20: 0.20 / 0.8
    assert rules.joint_tensile_bond_MPa(0.14) == pytest.approx(0.1)
    # Lourenco and Rots's set, f_t 0.25 MPa -> 0.018 N/mm, c 0.35 MPa -> 0.125 N/mm, scaled
    # to f_t 0.1 and c 0.2 MPa: 0.018 * 0.1 / 0.25 = 0.0072 N/mm, 0.125 * 0.2 / 0.35 N/mm
    G_I, G_II = rules.fracture_energies_J_m2(0.1, 0.2)
    assert G_I == pytest.approx(7.2) and G_II == pytest.approx(250.0 / 3.5)
    # the set itself comes back
    assert rules.fracture_energies_J_m2(0.25, 0.35) == pytest.approx((18.0, 125.0))
    j = rules.joint_parameters(5000, 10000, 100, 1.0)
    assert j["K_I_spring_Pa_m"] == pytest.approx(1e11) and j["d_spring"] == 0.0
    assert j["sigma_II_e_Pa"] == pytest.approx(1.25e5)
    assert j["sigma_I_e_Pa"] == pytest.approx(1.25e5 / 1.4)
    assert j["K_I_coh_Pa_m"] == pytest.approx(1e12) and j["d_coh_initial"] == 0.0


def test_unit_parameters():
    u = rules.unit_parameters(50.0, 20000.0)
    assert u["E_Pa"] == 2e10 and u["R_c_Pa"] == 5e7 and u["R_t_Pa"] == pytest.approx(5e6)
    assert u["eps_pic_t"] == pytest.approx(2.5e-4) and u["eps_pic_c"] == pytest.approx(5e-3)
    assert rules.tensile_fracture_energy_J_m2(10.0) == pytest.approx(73 * 10 ** 0.18)
    assert rules.tensile_fracture_energy_J_m2(10.0) == pytest.approx(110.49, rel=1e-4)
    assert rules.density_kg_m3() * 9.81 == pytest.approx(20e3)
    # the masonry's strength, where measured, is the units' crushing strength, and the rest
    # follows from it: R_t a tenth, eps_pic_c twice R_c / E, G_ft from 73 f^0.18
    m = rules.unit_parameters(50.0, 20000.0, masonry_fc_MPa=5.0)
    assert m["E_Pa"] == 2e10 and m["R_c_Pa"] == 5e6 and m["R_t_Pa"] == pytest.approx(5e5)
    assert m["eps_pic_c"] == pytest.approx(5e-4) and m["eps_pic_t"] == pytest.approx(2.5e-5)
    assert m["G_ft_J_m2"] == pytest.approx(73 * 5 ** 0.18)
    assert rules.unit_parameters(None, 20000.0, 5.0) == m
    with pytest.raises(ValueError, match="compressive strength"):
        rules.unit_parameters(None, 20000.0, None)


# --- one row's case -------------------------------------------------------------------------


def test_case_for_fixed_fixed_row():
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, _row("SC7")))
    w = case.wall
    # 900 x 900 mm with 10 mm joints: 7 courses of 120 mm, 5 units of 172 mm (units 110-140 x
    # 150-200 mm: means 125 and 175)
    assert (w.courses, w.units_per_course) == (7, 5)
    assert w.unit_height_m == pytest.approx(0.120) and w.unit_length_m == pytest.approx(0.172)
    assert w.half_unit_length_m == pytest.approx(0.081)
    assert w.wall_length_m == pytest.approx(0.9) and w.wall_height_m == pytest.approx(0.9)
    assert w.thickness_m == pytest.approx(0.2)
    assert case.supports.top_rotation == "fixed"            # H0 = H / 2
    assert case.loading.vertical_stress.value_Pa == pytest.approx(1.15e6)
    assert case.loading.horizontal.target_m == pytest.approx(1.5 * 0.0064 * 0.9)
    # the mortar's modulus is measured (323 MPa): its layer of 10 mm, 3.23e10 Pa/m
    assert case.joint.K_I_spring_Pa_m == pytest.approx(3.23e10, rel=1e-12)
    assert case.joint.K_II_spring_Pa_m == pytest.approx(3.23e10 / 2.4, rel=1e-12)
    assert case.joint.sigma_II_e_Pa == pytest.approx(0.1875e6)   # mortar 4.08 MPa
    assert case.blocks.E_Pa == pytest.approx(16.9e9)
    # the units crush at the masonry's strength (10.34 MPa), not their own (65.6 MPa)
    assert case.blocks.endo3d.R_c_Pa == pytest.approx(10.34e6)
    assert case.blocks.endo3d.R_t_Pa == pytest.approx(1.034e6)


def test_case_for_cantilever_row():
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, _row("R4")))
    # 1200 mm long with 900 mm units: two units per course at least, (1200 - 10) / 2 each
    assert (case.wall.courses, case.wall.units_per_course) == (4, 2)
    assert case.wall.unit_length_m == pytest.approx(0.595)
    assert case.supports.top_rotation == "free"             # H0 / H = 1950 / 1800
    assert case.supports.load_height_m == pytest.approx(0.150)
    # the larger drift at the peak, 1.01 %, of the 1.8 m wall, times 1.5
    assert case.loading.horizontal.target_m == pytest.approx(1.5 * 0.0101 * 1.8)
    # the mortar's modulus is measured (87 MPa): its layer of 10 mm
    assert case.joint.K_I_spring_Pa_m == pytest.approx(8.7e9, rel=1e-12)


def test_case_without_mortar_modulus_uses_the_prism():
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, _row("PG1")))
    # 2500 mm, 300 mm units, 10 mm joints: 8 courses of (2500 - 70) / 8 = 303.75 mm; a prism
    # of one unit and one joint with the masonry's 360 MPa and the units' 26000 MPa
    h, j = 0.30375, 0.010
    assert case.wall.unit_height_m == pytest.approx(h)
    K = case.joint.K_I_spring_Pa_m
    assert h / 26000e6 + 1 / K == pytest.approx((h + j) / 360e6, rel=1e-12)


def test_case_for_dry_row_takes_the_dry_law_and_touching_units():
    base = read_yaml(TEMPLATE.read_text())
    row = {**_row("SC5"), "joints": "Dry", "mortar_fc_MPa": "", "mortar_E_MPa": ""}
    case = case_from_dict(campaign.case_for_row(base, row))
    assert case.joint.law == "dry" and case.wall.joint_thickness_m == 0.0
    # 900 mm high in 7 courses of 900 / 7 mm: the prism of one unit with the masonry's and the
    # units' moduli in series gives the closure stiffness, a sixth of it less in shear
    h = 0.9 / 7
    E_m, E_u = float(row["masonry_E_compression_MPa"]), float(row["unit_E_MPa"])
    assert case.wall.unit_height_m == pytest.approx(h)
    assert h / (E_u * 1e6) + 1 / case.joint.K_n_Pa_m == pytest.approx(h / (E_m * 1e6), rel=1e-12)
    assert case.joint.K_t_Pa_m == pytest.approx(case.joint.K_n_Pa_m / 2.4, rel=1e-12)
    assert case.joint.mu == 0.65
    assert case.blocks.material == "endo3d"  # the units crush and split, dry or mortared
    assert case.blocks.endo3d.R_c_Pa == pytest.approx(float(row["masonry_fc_MPa"]) * 1e6)


def test_a_row_without_the_numbers_its_rules_need_is_named(tmp_path):
    rows = list(csv.DictReader(TESTS_CSV.open()))
    rows[0]["unit_fc_MPa"] = rows[0]["masonry_fc_MPa"] = ""  # no compression test at all
    rows[1]["joints"], rows[1]["masonry_E_compression_MPa"] = "dry", ""  # a dry wall, no E_m
    table = tmp_path / "tests.csv"
    with table.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows[:2])
    with pytest.raises(campaign.SweepError) as err:
        campaign.campaign_points(table, TEMPLATE)
    text = str(err.value)
    assert f"{rows[0]['test']}: unit_fc_MPa is empty" in text
    assert f"{rows[1]['test']}: masonry_E_compression_MPa is empty" in text


def test_a_table_without_the_columns_it_may_leave_empty_is_read(tmp_path):
    """The units' and the mortar's strengths may be absent from a table whose walls have the
    masonry's strength; a row that needs one then names it."""
    rows = list(csv.DictReader(TESTS_CSV.open()))[:1]
    for row in rows:
        del row["unit_fc_MPa"], row["mortar_fc_MPa"]
    table = tmp_path / "tests.csv"
    with table.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert len(campaign.read_tests(table)) == 1
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, rows[0]))
    assert case.blocks.endo3d.R_c_Pa == pytest.approx(float(rows[0]["masonry_fc_MPa"]) * 1e6)
    del rows[0]["masonry_fc_MPa"]
    with pytest.raises(ValueError, match=r"unit_fc_MPa is empty \(no such column\)"):
        campaign.case_for_row(base, rows[0])


def test_units_not_tested_crush_at_the_masonrys_strength():
    """The units' own strength is not needed where the masonry's was measured."""
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, {**_row("PG1"), "unit_fc_MPa": ""}))
    assert case.blocks.endo3d.R_c_Pa == pytest.approx(3.22e6)


def test_a_mortar_not_tested_takes_the_weakest_class():
    """Where the mortar's strength is missing, the joint strengths are those published for the
    weakest mortars (Eurocode 6, M1-M2: f_vk0 0.10 MPa), those of historic lime mortars."""
    base = read_yaml(TEMPLATE.read_text())
    case = case_from_dict(campaign.case_for_row(base, {**_row("SC5"), "mortar_fc_MPa": ""}))
    assert case.joint.law == "fczm"
    assert case.joint.sigma_II_e_Pa == pytest.approx(0.10e6 / 0.8)
    assert case.joint.sigma_I_e_Pa == pytest.approx(0.10e6 / 0.8 / 1.4)


def test_number_and_measured():
    assert campaign.number("110-140") == 125.0
    assert campaign.number("") is None
    assert campaign.measured(_row("PG1"))["peak_kN"] == pytest.approx((105.6 + 112.5) / 2)
    assert campaign.measured(_row("SC7"))["peak_kN"] == pytest.approx(103.0)


def test_dry_run_validates_every_row(tmp_path):
    result = campaign.run_campaign(TESTS_CSV, TEMPLATE, tmp_path / "c", dry_run=True,
                                   echo=lambda s: None)
    assert len(result.rows) == 14
    assert len(list((tmp_path / "c" / "cases").glob("*.yaml"))) == 14
    assert (tmp_path / "c" / "campaign.csv").is_file()


def test_only_refuses_an_unknown_test(tmp_path):
    with pytest.raises(campaign.SweepError):
        campaign.run_campaign(TESTS_CSV, TEMPLATE, tmp_path / "c", only=["XX"], dry_run=True,
                              echo=lambda s: None)


# --- curves and statistics ------------------------------------------------------------------


def test_statistics_on_made_up_errors():
    s = campaign.statistics_of([0.1, -0.2, 0.05, None, 0.15])
    assert s["count"] == 4 and s["within"] == 3
    assert s["median_abs_error"] == pytest.approx(0.125)
    assert s["mean_error"] == pytest.approx(0.025)
    assert campaign.statistics_of([None])["count"] == 0


def test_secant_and_envelope():
    # 15 % of 100 kN is reached half way between 1 and 2 mm
    assert campaign.secant_stiffness(np.array([0, 1, 2, 3.0]),
                                     np.array([0, 10, 20, 100.0])) == pytest.approx(10.0)
    u = np.array([0, 1, 0, -1, 0, 2, 1, -2, 0.0])
    f = np.array([0, 5, 0, -4, 0, 8, 2, -7, 0.0])
    eu, ef = campaign.envelope(u, f, 1.0)
    assert eu.tolist() == [1, 2] and ef.tolist() == [5, 8]
    eu, ef = campaign.envelope(u, f, -1.0)
    assert eu.tolist() == [1, 2] and ef.tolist() == [4, 7]


def test_failure_class():
    assert campaign.failure_class("diagonal stair-step") == 0.0
    assert campaign.failure_class("base sliding") == 0.0
    assert campaign.failure_class("rocking") == 1.0
    assert campaign.failure_class("rocking, toe crushing") == 1.0
    assert campaign.failure_class("rocking, diagonal stair-step") == 0.5
    assert campaign.failure_class("n/a") is None
    assert math.isclose(campaign.relative_error(115.0, 100.0), 0.15)


def test_envelope_of_a_backbone():
    # a curve listed from the largest pull to the largest push is its own envelope
    u = np.array([-3, -1, 0, 2, 4.0])
    f = np.array([-9, -5, 0, 6, 8.0])
    eu, ef = campaign.envelope(u, f, 1.0)
    assert eu.tolist() == [2, 4] and ef.tolist() == [6, 8]
    eu, ef = campaign.envelope(u, f, -1.0)
    assert eu.tolist() == [1, 3] and ef.tolist() == [5, 9]


def test_command_dry_run_and_bad_only(tmp_path):
    from typer.testing import CliRunner

    from masonry_nscd.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["campaign", str(TESTS_CSV), "--template", str(TEMPLATE), "-o",
                              str(tmp_path / "c"), "--only", "SC7,R4", "--dry-run"])
    assert res.exit_code == 0, res.output
    assert sorted(p.stem for p in (tmp_path / "c" / "cases").glob("*.yaml")) == ["R4", "SC7"]
    res = runner.invoke(app, ["campaign", str(TESTS_CSV), "--template", str(TEMPLATE), "-o",
                              str(tmp_path / "d"), "--only", "XX", "--dry-run"])
    assert res.exit_code == 2 and "XX" in res.output


def test_set_overrides_the_template_for_every_test_but_not_the_rows_fields(tmp_path):
    """``--set`` changes the template's mesh in every written case; a field that the row sets
    (the units' modulus) stays the row's; a path the schema lacks exits 2 naming it."""
    from typer.testing import CliRunner

    from masonry_nscd.case import load_case
    from masonry_nscd.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["campaign", str(TESTS_CSV), "--template", str(TEMPLATE), "-o",
                              str(tmp_path / "c"), "--only", "SC7,R4", "--dry-run",
                              "--set", "wall.elements_per_unit=[3,2,1]",
                              "--set", "blocks.E_Pa=1.0e9"])
    assert res.exit_code == 0, res.output
    for name, unit_E_MPa in (("SC7", 16900), ("R4", 20000)):
        case = load_case(tmp_path / "c" / "cases" / f"{name}.yaml")
        assert tuple(case.wall.elements_per_unit) == (3, 2, 1)
        assert case.blocks.E_Pa == pytest.approx(unit_E_MPa * 1e6)
    res = runner.invoke(app, ["campaign", str(TESTS_CSV), "--template", str(TEMPLATE), "-o",
                              str(tmp_path / "d"), "--dry-run", "--set", "wall.mesh=[3,2,1]"])
    assert res.exit_code == 2 and "wall.mesh" in res.output


def test_result_row_of_a_made_up_run():
    from masonry_nscd.studies.point import RunRecord

    point = campaign.campaign_points(TESTS_CSV, TEMPLATE, ["SC7"])[0]
    record = RunRecord("SC7", "ok", curve={"ux_mm": [0.0, 0.5, 1.0, 2.0],
                                           "fx_kN": [0.0, 50.0, 100.0, 80.0]},
                       outputs={"failure_mode_at_peak": {"mode": "diagonal stair-step"}})
    row = campaign.result_row(_row("SC7"), point, record)
    assert row["rig"] == "fixed-fixed"
    assert row["predicted_peak_kN"] == 100.0
    assert row["peak_error"] == pytest.approx(100 / 103 - 1)
    assert row["predicted_drift_pct"] == pytest.approx(1.0 / 900 * 100)    # 1 mm of 0.9 m
    assert row["drift_ratio"] == pytest.approx((1.0 / 9) / 0.64)
    assert row["predicted_stiffness_kN_mm"] == pytest.approx(100.0)      # 15 kN at 0.15 mm
    assert row["stiffness_ratio"] == pytest.approx(100 / 216)
    assert row["predicted_class"] == 0.0 == row["measured_class"]
    # SC7 was pushed one way (monotonic): its push against the push, no pull
    assert row["measured_peak_push_kN"] == 103.0 and row["measured_peak_pull_kN"] is None
    assert row["peak_push_error"] == pytest.approx(100 / 103 - 1)
    assert row.get("predicted_peak_pull_kN") is None
    # a cyclic run of R4 (61.5 kN pushed, 69.8 pulled): each direction against its own
    point = campaign.campaign_points(TESTS_CSV, TEMPLATE, ["R4"], cyclic=True)[0]
    record = RunRecord("R4", "ok", curve={"ux_mm": [0.0, 5.0, 0.0, -5.0, 0.0],
                                          "fx_kN": [0.0, 60.0, 0.0, -70.0, 0.0]}, outputs={})
    cyc = campaign.result_row(_row("R4"), point, record)
    assert (cyc["measured_peak_push_kN"], cyc["measured_peak_pull_kN"]) == (61.5, 69.8)
    assert (cyc["predicted_peak_push_kN"], cyc["predicted_peak_pull_kN"]) == (60.0, 70.0)
    assert cyc["peak_push_error"] == pytest.approx(60 / 61.5 - 1)
    assert cyc["peak_pull_error"] == pytest.approx(70 / 69.8 - 1)
    stats = campaign.campaign_statistics([row, {**row, "drift_ratio": 1.9, "stiffness_ratio": 1.6,
                                                "predicted_class": 1.0, "peak_error": 0.3}])
    assert stats["peak"]["within"] == 1 and stats["peak"]["count"] == 2    # -2.9 % and +30 %
    assert stats["drift_within_factor_2"] == 1 and stats["stiffness_within_factor_1.5"] == 0
    assert stats["class_right"] == 1


def test_energy_per_cycle_of_a_rigid_plastic_and_an_elastic_loop():
    """A rigid-plastic loop of force +-F0 between +-U takes 4 F0 U per cycle (ratio 1); an
    elastic line takes none (ratio 0); cycles are cut at the upward crossings of u = 0."""
    U, F0 = 2.0, 10.0
    one = [(0.0, 0.0), (0.0, F0), (U, F0), (U, -F0), (-U, -F0), (-U, F0), (0.0, F0)]
    u, f = (np.array(c) for c in zip(*(one + one[1:]), strict=True))
    cycles = campaign.energy_per_cycle(u, f)
    assert len(cycles) == 2
    for c in cycles:
        assert c["amplitude_mm"] == pytest.approx(U)
        assert c["energy_J"] == pytest.approx(4.0 * F0 * U)
        assert c["ratio"] == pytest.approx(1.0)
    t = np.linspace(0.0, 2.0 * np.pi, 401)
    (elastic,) = campaign.energy_per_cycle(U * np.sin(t), 5.0 * U * np.sin(t))
    assert elastic["ratio"] == pytest.approx(0.0, abs=1e-12)


def test_cyclic_option_makes_cycles_of_a_cyclic_row_only():
    """With ``cyclic`` a cyclic row's push is reversed cycles of 0.25, 0.5 and 1 times its
    target; the monotonic test (SC7) stays monotonic."""
    base = read_yaml(TEMPLATE.read_text())
    h = case_from_dict(campaign.case_for_row(base, _row("R4"), cyclic=True)).loading.horizontal
    target = 1.5 * 0.0101 * 1.8
    assert h.history == "cyclic" and h.cycles_per_amplitude == 1
    assert h.amplitudes_m == pytest.approx([0.25 * target, 0.5 * target, target])
    mono = case_from_dict(campaign.case_for_row(base, _row("SC7"), cyclic=True))
    assert mono.loading.horizontal.history == "monotonic"


def test_energy_per_cycle_ignores_noise_at_zero_and_envelopes():
    """Jitter of a measured signal around u = 0 does not cut a cycle in pieces, and a curve
    whose displacements never decrease (an envelope) has no cycles."""
    t = np.linspace(0.0, 4.0 * np.pi, 2001)
    u = 3.0 * np.sin(t) + 0.01 * np.cos(97.0 * t)
    f = 10.0 * np.cos(t)  # a circle in (u/U, f/F): E = pi U F per cycle
    cycles = campaign.energy_per_cycle(u, f)
    assert len(cycles) == 2
    assert cycles[0]["ratio"] == pytest.approx(np.pi / 4.0, rel=0.02)
    assert campaign.energy_per_cycle(np.linspace(-3.0, 3.0, 50), np.linspace(-9.0, 9.0, 50)) == []


def test_labels_of_points_side_by_side_do_not_overlap():
    """Three walls whose peaks nearly coincide (R5, PR6, SC2): each label finds a place whose
    box overlaps no point and no other label."""
    top = 160.0
    pts = [(87.75, 100.4, "R5"), (88.9, 100.6, "PR6"), (89.5, 100.1, "SC2")]
    boxes = [(a - 1.6, b - 1.6, a + 1.6, b + 1.6) for a, b, _ in pts]
    placed = [campaign._label_place(a, b, len(n), top, boxes) for a, b, n in pts]
    labels = boxes[len(pts):]
    assert len(labels) == 3 and len(placed) == 3
    for i, (x0, y0, x1, y1) in enumerate(labels):
        for j, (u0, v0, u1, v1) in enumerate(boxes):
            if j != len(pts) + i:
                assert x1 <= u0 or x0 >= u1 or y1 <= v0 or y0 >= v1
