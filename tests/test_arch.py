"""Arches of voussoirs: geometry, joints on radial planes, limit states.

The reference values come from limit analysis of the same voussoirs, computed here on its own
(not with the package): each voussoir a trapezoid on the chords of its intrados and extrados,
its weight at its centroid; the forces across the joints follow from the reaction at the left
springing (``F_x, F_y, M``) by statics; a thrust line fits in the arch when at every joint the
normal force is compressive and its eccentricity at most half the thickness,
``|M_j| <= N_j t / 2`` (no tension, no crushing, no sliding: Heyman's hypotheses), linear in the
three unknowns: a feasibility linear programme (scipy.optimize.linprog). The minimum thickness is
the smallest ``t`` for which it is feasible (bisection); the collapse multiplier of a horizontal
body force ``lambda g m`` the largest ``lambda`` for which it is (``lambda`` a fourth unknown).
Where the thrust line touches the intrados or the extrados at the limit, the hinges are.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import linprog
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, case_from_dict, load_case
from masonry_nscd.cli import app
from masonry_nscd.model.detection import find_joints
from masonry_nscd.scenes import build_scene
from masonry_nscd.scenes.arch import arch_geometry

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "arch_semicircular.yaml"
N = 24  # voussoirs of the shipped case
R = 1.0  # its centreline radius (m)


# --- limit analysis of the voussoirs, independent of the package ---------------------------------


def _cross(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _voussoirs(n: int, r: float, t: float):
    """Joint ends (intrados I, extrados E), joint normals towards higher voussoirs, and each
    voussoir's area and centroid (m^2, m) of a semicircular arch of n trapezoidal voussoirs."""
    theta = np.pi * np.arange(n + 1) / n
    u = np.stack([-np.cos(theta), np.sin(theta)], axis=1)
    inner, outer = (r - t / 2) * u, (r + t / 2) * u
    normals = np.stack([np.sin(theta), np.cos(theta)], axis=1)
    areas, centroids = [], []
    for k in range(n):
        P = np.array([inner[k], inner[k + 1], outer[k + 1], outer[k]])
        x, y = P[:, 0], P[:, 1]
        x1, y1 = np.roll(x, -1), np.roll(y, -1)
        c = x * y1 - x1 * y
        a = c.sum() / 2
        areas.append(a)
        centroids.append([((x + x1) * c).sum() / (6 * a), ((y + y1) * c).sum() / (6 * a)])
    return inner, outer, normals, np.array(areas), np.array(centroids)


def _joint_rows(n: int, r: float, t: float, point_load: int | None = None):
    """Per joint, the normal force N_j and the moment M_j about the joint's middle (signed so
    that M_j = e N_j with e > 0 towards the extrados) as affine functions ``a . x + b`` of
    ``x = (F_x, F_y, M_0, lambda)``: the reaction of the left abutment on the first voussoir,
    and the multiplier of the variable load: a horizontal body force ``lambda`` times the
    weights, or (``point_load`` = k) a downward force ``lambda`` at the middle of the extrados
    chord of voussoir k (0-based). Weights per unit of density, g and depth (m^2)."""
    inner, outer, normals, w, c = _voussoirs(n, r, t)
    mid = 0.5 * (inner + outer)
    along = (outer - inner) / t  # from intrados to extrados

    def below(values):  # sum over the voussoirs below each joint j = 0..n
        return np.concatenate([np.zeros((1, *np.shape(values)[1:])), np.cumsum(values, axis=0)])

    W, Wc = below(w), below(w[:, None] * c)  # weights below, and their first moments
    if point_load is None:  # lambda w_k along x at each centroid
        f = np.stack([W, np.zeros(n + 1)], axis=1)
        lever = -(Wc[:, 1] - mid[:, 1] * W)  # sum (c_k - m_j) x (w_k, 0)
    else:  # lambda (0, -1) at the middle of the extrados chord of voussoir point_load
        q = 0.5 * (outer[point_load] + outer[point_load + 1])
        on = np.arange(n + 1) > point_load
        f = np.where(on[:, None], [0.0, -1.0], 0.0)
        lever = np.where(on, -(q[0] - mid[:, 0]), 0.0)
    rows = []
    for j in range(n + 1):
        # force of the lower part on the upper one: F_j = (F_x, F_y - W_j) + lambda f_j
        aN = np.array([normals[j, 0], normals[j, 1], 0.0, f[j] @ normals[j]])
        bN = -W[j] * normals[j, 1]
        d = mid[0] - mid[j]
        # moment about the joint's middle: M_0 + (m_0 - m_j) x F_0 + sum (p - m_j) x f
        aM = np.array([-d[1], d[0], 1.0, lever[j]])
        bM = -(Wc[j, 0] - mid[j, 0] * W[j])
        sign = along[j, 0] * normals[j, 1] - along[j, 1] * normals[j, 0]  # e x n
        rows.append((aN, bN, sign * aM, sign * bM))
    return rows


def _programme(n, r, t, objective, lam_free, point_load=None):
    rows = _joint_rows(n, r, t, point_load)
    A, b = [], []
    for aN, bN, aM, bM in rows:
        A += [aM - t / 2 * aN, -aM - t / 2 * aN, -aN]
        b += [t / 2 * bN - bM, t / 2 * bN + bM, bN]
    bounds = [(None, None)] * 3 + [(0.0, None) if lam_free else (0.0, 0.0)]
    res = linprog(objective, A_ub=np.array(A), b_ub=np.array(b), bounds=bounds, method="highs")
    return res, rows


def min_thickness_ratio(n: int) -> float:
    """The smallest t / R for which a thrust line of the self-weight fits (bisection)."""
    lo, hi = 0.05, 0.2
    for _ in range(32):  # to 4e-11
        mid = 0.5 * (lo + hi)
        res, _ = _programme(n, 1.0, mid, np.zeros(4), False)
        lo, hi = (lo, mid) if res.status == 0 else (mid, hi)
    return hi


def limit_hinges(n: int, t: float, lam_free: bool, point_load=None) -> dict[int, str]:
    """Joint -> face (intrados/extrados) where the thrust line touches the arch at the limit:
    at t (just above the minimum thickness; self-weight), or at the largest lambda."""
    res, rows = _programme(n, 1.0, t, np.array([0, 0, 0, -1.0]) if lam_free else np.zeros(4),
                           lam_free, point_load)
    assert res.status == 0
    out = {}
    for j, (aN, bN, aM, bM) in enumerate(rows):
        e = (aM @ res.x + bM) / (aN @ res.x + bN) / (t / 2)
        if abs(e) > 0.999:
            out[j] = "extrados" if e > 0 else "intrados"
    return out


def collapse_multiplier(n: int, t: float, point_load: int | None = None) -> float:
    res, _ = _programme(n, 1.0, t, np.array([0, 0, 0, -1.0]), True, point_load)
    assert res.status == 0
    return float(res.x[3])


def test_limit_analysis_reproduces_couplet_heyman():
    """The programme's own check: many voussoirs give Heyman's t/R = 0.1075 (Ochsendorf's
    0.1075 with the rupture joint at 54.5 deg from the crown)."""
    assert min_thickness_ratio(400) == pytest.approx(0.1075, abs=5e-4)
    hinges = limit_hinges(400, 1.000001 * min_thickness_ratio(400), False)
    haunch = min(j for j, side in hinges.items() if side == "intrados")
    assert 90.0 - 180.0 * haunch / 400 == pytest.approx(54.5, abs=0.5)


# --- geometry and joints ---------------------------------------------------------------------------


@pytest.mark.parametrize("n", [5, 24])
def test_semicircular_geometry(n):
    g = arch_geometry("semicircular", 1.2, 2.4, 0.2, n)
    area = sum(0.5 * abs(_cross(q[2] - q[0], q[3] - q[1])) for q in g.quads)
    # n trapezoids: (R_e^2 - R_i^2) sin(pi/n) / 2 each
    assert area == pytest.approx(n * 2 * 1.2 * 0.2 * np.sin(np.pi / n) / 2, rel=1e-12)
    radial = g.joints_out - g.joints_in
    assert np.allclose(_cross(radial, g.joints_in), 0.0, atol=1e-12)  # through the centre
    assert np.allclose(np.einsum("jd,jd->j", radial, g.normals), 0.0, atol=1e-12)
    assert (g.crown_joint is None) == (n % 2 == 1)


def test_pointed_geometry_is_symmetric_with_a_vertical_crown_joint():
    g = arch_geometry("pointed", 1.5, 2.0, 0.2, 10)
    assert g.crown_joint == 5
    assert np.allclose(g.joints_in[5, 0], 0.0) and np.allclose(g.joints_out[5, 0], 0.0)
    assert np.allclose(g.normals[5], (1.0, 0.0))
    mirror = g.joints_in[::-1] * np.array([-1.0, 1.0])
    assert np.allclose(g.joints_in, mirror, atol=1e-12)
    c = 1.5 - 1.0  # the left arc's centre is at (c, 0): its joints are radial about it
    left = slice(0, 5)
    radial = g.joints_out[left] - g.joints_in[left]
    assert np.allclose(_cross(radial, g.joints_in[left] - [c, 0.0]), 0.0, atol=1e-12)


@pytest.mark.parametrize(("material", "gap", "divisions"), [
    ("rigid", 0.0, (1, 1, 1)), ("rigid", 0.01, (1, 1, 1)), ("elastic", 0.0, (2, 2, 1))])
def test_detection_finds_the_radial_joints(material, gap, divisions):
    """Generic contact detection on radial planes: every joint of the arch (n - 1 between
    voussoirs, 2 springings) is found, its points at the corners of the face (Gauss-Lobatto),
    on the candidate's face and on the antagonist's plane (gap = the joint thickness), with
    the joint's normal, tributary areas summing to the face's, frames orthonormal."""
    n, t, depth = 9, 0.2, 0.3
    case = case_from_dict({"arch": {"voussoirs": n, "thickness_m": t, "depth_m": depth,
                                    "joint_thickness_m": gap,
                                    "elements_per_voussoir": list(divisions)},
                           "blocks": {"material": material}, "joint": {"law": "coulomb"}})
    scene = build_scene(case)
    g = arch_geometry("semicircular", 1.0, 2.0, t, n, gap)
    joints = find_joints(scene.bodies, max_gap=gap).joints
    assert len(joints) == n + 1
    by_pair: dict[tuple[int, int], list] = {}
    for p in scene.points:
        by_pair.setdefault(tuple(sorted(p.bodies)), []).append(p)
    assert len(by_pair) == n + 1
    corners = (divisions[1] + 1) * (divisions[2] + 1)  # the face's nodes
    for (b0, b1), pts in by_pair.items():
        j = b1 if b1 < n else (0 if b0 == 0 else n)  # joint j between voussoirs j and j+1
        normal = np.array([*g.normals[j], 0.0])
        assert len(pts) == corners
        assert sum(p.area for p in pts) == pytest.approx(t * depth, rel=1e-9)
        for p in pts:
            assert abs(abs(p.frame[0] @ normal) - 1.0) < 1e-12
            assert np.allclose(p.frame @ p.frame.T, np.eye(3), atol=1e-12)
            assert p.gap == pytest.approx(gap, abs=1e-12)
            # on the joint's line, between intrados and extrados, moved by the gap's half
            rel = p.x[:2] - g.joints_in[j]
            along = (g.joints_out[j] - g.joints_in[j]) / t
            assert abs(rel @ g.normals[j]) == pytest.approx(gap / 2, abs=1e-12)
            assert -1e-12 <= rel @ along <= t + 1e-12


def test_arch_case_checks():
    with pytest.raises(CaseError, match="arch.voussoirs"):
        case_from_dict({"arch": {"shape": "pointed", "span_m": 2.0, "radius_m": 1.5,
                                 "voussoirs": 9}})
    with pytest.raises(CaseError, match="arch.radius_m"):
        case_from_dict({"arch": {"shape": "pointed", "span_m": 2.0, "radius_m": 0.9}})
    with pytest.raises(CaseError, match="arch.thickness_m"):
        case_from_dict({"arch": {"radius_m": 1.0, "thickness_m": 2.5}})
    with pytest.raises(CaseError, match="loading.point_load.block"):
        case_from_dict({"arch": {}, "loading": {"point_load": {"block": "voussoir 99"}}})
    with pytest.raises(CaseError, match="supports"):
        case_from_dict({"arch": {}, "supports": {"top_vertical": "fixed"}})
    with pytest.raises(CaseError, match="loading.body_force"):
        case_from_dict({"loading": {"body_force": {"rate_per_s": 0.1}}})
    case = case_from_dict({"arch": {"span_m": 3.0, "radius_m": None}})
    assert case.arch.centreline_radius_m == 1.5


def test_cli_threshold_refuses_bad_input(tmp_path):
    res = CliRunner().invoke(app, ["threshold", str(ROOT / "cases" / "smoke.yaml"), "--param",
                                   "wall.thickness_m", "--bounds", "0.1:0.2", "-o",
                                   str(tmp_path / "a")])
    assert res.exit_code == 2 and "arch" in res.output
    res = CliRunner().invoke(app, ["threshold", str(CASE), "--param", "arch.thickness",
                                   "--bounds", "0.1:0.2", "-o", str(tmp_path / "b")])
    assert res.exit_code == 2 and "arch.thickness" in res.output
    res = CliRunner().invoke(app, ["threshold", str(CASE), "--param", "arch.thickness_m",
                                   "--bounds", "0.2:0.1", "-o", str(tmp_path / "c")])
    assert res.exit_code == 2 and "--bounds" in res.output
    res = CliRunner().invoke(app, ["threshold", str(CASE), "--param", "arch.thickness_m",
                                   "--bounds", "0.1:3.0", "-o", str(tmp_path / "d")])
    assert res.exit_code == 2 and "arch.thickness_m" in res.output


# --- limit states ------------------------------------------------------------------------------


def _run(tmp_path, name, *overrides):
    from masonry_nscd.run import run_case

    case = load_case(CASE, ["output.vtu=false", *overrides])
    run_case(case, tmp_path / name, echo=lambda _m: None)
    return json.loads((tmp_path / name / "summary.json").read_text())


def _assert_hinges_at(summary, reference: dict[int, str]):
    """Every hinge of the limit analysis has a hinge of the run on the same face, at that
    joint or at the next one (within a voussoir)."""
    found = {h["joint"]: h["side"] for h in summary["hinges"]}
    assert len(found) >= 4, found
    for j, side in reference.items():
        near = [k for k in (j - 1, j, j + 1) if found.get(k) == side]
        assert near, (j, side, found)


def test_minimum_thickness_by_threshold(tmp_path):
    """``masonry threshold`` on the thickness of the 24-voussoir arch under its own weight
    finds t/R within 3 % of limit analysis; the arch stands 10 % above it and collapses 10 %
    below, with its hinges where the thrust line touches the arch at the limit."""
    ratio = min_thickness_ratio(N)
    assert ratio == pytest.approx(0.1071, abs=5e-4)  # 24 voussoirs (0.1075 for many)
    common = ["--set", "loading.body_force.rate_per_s=0", "--set", "collapse.end_time_s=2"]
    res = CliRunner().invoke(app, ["threshold", str(CASE), "--param", "arch.thickness_m",
                                   "--bounds", "0.09:0.13", "--rtol", "0.005", *common, "-o",
                                   str(tmp_path / "threshold")])
    assert res.exit_code == 0, res.output
    found = json.loads((tmp_path / "threshold" / "threshold.json").read_text())
    assert found["status_low"] == "collapse" and found["status_high"] == "standing"
    assert found["value"] / R == pytest.approx(ratio, rel=0.03)
    assert (tmp_path / "threshold" / "threshold.csv").read_text().startswith("run,value,status")
    above = _run(tmp_path, "above", f"arch.thickness_m={1.1 * ratio * R!r}", *common[1::2])
    assert above["status"] == "standing" and above["collapse"] is None
    assert above["hinges"] == [] and not above["moving_at_end"]
    below = _run(tmp_path, "below", f"arch.thickness_m={0.9 * ratio * R!r}", *common[1::2])
    assert below["status"] == "collapse"
    _assert_hinges_at(below, limit_hinges(N, 1.000001 * ratio * R, False))


def test_collapse_multiplier_of_a_horizontal_body_force(tmp_path):
    """The shipped case (t/R = 0.15) under a slowly growing horizontal body force: the
    multiplier at the onset of the mechanism within 2 % of limit analysis, and the four-hinge
    mechanism where limit analysis puts it."""
    t = load_case(CASE).arch.thickness_m
    lam = collapse_multiplier(N, t)
    s = _run(tmp_path, "lambda", "loading.body_force.rate_per_s=0.02",
             "collapse.onset_velocity_m_s=1e-4", "collapse.end_time_s=10")
    assert s["status"] == "collapse"
    assert s["collapse"]["loads_at_onset"]["lambda"] == pytest.approx(lam, rel=0.02)
    assert s["mechanism"] == "four-hinge"
    _assert_hinges_at(s, limit_hinges(N, t, True))


def test_onset_read_on_kinetic_energy_is_the_limit_multiplier(tmp_path):
    """The same run with the onset read on the voussoirs' kinetic energy, at the energy of the
    whole arch moving at the speed the test above calls rest (1e-4 m/s): the multiplier at
    the onset within 2 % of limit analysis too, and no later than the detection."""
    from masonry_nscd.scenes import build_scene

    case = load_case(CASE)
    t = case.arch.thickness_m
    scene = build_scene(case)
    mass = sum(scene.bodies[i].mass for i in scene.structure)  # rigid voussoirs (kg)
    rest_J = 0.5 * mass * 1e-4 ** 2
    s = _run(tmp_path, "energy", "loading.body_force.rate_per_s=0.02",
             f"collapse.onset_kinetic_energy_J={rest_J!r}", "collapse.end_time_s=10")
    assert s["status"] == "collapse"
    onset = s["collapse"]["loads_at_onset"]["lambda"]
    assert onset == pytest.approx(collapse_multiplier(N, t), rel=0.02)
    assert onset <= s["collapse"]["loads_at_detection"]["lambda"]


@pytest.mark.parametrize("damping", [False, True])
@pytest.mark.parametrize("part", [0.98, 1.02])
def test_a_held_body_force_stands_below_the_limit_and_collapses_above(tmp_path, part, damping):
    """The body force grown at the case's rate and held at ``part`` of the limit multiplier
    (rigid voussoirs: below it admissible forces carry the load, above none do): at 0.98 the
    arch comes to rest, its voussoirs displaced by the joints' springs alone (microns), at
    1.02 it collapses under the load it was held at; the same with kinetic damping, the
    mechanism above the limit still gaining kinetic energy."""
    case = load_case(CASE)
    bf = case.loading.body_force
    held = part * collapse_multiplier(N, case.arch.thickness_m)
    # after the ramp lambda = rate (t - start - ramp / 2)
    hold_s = bf.start_s + bf.ramp_s / 2 + held / bf.rate_per_s
    s = _run(tmp_path, "held", f"loading.body_force.hold_s={hold_s!r}",
             f"collapse.end_time_s={hold_s + 3.0!r}",
             f"solver.kinetic_damping={str(damping).lower()}")
    assert s["last_loads"]["lambda"] == pytest.approx(held, rel=1e-9)
    if part < 1.0:
        assert s["status"] == "standing" and not s["moving_at_end"]
        last = (tmp_path / "held" / "limit.csv").read_text().splitlines()[-1].split(",")
        assert float(last[3]) < 1e-4  # the largest displacement (m)
        creep = s["creep_at_end"]  # at rest: nothing grows over the run's last tenth
        assert creep["window_s"] == pytest.approx(0.1 * (hold_s + 3.0), rel=0.01)
        assert abs(creep["growth_m"]) < 1e-7
    else:
        assert s["status"] == "collapse"
        assert s["mechanism"] == "four-hinge"


def test_a_hold_before_the_load_starts_is_refused():
    with pytest.raises(CaseError, match="hold_s.*after start_s"):
        load_case(CASE, ["loading.body_force.hold_s=0.1"])


def test_collapse_load_of_a_point_load(tmp_path):
    """A force growing on the extrados of voussoir 7 (37.5 to 45 deg from the springing):
    the force at the onset within 2 % of limit analysis, and its four hinges."""
    t = load_case(CASE).arch.thickness_m
    per_area = 2000.0 * 9.81 * 0.25  # N per m^2 of the weights of _voussoirs
    force = collapse_multiplier(N, t, point_load=6) * per_area
    s = _run(tmp_path, "point", "loading.body_force.rate_per_s=0",
             "loading.point_load={block: voussoir 7, rate_N_s: 200}",
             "collapse.end_time_s=10")
    assert s["status"] == "collapse"
    assert s["collapse"]["loads_at_onset"]["point_load_N"] == pytest.approx(force, rel=0.02)
    assert s["mechanism"] == "four-hinge"
    _assert_hinges_at(s, limit_hinges(N, t, True, point_load=6))


def test_settlement_opens_the_spreading_mechanism(tmp_path):
    """The right support moving out by 2 cm and down by 1 cm: the arch follows on three hinges,
    the crown turning about its extrados and the haunches about their intrados, and stands."""
    s = _run(tmp_path, "settle", "loading.body_force.rate_per_s=0",
             "loading.settlement={support: right, displacement_m: [0.02, -0.01, 0.0], "
             "duration_s: 2.0}", "collapse.displacement_m=0.05", "collapse.end_time_s=3")
    assert s["status"] == "standing" and s["mechanism"] == "three-hinge"
    sides = {h["side"] for h in s["hinges"] if h["angle_from_crown_deg"] < 10.0}
    assert sides == {"extrados"}
    assert {h["side"] for h in s["hinges"] if h["angle_from_crown_deg"] > 30.0} == {"intrados"}
    assert s["last_loads"]["settlement_m"] == pytest.approx(math.hypot(0.02, 0.01), rel=1e-9)


def test_thrust_of_the_standing_arch_is_statically_admissible(tmp_path):
    """Under its own weight the arch's horizontal thrust lies between the smallest and the
    largest thrust of the admissible thrust lines, and each support carries half the weight."""
    t = load_case(CASE).arch.thickness_m
    s = _run(tmp_path, "gravity", "loading.body_force.rate_per_s=0", "collapse.end_time_s=0.3")
    assert s["status"] == "standing"
    thrust = [_programme(N, R, t, np.array([sign, 0, 0, 0]), False)[0] for sign in (1, -1)]
    h_min, h_max = thrust[0].x[0], thrust[1].x[0]
    per_area = 2000.0 * 9.81 * 0.25 * 1e-3  # kN per m^2 of the weights of _voussoirs
    left = s["support_forces_last_kN"]["left"]
    assert h_min * per_area * (1 - 1e-6) <= left[0] <= h_max * per_area * (1 + 1e-6)
    weight = _voussoirs(N, R, t)[3].sum() * per_area
    assert left[1] == pytest.approx(weight / 2, rel=1e-6)
    assert s["support_forces_last_kN"]["right"][0] == pytest.approx(-left[0], rel=1e-6)


def test_mechanism_plot(tmp_path):
    from masonry_nscd.plots import plot_runs

    _run(tmp_path, "collapse", "arch.thickness_m=0.095", "loading.body_force.rate_per_s=0",
         "collapse.end_time_s=1")
    written, _ = plot_runs([tmp_path / "collapse"], tmp_path / "plots")
    assert [p.name for p in written] == ["mechanism_arch_semicircular.png"]
    assert written[0].stat().st_size > 10_000


# --- the tilting table -------------------------------------------------------------------------


@pytest.mark.parametrize(("mu", "mode"), [(0.6, "topples"), (0.2, "slides")])
def test_block_on_a_tilting_base(mu, mode):
    """A rigid block b x h = 0.1 x 0.4 m on a base tilted by atan(lambda) (gravity and a
    growing horizontal body force lambda g m): it topples at lambda = b / h = 0.25 when
    mu > b / h, and slides first at lambda = mu when mu < b / h; within 2 %."""
    from masonry_nscd.collapse import watch
    from masonry_nscd.scenes.small import tilting_block

    b, h = 0.1, 0.4
    out = watch(tilting_block(width=b, height=h, mu=mu, rate_per_s=0.05), 10.0)
    assert out["status"] == "collapse"
    expected = b / h if mode == "topples" else mu
    assert out["collapse"]["loads_at_onset"]["lambda"] == pytest.approx(expected, rel=0.02)
    u = out["u"][0]  # the block's dofs about its centre: ux, uy, uz, rx, ry, rz
    if mode == "topples":  # turns about its toe: rz < 0, centre up and along x
        assert u[5] < -0.01 and u[1] > 0.0
        assert u[0] == pytest.approx(-u[5] * h / 2, rel=0.05)
    else:  # slides without turning
        assert abs(u[5]) < 1e-6 and u[0] > 0.005 and abs(u[1]) < 1e-6


@pytest.mark.parametrize("damping", [False, True])
def test_interrupted_arch_resumes_to_the_same_collapse(tmp_path, interrupt_before_step,
                                                       damping):
    """``limit.csv`` is cut back to the checkpoint and the onset kept: a resumed run reports
    the collapse of an uninterrupted one; with kinetic damping too (the checkpoint keeps the
    kinetic energy the next step is compared with)."""
    from masonry_nscd.run import run_case

    sets = ["output.vtu=false", "arch.thickness_m=0.1", "loading.body_force.rate_per_s=0",
            "collapse.end_time_s=1", f"solver.kinetic_damping={str(damping).lower()}"]
    run_case(load_case(CASE, sets), tmp_path / "ref", echo=lambda _m: None)
    interrupt_before_step(100)
    with pytest.raises(KeyboardInterrupt):
        run_case(load_case(CASE, sets), tmp_path / "run", echo=lambda _m: None)
    assert json.loads((tmp_path / "run" / "limit.json").read_text())["status"] == "interrupted"
    run_case(load_case(tmp_path / "run" / "case.yaml"), tmp_path / "run", resume=True,
             echo=lambda _m: None)
    ref, out = (json.loads((tmp_path / d / "limit.json").read_text()) for d in ("ref", "run"))
    assert out["status"] == ref["status"] == "collapse"
    for key in ("onset_step", "detected_step"):
        assert out["collapse"][key] == ref["collapse"][key]
    rows, ref_rows = ((tmp_path / d / "limit.csv").read_text().splitlines()
                      for d in ("run", "ref"))
    assert [r.split(",")[0] for r in rows] == [r.split(",")[0] for r in ref_rows]


def test_hinges_are_marked_in_the_vtu_output(tmp_path):
    """An arch 10 % thinner than the minimum, under its own weight: in the joints' VTU file of
    the last output step, the points marked ``joint_state`` = 5 (hinge) lie on the joints where
    limit analysis puts the five hinges (within a voussoir), four points each, and no other
    point is marked a hinge."""
    import meshio

    from masonry_nscd.post.limit import STATE_CODES
    from masonry_nscd.run import run_case

    ratio = min_thickness_ratio(N)
    case = load_case(CASE, [f"arch.thickness_m={0.9 * ratio * R!r}",
                            "loading.body_force.rate_per_s=0", "collapse.end_time_s=1"])
    run_case(case, tmp_path / "run", echo=lambda _m: None)
    last = max((tmp_path / "run" / "vtu").glob("joints_*.vtu"))  # zero-padded steps
    m = meshio.read(last)
    state = np.asarray(m.point_data["joint_state"])
    x = np.asarray(m.points)
    assert set(np.unique(state).tolist()) <= set(STATE_CODES.values())
    hinge = x[state == STATE_CODES["hinge"]]
    joints = np.rint(np.arctan2(hinge[:, 1], -hinge[:, 0]) / (np.pi / N)).astype(int)
    found, counts = np.unique(joints, return_counts=True)
    reference = limit_hinges(N, 1.000001 * ratio * R, False)
    assert len(found) == len(reference) == 5
    for j in reference:
        assert {j - 1, j, j + 1} & set(found.tolist()), (j, found)
    assert (counts == 4).all()


def test_creep_at_end_reads_the_growth_over_the_last_tenth_of_the_run():
    """A largest displacement that grows at 2 mm/s from 0.5 s on, read over the last tenth
    of a 2 s run (rows every 0.01 s): 0.2 s, 0.4 mm, 2 mm/s, and the report's standing line
    says so; at rest, nothing (steady); with one row, no reading."""
    from masonry_nscd.post.limit import creep_at_end, format_limit

    t = np.arange(201) * 0.01
    d = np.where(t > 0.5, 1e-3 + 2e-3 * (t - 0.5), 1e-3)
    creep = creep_at_end({"time_s": t, "max_displacement_m": d})
    assert creep["window_s"] == pytest.approx(0.2)
    assert creep["growth_m"] == pytest.approx(4e-4)
    assert creep["rate_m_s"] == pytest.approx(2e-3)
    assert creep_at_end({"time_s": t, "max_displacement_m": np.full_like(t, 1e-3)})[
        "growth_m"] == 0.0
    assert creep_at_end({"time_s": t[:1], "max_displacement_m": d[:1]}) is None
    standing = {"status": "standing", "last_loads": {"lambda": 0.5}}
    line = format_limit({**standing, "creep_at_end": creep})[1]
    assert line.endswith("grew by 0.4 mm over the last 0.2 s (2 mm/s)")
    at_rest = creep_at_end({"time_s": t, "max_displacement_m": np.full_like(t, 1e-3)})
    assert "steady over the last 0.2 s" in format_limit({**standing, "creep_at_end": at_rest})[1]
