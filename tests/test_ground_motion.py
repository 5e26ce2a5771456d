"""Ground motion: the record, the base's path, and Housner's rocking block on a moving base."""

from __future__ import annotations

import math

import numpy as np
import pytest

from masonry_nscd.loading import step_velocity
from masonry_nscd.loading.ground_motion import GroundMotion, read_acceleration_record
from masonry_nscd.scenes.small import rocking_block


def test_record_is_integrated_exactly_to_velocity_and_displacement():
    # a ramp of acceleration a(t) = 2 t on [0, 1], then 2 held to 2 s, then nothing
    g = GroundMotion(np.array([0.0, 1.0, 2.0]), np.array([0.0, 2.0, 2.0]), start_s=0.5)
    assert g(0.5) == 0.0 and g.displacement(0.4) == 0.0
    assert g.acceleration(1.0) == pytest.approx(1.0)
    assert g(1.0) == pytest.approx(0.25)  # t^2 at t = 0.5
    assert g.displacement(1.0) == pytest.approx(0.125 / 3.0)  # t^3 / 3
    assert g(2.5) == pytest.approx(1.0 + 2.0 * 1.0)
    assert g.displacement(2.5) == pytest.approx(1.0 / 3.0 + 1.0 + 1.0)
    # after the record: no acceleration, constant velocity
    assert g.acceleration(3.0) == 0.0 and g(3.5) == pytest.approx(3.0)
    assert g.displacement(3.5) == pytest.approx(g.displacement(2.5) + 3.0)
    assert g.end_s == 2.5


def test_imposed_base_stays_on_its_path_whatever_the_steps():
    t = np.linspace(0.0, 1.0, 41)
    g = GroundMotion(t, 3.0 * np.sin(2 * math.pi * 3 * t))
    u = v = 0.0
    for t0, t1 in [(0.0, 0.013), (0.013, 0.02), (0.02, 0.5), (0.5, 0.5005), (0.5005, 1.0)]:
        v1 = step_velocity(g, t0, t1, 1.0, v)
        u, v = u + (t1 - t0) * v1, v1
        assert u == pytest.approx(g.displacement(t1), abs=1e-15)


@pytest.mark.parametrize(("text", "message"), [
    ("t,a\n0,0\n1,1\n", "header 'time_s,acceleration_m_s2'"),
    ("time_s,acceleration_m_s2\n0,0\n1,x\n", "line 3: expected two numbers"),
    ("time_s,acceleration_m_s2\n0,0\n0,1\n", "line 3: time 0 s does not follow 0 s"),
    ("time_s,acceleration_m_s2\n0.5,0\n1,1\n", "line 2: the record must start at time 0"),
    ("time_s,acceleration_m_s2\n0,0\n1,inf\n", "line 3: values must be finite"),
    ("time_s,acceleration_m_s2\n0,0\n", "at least two rows"),
])
def test_record_errors_name_the_line(tmp_path, text, message):
    path = tmp_path / "rec.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        read_acceleration_record(path)


def _pulse(level):
    """A base acceleration pulse along x: ramp up over 50 ms, hold 0.3 s, ramp down (m/s^2)."""
    return np.array([0.0, 0.05, 0.1, 0.4, 0.45, 0.6]), np.array([0, 0, level, level, 0, 0])


@pytest.mark.parametrize(("factor", "rocks"), [(0.98, False), (1.02, True)])
def test_block_on_moving_base_rocks_above_housners_threshold(factor, rocks):
    # Housner (1963): a rigid block of half width b and half height h on a base accelerating
    # at a rocks once a > g b / h (here b / h = 1/4, friction 0.8 > 1/4 holds the toe)
    _, info = rocking_block()
    integ, info = rocking_block(record=_pulse(factor * info["threshold_m_s2"]), h=1e-3)
    rotation = 0.0
    while integ.t < 0.6 - 1e-9:
        assert integ.step().converged
        rotation = max(rotation, abs(integ.u[info["rotation_dof"]]))
    if rocks:
        # 2 % over the threshold for 0.3 s: rotation (a - g b/h) m h t^2 / (2 I_toe), about
        # 4e-3 rad
        assert rotation > 1e-3
    else:
        assert rotation < 1e-9
    b = integ.energy_account.balance(integ)  # the base's reaction did the work
    assert b["work_of_imposed_motions"] > 0.0 and b["relative_imbalance"] < 1e-6


def test_free_rocking_impact_keeps_housners_fraction_of_angular_velocity():
    # From a tilt about its left corner the block falls back onto its right corner. At the
    # impact, the contact points (restitution 0 in Moreau-Jean: the position-level
    # Signorini condition of a theta = 1 step) stop the right corner, friction keeps it from
    # sliding, the left corner lifts off; nothing else acts in the impact, so the angular
    # momentum about the right corner is kept: omega2 / omega1 = 1 - (3/2) sin^2(alpha), the
    # scheme gives Housner's factor (the impact takes the step in which the corner arrives
    # and the next one). The kinetic energy lost, 1/2 I_O (omega1^2 - omega2^2), is counted as
    # impact dissipation.
    integ, info = rocking_block(tilt=0.01, h=1e-4)
    right = np.array([p.x[0] for p in integ.points]) > 0.1
    acc = integ.energy_account
    omega, impacts = [], []
    while integ.t < 0.1:
        integ.step()
        omega.append(integ.v[info["rotation_dof"]])
        impacts.append(acc.balance(integ)["dissipated_impacts"])
        if (integ.joints.T[right, 0] < 0.0).any() and len(omega) > 2 and omega[-2] < 0.0:
            break
    k = len(omega) - 1  # the step in which the right corner arrives
    for _ in range(2):
        integ.step()
        omega.append(integ.v[info["rotation_dof"]])
        impacts.append(acc.balance(integ)["dissipated_impacts"])
    w1, w2 = omega[k - 1], omega[k + 1]
    assert w1 < -0.2  # sqrt(2 (3 g b / 4 R^2) tilt) = 0.29 rad/s, clockwise
    assert w2 / w1 == pytest.approx(info["housner_factor"], rel=0.05)
    width, height, m = 0.2, 0.8, info["mass"]
    inertia = m * (width ** 2 + height ** 2) / 3.0  # about a corner (kg m^2)
    lost = impacts[k + 1] - impacts[k - 1]
    assert lost == pytest.approx(0.5 * inertia * (w1 ** 2 - w2 ** 2), rel=0.05)


# --- the smoke wall on a moving base ------------------------------------------------------

SMOKE = "cases/smoke.yaml"
PGA = 3.0  # m/s^2


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    """One cycle of a 5 Hz sine of acceleration, 0.2 s, then 0.1 s of rest."""
    t = np.round(np.arange(0.0, 0.3001, 0.005), 6)
    a = np.where(t <= 0.2, PGA * np.sin(2 * np.pi * 5.0 * t), 0.0)
    path = tmp_path_factory.mktemp("rec") / "pulse.csv"
    path.write_text("time_s,acceleration_m_s2\n"
                    + "".join(f"{x:g},{y:.9g}\n" for x, y in zip(t, a)))
    return path


def _run_wall(out, record, sets=()):
    from typer.testing import CliRunner

    from masonry_nscd.cli import app

    args = ["run", SMOKE, "-o", str(out), "--set", "loading.horizontal.history=none",
            "--set", f"loading.ground_motion={{file: {record}, start_s: 0.1}}",
            "--set", "output.vtu=false"]
    for s in sets:
        args += ["--set", s]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    import json

    return json.loads((out / "summary.json").read_text())


@pytest.mark.parametrize("top_beam", ["present", "absent"])
def test_wall_on_a_moving_base_reports_drift_base_shear_and_energy(tmp_path, record, top_beam):
    # the smoke wall (81 kg of units) glued to its base, with the 500 kg top beam or without it; far
    # below sliding (mu N = 48 kN), and stiff (its period ~ 0.01 s against the 0.2 s pulse):
    # it moves with the base, so the base shear is the mass times the base's acceleration
    # and the drift (top relative to base) is a small fraction of the base's motion
    sets = [] if top_beam == "present" else ["supports.top_beam=absent",
                                             "loading.vertical_stress.value_Pa=0"]
    s = _run_wall(tmp_path / "run", record, sets)
    from masonry_nscd.io.runfolder import read_curve_csv

    curve = read_curve_csv(tmp_path / "run" / "force_displacement.csv")
    assert s["history"] == "ground_motion" and s["peak_force_kN"] is None
    assert s["last_time_s"] == pytest.approx(0.1 + 0.3)
    # courses of 3 x 0.3 m, 2 x 0.3 + 2 x 0.145 m, 3 x 0.3 m; units 0.1 x 0.15 m, 2000 kg/m^3
    mass = (0.9 + 0.89 + 0.9) * 0.1 * 0.15 * 2000.0 + (500.0 if top_beam == "present" else 0.0)
    assert abs(s["peak_base_shear_kN"]) == pytest.approx(1e-3 * mass * PGA, rel=0.02)
    base = GroundMotion(*read_acceleration_record(record), start_s=0.1)
    travel = max(abs(base.displacement(x)) for x in np.linspace(0.1, 0.4, 301))
    assert travel > 2e-3  # the base moves by millimetres
    assert abs(s["peak_drift_mm"]) < 0.02 * 1e3 * travel
    if top_beam == "absent":
        assert not np.any(curve["fx_kN"])  # no top beam, no force from it
        assert "top course" in s["measured"]
    assert s["energy_worst_relative_imbalance"] < 1e-6
    assert s["energy"]["work_of_imposed_motions_J"] > 0.0


def test_ground_motion_figure(tmp_path, record):
    from masonry_nscd.plots import plot_runs

    _run_wall(tmp_path / "run", record, ["output.hdf5=false"])
    written, _ = plot_runs([tmp_path / "run"], tmp_path / "plots")
    assert [p.name for p in written] == ["ground_motion_smoke.png"]


@pytest.mark.parametrize(("data", "field"), [
    ({"loading": {"ground_motion": {"file": "r.csv"}}}, "loading.horizontal.history"),
    ({"loading": {"horizontal": {"history": "none"}}}, "loading.horizontal.history"),
    ({"supports": {"top_beam": "absent"}, "loading": {"vertical_stress": {"value_Pa": 0}}},
     "supports.top_beam"),
    ({"supports": {"top_beam": "absent"}, "loading": {
        "horizontal": {"history": "none"}, "ground_motion": {"file": "r.csv"}}},
     "loading.vertical_stress.value_Pa"),
    ({"supports": {"top_vertical": "load_then_fixed"}, "loading": {
        "horizontal": {"history": "none"}, "ground_motion": {"file": "r.csv"}}},
     "supports.top_vertical"),
    ({"loading": {"horizontal": {"history": "none"},
                  "ground_motion": {"file": "r.csv", "scale": 0}}},
     "loading.ground_motion.scale"),
    ({"loading": {"horizontal": {"history": "none"},
                  "ground_motion": {"file": "r.csv", "direction": "z"}}},
     "loading.ground_motion.direction"),
])
def test_ground_motion_case_errors_name_the_field(data, field):
    from masonry_nscd.case import CaseError, case_from_dict

    with pytest.raises(CaseError) as err:
        case_from_dict(data)
    assert any(m.startswith(field) for m in err.value.messages), err.value.messages


def test_ground_motion_record_is_read_relative_to_the_case(tmp_path):
    from masonry_nscd.case import CaseError, load_case

    (tmp_path / "r.csv").write_text("time_s,acceleration_m_s2\n0,0\n0.1,1\n0.2,0\n")
    (tmp_path / "c.yaml").write_text(
        "loading:\n  horizontal: {history: none}\n  ground_motion: {file: r.csv, scale: 2}\n")
    case = load_case(tmp_path / "c.yaml")
    gm = case.loading.ground_motion
    assert gm.file == str(tmp_path / "r.csv")
    assert gm.history().peak_acceleration_m_s2 == 2.0
    assert case.loading.end_time_s == pytest.approx(0.25 + 0.2)
    (tmp_path / "r.csv").write_text("time_s,acceleration_m_s2\n0,0\n0.1,a\n")
    with pytest.raises(CaseError, match="loading.ground_motion.file: .*line 3"):
        load_case(tmp_path / "c.yaml")


def test_bench_and_calibrate_refuse_a_ground_motion():
    from masonry_nscd.case import case_from_dict
    from masonry_nscd.studies import bench, calibrate

    case = case_from_dict({"loading": {"horizontal": {"history": "none"},
                                       "ground_motion": {"file": "r.csv"}}})
    for check in (bench.check_history, calibrate.check_history):
        with pytest.raises(ValueError, match="loading.horizontal.history: got 'none'"):
            check(case)


def test_a_sweep_over_the_record_scale_tables_drift_and_base_shear(tmp_path, record):
    """`masonry sweep` of a ground-motion case fills the drift and base-shear columns; the wall
    moves with its base (see above), so twice the record gives twice the base shear."""
    import csv

    from typer.testing import CliRunner

    from masonry_nscd.cli import app

    out = tmp_path / "sweep"
    res = CliRunner().invoke(app, [
        "sweep", SMOKE, "--set", "loading.horizontal.history=none",
        "--set", f"loading.ground_motion={{file: {record}, start_s: 0.1}}",
        "--set", "output.vtu=false", "--set", "loading.ground_motion.scale=0.5,1.0",
        "--workers", "1", "-o", str(out)])
    assert res.exit_code == 0, res.output
    with open(out / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["status"] for r in rows] == ["ok", "ok"]
    shear = [abs(float(r["peak_base_shear_kN"])) for r in rows]
    assert shear[1] == pytest.approx(2.0 * shear[0], rel=0.02)
    assert all(r["peak_drift_mm"] and r["residual_drift_mm"] for r in rows)
