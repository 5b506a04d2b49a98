"""The Bernstein basis: values, degree elevation as weight matrices, and the one evaluator of
Bézier nets (points and first derivatives) that every module uses."""

from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np

__all__ = ["elevation_matrix", "elevation_matrix_2d", "bernstein", "evaluate_nets", "evaluate_pairs", "contract"]


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


def evaluate_nets(nets: np.ndarray, s: np.ndarray, t: np.ndarray, derivatives: bool = False):
    """Points of (k, d+1, d+1, c) nets at parameters (m,) s and t (pairs): (k, m, c).

    With derivatives=True also returns S_s and S_t, each (k, m, c)."""
    d = nets.shape[1] - 1
    bs, bt = bernstein(d, s), bernstein(d, t)
    points = contract(bs, bt, nets)
    if not derivatives:
        return points
    ds = d * contract(bernstein(d - 1, s), bt, nets[:, 1:] - nets[:, :-1])
    dt = d * contract(bs, bernstein(d - 1, t), nets[:, :, 1:] - nets[:, :, :-1])
    return points, ds, dt


def contract(bs: np.ndarray, bt: np.ndarray, nets: np.ndarray) -> np.ndarray:
    """sum_ij bs[m, i] bt[m, j] nets[k, i, j, c] -> (k, m, c), as one matrix product with the
    (m, ij) tensor basis (BLAS; an unoptimised einsum over four indices is ~10x slower)."""
    basis = (bs[:, :, None] * bt[:, None, :]).reshape(bs.shape[0], -1)
    k, a, b, c = nets.shape
    flat = np.ascontiguousarray(nets).reshape(k, a * b, c).transpose(1, 0, 2).reshape(a * b, k * c)
    return (basis @ flat).reshape(bs.shape[0], k, c).transpose(1, 0, 2)


def evaluate_pairs(nets: np.ndarray, s: np.ndarray, t: np.ndarray, derivatives: bool = False):
    """Net m of (m, d+1, d+1, c) nets at its own parameter pair (s[m], t[m]): points (m, c).

    With derivatives=True also returns S_s and S_t, each (m, c).  ``evaluate_nets`` is the
    grid form (every net at every pair)."""
    d = nets.shape[1] - 1
    bs, bt = bernstein(d, s), bernstein(d, t)
    along_t = np.einsum("mj,mijc->mic", bt, nets)  # rows of the net evaluated in t
    points = np.einsum("mi,mic->mc", bs, along_t)
    if not derivatives:
        return points
    ds = d * np.einsum("mi,mic->mc", bernstein(d - 1, s), along_t[:, 1:] - along_t[:, :-1])
    along_s = np.einsum("mi,mijc->mjc", bs, nets)
    dt = d * np.einsum("mj,mjc->mc", bernstein(d - 1, t), along_s[:, 1:] - along_s[:, :-1])
    return points, ds, dt
