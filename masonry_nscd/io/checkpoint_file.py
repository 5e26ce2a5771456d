"""The checkpoint file of a run folder (``checkpoint.npz``): the integrator's state on disk.

What the arrays are, and how an integrator is put back from them, is the step layer's
(:mod:`masonry_nscd.nscd.checkpoint`); this module writes them to a file and reads them back:

* the file is a NumPy ``.npz`` (no pickled objects) whose arrays are the integrator's state
  (SI units, :func:`masonry_nscd.nscd.checkpoint.integrator_state`), the step control's memory
  (``halve_next``, ``halve_run``, ``step_level``, ``step_easy``), the format's name
  (:data:`FORMAT`) and version (:data:`FORMAT_VERSION`), and the caller's own arrays, stored
  with the prefix ``run_`` to keep them apart;
* it is written atomically (:mod:`masonry_nscd.io.atomic`): a checkpoint on disk is always
  either the previous complete one or the new complete one.
"""

from __future__ import annotations

import os
import zipfile
from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from masonry_nscd.io.atomic import atomic_write
from masonry_nscd.nscd.checkpoint import CheckpointError, integrator_state

FORMAT = "masonry_nscd.checkpoint"
FORMAT_VERSION = 1
_EXTRA = "run_"


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
        **{k: np.asarray(v) for k, v in integ.step_memory().items()},
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
