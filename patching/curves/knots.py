"""B-spline coefficient maps: knot insertion (Boehm) as matrices, clamping, midpoint refinement.

Every function returns a *matrix* acting on coefficients (splipy's ``insert_knot``):
``new_coefficients = A @ old_coefficients``, the curve unchanged.  Knot vectors are float
arrays of length ``n + degree + 1`` for ``n`` coefficients; the curve's domain is
``[knots[degree], knots[n]]``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["insert_knot_matrix", "insert_knots_matrix", "clamp_matrix"]


def insert_knot_matrix(knots: np.ndarray, degree: int, u: float) -> tuple[np.ndarray, sp.csr_matrix]:
    """Boehm's insertion of one knot ``u``: ``(new_knots, A)`` with ``A`` of shape (n + 1, n).

    Q_i = P_i (i <= mu - d), Q_i = (1 - a_i) P_(i-1) + a_i P_i with a_i = (u - t_i) / (t_(i+d) - t_i)
    (mu - d < i <= mu), Q_i = P_(i-1) (i > mu), where t_mu <= u < t_(mu+1) (The NURBS Book, A5.1).
    ``u`` must lie in ``[knots[degree], knots[n]]``.
    """
    knots = np.asarray(knots, dtype=np.float64)
    d = degree
    n = len(knots) - d - 1
    mu = int(np.searchsorted(knots, u, side="right")) - 1
    if mu >= n:  # u = t_n, the domain's end: t_(n-1) <= u <= t_n is as valid a span
        mu = n - 1
    i = np.arange(n + 1)
    a = np.zeros(n + 1)
    a[i <= mu - d] = 1.0
    mid = (i > mu - d) & (i <= mu)
    im = i[mid]
    a[mid] = (u - knots[im]) / (knots[im + d] - knots[im])
    # Q_i = a_i P_i + (1 - a_i) P_(i-1): a_i = 1 below the span, 0 above it
    rows = np.r_[i[a > 0], i[a < 1]]
    cols = np.r_[i[a > 0], i[a < 1] - 1]
    vals = np.r_[a[a > 0], 1.0 - a[a < 1]]
    ok = (cols >= 0) & (cols < n)
    A = sp.csr_matrix((vals[ok], (rows[ok], cols[ok])), shape=(n + 1, n))
    return np.insert(knots, mu + 1, u), A


def insert_knots_matrix(knots: np.ndarray, degree: int, values, sparse: bool = False):
    """Insert every value of ``values`` in turn: ``(new_knots, A)``, A dense (or csr)."""
    knots = np.asarray(knots, dtype=np.float64)
    A = sp.identity(len(knots) - degree - 1, format="csr")
    for u in values:
        knots, step = insert_knot_matrix(knots, degree, float(u))
        A = step @ A
    return knots, (A.tocsr() if sparse else A.toarray())


def clamp_matrix(knots: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """The same curve on its domain ``[a, b] = [knots[d], knots[n]]`` with clamped knots.

    Inserts ``a`` and ``b`` until each has multiplicity ``d + 1`` and drops the coefficients
    whose basis functions vanish on ``[a, b]``; returns ``(clamped_knots, A)``.
    """
    knots = np.asarray(knots, dtype=np.float64)
    d = degree
    n = len(knots) - d - 1
    a, b = knots[d], knots[n]
    ka = int(np.sum(knots == a))
    kb = int(np.sum(knots == b))
    new, A = insert_knots_matrix(knots, d, [a] * max(0, d + 1 - ka) + [b] * max(0, d + 1 - kb), sparse=True)
    first = int(np.searchsorted(new, a, side="left"))
    last = int(np.searchsorted(new, b, side="right"))  # one past the last b
    keep = slice(first, last - d - 1)
    return new[first:last], A[keep]
