"""ENDO3D inside the NSCD step: a cube between frictionless plates follows the point driver.

One hexahedron of side 0.1 m (ENDO3D, the study's stone), on a fixed plate, shortened by an
upper plate whose vertical velocity is imposed; joints frictionless with very stiff springs, so
the stress is uniaxial and uniform. The plate force over the area against the shortening over
the height must be the uniaxial curve of the material-point driver (same element size).
"""

from dataclasses import dataclass

import numpy as np

from masonry_nscd.contact.laws import fczm as jl
from masonry_nscd.fe.hex8 import box_mesh
from masonry_nscd.loading import Loads, at_rest
from masonry_nscd.materials.endo3d import endo3d_params
from masonry_nscd.materials.point_driver import drive_block_path
from masonry_nscd.model import MAT_ENDO3D, Block, RigidBody, dof_offsets
from masonry_nscd.model.detection import contact_points
from masonry_nscd.nscd.integrator import Integrator

H = 0.1
E, NU = 11.1e9, 0.2


def _params():
    return endo3d_params(E=E, nu=NU, R_t=1.0e6, eps_pic_t=1.0e6 / E, G_ft=60.0, R_c=9.46e6,
                         eps_pic_c=0.13e-1, delta=0.4, beta=0.2, eps_kdc=0.18e-1, DCPK=1.0,
                         REF=0.3e6, GFR=4.5)


@dataclass(frozen=True)
class _Steady:
    """A motion at the constant velocity ``v`` (m/s) from t = 0."""

    v: float

    def __call__(self, t: float) -> float:
        return self.v

    def displacement(self, t: float) -> float:
        return self.v * t


def _cube_between_plates(elements=(1, 1, 1), mu=0.0, **solver):
    """The cube on a fixed plate, shortened by the upper plate at a strain rate of 2e-3 /s:
    ``(integrator, cube, points, dof offsets)``. The joints have springs 100 times stiffer than
    the cube (the strain is read on the cube itself, so the spring's share of the shortening
    does not matter) and friction ``mu``; ``solver``: the integrator's settings beyond these
    (h = 1e-2 s, Newton, tolerance 1e-7, theta 1 unless given)."""
    rate = 2e-3 * H  # shortening velocity, m/s
    cube = Block.box((0, 0, 0), (H, H, H), elements, E=E, nu=NU, density=2000.0,
                     material=MAT_ENDO3D)
    plate = np.array([H, 0.1, H])
    Xb, cb = box_mesh(np.array([0.0, -0.1, 0.0]), plate, (1, 1, 1))
    bottom = RigidBody.fixed(center=(H / 2, -0.05, H / 2), X=Xb, conn=cb)
    Xt, ct = box_mesh(np.array([0.0, H, 0.0]), plate, (1, 1, 1))
    top = RigidBody(center=(H / 2, H + 0.05, H / 2), mass=1.0, inertia=np.ones(3),
                    imposed_velocity={0: at_rest, 1: _Steady(-rate), 2: at_rest, 3: at_rest,
                                      4: at_rest, 5: at_rest}, X=Xt, conn=ct, support=True)
    bodies = [cube, bottom, top]
    pts = contact_points(bodies, lambda joint, ant: (0, jl.KIND_JOINT, 0), max_gap=0.0)
    P = jl.joint_params(mu=mu, d_spring=0.0, K_I_spring=100 * E / H, K_II_spring=100 * E / H)
    settings = {"h": 1e-2, "theta": 1.0, "tolerance": 1e-7, "max_iterations": 50,
                "method": "newton", **solver}
    integ = Integrator(bodies, pts, P, Loads(), endo3d_params=_params(), **settings)
    return integ, cube, pts, dof_offsets(bodies)


def test_endo3d_cube_in_compression_follows_the_point_driver():
    integ, cube, pts, dof0 = _cube_between_plates()  # frictionless joints
    strain, stress = [], []
    for _ in range(250):  # to about 5e-3 of shortening
        rep = integ.step()
        assert rep.converged, rep
        f = integ.point_forces()
        top_force = f[[p.bodies[1] == 2 for p in pts], 1].sum()  # on the cube, from the plate
        top_nodes = cube.X[:, 1] > H / 2
        strain.append(integ.u[dof0[0] + 1:dof0[1]:3][top_nodes].mean() / H)
        stress.append(top_force / (H * H))
    strain, stress = np.array(strain), np.array(stress)
    ref = drive_block_path(_params(), strain, H, "free")
    expected = np.asarray(ref["sigma_axial_Pa"])
    # the cube is in compression, and the pre-peak damage of the study's stone shows
    assert stress[-1] < -5e6
    assert abs(stress[-1]) < 0.8 * E * abs(strain[-1])
    assert np.allclose(stress[10:], expected[10:], rtol=2e-3, atol=2e3)


def test_the_residual_without_the_blocks_dense_product_is_the_same_function():
    # On the ENDO3D blocks' dofs the step residual M_hat (v - v_free) + c(v) is computed as
    # M v + h theta F_int(u) + b with b fixed over the step (integrator.MaterialCorrection):
    # the same function of v, at any iterate, and at theta < 1 the (1 - theta) F_int(u_n) term
    # too.
    from masonry_nscd.nscd import newton as nw
    from masonry_nscd.nscd.checkpoint import integrator_state, restore_integrator
    from masonry_nscd.nscd.step_residual import StepResidual

    integ = _cube_between_plates((2, 2, 1), mu=0.5, theta=0.7, endo3d_tau=1e-3)[0]
    for _ in range(60):  # past the pre-peak damage's start: the blocks' law is not linear
        assert integ.step().converged
    seen = {}
    solve = nw.NewtonSolver.solve

    def capture(self, v_free, u_old, U_old, params, uc_old, beta_old, T, dv_guess,
                correction=None, t_end=None):
        seen["args"] = (self, v_free.copy(), u_old.copy(), U_old.copy(), params, uc_old.copy(),
                        beta_old.copy(), T.copy(), correction)
        seen["fint_n"] = correction._fint_n.copy()
        seen["state"] = integrator_state(integ)
        return solve(self, v_free, u_old, U_old, params, uc_old, beta_old, T, dv_guess,
                     correction, t_end)

    nw.NewtonSolver.solve = capture
    try:
        integ.step()
    finally:
        nw.NewtonSolver.solve = solve
    restore_integrator(integ, seen["state"])  # the step's start again
    sv, v_free, *rest, corr = seen["args"]
    corr._fint_n = seen["fint_n"]
    assert integ.blocks_apart and corr.apart
    split = StepResidual(sv, v_free, *rest, corr)
    assert len(split._blocks[0])  # the blocks' rows by M v + h theta F_int(u) + b
    # the form M_hat (v - v_free) + c(v) needs the blocks' free velocity, which the step
    # leaves at v_n: v_n + M_hat^-1 [h F_theta - h F_int(u_n) - theta h^2 K0 v_n] there
    s, d, h, th = integ.sys, corr.dofs, integ.sys.h, integ.sys.theta
    v_n = seen["state"]["v"]
    assert np.array_equal(v_free[d], v_n[d])
    rhs = h * (th * corr._F1 + (1.0 - th) * seen["state"]["F0"]) - h * seen["fint_n"] \
        - th * h * h * s.k_op.matvec(v_n)
    v_free = v_free.copy()
    v_free[d] = (v_n + s.minv_op.matvec(rhs))[d]
    whole = StepResidual(sv, v_free, *rest, corr)
    whole._mhat_op = sv.mhat_op  # M_hat (v - v_free) + c(v)
    whole._blocks = tuple(x[:0] for x in whole._blocks)
    rng = np.random.default_rng(3)
    r = sv._solutions[-1][2]
    for scale in (0.0, 1e-4, 1e-2):  # the solution, and iterates away from it
        v = sv._solutions[-1][1] * (1.0 + scale * rng.standard_normal(len(v_free)))
        a, b = split(v, r), whole(v, r)
        size = np.linalg.norm(sv.mhat_op.matvec(v - v_free)) + np.linalg.norm(b.correction)
        # the form M_hat (v - v_free) goes through M_hat^-1 and back: round-off of the
        # condition of the blocks' M_hat (some 1e3 here) times the machine's epsilon
        assert np.linalg.norm(a.F - b.F) <= 1e-10 * size, (scale, np.linalg.norm(a.F - b.F), size)
        assert np.array_equal(a.correction, b.correction)
