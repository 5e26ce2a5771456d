"""The collapse watch with supports that move (``loading.settlement``): the block points'
displacements relative to the supports' rigid motion (``masonry_nscd/collapse.py``).

References: a rigid motion of all the supports is fitted exactly (least squares of a model
that holds it); two equal supports, one translated, by the least squares written out by hand;
a thick arch rides a settlement of one springing on three hinges and stands, an arch just
thicker than its minimum falls once its supports spread (no thrust line fits the span any
more), and keeps falling after the supports stopped.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from masonry_nscd.case import load_case
from masonry_nscd.collapse import CollapseMonitor, SupportCarriage, watch
from masonry_nscd.model import RigidBody, dof_offsets
from masonry_nscd.scenes import build_scene

ARCH = Path(__file__).resolve().parents[1] / "cases" / "arch_semicircular.yaml"


def _box(lo, size) -> RigidBody:
    lo, size = np.asarray(lo, float), np.asarray(size, float)
    X = np.array([lo + size * (i, j, k) for k in (0, 1) for j in (0, 1) for i in (0, 1)])
    return RigidBody.fixed(X.mean(axis=0), X=X, name="support")


def _supports_moved(bodies, t, theta, about):
    """The dofs of ``bodies`` moved as one rigid body: translation ``t`` of the point
    ``about`` and small rotation ``theta``."""
    u = np.zeros(int(dof_offsets(bodies)[-1]))
    for k, b in enumerate(bodies):
        u[6 * k:6 * k + 3] = t + np.cross(theta, b.reference - about)
        u[6 * k + 3:6 * k + 6] = theta
    return u


def test_a_rigid_motion_of_all_the_supports_is_taken_out_whole():
    bodies = [_box((-2.0, -0.5, 0.0), (0.5, 0.5, 0.3)), _box((1.5, -0.5, 0.0), (0.5, 0.5, 0.3)),
              _box((0.0, -0.4, 2.0), (0.2, 0.4, 0.2))]
    carriage = SupportCarriage.of(bodies, dof_offsets(bodies), 18)
    t, theta, about = np.array([0.01, -0.02, 0.005]), np.array([1e-3, -2e-3, 3e-3]), np.ones(3)
    u = _supports_moved(bodies, t, theta, about)
    x = np.array([[0.0, 1.0, 0.1], [0.7, 2.0, -0.3], [-1.0, 0.0, 0.0]])
    expected = t + np.cross(theta, x - about)
    assert np.abs(carriage.displacement(u, x) - expected).max() <= 1e-12


def test_one_of_two_springings_sinking_is_a_rotation_about_the_centre():
    """Two boxes ``w`` wide, ``h`` tall and ``b`` deep, centres ``L`` apart along x, the right
    one moved down by ``d``. The fit ``u = t + theta x (x - c)``: by symmetry only ``t_y`` and
    ``theta_z`` are not zero, and the normal equations over the 16 corners give ``t_y = -d/2``
    and ``theta_z = -d L / (L^2 + w^2 + h^2)`` (the corners' ``r_x = +-L/2 +- w/2``,
    ``r_y = +-h/2``: the sum of ``r_x U_y`` is ``-8 d L / 2``, of ``r_x^2 + r_y^2`` is
    ``4 (L^2 + w^2 + h^2)``)."""
    L, w, h, b, d = 2.0, 0.5, 0.25, 0.3, 0.03
    bodies = [_box((-L / 2 - w / 2, -h, 0.0), (w, h, b)), _box((L / 2 - w / 2, -h, 0.0), (w, h, b))]
    u = np.zeros(12)
    u[7] = -d
    carriage = SupportCarriage.of(bodies, dof_offsets(bodies), 12)
    q = carriage.K @ u[carriage.dofs]
    assert carriage.centre == pytest.approx([0.0, -h / 2, b / 2], abs=1e-15)
    assert q == pytest.approx([0.0, -d / 2, 0.0, 0.0, 0.0, -d * L / (L * L + w * w + h * h)],
                              abs=1e-15)


def test_without_a_moving_support_the_displacements_are_absolute():
    scene = build_scene(load_case(ARCH))
    monitor = CollapseMonitor(scene, scene.integrator(), None, lambda *a, **k: None)
    assert monitor.carriage is None


def _arch(thickness: float, settlement: str, threshold: float, end: float):
    return build_scene(load_case(ARCH, [
        "loading.body_force.rate_per_s=0", f"arch.thickness_m={thickness}",
        (f"loading.settlement={{support: right, displacement_m: {settlement}, start_s: 0.2, "
         "duration_s: 0.5}"), f"collapse.displacement_m={threshold}", "collapse.after_s=0",
        f"collapse.end_time_s={end}"]))


def test_a_thick_arch_stands_on_a_springing_sunk_deeper_than_the_threshold():
    """t/R = 0.25, the right springing 3 cm down, the threshold 2 cm: the voussoir on that
    springing goes down by the 3 cm with it, but the arch rides it and comes to rest:
    standing, with every block point at rest at the end."""
    scene = _arch(0.25, "[0.0, -0.03, 0.0]", 0.02, 1.0)
    out = watch(scene, 1.0)
    assert out["status"] == "standing"
    assert out["displacements"] == "relative to the supports' rigid motion"
    assert out["last"]["max_displacement_m"] < 0.02
    assert out["last"]["max_speed_m_s"] < scene.collapse.onset_velocity_m_s
    springer = scene.bodies[23]
    assert springer.name == "voussoir 24"
    down = springer.displacement_of(out["u"][23], springer.X)[:, 1]
    assert down.min() <= -0.03 * 0.99  # absolute: more than the threshold


def test_an_arch_at_its_minimum_thickness_falls_when_its_supports_spread():
    """t/R = 0.11 (the minimum under its weight is 0.107), the right support 5 cm out, the
    threshold 10 cm: the arch falls, and its blocks pass 10 cm relative to the supports after
    the supports have stopped (0.7 s), the whole settlement imposed."""
    out = watch(_arch(0.11, "[0.05, 0.0, 0.0]", 0.1, 1.5), 1.5)
    assert out["status"] == "collapse"
    c = out["collapse"]
    assert c["detected_by"] == "displacement"
    assert 0.7 < c["detected_time_s"] < 1.5
    assert c["loads_at_detection"]["settlement_m"] == pytest.approx(0.05, rel=1e-9)
