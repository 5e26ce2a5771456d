"""The Newton matrix's tangents against differences of what they linearise.

* ENDO3D blocks: ``Endo3dBlocks.tangent_stiffness`` (forward differences of the kernel per Gauss
  point, assembled with B) against central differences of the blocks' internal forces, in states
  that are elastic, cracked in tension and crushed in compression.
* Joints: the consistent tangent of ``step_residual.joint_tangents`` against central differences of the
  implicit law, on points that open and soften within the step, and the closed-form tangent
  where the integrity does not move.
"""

import numpy as np
import pytest

from masonry_nscd.contact.laws import fczm as jl
from masonry_nscd.fe import hex8
from masonry_nscd.materials.blocks import Endo3dBlocks
from masonry_nscd.materials.endo3d import endo3d_params
from masonry_nscd.model import MAT_ENDO3D, Block
from masonry_nscd.nscd.step_residual import evaluate_joints, joint_tangents

E, NU = 11.1e9, 0.2


def _block_and_material():
    blk = Block.box((0, 0, 0), (0.3, 0.1, 0.15), (2, 2, 1), E=E, nu=NU, density=2000.0,
                    material=MAT_ENDO3D)
    prm = endo3d_params(E=E, nu=NU, R_t=1.0e6, eps_pic_t=1.0e6 / E, G_ft=60.0, R_c=9.46e6,
                        eps_pic_c=0.13e-1, delta=0.4, beta=0.2, eps_kdc=0.18e-1, DCPK=1.0,
                        REF=0.3e6, GFR=4.5)
    return blk, Endo3dBlocks([blk], np.array([0, blk.ndof]), prm)


def _field(blk, strain):
    """Nodal displacements (3n,) of a homogeneous strain tensor (3x3) plus a bending-like term,
    so that the Gauss points differ."""
    X = blk.X
    u = X @ np.asarray(strain).T
    u[:, 0] += 2e-3 * strain[0][0] * (X[:, 1] - 0.05) * X[:, 0] / 0.3
    return u.ravel()


@pytest.mark.parametrize("name, strain", [
    ("elastic", [[3e-5, 0, 0], [0, -2e-5, 1e-5], [0, 1e-5, 0]]),
    ("cracked", [[4e-4, 0, 0], [0, -1e-4, 5e-5], [0, 5e-5, 0]]),
    ("crushed", [[4e-3, 0, 0], [0, -2e-2, 0], [0, 0, 4e-3]]),
])
def test_endo3d_tangent_is_the_derivative_of_the_internal_forces(name, strain):
    blk, mat = _block_and_material()
    u0 = _field(blk, strain)
    f = np.zeros(blk.ndof)
    mat.internal_forces(u0, f, trial=True)  # a trial state from the virgin one: one big step
    mat.commit()
    u1 = 1.05 * u0  # loading on from there, within a step
    mat.internal_forces(u1, f, trial=True)
    K = mat.tangent_stiffness()[0]
    rng = np.random.default_rng(3)
    d = rng.standard_normal(blk.ndof) * 1e-3 * np.abs(u0).max()
    errs = []
    for eps in (1e-3, 1e-4):
        fp, fm = np.zeros(blk.ndof), np.zeros(blk.ndof)
        mat.internal_forces(u1 + eps * d, fp, trial=True)
        mat.internal_forces(u1 - eps * d, fm, trial=True)
        fd = (fp - fm) / (2 * eps)
        errs.append(np.linalg.norm(K @ d - fd) / np.linalg.norm(fd))
    assert min(errs) < 2e-3, (name, errs)
    if name != "elastic":  # the damaged tangent is not the elastic one
        mat0 = _block_and_material()[1]
        mat0.internal_forces(u1, np.zeros(blk.ndof), trial=True)
        K0 = mat0.tangent_stiffness()[0]
        assert np.linalg.norm(K - K0) > 0.05 * np.linalg.norm(K0)


def _joint_case(u_now, beta_old):
    P = jl.joint_params(d_coh_initial=0.0)  # virgin joint: peaks at 2.9e-6 m (I), 3.3e-5 m (II)
    params = np.ascontiguousarray(P[None, :])
    u_pred = np.array([u_now])
    uc_old = np.zeros((1, 3))
    return params, u_pred, uc_old, np.array([beta_old])


def _evaluate(params, u, uc_old, beta_old):
    T, uc, beta = np.zeros((1, 3)), np.zeros((1, 3)), beta_old.copy()
    status, K = np.zeros(1, dtype=np.int64), np.zeros((1, 3, 3))
    args = (u, np.zeros((1, 3)), 1.0, 1.0, np.array([-1]),  # not a multiplier
            np.array([0]), params, uc_old, beta_old)
    evaluate_joints(*args, T, uc, beta, status)
    joint_tangents(*args, T, beta, status, K)
    return T[0], K[0], beta[0]


@pytest.mark.parametrize("u_now, softens", [
    ((6e-6, 0.0, 0.0), True),       # mode I past the peak: softening within the step
    ((2e-6, 6e-5, 0.0), True),      # mixed, softening
    ((-1e-6, 2e-7, 1e-7), False),   # closed, below the envelope: integrity unchanged
])
def test_joint_tangent_is_the_derivative_of_the_implicit_law(u_now, softens):
    params, u, uc_old, beta_old = _joint_case(u_now, 1.0)
    T, K, beta = _evaluate(params, u, uc_old, beta_old)
    assert (beta < 1.0) == softens
    scale = 1e-4 * np.linalg.norm(u)
    fd = np.zeros((3, 3))
    for j in range(3):
        e = np.zeros((1, 3))
        e[0, j] = scale
        Tp = _evaluate(params, u + e, uc_old, beta_old)[0]
        Tm = _evaluate(params, u - e, uc_old, beta_old)[0]
        fd[:, j] = (Tp - Tm) / (2 * scale)
    assert np.linalg.norm(K - fd) <= 1e-3 * np.linalg.norm(fd), (K, fd, beta)
    if softens:  # the frozen-integrity tangent would be far off
        Kf = np.zeros((3, 3))
        jl.tangent(u[0], T, uc_old[0], beta, jl.ST_OPEN if u[0, 0] > 0 else jl.ST_STICK,
                      params[0], Kf)
        assert np.linalg.norm(Kf - fd) > 0.2 * np.linalg.norm(fd)


def test_viscous_regularisation_relaxes_to_the_endo3d_stress_as_exp_minus_t_over_tau():
    """Strain jumped past the tensile peak in one step, then held: the stress is that of the
    relaxation ODE ``d sigma/dt = C0 d eps/dt - (sigma - sigma_endo3d)/tau`` with the strain and
    the ENDO3D stress linear over the first step (from zero): ``sigma_1 = (1 - phi)
    sigma_endo3d + phi C0 eps``, ``phi = (1 - exp(-h/tau)) / (h/tau)``; then, strain held,
    ``sigma_k - sigma_endo3d`` shrinks as ``exp(-t/tau)`` of the time held ``t = k h``, whatever
    the step (the implicit Euler rule gives ``(1 + h/tau)^-k``: at ``h = 4 tau``, 0.2 a step
    instead of 0.018)."""
    blk, mat0 = _block_and_material()
    tau = 1e-3
    u = _field(blk, [[4e-4, 0, 0], [0, -1e-4, 0], [0, 0, 0]])
    f = np.zeros(blk.ndof)
    mat0.internal_forces(u, f, trial=True)
    sig_inv = mat0.sigma_all.copy()  # the rate-independent stress at that strain
    for h in (4e-3, 2e-3, 1e-3):
        mat = Endo3dBlocks([blk], np.array([0, blk.ndof]), mat0.params, tau=tau, h=h)
        r = h / tau
        phi = (1.0 - np.exp(-r)) / r
        mat.internal_forces(u, f, trial=True)
        eps = mat._eps.copy()
        elastic = np.einsum("pij,pj->pi", mat.C0, eps)
        first = (1.0 - phi) * sig_inv + phi * elastic
        assert np.allclose(mat.sigma_all, first, rtol=1e-12, atol=1e-6)
        assert np.abs(elastic - sig_inv).max() > 1e5  # the jump does crack: something to relax
        for k in range(1, 6):
            mat.commit()
            mat.internal_forces(u, f, trial=True)
            gap = (first - sig_inv) * np.exp(-k * r)
            assert np.allclose(mat.sigma_all - sig_inv, gap, rtol=1e-9, atol=1e-6)
    # its tangent is phi C0 + (1 - phi) C, checked against differences
    mat.commit()
    u1 = 1.05 * u
    mat.internal_forces(u1, f, trial=True)
    K = mat.tangent_stiffness()[0]
    d = np.random.default_rng(5).standard_normal(blk.ndof) * 1e-3 * np.abs(u).max()
    fp, fm = np.zeros(blk.ndof), np.zeros(blk.ndof)
    mat.internal_forces(u1 + 1e-3 * d, fp, trial=True)
    mat.internal_forces(u1 - 1e-3 * d, fm, trial=True)
    fd = (fp - fm) / 2e-3
    assert np.linalg.norm(K @ d - fd) < 2e-3 * np.linalg.norm(fd)


@pytest.mark.parametrize("tau", [0.0, 1e-3])
def test_the_departure_from_the_linear_forces_is_summed_element_by_element(tau):
    """``internal_forces(..., departure=c)`` gives ``F_int(u) - F_int(u_n) - K0 (u - u_n)`` with
    ``K0`` the block's elastic stiffness as the scene assembles it (``hex8.assemble_block``): the
    residual's material correction, summed per element from the committed stresses and
    strains, in a cracked state and past it, with and without the viscous relaxation."""
    blk, mat0 = _block_and_material()
    mat = Endo3dBlocks([blk], np.array([0, blk.ndof]), mat0.params, tau=tau, h=2e-3)
    K0 = hex8.assemble_block(blk.X, blk.conn, hex8.elastic_matrix(E, NU), 2000.0)[0]
    u_n = _field(blk, [[4e-4, 0, 0], [0, -1e-4, 5e-5], [0, 5e-5, 0]])
    f_n, f, c = np.zeros(blk.ndof), np.zeros(blk.ndof), np.zeros(blk.ndof)
    mat.internal_forces(u_n, f_n, trial=True)
    mat.commit()
    mat.internal_forces(u_n, f_n, trial=False)  # F_int(u_n) from the committed stresses
    for scale in (1.0, 1.3):
        u = scale * u_n + _field(blk, [[1e-5, 0, 0], [0, 0, 2e-5], [0, 2e-5, 0]])
        mat.internal_forces(u, f, trial=True, departure=c)
        expected = f - f_n - K0 @ (u - u_n)
        assert np.abs(c - expected).max() <= 1e-9 * np.abs(f).max()
    assert np.abs(c).max() > 1e-3 * np.abs(f).max()  # the state is not linear: c is not zero
