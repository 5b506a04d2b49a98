"""The Bernstein basis: values, degree elevation as weight matrices, and the one evaluator of
Bézier nets (points and first derivatives) that every module uses."""

from __future__ import annotations

from functools import lru_cache
from math import comb

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .surface import BezierSurface

__all__ = [
    "elevation_matrix",
    "elevation_matrix_2d",
    "bernstein",
    "bernstein_derivatives",
    "common_nets",
    "group_nets",
    "evaluate_nets",
    "evaluate_pairs",
    "contract",
]


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


def common_nets(surface: "BezierSurface") -> tuple[np.ndarray, np.ndarray, int]:
    """All patches at one degree d (the largest): (faces (p,), nets (p, d+1, d+1, 3), d),
    rows in ``BezierSurface.patches`` order."""
    return group_nets(surface.groups)


def group_nets(groups) -> tuple[np.ndarray, np.ndarray, int]:
    """``common_nets`` of a sequence of ``PatchGroup`` (exact Bernstein degree elevation)."""
    d = max(g.degree for g in groups)
    faces, nets = [], []
    for g in groups:
        c = np.asarray(g.coefficients, dtype=np.float64)
        if g.degree != d:
            e = elevation_matrix_2d(g.degree, d)
            c = np.einsum("ab,kbc->kac", e, c.reshape(len(c), -1, 3)).reshape(len(c), d + 1, d + 1, 3)
        faces.append(np.asarray(g.faces, dtype=np.int64))
        nets.append(c)
    return np.concatenate(faces), np.concatenate(nets), d


def bernstein_derivatives(d: int, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Bernstein values B^d_j(x), first and second derivatives: three (N, d+1) arrays
    (B' = d (B^{d-1}_{j-1} - B^{d-1}_j), B'' = d (d-1) (B^{d-2}_{j-2} - 2 B^{d-2}_{j-1} + B^{d-2}_j))."""
    x = np.asarray(x, dtype=np.float64)
    b = _bernstein_triangle(d, x)
    b1 = np.zeros((x.size, d + 2))
    b1[:, 1:-1] = _bernstein_triangle(d - 1, x)
    db = d * (b1[:, :-1] - b1[:, 1:])
    b2 = np.zeros((x.size, d + 3))
    b2[:, 2:-2] = _bernstein_triangle(d - 2, x) if d >= 2 else 0.0
    ddb = d * (d - 1) * (b2[:, :-2] - 2 * b2[:, 1:-1] + b2[:, 2:]) if d >= 2 else np.zeros_like(b)
    return b, db, ddb


def _bernstein_triangle(d: int, x: np.ndarray) -> np.ndarray:
    """(N, d+1) B^d_j(x) by the triangle B^k_j = (1 - x) B^{k-1}_j + x B^{k-1}_{j-1}."""
    out = np.zeros((x.size, d + 1))
    out[:, 0] = 1.0
    y = 1.0 - x
    for k in range(1, d + 1):
        out[:, 1 : k + 1] = out[:, 1 : k + 1] * y[:, None] + out[:, :k] * x[:, None]
        out[:, 0] *= y
    return out
