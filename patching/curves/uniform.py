"""Uniform B-spline subdivision of degree d (Lane-Riesenfeld) as sparse operators.

A uniform B-spline of degree ``d`` with control points ``P_i`` and unit knot spacing is, after
halving the knot spacing, the B-spline of the points

    Q_j = sum_i binom(d + 1, j - 2 i) / 2^d  P_i                                   (1)

([KSD] sec. 3.1: ``B = b S`` with S the uniform part of the subdivision matrix; Table 1 lists
the masks ``[1, d+1, ..., 1] / 2^d``).  Operators are ``scipy.sparse`` matrices built from the
polygon size and the degree only, never from positions.

Index conventions (written down once, used by ``runs`` and ``limit``):

- closed polygon of n points: row ``j`` of the operator is ``Q_(j + o)`` of (1) with
  ``o = (d + 1) // 2``, indices mod n, so that for odd d the child of ``P_i`` is point ``2 i``
  (the vertex point) and for even d the two children of ``P_i`` are ``2 i`` and ``2 i + 1``;
- open polygon with free ends (no tags): the ``2 n - d`` points ``Q_d .. Q_(2n-1)``, those
  whose basis functions meet the domain of the ``n - d`` full spans.
"""

from __future__ import annotations

from math import comb

import numpy as np
import scipy.sparse as sp

__all__ = ["MAX_DEGREE", "MIN_DEGREE", "uniform_mask", "uniform_subdivision", "uniform_knots"]

MIN_DEGREE = 2
MAX_DEGREE = 7


def uniform_mask(degree: int) -> np.ndarray:
    """The refinement mask ``binom(d + 1, k) / 2^d``, k = 0..d+1 ([KSD] Table 1, B_d)."""
    d = degree
    return np.array([comb(d + 1, k) for k in range(d + 2)], dtype=np.float64) / 2.0**d


def uniform_subdivision(n: int, degree: int, closed: bool) -> sp.csr_matrix:
    """One step of uniform degree-d subdivision: (2n x n) closed, (2n - d x n) open, eq. (1)."""
    d = degree
    mask = uniform_mask(d)
    if closed:
        o = (d + 1) // 2
        j = np.arange(2 * n)
        rows, cols, vals = [], [], []
        for k, w in enumerate(mask):
            # Q_(j+o) takes P_i with (j + o) - 2 i = k, i.e. only rows of the right parity
            jj = j[(j + o - k) % 2 == 0]
            rows.append(jj)
            cols.append(((jj + o - k) // 2) % n)
            vals.append(np.full(len(jj), w))
        A = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * n, n))
        return A.tocsr()
    if n <= d:
        raise ValueError(f"an open polygon of degree {d} needs more than {d} points, not {n}")
    j = np.arange(d, 2 * n)
    rows, cols, vals = [], [], []
    for k, w in enumerate(mask):
        jj = j[(j - k) % 2 == 0]
        i = (jj - k) // 2
        ok = (i >= 0) & (i < n)
        rows.append(jj[ok] - d)
        cols.append(i[ok])
        vals.append(np.full(int(ok.sum()), w))
    A = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * n - d, n))
    return A.tocsr()


def uniform_knots(n: int, degree: int, closed: bool) -> tuple[np.ndarray, sp.csr_matrix]:
    """The limit of uniform subdivision as an (unclamped) B-spline: ``(knots, W)``, poles = W @ P.

    Open: knots ``-d .. n`` (domain of the ``n - d`` full spans ``[0, n - d]``), W the
    identity.  Closed: the periodic curve written with ``n + d`` poles, pole ``k`` being
    ``P_((k - d // 2) mod n)``, knots ``k - d // 2 - (d + 1) / 2``, so that the basis function of
    ``P_i`` is centred at parameter ``i`` (the closed index convention above: the child ``2 i``
    sits at ``i``); the domain ``[knots[d], knots[n + d]]`` has length n.
    """
    d = degree
    if not closed:
        return np.arange(-d, n + 1, dtype=np.float64), sp.identity(n, format="csr")
    s = d // 2
    k = np.arange(n + d)
    W = sp.coo_matrix((np.ones(n + d), (k, (k - s) % n)), shape=(n + d, n)).tocsr()
    knots = np.arange(n + 2 * d + 1, dtype=np.float64) - s - (d + 1) / 2
    return knots, W
