"""The NSCD engine on small scenes, against closed-form answers."""

import math

import numpy as np
import pytest

from masonry_nscd.contact.laws import fczm as jl
from masonry_nscd.contact.point_driver import drive_joint_history
from masonry_nscd.scenes.small import (
    block_between_plates,
    block_on_incline,
    block_on_support,
    column,
    slender_block_pushed,
)


@pytest.mark.parametrize("divisions", [(1, 1, 1), (2, 2, 1), (3, 2, 2)])
def test_block_between_plates_has_axial_stiffness_EA_over_L(divisions):
    integ, info = block_between_plates(divisions=divisions, force=50e3, tolerance=1e-7)
    for _ in range(250):
        rep = integ.step()
        assert rep.converged
    k = 50e3 / -integ.u[info["top_dof"]]
    assert k == pytest.approx(info["stiffness"], rel=1e-2)


def test_column_at_rest_reaction_equals_weight_and_no_drift():
    integ, info = column(n_blocks=3, tolerance=1e-7)
    for i in range(1000):
        rep = integ.step()
        assert rep.converged
        if i == 499:
            u500 = integ.u.copy()
    glued = np.array([p.group == 1 for p in integ.points])
    reaction = integ.point_forces()[glued, 1].sum()
    assert reaction == pytest.approx(info["weight"], rel=1e-6)
    # at rest: no drift between step 500 and 1000 (far below the settlement itself)
    settle = np.abs(integ.u).max()
    assert settle > 1e-8
    # what moves between steps 500 and 1000 stays within the solver tolerance (1e-7 of the
    # forces), far from a drift of the settlement
    assert np.abs(integ.u - u500).max() < 1e-3 * settle


DRY = {"K_n": 1e11, "K_t": 4e10}  # the dry law's interface stiffnesses (Pa/m)


def _slide_distance(ratio, steps=400, law="coulomb", method="nlgs"):
    N = 10e3
    mu = 0.6
    integ, info = block_on_support(law=law, mu=mu, normal_force=N,
                                   shear_force=ratio * mu * N, shear_start=0.05,
                                   shear_ramp=0.1, rigid=True, method=method,
                                   joint_kw=DRY if law == "dry" else None)
    xs = []
    for _ in range(steps):
        assert integ.step().converged
        xs.append(integ.u[info["dofs_x"]].mean())
    return np.array(xs), info


@pytest.mark.parametrize("method", ["nlgs", "newton"])
def test_coulomb_block_sticks_below_mu_N(method):
    xs, _ = _slide_distance(0.99, method=method)
    # a rigid block that sticks does not move (Newton: by the 1e-9 compliance of its
    # multipliers, a slip of 1e-9 of one step's, which does not accumulate)
    assert abs(xs[-1]) < 1e-12
    assert abs(xs[-1] - xs[-100]) < 1e-12


@pytest.mark.parametrize("method", ["nlgs", "newton"])
def test_coulomb_block_slides_above_mu_N_with_newtons_acceleration(method):
    xs, info = _slide_distance(1.01, method=method)
    h = 1e-3
    # once the shear is fully applied (t > 0.15 s) the block accelerates at (F - mu N) / m
    t = np.arange(1, len(xs) + 1) * h
    sel = t > 0.2
    a = np.polyfit(t[sel], xs[sel], 2)[0] * 2.0
    expected = 0.01 * 0.6 * 10e3 / info["mass"]
    assert a == pytest.approx(expected, rel=1e-2)


@pytest.mark.parametrize(("law", "method"), [("coulomb", "nlgs"), ("coulomb", "newton"),
                                            ("dry", "newton")])
def test_block_on_an_incline_sticks_below_the_friction_angle_and_slides_above(law, method):
    """A free rigid block on a plane inclined by ``a``: it stays put while ``tan a < mu``
    (1 degree below), and slides down at ``g (sin a - mu cos a)`` within 1 % above (3 degrees
    above), without turning."""
    mu, g, h = 0.6, 9.81, 1e-3
    angle = math.degrees(math.atan(mu))
    kw = DRY if law == "dry" else None
    for a_deg, moves in ((angle - 1.0, False), (angle + 3.0, True)):
        integ, info = block_on_incline(a_deg, law=law, mu=mu, method=method, h=h,
                                       joint_kw=kw)
        xs = []
        for _ in range(300):
            assert integ.step().converged
            xs.append(integ.u[:3] @ info["slope"])
        xs = np.array(xs)
        a = math.radians(a_deg)
        if not moves:
            # the rigid contact does not move; the dry joint by its springs only (shear
            # m g sin a / (K_t A) = 2.5e-8 m, and the turn of the block on its normal springs
            # under the moment of the friction) and it does not creep
            spring = info["mass"] * g * math.sin(a) / (DRY["K_t"] * 0.3 * 0.15)
            bound = 1e-12 if law == "coulomb" else 2.0 * spring
            assert np.abs(xs).max() < bound
            assert abs(xs[-1] - xs[-100]) < 1e-12
            continue
        t = np.arange(1, len(xs) + 1) * h
        sel = t > 0.1  # the weight is ramped over 0.05 s
        acc = np.polyfit(t[sel], xs[sel], 2)[0] * 2.0
        assert acc == pytest.approx(-g * (math.sin(a) - mu * math.cos(a)), rel=1e-2)
        # no rotation on the rigid contact; on the dry joint that of its normal springs under
        # the moment of the friction about the centre, mu m g cos a 0.05 / (K_n 0.15 0.3^3 / 12)
        turn = mu * info["mass"] * g * math.cos(a) * 0.05 / (DRY["K_n"] * 0.15 * 0.3**3 / 12)
        assert np.abs(integ.u[3:6]).max() < (1e-9 if law == "coulomb" else 1.1 * turn)


@pytest.mark.parametrize("law", ["coulomb", "dry"])
def test_slender_block_tips_at_its_closed_form_push(law):
    """A rigid block 0.1 m wide and 0.4 m tall, pressed by its weight W and N = 2 kN, pushed at
    the top: it tips about its toe when the push reaches ``(W + N) b / (2 h)``. With the
    contact points at the corners of the base (``lobatto``); with them at the Gauss
    points (``gauss``) it tips about the outer Gauss point, whose lever arm is short of
    ``b / 2`` by ``(1 - 1/sqrt(3)) / 2`` of a quad's width (b / 2 here, two quads)."""
    b, H, N = 0.1, 0.4, 2e3
    kw = DRY if law == "dry" else None
    for rule, arm in (("lobatto", b / 2), ("gauss", b / 2 - (1 - 1 / math.sqrt(3)) * b / 4)):
        integ, info = slender_block_pushed(width=b, height=H, normal_force=N, law=law,
                                           method="newton", joint_kw=kw, rule=rule)
        fx = []
        for _ in range(300):
            assert integ.step().converged
            fx.append(-integ.point_forces()[:, 0].sum())  # the base shear: the push
        assert integ.u[info["rotation_dof"]] < -5e-4  # it tipped (clockwise, about z)
        # within 2e-3 on rigid contacts; 2 % on the dry joint's springs (the bound asked),
        # whose closure lets the block turn and gather momentum before it tips (0.5 % over)
        rel = 2e-3 if law == "coulomb" else 2e-2
        assert max(fx) == pytest.approx((info["weight"] + N) * arm / H, rel=rel)


def test_dry_joint_with_newton_sticks_below_mu_N_and_slides_above():
    """A rigid block on a dry joint (``law='dry'``), Newton's solver: below ``mu N`` it moves
    only by the joint's shear spring, ``F / (K_t A)``; above, it accelerates at
    ``(F - mu N) / m`` within 1 %."""
    xs, info = _slide_distance(0.99, law="dry", method="newton")
    spring = 0.99 * 0.6 * 10e3 / (DRY["K_t"] * info["area"])
    assert xs[-1] == pytest.approx(spring, rel=1e-3)
    assert abs(xs[-1] - xs[-100]) < 1e-3 * spring
    xs, info = _slide_distance(1.01, law="dry", method="newton")
    t = np.arange(1, len(xs) + 1) * 1e-3
    sel = t > 0.2
    a = np.polyfit(t[sel], xs[sel], 2)[0] * 2.0
    assert a == pytest.approx(0.01 * 0.6 * 10e3 / info["mass"], rel=1e-2)


@pytest.mark.parametrize("sigma", [0.0, 0.5e6])
def test_rigid_block_on_joint_peak_shear_is_law_peak_times_area(sigma):
    size = (0.3, 0.1, 0.15)
    area = size[0] * size[2]
    integ, _info = block_on_support(law="fczm", mu=0.7, normal_force=sigma * area, rigid=True,
                                   size=size, shear_velocity=2e-3, shear_start=0.06,
                                   shear_ramp=0.02, h=2e-4)
    fx = []
    for _ in range(int(0.6 / 2e-4)):
        assert integ.step().converged
        fx.append(-integ.point_forces()[:, 0].sum())  # force of the block on the support
    peak = max(fx)
    # law peak: 0.1088 MPa of cohesion (b = 1 - 0.99944) plus mu (1 - b) sigma of friction
    expected = (0.1088e6 + 0.7 * (1 - 5.6e-4) * sigma) * area
    assert peak == pytest.approx(expected, rel=5e-3)


def test_nscd_single_contact_with_free_rigid_partner_equals_standalone_law():
    """A rigid body of finite mass on one contact point, loaded by forces: the tractions of the
    NSCD step equal those of the stand-alone law driven by the same relative displacements."""
    size = (0.1, 0.1, 0.1)
    from masonry_nscd.fe.hex8 import box_mesh
    from masonry_nscd.loading import Loads, Ramp, at_rest
    from masonry_nscd.model import RigidBody
    from masonry_nscd.model.detection import contact_points
    from masonry_nscd.nscd.integrator import Integrator

    body = RigidBody.box((0, 0, 0), size, 2000.0,
                         imposed_velocity={d: at_rest for d in (2, 3, 4, 5)})
    Xs, cs = box_mesh(np.array([0.0, -0.1, 0.0]), np.array(size), (1, 1, 1))
    support = RigidBody.fixed(center=(0.05, -0.05, 0.05), X=Xs, conn=cs)
    bodies = [body, support]
    pts = contact_points(bodies, lambda joint, ant: (0, jl.KIND_JOINT, 0), max_gap=0.0,
                         n_gauss=1)
    assert len(pts) == 1
    P = jl.joint_params(d_coh_initial=0.0)
    loads = Loads()
    F = np.zeros(12)
    F[0], F[1] = 2.0e3, 0.8e3  # pulls up and sideways: mixed-mode opening to failure
    loads.add(F, Ramp(1.0, 0.0, 0.05))
    integ = Integrator(bodies, pts, P, loads, h=1e-4, theta=1.0, tolerance=1e-12,
                       max_iterations=100, check_every=1)
    us, Ts = [], []
    for _ in range(400):
        assert integ.step().converged
        us.append(integ.joints.u[0].copy())
        Ts.append(integ.joints.T[0].copy())
    us, Ts = np.array(us), np.array(Ts)
    assert integ.joints.beta[0] < 0.5  # the joint softened on the way
    ref = drive_joint_history(P, us)
    scale = np.abs(Ts).max()
    assert np.abs(ref.T_n - Ts[:, 0]).max() < 1e-9 * scale
    assert np.abs(ref.T_t - Ts[:, 1]).max() < 1e-9 * scale


@pytest.mark.parametrize("damping", [False, True])
def test_kinetic_damping_stops_a_block_on_its_springs_at_the_static_settlement(damping):
    """A rigid block (0.1 x 0.4 x 0.15 m, 12 kg) on dry joints of 1e8 Pa/m over its 0.015 m^2
    base (k = 1.5e6 N/m), gravity ramped over 0.05 s, the theta = 1/2 scheme (no numerical
    dissipation): the undamped block still oscillates about the settlement m g / k after the
    ramp; with kinetic damping it is at rest there, each reset at a peak of the kinetic energy
    (the block passing the equilibrium), and the energy balance closes with the energy taken
    counted as numerical."""
    import dataclasses

    from masonry_nscd.scenes.small import tilting_block

    scene = tilting_block(rate_per_s=0.0, law="dry", method="newton", tolerance=1e-10,
                          h=2e-4, joint_kw={"K_n": 1e8, "K_t": 1e8})
    scene.solver = dataclasses.replace(scene.solver, theta=0.5, kinetic_damping=damping)
    integ = scene.integrator()
    mass, k = 2000.0 * 0.1 * 0.4 * 0.15, 1e8 * 0.1 * 0.15
    settlement = mass * 9.81 / k  # m
    uy = []
    while integ.t < 0.1 - 1e-9:
        assert integ.step().converged
        if integ.t > 0.06:
            uy.append(integ.u[1])
    swing = np.ptp(uy) / settlement
    if damping:
        assert integ.kinetic_resets > 0
        assert swing < 1e-4
        assert -uy[-1] == pytest.approx(settlement, rel=1e-4)
        balance = integ.energy_account.balance(integ)
        assert balance["relative_imbalance"] < 1e-8
        assert balance["numerical"] > 0.0
    else:
        assert swing > 1e-2  # still oscillating
        assert -np.mean(uy) == pytest.approx(settlement, rel=0.02)


def test_a_checkpoint_keeps_what_kinetic_damping_compares():
    """Restored from a checkpoint taken one step before a reset, the run resets in that step
    as the uninterrupted run does: the checkpoint keeps the last kinetic energy."""
    import dataclasses

    from masonry_nscd.io.checkpoint_file import checkpoint_arrays
    from masonry_nscd.nscd.checkpoint import restore_integrator
    from masonry_nscd.scenes.small import tilting_block

    scene = tilting_block(rate_per_s=0.0, law="dry", method="newton", tolerance=1e-10,
                          h=2e-4, joint_kw={"K_n": 1e8, "K_t": 1e8})
    scene.solver = dataclasses.replace(scene.solver, theta=0.5, kinetic_damping=True)
    run = scene.integrator()
    while run.kinetic_resets < 2:  # the step before the second reset
        before = checkpoint_arrays(run)
        run.step()
    assert not run.v.any()
    resumed = scene.integrator()
    restore_integrator(resumed, before)
    resumed.step()
    assert resumed.kinetic_resets == 1 and not resumed.v.any()
    assert resumed.u == pytest.approx(run.u, abs=1e-12)
