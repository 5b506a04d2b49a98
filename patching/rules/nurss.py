"""NURSS at an extraordinary vertex: the local rules of Sederberg, Zheng, Sewell and Sabin's
non-uniform recursive subdivision surfaces (1998, [TLC]'s and [ZTL]'s [SZSS98]), masks only.

The baseline that [TLC] (sec. 2, "a heuristic way to generalize non-uniform bi-cubic B-spline
refinement rules to arbitrary valences") and [ZTL] (Fig. 2a) compare the eigen-polyhedron
rules of [LFS16] against.  Away from extraordinary points NURSS is midpoint knot insertion of
the bicubic B-spline, the same rows as ``rules.catmark``'s curve rules; this module gives the
(2n+1) x (2n+1) matrix of one step on the 1-ring of a smooth vertex of valence n, in the point
order of ``eigen_polyhedron`` ([V, E_0.., F_0..], spoke i = V-E_i with interval d_i, face
i = (V, E_i, F_i, E_{i+1})).

Reconstruction (no seed restates NURSS's formulas; [TLC] sec. 4.3.1 writes the vertex rule
that [LFS16] kept from it).  Every rule is the tensor-product knot-insertion rule with the
one interval a valence-n vertex lacks, the interval *behind* V along spoke i, read as

    b_i = (d_{i-2} + d_{i+2}) / 2                      (the opposite spoke when n = 4),

and, as in [LFS16]'s and [TLC]'s local rules, the interval beyond E_i taken equal to d_i (the
1-ring then carries only the spoke intervals and the matrix is stationary; after one step it
is exact, both halves of a split spoke carrying d_i / 2).  With

    g_i = (d_i + 2 b_i) / (2 (b_i + 2 d_i)) = (d_{i-2} + d_i + d_{i+2}) / (d_{i-2} + 4 d_i + d_{i+2})

(the curve edge rule's weight of E_i on spoke i, [TLC] eq. 7's g_i):

* face point  F'_i = (1-g_i)(1-g_{i+1}) V + g_i (1-g_{i+1}) E_i + (1-g_i) g_{i+1} E_{i+1} + g_i g_{i+1} F_i
  (the tensor product of the two curve edge rules: [TLC]'s G_i);
* edge point  E'_i = M_i / 2 + (d_{i+1} F'_{i-1} + d_{i-1} F'_i) / (2 (d_{i-1} + d_{i+1})),
  M_i = (1-g_i) V + g_i E_i (the curve edge point along the spoke, [TLC]'s H_i), the cross
  direction by the curve vertex rule (face i-1 spans d_{i-1} across spoke i, face i d_{i+1});
* vertex point  V' = (n-3)/n V + 3/n sum_i (m_i M_i + f_i F'_i) / sum_i (m_i + f_i),
  f_i = d_{i-1} d_{i+2}, m_i = f_{i-1} + f_i: ``eigen_polyhedron.vertex_rule_weights``.

Checks that convinced (tests/test_nurss.py): equal intervals give Catmull-Clark's masks
(g_i = 1/2: centroid, (V + E_i + F'_{i-1} + F'_i) / 4, (n-2)/n V + (sum E + sum F) / n^2);
valence 4 gives the tensor product of cubic B-spline knot insertion for any intervals
(b_i the opposite spoke); the vertex rule's n = 4 form is the tensor product of the curve
vertex rules only with f_i = d_{i-1} d_{i+2}, m_i = f_{i-1} + f_i (worked out in
``vertex_rule_weights``' docstring).  What the reconstruction cannot check is NURSS's own
reading of b_i; with a different reading the EP rows change, the regular rows do not.

Eigen-structure ([TLC] sec. 3, [SZSS98]'s analysis as [TLC] reports it): the rows sum to one
(eigenvalue 1); at valence 4 the eigenvalues are the tensor products of the curve's
1, 1/2, 1/4 (so 1/2 twice); for equal spoke intervals they are Catmull-Clark's; for unequal
intervals at n != 4 the subdominant pair splits (lambda_2 != lambda_3), which is why NURSS's
EPs are not G1 in general and what [LFS16]'s eigen-polyhedron repairs
(``benchmarks/nurss_figures.py`` measures the split).
"""

from __future__ import annotations

import numpy as np

from patching.rules.eigen_polyhedron import VERTEX, vertex_rule_weights

__all__ = ["nurss_local_matrices", "nurss_local_matrix", "nurss_edge_weight"]


def nurss_edge_weight(intervals) -> np.ndarray:
    """g_i (module docstring): weight of E_i in the curve edge point on spoke i, (..., n)."""
    d = np.asarray(intervals, dtype=np.float64)
    dm2, dp2 = np.roll(d, 2, -1), np.roll(d, -2, -1)
    return (dm2 + d + dp2) / (dm2 + 4.0 * d + dp2)


def nurss_local_matrices(intervals) -> np.ndarray:
    """One NURSS step on the 1-rings of g vertices of valence n: (g, 2n+1, 2n+1) float64,
    new = M @ old in the order [V, E_0.., F_0..]; intervals (g, n), finite and positive
    (n >= 3).  Rows sum to 1; depends on the spoke intervals only."""
    d = np.asarray(intervals, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] < 3 or not np.all(np.isfinite(d)) or np.any(d <= 0):
        raise ValueError(f"NURSS spoke intervals: need (g, n >= 3) finite positive values, got {d.tolist()!r}")
    g_count, n = d.shape
    size = 2 * n + 1
    g = nurss_edge_weight(d)
    gn = np.roll(g, -1, axis=1)
    i = np.arange(n)
    E = 1 + i
    F = 1 + n + i
    m = np.zeros((g_count, size, size))
    # face points F'_i (rows 1 + n + i)
    m[:, F, VERTEX] = (1 - g) * (1 - gn)
    m[:, F, E] = g * (1 - gn)
    m[:, F, 1 + (i + 1) % n] = (1 - g) * gn
    m[:, F, F] = g * gn
    # edge points E'_i = M_i / 2 + (d_{i+1} F'_{i-1} + d_{i-1} F'_i) / (2 (d_{i-1} + d_{i+1}))
    dm, dp = np.roll(d, 1, axis=1), np.roll(d, -1, axis=1)
    w_prev = dp / (2.0 * (dm + dp))  # weight of F'_{i-1}
    w_here = dm / (2.0 * (dm + dp))  # weight of F'_i
    m[:, E, VERTEX] = 0.5 * (1 - g)
    m[:, E, E] = 0.5 * g
    m[:, E, :] += w_prev[:, :, None] * m[:, 1 + n + (i - 1) % n, :] + w_here[:, :, None] * m[:, F, :]
    m[:, VERTEX, :] = vertex_rule_weights(d)
    return m


def nurss_local_matrix(intervals) -> np.ndarray:
    """:func:`nurss_local_matrices` of one vertex: (2n+1, 2n+1) for intervals (n,)."""
    return nurss_local_matrices(np.asarray(intervals, dtype=np.float64)[None])[0]
