r"""Products by the bodies' block-diagonal matrices (``M_hat``, ``M_hat^-1``, ``K``).

Each body ``b`` has a dense block ``A_b`` (``n_b`` x ``n_b``, row-major) stored in one flat
array at offset ``off[b]`` (``-1``: the body has none, and the product is zero on its dofs).
The product ``y = A x`` is, body by body,

    y[d_b : d_b + n_b] = A_b x[d_b : d_b + n_b]          (d_b = body_dof0[b])

The bodies whose blocks have the same size form a group, and a group is multiplied by one
stacked BLAS product (``numpy.matmul`` of a (count, n, n) array by a (count, n, 1) one): a wall
has a few sizes (units, refined units, half units, rigid beams), so a product is a few BLAS
calls instead of a scalar loop over every entry. For this the flat array holds each group's
blocks one after the other (``grouped_offsets``), and a group's stack is a view of it: a
change of the flat array shows in the products.
"""

from __future__ import annotations

import numpy as np


def grouped_offsets(sizes: np.ndarray, present: np.ndarray | None = None) -> np.ndarray:
    """Offsets (int64, ``-1`` where ``present`` is False) of blocks of ``sizes`` (rows) laid out
    group by group: the blocks of one size one after the other, in the order of the bodies,
    groups by increasing size."""
    sizes = np.asarray(sizes, dtype=np.int64)
    present = np.ones(len(sizes), dtype=bool) if present is None else np.asarray(present)
    off = np.full(len(sizes), -1, dtype=np.int64)
    at = 0
    for n in np.unique(sizes[present]):
        for b in np.flatnonzero(present & (sizes == n)):
            off[b] = at
            at += int(n) * int(n)
    return off


class BlockDiagonal:
    """The block-diagonal matrix of the blocks in ``flat`` at offsets ``off`` (``-1``: none),
    for the bodies whose dofs start at ``body_dof0``; the blocks of one size must lie one after
    the other in ``flat`` (``grouped_offsets``)."""

    def __init__(self, body_dof0: np.ndarray, off: np.ndarray, flat: np.ndarray):
        sizes = np.diff(body_dof0)
        self.ndof = int(body_dof0[-1])
        self.groups: list[tuple[np.ndarray, np.ndarray]] = []  # (dofs (count, n), stack)
        covered = 0
        for n in np.unique(sizes[off >= 0]):
            bodies = np.flatnonzero((off >= 0) & (sizes == n))
            start = off[bodies]
            if np.any(start != start[0] + n * n * np.arange(len(bodies))):
                raise ValueError(f"the blocks of size {n} are not one after the other in the "
                                 "flat array (lay them out with grouped_offsets)")
            stack = flat[start[0]:start[0] + len(bodies) * n * n].reshape(len(bodies), n, n)
            dofs = body_dof0[bodies][:, None] + np.arange(n)
            self.groups.append((dofs, stack))
            covered += len(bodies) * n
        self.complete = covered == self.ndof  # every dof in a block: no zeros to write

    def matvec(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``A x`` (into ``out`` if given; its entries outside the blocks are set to zero)."""
        if out is None:
            out = np.empty(self.ndof)
        if not self.complete:
            out[:] = 0.0
        for dofs, stack in self.groups:
            out[dofs] = np.matmul(stack, x[dofs][..., None])[..., 0]
        return out


def without(body_dof0: np.ndarray, off: np.ndarray, flat: np.ndarray,
            bodies) -> BlockDiagonal | None:
    """The block-diagonal matrix of the blocks in ``flat`` at ``off`` of every body but
    ``bodies`` (its product zero on their dofs); None when their blocks cannot be left out of
    the groups (bodies of one size not all in ``bodies``, laid out between them)."""
    off = off.copy()
    off[list(bodies)] = -1
    try:
        return BlockDiagonal(body_dof0, off, flat)
    except ValueError:
        return None
