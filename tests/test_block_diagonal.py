"""The bodies' block-diagonal products (``nscd/block_diagonal.py``) against the dense matrix."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from masonry_nscd.nscd.block_diagonal import BlockDiagonal, grouped_offsets, without


def _blocks(sizes, present, rng):
    return [rng.standard_normal((n, n)) if p else None for n, p in zip(sizes, present,
                                                                       strict=True)]


def _flat(blocks, off):
    flat = np.zeros(sum(b.size for b in blocks if b is not None))
    for b, o in zip(blocks, off, strict=True):
        if b is not None:
            flat[o:o + b.size] = b.ravel()
    return flat


def test_product_equals_the_dense_block_diagonal():
    rng = np.random.default_rng(3)
    # sizes mixed as in a wall: units, refined units, rigid beams; two bodies without a block
    sizes = np.array([54, 6, 54, 150, 54, 6, 150, 24, 54])
    present = np.array([True, False, True, True, True, True, True, True, False])
    blocks = _blocks(sizes, present, rng)
    off = grouped_offsets(sizes, present)
    dof0 = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    op = BlockDiagonal(dof0, off, _flat(blocks, off))
    dense = scipy.linalg.block_diag(*[b if b is not None else np.zeros((n, n))
                                      for b, n in zip(blocks, sizes, strict=True)])
    x = rng.standard_normal(dof0[-1])
    out = np.full(dof0[-1], np.nan)  # entries outside the blocks must be written too
    op.matvec(x, out)
    np.testing.assert_allclose(out, dense @ x, rtol=0, atol=1e-12 * np.abs(dense @ x).max())
    assert not op.complete
    assert np.all(out[dof0[1]:dof0[2]] == 0.0)


def test_offsets_group_the_blocks_by_size_in_body_order():
    off = grouped_offsets(np.array([3, 2, 3, 2]), np.array([True, True, True, False]))
    # the 2 x 2 block first (size order), then the two 3 x 3 blocks in body order
    assert off.tolist() == [4, 0, 13, -1]


def test_views_follow_the_flat_array():
    sizes = np.array([4, 4, 9])
    off = grouped_offsets(sizes)
    dof0 = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    flat = np.zeros(int(np.sum(sizes ** 2)))
    op = BlockDiagonal(dof0, off, flat)
    assert op.complete
    flat[off[2]:off[2] + 81] = np.eye(9).ravel()  # changed after the operator was made
    x = np.arange(17.0)
    np.testing.assert_array_equal(op.matvec(x), np.r_[np.zeros(8), x[8:]])


def test_blocks_not_grouped_are_refused():
    sizes = np.array([2, 3, 2])
    off = np.array([0, 4, 13])  # body order: the two 2 x 2 blocks are not adjacent
    dof0 = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    with pytest.raises(ValueError, match="size 2"):
        BlockDiagonal(dof0, off, np.zeros(17))


def test_without_some_bodies_the_product_is_zero_on_their_dofs():
    rng = np.random.default_rng(5)
    sizes = np.array([54, 6, 54, 150, 54])
    present = np.ones(len(sizes), dtype=bool)
    blocks = _blocks(sizes, present, rng)
    off = grouped_offsets(sizes, present)
    dof0 = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    flat = _flat(blocks, off)
    x = rng.standard_normal(dof0[-1])
    whole = BlockDiagonal(dof0, off, flat).matvec(x)
    # every body of size 54 and the one of size 150 left out: a group each, whole
    op = without(dof0, off, flat, [0, 2, 3, 4])
    out = op.matvec(x)
    assert np.array_equal(out[54:60], whole[54:60])  # the rows of the body of 6 dofs
    assert not np.any(out[:54]) and not np.any(out[60:])
    # a body of size 54 laid out between two others of its size cannot be left out alone
    assert without(dof0, off, flat, [2]) is None
    assert np.array_equal(off, grouped_offsets(sizes, present))  # the offsets untouched
