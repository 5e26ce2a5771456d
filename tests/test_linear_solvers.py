"""The linear solvers of the Newton matrix (``nscd/linear.py``, ``solver.linear``), against
independent calculations and physics.

* ``gmres``: the solution of small dense systems from ``numpy.linalg.solve``; in exact
  arithmetic GMRES ends in at most n iterations, and with an exact preconditioner in one.
* ``rigid_body_modes``: the elastic stiffness of a block does no work on them (K R = 0).
* the two-level preconditioner: the solution of the Newton matrix of the smoke wall matches
  SuperLU's, and a step made with ``krylov`` the step made with ``lu`` to the Newton tolerance.
* a Krylov solve that cannot converge is detected and made by LU, to the same steps.
* ``auto``: a direct solver at the study's size (PARDISO, or SuperLU without MKL), from the
  unknowns counted from the scene.
* ``pardiso``: solutions of the Newton matrix as SuperLU's, a factor replaced by a later one
  refused, a run with it the run with SuperLU; asked for without MKL, an error naming the field.
* the case field and the bench options: errors that name the field and its range.
* the coarse LU: values laid on a larger pattern are the matrix; on the smoke wall its
  pattern is analysed once however the joints open and close (three times without the
  body system's structure).
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from typer.testing import CliRunner

from masonry_nscd.case import CaseError, load_case
from masonry_nscd.cli import app
from masonry_nscd.nscd import linear, pardiso
from masonry_nscd.nscd.newton import jacobian_coo
from masonry_nscd.scenes import build_scene, check_case
from masonry_nscd.studies import bench as bm

SMOKE = "cases/smoke.yaml"
STUDY = "cases/wall_0.5MPa_elastic.yaml"
QUIET = ["output.vtu=false", "output.hdf5=false", "output.energy=false"]
needs_mkl = pytest.mark.skipif(not pardiso.available(), reason="Intel MKL is not installed")


def test_gmres_solves_a_nonsymmetric_system_to_its_tolerance():
    rng = np.random.default_rng(3)
    n = 40
    A = np.eye(n) * 4.0 + rng.normal(size=(n, n)) * 0.3  # nonsymmetric, well conditioned
    b = rng.normal(size=n)
    x_ref = np.linalg.solve(A, b)
    x, its, left = linear.gmres(lambda v: A @ v, lambda v: v, b, None, 1e-10, 50, 200)
    assert np.linalg.norm(A @ x - b) <= 1e-10 * np.linalg.norm(b) * 1.0001
    assert left == pytest.approx(np.linalg.norm(A @ x - b), rel=1e-12)  # the true residual
    assert np.allclose(x, x_ref, rtol=0, atol=1e-8 * np.abs(x_ref).max())
    assert its <= n
    # restarted every 5 iterations it still gets there, in more iterations
    x5, its5, _ = linear.gmres(lambda v: A @ v, lambda v: v, b, None, 1e-10, 5, 2000)
    assert np.allclose(x5, x_ref, rtol=0, atol=1e-8 * np.abs(x_ref).max()) and its5 >= its
    # an exact preconditioner: one iteration; the exact solution as the start: none
    Ainv = np.linalg.inv(A)
    x1, its1, _ = linear.gmres(lambda v: A @ v, lambda v: Ainv @ v, b, None, 1e-10, 50, 200)
    assert its1 == 1 and np.allclose(x1, x_ref, atol=1e-10 * np.abs(x_ref).max())
    assert linear.gmres(lambda v: A @ v, lambda v: v, b, x_ref, 1e-10, 50, 200)[1] == 0
    # a start whose residual is larger than |b| is not taken: the same solve as from zero
    far = linear.gmres(lambda v: A @ v, lambda v: v, b, -10.0 * x_ref, 1e-10, 50, 200)
    assert far[1] == its and np.array_equal(far[0], x)


@pytest.fixture(scope="module")
def smoke_scene():
    return build_scene(load_case(SMOKE, QUIET))


def test_the_local_preconditioner_inverts_each_bodys_diagonal_block():
    """The local part of the Krylov preconditioner is the inverse of every body's diagonal
    block of ``S`` (bodies of 7, 6, 8 and 6 dofs, coupled to one another), and its coarse part
    solves ``R^T S R`` (six modes per body)."""
    body_of = np.repeat(np.arange(4), [7, 6, 8, 6])
    rng = np.random.default_rng(4)
    n = len(body_of)
    S = rng.normal(size=(n, n)) * (rng.random((n, n)) < 0.6) + 6.0 * np.eye(n)
    ks = linear.KrylovSolver(body_of, rng.normal(size=(n, 6)))
    pre = ks._preconditioner(sp.csr_matrix(S))
    r = rng.normal(size=n)
    expected = np.empty(n)
    for b in np.unique(body_of):
        d = np.flatnonzero(body_of == b)
        expected[d] = np.linalg.solve(S[np.ix_(d, d)], r[d])
    assert np.allclose(pre._local(r), expected, rtol=1e-12, atol=1e-12)
    R = ks.R.toarray()
    coarse = R @ np.linalg.solve(R.T @ S @ R, R.T @ r)
    assert np.allclose(pre._coarse(r), coarse, rtol=1e-8, atol=1e-8 * np.abs(coarse).max())
    # a later matrix in which only the third body's block changed: only that block is
    # inverted again, and every block's inverse is that of the new matrix
    S[np.ix_(body_of == 2, body_of == 2)] += np.eye(8)
    S[0, 20] += 1.0  # a coupling between two bodies: in no block
    pre = ks._preconditioner(sp.csr_matrix(S))
    assert ks.blocks_inverted == 1
    d = np.flatnonzero(body_of == 2)
    expected[d] = np.linalg.solve(S[np.ix_(d, d)], r[d])
    assert np.allclose(pre._local(r), expected, rtol=1e-12, atol=1e-12)


@needs_mkl
def test_the_coarse_matrix_summed_into_its_pattern_is_r_transpose_s_r():
    """With the body system's pattern known, ``R^T S R`` is summed straight into the analysed
    coarse pattern (``coarse_entries``): its LU solves the dense ``R^T S R``, for bodies of
    7, 6, 8 and 6 dofs, one of them with a mode no dof moves (its column dropped), and a later
    ``S`` with entries of the pattern left out (open joints). An ``S`` with an entry outside
    the pattern is summed by scipy's products instead, with the same result."""
    body_of = np.repeat(np.arange(4), [7, 6, 8, 6])
    rng = np.random.default_rng(11)
    n = len(body_of)
    modes = rng.normal(size=(n, 6))
    modes[body_of == 1, 4] = 0.0  # body 1's fifth mode: no coarse unknown
    full = (rng.random((n, n)) < 0.5) | np.eye(n, dtype=bool)
    full[np.ix_(body_of == 0, body_of == 3)] = False  # bodies 0 and 3 never touch
    full[np.ix_(body_of == 3, body_of == 0)] = False
    structure = sp.csr_matrix(full.astype(float))
    ks = linear.KrylovSolver(body_of, modes)
    ks.structure = (structure.indptr, structure.indices)
    R = ks.R.toarray()
    assert R.shape == (n, 23)
    r = rng.normal(size=n)
    for drop in (0.0, 0.3):
        S = np.where(full & (rng.random((n, n)) >= drop), rng.normal(size=(n, n)), 0.0)
        S += 6.0 * np.eye(n)
        lu = ks._coarse_factor(sp.csr_matrix(S))
        assert np.allclose(lu.solve(R.T @ r), np.linalg.solve(R.T @ S @ R, R.T @ r),
                           rtol=1e-10, atol=0)
    assert ks.coarse_analyses == 1
    # the entries themselves, against the dense product at each entry of the pattern
    kept = ks._coarse_pattern
    data = np.zeros(len(kept.keys))
    Sc = sp.csr_matrix(S)
    assert linear.coarse_entries(Sc.indptr, Sc.indices, Sc.data, 0, body_of, ks.modes,
                                 ks.n_bodies, *kept.pairs(ks.coarse_columns, ks.n_bodies),
                                 data) == 0
    S0 = R.T @ S @ R
    assert np.allclose(data, S0.T.ravel()[kept.keys], rtol=1e-12, atol=1e-12 * abs(S0).max())
    assert np.count_nonzero(S0) <= len(kept.keys)
    S[0, n - 1] = 1.0  # bodies 0 and 3: outside the pattern
    lu = ks._coarse_factor(sp.csr_matrix(S))
    assert np.allclose(lu.solve(R.T @ r), np.linalg.solve(R.T @ S @ R, R.T @ r), rtol=1e-10,
                       atol=0)
    assert ks.coarse_analyses == 2


def test_a_block_that_moved_less_than_the_tolerance_keeps_its_inverse():
    """A body's block is inverted again when it moved by more than ``block_tolerance`` of its
    Frobenius norm since its inverse was made, measured from that block (so that small moves
    do not add up unseen); the others keep the inverse they have."""
    body_of = np.repeat(np.arange(3), [6, 6, 6])
    rng = np.random.default_rng(7)
    n = len(body_of)
    S0 = rng.normal(size=(n, n)) + 8.0 * np.eye(n)
    ks = linear.KrylovSolver(body_of, rng.normal(size=(n, 6)))
    ks.block_tolerance = 1e-3
    ks._preconditioner(sp.csr_matrix(S0))
    blocks = [np.ix_(body_of == b, body_of == b) for b in range(3)]
    size = [np.linalg.norm(S0[blk]) for blk in blocks]
    E = np.zeros((6, 6))
    E[0, 1] = 1.0
    S1 = S0.copy()
    S1[blocks[0]] += 0.6e-3 * size[0] * E  # under the tolerance
    S1[blocks[1]] += 1.5e-3 * size[1] * E  # over it
    pre = ks._preconditioner(sp.csr_matrix(S1))
    assert ks.blocks_inverted == 1
    r = rng.normal(size=n)
    local = pre._local(r)
    d0, d1 = np.flatnonzero(body_of == 0), np.flatnonzero(body_of == 1)
    assert np.allclose(local[d0], np.linalg.solve(S0[blocks[0]], r[d0]), rtol=1e-12)
    assert np.allclose(local[d1], np.linalg.solve(S1[blocks[1]], r[d1]), rtol=1e-12)
    # a second move of the first block under the tolerance, which with the first is over it
    # from the block its inverse was made of
    S2 = S1.copy()
    S2[blocks[0]] += 0.6e-3 * size[0] * E
    pre = ks._preconditioner(sp.csr_matrix(S2))
    assert ks.blocks_inverted == 2
    assert np.allclose(pre._local(r)[d0], np.linalg.solve(S2[blocks[0]], r[d0]), rtol=1e-12)


def test_moved_blocks_at_tolerance_zero_is_any_change():
    a = np.arange(8.0).reshape(2, 4)
    b = a.copy()
    b[1, 3] = np.nextafter(b[1, 3], np.inf)  # the smallest change there is
    assert list(linear.moved_blocks(b, a, 0.0)) == [False, True]
    assert list(linear.moved_blocks(b, a, 1e-3)) == [False, False]


def test_rigid_body_modes_are_the_null_space_of_each_blocks_stiffness(smoke_scene):
    integ = smoke_scene.integrator()
    s = integ.sys
    xyz = [b.X if s.body_deformable[i] else None for i, b in enumerate(integ.bodies)]
    R = linear.rigid_body_modes(s.body_dof0, s.body_deformable, xyz)
    checked = 0
    for i in np.flatnonzero(s.body_deformable):
        d0, d1 = s.body_dof0[i], s.body_dof0[i + 1]
        n = d1 - d0
        K = s.k[s.k_off[i]:s.k_off[i] + n * n].reshape(n, n)
        Ri = R[d0:d1]
        assert np.linalg.matrix_rank(Ri) == 6
        # K R = 0 to round-off: no strain energy in a rigid motion
        assert np.abs(K @ Ri).max() <= 1e-9 * np.abs(K).max() * np.abs(Ri).max()
        checked += 1
    assert checked > 0


def _newton_matrix(integ):
    """The Newton matrix (CSC, natural order) at the last factorisation of ``integ``'s solver."""
    N = integ.newton
    nf = len(N.free)
    n = nf + 3 * len(N.mult)
    r, c, v = jacobian_coo(*N.jacobian_args(N._K_factorised), True)
    return sp.csc_matrix((v, (r, c)), shape=(n, n)), nf


def test_krylov_solve_of_the_newton_matrix_matches_superlu(smoke_scene):
    integ = smoke_scene.integrator()
    for _ in range(3):
        integ.step()
    J, nf = _newton_matrix(integ)
    assert J.shape[0] > nf  # glue rows: the multipliers are eliminated
    rng = np.random.default_rng(0)
    b = rng.normal(size=J.shape[0])
    x_ref = spla.splu(J).solve(b)
    N, s = integ.newton, integ.sys
    xyz = [bd.X if s.body_deformable[i] else None for i, bd in enumerate(integ.bodies)]
    modes = linear.rigid_body_modes(s.body_dof0, s.body_deformable, xyz)[N.free]
    body_of = np.searchsorted(s.body_dof0, N.free, side="right") - 1
    ks = linear.KrylovSolver(body_of, modes, rtol=1e-10, max_iterations=500)
    x = ks.factorise(J).solve(b)
    assert ks.last_residual <= 1e-9
    # J x = b row by row: the glue rows exactly (r is eliminated from them); the momentum rows
    # to the tolerance of the body system S v = b_v + B D^-1 b_g, whose residual they are
    res = b - J @ x
    assert np.linalg.norm(res[nf:]) <= 1e-12 * np.linalg.norm(b[nf:])
    B = -J[:nf, nf:]
    d = J[nf:, nf:].diagonal()  # D = eps I for the glue: its inverse is 1 / eps
    assert np.allclose(J[nf:, nf:].toarray(), np.diag(d))
    rhs = b[:nf] + B @ (b[nf:] / d)
    assert np.linalg.norm(res[:nf]) <= 1e-9 * np.linalg.norm(rhs)
    # so the velocities are SuperLU's to the conditioning of the glue only: the body system
    # holds the glue as springs 1 / eps, 1e9 times the local stiffness, and its residual of
    # 1e-10 bounds the error of v to about 1e-10 / eps relative
    v, v_ref = x[:nf], x_ref[:nf]
    assert np.linalg.norm(v - v_ref) <= 1e-3 * np.linalg.norm(v_ref)


@pytest.mark.parametrize("which", ["glue", "rigid contacts"])
def test_the_body_system_summed_directly_is_the_eliminated_newton_matrix(which):
    """The Krylov solver's ``S = A + B D^-1 C``, summed straight into its own pattern
    (``jacobian_values(..., eliminate=True)``), and the multipliers' blocks ``B``, ``C``,
    ``D^-1`` equal those that slicing and multiplying the Newton matrix give: on the smoke wall
    (glue) and on a short dry wall on rigid Signorini-Coulomb joints (full 3 x 3 blocks)."""
    if which == "glue":
        case = load_case(SMOKE, QUIET)
    else:
        case = load_case("cases/dry_stone_wall.yaml", [
            "wall.courses=3", "wall.units_per_course=2", "joint.law=coulomb",
            "loading.gravity.ramp_s=0.02", "output.vtu=false", "output.hdf5=false"])
    integ = build_scene(case).integrator()
    for _ in range(3):
        integ.step()
    N, s = integ.newton, integ.sys
    assert (N.mu >= 0.0).any() == (which == "rigid contacts")
    args = N.jacobian_args(N._K_factorised)
    r, c, v = jacobian_coo(*args, True)
    J = sp.csr_matrix((v, (r, c)), shape=(len(N.free) + 3 * len(N.mult),) * 2)
    xyz = [bd.X if s.body_deformable[i] else None for i, bd in enumerate(integ.bodies)]
    body_of = np.searchsorted(s.body_dof0, N.free, side="right") - 1
    ks = linear.KrylovSolver(body_of, linear.rigid_body_modes(s.body_dof0, s.body_deformable,
                                                               xyz)[N.free])
    S_ref, B_ref, C_ref, Dinv_ref = ks._body_system(J)
    K, Gu, Gr = N._K_factorised
    B, C, Dinv_blocks = N._multipliers(Gu, Gr)
    Dinv = linear.block_diagonal(Dinv_blocks)
    for _ in range(2):  # the first call makes the pattern, the second fills it
        S = N._body_system(N.jacobian_args((K, Dinv_blocks @ Gu, Gr)))
    scale = abs(S_ref).max()
    assert abs(S - S_ref).max() <= 1e-12 * scale
    for M, M_ref in ((B, B_ref), (C, C_ref), (Dinv, Dinv_ref)):
        assert abs(M - M_ref).max() <= 1e-12 * abs(M_ref).max()


def test_the_adaptive_steps_rungs_share_the_krylov_pattern():
    """A rung of the adaptive step (another h, the same bodies and points) takes the body
    system's pattern of the run's solver instead of making its own."""
    case = load_case(SMOKE, [*QUIET, "solver.linear=krylov", "solver.max_time_step_s=8e-3",
                             "solver.grow_after_steps=1", "solver.easy_iterations=20"])
    integ = build_scene(case).integrator()
    for _ in range(12):
        integ.step()
    assert integ._rungs, "the step did not grow"
    pattern = integ.newton._krylov_pattern
    assert pattern is not None
    for rung in integ._rungs.values():
        assert rung.newton._krylov_pattern is pattern


def test_a_krylov_step_is_the_lu_step_to_the_newton_tolerance():
    """Five steps of the smoke case with each linear solver: the same contact tractions to
    the Newton tolerance (relative change of the forces 1e-8 in that case), and the Krylov
    solver really did the solves (no LU fallback)."""
    out = {}
    for lin in ("lu", "krylov"):
        case = load_case(SMOKE, [*QUIET, f"solver.linear={lin}"])
        integ = build_scene(case).integrator()
        T = []
        for _ in range(5):
            integ.step()
            T.append(integ.joints.T.copy())
        out[lin] = np.array(T), integ
    tol = load_case(SMOKE, QUIET).solver.tolerance
    T_lu, lu = out["lu"]
    T_kr, kr = out["krylov"]
    assert lu.newton.linear == "lu" and kr.newton.linear == "krylov"
    counts = kr.solver_counts()
    assert counts["linear_iterations"] > 0 and counts["linear_fallbacks"] == 0
    assert lu.solver_counts()["linear_iterations"] == 0
    for k in range(5):
        scale = np.linalg.norm(T_lu[k])
        assert np.linalg.norm(T_kr[k] - T_lu[k]) <= 100.0 * tol * scale, k


def test_auto_picks_a_direct_solver_at_the_studys_size(monkeypatch):
    """auto: PARDISO below KRYLOV_MIN_UNKNOWNS where MKL is installed, SuperLU where it is
    not, Krylov from there; the direct solver that MASONRY_DIRECT_SOLVER names instead."""
    monkeypatch.delenv(linear.DIRECT_SOLVER_VARIABLE, raising=False)
    case = load_case(STUDY, QUIET)
    assert case.solver.linear == "auto"
    integ = build_scene(case).integrator()
    s = integ.sys
    # unknowns counted from the scene: free dofs, and three per glued point (the study's wall
    # has no rigid contacts)
    from masonry_nscd.contact import laws

    unknowns = s.ndof - len(s.imposed_dofs) + 3 * int(np.sum(s.kind == laws.KIND_GLUED))
    assert unknowns == len(integ.newton.free) + 3 * len(integ.newton.mult)
    assert unknowns < linear.KRYLOV_MIN_UNKNOWNS
    direct = "pardiso" if pardiso.available() else "lu"
    assert integ.newton.linear == direct
    assert linear.choose("auto", linear.KRYLOV_MIN_UNKNOWNS) == "krylov"
    assert linear.choose("auto", linear.KRYLOV_MIN_UNKNOWNS - 1) == direct
    assert linear.choose("krylov", 10) == "krylov" and linear.choose("lu", 10**7) == "lu"
    monkeypatch.setenv(linear.DIRECT_SOLVER_VARIABLE, "lu")
    assert linear.choose("auto", 10) == "lu"
    assert linear.choose("pardiso" if direct == "pardiso" else "krylov", 10) != "lu"
    assert linear.choose("auto", linear.KRYLOV_MIN_UNKNOWNS) == "krylov"
    monkeypatch.setenv(linear.DIRECT_SOLVER_VARIABLE, "cholesky")
    with pytest.raises(ValueError, match="MASONRY_DIRECT_SOLVER must be lu or pardiso"):
        linear.choose("auto", 10)
    monkeypatch.delenv(linear.DIRECT_SOLVER_VARIABLE)
    monkeypatch.setattr(pardiso, "available", lambda: False)
    assert linear.choose("auto", 10) == "lu"
    with pytest.raises(ValueError, match="needs Intel MKL"):
        linear.choose("pardiso", 10)
    monkeypatch.setenv(linear.DIRECT_SOLVER_VARIABLE, "pardiso")
    with pytest.raises(ValueError, match="needs Intel MKL"):
        linear.choose("auto", 10)


def test_solver_linear_is_validated(monkeypatch):
    with pytest.raises(CaseError, match=r"solver\.linear.*'auto'.*'lu'.*'pardiso'.*'krylov'"):
        load_case(SMOKE, ["solver.linear=cholesky"])
    with pytest.raises(ValueError, match="auto, lu, pardiso, krylov"):
        linear.choose("cg", 10)
    # pardiso asked for where MKL is missing: exit 2, naming the field and what to do
    monkeypatch.setattr(pardiso, "available", lambda: False)
    with pytest.raises(CaseError, match=r"solver\.linear.*got pardiso.*needs Intel MKL"):
        check_case(load_case(SMOKE, ["solver.linear=pardiso"]))
    res = CliRunner().invoke(app, ["validate", SMOKE, "--set", "solver.linear=pardiso"])
    assert res.exit_code == 2 and "solver.linear" in res.output


@needs_mkl
def test_pardiso_solves_the_newton_matrix_as_superlu(smoke_scene):
    """The smoke wall's Newton matrix (glue rows included, compliance 1e-9 of the Delassus
    diagonal: condition number about 1e9): PARDISO's solution is SuperLU's with partial
    pivoting to within what that conditioning allows, and both leave a residual at round-off;
    a second factorisation of another matrix of the pattern solves that one."""
    integ = smoke_scene.integrator()
    for _ in range(3):
        integ.step()
    J, _ = _newton_matrix(integ)
    J = J.tocsc()
    J.sort_indices()
    rng = np.random.default_rng(1)
    b = rng.normal(size=J.shape[0])
    x_ref = spla.splu(J).solve(b)
    handle = pardiso.Pardiso(J.indptr, J.indices, J.shape[0])
    x = handle.factorise(J.data).solve(b)
    assert np.linalg.norm(b - J @ x) <= 1e-10 * np.linalg.norm(b)
    assert np.linalg.norm(x - x_ref) <= 1e-7 * np.linalg.norm(x_ref)
    # the same pattern, other values (each entry scaled by 1 to 1.1), by the same handle
    J2 = sp.csc_matrix((J.data * rng.uniform(1.0, 1.1, J.nnz), J.indices, J.indptr),
                       shape=J.shape)
    x2 = handle.factorise(J2.data).solve(b)
    assert np.linalg.norm(b - J2 @ x2) <= 1e-10 * np.linalg.norm(b)


@needs_mkl
def test_a_replaced_pardiso_factor_refuses_to_solve():
    A = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 2.0, 5.0]]))
    handle = pardiso.Pardiso(A.indptr, A.indices, 3)
    first = handle.factorise(A.data)
    b = np.array([1.0, 2.0, 3.0])
    assert np.allclose(first.solve(b), np.linalg.solve(A.toarray(), b), rtol=1e-13, atol=0)
    second = handle.factorise(2.0 * A.data)
    assert np.allclose(second.solve(b), np.linalg.solve(2.0 * A.toarray(), b), rtol=1e-13,
                       atol=0)
    with pytest.raises(pardiso.PardisoError, match="replaced"):
        first.solve(b)
    with pytest.raises(ValueError, match="values for a pattern"):
        handle.factorise(np.ones(4))
    handle.release()


@needs_mkl
def test_a_reproducible_pardiso_handle_gives_the_same_bits_on_two_threads():
    """A coarse-like matrix (6 x 6 blocks on a grid of 60 x 40 bodies, nested dissection)
    factorised again and again on two threads in MKL's reproducible mode: the same solution
    bit for bit each time (without the mode, such factorisations differed in the last bits),
    and the solution of the matrix."""
    ny, nx = 60, 40
    grid = np.arange(ny * nx).reshape(ny, nx)
    pairs = [(grid.ravel(), grid.ravel()), (grid[:, :-1].ravel(), grid[:, 1:].ravel()),
             (grid[:-1, :].ravel(), grid[1:, :].ravel()),
             (grid[:-1, :-1].ravel(), grid[1:, 1:].ravel())]
    r = np.concatenate([a for a, b in pairs] + [b for a, b in pairs[1:]])
    c = np.concatenate([b for a, b in pairs] + [a for a, b in pairs[1:]])
    P = sp.csr_matrix((np.ones(len(r)), (r, c)), shape=(ny * nx, ny * nx))
    A = sp.kron(P, np.ones((6, 6)), format="csc")
    A.data = np.random.default_rng(3).normal(size=A.nnz)
    A = (A + 40.0 * sp.eye(A.shape[0])).tocsc()
    A.sort_indices()
    handle = pardiso.Pardiso(A.indptr, A.indices, A.shape[0], order=2, n_threads=2)
    assert handle.iparm[33] == 2
    b = np.linspace(-1.0, 1.0, A.shape[0])
    x = [handle.factorise(A.data).solve(b) for _ in range(4)]
    assert all(np.array_equal(x[0], y) for y in x[1:])
    assert np.linalg.norm(A @ x[0] - b) <= 1e-10 * np.linalg.norm(b)
    handle.release()


@needs_mkl
def test_a_run_with_pardiso_is_the_run_with_lu():
    """The smoke case to its end with each direct solver: the same Newton iterations and the
    same force-displacement curve to round-off (1e-9 of the largest force)."""
    out = {}
    for lin in ("lu", "pardiso"):
        integ = build_scene(load_case(SMOKE, [*QUIET, f"solver.linear={lin}"])).integrator()
        assert integ.newton.linear == lin
        T, its = [], 0
        for _ in range(60):
            rep = integ.step()
            its += rep.sweeps
            T.append(integ.joints.T.copy())
        out[lin] = np.array(T), its
    (T_lu, it_lu), (T_pa, it_pa) = out["lu"], out["pardiso"]
    assert it_pa == it_lu
    assert np.abs(T_pa - T_lu).max() <= 1e-9 * np.abs(T_lu).max()


def test_bench_scaling_sizes_and_options():
    # walls doubled in turn along the courses and the units per course, to 64 times the units
    sizes = bm.scaling_sizes(11, 6, 64)
    assert [k for k, *_ in sizes] == [1, 2, 4, 8, 16, 32, 64]
    assert all(c * n == k * 11 * 6 for k, c, n in sizes)
    assert sizes[4:] == [(16, 44, 24), (32, 88, 24), (64, 88, 48)]
    assert bm.scaling_sizes(11, 6) == sizes[:4]  # the default stays at 8x
    with pytest.raises(ValueError, match="power of two"):
        bm.scaling_sizes(11, 6, 12)
    runner = CliRunner()
    for args, field in ((["--largest", "3"], "--largest"), (["--largest", "512"], "--largest"),
                        (["--smallest", "16", "--largest", "8"], "--smallest"),
                        (["--time-limit", "0"], "--time-limit"),
                        (["--memory-limit", "0.1"], "--memory-limit")):
        res = runner.invoke(app, ["bench-scaling", STUDY, *args])
        assert res.exit_code == 2, (args, res.output)
        assert field in res.output


def test_a_wall_stopped_by_its_limit_keeps_its_build_and_steps():
    """A child result with four steps, cumulative solver counts before and after each step,
    stopped by its time limit: the row keeps the build time and the steps it made, and the
    counts per step are those of the steps after the skipped ones."""
    counts = [{"factorisations": f, "linear_iterations": 10 * f, "linear_fallbacks": 0}
              for f in (1, 3, 4, 6, 7)]
    res = {"status": "timeout", "message": "stopped", "process_s": 9.0, "peak_rss_MiB": 500.0,
           "scene_s": 1.0, "build_s": 1.5, "units": 10, "contact_points": 100, "dofs": 300,
           "step_s": [0.5, 0.2, 0.3, 0.4], "sweeps": [10, 4, 6, 8], "counts": counts}
    row = bm._scaling_row("8x", 4, 2, res, skip=1)
    assert (row.status, row.steps, row.build_s) == ("timeout", 4, 1.5)
    assert row.step_ms_median == pytest.approx(300.0)  # median of 0.2, 0.3, 0.4 s
    assert row.step_ms_mean == pytest.approx(350.0)  # all four, the first included
    assert not row.finished
    # one row per step in scaling_steps.csv, with the factorisations made in that step
    steps = bm.scaling_steps("8x", {**res, "t_s": [0.004, 0.008, 0.012, 0.016]})
    assert [(r.step, r.end_s, r.iterations, r.factorisations) for r in steps] == [
        (1, 0.004, 10, 2), (2, 0.008, 4, 1), (3, 0.012, 6, 2), (4, 0.016, 8, 1)]
    assert [r.step_ms for r in steps] == pytest.approx([500.0, 200.0, 300.0, 400.0])
    assert row.factorisations_per_step == pytest.approx((7 - 3) / 3)
    assert row.linear_iterations_per_step == pytest.approx((70 - 30) / 3)


def test_a_krylov_solve_that_does_not_converge_is_made_by_lu():
    """GMRES allowed one iteration to a relative residual of 1e-14 cannot converge: every
    such solve is detected, made again by an LU of the same matrix and recorded, and the steps
    are those of the LU run to the Newton tolerance."""
    T = {}
    for lin in ("lu", "krylov"):
        integ = build_scene(load_case(SMOKE, [*QUIET, f"solver.linear={lin}"])).integrator()
        if lin == "krylov":
            integ.newton._krylov.max_iterations = 1
            integ.newton._krylov.rtol = 1e-14
        for _ in range(3):
            integ.step()
        T[lin] = integ.joints.T.copy()
        if lin == "krylov":
            counts = integ.solver_counts()
            assert counts["linear_fallbacks"] >= 1
            notes = integ.linear_notes()
            assert len(notes) == counts["linear_fallbacks"]
            assert all("GMRES not converged" in n and "by LU" in n for n in notes)
    tol = load_case(SMOKE, QUIET).solver.tolerance
    assert np.linalg.norm(T["krylov"] - T["lu"]) <= 100.0 * tol * np.linalg.norm(T["lu"])


def test_newton_matrix_values_fill_the_pattern_as_its_triplets_do(smoke_scene):
    """``jacobian_values`` (the entries summed straight into a fixed pattern) gives the values
    that the triplets of ``jacobian_coo`` give through the pattern, bit for bit, in the natural
    pattern and in the pattern reordered by a first SuperLU factorisation; the matrix is the one
    scipy assembles from the triplets."""
    from masonry_nscd.nscd.newton import _Pattern, bodies_values, jacobian_values

    integ = smoke_scene.integrator()
    for _ in range(3):
        integ.step()
    N = integ.newton
    n = len(N.free) + 3 * len(N.mult)
    args = N.jacobian_args(N._K_factorised)
    r, c, v = jacobian_coo(*args, True)
    J = sp.csc_matrix((v, (r, c)), shape=(n, n))
    pat = _Pattern(r, c, n)
    for reordered in (False, True):
        data = jacobian_values(pat.slot, len(pat.indices), *args)
        assert np.array_equal(data, pat.values(v))
        # the bodies' blocks summed once, the points' entries onto a copy: the same bits
        bodies = bodies_values(pat.slot, len(pat.indices), *args)
        assert 0 < bodies[1] < len(v)
        assert np.array_equal(jacobian_values(pat.slot, len(pat.indices), *args, bodies=bodies),
                              data)
        if not reordered:
            # scipy sums the repeated entries in another order: equal to round-off
            assert np.allclose(pat.matrix(data).toarray(), J.toarray(), rtol=1e-14,
                               atol=1e-14 * abs(J).max())
            pat.factorise(data)  # the first factorisation reorders the pattern
    b = np.random.default_rng(2).normal(size=n)
    x = pat.factorise(data).solve(b)  # in the reordered pattern
    assert np.abs(J @ x - b).max() <= 1e-9 * abs(J).max() * np.abs(x).max()
    # a pattern one entry short is refused before anything is written past it, and one
    # entry too long is refused too
    with pytest.raises(RuntimeError, match="more entries than its pattern"):
        jacobian_values(pat.slot[:-1], len(pat.indices), *args)
    with pytest.raises(RuntimeError, match="entries, its pattern"):
        jacobian_values(np.append(pat.slot, 0), len(pat.indices), *args)


def _with_and_without_sharing(monkeypatch, solver: str, cls, method: str) -> list:
    """The smoke wall stepped 12 times with a step that grows (rungs made), with the rungs
    sharing the run's solver's parts, then with ``cls.method`` doing nothing (each its own)."""
    sets = [*QUIET, f"solver.linear={solver}", "solver.max_time_step_s=8e-3",
            "solver.grow_after_steps=1", "solver.easy_iterations=20"]
    runs = []
    for share in (True, False):
        if not share:
            monkeypatch.setattr(cls, method, lambda self, other: None)
        integ = build_scene(load_case(SMOKE, sets)).integrator()
        for _ in range(12):
            integ.step()
        assert integ._rungs, "the step did not grow"
        runs.append(integ)
    return runs


@pytest.mark.skipif(not pardiso.available(), reason="PARDISO needs MKL")
def test_the_adaptive_steps_rungs_share_the_newton_pattern_with_handles_of_their_own(
        monkeypatch):
    """With PARDISO the rungs take the Newton matrix's pattern (its slots) of the run's solver,
    each with a PARDISO handle of its own (a handle keeps one factorisation), and step to the
    same states as rungs that made their own."""
    from masonry_nscd.nscd.newton import NewtonSolver

    runs = _with_and_without_sharing(monkeypatch, "pardiso", NewtonSolver, "share_pattern")
    for integ, share in zip(runs, (True, False), strict=True):
        base = integ.newton._pattern
        for rung in integ._rungs.values():
            assert (rung.newton._pattern.slot is base.slot) == share
            assert rung.newton._pattern._pardiso is not base._pardiso
    shared, own = runs
    assert np.array_equal(shared.u, own.u) and np.array_equal(shared.joints.T, own.joints.T)


@pytest.mark.skipif(not pardiso.available(), reason="PARDISO needs MKL")
def test_the_adaptive_steps_rungs_share_the_krylov_solvers_fixed_parts(monkeypatch):
    """On krylov the rungs take the run's solver's coarse space, block numbering, coarse seed
    and analysed coarse pattern (with a PARDISO handle of their own), and step to the same
    states bit for bit as rungs that made their own."""
    runs = _with_and_without_sharing(monkeypatch, "krylov", linear.KrylovSolver, "share")
    for integ, share in zip(runs, (True, False), strict=True):
        base = integ.newton._krylov
        for rung in integ._rungs.values():
            own = rung.newton._krylov
            assert (own.R is base.R and own._block_of is base._block_of) == share
            assert (own._coarse_seed is base._coarse_seed) == share
            assert (own._coarse_pattern.keys is base._coarse_pattern.keys) == share
            assert own._coarse_pattern.handle is not base._coarse_pattern.handle
            assert own.coarse_analyses == 1
    shared, own = runs
    assert shared.solver_counts() == own.solver_counts()
    assert np.array_equal(shared.u, own.u) and np.array_equal(shared.joints.T, own.joints.T)


def test_nonzero_csr_drops_the_patterns_zeros_as_scipy_does():
    """A fixed pattern's CSR arrays with structural zeros: the same matrix as scipy's
    ``eliminate_zeros`` (entries, order and values), with 32-bit indices."""
    rng = np.random.default_rng(5)
    A = sp.random(40, 40, density=0.3, random_state=6, format="csr")
    A.data[rng.uniform(size=A.nnz) < 0.4] = 0.0  # zeros kept in the pattern
    A.data[0] = -0.0
    ref = A.copy()
    ref.eliminate_zeros()
    S = linear.nonzero_csr(A.indptr, A.indices, A.data, 40)
    assert S.indices.dtype == np.int32 and S.indptr.dtype == np.int32
    assert np.array_equal(S.indptr, ref.indptr) and np.array_equal(S.indices, ref.indices)
    assert np.array_equal(S.data, ref.data) and S.nnz == ref.nnz < A.nnz


def test_the_compiled_pattern_sort_gives_numpys_pattern():
    """``newton.csc_slots`` (the large patterns' sort) against ``np.unique`` of the keys
    ``cols n + rows`` (the small ones'): the same compressed columns and slots, duplicates and
    empty columns included."""
    from masonry_nscd.nscd.newton import csc_slots

    rng = np.random.default_rng(8)
    n, count = 300, 20_000
    rows, cols = rng.integers(0, n, count), rng.integers(0, n - 5, count)  # 5 empty columns
    uniq, slot = np.unique(cols * n + rows, return_inverse=True)
    indptr = np.empty(n + 1, dtype=np.int64)
    got_slot, got_indices = csc_slots(rows, cols, n, indptr)
    assert np.array_equal(got_slot, slot)
    assert np.array_equal(got_indices, uniq % n)
    assert np.array_equal(indptr, np.searchsorted(uniq // n, np.arange(n + 1)))


def test_block_inverses_on_threads_are_the_inverses_on_one():
    """The preconditioner's block inverses cut into ranges on threads are numpy's inverses of
    the whole stack, bit for bit (each block by the same LAPACK call)."""
    from masonry_nscd import threads

    rng = np.random.default_rng(3)
    blocks = rng.normal(size=(37, 9, 9)) + 9.0 * np.eye(9)
    try:
        threads.set_count(3)
        assert len(threads.ranges(len(blocks), min_size=linear.MIN_BLOCKS_PER_THREAD)) == 2
        assert np.array_equal(linear._inverses(blocks), np.linalg.inv(blocks))
    finally:
        threads.set_count(None)


def test_pardiso_takes_the_kernels_thread_count_unless_mkl_num_threads(monkeypatch):
    """A factorisation gives MKL the kernels' thread count (``--threads``), or
    ``MKL_NUM_THREADS`` when it is set; MKL is told again only when the number changes."""
    from masonry_nscd import threads

    calls = []

    class Lib:
        def MKL_Set_Num_Threads(self, n):
            calls.append(n)

    monkeypatch.setattr(pardiso, "_threads_set", 0)
    monkeypatch.delenv("MKL_NUM_THREADS", raising=False)
    try:
        threads.set_count(3)
        pardiso._use_threads(Lib())
        pardiso._use_threads(Lib())
        threads.set_count(1)
        pardiso._use_threads(Lib())
        monkeypatch.setenv("MKL_NUM_THREADS", "2")
        pardiso._use_threads(Lib())
    finally:
        threads.set_count(None)
    assert calls == [3, 1, 2]


def test_values_laid_on_a_larger_pattern_are_the_matrix():
    rng = np.random.default_rng(5)
    A = sp.random(30, 30, density=0.2, random_state=rng, format="csc")
    A.sort_indices()
    big = (A + sp.random(30, 30, density=0.2, random_state=rng, format="csc")).tocsc()
    big.sort_indices()
    keys = np.repeat(np.arange(30), np.diff(big.indptr)) * 30 + big.indices
    data = linear._on_pattern(keys, A)
    on_big = sp.csc_matrix((data, big.indices, big.indptr), shape=A.shape)
    assert np.array_equal(on_big.toarray(), A.toarray())
    own = np.repeat(np.arange(30), np.diff(A.indptr)) * 30 + A.indices
    assert linear._on_pattern(own[1:], A) is None  # an entry outside the pattern


def test_the_coarse_pattern_is_analysed_once_per_solver():
    """The smoke wall to its end with krylov: the coarse matrix's entries come and go as joints
    open and close, but its LU is analysed once, on every entry it can have."""
    if not pardiso.available():
        pytest.skip("the coarse LU is SciPy's SuperLU without MKL")
    integ = build_scene(load_case(SMOKE, [*QUIET, "solver.linear=krylov"])).integrator()
    for _ in range(60):
        integ.step()
    ks = integ.newton._krylov
    assert integ.newton.factorisations > 1
    assert ks.coarse_analyses == 1



def test_idle_step_sizes_let_go_and_step_the_same_when_the_run_comes_back():
    """The step sizes the run is not stepping with hold no Krylov matrix, no preconditioner
    blocks and no ``M_hat``, ``M_hat^-1``. With a direct solver (whose factors are kept) an
    integrator that let go of its ``M_hat`` and ``M_hat^-1`` between two steps steps to the
    same states bit for bit as one that kept them: they are made again by the same calls."""
    sets = [*QUIET, "solver.max_time_step_s=8e-3", "solver.grow_after_steps=1",
            "solver.easy_iterations=20"]
    integ = build_scene(load_case(SMOKE, [*sets, "solver.linear=krylov"])).integrator()
    levels = []
    for _ in range(6):
        integ.step()
        levels.append(integ._made_by)
        for k, other in {0: integ, **integ._rungs}.items():
            if k != integ._made_by:
                assert other.sys.minv is None and other.sys.mhat is None
                assert other.newton.lu is None and other.newton._krylov._last_blocks is None
    assert len(set(levels)) >= 2, "the step did not grow"
    direct = "pardiso" if pardiso.available() else "lu"
    runs = []
    for release in (True, False):
        run = build_scene(load_case(SMOKE, [*QUIET, f"solver.linear={direct}"])).integrator()
        for n in range(6):
            if release and n in (2, 4):
                run.release()
                assert run.sys.minv is None and run.newton.mhat is None
            run.step()
        runs.append(run)
    released, kept = runs
    assert np.array_equal(released.u, kept.u) and np.array_equal(released.v, kept.v)
    assert np.array_equal(released.joints.T, kept.joints.T)
