"""Sparse products split into row blocks that run on several cores.

scipy's sparse kernels (``csr_matvecs``, ``csr_matmat``) release the GIL, so the row blocks
of one product A @ B run in parallel in threads; the result is the same product, row for row
(each row's sum is computed by the same kernel in the same order).  Blocks hold about equal
numbers of non-zeros and are views into A's arrays (no copy of A).  Small products, and
machines with one core, take the plain product.
"""

from __future__ import annotations

import ctypes
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import scipy.sparse as sp

__all__ = ["row_blocks", "product"]

#: Below this many non-zeros in A a product is not split: a product that small runs from cache
#: in a few milliseconds, and two threads measured slower than one (refined icosahedron, 1.6M).
MIN_SPLIT_NNZ = 2_000_000
_POOL: ThreadPoolExecutor | None = None


def _workers() -> int:
    return max(1, min(8, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1))


def _pool() -> ThreadPoolExecutor:
    global _POOL
    if _POOL is None:
        _POOL = ThreadPoolExecutor(max_workers=_workers(), thread_name_prefix="nupatch")
    return _POOL


def row_blocks(a: sp.csr_matrix, parts: int) -> list[tuple[int, int]]:
    """Row ranges [r0, r1) that split A into ``parts`` blocks of about equal non-zeros."""
    cuts = np.searchsorted(a.indptr, np.linspace(0, a.nnz, parts + 1)[1:-1])
    edges = np.unique(np.concatenate([[0], np.clip(cuts, 0, a.shape[0]), [a.shape[0]]]))
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


def _block(a: sp.csr_matrix, r0: int, r1: int) -> sp.csr_matrix:
    """Rows r0..r1-1 of A, their data and indices views into A's.  The arrays are set on an
    empty matrix of the block's shape: the (data, indices, indptr) constructor would copy
    them (scipy's ``prune`` copies a view of less than half its base: for the operator's
    product, one of its two row blocks, ~50 MB of fresh pages)."""
    lo, hi = int(a.indptr[r0]), int(a.indptr[r1])
    block = sp.csr_matrix((r1 - r0, a.shape[1]), dtype=a.dtype)
    block.indptr = np.asarray(a.indptr[r0 : r1 + 1] - lo, dtype=a.indices.dtype)
    block.data, block.indices = a.data[lo:hi], a.indices[lo:hi]
    return block


def product(a: sp.csr_matrix, *factors, prune: bool = False):
    """A @ B_1 @ B_2 ... (left to right) for CSR A and CSR factors, the last one CSR or dense:
    the same matrix as the plain products, each row block of A carried through the whole
    chain in parallel (module docstring).  prune: drop explicit zeros (sparse result)."""
    a = a.tocsr()

    def chain(block):
        for f in factors:
            block = block @ f
        if prune and sp.issparse(block):
            block = block.tocsr()
            block.eliminate_zeros()
        return block

    workers = _workers()
    if workers == 1 or a.nnz < MIN_SPLIT_NNZ or a.shape[0] < 2 * workers:
        return chain(a)
    blocks = [_block(a, *r) for r in row_blocks(a, workers)]
    if factors and sp.issparse(factors[-1]):
        heads = list(_pool().map(lambda b: _chain(b, factors[:-1]), blocks))
        out = _product_into_one(heads, factors[-1])
        if out is not None:
            if prune:
                out.eliminate_zeros()
            return out
    parts = list(_pool().map(chain, blocks))
    if not sp.issparse(parts[0]):
        return np.concatenate(parts, axis=0)
    return sp.vstack(parts, format="csr")  # CSR blocks: their arrays concatenated, no re-sort


def _chain(block: sp.csr_matrix, factors) -> sp.csr_matrix:
    for f in factors:
        block = block @ f
    return block.tocsr()


def _product_into_one(blocks: list[sp.csr_matrix], b) -> sp.csr_matrix | None:
    """The row blocks' products with CSR ``b`` written by scipy's own kernels
    (``csr_matmat_maxnnz``, ``csr_matmat``: those of ``block @ b``) straight into the arrays of
    one CSR result, in parallel, then closed up where a block's kernel dropped exact zeros:
    the same rows as ``sp.vstack([block @ b ...])`` without allocating and copying the result
    twice (for a 14M-entry operator that second copy was ~0.5 s of page faults in a fresh
    process).  None when scipy's kernels are not where, or not what, this scipy has them (they
    are scipy's private ``_sparsetools``; the caller then stacks the blocks' products)."""
    try:
        from scipy.sparse import _sparsetools as kernels

        index_dtype = blocks[0]._get_index_dtype
    except (ImportError, AttributeError):  # pragma: no cover - another scipy layout
        return None
    b = sp.csr_matrix(b)
    n = b.shape[1]
    arrays = [b.indptr, b.indices] + [x for blk in blocks for x in (blk.indptr, blk.indices)]
    dtype = np.result_type(*(blk.dtype for blk in blocks), b.dtype)

    def converted(idx):
        return (np.asarray(b.indptr, idx), np.asarray(b.indices, idx),
                [(np.asarray(blk.indptr, idx), np.asarray(blk.indices, idx)) for blk in blocks])

    idx = index_dtype(arrays)
    bp, bj, ab = converted(idx)
    pool = _pool()
    try:
        maxnnz = list(pool.map(lambda k: int(kernels.csr_matmat_maxnnz(blocks[k].shape[0], n, *ab[k], bp, bj)), range(len(blocks))))
    except (TypeError, ValueError):  # pragma: no cover - kernels with another signature
        return None
    total = sum(maxnnz)
    wider = index_dtype(arrays, maxval=max(total, n))
    if wider != idx:
        idx = wider
        bp, bj, ab = converted(idx)
    indices = np.empty(total, dtype=idx)
    data = np.empty(total, dtype=dtype)
    starts = np.concatenate([[0], np.cumsum(maxnnz)]).astype(np.int64)
    ptrs = [np.empty(blk.shape[0] + 1, dtype=idx) for blk in blocks]

    def run(k: int) -> None:
        lo, hi = int(starts[k]), int(starts[k + 1])
        kernels.csr_matmat(blocks[k].shape[0], n, *ab[k], np.asarray(blocks[k].data, dtype), bp, bj, np.asarray(b.data, dtype),
                           ptrs[k], indices[lo:hi], data[lo:hi])

    try:
        list(pool.map(run, range(len(blocks))))
    except (TypeError, ValueError):  # pragma: no cover - kernels with another signature
        return None
    rows = sum(blk.shape[0] for blk in blocks)
    indptr = np.empty(rows + 1, dtype=idx)
    at = row = 0
    for k, blk in enumerate(blocks):
        count = int(ptrs[k][-1])
        lo = int(starts[k])
        if lo != at and count:  # close the gap that the previous blocks' dropped zeros left
            _move_left(indices, lo, at, count)
            _move_left(data, lo, at, count)
        indptr[row : row + blk.shape[0]] = ptrs[k][:-1] + at
        at += count
        row += blk.shape[0]
    indptr[rows] = at
    return sp.csr_matrix((data[:at], indices[:at], indptr), shape=(rows, n), copy=False)


def _move_left(a: np.ndarray, source: int, target: int, count: int) -> None:
    """a[target : target + count] = a[source : source + count] in place for a contiguous 1-D
    array, target < source: one memmove (the ranges may overlap), where a slice assignment
    would first copy the source to a temporary (for the operator's blocks, tens of MB of new
    pages per product)."""
    if not (a.ndim == 1 and a.flags.c_contiguous and 0 <= target < source and source + count <= a.size):
        raise ValueError("_move_left: not a leftward move inside one contiguous array")
    base, size = a.ctypes.data, a.itemsize
    ctypes.memmove(base + target * size, base + source * size, count * size)
