"""Drive one ENDO3D Gauss point along a loading path (the material-point checks of model.md).

The point belongs to a cube of side ``h`` (m) aligned with the axes, whose extent along a crack
direction gives the Hillerborg length. The axial strain ``eps_xx`` is prescribed step by step;
the other five strain components are either

* ``lateral='free'``: unknowns, found at each step so that the corresponding apparent stresses
  vanish (uniaxial stress). Predictor: the previous step's increment of the free components
  scaled to the new prescribed increment (when it goes the same way), else the elastic one
  (``C0_ff de_f = -C0_fp de_p``); then Newton iterations on the free components with a
  finite-difference Jacobian, each update limited to 10 times the prescribed increment (a fully
  cracked lateral direction is also stress free: a spurious solution far away that unlimited
  Newton steps can jump to) of the kernel (the state is always recomputed from the converged
  state of the previous step, so the iterations do not pollute the history), a backtracking line
  search, and the elastic stiffness ``C0`` restricted to the free components as the fallback
  iteration matrix; converged when ``max |sigma_free| <= 1e-6 R_t``;
* ``lateral='fixed'``: zero (uniaxial strain, confined).

Signs: compression negative. :func:`drive_block_point` makes the final strain ``to`` positive
for ``path='tension'`` and negative for ``path='compression'`` whatever sign is given.

The loop is ordinary Python calling the numba kernel of :mod:`masonry_nscd.materials.endo3d`
(no numba code here: a cached kernel calling a kernel of another module can go stale).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from masonry_nscd.materials.endo3d import (
    N_STATE,
    P_RT,
    S_D_C,
    S_D_CPP,
    S_D_T,
    elastic_matrix,
    endo3d_initial_state,
    endo3d_params,
    endo3d_update,
)

__all__ = [
    "CURVE_COLUMNS",
    "DriverError",
    "cube_nodes",
    "drive_block_path",
    "drive_block_point",
    "drive_mixed",
    "params_from_case",
    "write_curve_csv",
]

FloatArray = NDArray[np.float64]

#: Columns of the curve CSV written by :func:`write_curve_csv`.
CURVE_COLUMNS = ("step", "eps_axial", "sigma_axial_Pa", "d_t", "d_c", "d_cpp")


class DriverError(RuntimeError):
    """The mixed strain/stress iterations of a step did not converge."""


def cube_nodes(size: float) -> FloatArray:
    """Nodes (8, 3) of the cube ``[0, size]^3`` (m), in the usual hex8 order."""
    h = float(size)
    return np.array(
        [[0, 0, 0], [h, 0, 0], [h, h, 0], [0, h, 0], [0, 0, h], [h, 0, h], [h, h, h], [0, h, h]],
        dtype=np.float64,
    )


def params_from_case(case: Any) -> FloatArray:
    """ENDO3D parameter vector from a validated case: ``case.blocks.E_Pa``, ``case.blocks.nu``
    and the fields of ``case.blocks.endo3d`` (SI units, see :func:`endo3d_params`)."""
    b = case.blocks
    e = b.endo3d
    return endo3d_params(
        E=float(b.E_Pa),
        nu=float(b.nu),
        R_t=float(e.R_t_Pa),
        eps_pic_t=float(e.eps_pic_t),
        G_ft=float(e.G_ft_J_m2),
        R_c=float(e.R_c_Pa),
        eps_pic_c=float(e.eps_pic_c),
        delta=float(e.delta),
        beta=float(e.beta),
        eps_kdc=float(e.eps_kdc),
        crushing_length=float(e.crushing_length_m),
        DCPK=float(e.DCPK),
        REF=float(e.REF_Pa),
        GFR=float(e.GFR_J_m2),
    )


def drive_mixed(
    params: FloatArray,
    eps_path: FloatArray,
    free: NDArray[np.bool_],
    xe: FloatArray,
    *,
    state0: FloatArray | None = None,
    stress_tol: float | None = None,
    max_iter: int = 60,
) -> dict[str, FloatArray]:
    """Drive one point through ``eps_path`` (nsteps, 6) (Voigt, engineering shear): the
    components where ``free`` (6,) is False are prescribed from ``eps_path``; the free ones are
    solved at each step so that their apparent stresses vanish (``|sigma| <= stress_tol``, by
    default ``1e-6 R_t``). ``xe`` (8, 3): element nodes (m). ``state0``: starting state (virgin
    by default).

    Returns ``eps`` (nsteps, 6), ``sigma`` (nsteps, 6) in Pa, ``state`` (nsteps, N_STATE),
    ``status`` (nsteps,) of the kernel and ``iterations`` (nsteps,) of the mixed solve.
    Raises :class:`DriverError` when a step does not converge.
    """
    eps_path = np.ascontiguousarray(eps_path, dtype=np.float64)
    free = np.asarray(free, dtype=bool)
    xe = np.ascontiguousarray(xe, dtype=np.float64)
    nsteps = eps_path.shape[0]
    tol = 1e-6 * params[P_RT] if stress_tol is None else float(stress_tol)
    fi = np.flatnonzero(free)
    nf = fi.size
    C0 = elastic_matrix(params[0], params[1])
    C0ff = C0[np.ix_(fi, fi)]

    st_prev = endo3d_initial_state() if state0 is None else np.array(state0, dtype=np.float64)
    out_eps = np.zeros((nsteps, 6))
    out_sig = np.zeros((nsteps, 6))
    out_st = np.zeros((nsteps, N_STATE))
    out_status = np.zeros(nsteps, dtype=np.int64)
    out_iter = np.zeros(nsteps, dtype=np.int64)

    st = np.empty(N_STATE)
    sig = np.empty(6)
    st2 = np.empty(N_STATE)
    sig2 = np.empty(6)

    def evaluate(e: FloatArray, s_out: FloatArray, st_out: FloatArray) -> int:
        return endo3d_update(e, st_prev, params, xe, st_out, s_out)

    e_prev = np.zeros(6)
    de_p_prev = np.zeros(6)
    de_f_prev = np.zeros(nf)
    for k in range(nsteps):
        e = e_prev.copy()
        e[~free] = eps_path[k, ~free]
        de_p = e - e_prev
        if nf:
            dp2 = float(de_p @ de_p)
            if k >= 1 and dp2 > 0.0 and float(de_p @ de_p_prev) > 0.0:
                # same direction as the previous step: scaled secant predictor
                e[fi] += (float(de_p @ de_p_prev) / float(de_p_prev @ de_p_prev)) * de_f_prev
            else:
                # first step or reversal: elastic predictor C0_ff de_f = -C0_fp de_p
                e[fi] -= np.linalg.solve(C0ff, C0[fi] @ de_p)
        # trust region of the Newton updates of the free components
        step_max = 10.0 * max(float(np.max(np.abs(de_p))), 1e-3 * params[P_RT] / params[0])
        status = evaluate(e, sig, st)
        it = 0
        if nf:
            r = sig[fi].copy()
            rn = np.max(np.abs(r))
            while rn > tol:
                it += 1
                if it > max_iter:
                    raise DriverError(
                        f"step {k}: the stress-free components did not converge "
                        f"(max |sigma| = {rn:.3e} Pa after {max_iter} iterations)"
                    )
                # finite-difference Jacobian of the free stresses
                hfd = 1e-7 * max(np.max(np.abs(e)), params[P_RT] / params[0])
                J = np.empty((nf, nf))
                for a, j in enumerate(fi):
                    e2 = e.copy()
                    e2[j] += hfd
                    evaluate(e2, sig2, st2)
                    J[:, a] = (sig2[fi] - r) / hfd
                try:
                    de = np.linalg.solve(J, -r)
                    if not np.all(np.isfinite(de)):
                        raise np.linalg.LinAlgError
                except np.linalg.LinAlgError:
                    de = np.linalg.solve(C0ff, -r)
                accepted = False
                for direction in (de, np.linalg.solve(C0ff, -r)):
                    big = float(np.max(np.abs(direction)))
                    if big > step_max:
                        direction = direction * (step_max / big)
                    alpha = 1.0
                    while alpha >= 1.0 / 256.0:
                        e2 = e.copy()
                        e2[fi] += alpha * direction
                        st_k = evaluate(e2, sig2, st2)
                        rn2 = np.max(np.abs(sig2[fi]))
                        if rn2 < rn:
                            e = e2
                            sig[:] = sig2
                            st[:] = st2
                            status = st_k
                            r = sig[fi].copy()
                            rn = rn2
                            accepted = True
                            break
                        alpha *= 0.5
                    if accepted:
                        break
                if not accepted:
                    raise DriverError(
                        f"step {k}: no descent for the stress-free components "
                        f"(max |sigma| = {rn:.3e} Pa)"
                    )
        out_eps[k] = e
        out_sig[k] = sig
        out_st[k] = st
        out_status[k] = status
        out_iter[k] = it
        st_prev = st.copy()
        if float(de_p @ de_p) > 0.0:
            de_p_prev = de_p
            de_f_prev = e[fi] - e_prev[fi]
        e_prev = e.copy()
    return {
        "eps": out_eps,
        "sigma": out_sig,
        "state": out_st,
        "status": out_status,
        "iterations": out_iter,
    }


def drive_block_path(
    params: FloatArray,
    eps_axial: FloatArray,
    size: float = 0.1,
    lateral: str = "free",
    xe: FloatArray | None = None,
) -> dict[str, FloatArray]:
    """Drive the axial strain ``eps_xx`` through the values ``eps_axial`` (any path: loading,
    unloading, cycles), lateral components ``'free'`` (stress free) or ``'fixed'`` (zero).
    ``xe`` defaults to the cube of side ``size`` (m). Returns the arrays of :func:`drive_mixed`
    plus ``eps_axial``, ``sigma_axial_Pa``, ``d_t`` (largest tensile damage), ``d_c``, ``d_cpp``.
    """
    if lateral not in ("free", "fixed"):
        raise ValueError(f"lateral must be 'free' or 'fixed', got {lateral!r}")
    eps_axial = np.asarray(eps_axial, dtype=np.float64).ravel()
    path = np.zeros((eps_axial.size, 6))
    path[:, 0] = eps_axial
    free = np.zeros(6, dtype=bool)
    if lateral == "free":
        free[1:] = True
    nodes = cube_nodes(size) if xe is None else xe
    res = drive_mixed(params, path, free, nodes)
    st = res["state"]
    res["eps_axial"] = res["eps"][:, 0].copy()
    res["sigma_axial_Pa"] = res["sigma"][:, 0].copy()
    res["d_t"] = st[:, S_D_T].copy()
    res["d_c"] = st[:, S_D_C].copy()
    res["d_cpp"] = st[:, S_D_CPP].copy()
    return res


def drive_block_point(
    params: FloatArray,
    path: str,
    to: float,
    size: float = 0.1,
    steps: int = 200,
    lateral: str = "free",
) -> dict[str, NDArray[Any]]:
    """Monotonic uniaxial path of one ENDO3D point of a cube of side ``size`` (m).

    ``path``: ``'tension'`` or ``'compression'``; ``to``: final axial strain, made positive for
    tension and negative for compression (its sign is ignored); ``steps`` equal strain
    increments from 0; ``lateral``: ``'free'`` (uniaxial stress) or ``'fixed'`` (lateral strains
    zero). Returns arrays of ``steps + 1`` rows (row 0 is the unloaded state) under the keys
    ``step``, ``eps_axial``, ``sigma_axial_Pa`` (Pa, compression negative), ``d_t`` (largest
    tensile damage), ``d_c``, ``d_cpp``.
    """
    if path not in ("tension", "compression"):
        raise ValueError(f"path must be 'tension' or 'compression', got {path!r}")
    if steps < 1:
        raise ValueError(f"steps must be >= 1, got {steps}")
    if not size > 0.0:
        raise ValueError(f"size must be > 0, got {size}")
    final = abs(float(to)) if path == "tension" else -abs(float(to))
    eps_axial = np.linspace(0.0, final, steps + 1)
    res = drive_block_path(params, eps_axial[1:], size=size, lateral=lateral)
    zero = np.zeros(1)
    return {
        "step": np.arange(steps + 1, dtype=np.int64),
        "eps_axial": eps_axial,
        "sigma_axial_Pa": np.concatenate([zero, res["sigma_axial_Pa"]]),
        "d_t": np.concatenate([zero, res["d_t"]]),
        "d_c": np.concatenate([zero, res["d_c"]]),
        "d_cpp": np.concatenate([zero, res["d_cpp"]]),
    }


def write_curve_csv(path: str | Path, curve: dict[str, NDArray[Any]]) -> Path:
    """Write ``curve`` (from :func:`drive_block_point`) as CSV with the header
    ``step,eps_axial,sigma_axial_Pa,d_t,d_c,d_cpp``; returns the path."""
    path = Path(path)
    if path.parent != Path(""):
        path.parent.mkdir(parents=True, exist_ok=True)
    n = len(curve["step"])
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(CURVE_COLUMNS)
        for i in range(n):
            w.writerow(
                [int(curve["step"][i])] + [repr(float(curve[c][i])) for c in CURVE_COLUMNS[1:]]
            )
    return path
