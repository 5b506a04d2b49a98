"""Bézier extraction of one span of a non-uniform cubic B-spline, as weights ([FSLYJ], 3.2).

Knot-interval convention (docs/knots.md): along a row of control points the leg P_i P_{i+1}
carries the interval t_{i+3} - t_{i+2}.  The span between the middle two of four control points
P_0..P_3 therefore is [t_3, t_4] and depends on five leg intervals

    e = (e_0, e_1, e_2, e_3, e_4) = (t_2 - t_1, t_3 - t_2, t_4 - t_3, t_5 - t_4, t_6 - t_5),

the legs P_{-1}P_0, P_0P_1, P_1P_2 (the span itself), P_2P_3 and P_3P_4.  With blossoms,
P_j = f(t_{j+1}, t_{j+2}, t_{j+3}) and the Bézier points are b_k = f(t_3^{3-k}, t_4^k); the
de Boor recursion evaluates the blossom (The NURBS Book, A5.1 generalised to blossoms).  This
is the same double-knot insertion that [FSLYJ] writes as face points (Fig. 6, alpha = d_0 /
(d_0 + d_1 + d_2)) and edge/vertex points (eq. 1).  Every denominator contains the span e_2,
so the weights exist whenever e_2 > 0; multiple knots (zero intervals) are allowed elsewhere.
"""

from __future__ import annotations

import numpy as np

__all__ = ["cubic_span_extraction", "blossom_weights"]


def blossom_weights(knots: np.ndarray, args: np.ndarray) -> np.ndarray:
    """Weights of the cubic blossom f(u_1, u_2, u_3) over the four control points.

    knots: (k, 6) float64, t_1..t_6 of each span.  args: (k, m, 3) blossom arguments.
    Returns (k, m, 4): f(args[., q]) = sum_j w[., q, j] P_j.
    """
    k, m, _ = args.shape
    t = np.concatenate([np.zeros((k, 1)), knots], axis=1)  # t[:, i] = t_i, t_0 unused
    # Level-0 points: identity weights, Q[j] for j = 0..3.
    q = np.broadcast_to(np.eye(4), (k, m, 4, 4)).copy()  # (k, m, point j, weight)
    for r in (1, 2, 3):
        u = args[:, :, r - 1][:, :, None]  # (k, m, 1)
        j = np.arange(r, 4)
        lo = t[:, j][:, None, :]  # t_j
        hi = t[:, j + 4 - r][:, None, :]  # t_{j+4-r}
        a = ((u - lo) / (hi - lo))[..., None]  # (k, m, len(j), 1)
        new = q.copy()
        new[:, :, j, :] = (1.0 - a) * q[:, :, j - 1, :] + a * q[:, :, j, :]
        q = new
    return q[:, :, 3, :]


def cubic_span_extraction(intervals: np.ndarray) -> np.ndarray:
    """Bézier weights of the span [t_3, t_4]: (k, 4, 4) with b_i = sum_j W[., i, j] P_j.

    intervals: (k, 5) float64 leg intervals e_0..e_4 (module docstring); e_2 > 0.
    Rows sum to 1 (affine invariance).
    """
    e = np.asarray(intervals, dtype=np.float64)
    knots = np.cumsum(np.concatenate([np.zeros((e.shape[0], 1)), e], axis=1), axis=1)  # t_1..t_6
    t3, t4 = knots[:, 2], knots[:, 3]
    args = np.stack(
        [
            np.stack([t3, t3, t3], axis=1),
            np.stack([t3, t3, t4], axis=1),
            np.stack([t3, t4, t4], axis=1),
            np.stack([t4, t4, t4], axis=1),
        ],
        axis=1,
    )
    return blossom_weights(knots, args)
