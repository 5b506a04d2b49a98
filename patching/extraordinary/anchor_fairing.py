"""A second placement of the auxiliary control points: fairing ([FSLYJ] sec. 3.5 and
Fig. 16c).

Section 3.5 leaves the anchors free.  Fig. 16c improves the default placement "by minimizing
the average of thin plate energy for irregular patches and the difference between the new
auxiliary points with default ones"; the conclusion names the fairing energy of [SSEL13].  Used
here, per EP v with anchors A_v (the other EPs' anchors held at their defaults, so the operator
stays local):

    min_{A_v}  sum_f E_f(coefficients of f)  +  mu |A_v - A_v^default|^2,

    E_f = integral over the face of |S_xx|^2 + 2 |S_xy|^2 + |S_yy|^2 dx dy,

the thin-plate energy in knot-interval units (x = delta s, y = epsilon t on a face of
intervals delta, epsilon, so a face's energy is (eps / delta^3) I_ss + (2 / (delta eps)) I_st +
(delta / eps^3) I_tt in patch parameters), summed over every patch whose coefficients involve
A_v.  mu = 0.1 times the mean diagonal of the energy's Hessian in A_v: a dimensionless weight
that keeps the anchors near the eigen-polyhedron placement (which fixes the limit point and
tangent plane) while smoothing the rest.  Coefficients are linear in the anchors and the
control points, so the faired anchors are again linear in the control points.

EPs whose patches share anchors of other EPs (adjacent EPs: every vertex of the cube) are
coupled.  The per-EP solves are then the blocks of one block-Jacobi step on the joint energy,
from the defaults, and applied all at once they overshoot: on the cube with random intervals
(ratio 5) they folded a quarter of the surfaces.  Each EP's change is therefore damped by
omega_v = 1 / k_v, k_v the largest number of faired EPs whose anchors touch one of v's
patches.  With H = sum_p H_p and H_p <= k_p blockdiag(H_p) (Cauchy-Schwarz over the k_p
blocks of a patch), the damped step changes the joint energy by
sum_v (-omega_v + k_v omega_v^2 / 2) g_v^T H_vv^-1 g_v <= 0: it never makes the surface
less fair than the defaults.  An isolated EP (k_v = 1) gets its exact minimiser, as before;
a joint solve would make every anchor of an EP cluster depend on the whole cluster, and M
dense on EP-rich meshes.
"""

from __future__ import annotations

from functools import lru_cache
from math import comb

import numpy as np
import scipy.sparse as sp

__all__ = ["thin_plate_matrices", "faired_anchors"]

MU = 0.1


def _gram(k: int) -> np.ndarray:
    """(k+1, k+1): integral of B^k_i B^k_j over [0, 1]."""
    i = np.arange(k + 1)
    return np.array([[comb(k, a) * comb(k, b) / ((2 * k + 1) * comb(2 * k, a + b)) for b in i] for a in i])


def _difference(d: int, order: int) -> np.ndarray:
    """(d+1-order, d+1): the Bernstein coefficients of the order-th derivative."""
    out = np.eye(d + 1)
    for r in range(order):
        out = (d - r) * (out[1:] - out[:-1])
    return out


@lru_cache(maxsize=None)
def thin_plate_matrices(d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((d+1)^2, (d+1)^2) quadratic forms I_ss, I_st, I_tt of a row-major net[i, j] (i = s)."""
    g = _gram(d)
    d1, d2 = _difference(d, 1), _difference(d, 2)
    a2 = d2.T @ _gram(d - 2) @ d2
    a1 = d1.T @ _gram(d - 1) @ d1
    return np.kron(a2, g), np.kron(a1, a1), np.kron(g, a2)


def _energy_blocks(degrees: np.ndarray, spans: np.ndarray) -> sp.csr_matrix:
    """Block-diagonal energy over all patch rows (patches in row order)."""
    blocks = []
    for d, (delta, eps) in zip(degrees.tolist(), spans.tolist()):
        iss, ist, itt = thin_plate_matrices(d)
        blocks.append(eps / delta**3 * iss + 2.0 / (delta * eps) * ist + delta / eps**3 * itt)
    return sp.block_diag(blocks, format="csr")


def faired_anchors(
    stacked: sp.csr_matrix,
    n_points: int,
    default: sp.csr_matrix,
    anchor_sets: list[np.ndarray],
    degrees: np.ndarray,
    spans: np.ndarray,
) -> sp.csr_matrix:
    """(n_anchors, n_points): faired anchors.

    stacked: all patch rows over [points | anchors]; default: the default anchors over points;
    anchor_sets: the anchor indices (0-based among anchors) of each EP; degrees, spans: per
    patch in row order, its degree and its (u, v) intervals."""
    energy = _energy_blocks(degrees, spans)
    row_patch = np.repeat(np.arange(degrees.size), (degrees + 1) ** 2)
    patch_first = np.concatenate([[0], np.cumsum((degrees + 1) ** 2)])
    anchor_part = stacked[:, n_points:].tocsc()
    point_part = stacked[:, :n_points].tocsr()
    out = default.tolil(copy=True)
    touched_by = [np.unique(row_patch[anchor_part[:, ids].indices]) for ids in anchor_sets]
    sharing = np.zeros(degrees.size, dtype=np.int64)
    for touched in touched_by:
        sharing[touched] += 1
    for ids, touched in zip(anchor_sets, touched_by):
        rows = np.concatenate([np.arange(patch_first[p], patch_first[p + 1]) for p in touched])
        q = energy[rows][:, rows].toarray()
        block = anchor_part[rows].tocsr()
        r_a = block[:, ids].toarray()  # (rows, n)
        start = default[ids].toarray()  # A_v's default rows
        # coefficients with A_v removed and every other anchor at its default: (rows, n_points)
        rest = (point_part[rows] + block @ default).toarray() - r_a @ start
        h = r_a.T @ q @ r_a
        mu = MU * np.mean(np.diag(h))
        rhs = -(r_a.T @ q @ rest) + mu * start
        solved = np.linalg.solve(h + mu * np.eye(len(ids)), rhs)
        # damped block-Jacobi step (module docstring): a patch touched by k EPs' anchors
        solved = start + (solved - start) / sharing[touched].max()
        solved[np.abs(solved) < 1e-15] = 0.0
        out[ids] = solved
    return out.tocsr()
