"""Bernstein-basis helpers as weight matrices: degree elevation and reduction."""

from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np

__all__ = ["elevation_matrix", "elevation_matrix_2d", "bernstein"]


@lru_cache(maxsize=None)
def elevation_matrix(p: int, q: int) -> np.ndarray:
    """(q+1, p+1) weights raising a degree-p Bézier curve to degree q >= p (exact):
    b^q_k = sum_j C(p, j) C(q-p, k-j) / C(q, k) b^p_j."""
    out = np.zeros((q + 1, p + 1))
    for k in range(q + 1):
        for j in range(max(0, k - (q - p)), min(p, k) + 1):
            out[k, j] = comb(p, j) * comb(q - p, k - j) / comb(q, k)
    out.setflags(write=False)
    return out


@lru_cache(maxsize=None)
def elevation_matrix_2d(p: int, q: int) -> np.ndarray:
    """((q+1)^2, (p+1)^2) weights raising a tensor-product net, row-major net[i, j]."""
    e = elevation_matrix(p, q)
    out = np.kron(e, e)
    out.setflags(write=False)
    return out


def bernstein(degree: int, s: np.ndarray) -> np.ndarray:
    """(len(s), degree+1) values B^degree_j(s)."""
    s = np.asarray(s, dtype=np.float64)[:, None]
    j = np.arange(degree + 1)[None, :]
    coef = np.array([comb(degree, k) for k in range(degree + 1)], dtype=np.float64)[None, :]
    return coef * s**j * (1 - s) ** (degree - j)
