"""Checkpoints of the NSCD time loop: the integrator's state as plain arrays, and back.

What a checkpoint holds (SI units, as in the integrator):

* ``u`` (m, rad for rigid rotations), ``v`` (m/s, rad/s): the dofs at the end of the last step;
* ``t`` (s), ``step_index``: time and number of steps done;
* ``F0`` (N): external forces at ``t`` (the start of the next step);
* ``dv`` (m/s): the last impulse velocity correction, the warm start of the next contact solve;
* ``halve_next``, ``halve_run``: how many of the next steps are to be made as halves at once,
  and how many after the next failure at h (the step control's memory of recent failures,
  ``Integrator.halve_after_failure``; absent in older checkpoints: no memory);
* ``step_level``, ``step_easy``: the adaptive step size's level and its count of easy steps
  (``nscd/step_size.py``; absent in older checkpoints: level 0);
* ``kinetic_last_J``: with kinetic damping, the kinetic energy at the end of the last step (J),
  which the next step's is compared with (absent: no comparison at the first step);
* ``joint_u``, ``joint_U``, ``joint_uc``, ``joint_beta``, ``joint_T``, ``joint_status``: the
  :class:`~masonry_nscd.nscd.integrator.JointState` of every contact point (m, m/s, m, -, Pa,
  status code);
* ``energy`` (J): the accumulated terms of the energy balance (``nscd/energy.py``,
  ``ACCUMULATED``); a checkpoint written before it was kept resumes with them at zero;
* ``material_state``, ``material_sigma``, ``material_eps``, ``material_sigma_endo3d``: the
  committed ENDO3D Gauss-point states, apparent stresses (Pa), strains and ENDO3D stresses (Pa)
  of the ENDO3D blocks, when the scene has any (the strains and the two stresses are where the
  viscous regularisation relaxes from; a checkpoint written before the ENDO3D stresses were
  kept resumes with them equal to the apparent ones: no overstress).

Not saved: what the solver keeps between steps to go faster. The sparse LU of the Newton
matrix, its iteration matrix of the ENDO3D blocks (their tangent) and the last trial states
are rebuilt by a freshly built integrator on its first step. That changes only the iteration
path: a resumed run reaches the same states as an uninterrupted one within the solver
tolerance.

The file that holds these arrays (``checkpoint.npz`` of a run folder) is written and read by
:mod:`masonry_nscd.io.checkpoint_file`: this module knows no file.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

_JOINT_FIELDS = ("u", "U", "uc", "beta", "T", "status")


class CheckpointError(ValueError):
    """A checkpoint that cannot be read or does not fit the integrator."""


def integrator_state(integ) -> dict[str, NDArray]:
    """Copies of every array that the next step of ``integ`` (an ``Integrator``) depends on."""
    out: dict[str, NDArray] = {
        "u": integ.u, "v": integ.v, "t": np.float64(integ.t),
        "step_index": np.int64(integ.step_index), "F0": integ._F0, "dv": integ._dv,
        "energy": integ.energy,
    }
    j = integ.joints
    for name in _JOINT_FIELDS:
        out[f"joint_{name}"] = getattr(j, name)
    mat = integ.material
    if mat is not None:
        out["material_state"] = mat.state_all
        out["material_sigma"] = mat.sigma_committed_all
        out["material_eps"] = mat.eps_committed_all
        out["material_sigma_endo3d"] = mat.sigma_endo3d_committed_all
    return {k: np.array(v, copy=True) for k, v in out.items()}


def _check_shape(name: str, value: np.ndarray, shape: tuple[int, ...]) -> None:
    if value.shape != shape:
        raise CheckpointError(f"checkpoint field {name!r}: shape {value.shape}, the scene "
                              f"needs {shape} (was the case changed?)")


def _put(name: str, target: np.ndarray, value: np.ndarray) -> None:
    """Copy ``value`` into ``target`` in place (views into it stay valid), checking the shape."""
    _check_shape(name, value, target.shape)
    target[...] = value


def restore_integrator(integ, state: Mapping[str, ArrayLike]) -> None:
    """Put ``state`` (from :func:`integrator_state`) into ``integ``, a freshly built integrator
    of the same scene. Raises :class:`CheckpointError` when a field is missing or has another
    shape. The solver caches stay as built (empty) and fill again on the next step."""
    need = ["u", "v", "t", "step_index", "F0", "dv", *(f"joint_{n}" for n in _JOINT_FIELDS)]
    mat = integ.material
    if mat is not None:
        need += ["material_state", "material_sigma", "material_eps"]
    missing = [k for k in need if k not in state]
    if missing:
        raise CheckpointError(f"checkpoint lacks {', '.join(missing)}")
    if mat is None and "material_state" in state:
        raise CheckpointError("checkpoint has ENDO3D block states, the scene has no ENDO3D block")
    arr = {k: np.asarray(state[k]) for k in need}
    for name in ("u", "v", "F0", "dv"):
        _check_shape(name, arr[name], integ.u.shape)
    j = integ.joints
    for name in _JOINT_FIELDS:
        _put(f"joint_{name}", getattr(j, name), arr[f"joint_{name}"])
    if mat is not None:
        _put("material_state", mat.state_all, arr["material_state"])
        _put("material_sigma", mat.sigma_committed_all, arr["material_sigma"])
        _put("material_eps", mat.eps_committed_all, arr["material_eps"])
        _put("material_sigma_endo3d", mat.sigma_endo3d_committed_all,
             np.asarray(state.get("material_sigma_endo3d", arr["material_sigma"])))
        # no trial pending: the trial states and stresses equal the committed ones
        mat.trial_all[...] = mat.state_all
        mat.sigma_all[...] = mat.sigma_committed_all
    integ.u = arr["u"].astype(float, copy=True)
    integ.v = arr["v"].astype(float, copy=True)
    integ._F0 = arr["F0"].astype(float, copy=True)
    integ._dv = arr["dv"].astype(float, copy=True)
    if "energy" in state:
        _put("energy", integ.energy, np.asarray(state["energy"]))
    else:
        integ.energy[...] = 0.0
    integ.t = float(arr["t"])
    integ.step_index = int(arr["step_index"])
    integ.set_step_memory({k: np.asarray(v) for k, v in state.items()
                           if k in ("halve_next", "halve_run", "step_level", "step_easy",
                                    "kinetic_last_J")})
