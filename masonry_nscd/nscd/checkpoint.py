"""Checkpoints of the NSCD time loop: the integrator's state as plain arrays, to disk and back.

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

The file is a NumPy ``.npz`` (no pickled objects), written atomically
(:mod:`masonry_nscd.io.atomic`): a checkpoint on disk is always either the previous complete one
or the new complete one. The caller may add its own arrays (prefixed
``run_`` by :func:`write_checkpoint` to keep them apart).
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from masonry_nscd.io.atomic import atomic_write

FORMAT = "masonry_nscd.checkpoint"
FORMAT_VERSION = 1
_JOINT_FIELDS = ("u", "U", "uc", "beta", "T", "status")
_EXTRA = "run_"


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
                           if k in ("halve_next", "halve_run", "step_level", "step_easy")})


def save_checkpoint(path: str | os.PathLike[str], integ,
                    extra: Mapping[str, ArrayLike] | None = None) -> None:
    """Write the state of ``integ`` and the caller's ``extra`` arrays to ``path`` atomically
    (:func:`checkpoint_arrays`, then :func:`write_checkpoint`)."""
    write_checkpoint(path, checkpoint_arrays(integ), extra)


def checkpoint_arrays(integ) -> dict[str, NDArray]:
    """The integrator's part of a checkpoint of ``integ``, as copies: a file written later by
    :func:`write_checkpoint` holds the state of now."""
    return {
        "format": np.array(FORMAT), "format_version": np.int64(FORMAT_VERSION),
        **integrator_state(integ),
        **{k: np.int64(v) for k, v in integ.step_memory().items()},
    }


def write_checkpoint(path: str | os.PathLike[str], state: Mapping[str, NDArray],
                     extra: Mapping[str, ArrayLike] | None = None) -> None:
    """Write ``state`` (:func:`checkpoint_arrays`) and the caller's ``extra`` arrays to
    ``path`` atomically. ``extra`` arrays must be numeric or unicode strings (no objects); they
    are read back by :func:`load_checkpoint` under their own names."""
    arrays = dict(state)
    for k, v in (extra or {}).items():
        a = np.asarray(v)
        if a.dtype.kind not in "biufU":
            raise TypeError(f"checkpoint extra {k!r}: numeric or str array expected, got "
                            f"dtype {a.dtype}")
        arrays[_EXTRA + k] = a

    def write(tmp: str) -> None:
        with open(tmp, "wb") as f:  # a file object: np.savez would add .npz to a name
            np.savez(f, **arrays)

    atomic_write(path, write)


def load_checkpoint(path: str | os.PathLike[str]) -> tuple[dict[str, NDArray],
                                                           dict[str, NDArray]]:
    """Read a checkpoint: ``(integrator state, extra arrays)``. :class:`CheckpointError` when
    the file is not a checkpoint of this format (``FileNotFoundError`` when it is missing)."""
    try:
        with open(path, "rb") as f, np.load(f, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise CheckpointError(f"{path}: not a readable checkpoint ({exc})") from exc
    if str(data.pop("format", "")) != FORMAT:
        raise CheckpointError(f"{path}: not a {FORMAT} file")
    version = int(data.pop("format_version", -1))
    if version != FORMAT_VERSION:
        raise CheckpointError(f"{path}: checkpoint format version {version}, this program "
                              f"reads version {FORMAT_VERSION}")
    extra = {k[len(_EXTRA):]: v for k, v in data.items() if k.startswith(_EXTRA)}
    state = {k: v for k, v in data.items() if not k.startswith(_EXTRA)}
    return state, extra
