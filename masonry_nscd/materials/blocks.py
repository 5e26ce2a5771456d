r"""ENDO3D in the blocks of a scene: Gauss-point states, internal forces, outputs.

Every deformable block with ``material = MAT_ENDO3D`` carries an ENDO3D state at each of the
8 Gauss points of each of its hexahedra. For a trial displacement ``u`` of the step the strains
are computed at the Gauss points, ENDO3D updates the states from those committed at the end of
the last step (``endo3d_update_elements``; the committed states are never modified by a trial),
and the internal forces are ``F_int = sum_e sum_g B^T sigma det J`` (N). ``commit`` makes the
last trial the state of the step.

In the step, the theta-method's internal-force term is ``theta F_int(u_n+1) + (1 - theta)
F_int(u_n)``; the solver linearises it with the elastic stiffness K0 (the iteration matrix of
the reference ENDO3D implementation), so the correction it needs is

    c(u_n+1) = h theta [ F_int(u_n+1) - F_int(u_n) - K0 (u_n+1 - u_n) ]          (N s)

which is zero for linear elastic blocks. Blocks that are linear elastic never call ENDO3D.
"""

from __future__ import annotations

import numpy as np

from masonry_nscd.fe import hex8
from masonry_nscd.materials import endo3d
from masonry_nscd.model import MAT_ENDO3D, Block


class Endo3dBlocks:
    """The ENDO3D blocks of a scene (body indices ``bodies``) and their Gauss-point states."""

    def __init__(self, bodies: list, body_dof0: np.ndarray, params: np.ndarray):
        self.params = np.ascontiguousarray(params, dtype=float)
        self.index = [i for i, b in enumerate(bodies)
                      if isinstance(b, Block) and b.material == MAT_ENDO3D]
        self.blocks = [bodies[i] for i in self.index]
        self.dofs = [np.arange(body_dof0[i], body_dof0[i + 1]) for i in self.index]
        self.xe = [np.ascontiguousarray(b.X[b.conn]) for b in self.blocks]  # (nel, 8, 3)
        self.elem_of_point = [np.repeat(np.arange(len(b.conn)), 8).astype(np.int64)
                              for b in self.blocks]
        init = endo3d.endo3d_initial_state()
        self.state = [np.tile(init, (8 * len(b.conn), 1)) for b in self.blocks]
        self.trial = [s.copy() for s in self.state]
        self.sigma = [np.zeros((8 * len(b.conn), 6)) for b in self.blocks]
        self.sigma_committed = [s.copy() for s in self.sigma]
        self.failures = 0

    def __bool__(self) -> bool:
        return bool(self.blocks)

    def internal_forces(self, u: np.ndarray, fint: np.ndarray, *, trial: bool = True) -> None:
        """Write the ENDO3D internal forces of the blocks at displacement u into fint (N).

        ``trial``: update trial states from the committed ones (inside a step); otherwise the
        committed stresses are used as they are (forces at the start of the step).
        """
        self.failures = 0
        for k, b in enumerate(self.blocks):
            d = self.dofs[k]
            if trial:
                eps = np.empty((8 * len(b.conn), 6))
                hex8.gauss_strains(b.X, b.conn, np.ascontiguousarray(u[d]), eps)
                self.failures += endo3d.endo3d_update_elements(
                    eps, self.state[k], self.params, self.xe[k], self.elem_of_point[k],
                    self.trial[k], self.sigma[k])
                sig = self.sigma[k]
            else:
                sig = self.sigma_committed[k]
            f = np.empty(len(d))
            hex8.internal_forces(b.X, b.conn, sig, f)
            fint[d] = f

    def commit(self) -> None:
        """The last trial becomes the state at the end of the step."""
        for k in range(len(self.blocks)):
            self.state[k][:] = self.trial[k]
            self.sigma_committed[k][:] = self.sigma[k]

    def secant_scale(self, trial: bool = False) -> list[np.ndarray]:
        """Per element of each block, the scale of C0 in the secant iteration matrix.

        ``(1 - d_c)(1 - max(d_cpp, d_t))`` averaged over the element's Gauss points, from the
        committed states (or the last trial ones), floored at 1e-3 so that the matrix stays
        positive definite.
        """
        out = []
        states = self.trial if trial else self.state
        for k, b in enumerate(self.blocks):
            d_c, d_cpp, d_t, _ = endo3d.endo3d_outputs(states[k])
            g = (1.0 - d_c) * (1.0 - np.maximum(d_cpp, d_t))
            out.append(np.maximum(g.reshape(len(b.conn), 8).mean(axis=1), 1e-3))
        return out

    def element_fields(self) -> dict[str, np.ndarray]:
        """Per element, over its Gauss points: max d_c, max d_cpp, max d_t, max crack opening
        (m), and the mean apparent stress (nel, 6), Pa. Blocks in the order of ``index``."""
        out = {"d_c": [], "d_cpp": [], "d_t": [], "crack_opening_m": [], "stress_Pa": []}
        for k, b in enumerate(self.blocks):
            d_c, d_cpp, d_t, w = endo3d.endo3d_outputs(self.state[k])
            ne = len(b.conn)
            out["d_c"].append(d_c.reshape(ne, 8).max(axis=1))
            out["d_cpp"].append(d_cpp.reshape(ne, 8).max(axis=1))
            out["d_t"].append(d_t.reshape(ne, 8).max(axis=1))
            out["crack_opening_m"].append(w.reshape(ne, 8).max(axis=1))
            out["stress_Pa"].append(self.sigma_committed[k].reshape(ne, 8, 6).mean(axis=1))
        return {key: (np.concatenate(v) if v else np.zeros(0)) for key, v in out.items()}
