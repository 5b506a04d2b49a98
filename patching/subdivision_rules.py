"""Subdivision masks only: weights for face, edge and vertex points, no mesh (STYLE 1, like
OpenSubdiv's ``sdc/``).  ``subdivision`` gathers the knot intervals and tags from the topology
and calls these, vectorised over arrays of configurations.

Curve rules (the building block of every regular rule): a cubic B-spline with control points
``... P_{i-1}, P_i, P_{i+1} ...``; the edge ``P_j P_{j+1}`` carries the knot interval ``d_j``
(DESIGN 2).  Inserting a knot at the middle of every interval (each interval split into two
halves) gives, [SZSS98] and seed 000 eqs. (11)-(13):

    edge point on P_i P_{i+1}:
        E_i = ((d_i + 2 d_{i+1}) P_i + (d_i + 2 d_{i-1}) P_{i+1}) / (2 (d_{i-1} + d_i + d_{i+1}))
    vertex point at P_i:
        V_i = (d_i E_{i-1} + (d_{i-1} + d_i) P_i + d_{i-1} E_i) / (2 (d_{i-1} + d_i))

Seed 000 writes both with the intervals beyond the two neighbours equal to the spoke's own
(its eqs. 12-13 are the edge rule with ``d_{i+1} = d_i``); written here in general, and checked
(tests) against OpenCASCADE's knot insertion on torus grids.  Uniform intervals give the
classic ``(1/2, 1/2)`` and ``(1/8, 3/4, 1/8)``.  Every mask is invariant under scaling all
intervals, and its weights sum to one.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "curve_edge_weights",
    "curve_vertex_weights",
    "blz_gamma",
    "curve_limit_weights",
    "curve_derivative_weights",
    "SMOOTH",
    "DART",
    "CREASE",
    "CORNER",
]

#: Vertex rules, numbered as OpenSubdiv's Sdc::Crease::Rule by sharp-edge count (0, 1, 2, >2).
SMOOTH, DART, CREASE, CORNER = 0, 1, 2, 3


def curve_edge_weights(d_prev, d, d_next):
    """Weights ``(w_i, w_{i+1})`` of the midpoint-insertion edge point of ``P_i P_{i+1}``.

    d_prev = d_{i-1} (beyond P_i), d = d_i (the edge), d_next = d_{i+1} (beyond P_{i+1}); arrays
    broadcast.  A zero total (three zero intervals) is a point of multiplicity four: the
    midpoint is returned there.
    """
    d_prev, d, d_next = (np.asarray(x, dtype=np.float64) for x in (d_prev, d, d_next))
    total = 2.0 * (d_prev + d + d_next)
    safe = np.where(total > 0, total, 1.0)
    w_i = np.where(total > 0, (d + 2.0 * d_next) / safe, 0.5)
    return w_i, 1.0 - w_i


def curve_vertex_weights(d_mm, d_m, d_p, d_pp):
    """Weights ``(w_{i-1}, w_i, w_{i+1})`` of the midpoint-insertion vertex point at ``P_i``.

    d_mm = d_{i-2}, d_m = d_{i-1} (edge P_{i-1} P_i), d_p = d_i (edge P_i P_{i+1}),
    d_pp = d_{i+1}.  From V_i above with E_{i-1}, E_i expanded:
    ``w_{i-1} = d_i (d_{i-1} + 2 d_i) / (4 (d_{i-1} + d_i)(d_{i-2} + d_{i-1} + d_i))`` and its
    mirror image; ``w_i = 1 - w_{i-1} - w_{i+1}``.
    """
    d_mm, d_m, d_p, d_pp = (np.asarray(x, dtype=np.float64) for x in (d_mm, d_m, d_p, d_pp))
    s = d_m + d_p
    den_m = 4.0 * s * (d_mm + d_m + d_p)
    den_p = 4.0 * s * (d_m + d_p + d_pp)
    w_m = np.where(den_m > 0, d_p * (d_m + 2.0 * d_p) / np.where(den_m > 0, den_m, 1.0), 0.0)
    w_p = np.where(den_p > 0, d_m * (d_p + 2.0 * d_m) / np.where(den_p > 0, den_p, 1.0), 0.0)
    return w_m, 1.0 - w_m - w_p, w_p


def blz_gamma(theta):
    """Biermann-Levin-Zorin's edge weight next to a tagged vertex: ``3/8 - cos(theta)/4``
    (seed 000 section 2).  The tagged end gets ``3/4 - gamma``, the other end ``gamma``, the
    four far vertices ``1/16`` each; ``theta = pi/2`` gives the standard ``3/8``."""
    return 0.375 - 0.25 * np.cos(np.asarray(theta, dtype=np.float64))


def curve_limit_weights(a, b):
    """Limit position of a stationary curve vertex: weights ``(w_{-1}, w_0, w_{+1})``.

    After one step every vertex point has the same interval on both halves of each side:
    ``a`` (twice) towards ``P_{-1}``, ``b`` (twice) towards ``P_{+1}``; the curve rules on
    ``(P_{-1}, P_0, P_{+1})`` are then a closed 3x3 matrix whose left eigenvector of eigenvalue 1
    is (derived symbolically, checked in the tests against repeated subdivision):
    ``(b^2 / ((a+b)(2a+b)), 6ab / ((a+2b)(2a+b)), a^2 / ((a+b)(a+2b)))``; uniform: (1, 4, 1)/6,
    the value of the cubic B-spline at the knot between the two intervals.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    return (
        b * b / ((a + b) * (2 * a + b)),
        6 * a * b / ((a + 2 * b) * (2 * a + b)),
        a * a / ((a + b) * (a + 2 * b)),
    )


def curve_derivative_weights(a, b):
    """Derivative of the stationary curve at its vertex with respect to the knot parameter:
    weights on ``(P_{-1}, P_0, P_{+1})``, summing to 0.

    The left eigenvector of eigenvalue 1/2 of the same 3x3 matrix,
    ``(-b (a+2b), -2 (a-b)(a+b), a (2a+b))``, normalised so that it gives 1 on the Greville
    abscissae ``(-a, (b-a)/3, b)`` (linear precision): divided by
    ``(a+b)(9ab + 2(a-b)^2)/3``.  Uniform unit intervals: ``(P_{+1} - P_{-1}) / 2``.
    """
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    scale = 3.0 / ((a + b) * (9 * a * b + 2 * (a - b) ** 2))
    return -b * (a + 2 * b) * scale, -2 * (a - b) * (a + b) * scale, a * (2 * a + b) * scale
