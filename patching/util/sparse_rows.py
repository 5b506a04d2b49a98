"""The one builder of sparse matrices from triplets, gathered rule by rule (OpenSubdiv's
stencil tables are built the same way): ``add(rows, cols, weights)`` with broadcasting, then
``matrix(shape)``, duplicates summed and zeros dropped."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["TripletRows"]


class TripletRows:
    """COO triplets of a sparse matrix, gathered in blocks."""

    def __init__(self) -> None:
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []

    def add(self, rows, cols, vals) -> None:
        """Entries (rows, cols) += vals, the three broadcast against each other."""
        rows, cols, vals = np.broadcast_arrays(
            np.asarray(rows, np.int64), np.asarray(cols, np.int64), np.asarray(vals, np.float64)
        )
        self.r.append(rows.ravel())
        self.c.append(cols.ravel())
        self.v.append(vals.ravel())

    def matrix(self, shape: tuple[int, int]) -> sp.csr_matrix:
        """The CSR matrix of every triplet added: repeated entries summed, zeros dropped."""
        r = np.concatenate(self.r) if self.r else np.zeros(0, np.int64)
        c = np.concatenate(self.c) if self.c else np.zeros(0, np.int64)
        v = np.concatenate(self.v) if self.v else np.zeros(0)
        m = sp.csr_matrix((v, (r, c)), shape=shape)
        m.sum_duplicates()
        m.eliminate_zeros()
        return m
