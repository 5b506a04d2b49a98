"""Sparse products split into row blocks that run on several cores.

scipy's sparse kernels (``csr_matvecs``, ``csr_matmat``) release the GIL, so the row blocks
of one product A @ B run in parallel in threads; the result is the same product, row for row
(each row's sum is computed by the same kernel in the same order).  Blocks hold about equal
numbers of non-zeros and are views into A's arrays (no copy of A).  Small products, and
machines with one core, take the plain product.
"""

from __future__ import annotations

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
    lo, hi = a.indptr[r0], a.indptr[r1]
    return sp.csr_matrix((a.data[lo:hi], a.indices[lo:hi], a.indptr[r0 : r1 + 1] - lo), shape=(r1 - r0, a.shape[1]), copy=False)


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
    parts = list(_pool().map(lambda r: chain(_block(a, *r)), row_blocks(a, workers)))
    if not sp.issparse(parts[0]):
        return np.concatenate(parts, axis=0)
    return sp.vstack(parts, format="csr")  # CSR blocks: their arrays concatenated, no re-sort
